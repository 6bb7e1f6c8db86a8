"""Simulated voltage-step runs from a motor profile (stand.physics), for tests and benches.

The motor runs on its profile's drive in voltage mode; the run keeps the columns of a
step run file (CONTRACT §1): ``time_s``, ``voltage_V``, ``velocity_rad_s`` and, when
asked, ``current_A``. The physics saturates the voltage at the drive's supply and
reports the voltage it applied.
"""

from __future__ import annotations

import numpy as np

from stand.errors import InputError
from stand.physics.plant import MotorPlant
from stand.physics.simulate import simulate_motor
from stand.profiles import load_motor
from stand.runfile import Run, check_columns

#: Fraction of the run before the step, so the record starts at rest.
PRE_STEP_FRACTION = 0.05


def step_voltages(samples: int, levels: list[float]) -> np.ndarray:
    """A staircase: 0 V for the first 5 %, then ``levels`` in equal parts, V."""
    if not levels:
        raise InputError("levels: give at least one step voltage")
    command = np.zeros(samples)
    first = int(round(PRE_STEP_FRACTION * samples))
    parts = np.array_split(np.arange(first, samples), len(levels))
    for level, part in zip(levels, parts, strict=True):
        command[part] = level
    return command


def simulate_step_run(profile: str, levels: list[float], duration_s: float,
                      with_current: bool = True, seed: int | None = None,
                      dt_s: float | None = None, effects: bool = True) -> Run:
    """A step run of the motor of ``profile`` (name or YAML path).

    Parameters
    ----------
    profile : str
        Motor profile.
    levels : list of float
        Step voltages, V, each held for an equal share of the run after 5 % at 0 V.
    duration_s : float
        Length of the run, s.
    with_current : bool
        Keep the measured current column.
    seed : int or None
        Seed of the sensor noise.
    dt_s : float or None
        Sample period, s (default: the profile's).
    effects : bool
        Include the profile's effects (friction, cogging, ...).
    """
    spec = load_motor(profile)
    dt = dt_s or spec.sample_period_s
    command = step_voltages(int(round(duration_s / dt)), levels)
    plant = MotorPlant(spec.motor_params(), spec.drive_params("voltage"), spec.sensor_params(),
                       spec.effect_set() if effects else None, seed=seed)
    run = simulate_motor(plant, "voltage", command, dt)
    names = ["time_s", "voltage_V", "velocity_rad_s"] + (["current_A"] if with_current else [])
    step = check_columns({name: run[name] for name in names}, "step", f"<simulated {spec.name}>")
    step.meta.update(run.meta)
    return step
