"""Free-run simulation of a fitted model on a measured run, re-anchored per segment.

The simulation re-anchors to the measured state at the start of every segment of
``horizon`` samples: position from the filtered position, velocity from the filtered
velocity, the load of a backlash model from the kinematic load estimate. Within a
segment the model runs free, driven only by the measured current (held over each sample
period as :func:`~stand.diagnose.model.interval_current` reconstructs it). All segments
step together (vectorised), so a 20 s run at 1 kHz simulates in well under a second.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from stand.diagnose.model import (
    EDGE_SAMPLES,
    VELOCITY_RESOLUTION_COUNTS,
    FittedModel,
    interval_current,
    load_estimate,
    periodic_mean,
    shifted,
)
from stand.diagnose.signals import Signals

#: Largest product of sub-step and fastest model rate in the simulation.
MAX_RATE_STEP = 0.1
#: Most sub-steps per sample in the simulation.
MAX_SUBSTEPS = 20
#: Least friction smoothing speed, as a fraction of the run's 95th-percentile speed.
FRICTION_SMOOTHING_FRACTION = 1e-3


@dataclass(frozen=True)
class Segments:
    """Where the simulation is re-anchored: ``starts`` (sample indices), ``horizon``."""

    starts: np.ndarray
    horizon: int

    @property
    def index(self) -> np.ndarray:
        """Sample indices covered, shape (segments, horizon)."""
        return self.starts[:, None] + np.arange(self.horizon)[None, :]


@dataclass
class _State:
    theta: np.ndarray
    omega: np.ndarray
    theta_l: np.ndarray = field(default_factory=lambda: np.zeros(0))
    omega_l: np.ndarray = field(default_factory=lambda: np.zeros(0))


def simulate(model: FittedModel, sig: Signals, seg: Segments) -> np.ndarray:
    """Velocity of ``model`` driven by ``sig``'s current, re-anchored per segment.

    Returns
    -------
    ndarray, shape (segments, horizon)
        Simulated velocity at the samples ``seg.index``, rad/s.
    """
    spec, c = model.spec, model.coef
    dt = sig.dt_s
    current = interval_current(shifted(sig.current, spec.delay), spec.input_weight)
    drive = current[seg.index]
    st = _State(sig.theta_f[seg.starts].copy(), sig.omega_f[seg.starts].copy())
    gap = spec.backlash_gap
    ratio = max(-c.get("load_accel", 0.0), 0.0)
    if gap is not None:
        tl, wl = load_estimate(sig.theta_f, sig.omega_f, gap, dt, spec.backlash_restitution)
        st.theta_l, st.omega_l = tl[seg.starts].copy(), wl[seg.starts].copy()
    fc = -c.get("sign", 0.0)
    fs = -c.get("stribeck", 0.0)
    ws = spec.stribeck_ws or 1.0
    smooth = friction_smoothing(sig)
    friction = "sign" in c
    rate = max(abs(model.c_omega), math.sqrt(abs(model.c_theta)),
               (spec.cogging_N or 0) * float(np.max(np.abs(sig.omega_f))),
               (spec.ripple_N or 0) * float(np.max(np.abs(sig.omega_f))))
    n_sub = int(min(MAX_SUBSTEPS, max(1, math.ceil(rate * dt / MAX_RATE_STEP))))
    h = dt / n_sub
    out = np.empty(seg.index.shape)
    for j in range(seg.horizon):
        out[:, j] = st.omega
        for _ in range(n_sub):
            _step(model, st, drive[:, j], h, friction, fc, fs, ws, smooth, gap, ratio)
    return out


def _step(model: FittedModel, st: _State, i: np.ndarray, h: float, friction: bool,
          fc: float, fs: float, ws: float, smooth: float, gap: float | None,
          ratio: float) -> None:
    spec, c = model.spec, model.coef
    theta, omega = st.theta, st.omega
    a = model.c_theta * theta + model.c_omega * omega + c["current"] * i
    if spec.offset:
        a = a + c["one"]
    step = omega * h  # position-periodic torques: their mean over the sub-step
    if spec.cogging_N is not None:
        mean_sin, mean_cos = periodic_mean(spec.cogging_N, theta, step)
        a = a + c["cog_sin"] * mean_sin + c["cog_cos"] * mean_cos
    if spec.ripple_N is not None:
        mean_sin, mean_cos = periodic_mean(spec.ripple_N, theta, step)
        a = a + i * (c["rip_sin"] * mean_sin + c["rip_cos"] * mean_cos)
    scale: np.ndarray | float = 1.0
    side = np.zeros_like(theta)
    if gap is not None:
        twist = theta - st.theta_l
        side = np.where(twist >= gap - 1e-12, 1.0, np.where(twist <= -gap + 1e-12, -1.0, 0.0))
        level = fc + fs * np.exp(-((omega / ws) ** 2)) if friction else 0.0
        a_motor = a - level * np.sign(omega)
        side = np.where(side * a_motor > 0, side, 0.0)
        side = np.where(side * (st.omega_l - omega) > 0, 0.0, side)  # load rebounding away
        scale = np.where(side != 0, 1.0 / (1.0 + ratio), 1.0)
    if friction:
        # Friction stepped implicitly (stable for any smoothing): where it can stop the
        # shaft within the step the speed goes to the linear regime of tanh near zero.
        level = fc + fs * np.exp(-((omega / ws) ** 2))
        free = omega + h * scale * a
        stop = h * scale * np.maximum(level, 0.0)
        new = np.where(np.abs(free) > stop, free - stop * np.sign(free), free / (1.0 + stop / smooth))
        new = np.where(level < 0, free - h * scale * level * np.tanh(omega / smooth), new)
    else:
        new = omega + h * scale * a
    st.theta = theta + 0.5 * h * (omega + new)
    st.omega = new
    if gap is not None:
        carried = side != 0
        free_l = st.theta_l + h * st.omega_l
        st.theta_l = np.where(carried, st.theta - side * gap, free_l)
        st.omega_l = np.where(carried, st.omega, st.omega_l)
        twist = st.theta - st.theta_l
        hit = np.abs(twist) > gap
        e = spec.backlash_restitution  # impact of two bodies: momentum kept, relative
        v = (st.omega + ratio * st.omega_l) / (1.0 + ratio)  # speed reversed times e
        rel = st.omega - st.omega_l
        st.omega = np.where(hit, v - e * ratio * rel / (1.0 + ratio), st.omega)
        st.omega_l = np.where(hit, v + e * rel / (1.0 + ratio), st.omega_l)
        st.theta_l = np.where(hit, st.theta - np.sign(twist) * gap, st.theta_l)


def friction_smoothing(sig: Signals) -> float:
    """Speed over which simulated friction changes sign, rad/s: ``sign(ω)`` becomes
    ``tanh(ω/ε)`` with ε the run's velocity resolution (as in :func:`velocity_sign`), at
    least ``FRICTION_SMOOTHING_FRACTION`` of its 95th-percentile speed.

    A hard sign with stiction (Karnopp) makes the free run flip the friction torque at
    the simulated, not the real, zero crossing and stick where the real shaft moved; a
    friction that changes sign within the velocity resolution keeps the free run close
    to the measured one without claiming more than the data resolve near standstill.
    """
    top = float(np.quantile(np.abs(sig.omega_f), 0.95))
    return max(VELOCITY_RESOLUTION_COUNTS * sig.quant_rad / sig.dt_s,
               FRICTION_SMOOTHING_FRACTION * top, 1e-12)


def segments(n: int, dt_s: float, horizon_s: float, min_segments: int) -> Segments:
    """Anchor points: segments of ``horizon_s`` (fewer samples if needed for
    ``min_segments``), skipping the filter edges."""
    usable = n - 2 * EDGE_SAMPLES - 1
    horizon = max(10, min(int(round(horizon_s / dt_s)), usable // min_segments))
    count = usable // horizon
    starts = EDGE_SAMPLES + horizon * np.arange(count)
    return Segments(starts=starts, horizon=horizon)
