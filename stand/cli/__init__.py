"""The ``stand`` command line (CONTRACT §2).

Each command lives in its own module under ``stand.cli`` and is imported only when it
runs (the table below, as python-can's interface table: ``stand serve`` need not load
SciPy, nor ``stand identify`` FastAPI). A command module defines::

    def add_arguments(parser) -> None
    def run(args) -> JsonResult | dict          # a result of the public API, or plain data
    def summarize(result: dict) -> str          # the human summary of the JSON object

The JSON object is the result's ``to_json()``: the same object the Python API returns.

With ``--json`` only the JSON object goes to stdout. Exit codes: 0 success, 2 bad input
(:class:`~stand.errors.InputError`, :class:`~stand.errors.NotFoundError`, argparse),
1 any other failure.
"""

from __future__ import annotations

import argparse
import importlib
import json
import logging
import sys
from collections.abc import Sequence

from stand.cli.options import check as check_options
from stand.errors import InputError, NotFoundError, StandError
from stand.jsonable import JsonResult, to_jsonable

#: Command name to (module, one-line help).
COMMANDS: dict[str, tuple[str, str]] = {
    "simulate": ("stand.cli.simulate", "simulate a profile and write a run file"),
    "identify": ("stand.cli.identify", "Q-matrix identification of a single-motor run (seed 000)"),
    "torque-constant": ("stand.cli.torque_constant", "torque constant from no-load and loaded runs"),
    "efficiency": ("stand.cli.efficiency", "reducer efficiency from a two-motor run (seed 000 eq. 18)"),
    "step-identify": ("stand.cli.step_identify", "R, L, K, J, Kf from voltage steps (seed 001)"),
    "diagnose": ("stand.cli.diagnose", "diagnose the sim-to-real gap on a holdout run"),
    "import": ("stand.cli.importer", "import a MAT, CSV, MF4 or CAN trace file into a run file"),
    "export": ("stand.cli.export", "export a run file to ASAM MDF 4 (.mf4) with units and metadata"),
    "report": ("stand.cli.report", "one self-contained HTML report of results, with pass/fail limits"),
    "run": ("stand.cli.run", "run an experiment profile over the CAN bus"),
    "serve": ("stand.cli.serve", "start the HTTP service"),
    "demo": ("stand.cli.demo", "run the whole simulated stand on the virtual bus"),
    "batch": ("stand.cli.batch", "one operation over many runs, on Dask (files, globs, stored runs)"),
}

log = logging.getLogger("stand")


#: Log level of each -v / -q count (default INFO: progress lines on stderr).
LOG_LEVELS = {-2: logging.ERROR, -1: logging.WARNING, 0: logging.INFO, 1: logging.DEBUG}


def _version() -> str:
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("motorstand")
    except PackageNotFoundError:  # run from a source tree that was never installed
        return "unknown (not installed)"


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="stand", description="Test-stand controller for motors and gear reducers.",
        epilog="commands: " + "; ".join(f"{n}: {h}" for n, (_, h) in COMMANDS.items()),
    )
    parser.add_argument("--version", action="version", version=f"%(prog)s {_version()}")
    parser.add_argument("-v", "--verbose", action="count", default=0,
                        help="more log lines on stderr (-v: debug)")
    parser.add_argument("-q", "--quiet", action="count", default=0,
                        help="fewer log lines on stderr (-q: warnings, -qq: errors only)")
    parser.add_argument("command", choices=list(COMMANDS), help="what to do")
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``stand`` console script; returns the exit code."""
    argv = list(sys.argv[1:] if argv is None else argv)
    top = _parser()
    if not argv or argv[0] in ("-h", "--help"):
        top.print_help(sys.stderr if not argv else sys.stdout)
        return 0 if argv else 2
    # Options before the command: --version, -v, -q (each command parses the rest).
    first = next((k for k, a in enumerate(argv) if not a.startswith("-")), len(argv))
    options = top.parse_args([*argv[:first], next(iter(COMMANDS))])
    argv = argv[first:]
    if not argv:
        top.error("give a command")
    level = LOG_LEVELS[max(-2, min(1, options.verbose - options.quiet))]
    logging.basicConfig(level=logging.INFO, stream=sys.stderr, format="%(message)s")
    log.setLevel(level)  # the project's own lines; libraries keep the root's level
    name = argv[0]
    if name not in COMMANDS:
        top.parse_args(argv[:1])  # prints the usage and exits 2
    module_name, help_text = COMMANDS[name]
    module = importlib.import_module(module_name)
    parser = argparse.ArgumentParser(prog=f"stand {name}", description=help_text)
    parser.add_argument("--json", action="store_true", help="print one JSON object on stdout")
    module.add_arguments(parser)
    try:  # argparse exits (2 on a bad option, 0 for --help); callers get the code back
        args = parser.parse_args(argv[1:])
        check_options(parser, args)  # checks across options, reported like argparse's own
    except SystemExit as stop:
        return stop.code if isinstance(stop.code, int) else 0
    try:
        result = module.run(args)
    except (InputError, NotFoundError) as exc:
        print(f"stand {name}: {exc}", file=sys.stderr)
        return 2
    except StandError as exc:
        print(f"stand {name}: {exc}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print(f"stand {name}: interrupted", file=sys.stderr)
        return 1
    data = result.to_json() if isinstance(result, JsonResult) else to_jsonable(result)
    if args.json:
        json.dump(data, sys.stdout, allow_nan=False)
        sys.stdout.write("\n")
    else:
        print(module.summarize(data))
    return 0
