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
user would see. A member of a pair counts by what it adds beside the other
(:func:`added_snr`). Nothing here is used by the diagnosis; the engine never sees the
truth.
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
    return float(np.sqrt(np.mean(nominal_error(run, J, D, Kt, horizon_s, weight) ** 2)))


def nominal_error(run: Run, J: float, D: float, Kt: float, horizon_s: float,
                  weight: float, against_true: bool = False) -> np.ndarray:
    """The error (rad/s) whose RMS is :func:`nominal_gap`, sample by sample;
    ``against_true``: against the true speed instead of the measured one (the error
    free of quantization)."""
    dt = run.dt_s
    current = interval_current(np.asarray(run["current_A"], dtype=float), weight)
    true_speed = np.asarray(run.meta["true_velocity_rad_s"], dtype=float)
    measured = (true_speed if against_true
                else np.gradient(np.asarray(run["position_rad"], dtype=float), dt))
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
    return (simulated.ravel() - measured[: count * horizon])[1:-1]


def _noise_gap(without_effects: Run, J: float, D: float, Kt: float,
               horizon_s: float) -> tuple[float, float]:
    """The noise gap ``g0`` of the effect-free run and the input weight that gives it
    (the best of :data:`WEIGHTS`)."""
    noise_gaps = {w: nominal_gap(without_effects, J, D, Kt, horizon_s, w) for w in WEIGHTS}
    weight = min(noise_gaps, key=noise_gaps.__getitem__)
    return noise_gaps[weight], weight


def effect_snr(with_effect: Run, without_effect: Run, J: float, J_with: float, D: float,
               Kt: float, horizon_s: float) -> float:
    """SNR of the effect that makes ``with_effect`` differ from ``without_effect`` (the
    same command, sensors and seed). ``J_with`` is the rigid inertia of the stand with
    the effect (``J`` plus a backlash load), ``J`` the motor's."""
    g0, weight = _noise_gap(without_effect, J, D, Kt, horizon_s)
    g1 = nominal_gap(with_effect, J_with, D, Kt, horizon_s, weight)
    if g0 == 0.0:
        return math.inf if g1 > 0 else 0.0
    return math.sqrt(max(g1**2 - g0**2, 0.0)) / g0


def added_snr(with_effect: Run, beside: Run, without_effects: Run, J_with: float,
              J_beside: float, J: float, D: float, Kt: float, horizon_s: float) -> float:
    """SNR of what an effect adds beside another: ``with_effect`` has both, ``beside``
    the other alone, ``without_effects`` neither (the same command, sensors and seed);
    ``J_with``, ``J_beside`` and ``J`` are the three stands' rigid inertias (the motor's
    plus a backlash load's).

    It is the RMS of the change the effect makes to the exact nominal model's error
    against the true speed, ``e_with − e_beside``, over the noise gap ``g0``. Not
    ``sqrt(g1² − g_beside²)``, as :func:`effect_snr` has it beside no effect: beside a
    strong effect whose error the added one partly cancels, that difference of squares
    reads 0 for an effect that clearly shows. Not against the measured speed either:
    the slightest change of the motion draws the encoder's quantization anew, and
    their difference would be noise of the size of ``g0``."""
    g0, weight = _noise_gap(without_effects, J, D, Kt, horizon_s)
    change = (nominal_error(with_effect, J_with, D, Kt, horizon_s, weight, True)
              - nominal_error(beside, J_beside, D, Kt, horizon_s, weight, True))
    rms = float(np.sqrt(np.mean(change**2)))
    if g0 == 0.0:
        return math.inf if rms > 0 else 0.0
    return rms / g0


__all__ = ["added_snr", "effect_snr", "nominal_error", "nominal_gap"]
