"""Fit figures of an output-error fit: fit %, residual whiteness, confidence intervals."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import stats

#: Two-sided confidence level of the reported intervals.
CONFIDENCE = 0.95
#: Two-sided level of the autocorrelation band of the whiteness test.
WHITENESS_LEVEL = 0.99
#: Largest lag of the whiteness test, samples.
WHITENESS_MAX_LAG = 25


def fit_percent(measured: np.ndarray, simulated: np.ndarray) -> float:
    """``100·(1 − ‖y − ŷ‖ / ‖y − mean y‖)``, %: 100 is perfect, 0 is no better than the mean."""
    spread = float(np.linalg.norm(measured - np.mean(measured)))
    if spread == 0.0:
        return float("nan")
    return 100.0 * (1.0 - float(np.linalg.norm(measured - simulated)) / spread)


@dataclass(frozen=True)
class Whiteness:
    """Residual whiteness test: autocorrelation at lags 1..``lags`` against a band.

    Under white residuals each normalized autocorrelation ``r_k`` lies within
    ``±z/√N`` (``z`` for ``WHITENESS_LEVEL``) with that probability, so a few lags may
    fall outside by chance: the test passes when no more than ``allowed`` do (the
    ``WHITENESS_LEVEL`` quantile of the binomial count).

    Attributes
    ----------
    lags : int
        Lags tested.
    band : float
        Half width of the band, ``z/√N``.
    max_abs_autocorrelation : float
        Largest ``|r_k|`` over the lags.
    outside : int
        Lags outside the band.
    allowed : int
        Lags allowed outside by chance.
    ljung_box_p : float
        p-value of the Ljung-Box portmanteau statistic over the same lags.
    passed : bool
        ``outside <= allowed``.
    """

    lags: int
    band: float
    max_abs_autocorrelation: float
    outside: int
    allowed: int
    ljung_box_p: float
    passed: bool


def whiteness(residuals: np.ndarray, max_lag: int = WHITENESS_MAX_LAG) -> Whiteness:
    """Whiteness test of ``residuals`` (one channel, samples in order)."""
    e = residuals - np.mean(residuals)
    n = len(e)
    lags = max(1, min(max_lag, n // 4))
    denominator = float(e @ e) or 1.0
    r = np.array([float(e[k:] @ e[:-k]) / denominator for k in range(1, lags + 1)])
    z = float(stats.norm.ppf(0.5 + WHITENESS_LEVEL / 2))
    band = z / np.sqrt(n)
    outside = int(np.sum(np.abs(r) > band))
    allowed = int(stats.binom.ppf(WHITENESS_LEVEL, lags, 1 - WHITENESS_LEVEL))
    q = n * (n + 2) * float(np.sum(r * r / (n - np.arange(1, lags + 1))))
    return Whiteness(lags, float(band), float(np.max(np.abs(r))), outside, allowed,
                     float(stats.chi2.sf(q, lags)), outside <= allowed)


def interval(value: float | None, std: float | None, dof: int) -> list[float] | None:
    """Two-sided ``CONFIDENCE`` interval ``value ± t·std`` (Student t with ``dof``)."""
    if value is None or std is None:
        return None
    t = float(stats.t.ppf(0.5 + CONFIDENCE / 2, max(dof, 1)))
    return [value - t * std, value + t * std]
