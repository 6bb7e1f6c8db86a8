"""Whole runs from a plant and a command sequence: the direct simulation of a stand.

The sample at ``time_s[k]`` is read before ``command[k]`` is applied for one period, as
a SYNC-triggered drive does (read, then actuate).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from stand.errors import InputError
from stand.physics.plant import MotorPlant
from stand.physics.reducer import ReducerPlant
from stand.runfile import CURRENT_MEAN_COLUMN, Run, check_columns


def _commands(commands: Sequence[tuple[str, np.ndarray]], ports: int) -> int:
    if len(commands) != ports:
        raise InputError(f"commands: the plant has {ports} port(s), got {len(commands)}")
    lengths = {len(np.asarray(values)) for _, values in commands}
    if len(lengths) != 1:
        raise InputError(f"commands: every port needs the same number of samples, got {lengths}")
    return lengths.pop()


def simulate_motor(plant: MotorPlant, mode: str, command: np.ndarray, dt_s: float,
                   current_mean: bool = False) -> Run:
    """Run ``plant`` through ``command`` (one value a sample, in ``mode``'s unit);
    ``current_mean``: the drive also reports its current averaged over each period
    (column ``current_mean_A``).

    Returns
    -------
    Run
        Single-motor run: ``time_s``, ``current_A``, ``position_rad``, ``voltage_V``,
        ``velocity_rad_s`` (and ``speed_target_rad_s`` in speed mode, and
        ``current_mean_A`` with ``current_mean``);
        ``meta['true_velocity_rad_s']`` and ``meta['true_current_A']`` hold the
        unmeasured truth.
    """
    n = _commands([(mode, command)], 1)
    out = np.empty((5, n))
    truth = np.empty((2, n))
    for k, target in enumerate(np.asarray(command, dtype=float)):
        m = plant.measure(dt_s)
        out[:, k] = (m.current_A, m.position_rad, m.voltage_V, m.velocity_rad_s,
                     m.current_mean_A)
        truth[:, k] = (plant.omega, plant.armature.i)
        plant.command(mode, target)
        plant.advance(dt_s)
    columns = {
        "time_s": np.arange(n) * dt_s,
        "current_A": out[0], "position_rad": out[1],
        "voltage_V": out[2], "velocity_rad_s": out[3],
    }
    if current_mean:
        columns[CURRENT_MEAN_COLUMN] = out[4]
    if mode == "speed":  # the target held over the period after each sample
        columns["speed_target_rad_s"] = np.asarray(command, dtype=float)
    run = check_columns(columns, "single", "<simulated>")
    run.meta.update(true_velocity_rad_s=truth[0], true_current_A=truth[1])
    return run


def simulate_reducer(plant: ReducerPlant, commands: Sequence[tuple[str, np.ndarray]],
                     dt_s: float) -> Run:
    """Run the two-motor stand; ``commands`` is ``[(mode_in, values), (mode_out, values)]``."""
    n = _commands(commands, 2)
    (mode_in, values_in), (mode_out, values_out) = commands
    out = np.empty((6, n))
    for k in range(n):
        a, b = plant.measure(dt_s, 0), plant.measure(dt_s, 1)
        out[:, k] = (a.current_A, a.position_rad, b.current_A, b.position_rad,
                     a.voltage_V, b.voltage_V)
        plant.command(mode_in, float(values_in[k]), 0)
        plant.command(mode_out, float(values_out[k]), 1)
        plant.advance(dt_s)
    return check_columns({
        "time_s": np.arange(n) * dt_s,
        "current_in_A": out[0], "position_in_rad": out[1],
        "current_out_A": out[2], "position_out_rad": out[3],
        "voltage_in_V": out[4], "voltage_out_V": out[5],
    }, "reducer", "<simulated>")
