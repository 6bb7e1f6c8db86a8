"""Excitation signals for identification runs (seed 000 §4.1: white noise; PRBS; steps).

Each returns one command value a sample; ``hold`` keeps each random value for that many
samples (zero-order hold), which sets the bandwidth of the excitation.
"""

from __future__ import annotations

import numpy as np

from stand.errors import InputError

EXCITATIONS: tuple[str, ...] = ("prbs", "noise", "step", "steps", "constant", "sine")


def excitation(kind: str, samples: int, dt_s: float, level: float, amplitude: float,
               hold: int = 10, step_time_s: float = 0.0, seed: int | None = None) -> np.ndarray:
    """A command sequence of ``samples`` values.

    Parameters
    ----------
    kind : {'prbs', 'noise', 'step', 'steps', 'constant', 'sine'}
        ``prbs``: level ± amplitude, random sign; ``noise``: level + amplitude·N(0, 1);
        ``step``: 0 before ``step_time_s``, level after; ``steps``: level, with
        level + amplitude on alternate quarters; ``constant``: level; ``sine``: level +
        amplitude·sin at 1/(hold·dt) Hz / 10.
    samples : int
        Number of samples.
    dt_s : float
        Sample period, s.
    level, amplitude : float
        Mean level and excursion, in the command's unit.
    hold : int
        Samples each random value is held.
    step_time_s : float
        Time of the step for ``step``, s.
    seed : int or None
        Seed of the random sequence.
    """
    if kind not in EXCITATIONS:
        raise InputError(f"excitation must be one of {', '.join(EXCITATIONS)}, not {kind!r}")
    if samples < 1 or hold < 1:
        raise InputError(f"samples and hold must be >= 1, got {samples} and {hold}")
    rng = np.random.default_rng(seed)
    values: np.ndarray
    draws = -(-samples // hold)
    if kind == "prbs":
        values = level + amplitude * np.repeat(rng.choice([-1.0, 1.0], draws), hold)[:samples]
    elif kind == "noise":
        values = level + amplitude * np.repeat(rng.standard_normal(draws), hold)[:samples]
    elif kind == "step":
        values = np.where(np.arange(samples) * dt_s >= step_time_s, level, 0.0)
    elif kind == "steps":
        quarter = np.arange(samples) * 4 // samples
        values = level + amplitude * (quarter % 2)
    elif kind == "sine":
        frequency_hz = 0.1 / (hold * dt_s)
        values = level + amplitude * np.sin(2 * np.pi * frequency_hz * np.arange(samples) * dt_s)
    else:
        values = np.full(samples, float(level))
    return np.asarray(values, dtype=float)
