"""Regressor and instrument columns of the identification model with effects.

The model is seed 000's acceleration row with the effect regressors of the diagnosis
(:class:`stand.diagnosis.model.ModelSpec`) as extra input columns::

    θ'' = −(C/J)·θ − (D/J)·θ' + (Kt/J)·i(t + d) + Σ_j c_j·φ_j(θ, θ', i)

The current over the period after sample ``n`` is ``(1 − w)·i[n + k] + w·i[n + k + 1]``
(:func:`stand.diagnosis.model.interval_current`; ``k`` the delay, ``w`` the
``input_weight``): ``w = 1`` for a drive that samples, then actuates, its current loop
settling within the period on the value read at the next sample; ``w = 0.5`` for a
current that varies smoothly (the period's mean); ``w = 0`` for a drive that actuates,
then samples.

When the timing is fitted, its column is the current loop's settling: a fast loop
settling on a held reference leaves each period's deficit ``(1 − w)·Δi`` near the
period's start, not spread over it (:meth:`Design._settling`): the same velocity, but the
angle differs by ``(Kt/J)·(1 − w)·Δi·Δt²/2``.

Every column is passed through the kernel that the sampled second-derivative kernel
applies to the acceleration (:func:`~stand.ident.derivatives.acceleration_kernel`, the
sampled sum written as an integral over the acceleration), so the filtered signals obey
the same equation. A column held over each period (the current, the period means of
``sin Nθ``) goes through it period by period
(:func:`~stand.ident.derivatives.filter_held`);
the friction columns are period means too (of ``sign θ'`` at points within the period,
from a velocity that keeps each period's mean ``Δθ/Δt``, :meth:`Design.omega_within`).

Rows at rest. Where the encoder reads one angle over two or more periods the shaft rests
(static friction holds any torque up to its breakaway level) or crawls below the
encoder's resolution: no friction column knows the torque there, and a speed loop winding
its current up against a stuck shaft would pull Kt/J towards zero. The rows whose kernel
meets such a stretch are left out (:attr:`Design.moving`).

Instruments. The measured current carries sensor noise; as a regressor it makes an
errors-in-variables problem and least squares pulls Kt/J towards zero by the share of
the filtered noise in the filtered current. Each column that holds the current has an
instrument built the same way from ``½·(i(t − L) + i(t + L))``, with ``L`` longer than
the kernel's support: white sensor noise at ``t ± L`` is independent of that at ``t``
after filtering, while the current itself (driven by the command and the motion) is
correlated across ``L``. Columns of the motion alone (θ, θ', sign θ', sin Nθ) are their
own instruments: the encoder's quantization error is independent of the current noise,
and the kernel's odd first and even second derivative leave the filtered velocity and
acceleration noise uncorrelated at lag zero.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from stand.diagnosis.model import (
    ModelSpec,
    interval_current,
    periodic_column,
    shifted,
    velocity_sign,
)
from stand.diagnosis.signals import Signals, near_rest
from stand.ident.derivatives import (
    _convolve_valid,
    acceleration_interval_weights,
    acceleration_kernel,
    filter_held,
    kernel,
)
from stand.ident.noise import noise_sigma, noise_variance_uncertainty, passband_noise

#: Points per sample period at which the friction columns are averaged.
SUBSAMPLES = 8
#: The current's change over the period after each sample, ``i[n + k + 1] − i[n + k]``:
#: with its own coefficient ``(Kt/J)·w`` it makes the timing ``w`` of the current within
#: the period a free, linear parameter (see :meth:`Design.matrices`).
TIMING_COLUMN = "current_step"
#: The same change over the periods in which the current does not settle but keeps
#: moving the same way into the next period (a drive at its supply voltage ramps the
#: current over several periods): such a period holds a ramp between its end samples,
#: not a step settled early in it, and its current's timing has a coefficient of its own.
RAMP_COLUMN = "current_ramp"
#: Half the current's change over the periods that settle no step (:data:`DRIFT_WEIGHT`),
#: a part of the current's column where the timing column carries the settling.
DRIFT_COLUMN = "current_drift"
#: A change of the current counts as a ramp going on when it and the next change have
#: the same sign and each exceeds this many standard deviations of a difference of two
#: noisy samples (4: white noise alone passes each with probability 6e-5, both far less).
RAMP_SIGMAS = 4.0
#: ... and the next change is at least this share of it. A first-order current loop of
#: time constant ``τ`` carries ``e^(−Δt/τ)`` of a period's change into the next period;
#: it settles within the period (``w = 1 − τ/Δt`` ≥ 0, the timing column's model) while
#: ``τ`` ≤ Δt, i.e. while it carries at most ``1/e``. Beyond that the current is still
#: on its way at the next sample: a ramp. (A noise-free run has no noise floor, and
#: every settling tail would otherwise count as a ramp.)
RAMP_CARRIED_SHARE = float(np.exp(-1.0))
#: A period whose current changes by no more than the ramp's noise floor
#: (:data:`RAMP_SIGMAS`) settles no step: its current holds or drifts with the motion (a
#: drive at its supply voltage follows ``(V − Kt·ω)/R``, linear in time across the
#: period), and its mean over the period is the mean of its end samples, ``w = ½``,
#: rather than the settled end value a step's timing gives.
DRIFT_WEIGHT = 0.5
#: The timing column carries a fast current loop's settling at the start of each period
#: (:meth:`Design._settling`) rather than a change held over the whole period.
SETTLING_AT_START = True
#: Torque ripple's columns, the current times ``sin Nθ`` and ``cos Nθ``. Where the timing
#: column carries the current loop's settling, they take the current the loop settles
#: on over the period (its end value): the ripple scales the torque the current makes
#: over the period, and the settling's deficit is a share ``1 − w`` of a step (0.04–0.2
#: on the simulated drives) where the value at the period's start misses a share ``w``.
RIPPLE_COLUMNS = ("rip_sin", "rip_cos")
#: Columns that carry the measured current (and so need an instrument).
CURRENT_COLUMNS = frozenset({"current", TIMING_COLUMN, RAMP_COLUMN, DRIFT_COLUMN,
                             *RIPPLE_COLUMNS})


def lagged_mean(values: np.ndarray, lag: int) -> np.ndarray:
    """``½·(v[n − lag] + v[n + lag])`` (edge values repeated), the instrument's current."""
    if lag <= 0:
        return values
    padded = np.concatenate([np.repeat(values[:1], lag), values, np.repeat(values[-1:], lag)])
    return 0.5 * (padded[:-2 * lag] + padded[2 * lag:])


