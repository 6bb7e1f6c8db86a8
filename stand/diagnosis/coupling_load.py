"""The load behind a compliant coupling, estimated from the motor's measured motion.

A load inertia on a torsionally elastic shaft (no dead zone) follows the motor through
a second-order mode: ``θ_l'' = ωn²·(θ − θ_l) + 2ζωn·(θ' − θ_l')``, so its position is
the motor's through ``H(s) = (2ζωn·s + ωn²)/(s² + 2ζωn·s + ωn²)``, whatever the load's
inertia. The fit and the free-run simulation of such a model both use it
(:func:`coupling_state`, cached on the signals), as a backlash model uses its kinematic
load estimate (:mod:`.backlash_load`).
"""

from __future__ import annotations

import math

import numpy as np

from stand.diagnosis.signals import Signals


def coupling_filter(hz: float, zeta: float, dt_s: float) -> tuple[np.ndarray, np.ndarray]:
    """``H(s)`` of a coupling mode at ``hz`` with damping ratio ``zeta``, discretised
    (bilinear, the mode's frequency prewarped) for samples ``dt_s`` apart."""
    # imported here: a diagnosis that names no load behind the motor never needs it, and
    # its import costs more than such a diagnosis of 20 s at 1 kHz saves elsewhere
    from scipy.signal import bilinear
    wn = 2.0 * math.pi * hz
    warped = 2.0 / dt_s * math.tan(wn * dt_s / 2.0)
    b, a = bilinear([2.0 * zeta * warped, warped**2], [1.0, 2.0 * zeta * warped, warped**2],
                    fs=1.0 / dt_s)
    return np.asarray(b), np.asarray(a)


def coupling_state(sig: Signals, hz: float, zeta: float) -> np.ndarray:
    """The load's position (rad) and speed (rad/s) behind a coupling mode at ``hz``
    (damping ``zeta``), driven by the filtered motion of ``sig``; starts twisted by
    nothing. Cached on ``sig``."""
    key = ("coupling_state", hz, zeta)
    if key not in sig.cache:
        from scipy.signal import lfilter, lfilter_zi  # as in coupling_filter

        b, a = coupling_filter(hz, zeta, sig.dt_s)
        zi = lfilter_zi(b, a)
        sig.cache[key] = np.stack([
            lfilter(b, a, x, zi=zi * x[0])[0] for x in (sig.theta_f, sig.omega_f)])
    return sig.cache[key]


__all__ = ["coupling_filter", "coupling_state"]
