"""A drag continuous through zero speed, ``tanh(ω/ω_d)``: its column in the fit.

Not a vocabulary effect: the competitor a dry friction verdict meets (:mod:`.drag`).
Dry friction jumps with the sign of the speed; a drag that an eddy-current brake, a
fluid coupling or a seal's film makes grows from zero with the speed and levels off.
Like the friction columns (:func:`stand.diagnosis.dry_friction.period_mean`) it is the
mean over the period after each sample, the speed moving linearly between the samples.
"""

from __future__ import annotations

import numpy as np


def _log_cosh(x: np.ndarray) -> np.ndarray:
    """``log(cosh(x))``, without overflow."""
    return np.asarray(np.logaddexp(x, -x) - np.log(2.0))


def drag_mean(speed: np.ndarray, ws: float) -> np.ndarray:
    """Mean of ``tanh(ω/ω_d)`` (``ws``: ``ω_d``, rad/s) over the period after each
    sample, the speed moving linearly from ``speed[n]`` to ``speed[n + 1]`` (rad/s; the
    last period holds its speed): ``ω_d·Δ log cosh(ω/ω_d) / Δω``."""
    start = speed
    end = np.concatenate([speed[1:], speed[-1:]])
    span = end - start
    moved = np.abs(span) > 1e-9 * ws
    rise = ws * (_log_cosh(end / ws) - _log_cosh(start / ws))
    return np.asarray(np.where(moved, rise / np.where(moved, span, 1.0), np.tanh(start / ws)))


__all__ = ["drag_mean"]