def moving_rows(theta: np.ndarray, half_width: int) -> np.ndarray:
    """Rows of a design of kernel ``half_width`` (``len(θ) − 2·half_width``) whose kernel,
    widened by a period either way for the held columns, meets no still period
    (:func:`~stand.diagnosis.signals.near_rest`): the rows on which the model's
    friction holds."""
    return ~near_rest(theta, half_width + 1)[half_width:len(theta) - half_width]


#: Points of the search for the crossing within a period (:func:`reversal_lines`).
CROSSING_GRID = 257


def reversal_lines(before: np.ndarray, mean: np.ndarray, after: np.ndarray
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Where in a period the shaft reverses, from the mean velocities of the period and
    its neighbours, with a line of its own on either side of the crossing.

    In units of the period, the velocity is ``a_L·(s − τ)`` before the crossing ``τ``
    (0 ≤ τ ≤ 1) and ``a_R·(s − τ)`` after it: constant accelerations that differ by
    twice the friction (a held torque, Coulomb friction flipping at ω = 0). The
    neighbours' means give ``a_L = −ω̄_{n−1}/(½ + τ)`` and ``a_R = ω̄_{n+1}/(3/2 − τ)``,
    and ``τ`` makes the period's own mean ``−a_L·τ²/2 + a_R·(1 − τ)²/2`` equal to
    ``ω̄_n``. Without a kink this is the line through the three means.

    Returns
    -------
    crossing, left, right : ndarray
        ``τ`` (NaN where no crossing in the period keeps its mean), ``a_L`` and ``a_R``,
        rad/s per period.
    """
    tau = np.linspace(0.0, 1.0, CROSSING_GRID)
    b, m, a = before[:, None], mean[:, None], after[:, None]
    f = b * tau**2 / (1 + 2 * tau) + a * (1 - tau) ** 2 / (3 - 2 * tau) - m
    change = np.signbit(f[:, :-1]) != np.signbit(f[:, 1:])
    first = np.argmax(change, axis=1)
    rows = np.arange(len(f))
    f0, f1 = f[rows, first], f[rows, first + 1]
    with np.errstate(divide="ignore", invalid="ignore"):
        crossing = tau[first] + (tau[1] - tau[0]) * f0 / (f0 - f1)
    crossing = np.where(change.any(axis=1), crossing, np.nan)
    return crossing, -before / (0.5 + crossing), after / (1.5 - crossing)


@dataclass
class Design:
    """A run prepared for the extended model: filtered motion and a column cache.

    Attributes
    ----------
    sig : Signals
        The run's signals (for the velocity sign and the filtered angle of the periodic
        columns).
    half_width : int
        Kernel half width, samples.
    lag : int
        Lag of the current instruments, samples (0: least squares, no instruments).
    theta, omega, alpha : ndarray
        Kernel-filtered angle (rad), velocity (rad/s), acceleration (rad/s²) on the rows.
    moving : ndarray of bool
        The rows the fit takes: those whose kernel meets no stretch of the shaft at rest
        (:func:`moving_rows`).
    """

    sig: Signals
    half_width: int
    lag: int
    theta: np.ndarray
    omega: np.ndarray
    alpha: np.ndarray
    moving: np.ndarray
    cache: dict[tuple[object, ...], np.ndarray] = field(default_factory=dict, repr=False)

    @classmethod
    def build(cls, sig: Signals, half_width: int, lag: int) -> Design:
        """Filter the angle of ``sig`` with the kernel of ``half_width`` samples.

        The input columns are filtered as the sampled second-derivative kernel filters
        the acceleration (:meth:`filt`); the angle and the velocity (the spring and
        damping columns) keep the sampled kernel and its derivative: the velocity filtered
        as the acceleration is needs the angle's mean over each period, and its mean of
        the end samples misses ``Δt²·θ''/12``, more than the sampled derivative misses
        (Kt/J −0.008 % against −0.002 % on a noise-free stand with ``Δt·D/J`` = 0.04).
        """
        g, g1, g2 = kernel(half_width, sig.dt_s)
        theta, omega, alpha = (_convolve_valid(sig.theta, w, sig.dt_s) for w in (g, g1, g2))
        return cls(sig, half_width, lag, theta, omega, alpha, moving_rows(sig.theta, half_width))

    def filt(self, values: np.ndarray, held: bool = True) -> np.ndarray:
        """``values`` through the kernel, on the rows of the design; ``held``: each value
        holds over the period after its sample."""
        h, dt = self.half_width, self.sig.dt_s
        if held:
            return filter_held(values, h, dt, acceleration_interval_weights(h, dt))
        return _convolve_valid(values, acceleration_kernel(h, dt), dt)

    def current(self, spec: ModelSpec, instrument: bool) -> np.ndarray:
        """Current at the model's timing, unfiltered (the lagged mean for the instrument)."""
        i = interval_current(shifted(self.sig.current, spec.delay), spec.input_weight)
        return lagged_mean(i, self.lag) if instrument else i

    def column(self, spec: ModelSpec, name: str, instrument: bool = False) -> np.ndarray:
        """Filtered input column ``name`` of ``spec`` (or its instrument), cached."""
        instrument = instrument and name in CURRENT_COLUMNS and self.lag > 0
        key = (name, instrument, spec.delay, spec.input_weight, spec.stribeck_ws,
               spec.cogging_N if name.startswith("cog") else spec.ripple_N)
        if key not in self.cache:
            self.cache[key] = self.filt(self._raw(spec, name, instrument), True)
        return self.cache[key]

    def omega_within(self) -> np.ndarray:
        """Velocity at ``SUBSAMPLES`` midpoints of each period, rad/s, shape
        (samples, SUBSAMPLES).

        The angle gives each period's mean velocity ``ω̄_n = (θ[n + 1] − θ[n])/Δt``
        exactly (to a count); the velocity within the period keeps it. Within a period
        the velocity is the line through its mean with the slope of the neighbouring
        means. Where the neighbours' means have opposite signs the shaft reverses in the
        period, and friction flips with the sign of ω: the velocity has a kink at zero, a
        line on either side (:func:`reversal_lines`). A low-passed velocity spreads that
        kink over several samples and moves the crossing, and the friction columns'
        impulse with it, in proportion to the friction.
        """
        theta = self.sig.theta
        mean = np.diff(theta, append=2 * theta[-1] - theta[-2]) / self.sig.dt_s
        before = np.concatenate([mean[:1], mean[:-1]])
        after = np.concatenate([mean[1:], mean[-1:]])
        share = (np.arange(SUBSAMPLES) + 0.5) / SUBSAMPLES
        omega = mean[:, None] + 0.5 * (after - before)[:, None] * (share - 0.5)
        turning = np.flatnonzero(before * after < 0)
        if turning.size:
            lines = reversal_lines(before[turning], mean[turning], after[turning])
            crossing, left, right = (x[:, None] for x in lines)
            kinked = np.where(share < crossing, left * (share - crossing),
                              right * (share - crossing))
            found = np.isfinite(crossing[:, 0])
            omega[turning[found]] = kinked[found]
        return np.asarray(omega)

    def _raw(self, spec: ModelSpec, name: str, instrument: bool) -> np.ndarray:
        sig = self.sig
        if name == "current":
            return self.current(spec, instrument)
        if name in (TIMING_COLUMN, RAMP_COLUMN, DRIFT_COLUMN):
            weight = DRIFT_WEIGHT if name == DRIFT_COLUMN else 1.0
            step = weight * self.current_change(spec.delay) * self.change_mask(
                spec.delay, self._change_kind(spec, name))
            return lagged_mean(step, self.lag) if instrument else step
        if name == "one":
            return np.ones(len(sig))
        if name in ("sign", "stribeck"):
            # Period means: the friction torque changes sign within the period of a
            # reversal, in proportion to the time spent on either side.
            omega = self.omega_within()
            column = velocity_sign(omega, sig)
            if name == "stribeck":
                column = column * np.exp(-((omega / (spec.stribeck_ws or 1.0)) ** 2))
            return np.asarray(column.mean(axis=1))
        order = (spec.cogging_N if name.startswith("cog") else spec.ripple_N) or 0
        periodic = periodic_column(order, sig, name.endswith("sin"))
        if name.startswith("rip"):
            return self.current(spec, instrument) * periodic
        return periodic

    @staticmethod
    def _settles(spec: ModelSpec, names: list[str]) -> bool:
        """The timing column carries the current loop's settling (see :meth:`_settling`)."""
        return SETTLING_AT_START and TIMING_COLUMN in names and spec.input_weight == 0.0

    def _settling(self, spec: ModelSpec, instrument: bool, share: float = 0.0) -> np.ndarray:
        """The timing column as the settling of a fast current loop: each period's
        change ``i[n+k+1] − i[n+k]`` as an impulse ``share`` of a period after the
        period's start (the columns for 0 and 1 cached).

        A first-order loop (``τ`` ≪ Δt) settling on a held reference gives over the
        period ``i[n+1] − (i[n+1] − i[n])·e^(−s/τ)``: the period's end value held, less a
        deficit of area ``(1 − w)·Δt·Δi`` (``w = 1 − τ/Δt``) within a few ``τ`` of the
        period's start, its centroid ``τ`` after it. Held over the whole period instead,
        the deficit sits half a period late: the velocity is the same but the angle is
        not. Through the kernel ``K`` (:meth:`filt`), linear between the sample instants,
        the deficit is exactly ``(1 − w)·Δt·Δi·K(t − t_n − τ)``, the interpolation of the
        impulses at ``t_n`` and ``t_{n+1}`` with the ``share`` ``τ/Δt`` (the fit takes it
        as ``1 − w`` of a first pass, :class:`~stand.ident.select.Fitter`). With the
        current held at ``w = 1`` and this column (coefficient ``(Kt/J)·w``) the model is
        ``(Kt/J)·[held(w = 1) − impulse + w·impulse]``.
        """
        key = ("settling", instrument, spec.delay)
        if key not in self.cache:
            raw = self._raw(spec, TIMING_COLUMN, instrument)
            later = np.concatenate([[0.0], raw[:-1]])
            self.cache[key] = np.stack([self.filt(raw, held=False),
                                        self.filt(later, held=False)])
        at_start, next_start = self.cache[key]
        return np.asarray((1.0 - share) * at_start + share * next_start)

    def _settling_weights(self, share: float = 0.0) -> np.ndarray:
        """Weight of each current sample in :meth:`_settling` (as :meth:`noise_weights`)."""
        g = acceleration_kernel(self.half_width, self.sig.dt_s)
        zero = np.zeros(1)
        at_start = self.sig.dt_s * (np.concatenate([g, zero, zero])
                                    - np.concatenate([zero, g, zero]))
        next_start = np.concatenate([zero, at_start[:-1]])
        return np.asarray((1.0 - share) * at_start + share * next_start)

    def current_change(self, delay: int) -> np.ndarray:
        """The current's change over the period after each sample, ``i[n + 1] − i[n]``
        of the current read ``delay`` samples late."""
        current = shifted(self.sig.current, delay)
        return np.asarray(interval_current(current, 1.0) - interval_current(current, 0.0))

    def change_mask(self, delay: int, kind: str) -> np.ndarray:
        """1 on the periods of one ``kind`` of current change, 0 on the others.

        ``ramp``: the change goes on into the next period beyond the noise
        (:data:`RAMP_SIGMAS`) and beyond a settling loop's tail
        (:data:`RAMP_CARRIED_SHARE`); ``settle``: not a ramp, and beyond the noise (a
        step the current loop settles); ``drift``: neither (:data:`DRIFT_WEIGHT`);
        ``steady``: settle or drift (every period that is no ramp). A run whose noise
        floor is above all of its steps has no drift: the data cannot tell a step from a
        drift, and every period that is no ramp settles with the timing column's ``w``.
        """
        key = ("change masks", delay)
        if key not in self.cache:
            step = self.current_change(delay)
            following = np.concatenate([step[1:], [0.0]])
            floor = RAMP_SIGMAS * np.sqrt(2.0) * noise_sigma(self.sig.current)
            beyond = np.abs(step) > floor
            ramp = (beyond & (np.abs(following) > floor) & (step * following > 0)
                    & (np.abs(following) >= RAMP_CARRIED_SHARE * np.abs(step)))
            settle = beyond & ~ramp
            if not settle.any():  # no step beyond the noise: the timing column takes all
                settle = ~ramp
            self.cache[key] = np.stack([ramp, settle, ~(ramp | settle)]).astype(float)
        ramp, settle, drift = self.cache[key]
        return np.asarray({"ramp": ramp, "settle": settle, "drift": drift,
                           "steady": settle + drift}[kind])

    def ramp_mask(self, delay: int, ramp: bool) -> np.ndarray:
        """:meth:`change_mask` of the ramps when ``ramp``, of every other period when not."""
        return self.change_mask(delay, "ramp" if ramp else "steady")

    @staticmethod
    def _change_kind(spec: ModelSpec, name: str) -> str:
        """The periods whose change column ``name`` carries: the ramps for the ramp's
        column; the drifts (periods that settle no step) for the drift's; for the timing
        column, the settled steps where it carries the loop's settling (the drifts then
        hold ``w = ½``, :data:`DRIFT_WEIGHT`), every period that is no ramp where it is a
        free timing of the held current."""
        if name == RAMP_COLUMN:
            return "ramp"
        if name == DRIFT_COLUMN:
            return "drift"
        return "settle" if SETTLING_AT_START and spec.input_weight == 0.0 else "steady"

    def noise_weights(self, weight: float = 0.5) -> np.ndarray:
        """Weight of each current sample in the filtered held current of ``input_weight``
        ``weight`` (the period integrals of the columns' kernel,
        :func:`~stand.ident.derivatives.acceleration_interval_weights`)."""
        weights = acceleration_interval_weights(self.half_width, self.sig.dt_s)
        return np.asarray((1 - weight) * np.concatenate([[0.0], weights])
                          + weight * np.concatenate([weights, [0.0]]))

    def noise_level(self) -> tuple[float, float]:
        """Variance (A²) of white noise that passes the kernel as the current's noise
        does, and its relative uncertainty.

        Two estimates, each at least the noise (the signal only adds to it): the white
        level from the sample-to-sample differences
        (:func:`~stand.ident.noise.noise_sigma`, uncertain by the disagreement of first
        and second differences, :func:`~stand.ident.noise.noise_variance_uncertainty`),
        and the least level of the spectrum above the kernel's passband
        (:func:`~stand.ident.noise.passband_noise`): lower where the noise is coloured
        towards high frequencies, higher where a broadband command fills the spectrum.
        The smaller is taken.
        """
        key = ("noise level",)
        if key not in self.cache:
            cutoff = 1.0 / (2.0 * (self.half_width + 1) * self.sig.dt_s)
            white = (noise_sigma(self.sig.current) ** 2,
                     noise_variance_uncertainty(self.sig.current))
            band = passband_noise(self.sig.current, self.sig.dt_s, cutoff)
            self.cache[key] = np.array(min(white, band))
        variance, uncertainty = self.cache[key]
        return float(variance), float(uncertainty)

    def filtered_noise(self, weight: float = 0.5) -> tuple[float, float]:
        """Variance of the current noise after the kernel (A²) and its relative uncertainty.

        White noise of the variance :meth:`noise_level` gives keeps ``σ²·Σ e²`` after the
        kernel, with ``e`` the weight of each sample in the held current of
        ``input_weight`` ``weight``.
        """
        variance, uncertainty = self.noise_level()
        return variance * float(np.sum(self.noise_weights(weight) ** 2)), uncertainty

    def noise_gram(self, spec: ModelSpec, names: list[str], rows: np.ndarray,
                   settling_share: float = 0.0) -> np.ndarray:
        """What the current noise adds to ``XᵀX`` of ``matrices(spec, False, timing)``.

        The noise of a current column ``j`` is ``Σ_s e_j[s]·n[s]·m_j`` with ``e_j`` the
        weights of the samples in it (:meth:`noise_weights`; for the timing column the
        difference of those of ``w = 1`` and ``w = 0``) and ``m_j`` its multiplier (1, or
        the ripple's ``sin Nθ``/``cos Nθ``); summed over the rows, the product of two such
        columns has the mean ``σ²·(e_j·e_l)·Σ m_j·m_l``. Bias-compensated least squares
        subtracts it.
        """
        sigma2, _ = self.noise_level()
        own = self.noise_weights(spec.input_weight)
        ones = np.ones(len(self.sig))
        step = self.noise_weights(1.0) - self.noise_weights(0.0)
        settles = self._settles(spec, names)
        sources: dict[str, list[tuple[np.ndarray, np.ndarray]]] = {}
        for name in names:
            if name == "current":
                sources[name] = [(own, ones)]
                if settles:
                    mask = self.change_mask(spec.delay, "settle")
                    sources[name].append((step - self._settling_weights(settling_share), mask))
                    sources[name].append((DRIFT_WEIGHT * step,
                                          self.change_mask(spec.delay, "drift")))
            elif name == TIMING_COLUMN and settles:
                sources[name] = [(self._settling_weights(settling_share),
                                  self.change_mask(spec.delay, "settle"))]
            elif name in (TIMING_COLUMN, RAMP_COLUMN):
                sources[name] = [(step, self.ramp_mask(spec.delay, name == RAMP_COLUMN))]
            elif name in RIPPLE_COLUMNS:
                weights = self.noise_weights(1.0) if settles else own
                sources[name] = [(weights, periodic_column(spec.ripple_N or 0, self.sig,
                                                           name == "rip_sin"))]
        h = self.half_width
        out = np.zeros((len(names), len(names)))
        for j, a in enumerate(names):
            for k, b in enumerate(names):
                if a in sources and b in sources:
                    for ea, ma in sources[a]:
                        for eb, mb in sources[b]:
                            product = (ma * mb)[h:len(self.sig) - h][rows]
                            out[j, k] += sigma2 * float(ea @ eb) * float(np.sum(product))
        return out

    def rows(self, spec: ModelSpec, instrumented: bool = True) -> np.ndarray:
        """Rows of ``matrices(spec, instrumented)`` within the filtered signals: the
        :attr:`moving` ones, but those within ``lag`` of either end (where the instrument
        is padded) and the delay's last samples."""
        lag = self.lag if instrumented else 0
        return lag + np.flatnonzero(self.moving[lag:len(self.alpha) - max(lag, spec.delay)])

    def matrices(self, spec: ModelSpec, instrumented: bool = True, timing: bool = False,
                 settling_share: float = 0.0
                 ) -> tuple[list[str], np.ndarray, np.ndarray, np.ndarray]:
        """Names, output ``y = θ''``, regressors ``X`` and instruments ``Z`` of ``spec``.

        The columns are ``θ`` (only with ``spec.spring``), ``θ'``, then the inputs of
        ``spec.names()``; rows within ``lag`` of either end (where the instrument is
        padded) and the delay's last samples are dropped. Not ``instrumented``: ``Z = X``
        on every row. ``timing``: the :data:`TIMING_COLUMN` follows the current, so the
        current over the period is ``i[n + k] + w'·(i[n + k + 1] − i[n + k])`` on top of
        ``spec.input_weight`` with ``w'`` fitted (a drive's current loop settles within
        the period at a time of its own: a first-order loop of time constant ``τ`` gives
        the period mean ``w = 1 − τ/Δt``, which the grid of 0, ½, 1 would miss). Where
        the current ramps on into the next period (:meth:`ramp_mask`), its change is the
        :data:`RAMP_COLUMN` instead, with a ``w`` of its own. ``settling_share``: where
        in the period the timing column places the loop's settling (:meth:`_settling`).
        """
        inputs = spec.names()
        if timing:
            inputs.insert(1, TIMING_COLUMN)
            if np.any(self.ramp_mask(spec.delay, True)):
                inputs.insert(2, RAMP_COLUMN)
        names = (["theta"] if spec.spring else []) + ["omega"] + inputs
        motion = {"theta": self.theta, "omega": self.omega}

        def col(name: str, instrument: bool) -> np.ndarray:
            if name in motion:
                return motion[name]
            if self._settles(spec, names):
                if name == TIMING_COLUMN:
                    return self._settling(spec, instrument, settling_share)
                if name == "current":  # held at the period's end, less the settling; the
                    # periods that settle no step at the mean of their end samples
                    return (self.column(spec, name, instrument)
                            + self.column(spec, TIMING_COLUMN, instrument)
                            - self._settling(spec, instrument, settling_share)
                            + self.column(spec, DRIFT_COLUMN, instrument))
                if name in RIPPLE_COLUMNS:
                    return self.column(replace(spec, input_weight=1.0), name, instrument)
            return self.column(spec, name, instrument)

        X = np.column_stack([col(n, False) for n in names])
        Z = X if not (instrumented and self.lag) else np.column_stack(
            [col(n, True) for n in names])
        keep = self.rows(spec, instrumented)
        return names, self.alpha[keep], X[keep], Z[keep]
