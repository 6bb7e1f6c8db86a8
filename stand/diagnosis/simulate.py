"""Free-run simulation of a fitted model on a measured run, re-anchored per segment.

The model runs free over each segment of ``horizon`` samples, driven only by the
measured current (held over each sample period as
:func:`~stand.diagnosis.model.interval_current` reconstructs it), and is re-anchored at
the start of every segment. The simulated speed is compared with the measured one,
which is the central difference of the measured position (the mean speed over two
sample periods, not the speed at the instant), so the simulation reports the same: the
central difference of its own position.

The anchor is the state one sample before the segment: the filtered position, a backlash
load from the kinematic load estimate (a load on a compliant coupling from the measured
motion through its mode), and the speed that carries the model through the
measured position one sample after the segment starts (a shooting step, solved per
segment with the model itself). The filtered speed is no anchor: on a run whose
acceleration changes within a few samples (a speed loop, a fast command) the low-pass
rounds it off and the anchor error swamps every other error of the free run. All
segments step together (vectorised), so a 20 s run at 1 kHz simulates in well under a
second.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from stand.diagnosis.dry_friction import friction_step
from stand.diagnosis.model import (
    EDGE_SAMPLES,
    LOAD_COLUMNS,
    FittedModel,
    load_motion,
    period_current,
    period_shape,
    periodic_mean,
    ripple_on_offset,
    velocity_resolution,
)
from stand.diagnosis.signals import Signals

#: Largest product of sub-step and fastest model rate in the simulation.
MAX_RATE_STEP = 0.1
#: Most sub-steps per sample in the simulation.
MAX_SUBSTEPS = 20
#: Sub-steps per sample of a model whose backlash gap the run's top speed crosses within
#: a sample. The contact is found at the end of a sub-step, so the impact comes late by
#: up to a sub-step and the momentum it shares with it: an error of the free run that
#: falls as 1/sub-steps. With every parameter at its true value, on a current-mode run
#: sampled every 4.3 ms (seed 260 case 184) the holdout gap was 1.14 % at 1 sub-step,
#: 0.69 % at 2, 0.59 % at 3, 0.55 % at 5, 0.53 % at 10 and at 20 (nominal model 1.45 %);
#: each sub-step costs about 0.06 s of the 20 s timing case's diagnosis.
BACKLASH_SUBSTEPS = 4
#: Most rows (models times segments) stepped together: well past where numpy's per-call
#: overhead is paid off, with working arrays of a few hundred kB.
BATCH_ROWS = 16384
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

    def copy(self) -> _State:
        return _State(self.theta.copy(), self.omega.copy(), self.theta_l.copy(),
                      self.omega_l.copy())


#: Newton steps of the shooting anchor (the first is exact for a linear model).
SHOOTING_STEPS = 2


def simulate(model: FittedModel, sig: Signals, seg: Segments) -> np.ndarray:
    """Speed of ``model`` driven by ``sig``'s current, re-anchored per segment.

    Returns
    -------
    ndarray, shape (segments, horizon)
        Simulated speed at the samples ``seg.index`` as the measurement reports it (the
        central difference of the simulated position), rad/s.
    """
    return simulate_many([model], sig, seg)[0]


def simulate_many(models: list[FittedModel], sig: Signals, seg: Segments) -> list[np.ndarray]:
    """:func:`simulate` of each of ``models``, those of one kind (:func:`_kind`: the same
    terms and sub-steps) stepped together, each model's segments a block of rows.

    A search that picks by simulation (a backlash gap's grid) simulates dozens of models
    that differ only in their values; one at a time, each sub-step's few hundred rows
    cost what numpy's per-call overhead costs, not what the arithmetic does."""
    out: list[np.ndarray] = [np.empty(0)] * len(models)
    kinds: dict[Kind, list[int]] = {}
    top = float(np.max(np.abs(sig.omega_f)))
    for k, model in enumerate(models):
        kinds.setdefault(_kind(model, sig, top), []).append(k)
    size = max(1, BATCH_ROWS // len(seg.starts))
    for kind, members in kinds.items():
        for first in range(0, len(members), size):
            chunk = members[first:first + size]
            speeds = _simulate_together([models[k] for k in chunk], sig, seg, kind)
            for k, speed in zip(chunk, speeds, strict=True):
                out[k] = speed
    return out


def _simulate_together(models: list[FittedModel], sig: Signals, seg: Segments,
                       kind: Kind) -> list[np.ndarray]:
    """:func:`simulate` of ``models``, all of ``kind``, in one pass."""
    spec = models[0].spec
    dt = sig.dt_s
    first = seg.starts - 1
    periods = first[:, None] + np.arange(seg.horizon + 1)[None, :]
    drive = np.concatenate([period_current(model, sig)[periods] for model in models])
    # the angle's share of a current that is not held over its period (its ramp-weighted
    # mean above its mean, a kick's early current): (Δt²/2)·(Kt/J)·shape
    shapes = [period_shape(model, sig) for model in models]
    bend = None if shapes[0] is None else np.concatenate([
        0.5 * dt * dt * model.coef["current"] * shape[periods]
        for model, shape in zip(models, shapes, strict=True) if shape is not None])
    step = _Stepper(models, sig, len(first), kind)
    count = len(models)
    anchor = _State(np.tile(sig.theta_f[first], count), np.tile(sig.omega_meas[first], count))
    if spec.backlash_gap is not None or spec.coupling_hz is not None:
        loads = [load_motion(model.spec, sig) for model in models]
        anchor.theta_l = np.concatenate([tl[first] for tl, _ in loads])
        anchor.omega_l = np.concatenate([wl[first] for _, wl in loads])
    # a coupled load fitted stiffer than the sub-steps resolve (tens of times the rotor's
    # inertia at a high mode) diverges: its error is then the scorer's bound
    # (:class:`~stand.diagnosis.scoring.Bench`), and no search keeps it
    quiet = {"over": "ignore", "invalid": "ignore"} if spec.coupling_hz is not None else {}
    with np.errstate(**quiet):  # type: ignore[arg-type]
        _shoot(step, anchor, drive[:, :2],
               np.tile(sig.theta[seg.starts + 1] - sig.theta[first], count),
               None if bend is None else bend[:, :2])
        theta = _positions(step, anchor, drive, bend)
    return np.split((theta[:, 2:] - theta[:, :-2]) / (2.0 * dt), count)


def _shoot(step: _Stepper, anchor: _State, drive: np.ndarray, travel: np.ndarray,
           bend: np.ndarray | None) -> None:
    """Set ``anchor.omega`` so the model travels ``travel`` (rad) over the sample periods
    of ``drive`` (Newton steps, the slope by a finite difference). Where the model
    barely responds to its start speed (a shaft held by friction), the slope of the
    linear model is used instead."""
    span = drive.shape[1] * step.sig.dt_s
    linear = step.rows([span * phi1(c_omega * span) for c_omega in step.c_omegas])
    delta = max(1e-6, 1e-3 * step.sig.top_speed)
    for _ in range(SHOOTING_STEPS):
        reach = _positions(step, anchor, drive, bend)[:, -1] - anchor.theta
        nudged = anchor.copy()
        nudged.omega = anchor.omega + delta
        slope = (_positions(step, nudged, drive, bend)[:, -1] - nudged.theta - reach) / delta
        slope = np.where(slope > 0.1 * linear, slope, linear)
        anchor.omega = anchor.omega + (travel - reach) / slope


def _positions(step: _Stepper, anchor: _State, drive: np.ndarray,
               bend: np.ndarray | None = None) -> np.ndarray:
    """Positions of the model from ``anchor`` (column 0) at the end of each sample period
    of ``drive``, shape (segments, periods + 1), rad; ``bend`` is added to the angle at
    the end of each period (rad: a current not held over its period)."""
    st = anchor.copy()
    theta = np.empty((len(st.theta), drive.shape[1] + 1))
    theta[:, 0] = st.theta
    for j in range(drive.shape[1]):
        step.sample(st, drive[:, j])
        if bend is not None:
            st.theta = st.theta + bend[:, j]
        theta[:, j + 1] = st.theta
    return theta


#: What models stepped together share (:func:`_kind`).
Kind = tuple[int, bool, int | None, int | None, bool, bool, bool, bool, bool, bool, bool, bool]


def _kind(model: FittedModel, sig: Signals, top: float) -> Kind:
    """What models stepped together must share: their sub-steps and the terms and
    branches of :meth:`_Stepper._substep` they take (``top``: the run's largest
    filtered speed, rad/s)."""
    spec, c = model.spec, model.coef
    # a coupling's mode, as the motor meets it: ωn·sqrt(1 + J_l/J)
    mode = (2.0 * math.pi * spec.coupling_hz * math.sqrt(1.0 + _load_ratio(c))
            if spec.coupling_hz is not None else 0.0)
    # a drag continuous through zero is steepest there: |c_drag|/ω_d
    drag = abs(c.get("drag", 0.0)) / spec.drag_ws if spec.drag_ws is not None else 0.0
    rate = max(abs(model.c_omega), math.sqrt(abs(model.c_theta)),
               (spec.cogging_N or 0) * top, (spec.ripple_N or 0) * top, mode, drag)
    # a backlash contact is found at the end of a sub-step (BACKLASH_SUBSTEPS)
    gap = spec.backlash_gap
    contact = min(BACKLASH_SUBSTEPS, math.ceil(top * sig.dt_s / gap)) if gap else 1
    n_sub = int(min(MAX_SUBSTEPS, max(1, contact, math.ceil(rate * sig.dt_s / MAX_RATE_STEP))))
    friction, stribeck = "sign" in c, "stribeck" in c
    fc, fs = -c.get("sign", 0.0), -c.get("stribeck", 0.0)
    # a physical friction (a level >= 0 at every speed, a static level > 0) is stepped
    # as dry friction; a constant level below zero drives the shaft (not friction)
    dry = friction and fc >= 0 and fc + (fs if stribeck else 0.0) > 0
    pushing = friction and not stribeck and fc < 0
    return (n_sub, spec.offset, spec.cogging_N, spec.ripple_N, gap is not None, friction,
            stribeck, dry, pushing, spec.coupling_hz is not None, spec.drag_ws is not None,
            spec.load_friction)


def _load_ratio(coef: dict[str, float]) -> float:
    """``J_load/J`` of a model's load (behind a backlash or a compliant coupling), 0
    without one or for an unphysical (positive) coefficient."""
    return max(0.0, *(-coef.get(name, 0.0) for name in LOAD_COLUMNS))


class _Stepper:
    """One sample period of ``models`` (all of ``kind``, :func:`_kind`) for all segments
    at once (its sub-steps): each model's ``segments`` a block of rows, each model's
    values a number (one model) or a column over the rows."""

    def __init__(self, models: list[FittedModel], sig: Signals, segments: int,
                 kind: Kind) -> None:
        self.sig, self.spec, self.segments = sig, models[0].spec, segments
        (self.n_sub, _, _, _, backlash, self.friction, self.stribeck, self.dry,
         self.pushing, self.coupled, self.dragged, self.loaded) = kind
        coef = [model.coef for model in models]

        def of(name: str) -> np.ndarray | float:
            return self.rows([c.get(name, 0.0) for c in coef])

        self.current, self.one = of("current"), of("one")
        self.cog_sin, self.cog_cos = of("cog_sin"), of("cog_cos")
        self.rip_sin, self.rip_cos = of("rip_sin"), of("rip_cos")
        # a ripple beside a current offset acts on the true current, i + one/current
        # (:func:`stand.diagnosis.model.ripple_on_offset`)
        self.rip_shift = (self.rows([c["one"] / c["current"] for c in coef])
                          if ripple_on_offset(self.spec) else 0.0)
        self.c_omegas = [model.c_omega for model in models]
        self.c_theta = self.rows([model.c_theta for model in models])
        self.c_omega = self.rows(self.c_omegas)
        self.gap = self.rows([model.spec.backlash_gap or 0.0 for model in models]) if backlash else None
        self.restitution = self.rows([model.spec.backlash_restitution for model in models])
        ratios = [_load_ratio(c) for c in coef]
        self.ratio = self.rows(ratios)
        modes = [2.0 * math.pi * (model.spec.coupling_hz or 0.0) for model in models]
        self.mode_sq = self.rows([w * w for w in modes])
        self.mode_damping = self.rows([2.0 * model.spec.coupling_zeta * w
                                       for model, w in zip(models, modes, strict=True)])
        self.fc = self.rows([-c.get("sign", 0.0) for c in coef])
        self.fs = self.rows([-c.get("stribeck", 0.0) for c in coef])
        # a friction level growing with the current carried: per unit of |i|
        self.load_level = self.rows([-c.get("load_friction", 0.0) for c in coef])
        self.ws = self.rows([model.spec.stribeck_ws or 1.0 for model in models])
        self.drag = of("drag")
        self.drag_ws = self.rows([model.spec.drag_ws or 1.0 for model in models])
        self.smooth = friction_smoothing(sig)
        self.h = sig.dt_s / self.n_sub
        # The speed's own rate c_ω stepped exactly: over a sub-step the speed relaxes at
        # that rate towards what the other terms (held over the sub-step) drive it to.
        # An Euler step gives the drive torque a gain h where the exact one is
        # (e^(c_ω·h) − 1)/c_ω: ~c_ω·h/2 too much, a few % at c_ω·h of 0.05-0.1, a
        # structural error of the simulation that effect candidates would absorb. While
        # a backlash load is carried the rate is c_ω/(1 + J_l/J).
        self.h_free = self.rows([self.h * phi1(m.c_omega * self.h) for m in models])
        self.h_carried = self.rows([self.h * phi1(m.c_omega * self.h / (1.0 + r))
                                    for m, r in zip(models, ratios, strict=True)])

    def rows(self, values: list[float]) -> np.ndarray | float:
        """One value per model as the rows take it: the number itself for one model."""
        if len(values) == 1:
            return float(values[0])
        return np.repeat(np.asarray(values, dtype=float), self.segments)

    def sample(self, st: _State, i: np.ndarray) -> None:
        """Advance ``st`` by one sample period under the current ``i``."""
        for _ in range(self.n_sub):
            self._substep(st, i)

    def _substep(self, st: _State, i: np.ndarray) -> None:
        spec, h, gap, ratio = self.spec, self.h, self.gap, self.ratio
        theta, omega = st.theta, st.omega
        a = self.c_theta * theta + self.c_omega * omega + self.current * i
        if spec.offset:
            a = a + self.one
        if self.coupled:  # the load on the coupling, its torque held over the sub-step
            a_load = (self.mode_sq * (theta - st.theta_l)
                      + self.mode_damping * (omega - st.omega_l))
            a = a - ratio * a_load
        if self.dragged:  # smooth: held over the sub-step like the other torques
            a = a + self.drag * np.tanh(omega / self.drag_ws)
        step = omega * h  # position-periodic torques: their mean over the sub-step
        if spec.cogging_N is not None:
            mean_sin, mean_cos = periodic_mean(spec.cogging_N, theta, step)
            a = a + self.cog_sin * mean_sin + self.cog_cos * mean_cos
        if spec.ripple_N is not None:
            mean_sin, mean_cos = periodic_mean(spec.ripple_N, theta, step)
            a = a + (i + self.rip_shift) * (self.rip_sin * mean_sin + self.rip_cos * mean_cos)
        # without a Stribeck term the friction level is the Coulomb level (and what the
        # current carried adds to it)
        fc = self.fc + self.load_level * np.abs(i) if self.loaded else self.fc
        level: np.ndarray | float = (
            fc + self.fs * np.exp(-((omega / self.ws) ** 2)) if self.stribeck
            else fc if self.friction else 0.0)
        scale: np.ndarray | float = 1.0
        h_eff: np.ndarray | float = self.h_free
        if gap is not None:
            twist = theta - st.theta_l
            side = np.where(twist >= gap - 1e-12, 1.0, np.where(twist <= -gap + 1e-12, -1.0, 0.0))
            a_motor = a - level * np.sign(omega)
            side = np.where(side * a_motor > 0, side, 0.0)
            side = np.where(side * (st.omega_l - omega) > 0, 0.0, side)  # load rebounding away
            scale = np.where(side != 0, 1.0 / (1.0 + ratio), 1.0)
            h_eff = np.where(side != 0, self.h_carried, self.h_free)
        if self.dry:
            # dry friction as the continuous shaft meets it: its zero crossing, sticking
            # and breakaway located in the step, the Stribeck level averaged along it
            new, mean = friction_step(omega, omega + h_eff * scale * a, h_eff * scale,
                                      fc, self.fs if self.stribeck else 0.0, self.ws)
            st.theta = theta + h * mean
        else:
            if self.friction:
                # a fitted friction level that drives the shaft somewhere (not friction):
                # stepped implicitly, stable for any smoothing
                smooth = self.smooth
                free = omega + h_eff * scale * a
                if self.pushing:
                    new = free - h_eff * scale * level * np.tanh(omega / smooth)
                else:
                    stop = h_eff * scale * np.maximum(level, 0.0)
                    new = np.where(np.abs(free) > stop, free - stop * np.sign(free),
                                   free / (1.0 + stop / smooth))
                    if self.stribeck:
                        new = np.where(level < 0,
                                       free - h_eff * scale * level * np.tanh(omega / smooth),
                                       new)
            else:
                new = omega + h_eff * scale * a
            st.theta = theta + 0.5 * h * (omega + new)
        st.omega = new
        if self.coupled:
            st.omega_l = st.omega_l + h * a_load
            st.theta_l = st.theta_l + h * st.omega_l
        if gap is not None:
            carried = side != 0
            free_l = st.theta_l + h * st.omega_l
            st.theta_l = np.where(carried, st.theta - side * gap, free_l)
            st.omega_l = np.where(carried, st.omega, st.omega_l)
            twist = st.theta - st.theta_l
            hit = np.abs(twist) > gap
            e = self.restitution  # impact of two bodies: momentum kept, relative
            v = (st.omega + ratio * st.omega_l) / (1.0 + ratio)  # speed reversed times e
            rel = st.omega - st.omega_l
            st.omega = np.where(hit, v - e * ratio * rel / (1.0 + ratio), st.omega)
            st.omega_l = np.where(hit, v + e * rel / (1.0 + ratio), st.omega_l)
            st.theta_l = np.where(hit, st.theta - np.sign(twist) * gap, st.theta_l)


def phi1(z: float) -> float:
    """``(e^z − 1)/z``, 1 at ``z = 0``: what a rate ``z`` per unit time makes of a unit
    time step driven by a held input (the exact step of a linear first-order system)."""
    return 1.0 + 0.5 * z if abs(z) < 1e-9 else math.expm1(z) / z


def friction_smoothing(sig: Signals) -> float:
    """Speed over which a simulated friction that is not physical (a fitted level that
    pushes the shaft along somewhere) changes sign, rad/s: ``sign(ω)`` becomes
    ``tanh(ω/ε)`` with ε the run's velocity resolution (as in :func:`velocity_sign`), at
    least ``FRICTION_SMOOTHING_FRACTION`` of its 95th-percentile speed. A physical
    friction is stepped as dry friction (:func:`.dry_friction.friction_step`)."""
    return max(velocity_resolution(sig),
               FRICTION_SMOOTHING_FRACTION * sig.top_speed, 1e-12)


def segments(n: int, dt_s: float, horizon_s: float, min_segments: int) -> Segments:
    """Anchor points: segments of ``horizon_s`` (fewer samples if needed for
    ``min_segments``), skipping the filter edges."""
    usable = n - 2 * EDGE_SAMPLES - 1
    horizon = max(10, min(int(round(horizon_s / dt_s)), usable // min_segments))
    count = usable // horizon
    starts = EDGE_SAMPLES + horizon * np.arange(count)
    return Segments(starts=starts, horizon=horizon)
