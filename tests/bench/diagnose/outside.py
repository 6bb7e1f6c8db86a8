"""Effects outside the diagnosis' vocabulary, for the benchmark: plausible physics of
real stands that no vocabulary effect models, planted as a torque the simulator adds
(:attr:`stand.physics.plant.MotorPlant.extra_torque`).

None of them takes part in any tuning of the diagnosis: the rule that calls a gap
``unexplained`` is calibrated on in-vocabulary cases alone (docs/results/diagnose.md).
Each torque opposes the motor (it is subtracted from the drive torque), N·m.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np

Torque = Callable[[float, float, float, float], float]


def fan_drag(p: dict[str, float], duration_s: float) -> Torque:
    """Aerodynamic (fan) drag ``Cd·ω·|ω|``, N·m (``Cd`` in N·m·s²/rad²)."""
    cd = p["Cd"]
    return lambda theta, omega, i, t: cd * omega * abs(omega)


def kt_saturation(p: dict[str, float], duration_s: float) -> Torque:
    """Torque constant falling with current (magnetic saturation), bounded:
    ``Kt·i·(1 − α·x²/(1 + x²))`` with ``x = i/i_ref``, the loss ``Kt·α·i·x²/(1 + x²)``."""
    kt, alpha, iref = p["Kt"], p["alpha"], p["i_ref"]

    def loss(theta: float, omega: float, i: float, t: float) -> float:
        x2 = (i / iref) ** 2
        return kt * alpha * i * x2 / (1.0 + x2)

    return loss


def load_unbalance(p: dict[str, float], duration_s: float) -> Torque:
    """Gravity on an eccentric mass behind a reducer of non-integer ratio ``r``:
    ``T·sin(θ/r + φ)``, a position-periodic torque of 1/r cycles per motor revolution
    (no whole order, unlike cogging)."""
    T, r, phi = p["T"], p["ratio"], p["phi"]
    return lambda theta, omega, i, t: T * math.sin(theta / r + phi)


def kt_drift(p: dict[str, float], duration_s: float) -> Torque:
    """Torque constant drifting with the winding's temperature over the run:
    ``Kt·(1 − β·t/duration)``, the loss ``Kt·β·i·t/duration``."""
    kt, beta = p["Kt"], p["beta"]
    return lambda theta, omega, i, t: kt * beta * i * (t % duration_s) / duration_s


#: Name to the torque it plants.
OUTSIDE: dict[str, Callable[[dict[str, float], float], Torque]] = {
    "fan_drag": fan_drag, "kt_saturation": kt_saturation,
    "load_unbalance": load_unbalance, "kt_drift": kt_drift,
}


def draw_outside(name: str, rng: np.random.Generator, Kt: float, torque_ref: float,
                 current_ref: float, omega_ref: float, strength: float) -> dict[str, Any]:
    """Parameters of outside effect ``name`` whose torque is about ``strength`` times
    the run's typical drive torque ``torque_ref`` (N·m) at its typical current
    ``current_ref`` (A) and speed ``omega_ref`` (rad/s)."""
    if name == "fan_drag":
        return {"Cd": strength * torque_ref / omega_ref**2}
    if name == "kt_saturation":
        return {"Kt": Kt, "alpha": strength, "i_ref": current_ref}
    if name == "load_unbalance":
        return {"T": strength * torque_ref, "ratio": float(rng.uniform(2.2, 7.8)),
                "phi": float(rng.uniform(0, 2 * math.pi))}
    if name == "kt_drift":
        return {"Kt": Kt, "beta": 2 * strength}
    raise KeyError(name)


def outside_torque(effects: dict[str, dict[str, float]], duration_s: float) -> Torque | None:
    """The summed torque of the outside effects planted, or None."""
    parts = [OUTSIDE[name](p, duration_s) for name, p in effects.items()]
    if not parts:
        return None
    return lambda theta, omega, i, t: sum(f(theta, omega, i, t) for f in parts)
