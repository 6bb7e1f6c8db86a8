"""Noise level of a measured signal, for excitation checks and uncertainties."""

from __future__ import annotations

import numpy as np

#: Ratio of the standard deviation to the median absolute deviation of a normal variable.
MAD_TO_SIGMA = 1.4826
#: Least relative uncertainty of a noise variance read off a median absolute deviation
#: (its sampling error over a few thousand samples is a few %).
MIN_VARIANCE_UNCERTAINTY = 0.05


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



def noise_variance_uncertainty(signal: np.ndarray) -> float:
    """Relative uncertainty of ``noise_sigma(signal)**2``.

    White noise gives the same variance from the first differences (each carrying
    ``2σ²``) and from the second differences (``6σ²``); a signal that moves between
    samples, or noise that is not white, makes them disagree. Returns their relative
    difference, at least :data:`MIN_VARIANCE_UNCERTAINTY`.
    """
    x = np.asarray(signal, dtype=float)
    first = noise_sigma(x)
    d2 = np.diff(x, 2)
    if d2.size == 0 or first == 0.0:
        return 1.0
    second = MAD_TO_SIGMA * float(np.median(np.abs(d2 - np.median(d2)))) / np.sqrt(6.0)
    return max(MIN_VARIANCE_UNCERTAINTY, abs(first**2 - second**2) / first**2)
