"""Option types of the ``stand`` commands: every value checked when the line is parsed.

Each function here is an argparse ``type=``: it turns the text into the value (paths stay
the text given) or raises
:class:`argparse.ArgumentTypeError`, which argparse reports as ``stand CMD: error:
argument --NAME: ...`` with exit 2 before anything runs. Numbers must be finite and in
their physical range; output paths must be creatable (tried, not guessed: the process
may be root, for whom ``os.access`` says yes to ``/proc``).

Checks that need two options at once go through :func:`require`; the command line runs
them after parsing (:func:`check`), with the same message form and exit code.
"""

from __future__ import annotations

import argparse
import math
import tempfile
from collections.abc import Callable
from pathlib import Path

from stand.runfile import MIN_PERIOD_S

#: Largest seed: numpy's legacy seeding range, 2**32 - 1.
MAX_SEED = 2**32 - 1
#: Longest stand time a command simulates or runs, s (the experiment profiles' bound).
MAX_DURATION_S = 3600.0
#: Longest sample period, s (the shortest is the run files' own, MIN_PERIOD_S).
MAX_PERIOD_S = 10.0
#: Most samples one simulated run may have (duration / period): 80 bytes a sample or so
#: in memory while simulating, so 10**7 is under a gigabyte.
MAX_SAMPLES = 10_000_000
#: File types ``--plot FILE`` may write (what matplotlib writes without extra backends).
PLOT_SUFFIXES = (".png", ".svg", ".pdf")

Check = Callable[[argparse.Namespace], str]


def real(low: float | None = None, high: float | None = None, *, above: float | None = None,
         unit: str = "") -> Callable[[str], float]:
    """A finite number with ``low <= x <= high`` and ``x > above`` (each if given)."""
    def convert(text: str) -> float:
        try:
            value = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
        if not math.isfinite(value):
            raise argparse.ArgumentTypeError(f"{text!r}: expected a finite number")
        bounds = [f"> {above:g}" if above is not None else "",
                  f">= {low:g}" if low is not None else "",
                  f"<= {high:g}" if high is not None else ""]
        wanted = " and ".join(b for b in bounds if b)
        if ((above is not None and not value > above) or (low is not None and value < low)
                or (high is not None and value > high)):
            raise argparse.ArgumentTypeError(f"{text!r}: expected a number {wanted}{unit}")
        return value
    return convert


def whole(low: int | None = None, high: int | None = None) -> Callable[[str], int]:
    """An integer with ``low <= n <= high`` (each if given)."""
    def convert(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text!r} is not a whole number") from None
        if (low is not None and value < low) or (high is not None and value > high):
            span = f"{low if low is not None else '-inf'}..{high if high is not None else 'inf'}"
            raise argparse.ArgumentTypeError(f"{value}: expected a whole number in {span}")
        return value
    return convert


positive = real(above=0.0)
non_negative = real(low=0.0)
finite = real()
duration = real(above=0.0, high=MAX_DURATION_S, unit=" s")
period = real(low=MIN_PERIOD_S, high=MAX_PERIOD_S, unit=" s")
seed = whole(0, MAX_SEED)
port = whole(0, 65535)


def _takes_files(text: str, directory: Path) -> str:
    """``text`` when ``directory`` is one that takes new files; tried by creating and
    removing one, the one sure test."""
    if not directory.is_dir():
        raise argparse.ArgumentTypeError(f"{text!r}: {directory} is not a directory")
    try:
        with tempfile.NamedTemporaryFile(dir=directory, prefix=".stand-check-"):
            pass
    except OSError as exc:
        raise argparse.ArgumentTypeError(f"{text!r}: cannot write into {directory}: "
                                         f"{exc.strerror or exc}") from None
    return text


def output_file(text: str, suffixes: tuple[str, ...] = ()) -> str:
    """A file the command may write: in an existing directory that takes files, not a
    directory itself, not an existing non-regular file; with one of ``suffixes``."""
    path = Path(text)
    if suffixes and path.suffix.lower() not in suffixes:
        raise argparse.ArgumentTypeError(f"{text!r}: expected a file name ending in "
                                         f"{', '.join(suffixes)}")
    if path.is_dir():
        raise argparse.ArgumentTypeError(f"{text!r} is a directory; expected a file name")
    if path.exists() and not path.is_file():
        raise argparse.ArgumentTypeError(f"{text!r} exists and is not a regular file")
    return _takes_files(text, path.parent)


def plot_file(text: str) -> str:
    """A figure file (``.png``, ``.svg``, ``.pdf``) the command may write."""
    return output_file(text, PLOT_SUFFIXES)


def output_dir(text: str) -> str:
    """A directory the command may fill: existing and taking files, or creatable under
    the nearest existing directory."""
    path = Path(text)
    if path.exists() and not path.is_dir():
        raise argparse.ArgumentTypeError(f"{text!r} exists and is not a directory")
    existing = path
    while not existing.exists():
        existing = existing.parent
    return _takes_files(text, existing)


def input_file(text: str) -> str:
    """An existing regular file to read (not a device such as /dev/zero, not a folder)."""
    path = Path(text)
    if not path.exists():
        raise argparse.ArgumentTypeError(f"{text!r}: no such file")
    if not path.is_file():
        raise argparse.ArgumentTypeError(f"{text!r} is not a regular file")
    return text


def require(parser: argparse.ArgumentParser, check: Check) -> None:
    """Add a check over several options: ``check(args)`` returns '' or what is wrong."""
    checks: list[Check] = parser.get_default("_checks") or []
    parser.set_defaults(_checks=[*checks, check])


def check(parser: argparse.ArgumentParser, args: argparse.Namespace) -> None:
    """Run the checks of :func:`require`; the first failure exits 2 via ``parser.error``."""
    for each in getattr(args, "_checks", None) or []:
        problem = each(args)
        if problem:
            parser.error(problem)


def samples_within(limit: int = MAX_SAMPLES) -> Check:
    """``--duration / --period`` at most ``limit`` samples (when --period is given)."""
    def within(args: argparse.Namespace) -> str:
        if getattr(args, "period", None) is None or getattr(args, "duration", None) is None:
            return ""
        count = args.duration / args.period
        if count > limit:
            return (f"argument --duration/--period: {args.duration:g} s at {args.period:g} s is "
                    f"{count:.3g} samples, more than {limit}; shorten --duration or lengthen "
                    "--period")
        return ""
    return within


def effect(text: str) -> str:
    """``NAME[:param=value,...]`` checked by the effect's own rules (the vocabulary of
    CONTRACT §3, finite values, whole numbers where the physics counts)."""
    from stand.cli.simulate import parse_effect
    from stand.errors import InputError
    from stand.physics.effects import Effects

    try:
        name, params = parse_effect(text)
        Effects.from_mapping({name: params}, "--effect")
    except InputError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None
    return text


def add_motor_supply(parser: argparse.ArgumentParser) -> None:
    """``--motor PROFILE``: the drive's supply and the motor's armature for a speed-loop
    run's refinement (:class:`~stand.ident.supply.DriveSupply`)."""
    parser.add_argument("--motor", default=None, metavar="PROFILE",
                        help="motor profile (name or YAML path) whose drive supply, current "
                             "limit, R, L and Kt start the speed-loop refinement's model of a "
                             "loop that saturates (R, L, Kt are refitted)")

