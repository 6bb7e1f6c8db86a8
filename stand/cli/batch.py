"""``stand batch OPERATION INPUTS... -o RESULTS``: one operation over many runs, on Dask.

OPERATION is ``identify``, ``torque-constant``, ``efficiency``, ``step-identify`` or
``diagnose``, with that command's options. INPUTS are run files, globs, ``run:ID`` or
``query:KEY=VALUE,...`` (stored runs of the service), or ``FIRST,SECOND`` pairs for
``diagnose`` (TRAIN,HOLDOUT) and ``torque-constant`` (NO_LOAD,LOADED). One row per input
goes to RESULTS (.csv or .parquet) with an ``error`` column; the fleet figures of each
group go to ``RESULTS`` with the suffix ``.fleets.json``. A progress bar goes to stderr.
"""

from __future__ import annotations

import argparse
import json
import logging
import sys
import time
from dataclasses import replace
from pathlib import Path
from typing import Any, TextIO

from stand.batch import OPERATIONS, BatchResult, run_batch
from stand.batch.inputs import POOL_KEYS
from stand.batch.table import check_output
from stand.cli import options

#: Most processes of the local cluster, and most items in one Dask task.
MAX_WORKERS = 1024
MAX_CHUNK = 10**6
#: Least time between two redraws of the progress bar, s.
PROGRESS_INTERVAL_S = 0.5
PROGRESS_WIDTH = 30


class ProgressBar:
    """A one-line progress bar on ``stream`` (redrawn in place on a terminal; otherwise a
    line every tenth of the batch)."""

    def __init__(self, stream: TextIO | None = None) -> None:
        # sys.stderr when the bar is made, not when the module was imported (a test's
        # captured stream then, closed by now)
        self.stream = sys.stderr if stream is None else stream
        self.start = time.monotonic()
        self.last = -PROGRESS_INTERVAL_S
        self.tty = self.stream.isatty()
        self.tenth = -1

    def __call__(self, done: int, total: int) -> None:
        now = time.monotonic()
        tenth = 10 * done // max(total, 1)
        if self.tty and (now - self.last >= PROGRESS_INTERVAL_S or done == total):
            filled = PROGRESS_WIDTH * done // max(total, 1)
            bar = "#" * filled + "." * (PROGRESS_WIDTH - filled)
            self.stream.write(f"\r[{bar}] {done}/{total} items, {now - self.start:.1f} s")
            if done == total:
                self.stream.write("\n")
            self.stream.flush()
            self.last = now
        elif not self.tty and tenth != self.tenth:
            self.stream.write(f"batch: {done}/{total} items, {now - self.start:.1f} s\n")
            self.tenth = tenth


def results_file(text: str) -> str:
    """A results table the command may write: .csv or .parquet, in a folder that takes files."""
    return options.output_file(text, (".csv", ".parquet"))


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("operation", choices=list(OPERATIONS), help="what to do with each input")
    parser.add_argument("inputs", nargs="+", metavar="INPUT",
                        help="run file, glob, run:ID, query:KEY=VALUE[,...] (kind, state, "
                             "profile, origin, limit), or FIRST,SECOND for diagnose "
                             "(TRAIN,HOLDOUT) and torque-constant (NO_LOAD,LOADED)")
    parser.add_argument("-o", "--output", required=True, metavar="RESULTS", type=results_file,
                        help="results table, .csv or .parquet (one row per input)")
    engine = parser.add_argument_group("engine")
    engine.add_argument("--workers", type=options.whole(0, MAX_WORKERS), default=2,
                        help="processes of the local Dask cluster (default 2); 0 runs every "
                             "item in this process without Dask")
    engine.add_argument("--scheduler", metavar="ADDRESS",
                        help="an existing Dask scheduler (tcp://HOST:8786) instead of a local cluster")
    engine.add_argument("--chunk", type=options.whole(1, MAX_CHUNK), default=1, metavar="N",
                        help="items per Dask task (default 1; larger for items of a few ms)")
    engine.add_argument("--db", metavar="FILE",
                        help="the service's SQLite file for run:/query: inputs "
                             "(default: the service's, from STAND_DATA_DIR / STAND_DB_PATH)")
    engine.add_argument("--pool", default="auto",
                        help=f"fleets for pooled figures: {', '.join(POOL_KEYS)} or re:REGEX "
                             "(auto: a stored run's profile, a file's folder)")
    engine.add_argument("--no-progress", action="store_true", help="no progress bar")
    ops = parser.add_argument_group("operation options (as the single commands')")
    ops.add_argument("--method", help="identify/torque-constant: default, paper; "
                                      "step-identify: trf, lm, gd, pattern")
    ops.add_argument("--no-load-current", type=options.non_negative, dest="no_load_current_A",
                     metavar="A",
                     help="identify: no-load current subtracted, A")
    ops.add_argument("--half-width", type=options.whole(1, 10**5),
                     help="identify/torque-constant: kernel half width")
    ops.add_argument("--added-inertia", type=options.positive, metavar="KGM2",
                     help="torque-constant: inertia of the added disk, kg·m²")
    ops.add_argument("--no-compensation", dest="compensate", action="store_const", const=False,
                     help="torque-constant: do not subtract the no-load current")
    ops.add_argument("--ratio", type=options.positive, metavar="N", help="efficiency: reduction ratio")
    ops.add_argument("--k-in", type=options.positive, metavar="NM_PER_A", help="efficiency: input Kt, N·m/A")
    ops.add_argument("--k-out", type=options.positive, metavar="NM_PER_A",
                     help="efficiency: output Kt, N·m/A")
    ops.add_argument("--known", action="append", metavar="NAME=VALUE",
                     help="step-identify: a known parameter, repeatable")
    ops.add_argument("--hold", help="step-identify: preceding or following")
    ops.add_argument("--speed-only", dest="use_current", action="store_const", const=False,
                     help="step-identify: ignore current_A")
    ops.add_argument("--kt", type=options.positive, help="diagnose: torque constant, N·m/A")
    ops.add_argument("--horizon", type=options.positive, dest="horizon_s", metavar="S",
                     help="diagnose: free-run time between re-anchorings, s")
    ops.add_argument("--max-effects", type=options.whole(1, 8), help="diagnose: most effects in the verdict")
    ops.add_argument("--spring", action="store_const", const=True,
                     help="diagnose: keep the spring term C·θ")


