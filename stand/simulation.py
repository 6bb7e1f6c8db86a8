"""Simulated runs of a shipped (or given) motor or stand profile: :func:`simulate`.

The motor's own physics (:mod:`stand.physics`), driven by an excitation of its drive
mode within the profile's limits, sampled as a drive reports it. A stand profile gives a
two-motor reducer run: the input motor speed-controlled, the output motor stepping a
load current. The same run the command line's ``stand simulate`` writes.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

import numpy as np

from stand.errors import InputError, NotFoundError
from stand.excitation import excitation as make_excitation
from stand.physics.effects import Effects
from stand.physics.plant import MotorPlant
from stand.physics.reducer import ReducerPlant
from stand.physics.simulate import simulate_motor, simulate_reducer
from stand.profiles import Limits, load_motor, load_stand, resolve
from stand.runfile import Run

EffectParams = Mapping[str, Mapping[str, float]]


def _default_command(mode: str, limits: Limits) -> tuple[float, float]:
    """Mean command and excursion well inside the limits (V, A or rad/s)."""
    if mode == "speed":
        return 0.5 * limits.speed_rad_s, 0.25 * limits.speed_rad_s
    if mode == "voltage":
        return 0.5 * limits.voltage_V, 0.25 * limits.voltage_V
    return 0.3 * limits.current_A, 0.15 * limits.current_A


def _effects(own: EffectParams, effects: EffectParams | None, replace_effects: bool,
             where: str) -> Effects:
    merged = {} if replace_effects else {k: dict(v) for k, v in own.items()}
    merged.update({k: dict(v) for k, v in (effects or {}).items()})
    return Effects.from_mapping(merged, where)


def _is_stand(profile: str | Path) -> bool:
    try:
        resolve(profile, "stands")
    except NotFoundError:
        return False
    return True


def simulate(profile: str | Path, duration_s: float = 10.0, *, period_s: float | None = None,
             mode: str | None = None, excitation: str = "prbs", level: float | None = None,
             amplitude: float | None = None, hold: int = 10, step_time_s: float = 0.0,
             effects: EffectParams | None = None, replace_effects: bool = False,
             added_inertia: float = 0.0, load_current_A: float = 0.5,
             seed: int | None = None) -> Run:
    """Simulate a motor or a two-motor stand profile.

    Parameters
    ----------
    profile : str or Path
        A shipped motor or stand profile's name (``crouzet_82800502``,
        ``cycloidal_two_motor``) or a YAML file.
    duration_s : float
        Stand time, s.
    period_s : float or None
        Sample period, s (default: the profile's).
    mode : {'voltage', 'current', 'speed'} or None
        Drive mode of a motor profile (default: the profile's).
    excitation : str
        Command shape of a motor profile (:data:`stand.excitation.EXCITATIONS`).
    level, amplitude : float or None
        Mean command and its excursion (V, A or rad/s; default: well inside the limits).
        On a stand, ``level`` is the input motor's speed, rad/s.
    hold : int
        Samples a random command value is held.
    step_time_s : float
        Time of a step command, s.
    effects : mapping of str to mapping, optional
        Effects of CONTRACT §3 to add, ``{"cogging": {"Tcog": 0.002, "N": 12}}``, over the
        (input) motor's own.
    replace_effects : bool
        Drop the profile's own effects first (``effects`` alone, or none).
    added_inertia : float
        Inertia of a disk on a motor's shaft, kg·m².
    load_current_A : float
        On a stand, the output motor's load current step, A.
    seed : int or None
        Seed of the sensor noise and the excitation.

    Returns
    -------
    Run
        A single-motor run (motor profile) or a reducer run (stand profile).

    Raises
    ------
    InputError
        A parameter out of range or a command beyond the profile's limits.
    NotFoundError
        No such profile.
    """
    if not duration_s > 0:
        raise InputError(f"duration_s must be > 0 s, got {duration_s}")
    if period_s is not None and not period_s > 0:
        raise InputError(f"period_s must be > 0 s, got {period_s}")
    if _is_stand(profile):
        return _simulate_stand(profile, duration_s, period_s, level, effects, replace_effects,
                               load_current_A, seed)
    motor = load_motor(profile)
    dt = period_s or motor.sample_period_s
    mode = mode or motor.drive.mode
    default_level, default_amplitude = _default_command(mode, motor.limits)
    level = default_level if level is None else level
    amplitude = default_amplitude if amplitude is None else amplitude
    samples = int(round(duration_s / dt))
    command = make_excitation(excitation, samples, dt, level, amplitude, hold, step_time_s, seed)
    limit = {"speed": motor.limits.speed_rad_s, "voltage": motor.limits.voltage_V,
             "current": motor.limits.current_A}[mode]
    if np.max(np.abs(command)) > limit:
        raise InputError(
            f"command reaches {np.max(np.abs(command)):.4g}, beyond the profile's {mode} "
            f"limit {limit:.4g}; lower the level or the amplitude"
        )
    plant = MotorPlant(motor.motor_params(), motor.drive_params(mode), motor.sensor_params(),
                       _effects(motor.effects, effects, replace_effects, "effects"),
                       added_inertia=added_inertia, seed=seed)
    return simulate_motor(plant, mode, command, dt)


def _simulate_stand(profile: str | Path, duration_s: float, period_s: float | None,
                    level: float | None, effects: EffectParams | None, replace_effects: bool,
                    load_current_A: float, seed: int | None) -> Run:
    stand = load_stand(profile)
    motor_in, motor_out = load_motor(stand.motor_in), load_motor(stand.motor_out)
    dt = period_s or stand.sample_period_s
    samples = int(round(duration_s / dt))
    speed = 0.4 * motor_in.limits.speed_rad_s if level is None else level
    if abs(speed) > motor_in.limits.speed_rad_s:
        raise InputError(f"level {speed} rad/s exceeds the input motor's speed limit "
                         f"{motor_in.limits.speed_rad_s} rad/s")
    if abs(load_current_A) > motor_out.limits.current_A:
        raise InputError(f"load current {load_current_A} A exceeds the output motor's limit "
                         f"{motor_out.limits.current_A} A")
    # Output load: 0 A and -load alternately, 8 plateaus after a settling quarter.
    plateau = np.arange(samples) * 10 // samples
    load = np.where((plateau >= 2) & (plateau % 2 == 1), -abs(load_current_A), 0.0)
    plant = ReducerPlant(
        motor_in.motor_params(), motor_out.motor_params(), stand.reducer_params(),
        motor_in.drive_params("speed"), motor_out.drive_params("current"),
        motor_in.sensor_params(), _effects(motor_in.effects, effects, replace_effects, "effects"),
        motor_out.effect_set(), seed=seed)
    return simulate_reducer(plant, [("speed", np.full(samples, speed)), ("current", load)], dt)
