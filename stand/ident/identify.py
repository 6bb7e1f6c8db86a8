"""One single-motor run to the model of seed 000 eqs. 2-5: A, B and the physical ratios.

The state is ``x = [θ, ω]`` and the input ``u = i − i_nl`` (measured current less the
no-load current of §5.1, 0 when not compensating). Eq. 10 gives::

    A = [[0, 1], [−C/J, −D/J]],   B = [[0], [Kt/J]]

``fit_percent`` is the equation-error fit of the acceleration row (the row that carries
the physics; the first row is the kinematic identity θ' = ω).

``effects='none'`` is exactly seed 000's model and least-squares solver (eq. 10). Any
other choice adds effect regressors (:mod:`stand.ident.columns`, chosen by
:mod:`stand.ident.select`) and, with the default derivatives, estimates by instrumental
variables, so that current-sensor noise does not pull Kt/J towards zero. Every
standard error and interval is the block sandwich of :mod:`stand.ident.estimate`.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
from scipy.stats import chi2

from stand.diagnosis.model import ModelSpec, period_mean_current
from stand.diagnosis.signals import MIN_DIAGNOSE_SAMPLES, Signals, prepare, quantization_step
from stand.errors import InputError, NotExcitedError
from stand.ident.checks import effect_params, rest_warning, run_warnings
from stand.ident.closed_loop import ClosedLoopFit, fit_closed_loop
from stand.ident.columns import TIMING_COLUMN, Design
from stand.ident.derivatives import auto_half_width, state_derivatives
from stand.ident.estimate import Estimate, block_count, solve_blocks, t_quantile
from stand.ident.noise import noise_sigma
from stand.ident.qmatrix import QSums, solve
from stand.ident.select import (
    Fitter,
    Selection,
    model_disagreement,
    model_variance,
    parse_effects,
    select,
)
from stand.ident.speed_loop import TARGET_COLUMN, SpeedLoop, fit_speed_loop, speed_loop
from stand.ident.supply import DriveSupply
from stand.jsonable import JsonResult
from stand.runfile import CURRENT_MEAN_COLUMN, Run

#: Estimators (:class:`stand.ident.select.Fitter`); ``auto`` picks ``bc`` or ``iv`` per run.
ESTIMATORS: tuple[str, ...] = ("auto", "iv", "bc", "ls")
#: Lag of the current instruments beyond the kernel's support, samples.
INSTRUMENT_MARGIN = 1

#: Warning of a speed-loop run whose law holds but for some samples (those where the
#: drive's voltage runs out) when the drive's supply is not known.
SUPPLY_UNKNOWN = ("the PI speed law explains the current only outside some stretches, as on a "
                  "drive whose supply voltage cannot follow the loop's kicks: the supply could "
                  "not be modelled (tell the drive's supply, R and L: --motor PROFILE), so the "
                  "output-error refinement is not used and Kt/J may be biased")

#: Blocks the current is split into to test that it varies beyond its noise.
EXCITATION_BLOCKS = 20
#: Significance level of that test: a current whose block means vary no more than white
#: noise would make them, at this level, counts as constant.
EXCITATION_SIGNIFICANCE = 1e-3
#: Largest relative standard error of Kt/J for which a run counts as exciting the model;
#: beyond it the current carries no information distinguishable from noise (e.g. a
#: constant current at a constant speed).
MAX_RELATIVE_SE = 0.5


@dataclass(frozen=True)
class IdentifyResult(JsonResult):
    """Identified model of one run (CONTRACT §2 ``stand identify``).

    Attributes
    ----------
    A : list of list of float
        System matrix (2x2): rows θ', ω'; columns θ, ω.
    B : list of list of float
        Input matrix (2x1), per A of current, rad/s² per A in the second row.
    Kt_over_J : float
        ``B[1][0]``, rad/(s²·A).
    D_over_J : float
        ``−A[1][1]``, 1/s.
    C_over_J : float
        ``−A[1][0]``, 1/s².
    Kt_over_J_se, D_over_J_se, C_over_J_se : float
        Standard errors from the block sandwich (:mod:`stand.ident.estimate`): they hold
        for residuals correlated over less than a block.
    fit_percent : float
        Equation-error fit of the acceleration row, %.
    condition_number : float
        Of the equilibrated normal matrix of eq. 10.
    samples : int
        Rows used in eq. 10.
    method : str
        ``default`` or ``paper``.
    dt_s : float
        Sample period, s.
    no_load_current_A : float
        Current subtracted from the measured current, A.
    half_width : int
        Half width of the default method's kernel, samples (0 for ``paper``).
    Kt_over_J_ci95, D_over_J_ci95 : list of float
        95 % intervals ``[low, high]`` (Student's t over the blocks), rad/(s²·A) and 1/s.
    effects : list of str
        Effects in the model (CONTRACT §3 names; empty for seed 000's model).
    effect_params : dict
        Each effect's parameters: torques as currents ``T/Kt`` (A), orders, phases (rad),
        delays (samples), Stribeck velocity (rad/s).
    warnings : list of str
        What in the data limits the answer.
    estimator : str
        ``iv`` (instrumental variables), ``bc`` (bias-compensated least squares) or
        ``ls`` (least squares).
    current_timing_samples : float
        Where the current is read relative to the encoder sample, samples (the delay
        plus the interpolation weight).
    source : str
        The run identified (its file name).
    current_input : str
        The current the equation-error model is driven by: ``samples`` (the sampled
        current, its timing within the period fitted), ``current_mean_A`` (the drive's
        own mean over each period) or ``speed_law`` (the PI speed law's current over
        each period).
    """

    A: list[list[float]]
    B: list[list[float]]
    Kt_over_J: float
    D_over_J: float
    C_over_J: float
    Kt_over_J_se: float
    D_over_J_se: float
    C_over_J_se: float
    fit_percent: float
    condition_number: float
    samples: int
    method: str
    dt_s: float
    no_load_current_A: float
    half_width: int
    Kt_over_J_ci95: list[float]
    D_over_J_ci95: list[float]
    effects: list[str]
    effect_params: dict[str, dict[str, float]]
    warnings: list[str]
    estimator: str
    current_timing_samples: float
    source: str = ""
    current_input: str = "samples"


def _check_current_varies(current: np.ndarray, source: str) -> None:
    """Refuse a current that is constant but for noise (it cannot separate Kt·i from
    constant torques such as Coulomb friction or an offset).

    The run is cut into ``EXCITATION_BLOCKS`` blocks of ``b`` samples; under "constant plus
    white noise of standard deviation σ" the variance of the block means times ``b/σ²``
    is χ²-distributed with ``blocks − 1`` degrees of freedom divided by them. The current
    must exceed its upper ``EXCITATION_SIGNIFICANCE`` quantile. σ comes from the
    sample-to-sample differences, so slow variation (the signal) does not inflate it.
    """
    blocks = min(EXCITATION_BLOCKS, len(current) // 2)
    b = len(current) // blocks
    means = current[: blocks * b].reshape(blocks, b).mean(axis=1)
    sigma = noise_sigma(current)
    observed = float(np.var(means, ddof=1))
    limit = chi2.ppf(1 - EXCITATION_SIGNIFICANCE, blocks - 1) / (blocks - 1) * sigma**2 / b
    if not observed > limit:
        raise NotExcitedError(
            f"{source}: current_A is constant but for its noise ({sigma:.3g} A): the means of "
            f"{blocks} blocks of {b} samples vary by {np.sqrt(observed):.3g} A, not beyond the "
            f"{np.sqrt(limit):.3g} A noise explains; a constant current cannot separate Kt "
            "from constant torques; excite the motor with a varying command (e.g. a "
            "band-limited or PRBS speed command)"
        )


def identify_run(run: Run, method: str = "default", no_load_current_A: float = 0.0,
                 half_width: int | None = None, effects: str = "auto",
                 estimator: str | None = None,
                 supply: DriveSupply | None = None) -> IdentifyResult:
    """Identify A and B of one single-motor run by seed 000 eq. 10, with effects.

    Parameters
    ----------
    run : Run
        Single-motor run with ``position_rad`` and ``current_A``.
    method : {'default', 'paper'}
        Derivatives: kernel filtering or the paper's forward Euler differences. ``paper``
        is seed 000's model: it takes no effects (``auto`` then means ``none``).
    no_load_current_A : float
        No-load current subtracted from the measured current (§5.1), A.
    half_width : int or None
        Half width of the default kernel, samples; ``None`` (default) chooses it from the
        current's noise (:func:`~stand.ident.derivatives.auto_half_width`).
    effects : str
        ``auto`` (the data choose), ``none`` (seed 000's model), or comma-separated names
        of :data:`~stand.ident.select.IDENT_EFFECTS`.
    estimator : {'auto', 'iv', 'bc', 'ls'} or None
        How current noise is kept from biasing Kt/J: instrumental variables, least
        squares compensated for the noise's known contribution, or plain least squares
        (the noise then pulls Kt/J towards zero). ``auto`` takes whichever of ``bc`` and
        ``iv`` has the smaller error on this run (:func:`_pick_estimator`). ``None``:
        ``auto`` with effects, ``ls`` for ``effects='none'`` (seed 000's solver).
    supply : DriveSupply or None
        The drive's supply and current limit and the motor's armature (start values):
        a speed-loop run's output-error refinement then models a loop that saturates
        (:mod:`stand.ident.closed_loop`), and is tried even where the loop law alone
        does not explain the current. Unused without the speed target.

    Raises
    ------
    InputError
        Unknown ``effects`` or ``estimator``, effects asked of the paper method.
    NotExcitedError
        The run does not determine the model.
    """
    wanted = parse_effects(effects)
    if estimator is not None and estimator not in ESTIMATORS:
        raise InputError(f"estimator must be one of {', '.join(ESTIMATORS)}, not {estimator!r}")
    if method == "paper" and wanted:
        raise InputError("effects: the paper method is seed 000's model and takes no effects; "
                         "use --method default with --effects, or --effects none")
    if method == "paper" and estimator not in (None, "ls"):
        raise InputError(f"estimator: the paper method is seed 000's least squares, not "
                         f"{estimator!r}; use --method default for the other estimators")
    position = run["position_rad"]
    if np.ptp(position) == 0:
        raise NotExcitedError(
            f"{run.source}: position_rad never changes: the motor is at rest, which does not "
            "excite the model; command a varying speed"
        )
    measured = run["current_A"]
    _check_current_varies(measured, run.source)
    warnings: list[str] = []
    short = len(measured) < MIN_DIAGNOSE_SAMPLES
    if wanted is None and (method == "paper" or short):
        if short:
            warnings.append(f"{len(measured)} samples are too few to choose effects (at least "
                            f"{MIN_DIAGNOSE_SAMPLES}): seed 000's model without effects")
        wanted = []
    if wanted == [] and estimator in (None, "ls"):
        return _seed_model(run, method, no_load_current_A, half_width, warnings)
    if short:
        raise InputError(f"{run.source}: {len(measured)} samples; effects or the iv "
                         f"estimator need at least {MIN_DIAGNOSE_SAMPLES}")
    return _extended(run, no_load_current_A, half_width, wanted,
                     estimator or "auto", warnings, supply)


def _seed_model(run: Run, method: str, no_load_current_A: float, half_width: int | None,
                warnings: list[str]) -> IdentifyResult:
    """Seed 000's model by least squares (eq. 10), with block-sandwich uncertainties."""
    dt = run.dt_s
    current = run["current_A"] - no_load_current_A
    states = state_derivatives(run["position_rad"], current, dt, method, half_width)
    sums = QSums.zeros(2, 1).add(states.xdot, states.x, states.inputs, dt)
    try:
        q = solve(sums, names=["angle θ", "speed ω", "current i"])
    except NotExcitedError as exc:
        raise NotExcitedError(f"{run.source}: {exc}") from None
    support = 2 * states.first + 1 if method == "default" else 3
    X = np.column_stack([states.theta, states.omega, states.inputs[:, 0]])
    est = solve_blocks(["theta", "omega", "current"], states.alpha, X, X,
                       block_count(len(X), support), run.source)
    warnings = warnings + run_warnings(run, est, [])
    # A, B and the figures of eq. 10 as seed 000's solver gives them; the sandwich adds
    # only the uncertainties.
    est = replace(est, fit_percent=float(q.fit_percent[1]),
                  condition_number=float(q.condition_number))
    return _result(run, est, method, no_load_current_A,
                   states.first if method == "default" else 0, [], {}, warnings, "ls", 0.0,
                   A=q.A.tolist(), B=q.B.tolist())


def _extended(run: Run, no_load_current_A: float, half_width: int | None,
              wanted: list[str] | None, estimator: str, warnings: list[str],
              supply: DriveSupply | None = None) -> IdentifyResult:
    """The model with effects (or seed 000's, by iv), fitted on the kernel-filtered run.

    A speed loop whose law holds only with its integrator fitted anew after each stretch
    at the current limit (``resets``) is first fitted as a refused law where the drive's
    supply is known: the simulation with the supply (which clips the command at the
    limit) is the better model where it explains the run, and the reset law's current
    where it does not."""
    loop = speed_loop(run)
    if loop is not None and loop.resets and supply is not None:
        trial: list[str] = []
        refused = replace(loop, period_current=np.empty(0), resets=0)
        result, simulated = _fitted(run, refused, no_load_current_A, half_width, wanted,
                                    estimator, trial, supply)
        if simulated:
            warnings += trial
            return result
    return _fitted(run, loop, no_load_current_A, half_width, wanted, estimator, warnings,
                   supply)[0]


def _fitted(run: Run, loop: SpeedLoop | None, no_load_current_A: float,
            half_width: int | None, wanted: list[str] | None, estimator: str,
            warnings: list[str], supply: DriveSupply | None
            ) -> tuple[IdentifyResult, bool]:
    """:func:`_extended` with the speed loop ``loop`` (None: no target); also whether the
    output-error refinement of the loop holds."""
    sig = prepare(run)
    if no_load_current_A:
        sig = replace(sig, current=sig.current - no_load_current_A, cache={})
    sigma = noise_sigma(sig.current)
    h = half_width or auto_half_width(sig.current, sigma)
    first = "bc" if estimator == "auto" else estimator
    # the measured current; the drive's own mean over each period where it reports one;
    # and under a speed loop whose law holds, the current over each period from that law
    # (its own timing): the smaller held-out error decides
    currents: list[tuple[np.ndarray, float | None, str]] = [(sig.current, None, "samples")]
    if CURRENT_MEAN_COLUMN in run:
        currents.append((period_mean_current(run) - no_load_current_A, 0.0,
                         CURRENT_MEAN_COLUMN))
    if loop is not None and loop.holds:
        currents.append((loop.period_current - no_load_current_A, 0.0, "speed_law"))
    fits = []
    for current, known_timing, source in currents:
        design = _design(replace(sig, current=current, cache={}), h)
        fitter = Fitter(design, first, run.source)
        if loop is not None:
            # the law's current is the period's own (no timing to fit); the sampled current
            # under a speed loop is no current loop's step response either, and a free
            # timing would absorb part of the loop's kick between samples
            fitter.timing = False
        chosen = select(fitter, wanted, input_weight=known_timing)
        fits.append((float(chosen.estimate.cv_sse.sum()), source, design, fitter, chosen))
    fits.sort(key=lambda fit: fit[0])
    _, source, design, fitter, chosen = fits[0]
    from_loop = source == "speed_law"
    spec, est = chosen.spec, chosen.estimate
    if estimator == "auto":
        estimator, spec, est = _pick_estimator(fitter, spec, est)
    spread = model_variance(fitter, chosen)
    est = est.with_variance("current", spread)
    if source == CURRENT_MEAN_COLUMN:
        # the period's mean is not the current's shape within it (a kick early in the
        # period moves the angle more than its mean says), which no column here models
        kp = None if loop is None else _loop_kp(loop, supply)
        est = est.with_variance("current", _mean_shape_variance(
            design, fitter, chosen, fits[1][4].estimate, kp, run.dt_s))
        if kp == 0.0:
            warnings.append(
                "the drive's period-mean current drives Kt/J, but the speed loop's gain is "
                "unknown (its law could not be fitted): the interval is as wide as the mean "
                "and the sampled current disagree; give --motor PROFILE with the drive's "
                "speed_kp to bound it by the loop's kick instead")
        loop = None  # the drive measured the current over each period: nothing to rebuild
    refined = _closed_loop(run, loop, spec, est, sigma, supply, warnings) if loop is not None else None
    if loop is not None and refined is not None and refined.holds:
        # the effects are the equation error's choice: their models' spread stays
        law = (est.with_variance("current", (loop.kp_rel_sd * est.value("current")) ** 2)
               if from_loop else None)
        est = with_closed_loop(est, refined).with_variance("current", spread)
        if law is not None:
            # the law's equation error and the simulation model the loop differently;
            # where both hold, Kt/J is known no better than they agree
            est = est.with_variance("current", model_disagreement(law, est, "current"))
    elif loop is not None and not loop.holds:
        warnings.append(loop.message)
        if refined is not None:
            warnings.append(refined.message)
        est = est.with_variance("current", missed_kick_variance(loop, est, run.dt_s))
    elif loop is not None and loop.holds:
        if refined is not None:
            warnings.append(refined.message)
        if from_loop:
            # Kt/J scales as 1/kp: kp's relative uncertainty is Kt/J's
            est = est.with_variance("current", (loop.kp_rel_sd * est.value("current")) ** 2)
        else:
            warnings.append("the current reconstructed from the PI speed law fits the motion "
                            "worse than the sampled current (the loop may saturate between "
                            "samples): the sampled current is used, and Kt/J may be high by "
                            "up to π·f_loop·Δt")
            est = est.with_variance("current", missed_kick_variance(loop, est, run.dt_s))
    params = effect_params(spec, chosen.effects, est)
    warnings += run_warnings(run, est, chosen.notes) + rest_warning(design)
    timing = spec.delay + current_weight(spec, est)
    result = _result(run, est, "default", no_load_current_A, h, chosen.effects, params,
                     warnings, estimator, timing)
    return replace(result, current_input=source), refined is not None and refined.holds


def _design(sig: Signals, h: int) -> Design:
    """The extended model's design of ``sig`` with the derivative filter of half width ``h``."""
    return Design.build(sig, h, 2 * h + 1 + INSTRUMENT_MARGIN)


def _mean_shape_variance(design: Design, fitter: Fitter, chosen: Selection,
                         next_best: Estimate, kp: float | None, dt: float) -> float:
    """Variance of Kt/J from the current's shape within each period, where the drive's
    period mean drives the model (``chosen``, fitted by ``fitter`` on ``design``).

    Two parts. What the same model fitted through a derivative filter twice as wide
    disagrees with it (Hausman): a shape within one period weighs less at half the
    bandwidth, so a shape that matters shows as a Kt/J that moves with the filter. And,
    under a speed loop, a bound on the kick's place within the period: the samples miss
    up to the share ``π·f_loop·Δt`` of the current (:func:`missed_kick_variance`); the
    mean holds all of it and misses only where in the period it came, an error second
    order in that share, ``(π·f_loop·Δt)²`` of Kt/J, as a rectangular distribution (GUM),
    and no more than the next-best input disagrees (``next_best``). ``kp`` is the loop's
    gain (:func:`_loop_kp`; None: no speed loop); where it is 0 (unknown), the
    disagreement alone."""
    est = chosen.estimate
    disagreement = model_disagreement(next_best, est, "current")
    wide = Fitter(_design(design.sig, 2 * design.half_width), fitter.estimator, fitter.source)
    wide.timing = fitter.timing
    try:
        variance = model_disagreement(wide.fit(chosen.spec), est, "current")
    except NotExcitedError:  # too short for the wider filter: as far as the inputs agree
        return disagreement
    if kp is not None:
        a = est.value("current")
        bound = _kick_share(kp, a, dt) ** 2 * a if kp > 0 and a > 0 else 0.0
        variance += min(disagreement, bound**2 / 3.0) if bound else disagreement
    return variance


def _loop_kp(loop: SpeedLoop, supply: DriveSupply | None) -> float:
    """The speed loop's proportional gain, A per rad/s: its law's, else the drive's
    (``supply``, from a motor profile); 0 where neither is known."""
    if loop.kp > 0:
        return loop.kp
    return (supply.speed_kp or 0.0) if supply else 0.0


def missed_kick_variance(loop: SpeedLoop, est: Estimate, dt: float) -> float:
    """Variance of Kt/J from the loop's kick between samples, where Kt/J comes from the
    sampled current of a speed-loop run and no simulation of the loop holds.

    The samples then miss up to ``π·f_loop·Δt`` of the current that accelerates the rotor
    (``f_loop = kp·Kt/(2π·J)``, :mod:`stand.ident.speed_loop`), a bias of Kt/J of up to
    that share which one run cannot tell from inertia. Known only as a bound, it enters
    as a rectangular distribution of that half width (standard uncertainty
    ``bound/√3``, as the GUM takes a bound), so that the interval keeps the warning's
    promise. 0 where the law's ``kp`` is not positive (no bound is known).
    """
    a = est.value("current")
    if not (loop.kp > 0 and a > 0):
        return 0.0
    bound = _kick_share(loop.kp, a, dt) * a   # π·f_loop·Δt of Kt/J
    return float(bound**2 / 3.0)


def _kick_share(kp: float, kt_over_j: float, dt: float) -> float:
    """``π·f_loop·Δt``: the share of a speed loop's current kick the samples can miss, for
    a loop of gain ``kp`` (A per rad/s) on a motor of ``Kt/J`` sampled every ``dt``
    (``f_loop = kp·Kt/(2π·J)``)."""
    return 0.5 * kp * kt_over_j * dt


def _closed_loop(run: Run, loop: SpeedLoop, spec: ModelSpec, est: Estimate,
                 sigma: float, supply: DriveSupply | None,
                 warnings: list[str]) -> ClosedLoopFit | None:
    """The output-error refinement of a speed-loop run (:mod:`stand.ident.closed_loop`),
    started from ``est``, where its loop law holds or the drive's supply is known.

    Where the law is refused, the law fitted on the samples outside the saturated
    stretches starts the simulation with the supply, even where it does not hold on
    those samples either (a drive holds its integrator at the limit, which leaves the
    law after each stretch; the simulation models that and refits the gains, and its fit
    is used only where it explains the run). Without the supply: None, with a warning
    that the supply could not be modelled where that trimmed law holds. None too where
    the law holds only with its integrator fitted anew after each stretch at the current
    limit (``loop.resets``): that law's current stands (:func:`_extended` tries the
    simulation with the supply first)."""
    if loop.resets:
        return None
    theta = run["position_rad"]
    saturated = not loop.holds
    if saturated:
        # a loop that saturates its supply: the law fitted on the samples it explains
        # (those outside the saturated stretches) starts the simulation that models them
        loop = fit_speed_loop(theta, run["current_A"], run[TARGET_COLUMN], run.dt_s,
                              quantization_step(theta), trim=True)
        if supply is None:
            if loop.holds:
                warnings.append(SUPPLY_UNKNOWN)
            return None
    names = [name for name in spec.names() if name not in ("current", "one")]
    start = np.array([est.value(name) for name in names])
    return fit_closed_loop(theta, run["current_A"], run[TARGET_COLUMN], run.dt_s, loop, spec,
                           est.value("current"), -est.value("omega"), start,
                           quantization_step(theta), sigma, supply, saturated)


def with_closed_loop(est: Estimate, fit: ClosedLoopFit) -> Estimate:
    """``est`` with Kt/J and D/J from the output-error fit: their values, and variances
    scaled so that ``est``'s t quantile gives the fit's interval (no covariance with the
    other coefficients, which stay the equation error's)."""
    beta, cov = est.beta.copy(), est.cov.copy()
    ratio = (t_quantile(fit.dof) / t_quantile(est.dof)) ** 2
    for name, value, se, sign in (("current", fit.Kt_over_J, fit.Kt_over_J_se, 1.0),
                                  ("omega", fit.D_over_J, fit.D_over_J_se, -1.0)):
        k = est.names.index(name)
        beta[k] = sign * value
        cov[k, :] = cov[:, k] = 0.0
        cov[k, k] = se**2 * ratio
    return replace(est, beta=beta, cov=cov)


def current_weight(spec: ModelSpec, est: Estimate) -> float:
    """Where in the period after a sample the current is read, as ``w`` of
    :func:`~stand.diagnosis.model.interval_current`: the spec's, plus the fitted share of
    the timing column when the estimate has one."""
    if TIMING_COLUMN not in est.names:
        return spec.input_weight
    return spec.input_weight + est.value(TIMING_COLUMN) / est.value("current")


def _pick_estimator(fitter: Fitter, spec: ModelSpec,
                    bc: Estimate) -> tuple[str, ModelSpec, Estimate]:
    """``bc`` or ``iv`` for ``spec``, whichever has the smaller error of Kt/J (with the
    spec it was fitted with: ``iv`` takes the current's timing ``bc`` found).

    The compensation of ``bc`` is as good as the noise variance it subtracts: its error
    is the shift it makes (``bc`` less ``ls``) times the relative uncertainty of that
    variance (:func:`~stand.ident.noise.noise_sigma_uncertainty`), added to its variance
    (and to its reported covariance). ``iv`` has no such term, but weak instruments (a
    current that decorrelates within the lag, as under a fast speed loop) widen it.
    ``ls`` is the model ``bc`` was fitted with (``fitter``'s, with or without the
    current's timing column), so that the shift is the compensation's alone.
    """
    design, source = fitter.design, fitter.source
    k = bc.names.index("current")
    least = Fitter(design, "ls", source)
    least.timing = fitter.timing
    ls = least.fit(spec)
    shift = (bc.beta[k] - ls.beta[k]) * design.filtered_noise(spec.input_weight)[1]
    cov = bc.cov.copy()
    cov[k, k] += shift**2
    bc = replace(bc, cov=cov)
    iv_spec = replace(spec, input_weight=float(np.clip(current_weight(spec, bc), 0.0, 1.0)))
    try:
        iv = Fitter(design, "iv", source).fit(iv_spec)
    except NotExcitedError:
        return "bc", spec, bc
    return ("iv", iv_spec, iv) if iv.cov[k, k] < bc.cov[k, k] else ("bc", spec, bc)


def _result(run: Run, est: Estimate, method: str, no_load_current_A: float, half_width: int,
            effects: list[str], params: dict[str, dict[str, float]], warnings: list[str],
            estimator: str, timing: float, A: list[list[float]] | None = None,
            B: list[list[float]] | None = None) -> IdentifyResult:
    b2, b2_se = est.value("current"), float(est.se[est.names.index("current")])
    if not abs(b2) > MAX_RELATIVE_SE ** -1 * b2_se:
        raise NotExcitedError(
            f"{run.source}: Kt/J = {b2:.4g} ± {b2_se:.2g}: the run does not determine Kt/J "
            f"(relative standard error above {MAX_RELATIVE_SE:.0%}); excite the motor more "
            "(larger or faster command changes, a longer run) or use the default method"
        )
    d, c = -est.value("omega"), -est.value("theta") if "theta" in est.names else 0.0
    c_se = float(est.se[est.names.index("theta")]) if "theta" in est.names else 0.0
    return IdentifyResult(
        A=A or [[0.0, 1.0], [-c, -d]], B=B or [[0.0], [b2]],
        Kt_over_J=b2, D_over_J=d, C_over_J=c,
        Kt_over_J_se=b2_se, D_over_J_se=float(est.se[est.names.index("omega")]),
        C_over_J_se=c_se, fit_percent=est.fit_percent, condition_number=est.condition_number,
        samples=est.samples, method=method, dt_s=run.dt_s, no_load_current_A=no_load_current_A,
        half_width=half_width, Kt_over_J_ci95=est.interval("current"),
        D_over_J_ci95=est.interval("omega", -1.0), effects=effects, effect_params=params,
        warnings=warnings, estimator=estimator, current_timing_samples=timing,
        source=run.source,
    )