#: Option names of the parser that belong to the operations.
OPTION_NAMES = ("method", "no_load_current_A", "half_width", "added_inertia", "compensate",
                "ratio", "k_in", "k_out", "known", "hold", "use_current", "kt", "horizon_s",
                "max_effects", "spring")


def options_of(args: argparse.Namespace) -> dict[str, Any]:
    """The operation options given on the command line (``None`` ones left out)."""
    options = {name: getattr(args, name) for name in OPTION_NAMES
               if getattr(args, name) is not None}
    if "known" in options:
        from stand.cli.step_identify import parse_known

        options["known"] = parse_known(options["known"])
    return options


def fleets_path(output: str | Path) -> Path:
    """Where the fleet figures of a results table go: ``RESULTS.fleets.json``."""
    out = Path(output)
    return out.with_name(out.stem + ".fleets.json")


def _database(args: argparse.Namespace) -> Path | None:
    if args.db:
        return Path(args.db)
    if any(text.startswith(("run:", "query:")) or ",run:" in text for text in args.inputs):
        from stand.settings import get_settings

        return get_settings().database
    return None


def _quiet_dask(record: logging.LogRecord) -> bool:
    return not record.name.startswith("distributed") or record.levelno >= logging.WARNING


def run(args: argparse.Namespace) -> BatchResult:
    check_output(args.output)
    # The command line logs at INFO; Dask's scheduler and nannies (whose loggers carry
    # levels of their own) would fill stderr with start-up and shutdown chatter. Their
    # warnings and errors still show.
    for handler in logging.getLogger().handlers:
        handler.addFilter(_quiet_dask)
    progress = None if args.no_progress else ProgressBar()
    result = run_batch(args.operation, args.inputs, options_of(args), workers=args.workers,
                       scheduler=args.scheduler, database=_database(args), pool=args.pool,
                       chunk=args.chunk, on_progress=progress).write(args.output)
    if result.fleets:
        path = fleets_path(args.output)
        partial = path.with_name(path.name + ".partial")
        partial.write_text(json.dumps([f.to_json() for f in result.fleets], indent=1,
                                      allow_nan=False) + "\n", encoding="utf-8")
        partial.replace(path)
        result = replace(result, fleets_output=str(path))
    return result


def summarize(result: dict[str, Any]) -> str:
    lines = [f"{result['operation']}: {result['ok']} of {result['items']} items done, "
             f"{result['errors']} error(s), {result['seconds']:.1f} s on {result['engine']}; "
             f"table: {result['output']}"]
    lines += [f"  error, item {e['item']} ({e['input']}): {e['error']}"
              for e in result["first_errors"]]
    for fleet in result["fleets"]:
        line = f"fleet {fleet['group']}: {fleet['field']} over {fleet['runs']} run(s)"
        if fleet["std"] is not None:
            low, high = fleet["std_ci95"]
            line += (f": mean {fleet['mean']:.6g} (95 % {fleet['mean_ci95'][0]:.6g} .. "
                     f"{fleet['mean_ci95'][1]:.6g}), spread {fleet['std']:.3g} "
                     f"(95 % {low:.3g} .. {high:.3g})")
        if fleet["pooled"]:
            pooled = fleet["pooled"]
            line += (f"; pooled Kt/J {pooled['Kt_over_J']:.6g} ± {pooled['Kt_over_J_se']:.2g} "
                     f"rad/(s²·A) from {pooled['samples']} samples")
        if fleet["message"]:
            line += f" ({fleet['message']})"
        lines.append(line)
    if result.get("fleets_output"):
        lines.append(f"fleets: {result['fleets_output']}")
    return "\n".join(lines)
