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


def second_difference_sigma(signal: np.ndarray) -> float:
    """Standard deviation of the white noise on a signal, read off the median absolute
    deviation of its second differences (each carrying ``6σ²`` of white noise); the
    steps of a command and a smooth motion barely move it. In the signal's unit; 0 for
    fewer than three samples."""
    d2 = np.diff(np.asarray(signal, dtype=float), 2)
    if d2.size == 0:
        return 0.0
    return float(MAD_TO_SIGMA * np.median(np.abs(d2 - np.median(d2))) / np.sqrt(6.0))


def noise_variance_uncertainty(signal: np.ndarray) -> float:
    """Relative uncertainty of ``noise_sigma(signal)**2``.

    White noise gives the same variance from the first differences (each carrying
    ``2σ²``) and from the second differences (``6σ²``); a signal that moves between
    samples, or noise that is not white, makes them disagree. Returns their relative
    difference, at least :data:`MIN_VARIANCE_UNCERTAINTY`.
    """
    x = np.asarray(signal, dtype=float)
    first = noise_sigma(x)
    if x.size < 3 or first == 0.0:
        return 1.0
    second = second_difference_sigma(x)
    return max(MIN_VARIANCE_UNCERTAINTY, abs(first**2 - second**2) / first**2)


#: The passband noise is read in octave bands from this many times the kernel's cutoff
#: up to the Nyquist frequency (below it the run's own signal fills the spectrum).
PASSBAND_START = 4.0
#: Bands within this many standard errors of the least band level are pooled with it.
POOL_SE = 2.0
#: Fewest spectral lines in a band for its level to count.
MIN_BAND_LINES = 4


def passband_noise(signal: np.ndarray, dt_s: float, cutoff_hz: float) -> tuple[float, float]:
    """Variance of white noise that puts into a low-pass of cutoff ``cutoff_hz`` what the
    noise of ``signal`` puts there, and its relative uncertainty.

    Coloured noise (most of its power at high frequencies, as a PWM-driven current shows)
    makes :func:`noise_sigma` (from sample-to-sample differences, which weigh the highest
    frequencies) overstate what passes a long kernel. The spectrum (Welch, segments of at
    least 8 kernel lengths) is read in octave bands from ``PASSBAND_START`` times the
    cutoff up to the Nyquist frequency; the run's signal only adds to a band, so the least
    band level is the noise level nearest to the passband that the data show. The least
    of several noisy band means is biased low, so the bands within ``POOL_SE`` standard
    errors of it (all of them for white noise) are pooled, weighted by their lines. A
    white level ``P`` (one-sided, per Hz) is the variance ``P/(2Δt)``. The uncertainty is
    the sampling error of the pooled mean, ``1/√(lines·segments)``, at least
    :data:`MIN_VARIANCE_UNCERTAINTY`. Falls back to :func:`noise_sigma` (and 1) when the
    run is too short to resolve a band.
    """
    from scipy.signal import welch

    x = np.asarray(signal, dtype=float)
    fs = 1.0 / dt_s
    segment = int(2 ** np.ceil(np.log2(max(16.0, 8.0 * fs / max(cutoff_hz, 1e-12)))))
    segment = min(segment, len(x))
    freq, psd = welch(x, fs=fs, nperseg=segment, detrend="linear")
    segments = max(1, 2 * len(x) // segment - 1)
    levels: list[tuple[float, int]] = []
    low = PASSBAND_START * cutoff_hz
    while low < fs / 2:
        band = (freq >= low) & (freq < 2 * low)
        if int(np.sum(band)) >= MIN_BAND_LINES:
            levels.append((float(np.mean(psd[band])), int(np.sum(band))))
        low *= 2
    if not levels:
        return noise_sigma(x) ** 2, 1.0
    least, lines = min(levels)
    ceiling = least * (1.0 + POOL_SE / np.sqrt(lines * segments))
    pooled = [(level, n) for level, n in levels if level <= ceiling]
    total = sum(n for _, n in pooled)
    level = sum(level * n for level, n in pooled) / total
    return (level * fs / 2.0,
            max(MIN_VARIANCE_UNCERTAINTY, 1.0 / float(np.sqrt(total * segments))))
