"""``stand simulate PROFILE -o RUN.csv``: write a simulated run file (CONTRACT §1)."""

from __future__ import annotations

import argparse
from typing import Any

import numpy as np

from stand.errors import InputError, NotFoundError
from stand.excitation import EXCITATIONS, excitation
from stand.physics.effects import Effects
from stand.physics.plant import MotorPlant
from stand.physics.reducer import ReducerPlant
from stand.physics.simulate import simulate_motor, simulate_reducer
from stand.profiles import load_motor, load_stand, resolve
from stand.runfile import Run, write_run


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
    parser.add_argument("-o", "--output", required=True, help="run file to write (CSV)")
    parser.add_argument("--duration", type=float, default=10.0, help="stand time, s")
    parser.add_argument("--period", type=float, help="sample period, s (default: profile)")
    parser.add_argument("--mode", choices=["voltage", "current", "speed"],
                        help="drive mode (default: the profile's)")
    parser.add_argument("--excitation", choices=EXCITATIONS, default="prbs")
    parser.add_argument("--level", type=float, help="mean command (V, A or rad/s)")
    parser.add_argument("--amplitude", type=float, help="excursion of the command")
    parser.add_argument("--hold", type=int, default=10, help="samples a random value is held")
    parser.add_argument("--step-time", type=float, default=0.0, help="time of a step, s")
    parser.add_argument("--effect", action="append", default=[], metavar="NAME[:p=v,...]",
                        help="add an effect of CONTRACT §3 (repeatable); 'none' drops "
                             "the profile's effects")
    parser.add_argument("--added-inertia", type=float, default=0.0, help="disk inertia, kg·m²")
    parser.add_argument("--load-current", type=float, default=0.5,
                        help="stand profiles: output-motor load step, A")
    parser.add_argument("--seed", type=int, default=None, help="seed of noise and excitation")


def effects_with(profile_effects: dict[str, dict[str, float]], options: list[str]) -> Effects:
    """The profile's effects, changed by ``--effect`` options."""
    merged = dict(profile_effects)
    for text in options:
        name, params = parse_effect(text)
        if name == "none":
            merged = {}
        else:
            merged[name] = params
    return Effects.from_mapping(merged, "--effect")


def _default_command(mode: str, limits: Any) -> tuple[float, float]:
    if mode == "speed":
        return 0.5 * limits.speed_rad_s, 0.25 * limits.speed_rad_s
    if mode == "voltage":
        return 0.5 * limits.voltage_V, 0.25 * limits.voltage_V
    return 0.3 * limits.current_A, 0.15 * limits.current_A


def simulate_profile(args: argparse.Namespace) -> Run:
    """The run that ``args`` describe (motor or stand profile)."""
    try:
        resolve(args.profile, "stands")
        is_stand = True
    except NotFoundError:
        is_stand = False
    if args.duration <= 0:
        raise InputError(f"--duration must be > 0 s, got {args.duration}")
    if is_stand:
        return _simulate_stand(args)
    profile = load_motor(args.profile)
    dt = args.period or profile.sample_period_s
    mode = args.mode or profile.drive.mode
    level, amplitude = _default_command(mode, profile.limits)
    level = level if args.level is None else args.level
    amplitude = amplitude if args.amplitude is None else args.amplitude
    samples = int(round(args.duration / dt))
    command = excitation(args.excitation, samples, dt, level, amplitude, args.hold,
                         args.step_time, args.seed)
    limit = {"speed": profile.limits.speed_rad_s, "voltage": profile.limits.voltage_V,
             "current": profile.limits.current_A}[mode]
    if np.max(np.abs(command)) > limit:
        raise InputError(
            f"command reaches {np.max(np.abs(command)):.4g}, beyond the profile's {mode} "
            f"limit {limit:.4g}; lower --level/--amplitude"
        )
    plant = MotorPlant(profile.motor_params(), profile.drive_params(mode),
                       profile.sensor_params(), effects_with(profile.effects, args.effect),
                       added_inertia=args.added_inertia, seed=args.seed)
    return simulate_motor(plant, mode, command, dt)


def _simulate_stand(args: argparse.Namespace) -> Run:
    stand = load_stand(args.profile)
    motor_in, motor_out = load_motor(stand.motor_in), load_motor(stand.motor_out)
    dt = args.period or stand.sample_period_s
    samples = int(round(args.duration / dt))
    speed = 0.4 * motor_in.limits.speed_rad_s if args.level is None else args.level
    if abs(speed) > motor_in.limits.speed_rad_s:
        raise InputError(f"--level {speed} rad/s exceeds the input motor's speed limit")
    if abs(args.load_current) > motor_out.limits.current_A:
        raise InputError(f"--load-current {args.load_current} A exceeds the output motor's limit")
    # Output load: 0 A and -load alternately, 8 plateaus after a settling quarter.
    plateau = np.arange(samples) * 10 // samples
    load = np.where((plateau >= 2) & (plateau % 2 == 1), -abs(args.load_current), 0.0)
    plant = ReducerPlant(
        motor_in.motor_params(), motor_out.motor_params(), stand.reducer_params(),
        motor_in.drive_params("speed"), motor_out.drive_params("current"),
        motor_in.sensor_params(), effects_with(motor_in.effects, args.effect),
        motor_out.effect_set(), seed=args.seed)
    return simulate_reducer(plant, [("speed", np.full(samples, speed)), ("current", load)], dt)


def run(args: argparse.Namespace) -> dict[str, Any]:
    result = simulate_profile(args)
    path = write_run(args.output, result.columns)
    return {"path": str(path), "samples": len(result), "dt_s": result.dt_s,
            "columns": list(result.columns)}


def summarize(result: dict[str, Any]) -> str:
    return (f"wrote {result['samples']} samples at {1 / result['dt_s']:.4g} Hz "
            f"to {result['path']} ({', '.join(result['columns'])})")
