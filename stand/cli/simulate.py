"""``stand simulate PROFILE -o RUN.csv``: write a simulated run file (CONTRACT §1)."""

from __future__ import annotations

import argparse
from typing import Any

from stand.cli import options
from stand.effects.delay import Delay
from stand.errors import InputError, NotFoundError
from stand.excitation import EXCITATIONS
from stand.physics.effects import Effects
from stand.runfile import write_run
from stand.simulation import simulate


def parse_effect(text: str) -> tuple[str, dict[str, float]]:
    """``NAME`` or ``NAME:param=value,param=value`` to (name, params)."""
    name, _, rest = text.partition(":")
    params: dict[str, float] = {}
    for item in filter(None, rest.split(",")):
        key, sep, value = item.partition("=")
        if not sep:
            raise InputError(f"--effect {text!r}: expected param=value, got {item!r}")
        try:
            params[key.strip()] = float(value)
        except ValueError:
            raise InputError(f"--effect {text!r}: {value!r} is not a number") from None
    return name.strip(), params


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("profile", help="motor or stand profile (name or YAML path)")
    parser.add_argument("-o", "--output", required=True, type=options.output_file,
                        help="run file to write (CSV)")
    parser.add_argument("--duration", type=options.duration, default=10.0, help="stand time, s")
    parser.add_argument("--period", type=options.period, help="sample period, s (default: profile)")
    parser.add_argument("--mode", choices=["voltage", "current", "speed"],
                        help="drive mode (default: the profile's)")
    parser.add_argument("--excitation", choices=EXCITATIONS, default="prbs")
    parser.add_argument("--level", type=options.finite, help="mean command (V, A or rad/s)")
    parser.add_argument("--amplitude", type=options.non_negative, help="excursion of the command")
    parser.add_argument("--hold", type=options.whole(1, 10**6), default=10,
                        help="samples a random value is held")
    parser.add_argument("--step-time", type=options.non_negative, default=0.0,
                        help="time of a step, s")
    parser.add_argument("--effect", action="append", default=[], metavar="NAME[:p=v,...]",
                        type=options.effect,
                        help="add an effect of CONTRACT §3 (repeatable); 'none' drops "
                             "the profile's effects")
    parser.add_argument("--added-inertia", type=options.non_negative, default=0.0,
                        help="disk inertia, kg·m²")
    parser.add_argument("--load-current", type=options.non_negative, default=0.5,
                        help="stand profiles: output-motor load step, A")
    parser.add_argument("--seed", type=options.seed, default=None,
                        help="seed of noise and excitation")
    options.require(parser, options.samples_within())
    options.require(parser, _delay_within_run)


def _delay_within_run(args: argparse.Namespace) -> str:
    """A ``delay`` effect must lag by fewer samples than the run has."""
    for text in args.effect:
        name, params = parse_effect(text)
        if name != Delay.name or "k" not in params:
            continue
        try:
            dt = args.period or _profile_period(args.profile)
        except (NotFoundError, InputError):
            return ""  # the profile's own error comes when the command runs
        samples = args.duration / dt
        if params["k"] >= samples:
            return (f"argument --effect: {text!r}: a lag of {params['k']:g} samples is not "
                    f"shorter than the run ({samples:.0f} samples)")
    return ""


def _profile_period(profile: str) -> float:
    from stand.profiles import load_motor, load_stand

    try:
        return float(load_stand(profile).sample_period_s)
    except NotFoundError:
        return float(load_motor(profile).sample_period_s)


def effect_options(options: list[str]) -> tuple[dict[str, dict[str, float]], bool]:
    """The effects ``--effect`` options add, and whether they drop the profile's own
    (``none``, which also drops the options before it)."""
    effects: dict[str, dict[str, float]] = {}
    replace = False
    for text in options:
        name, params = parse_effect(text)
        if name == "none":
            effects, replace = {}, True
        else:
            effects[name] = params
    Effects.from_mapping(effects, "--effect")  # names the option's bad effect or parameter
    return effects, replace


def run(args: argparse.Namespace) -> dict[str, Any]:
    effects, replace = effect_options(args.effect)
    result = simulate(
        args.profile, args.duration, period_s=args.period, mode=args.mode,
        excitation=args.excitation, level=args.level, amplitude=args.amplitude, hold=args.hold,
        step_time_s=args.step_time, effects=effects, replace_effects=replace,
        added_inertia=args.added_inertia, load_current_A=args.load_current, seed=args.seed)
    path = write_run(args.output, result.columns)
    return {"path": str(path), "samples": len(result), "dt_s": result.dt_s,
            "columns": list(result.columns)}


def summarize(result: dict[str, Any]) -> str:
    return (f"wrote {result['samples']} samples at {1 / result['dt_s']:.4g} Hz "
            f"to {result['path']} ({', '.join(result['columns'])})")
