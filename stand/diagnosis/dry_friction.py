"""Dry friction along the speed's path within a sample period: in the fit's columns and
in the simulation's step.

The friction torque changes abruptly with the speed (its sign at zero, the Stribeck hump
within ``ωs`` of it), often within one sample period. Sampled at the sample instants, or
at a low-passed speed, its columns misplace the zero crossing and see a hump narrower
than a period at one point of it. The speed at the sample instants (the central
difference of the measured position) is taken as moving linearly between them, and each
column is the friction's mean over the period (:func:`period_mean`), as the
position-periodic torques are (:func:`stand.diagnosis.model.periodic_mean`).

The simulation's step (:func:`friction_step`):

The diagnosis simulates its models with one or a few sub-steps per sample period
(:mod:`.simulate`), often longer than the time the shaft takes to cross zero speed or to
pass the Stribeck hump. Taken at the step's start, the friction then acts with the wrong
sign for the part of the step after a zero crossing, a sticking shaft breaks away a whole
step early or late, and a hump narrower than the step's speed change is seen at one
point of it. This step follows the physics of the stand's plant
(:mod:`stand.physics.plant`) instead, with the speed linear in time within the step:

* sliding, the friction level is its mean along the speed's path over the step,
  ``Tc + (Ts − Tc)·mean(exp(−(ω/ωs)²))``, in closed form with ``erf``, the path's end
  predicted with the start level and corrected once;
* where the speed would cross zero, the crossing is located in the step; the shaft then
  sticks for the rest of it unless the other torques exceed the static level ``Ts``, and
  slides on from rest the other way if they do;
* a shaft at rest (exactly zero speed: it stuck) breaks away when the other torques
  exceed ``Ts``.

Torques are per unit inertia (rad/s²) and the speed change per unit of them over the step
is ``gain`` (the step length, or its exact form under viscous damping).
"""

from __future__ import annotations

import math

import numpy as np
from scipy.special import erf

#: ``√π/2``: ``∫₀^x exp(−v²) dv = (√π/2)·erf(x)``.
_HALF_SQRT_PI = 0.5 * math.sqrt(math.pi)


def hump_integral(omega: np.ndarray, ws: np.ndarray | float) -> np.ndarray:
    """``∫₀^ω exp(−(v/ωs)²) dv``, rad/s (odd in ``ω``)."""
    return np.asarray(ws * _HALF_SQRT_PI * erf(omega / ws))


def period_mean(speed: np.ndarray, ws: float | None = None) -> np.ndarray:
    """Mean of ``sign(ω)`` (``ws`` None) or of ``sign(ω)·exp(−(ω/ωs)²)`` over the period
    after each sample, the speed moving linearly from ``speed[n]`` to ``speed[n + 1]``
    (rad/s; the last period holds its speed). Across a zero crossing the mean holds both
    signs in proportion."""
    start = speed
    end = np.concatenate([speed[1:], speed[-1:]])
    span = end - start
    moved = span != 0
    if ws is None:  # ∫ sign(ω) dω = |ω|
        rise = np.abs(end) - np.abs(start)
        at_start = np.sign(start)
    else:
        rise = hump_integral(np.abs(end), ws) - hump_integral(np.abs(start), ws)
        at_start = np.sign(start) * np.exp(-((start / ws) ** 2))
    return np.asarray(np.where(moved, rise / np.where(moved, span, 1.0), at_start))


def hump_mean(start: np.ndarray, end: np.ndarray, ws: np.ndarray | float) -> np.ndarray:
    """Mean of ``exp(−(ω/ωs)²)`` while ``ω`` moves linearly from ``start`` to ``end``
    (rad/s; both on one side of zero), the value at ``start`` where they meet."""
    span = end - start
    tiny = 1e-9 * ws
    moved = np.abs(span) > tiny
    integral = hump_integral(end, ws) - hump_integral(start, ws)
    mean = np.abs(integral) / np.where(moved, np.abs(span), 1.0)
    return np.where(moved, mean, np.exp(-((start / ws) ** 2)))


def friction_step(omega: np.ndarray, free: np.ndarray, gain: np.ndarray | float,
                  coulomb: np.ndarray | float, excess: np.ndarray | float,
                  ws: np.ndarray | float) -> tuple[np.ndarray, np.ndarray]:
    """Speed at the end of a step and mean speed over it, rad/s.

    Parameters
    ----------
    omega : ndarray
        Speed at the start of the step, rad/s (exactly 0: a shaft that stuck).
    free : ndarray
        Speed the other torques alone would reach by the end of the step, rad/s.
    gain : ndarray or float
        Speed change per unit torque (per inertia) over the step, s (> 0).
    coulomb, excess : ndarray or float
        Coulomb level ``Tc`` and static excess ``Ts − Tc`` per inertia, rad/s², with a
        static level ``Tc + (Ts − Tc)`` above zero.
    ws : ndarray or float
        Stribeck velocity, rad/s (unused when ``excess`` is 0).

    Each of ``gain``, ``coulomb``, ``excess`` and ``ws`` is one value or one per speed.
    """
    side = np.sign(omega)
    if np.any(excess):  # the end predicted with the start's level, the level averaged to it
        slid = free - gain * side * (coulomb + excess * np.exp(-((omega / ws) ** 2)))
        ahead = np.where(side * slid > 0, slid, 0.0)
        slid = free - gain * side * (coulomb + excess * hump_mean(omega, ahead, ws))
    else:
        slid = free - side * (gain * coulomb)
    mean = 0.5 * (omega + slid)
    through = side * slid <= 0  # crossing zero within the step, or at rest
    if not through.any():
        return slid, mean
    at = np.flatnonzero(through)
    start, sign = omega[at], side[at]
    g, coulomb, excess, ws = (value if np.ndim(value) == 0 else np.asarray(value)[at]
                              for value in (gain, coulomb, excess, ws))
    drive = free[at] - start  # the other torques' speed change over the step
    zero = np.zeros_like(start)
    to_zero = coulomb + excess * hump_mean(start, zero, ws) if np.any(excess) else coulomb
    # the share of the step before zero speed (speed linear in time; 0 at rest)
    before = np.abs(start) / (g * to_zero - sign * drive)
    rest = 1.0 - before
    # from rest: stuck below the static level, else off in the direction of the push
    push = drive / g
    static = coulomb + excess
    away = np.sign(push)
    off = rest * g * (push - away * static)
    if np.any(excess):
        off = rest * g * (push - away * (coulomb + excess * hump_mean(zero, off, ws)))
    off = np.where(np.abs(push) > static, off, 0.0)
    slid[at] = off
    mean[at] = 0.5 * (before * start + rest * off)
    return slid, mean


__all__ = ["friction_step", "hump_integral", "hump_mean", "period_mean"]
