"""Noise level of a measured signal, for excitation checks and uncertainties."""

from __future__ import annotations

import numpy as np

#: Ratio of the standard deviation to the median absolute deviation of a normal variable.
MAD_TO_SIGMA = 1.4826


def noise_sigma(signal: np.ndarray) -> float:
    """Standard deviation of the white noise on a slowly varying signal.

    Estimated robustly from the median absolute deviation of the sample-to-sample
    differences (each difference carries the noise of two samples, hence ``/√2``); steps
    and slow variation hardly affect it. In the signal's unit.
    """
    d = np.diff(np.asarray(signal, dtype=float))
    if d.size == 0:
        return 0.0
    return float(MAD_TO_SIGMA * np.median(np.abs(d - np.median(d))) / np.sqrt(2.0))
