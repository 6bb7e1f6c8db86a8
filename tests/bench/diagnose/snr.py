"""Signal-to-noise ratio of a planted effect (benchmark answer key only).

How much an effect shows on a stand is a property of the stand, not of any diagnosis:
this module measures it with the TRUE plant. The exact nominal model (the true ``J``
(plus a backlash load), ``D`` and ``Kt``, no effect) is driven by the run's measured
current and re-anchored to the TRUE shaft speed every ``horizon_s`` (the diagnosis
re-anchors on the same horizon, from the measured positions: it has no true speed);
its error against the measured speed (central difference of the measured position) is
the gap a perfect nominal model leaves. On the same command,
sensor noise and seed without the effect, that gap is noise and quantization alone
(``g0``); with the effect it is ``g1``. The effect's SNR is the RMS the effect adds over
the noise, relative to the noise::

    SNR = sqrt(max(g1² − g0², 0)) / g0

An effect with SNR < 1 changes the holdout speed less than the sensors' own noise does:
no diagnosis can be expected to name it, and it does not make a sim-to-real gap that a
user would see. Nothing here is used by the diagnosis; the engine never sees the truth.
"""

from __future__ import annotations

import math

import numpy as np

from stand.diagnosis.model import interval_current
from stand.runfile import Run

#: Input reconstructions tried for the exact nominal model (the best one on the
#: effect-free run is used for both runs; see ``ModelSpec.input_weight``).
WEIGHTS: tuple[float, ...] = (0.5, 0.75, 1.0)


def nominal_gap(run: Run, J: float, D: float, Kt: float, horizon_s: float,
                weight: float) -> float:
    """RMS error (rad/s) of the exact nominal model on ``run`` against its measured
    speed, re-anchored to the true speed (``run.meta['true_velocity_rad_s']``)."""
    dt = run.dt_s
    current = interval_current(np.asarray(run["current_A"], dtype=float), weight)
    true_speed = np.asarray(run.meta["true_velocity_rad_s"], dtype=float)
    measured = np.gradient(np.asarray(run["position_rad"], dtype=float), dt)
    horizon = max(1, int(round(horizon_s / dt)))
    count = len(current) // horizon
    drive = current[: count * horizon].reshape(count, horizon)
    decay = math.exp(-D * dt / J)
    gain = (1.0 - decay) * Kt / D if D > 0 else Kt * dt / J
    speed = true_speed[: count * horizon : horizon].copy()
    simulated = np.empty((count, horizon))
    for k in range(horizon):  # exact discretization of J·ω' + D·ω = Kt·i, all segments at once
        simulated[:, k] = speed
        speed = decay * speed + gain * drive[:, k]
    error = (simulated.ravel() - measured[: count * horizon])[1:-1]
    return float(np.sqrt(np.mean(error**2)))


def effect_snr(with_effect: Run, without_effect: Run, J: float, J_with: float, D: float,
               Kt: float, horizon_s: float) -> float:
    """SNR of the effect that makes ``with_effect`` differ from ``without_effect`` (the
    same command, sensors and seed). ``J_with`` is the rigid inertia of the stand with
    the effect (``J`` plus a backlash load), ``J`` the motor's."""
    noise_gaps = {w: nominal_gap(without_effect, J, D, Kt, horizon_s, w) for w in WEIGHTS}
    weight = min(noise_gaps, key=noise_gaps.__getitem__)
    g0 = noise_gaps[weight]
    g1 = nominal_gap(with_effect, J_with, D, Kt, horizon_s, weight)
    if g0 == 0.0:
        return math.inf if g1 > 0 else 0.0
    return math.sqrt(max(g1**2 - g0**2, 0.0)) / g0


__all__ = ["effect_snr", "nominal_gap"]
