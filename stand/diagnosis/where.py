"""Where the gap lies: the nominal model's holdout residual analysed five ways.

The residual analysed is the equation error of the nominal model on HOLDOUT (the torque
per unit inertia the model misses, rad/s², filtered signals): unlike the simulated
velocity error it is not smeared over the re-anchoring segment, so it points at the
instant and the state where the model is wrong.

* by regime: mean squared residual in each regime over the overall mean; the regime
  with the largest ratio is reported when it stands out, else ``everywhere``;
* against position: the amplitude spectrum of the residual over the position, in
  cycles per revolution (orders 1 .. ``MAX_ORDER``), against the level of the other
  orders;
* against velocity and its sign: regime ratios for positive and negative velocity;
* in frequency: the band holding the central half of the residual's energy (Welch);
* against the input: the lag of the largest cross-correlation with the current.
"""

from __future__ import annotations

import math

import numpy as np

from stand.diagnosis.report import Where
from stand.diagnosis.signals import Signals, correlation_time, power_spectral_density

REGIMES: tuple[str, ...] = ("low_speed", "reversal", "high_speed", "acceleration", "steady")
#: Speeds below this fraction of the 95th-percentile speed count as low speed.
LOW_SPEED_FRACTION = 0.1
#: Speeds above this fraction of it count as high speed.
HIGH_SPEED_FRACTION = 0.6
#: Half width of the window around a velocity reversal, s.
REVERSAL_WINDOW_S = 0.02
#: Accelerations above this quantile of |acceleration| count as acceleration.
ACCEL_QUANTILE = 0.8
#: Accelerations below this quantile (and not low speed) count as steady.
STEADY_QUANTILE = 0.3
#: A regime must hold this share of the samples to be reported.
MIN_REGIME_SHARE = 0.03
#: A regime is reported when its energy ratio exceeds the runner-up ``everywhere`` level.
REGIME_RATIO = 1.5
#: Orders searched against position, cycles per revolution.
MAX_ORDER = 60
#: A position order is reported when its amplitude exceeds the median order by this
#: factor (the median amplitude estimates the noise level of a single order).
ORDER_PEAK_FACTOR = 4.0
#: A lag is reported when the correlation exceeds this many standard errors.
LAG_SIGMAS = 4.0
#: Longest lag searched, s.
MAX_LAG_S = 0.05


def regime_masks(sig: Signals) -> dict[str, np.ndarray]:
    """Boolean masks of the regimes of CONTRACT §3 on ``sig``."""
    speed = np.abs(sig.omega_f)
    top = sig.top_speed or 1.0
    accel = np.abs(sig.accel_f)
    low = speed < LOW_SPEED_FRACTION * top
    sign = np.sign(sig.omega_f)
    flips = np.flatnonzero(sign[1:] * sign[:-1] < 0)
    reversal = np.zeros(len(sig), dtype=bool)
    half = max(1, int(round(REVERSAL_WINDOW_S / sig.dt_s)))
    for k in flips:
        reversal[max(0, k - half):k + half + 1] = True
    return {
        "low_speed": low,
        "reversal": reversal,
        "high_speed": speed > HIGH_SPEED_FRACTION * top,
        "acceleration": accel > np.quantile(accel, ACCEL_QUANTILE),
        "steady": (accel < np.quantile(accel, STEADY_QUANTILE)) & ~low,
    }


def _order(residual: np.ndarray, theta: np.ndarray, max_order: int) -> int | None:
    orders = np.arange(1, max_order + 1)
    angle = np.outer(orders, theta)
    centred = residual - residual.mean()
    amplitude = np.hypot(np.cos(angle) @ centred, np.sin(angle) @ centred) / len(residual)
    if orders.size < 5:
        return None
    best = int(np.argmax(amplitude))
    return int(orders[best]) if amplitude[best] > ORDER_PEAK_FACTOR * np.median(amplitude) else None


def _band(residual: np.ndarray, dt_s: float) -> list[float]:
    freq, power = power_spectral_density(residual, dt_s, min(1024, len(residual)))
    cumulative = np.cumsum(power)
    cumulative /= cumulative[-1]
    low = float(freq[np.searchsorted(cumulative, 0.25)])
    high = float(freq[min(int(np.searchsorted(cumulative, 0.75)), len(freq) - 1)])
    return [low, high]


def _lag(residual: np.ndarray, current: np.ndarray, dt_s: float) -> float | None:
    r = residual - residual.mean()
    i = current - current.mean()
    scale = float(np.sqrt(np.sum(r * r) * np.sum(i * i)))
    if scale == 0.0:
        return None
    max_lag = max(1, int(round(MAX_LAG_S / dt_s)))
    lags = np.arange(-max_lag, max_lag + 1)
    n = len(r)
    corr = np.array([np.sum(r[max(0, int(k)):n + min(0, int(k))]
                            * i[max(0, -int(k)):n - max(0, int(k))]) for k in lags]) / scale
    best = int(np.argmax(np.abs(corr)))
    # Standard error of a correlation of two coloured series: 1/sqrt(effective samples).
    effective = n / max(1.0, correlation_time(r) * correlation_time(i))
    if abs(corr[best]) < LAG_SIGMAS / math.sqrt(effective):
        return None
    return float(lags[best] * dt_s)


def locate(residual: np.ndarray, sig: Signals) -> Where:
    """Where the residual of the nominal model on ``sig`` lies."""
    energy = residual**2
    mean = float(np.mean(energy)) or 1.0
    ratios: dict[str, float] = {}
    for name, mask in regime_masks(sig).items():
        if mask.mean() >= MIN_REGIME_SHARE:
            ratios[name] = float(np.mean(energy[mask]) / mean)
    regime = "everywhere"
    if ratios:
        best = max(ratios, key=lambda k: ratios[k])
        if ratios[best] > REGIME_RATIO:
            regime = best
    by_sign = {}
    for name, mask in (("positive", sig.omega_f > 0), ("negative", sig.omega_f < 0)):
        if mask.any():
            by_sign[name] = float(np.mean(energy[mask]) / mean)
    by_current = {}
    level = np.abs(sig.current)
    low, high = np.quantile(level, [1 / 3, 2 / 3])
    for name, mask in (("low", level <= low), ("middle", (level > low) & (level <= high)),
                       ("high", level > high)):
        if mask.any():
            by_current[name] = float(np.mean(energy[mask]) / mean)
    max_order = MAX_ORDER
    if sig.quant_rad > 0:
        max_order = max(1, min(MAX_ORDER, int(2 * math.pi / sig.quant_rad // 16)))
    return Where(regime=regime, cycles_per_rev=_order(residual, sig.theta_f, max_order),
                 band_hz=_band(residual, sig.dt_s), lag_s=_lag(residual, sig.current, sig.dt_s),
                 regime_energy=ratios, velocity_sign_energy=by_sign,
                 current_level_energy=by_current)
