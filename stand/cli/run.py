"""``stand run EXPERIMENT -o DIR``: run an experiment profile over the CAN bus.

Writes one run file (CONTRACT §1) and one raw trace (candump ``.log``, or ``.asc``/``.blf``
with ``--trace-format``) per run into DIR.
On the ``virtual`` interface the profile's drives are simulated in this process unless
``--no-simulate`` is given; on ``socketcan`` or another interface the drives are real or
simulated by ``python -m bus.simstand`` in another process.
"""

from __future__ import annotations

import argparse
import logging
from dataclasses import replace
from typing import Any

from stand.cli import options
from stand.controller import StandController, load_experiment
from stand.jsonable import to_jsonable
from stand.settings import get_settings

log = logging.getLogger("stand")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("experiment", help="experiment profile (name under profiles/experiments or path)")
    parser.add_argument("-o", "--output", required=True, type=options.output_dir,
                        help="directory for run files and traces")
    parser.add_argument("--interface", help="python-can interface (default: STAND_BUS_INTERFACE)")
    parser.add_argument("--channel", help="python-can channel (default: STAND_BUS_CHANNEL)")
    parser.add_argument("--time-mode", choices=["lockstep", "realtime"],
                        help="lockstep (simulated drives) or realtime (default: STAND_TIME_MODE)")
    parser.add_argument("--simulate", action=argparse.BooleanOptionalAction, default=None,
                        help="simulate the drives in this process (default: on 'virtual' only)")
    parser.add_argument("--seed", type=options.seed, default=None,
                        help="seed of the simulated sensor noise")
    parser.add_argument("--repeats", type=options.whole(1, 100), help="override the profile's repeats")
    parser.add_argument("--duration", type=options.duration,
                        help="override the profile's run length, s")
    parser.add_argument("--eds", metavar="FILE", type=options.input_file,
                        help="EDS or DCF of the drives (a real drive's, from its vendor; default: the "
                             "simulated drive's); each device's 0x1000 and 0x1018 are checked against it")
    parser.add_argument("--trace-format", choices=["log", "asc", "blf"], default="log",
                        help="raw trace of each run: candump .log, Vector .asc or .blf")


def run(args: argparse.Namespace) -> dict[str, Any]:
    from bus.adapters import BusConfig
    from bus.stand_bus import StandBus

    for noisy in ("canopen", "can"):  # their INFO lines would drown the progress
        logging.getLogger(noisy).setLevel(logging.WARNING)
    experiment = load_experiment(args.experiment)
    changes: dict[str, Any] = {}
    if args.repeats is not None:
        changes["repeats"] = args.repeats
    if args.duration is not None:
        changes["duration_s"] = args.duration
    if changes:
        experiment = type(experiment)(**{**experiment.model_dump(), **changes})
    settings = get_settings()
    config = BusConfig.from_settings()
    if args.interface or args.channel:
        config = replace(config, interface=args.interface or config.interface,
                         channel=args.channel or config.channel)
    time_mode = args.time_mode or settings.time_mode
    profile = experiment.stand or experiment.motor

    def progress(fraction: float) -> None:
        step = int(fraction * 20)
        if step != progress.last:  # type: ignore[attr-defined]
            progress.last = step  # type: ignore[attr-defined]
            log.info("%s: %3.0f %%", experiment.name, 100 * fraction)

    progress.last = -1  # type: ignore[attr-defined]
    with StandBus(profile, config, simulate=args.simulate, seed=args.seed, eds=args.eds) as bus:
        controller = StandController(bus, time_mode, progress=progress,
                                     trace_suffix=f".{args.trace_format}")
        result = controller.run_experiment(experiment, args.output)
        status = bus.status()
    return {"experiment": result.name, "procedure": result.procedure, "output": str(args.output),
            "complete": result.complete, "runs": to_jsonable(result.runs),
            "bus": {"interface": config.interface, "channel": config.channel,
                    "time_mode": time_mode, "nodes": status["nodes"]}}


def summarize(result: dict[str, Any]) -> str:
    lines = [f"{result['experiment']} ({result['procedure']}) -> {result['output']}"]
    for r in result["runs"]:
        gaps = "" if r["complete"] else (f"  INCOMPLETE: lost {r['lost']}, duplicates {r['duplicates']}, "
                                         f"late {r['late']}, targets a SYNC late {r['late_targets']}, "
                                         f"aborted: {r['aborted']}")
        lines.append(f"  {r['name']}: {r['samples']} samples at {1 / r['period_s']:.4g} Hz, "
                     f"{r['stand_time_s']:.3g} s stand time in {r['wall_time_s']:.3g} s -> {r['path']}{gaps}")
    return "\n".join(lines)
