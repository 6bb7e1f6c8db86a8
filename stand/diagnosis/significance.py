"""Is a candidate's holdout improvement more than noise? A paired test over segments.

The simulation is re-anchored to the measured state at the start of each segment
(:func:`stand.diagnosis.model.segments`), so the squared velocity errors of different
segments are nearly independent, while samples inside a segment are not. The test
therefore works on one number per segment: ``d_j = Σ e_base² − Σ e_candidate²`` over
segment ``j``, and asks whether the mean of ``d`` is above zero (one-sided paired
t-test, ``segments − 1`` degrees of freedom; a Diebold-Mariano test with blocks as the
unit). Sensor noise and encoder quantization enter both error sets alike, so a candidate
that only fits noise on TRAIN does not improve HOLDOUT and is not significant.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.special import stdtr

#: Family-wise false-alarm probability of one selection step (over all candidates).
FAMILY_ALPHA = 0.01
#: Smallest shrink of the gap that counts as explaining part of it. The paired test
#: holds sensor noise, not the nominal model's own structural error (the sampled
#: current misses the intra-sample current of a fast loop, for one): on effect-free
#: runs candidates that absorb a little of that error pass the test with shrinks of
#: 1-4 %, so a candidate must also shrink the gap by this much.
MIN_SHRINK = 0.05


@dataclass(frozen=True)
class PairedTest:
    """Result of :func:`paired_improvement`.

    Attributes
    ----------
    t : float
        t statistic of the mean per-segment improvement.
    p_value : float
        One-sided p-value (improvement > 0).
    segments : int
        Segments compared.
    shrink : float
        ``1 − sqrt(Σ cand_sse / Σ base_sse)``: the relative shrink of the RMS error.
    """

    t: float
    p_value: float
    segments: int
    shrink: float

    def significant(self, tests: int) -> bool:
        """True when ``p_value`` is below ``FAMILY_ALPHA / tests`` (Bonferroni) and the
        shrink reaches ``MIN_SHRINK``."""
        return bool(self.p_value < FAMILY_ALPHA / max(tests, 1) and self.shrink >= MIN_SHRINK)


def paired_improvement(base_sse: np.ndarray, cand_sse: np.ndarray) -> PairedTest:
    """Whether a candidate improves HOLDOUT beyond noise, on two kinds of error at once.

    Row 0 of ``base_sse`` and ``cand_sse`` holds each segment's summed squared error of
    the simulated velocity, row 1 that of the equation error (the one-step error in
    acceleration, which does not accumulate within a segment and so also sees effects
    a free run hides, e.g. friction in closed-loop data). Each row is tested on the log
    ratio of the segment errors (does a typical segment improve?); the simulated
    velocity also on their difference (does the summed error, the gap itself, fall?
    Diebold-Mariano with squared-error loss), which sees an effect that shows in a
    minority of segments only: cogging at low speed, backlash at reversals, friction
    near standstill. One segment's chance gain cannot pass it alone (it raises the
    spread with the mean). The p-value is the smallest of the three times three
    (Bonferroni); ``shrink`` is that of the simulated velocity, the gap of CONTRACT §3.
    """
    base = np.atleast_2d(np.asarray(base_sse, dtype=float))
    cand = np.atleast_2d(np.asarray(cand_sse, dtype=float))
    tests = [_log_ratio_test(b, c) for b, c in zip(base, cand, strict=True)]
    tests.append(_difference_test(base[0], cand[0]))
    best = min(tests, key=lambda t: t.p_value)
    return PairedTest(t=best.t, p_value=min(1.0, len(tests) * best.p_value),
                      segments=best.segments, shrink=tests[0].shrink)


_TINY = 1e-300


def _log_ratio_test(base: np.ndarray, cand: np.ndarray) -> PairedTest:
    """One-sided paired t-test that ``cand`` is below ``base`` per segment (log ratio)."""
    d = np.log(np.maximum(base, _TINY)) - np.log(np.maximum(cand, _TINY))
    return _t_test(d, base, cand)


def _difference_test(base: np.ndarray, cand: np.ndarray) -> PairedTest:
    """One-sided paired t-test that the summed squared error falls (the difference)."""
    return _t_test(base - cand, base, cand)


def _t_test(d: np.ndarray, base: np.ndarray, cand: np.ndarray) -> PairedTest:
    """One-sided t-test that the mean of the per-segment improvements ``d`` is above 0."""
    shrink = 1.0 - float(np.sqrt(np.sum(cand) / max(np.sum(base), _TINY)))
    n = d.size
    spread = float(np.std(d, ddof=1)) if n > 1 else 0.0
    mean = float(np.mean(d))
    if n < 2 or spread == 0.0:
        t = np.inf if mean > 0 else -np.inf if mean < 0 else 0.0
        return PairedTest(t=t, p_value=0.0 if mean > 0 else 1.0, segments=n, shrink=shrink)
    t = mean / (spread / np.sqrt(n))
    return PairedTest(t=float(t), p_value=float(stdtr(n - 1, -t)), segments=n,
                      shrink=shrink)
