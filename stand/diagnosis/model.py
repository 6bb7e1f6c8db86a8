"""The nominal model of seed 000 and its extensions: regressors, fit and free-run simulation.

Every model is ``J·θ'' + D·θ' + C·θ = Kt·i + extensions``, written per unit inertia::

    θ'' = c_θ·θ + c_ω·θ' + c_i·i(t + k·Δt) + Σ_j c_j·φ_j(θ, θ', i)

with the states ``x = [θ, θ']`` and the inputs ``u = [i, φ_1, φ_2, ...]`` of the Q-matrix
solver (:mod:`stand.ident.qmatrix`, seed 000 eq. 10); the extension regressors ``φ_j``
enter as extra input columns. The fit uses the filtered signals of
:mod:`stand.diagnosis.signals` (equation error); the nonlinear hyper-parameters (delay
``k``, order ``N``, Stribeck velocity, backlash gap) are fixed by :class:`ModelSpec`.

Simulation (:func:`stand.diagnosis.simulate.simulate`) runs a fitted model free over
segments of HOLDOUT, re-anchored at the start of each, driven only by the measured
current; the same segments are used for every candidate.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from stand.diagnosis import kicks, supply_limit
from stand.diagnosis.backlash_load import load_state
from stand.diagnosis.coupling_load import coupling_state
from stand.diagnosis.dry_friction import period_mean
from stand.diagnosis.signals import Signals, near_rest
from stand.diagnosis.smooth_drag import drag_mean
from stand.errors import InputError, NotExcitedError
from stand.ident.qmatrix import QSums, solve
from stand.runfile import CURRENT_MEAN_COLUMN, Run

#: Samples dropped at each end of a run in the fit (filter and shift transients).
EDGE_SAMPLES = 50
#: Reach of the zero-phase filter's kernel on either side, samples: beyond it lies less
#: than 0.2 % of its weight (:func:`stand.diagnosis.signals.lowpass`).
FILTER_REACH_SAMPLES = 12
#: Least stretch of periods with an unchanged angle that the fit leaves out with the
#: filter's reach around it (:func:`fit_rows`). Three, not the identification's two: a
#: shaft reversing across one encoder count under a sine spends two periods there, and
#: the filter's reach around every reversal would take the low speeds that tell
#: Stribeck friction from Coulomb friction (fresh seed 251 case 40, Ts four times Tc:
#: called Coulomb friction with two, Stribeck friction with three; a loop resting
#: hundreds of periods is named Coulomb friction with either).
MIN_REST_PERIODS = 3
#: Input columns of a second inertia's acceleration, coefficient ``−J_load/J``: behind a
#: backlash, and behind a compliant coupling (fitted alike, :func:`_from_fitting_form`).
LOAD_COLUMNS: tuple[str, ...] = ("load_accel", "coupling_accel")
#: Largest load inertia behind a backlash, relative to the motor's, that a fit may give.
MAX_LOAD_RATIO = 1000.0
#: The share ``J_l/(J + J_l)`` of such a load.
MAX_LOAD_SHARE = MAX_LOAD_RATIO / (1.0 + MAX_LOAD_RATIO)
#: Input columns of a speed loop's kicks (:mod:`.kicks`, :func:`kick_basis`).
KICK_COLUMNS = tuple(f"kick{j}" for j in range(kicks.COLUMNS))
#: Input columns of the current's shape where the drive's voltage is at its supply
#: (:mod:`.supply_limit`, :func:`supply_basis`).
SUPPLY_COLUMNS = tuple(f"supply_{name}" for name in supply_limit.CLASSES)
#: Velocity resolution of a run, in encoder counts per sample period (of the filtered
#: velocity, which averages over several samples).
VELOCITY_RESOLUTION_COUNTS = 0.4


@dataclass(frozen=True)
class ModelSpec:
    """Which extensions a model has (all off: the nominal model of seed 000).

    Attributes
    ----------
    delay : int
        Samples the current lags the encoder (the model uses ``i[n + delay]``).
    offset : bool
        A constant torque term (a current-sensor offset ``i0``).
    coulomb : bool
        A ``sign(ω)`` friction term.
    stribeck_ws : float or None
        Stribeck velocity of a ``sign(ω)·exp(−(ω/ωs)²)`` term, rad/s.
    cogging_N : int or None
        Order of ``sin(Nθ)``, ``cos(Nθ)`` torque terms, cycles per revolution.
    ripple_N : int or None
        Order of ``i·sin(Nθ)``, ``i·cos(Nθ)`` torque terms.
    backlash_gap : float or None
        Half width of a dead zone to a load inertia, rad. The kinematic load estimate
        (:func:`~stand.diagnosis.backlash_load.load_estimate`) gives the load's
        acceleration (carried along, or coasting in the gap, with momentum exchanged at
        each impact); the regressor ``load_accel`` with coefficient ``−J_load/J`` is the
        torque the load takes.
    backlash_restitution : float
        Coefficient of restitution of the backlash contact: 0 carries the load along
        after an impact, ``e > 0`` lets it rebound (relative speed ``−e`` times that
        before the impact), as gear teeth do.
    coupling_hz : float or None
        Mode of a load inertia on a compliant coupling (no dead zone), Hz: not a
        vocabulary effect, the competitor a backlash verdict is checked against
        (:mod:`.coupling`). The load follows the measured motion through the mode
        (:func:`~stand.diagnosis.coupling_load.coupling_state`); the regressor
        ``coupling_accel`` with coefficient ``−J_load/J`` is the torque it takes. Never
        beside ``backlash_gap``.
    coupling_zeta : float
        Damping ratio of that mode.
    drag_ws : float or None
        Speed scale of a drag continuous through zero speed, ``tanh(ω/ω_d)``, rad/s:
        not a vocabulary effect, the competitor a dry friction verdict is checked
        against in the friction's place (:mod:`.drag`; beside it only to see whether
        the friction stays).
    load_friction : bool
        A friction level that grows with the torque carried, ``|i|·sign(ω)`` (a gear
        mesh's load-dependent loss): not a vocabulary effect, the competitor a dry
        friction verdict is checked against beside its friction (:mod:`.load_friction`).
    input_weight : float
        How the current between two samples is reconstructed: over the period from
        sample ``n`` to ``n + 1`` it is ``(1 − w)·i[n] + w·i[n + 1]``. ``0.5`` is the
        trapezoid (a smooth current); ``1`` a drive that reads, then actuates, with a
        current loop much faster than the sample period (the current settles at the
        next sample's value right after each sample). Part of the nominal model's input
        reconstruction, picked once on TRAIN and shared by every candidate.
    spring : bool
        Whether the ``C·θ`` term of seed 000 is in the model (``C = 0`` otherwise; see
        :func:`stand.diagnosis.engine.diagnose`).
    """

    delay: int = 0
    offset: bool = False
    coulomb: bool = False
    stribeck_ws: float | None = None
    cogging_N: int | None = None
    ripple_N: int | None = None
    backlash_gap: float | None = None
    backlash_restitution: float = 0.0
    coupling_hz: float | None = None
    coupling_zeta: float = 0.0
    drag_ws: float | None = None
    load_friction: bool = False
    input_weight: float = 0.5
    spring: bool = False
    #: Whether the speed loop's kicks of the current between samples are in the input
    #: (:mod:`.kicks`: its columns ``kick0``, ``kick1``, ... fitted with the others).
    #: Part of the input reconstruction with ``input_weight``, picked with it on TRAIN.
    kicks: bool = False
    #: The classes of periods where the drive's voltage is at its supply whose share of
    #: the current's change is in the input (:mod:`.supply_limit`: columns
    #: ``supply_<class>`` fitted with the others; empty: none). Picked with
    #: ``input_weight`` on TRAIN, like ``kicks``.
    supply: tuple[str, ...] = ()
    #: Whether the error of the drive's lag in a speed law's current (fitted on each run
    #: by the law, :mod:`stand.ident.speed_loop`) is refined with the model: column
    #: ``lag``, the current's change per share of a period of lag
    #: (``Signals.lag_slopes``). Picked on TRAIN with the law's current.
    lag: bool = False

    def names(self) -> list[str]:
        """Names of the input columns ``u`` (``current`` first)."""
        out = ["current"]
        if self.offset:
            out.append("one")
        if self.coulomb or self.stribeck_ws is not None:
            out.append("sign")
        if self.stribeck_ws is not None:
            out.append("stribeck")
        if self.drag_ws is not None:
            out.append("drag")
        if self.load_friction:
            out.append("load_friction")
        if self.cogging_N is not None:
            out += ["cog_sin", "cog_cos"]
        if self.ripple_N is not None:
            out += ["rip_sin", "rip_cos"]
        if self.backlash_gap is not None:
            out.append("load_accel")
        if self.coupling_hz is not None:
            out.append("coupling_accel")
        if self.kicks:
            out += list(KICK_COLUMNS)
        out += [f"supply_{name}" for name in self.supply]
        if self.lag:
            out.append("lag")
        return out

    def merged(self, other: ModelSpec) -> ModelSpec:
        """A model with the extensions of both."""
        return ModelSpec(
            delay=max(self.delay, other.delay), offset=self.offset or other.offset,
            coulomb=self.coulomb or other.coulomb,
            stribeck_ws=other.stribeck_ws if other.stribeck_ws is not None else self.stribeck_ws,
            cogging_N=other.cogging_N if other.cogging_N is not None else self.cogging_N,
            ripple_N=other.ripple_N if other.ripple_N is not None else self.ripple_N,
            backlash_gap=(other.backlash_gap if other.backlash_gap is not None
                          else self.backlash_gap),
            backlash_restitution=(other.backlash_restitution if other.backlash_gap is not None
                                  else self.backlash_restitution),
            coupling_hz=other.coupling_hz if other.coupling_hz is not None else self.coupling_hz,
            coupling_zeta=(other.coupling_zeta if other.coupling_hz is not None
                           else self.coupling_zeta),
            drag_ws=other.drag_ws if other.drag_ws is not None else self.drag_ws,
            load_friction=self.load_friction or other.load_friction,
            input_weight=self.input_weight, spring=self.spring,
            kicks=self.kicks, supply=self.supply, lag=self.lag,
        )


@dataclass(frozen=True)
class FittedModel:
    """A model identified on one run.

    Attributes
    ----------
    spec : ModelSpec
        Its structure.
    c_theta, c_omega : float
        ``−C/J`` (1/s²) and ``−D/J`` (1/s).
    coef : dict of str to float
        Coefficient of each input column, in rad/s² per unit of the column
        (``current``: ``Kt/J``).
    residual_rms : float
        RMS equation error on the fitting run, rad/s².
    condition_number : float
        Of the scaled regressor matrix.
    """

    spec: ModelSpec
    c_theta: float
    c_omega: float
    coef: dict[str, float]
    residual_rms: float
    condition_number: float
    samples: int
    c_theta_se: float = 0.0


def shifted(values: np.ndarray, k: int) -> np.ndarray:
    """``values[n + k]`` (the last value repeated past the end)."""
    if k <= 0:
        return values
    return np.concatenate([values[k:], np.repeat(values[-1], k)])


def interval_current(current: np.ndarray, weight: float) -> np.ndarray:
    """Current over the period after each sample, ``(1 − w)·i[n] + w·i[n + 1]``."""
    following = np.concatenate([current[1:], current[-1:]])
    return (1.0 - weight) * current + weight * following


def period_mean_current(run: Run) -> np.ndarray:
    """The current over the period after each sample (a model's input at
    :data:`~stand.diagnosis.input_weight.PERIOD_MEAN_WEIGHT`) from the drive's current
    averaged over the period that ends at each sample (``current_mean_A``): the next
    row's (:func:`interval_current` at weight 1), the last period's repeated at the end.

    Raises
    ------
    RunFileError
        The run has no ``current_mean_A``.
    """
    return interval_current(np.asarray(run[CURRENT_MEAN_COLUMN], dtype=float), 1.0)


#: Weights of the four sample periods around a sample (from two before to two after)
#: in the acceleration estimate: the second central difference over ±2 samples (the
#: central difference of the central difference) is the mean of the true acceleration
#: under a triangle of ±2 periods, whose area over those periods is 1/8, 3/8, 3/8, 1/8.
DIFFERENCE_KERNEL = (0.125, 0.375, 0.375, 0.125)


#: Weights of the same four periods for an angle moved at each period's end (a current's
#: shape within the period, ``Signals.current_shape``): the second central difference
#: over ±2 samples reads ``(s[n] + s[n + 1] − s[n − 1] − s[n − 2])/8`` of it.
BEND_KERNEL = (-0.125, -0.125, 0.125, 0.125)


def bend_at_samples(shape: np.ndarray) -> np.ndarray:
    """What a current's shape within its periods (its ramp-weighted mean above its mean,
    ``Signals.current_shape``) gives at the sample instants in the acceleration
    estimate, per unit of the current's gain: it moves the angle by ``(Δt²/2)·shape`` at
    each period's end (:data:`BEND_KERNEL`)."""
    return at_samples(shape, BEND_KERNEL)


def at_samples(per_interval: np.ndarray,
               kernel: tuple[float, ...] = DIFFERENCE_KERNEL) -> np.ndarray:
    """What a torque held at ``per_interval[n]`` over each period ``n .. n + 1`` gives at
    the sample instants in the acceleration estimate (:data:`DIFFERENCE_KERNEL`, or
    another ``kernel`` over the same four periods)."""
    padded = np.concatenate([per_interval[:1], per_interval[:1], per_interval,
                             per_interval[-1:]])
    n = len(per_interval)
    out = np.zeros(n)
    for k, w in enumerate(kernel):
        out += w * padded[k:k + n]
    return out


def _sampled_current(spec: ModelSpec, sig: Signals) -> np.ndarray:
    """The current over the period after each sample as ``spec`` reconstructs it from
    the samples of ``sig`` alone (shifted by its ``delay``, weighted by its
    ``input_weight``: :func:`interval_current`), A."""
    return interval_current(shifted(sig.current, spec.delay), spec.input_weight)


def period_current(model: FittedModel, sig: Signals) -> np.ndarray:
    """The current over the period after each sample that drives ``model`` on ``sig``,
    A: the samples' reconstruction (``delay``, ``input_weight``), and where the model
    has them, the speed loop's kicks between samples (:mod:`.kicks`) in current units
    (their fitted torque over the current's)."""
    spec = model.spec
    current = _sampled_current(spec, sig)
    if spec.kicks:
        gains = np.array([model.coef[name] for name in KICK_COLUMNS])
        current = current + kick_basis(sig) @ gains / model.coef["current"]
    if spec.supply:
        shares = np.array([model.coef[f"supply_{name}"] for name in spec.supply])
        current = (current + supply_basis(sig, spec.delay, spec.supply) @ shares
                   / model.coef["current"])
    if spec.lag:
        current = current + lag_share(model) * interval_current(lag_slope(sig, spec, 0),
                                                                spec.input_weight)
    return current


def period_shape(model: FittedModel, sig: Signals) -> np.ndarray | None:
    """How much the current's ramp-weighted mean over the period after each sample
    exceeds its mean under ``model`` on ``sig`` (A; ``Signals.current_shape`` shifted by
    the model's delay, with its lag refinement where the model has one), or None where
    the current is held over each period."""
    if sig.current_shape is None:
        return None
    spec = model.spec
    shape = shifted(sig.current_shape, spec.delay)
    if spec.lag:
        shape = shape + lag_share(model) * lag_slope(sig, spec, 1)
    return shape


def lag_share(model: FittedModel) -> float:
    """The share of a period by which ``model`` corrects the drive's lag in the speed
    law's current (0 without the ``lag`` column)."""
    return model.coef.get("lag", 0.0) / model.coef["current"]


def lag_slope(sig: Signals, spec: ModelSpec, row: int) -> np.ndarray:
    """Row ``row`` of ``sig.lag_slopes`` (0: the current's, 1: its shape's), shifted by
    ``spec``'s delay as the current is."""
    if sig.lag_slopes is None:
        raise InputError(f"{sig.source}: no speed law's current, so no lag to refine")
    return shifted(sig.lag_slopes[row], spec.delay)


def kick_basis(sig: Signals) -> np.ndarray:
    """:func:`stand.diagnosis.kicks.basis` of ``sig``'s target changes (cached on it)."""
    if sig.target_change is None:
        raise InputError(f"{sig.source}: no speed target, so no kicks of a speed loop")
    if ("kicks",) not in sig.cache:
        sig.cache["kicks",] = kicks.basis(sig.target_change, sig.omega_meas)
    return sig.cache["kicks",]


def supply_classes(sig: Signals) -> tuple[str, ...]:
    """The classes of periods at the drive's supply whose shares the models of ``sig``
    may fit (:func:`stand.diagnosis.supply_limit.classes`): none under a speed loop
    (a run that holds its target), whose current over a period is the loop's, not a
    step to a command; there its kicks are the input's (:mod:`.kicks`)."""
    if sig.at_supply is None or sig.target_change is not None:
        return ()
    return supply_limit.classes(sig.current, sig.at_supply)


def supply_within_period(model: FittedModel) -> bool:
    """Whether ``model``'s shares of the current's change at the supply
    (:mod:`.supply_limit`) keep the current over each such period between its two
    samples: ``0 ≤ w + s ≤ 1`` with ``w`` the input weight, as any current that moves
    from one sample to the next without overshooting them does. A share beyond takes
    something else than the current's shape (noise on a few periods, a friction's
    torque at the supply), and the models carry it to HOLDOUT (on the benchmark:
    shares of +1.4 and −11 fitted on 70 and 28 periods). True without shares."""
    w = model.spec.input_weight
    gain = model.coef["current"]
    return all(0.0 <= w + model.coef[f"supply_{name}"] / gain <= 1.0
               for name in model.spec.supply) if gain > 0 else not model.spec.supply


def supply_basis(sig: Signals, delay: int, names: tuple[str, ...]) -> np.ndarray:
    """:func:`stand.diagnosis.supply_limit.basis` of classes ``names`` of ``sig``'s
    current read ``delay`` samples late (cached on it); zeros on a run whose voltage
    never sits at a supply (a model picked on TRAIN, simulated on a HOLDOUT that stays
    below it)."""
    key = ("supply", delay, *names)
    if key not in sig.cache:
        sig.cache[key] = supply_limit.basis(shifted(sig.current, delay), sig.at_supply, names)
    return sig.cache[key]


def sample_current(current: np.ndarray, weight: float) -> np.ndarray:
    """Current at each sample instant consistent with :func:`interval_current`."""
    return at_samples(interval_current(current, weight))


#: Where ``sin(x)/x`` is taken at x = 0 (as ``np.sinc`` does).
_EPS = float(np.finfo(float).eps)


def periodic_mean(order: int, theta: np.ndarray,
                  step: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Means of ``sin(N·θ)`` and ``cos(N·θ)`` while ``θ`` moves linearly from ``theta``
    by ``step`` (rad): the value at the midpoint times ``sinc(N·step/2)``.

    A position-periodic torque of order ``N`` turns through ``N·step`` radians within a
    sample period at speed; its value at the sample instant is then aliased, while its
    mean over the period is what changes the sampled speed."""
    middle = order * (theta + 0.5 * step)
    # np.sinc(N·step/2π), without its per-call overhead (the simulation calls this at
    # every sub-step): sin(x)/x of x = π·(N·step/2π), and 1 at x = 0
    x = np.pi * (order * step / (2.0 * np.pi))
    x = np.where(x, x, _EPS)
    damping = np.sin(x) / x
    return np.sin(middle) * damping, np.cos(middle) * damping



def periodic_column(order: int, sig: Signals, sine: bool) -> np.ndarray:
    """Mean of ``sin(N·θ)`` (or cos) over the period after each sample, the filtered
    position taken as moving linearly between samples (both computed once per order
    and cached on ``sig``: the two columns of an order are always used together)."""
    key = ("periodic", order)
    if key not in sig.cache:
        theta = sig.theta_f
        step = np.concatenate([np.diff(theta), [0.0]])
        sig.cache[key] = np.stack(periodic_mean(order, theta, step))
    return sig.cache[key][0 if sine else 1]


def _column_key(spec: ModelSpec, name: str) -> tuple[object, ...]:
    """What input column ``name`` of ``spec`` depends on (the key of the filter cache)."""
    if name in KICK_COLUMNS:
        return (name,)
    if name in SUPPLY_COLUMNS:
        return (name, spec.delay)
    current = (spec.delay, spec.input_weight)
    return {
        "current": ("current", *current), "lag": ("lag", *current), "one": ("one",),
        "sign": ("sign",),
        "stribeck": ("stribeck", spec.stribeck_ws), "drag": ("drag", spec.drag_ws),
        "cog_sin": ("cog_sin", spec.cogging_N),
        "cog_cos": ("cog_cos", spec.cogging_N), "rip_sin": ("rip_sin", spec.ripple_N, *current),
        "rip_cos": ("rip_cos", spec.ripple_N, *current),
        "load_friction": ("load_friction", *current),
        "load_accel": ("load", spec.backlash_gap, spec.backlash_restitution),
        "coupling_accel": ("coupling", spec.coupling_hz, spec.coupling_zeta),
    }[name]


def _column(spec: ModelSpec, sig: Signals, name: str) -> np.ndarray:
    """Unfiltered input column ``name`` of ``spec`` on the measured run ``sig``."""
    theta = sig.theta_f
    if name == "current":
        column = sample_current(shifted(sig.current, spec.delay), spec.input_weight)
        if sig.current_shape is not None:
            column = column + bend_at_samples(shifted(sig.current_shape, spec.delay))
        return column
    if name == "lag":
        return (sample_current(lag_slope(sig, spec, 0), spec.input_weight)
                + bend_at_samples(lag_slope(sig, spec, 1)))
    if name in KICK_COLUMNS:
        return at_samples(kick_basis(sig)[:, KICK_COLUMNS.index(name)])
    if name in SUPPLY_COLUMNS:
        return at_samples(supply_basis(sig, spec.delay, (name.removeprefix("supply_"),))[:, 0])
    if name == "one":
        return np.ones(len(theta))
    if name == "sign":
        return at_samples(period_mean(friction_speed(sig)))
    if name == "stribeck":
        return at_samples(period_mean(friction_speed(sig), spec.stribeck_ws or 1.0))
    if name == "drag":
        return at_samples(drag_mean(friction_speed(sig), spec.drag_ws or 1.0))
    if name == "load_friction":
        current = _sampled_current(spec, sig)
        return at_samples(np.abs(current) * period_mean(friction_speed(sig)))
    if name in ("cog_sin", "cog_cos"):
        return at_samples(periodic_column(spec.cogging_N or 0, sig, name == "cog_sin"))
    if name in ("rip_sin", "rip_cos"):
        current = _sampled_current(spec, sig)
        periodic = periodic_column(spec.ripple_N or 0, sig, name == "rip_sin")
        return at_samples(current * periodic)
    if name in LOAD_COLUMNS:
        return np.asarray(np.gradient(load_motion(spec, sig)[1], sig.dt_s))
    raise InputError(f"unknown input column {name!r}")


def load_motion(spec: ModelSpec, sig: Signals) -> np.ndarray:
    """Position (rad) and speed (rad/s) of ``spec``'s load estimated from the measured
    motion of ``sig``: on a compliant coupling through its mode
    (:func:`~stand.diagnosis.coupling_load.coupling_state`), else behind the backlash gap
    (:func:`~stand.diagnosis.backlash_load.load_state`)."""
    if spec.coupling_hz is not None:
        return coupling_state(sig, spec.coupling_hz, spec.coupling_zeta)
    return load_state(sig, spec.backlash_gap or 0.0, spec.backlash_restitution)


def regressors(spec: ModelSpec, sig: Signals) -> dict[str, np.ndarray]:
    """Unfiltered input columns of ``spec`` on the measured run ``sig``."""
    return {name: _column(spec, sig, name) for name in spec.names()}


def filtered_inputs(spec: ModelSpec, sig: Signals) -> np.ndarray:
    """The input columns of ``spec`` through the run's low-pass, shape (samples, columns)."""
    return np.column_stack([_filtered_column(spec, sig, name) for name in spec.names()])


def _filtered_column(spec: ModelSpec, sig: Signals, name: str) -> np.ndarray:
    """Input column ``name`` of ``spec`` through the run's low-pass, cached on ``sig``
    (columns are reused across the searches)."""
    key = _column_key(spec, name)
    if key not in sig.cache:
        sig.cache[key] = sig.filt(_column(spec, sig, name))
    return sig.cache[key]


def _prefetch(specs: list[ModelSpec], sig: Signals) -> None:
    """Filter the columns of ``specs`` not yet cached on ``sig`` in one pass of the
    low-pass (a search's specs bring dozens of new columns at once)."""
    missing: dict[tuple[object, ...], tuple[ModelSpec, str]] = {}
    for spec in specs:
        for name in spec.names():
            key = _column_key(spec, name)
            if key not in sig.cache:
                missing.setdefault(key, (spec, name))
    if len(missing) < 2:
        return
    raw = np.stack([_column(spec, sig, name) for spec, name in missing.values()])
    for key, column in zip(missing, sig.filt(raw, axis=1), strict=True):
        sig.cache[key] = column


def velocity_resolution(sig: Signals) -> float:
    """The run's velocity resolution, rad/s: ``VELOCITY_RESOLUTION_COUNTS`` encoder
    steps per sample period."""
    return VELOCITY_RESOLUTION_COUNTS * sig.quant_rad / sig.dt_s


def friction_speed(sig: Signals) -> np.ndarray:
    """Speed at the sample instants the friction columns follow, rad/s: the central
    difference of the measured position (the low-passed speed rounds off the kink
    friction makes at a zero crossing, and crosses zero late), zero where it is below
    the velocity resolution of the run (a shaft at rest, or quantization)."""
    omega = sig.omega_meas
    return np.where(np.abs(omega) > velocity_resolution(sig), omega, 0.0)


def velocity_sign(omega: np.ndarray, sig: Signals) -> np.ndarray:
    """``sign(ω)``, zero where ``|ω|`` is below the velocity resolution of the run."""
    resolution = velocity_resolution(sig)
    return np.where(np.abs(omega) > resolution, np.sign(omega), 0.0)


def _fit_columns(spec: ModelSpec, sig: Signals) -> list[tuple[tuple[object, ...], np.ndarray]]:
    """The filtered input columns of ``spec`` as the fit uses them, each with its cache
    key: a backlash model's load column in its fitting form (:func:`_from_fitting_form`),
    the twist acceleration ``θ'' − θ_l''``."""
    out = []
    for name in spec.names():
        key, column = _column_key(spec, name), _filtered_column(spec, sig, name)
        if name in LOAD_COLUMNS:
            out.append((("twist", *key), sig.accel_f - column))
        else:
            out.append((key, column))
    return out


def fit_rows(sig: Signals, delay: int) -> np.ndarray:
    """Samples the fit takes: all but ``EDGE_SAMPLES`` at each end (and the delay's last),
    and but those within the filter's reach (:data:`FILTER_REACH_SAMPLES`, and a period
    more for breakaway and stop) of a stretch of the shaft at rest (at least
    :data:`MIN_REST_PERIODS`, :func:`~stand.diagnosis.signals.near_rest`): static
    friction holds any torque up to its breakaway level there, which no friction
    model's column knows, and a speed loop winding its current up against a stuck shaft
    would pull Kt/J towards zero (the simulation steps the sticking itself,
    :mod:`.dry_friction`)."""
    key = ("fit rows", delay)
    if key not in sig.cache:
        near = near_rest(sig.theta, FILTER_REACH_SAMPLES + 1, MIN_REST_PERIODS)
        rows = np.arange(EDGE_SAMPLES, len(sig) - EDGE_SAMPLES - delay)
        sig.cache[key] = rows[~near[rows]]
    return sig.cache[key]


def _stack(spec: ModelSpec, sig: Signals) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``ẋ``, ``x`` and ``u`` of the fit (:func:`_fit_columns`) on its rows (:func:`fit_rows`)."""
    u_f = np.column_stack([column for _, column in _fit_columns(spec, sig)])
    keep = fit_rows(sig, spec.delay)
    if spec.spring:
        x = np.column_stack([sig.theta_f, sig.omega_f])[keep]
        xdot = np.column_stack([sig.omega_f, sig.accel_f])[keep]
    else:  # the velocity row alone: x = [θ'], ẋ = [θ'']
        x, xdot = sig.omega_f[keep, None], sig.accel_f[keep, None]
    return xdot, x, u_f[keep]


def _from_fitting_form(spec: ModelSpec, A: np.ndarray, B: np.ndarray
                       ) -> tuple[np.ndarray, np.ndarray]:
    """Coefficients of a backlash model fitted in its fitting form, in the model's form.

    The model ``J·θ'' + J_l·θ_l'' = Kt·i − D·θ' − …`` is written per motor inertia with
    the load acceleration ``θ_l''`` as a regressor (coefficient ``−J_l/J``). Fitted that
    way it is an errors-in-variables problem: while the load is carried ``θ_l'' = θ''``,
    the output itself, so least squares gains by moving that coefficient towards
    ``+1`` (it shrinks the whole residual by ``1 − c``), whatever the gap; the equation
    error then no longer tells gaps apart. Fitted per total inertia instead,
    ``θ'' = (Kt·i − D·θ' − …)/(J + J_l) + c·(θ'' − θ_l'')`` with ``c = J_l/(J + J_l)``,
    the load column is the twist acceleration, zero while the load is carried, and the
    fit has no such direction. This converts back (every other coefficient times
    ``1/(1 − c)``, the load's ``−c/(1 − c)``); ``c ≤ 0`` gives a non-negative load
    coefficient, which the searches reject as unphysical, and ``c`` is held at the share
    of a load ``MAX_LOAD_RATIO`` times the motor's (:func:`_never_carried`).
    """
    load = _load_column(spec)
    if load is None:
        return A, B
    c = np.minimum(B[..., load], MAX_LOAD_SHARE)  # so 1 − c > 0
    gain = 1.0 / (1.0 - c)
    B = B * gain[..., None]
    B[..., load] = -c * gain
    return A * gain[..., None], B


def _load_column(spec: ModelSpec) -> int | None:
    """Index among ``spec``'s input columns of its load's (a backlash's or a compliant
    coupling's, :data:`LOAD_COLUMNS`), None without a load."""
    names = spec.names()
    return next((names.index(name) for name in LOAD_COLUMNS if name in names), None)


def _never_carried(spec: ModelSpec, B: np.ndarray) -> np.ndarray:
    """Where a backlash model fitted in its fitting form (coefficients ``B``, shape
    (specs, columns)) has a load share above ``MAX_LOAD_SHARE``: a load the run never
    carries (a gap wider than its travel). The twist acceleration is then the
    acceleration itself and the fit trivial (share 1), not a model; the searches skip
    it, and a fit of it elsewhere keeps the load at ``MAX_LOAD_RATIO``."""
    load = _load_column(spec)
    if load is None:
        return np.zeros(B.shape[0], dtype=bool)
    return np.asarray(B[:, load] > MAX_LOAD_SHARE)


def ripple_on_offset(spec: ModelSpec) -> bool:
    """Whether ``spec`` holds a torque ripple beside a current offset.

    A ripple multiplies the current the motor carries, ``Kt·(i − i0)·(1 + ε·sin(Nθ +
    φ))`` with ``i`` the measured current and ``i0`` the sensor's offset; fitted on the
    measured current alone, the model misses ``−Kt·i0·ε·sin(Nθ + φ)``, a cogging torque of
    the ripple's order, and a cogging candidate of that order takes it up (benchmark
    seed 279 case 189: a cogging of order 3 and 2.1 A named beside the planted offset of
    7.7 A and ripple of order 3 and ``ε`` 0.26, where ``ε·i0`` is 2.0 A). The model's
    ripple columns then act on ``i + one/current`` (:func:`fit` by a fixed point,
    :func:`equation_residual`, and the free run, :mod:`.simulate`), with no parameter
    added. The searches' equation errors (:func:`fit_residual_batch`) keep the measured
    current: they rank orders and hyper-parameters, which the cross term barely moves."""
    return spec.offset and spec.ripple_N is not None


#: Passes of :func:`fit`'s fixed point for a ripple beside a current offset: each pass
#: leaves about ``ε`` (the ripple's relative size, a few tenths) of the last one's error
#: in the offset's share of the ripple, so four leave about ``ε⁴`` of the first's.
RIPPLE_OFFSET_PASSES = 4


def offset_ripple(value: Callable[[str], float], positions: np.ndarray) -> np.ndarray:
    """What a ripple beside a current offset adds for acting on the true current
    (:func:`ripple_on_offset`), per inertia: ``(one/current)·(rip_sin·sin Nθ + rip_cos·
    cos Nθ)``, from the model's coefficients ``value(name)`` and ``positions`` (samples ×
    2: the sine and cosine of the ripple's order, in the columns' unit)."""
    ripple = np.array([value("rip_sin"), value("rip_cos")])
    return np.asarray(value("one") / value("current") * (positions @ ripple))


def _ripple_positions(spec: ModelSpec, sig: Signals) -> np.ndarray:
    """The filtered position terms of the ripple's order (samples × 2: sine, cosine),
    the cogging columns of that order."""
    order = ModelSpec(cogging_N=spec.ripple_N)
    return np.column_stack([_filtered_column(order, sig, "cog_sin"),
                            _filtered_column(order, sig, "cog_cos")])


def fit(spec: ModelSpec, sig: Signals) -> FittedModel:
    """Identify the model ``spec`` on ``sig`` with the Q-matrix solver (eq. 10).

    Raises
    ------
    NotExcitedError
        The run does not determine the model.
    """
    xdot, x, u = _stack(spec, sig)
    sums = QSums.zeros(x.shape[1], u.shape[1]).add(xdot, x, u, sig.dt_s)
    result = solve(sums)
    names = spec.names()
    if ripple_on_offset(spec):
        # the ripple multiplies the true current, i − i0 (i0 = −one/current): a torque
        # bilinear in the offset and the ripple, fitted by a fixed point on its share of
        # the position-periodic torque at the ripple's order (:func:`ripple_on_offset`)
        positions = _ripple_positions(spec, sig)[fit_rows(sig, spec.delay)]
        for _ in range(RIPPLE_OFFSET_PASSES):
            fitted = dict(zip(names, np.asarray(result.B)[-1], strict=True))
            target = xdot.copy()
            target[:, -1] -= offset_ripple(fitted.__getitem__, positions)
            result = solve(QSums.zeros(x.shape[1], u.shape[1]).add(target, x, u, sig.dt_s))
    A, B = _from_fitting_form(spec, np.asarray(result.A)[-1], np.asarray(result.B)[-1])
    coef = {name: float(B[j]) for j, name in enumerate(names)}
    if not coef["current"] > 0 and spec == ModelSpec():
        raise NotExcitedError(
            f"{sig.source}: the identified gain from current to acceleration is "
            f"{coef['current']:.3g}, not positive; check the sign of current_A against "
            "position_rad, or excite the motor more"
        )
    se = _from_fitting_form(spec, np.asarray(result.A_se)[-1], np.asarray(result.B)[-1])[0]
    c_theta_se = abs(float(se[0])) if spec.spring else 0.0
    return FittedModel(spec=spec, c_theta=float(A[0]) if spec.spring else 0.0,
                       c_omega=float(A[-1]), coef=coef, c_theta_se=c_theta_se,
                       residual_rms=float(np.asarray(result.residual_rms)[-1]),
                       condition_number=float(result.condition_number),
                       samples=int(result.samples))


def fit_residual_batch(specs: list[ModelSpec], sig: Signals) -> tuple[np.ndarray, np.ndarray]:
    """Equation-error RMS on ``sig`` of each of ``specs`` (same column layout), rad/s².

    The specs must have the same number of input columns; they are solved as one batch.
    Problems that cannot be solved (or give no finite model) give ``inf``. Also returns
    the input coefficients, shape (specs, columns), in the order of ``ModelSpec.names``.

    The specs of a search share most of their columns (the base model's) and differ in
    one or two, so the sums of eq. 10 are taken once over the distinct columns of the
    whole batch (one Gram matrix) and each spec's sums are its rows and columns of it:
    the same sums as stacking every spec's samples, without the copies.
    """
    sums = _batch_sums(specs, sig)
    result = solve(sums, check=False)
    rms = np.asarray(result.residual_rms)[:, -1]
    B_fitted = np.asarray(result.B)[:, -1, :]
    A, B = _from_fitting_form(specs[0], np.asarray(result.A)[:, -1, :], B_fitted)
    solved = (np.isfinite(rms) & np.isfinite(A).all(axis=1) & np.isfinite(B).all(axis=1)
              & ~_never_carried(specs[0], B_fitted))
    return np.where(solved, rms, np.inf), B


def _batch_sums(specs: list[ModelSpec], sig: Signals) -> QSums:
    """The Q-matrix sums of every spec of a batch of one delay, from the products of the
    columns all specs share with everything and of each spec's own columns with
    themselves (:func:`_fit_columns`); a batch of several delays is stacked per spec."""
    if len({spec.delay for spec in specs}) > 1:
        stacks = [_stack(spec, sig) for spec in specs]
        n = min(len(s[1]) for s in stacks)
        xdot = np.stack([s[0][:n] for s in stacks])
        x = np.stack([s[1][:n] for s in stacks])
        u = np.stack([s[2][:n] for s in stacks])
        return QSums.zeros(x.shape[2], u.shape[2], (len(specs),)).add(xdot, x, u, sig.dt_s)
    keep = fit_rows(sig, specs[0].delay)
    _prefetch(specs, sig)
    layouts = [dict(_fit_columns(spec, sig)) for spec in specs]
    shared = {k: v for k, v in layouts[0].items() if all(k in lay for lay in layouts)}
    own = [[k for k in lay if k not in shared] for lay in layouts]
    states = ([sig.omega_f, sig.accel_f, sig.theta_f, sig.omega_f] if specs[0].spring
              else [sig.accel_f, sig.omega_f])
    nx = len(states) // 2
    common = np.column_stack([*states, *shared.values(), np.ones(len(sig))])[keep]
    a, o = common.shape[1], len(own[0])
    G = np.empty((len(specs), a + o, a + o))
    G[:, :a, :a] = common.T @ common
    if o:  # each spec's own columns as rows (a copy of contiguous rows, not a transpose)
        mine = np.stack([lay[k] for lay, keys in zip(layouts, own, strict=True)
                         for k in keys])[:, keep]
        cross = (mine @ common).reshape(len(specs), o, a)
        G[:, :a, a:] = cross.transpose(0, 2, 1)
        G[:, a:, :a] = cross
        by_spec = mine.reshape(len(specs), o, -1)
        G[:, a:, a:] = by_spec @ by_spec.transpose(0, 2, 1)
    # from the order [states, shared, 1, own] to each spec's [states, its columns, 1]
    place = {k: 2 * nx + j for j, k in enumerate(shared)}
    index = np.array([[*range(2 * nx),
                       *(place[k] if k in place else a + keys.index(k) for k in lay),
                       a - 1] for lay, keys in zip(layouts, own, strict=True)])
    rows = np.arange(len(specs))[:, None, None]
    G = sig.dt_s * G[rows, index[:, :, None], index[:, None, :]]
    samples = np.full(len(specs), common.shape[0], dtype=np.int64)
    return QSums(nx, index.shape[1] - 2 * nx - 1, G, samples)


def equation_residual(model: FittedModel, sig: Signals) -> np.ndarray:
    """Equation error of ``model`` on ``sig`` (filtered signals), rad/s², full length."""
    u = filtered_inputs(model.spec, sig)
    pred = (model.c_theta * sig.theta_f + model.c_omega * sig.omega_f
            + u @ np.array([model.coef[name] for name in model.spec.names()]))
    if ripple_on_offset(model.spec):
        pred = pred + offset_ripple(model.coef.__getitem__, _ripple_positions(model.spec, sig))
    return np.asarray(sig.accel_f - pred)


def nominal() -> ModelSpec:
    """The nominal model of seed 000 (no extension)."""
    return ModelSpec()


__all__ = ["KICK_COLUMNS", "LOAD_COLUMNS", "SUPPLY_COLUMNS", "FittedModel", "ModelSpec", "equation_residual",
           "fit", "fit_residual_batch", "interval_current", "kick_basis", "lag_share",
           "lag_slope", "load_motion", "nominal", "offset_ripple",
           "period_current", "period_mean_current", "period_shape", "supply_basis",
           "supply_classes", "supply_within_period",
           "periodic_column", "periodic_mean",
           "regressors", "ripple_on_offset", "shifted", "velocity_resolution", "velocity_sign"]
