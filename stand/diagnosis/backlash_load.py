"""The load behind a backlash gap, estimated from the motor's measured motion.

A free load coasts inside the gap and is struck by the motor at either edge (the motor
taken as the heavier side, its measured motion given). The fit and the free-run
simulation of a backlash model both use it (:func:`load_state`, cached on the signals).
"""

from __future__ import annotations

import numpy as np

from stand.diagnosis.signals import Signals


def load_estimate(theta: np.ndarray, omega: np.ndarray, gap: float, dt_s: float,
                  restitution: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """Kinematic estimate of a free load behind a dead zone of ± ``gap`` rad.

    The load coasts at constant speed inside the gap. When the motor reaches either
    edge the load is struck by the motor (taken as the heavier side, its measured
    motion given): with ``restitution`` 0 it is carried along (inelastic contact), with
    ``e > 0`` it rebounds from the motor, ``ω_l ← ω + e·(ω − ω_l)``. Returns load
    position (rad) and velocity (rad/s) at each sample.
    """
    if restitution == 0.0:
        return _carried_load(theta, omega, gap, dt_s)
    n = len(theta)
    theta_l = np.empty(n)
    omega_l = np.empty(n)
    tl, wl = float(theta[0]), float(omega[0])
    th = theta.tolist()
    om = omega.tolist()
    e = restitution
    for k in range(n):
        tl += wl * dt_s if k else 0.0
        twist = th[k] - tl
        if twist > gap:
            tl = th[k] - gap
            wl = om[k] + e * (om[k] - wl) if wl < om[k] else om[k]
        elif twist < -gap:
            tl = th[k] + gap
            wl = om[k] + e * (om[k] - wl) if wl > om[k] else om[k]
        theta_l[k] = tl
        omega_l[k] = wl
    return theta_l, omega_l


def _carried_load(theta: np.ndarray, omega: np.ndarray, gap: float, dt_s: float
                  ) -> tuple[np.ndarray, np.ndarray]:
    """:func:`load_estimate` with restitution 0, the same arithmetic sample by sample.

    A load carried at one sample is carried at the next while the motor, at its edge
    of the gap, keeps ahead of the load coasting on at its speed; whether it does is
    known in advance for every sample, so a stretch of contact is filled at once and
    only the samples in between are stepped one by one."""
    n = len(theta)
    theta_l, omega_l = np.empty(n), np.empty(n)
    # after contact at sample k - 1 on the side of ±gap, is there contact at k on it?
    pushed_on = np.flatnonzero(~(theta[1:] - ((theta[:-1] - gap) + omega[:-1] * dt_s) > gap))
    pulled_on = np.flatnonzero(~(theta[1:] - ((theta[:-1] + gap) + omega[:-1] * dt_s) < -gap))
    th, om = theta.tolist(), omega.tolist()
    tl, wl = th[0], om[0]
    theta_l[0], omega_l[0] = tl, wl
    k = 1
    while k < n:
        tl += wl * dt_s
        twist = th[k] - tl
        side = 1.0 if twist > gap else -1.0 if twist < -gap else 0.0
        if side:
            tl, wl = th[k] - side * gap, om[k]
        theta_l[k], omega_l[k] = tl, wl
        if not side:
            k += 1
            continue
        ends = pushed_on if side > 0 else pulled_on
        at = int(np.searchsorted(ends, k))
        last = int(ends[at]) if at < len(ends) else n - 1  # the last sample in contact
        theta_l[k + 1:last + 1] = theta[k + 1:last + 1] - side * gap
        omega_l[k + 1:last + 1] = omega[k + 1:last + 1]
        tl, wl = float(theta_l[last]), float(omega_l[last])
        k = last + 1
    return theta_l, omega_l


def load_state(sig: Signals, gap: float, restitution: float) -> np.ndarray:
    """:func:`load_estimate` on the filtered motion of ``sig``, rows load position (rad)
    and load velocity (rad/s); cached on ``sig`` (the fit and the simulation of a
    backlash model both need it)."""
    key = ("load_state", gap, restitution)
    if key not in sig.cache:
        sig.cache[key] = np.stack(load_estimate(sig.theta_f, sig.omega_f, gap, sig.dt_s,
                                                restitution))
    return sig.cache[key]
