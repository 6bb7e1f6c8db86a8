"""Equation-error start: the transfer-function coefficients by linear least squares.

Integrating ``ω'' + a1·ω' + a0·ω = b0·v`` twice from the start of a run gives an equation
linear in the coefficients that needs no derivative of the noisy measurement::

    ω(t) = −a1·∫ω − a0·∫∫ω + b0·∫∫v + e0 + e1·t

(``e0``, ``e1`` carry the unknown initial state of each run). With the current,
``i = −a1·∫i − a0·∫∫i + c1·∫v + c0·∫∫v + d0 + d1·t`` shares ``a1`` and ``a0``. All runs
and both equations are stacked, each equation weighted by its noise level, and solved
once. Integration averages the noise, so the estimate is close enough for the nonlinear
output-error fit to start from, with no hand-tuned starting point.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from scipy.integrate import cumulative_trapezoid

from stand.errors import NotExcitedError
from stand.ident.noise import second_difference_sigma
from stand.stepid.model import StepData

#: A speed range beyond this many noise standard deviations counts as a response.
EXCITED_NOISE_MULTIPLE = 10.0
#: Weight of the equation of a channel whose noise cannot be estimated (noise-free data).
NOISE_FLOOR_FRACTION = 1e-6


def noise_level(values: np.ndarray) -> float:
    """Robust white-noise standard deviation of a smooth signal, in its unit.

    The median absolute deviation of second differences, scaled for Gaussian noise
    (``Δ²`` of white noise has variance ``6·σ²``); steps affect only a few samples.
    """
    sigma = second_difference_sigma(values)
    floor = NOISE_FLOOR_FRACTION * max(float(np.max(np.abs(values))), 1e-12)
    return max(sigma, floor)


def _excited(run: StepData) -> bool:
    """A voltage change, or a speed that moves beyond its noise (a run from a step instant)."""
    speed = run.velocity_rad_s
    return bool(np.ptp(run.voltage_V) > 0
                or np.ptp(speed) > EXCITED_NOISE_MULTIPLE * noise_level(speed))


def _voltage_integral(data: StepData, hold: str) -> np.ndarray:
    """Exact integral of the held voltage from the first sample, V·s."""
    v = data.voltage_V
    held = v[1:] if hold == "preceding" else v[:-1]
    return np.concatenate([[0.0], np.cumsum(held) * data.dt_s])


def equation_error(data: Sequence[StepData], use_current: bool, hold: str) -> np.ndarray:
    """Coefficients ``(b0, a1, a0[, c1, c0])`` by integral equation error.

    Raises
    ------
    NotExcitedError
        The voltage never changes or the speed does not respond.
    """
    n_runs = len(data)
    n_coef = 5 if use_current else 3
    blocks: list[np.ndarray] = []
    targets: list[np.ndarray] = []
    channels = 2 if use_current else 1
    for r, run in enumerate(data):
        t = run.time_s
        iv = _voltage_integral(run, hold)
        iiv = cumulative_trapezoid(iv, t, initial=0.0)
        for ch in range(channels):
            y = run.velocity_rad_s if ch == 0 else run.current_A
            assert y is not None  # use_current is only set when every run has current
            weight = 1.0 / noise_level(y)
            iy = cumulative_trapezoid(y, t, initial=0.0)
            iiy = cumulative_trapezoid(iy, t, initial=0.0)
            rows = np.zeros((len(t), n_coef + 2 * channels * n_runs))
            rows[:, 1], rows[:, 2] = -iy, -iiy
            if ch == 0:
                rows[:, 0] = iiv
            else:
                rows[:, 3], rows[:, 4] = iv, iiv
            offset = n_coef + 2 * (r * channels + ch)
            rows[:, offset], rows[:, offset + 1] = 1.0, t
            blocks.append(rows * weight)
            targets.append(y * weight)
    M = np.vstack(blocks)
    y_all = np.concatenate(targets)
    scale = np.linalg.norm(M, axis=0)
    if not np.all(scale[:n_coef] > 0) or not any(_excited(run) for run in data):
        raise NotExcitedError(
            "the voltage never changes and the speed stays at one level in every run; "
            "step identification needs a voltage step (or a run that starts at one)"
        )
    solution, *_ = np.linalg.lstsq(M / scale, y_all, rcond=None)
    return np.asarray(solution[:n_coef] / scale[:n_coef])
