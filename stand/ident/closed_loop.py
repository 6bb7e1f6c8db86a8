"""Output-error refinement of a speed-loop run: the whole loop simulated, fitted to the
sampled angle and current.

The equation error of :mod:`stand.ident.speed_loop` fits the PI law at the samples with
the acceleration from the angle's second difference. On the loop's exponential
transients the drive's own lag between speed and current (current loop, computation)
and ``kp`` then trade off, and ``kp`` comes out high by about ``2π·f_loop·τ``. Here the
mechanics give the acceleration instead: the held target drives the loop and the
motor between the samples, exactly (the loop is linear between samples)::

    θ' = ω
    ω' = a·i − d·ω + Σ_k b_k·g_k          a = Kt/J, d = D/J
    I' = ki·(r − ω)                       (integrator, A)
    τ·i' = kp·(r − ω) + I − i             (current loop with the drive's lag τ)

with the target ``r`` held over each period and the selected effects' torques
``g_k`` (Coulomb and Stribeck friction, cogging, ripple) taken as held inputs over each
period from the measured angle. The discrete system is the exact zero-order-hold one
(matrix exponential), stepped as four first-order recursions in modal form. The
parameters ``a, d, kp, ki, τ``, the effects' coefficients, the current sensor's offset
and the initial state are fitted by least squares to the sampled angle (weighted by
the encoder's ``q/√12``) and the sampled current (by its noise, at the loop's delay).
A constant torque (an offset) is not separable from the integrator's start and the
sensor offset, and needs no column.

Uncertainty: the sandwich ``H⁻¹·S·H⁻ᵀ`` of the Jacobian, with ``S`` summed over
contiguous blocks of samples (residuals of a free simulation are correlated over the
loop's settling time, far less than a block), and Student's t with blocks − 1 degrees of
freedom.

The drive's current limit and, when it is told (:class:`DriveSupply`), its supply
voltage and the armature are modelled too: the simulation
(:class:`stand.ident.loop_model.LoopModel`) steps the drive's modes (the law, the command
at its limit, the supply applied; the integrator held at the limit) through their
switches within each period. Where the fit with the supply ends in a minimum of the
solver's own, it starts once more nearer the run (:func:`_supplied_start`).

Not modelled: sticking friction (Karnopp) near zero speed.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares, minimize_scalar
from scipy.stats import chi2

from stand.diagnosis.model import ModelSpec, periodic_mean
from stand.ident.estimate import BLOCKS, t_interval
from stand.ident.loop_model import LOG_LAG_RANGE, LoopModel
from stand.ident.speed_loop import DELAY_SIGMAS, SpeedLoop
from stand.ident.supply import DriveSupply

#: Start value of the drive's lag τ, s (a current loop of a few kHz).
START_LAG_S = 3e-4
#: Largest RMS of the current's residual over its noise for which the simulation counts
#: as explaining the run (a loop that saturates, or another law, leaves far more).
MAX_CURRENT_RATIO = 2.0
#: Least encoder error for an unquantized angle, rad (only to keep the weights finite).
MIN_ANGLE_SD_RAD = 1e-9
#: Most evaluations per parameter and one where the drive's supply is modelled (each
#: steps through the mode switches; the fit starts from the one without the supply).
SUPPLY_STEPS = 5
#: Factors of the told armature resistance tried in a second start of the fit with the
#: supply (1/2 … 2, log-spaced), and the share by which one must fit better than the
#: factor nearer 1 to be taken.
RESISTANCE_SCAN = tuple(float(f) for f in np.geomspace(0.5, 2.0, 13))
RESISTANCE_TIE = 0.01
#: Tolerance of the refined resistance's logarithm (0.1 %).
RESISTANCE_XTOL = 1e-3
#: Most evaluations of the residuals by the least-squares solver, per parameter and one
#: (its finite-difference Jacobians included).
MAX_EVALUATIONS = 30


@dataclass(frozen=True)
class ClosedLoopFit:
    """Output-error fit of the speed loop and the mechanics.

    Attributes
    ----------
    Kt_over_J, D_over_J : float
        ``a`` rad/(s²·A) and ``d`` 1/s.
    Kt_over_J_se, D_over_J_se : float
        Block-sandwich standard errors.
    dof : int
        Degrees of freedom of the intervals (blocks − 1).
    kp, ki, lag_s : float
        Loop gains (A per rad/s, A per rad) and the drive's lag, s.
    current_ratio, angle_ratio : float
        RMS of the current's and the angle's residual over their noise.
    holds : bool
        The simulation explains the current to within ``MAX_CURRENT_RATIO`` of its noise.
    message : str
        Why the fit is not used, or empty.
    """

    Kt_over_J: float
    D_over_J: float
    Kt_over_J_se: float
    D_over_J_se: float
    dof: int
    kp: float
    ki: float
    lag_s: float
    current_ratio: float
    angle_ratio: float
    holds: bool
    message: str = ""

    def interval(self, value: float, se: float) -> list[float]:
        """95 % interval of ``value`` with standard error ``se``."""
        return t_interval(value, se, self.dof)


def effect_inputs(spec: ModelSpec, theta: np.ndarray, period_current: np.ndarray,
                  dt: float, quant_rad: float) -> np.ndarray:
    """The selected effects' torque columns held over each period (rows: periods), from
    the measured angle: ``sign(ω̄)`` (Coulomb), ``sign(ω̄)·exp(−(ω̄/ωs)²)`` (Stribeck),
    the period means of ``sin, cos(Nθ)`` (cogging) and of ``i·sin, i·cos(Nθ)`` (ripple,
    with the current over the period from the loop law). ``ω̄`` is the period's mean
    speed; zero sign below one encoder step per period."""
    step = np.diff(theta)
    mean_speed = step / dt
    sign = np.where(np.abs(step) > 0.5 * quant_rad, np.sign(step), 0.0)
    columns = []
    if spec.coulomb or spec.stribeck_ws is not None:
        columns.append(sign)
    if spec.stribeck_ws is not None:
        columns.append(sign * np.exp(-((mean_speed / spec.stribeck_ws) ** 2)))
    if spec.cogging_N is not None:
        columns += list(periodic_mean(spec.cogging_N, theta[:-1], step))
    if spec.ripple_N is not None:
        current = period_current[:-1]
        columns += [current * s for s in periodic_mean(spec.ripple_N, theta[:-1], step)]
    return np.column_stack(columns) if columns else np.zeros((len(step), 0))


def fit_closed_loop(theta: np.ndarray, current: np.ndarray, target: np.ndarray, dt: float,
                    loop: SpeedLoop, spec: ModelSpec, kt_over_j: float, d_over_j: float,
                    effect_start: np.ndarray, quant_rad: float,
                    current_sd: float, supply: DriveSupply | None = None,
                    saturated: bool = False) -> ClosedLoopFit:
    """Fit the simulated loop and mechanics to a speed-mode run by output error.

    Parameters
    ----------
    theta, current, target : ndarray
        Measured angle (rad), current (A), and the speed target held over the period
        after each sample (rad/s).
    dt : float
        Sample period, s.
    loop : SpeedLoop
        The equation-error fit of the loop law (start values, delay of the current).
    spec : ModelSpec
        Effects selected on the equation error; their coefficients are refitted.
    kt_over_j, d_over_j : float
        Start values of ``a`` (rad/(s²·A)) and ``d`` (1/s).
    effect_start : ndarray
        Start values of the effects' coefficients (torque per inertia, rad/s², per unit
        of each column of :func:`effect_inputs`).
    quant_rad : float
        Encoder step, rad (0: unquantized).
    current_sd : float
        Current noise, A.
    supply : DriveSupply or None
        The drive's supply and current limit and the motor's armature: where the
        current loop needs more than the supply, the current follows the armature
        (``V/L``, ``R/L``, ``Kt/L`` fitted from these starts), and the command is clipped
        at the current limit (fitted from it). None: neither is modelled but the limit
        the samples show (``loop.limit_A``).
    """
    # the ripple's current over each period: the law's where it holds, else the samples'
    period_current = loop.period_current if loop.holds else current
    inputs = effect_inputs(spec, theta, period_current, dt, quant_rad)
    angle_sd = max(quant_rad / np.sqrt(12.0), MIN_ANGLE_SD_RAD)
    # a floor()-quantized encoder reads half a step low on average
    measured = theta + 0.5 * quant_rad
    limit = loop.limit_A if loop.saturates else np.inf
    # τ enters as its logarithm (positive, and unbounded for the Levenberg-Marquardt
    # solver, whose QR steps are far cheaper here than a bounded solver's SVD)
    start = np.concatenate([[kt_over_j, d_over_j, loop.kp, loop.ki, np.log(START_LAG_S), 0.0,
                             measured[0], 0.0, loop.offset_A,
                             current[min(loop.delay, len(current) - 1)], 0.0],
                            effect_start])
    model = LoopModel(measured, current, target, inputs, dt, loop.delay, angle_sd,
                       current_sd, bool(np.isfinite(limit)))
    if supply is None or not saturated:
        fit, p = _solve(model, np.append(start, [limit] if np.isfinite(limit) else []), dt,
                        MAX_EVALUATIONS)
        if supply is None:
            return fit
        start = p[:len(start)]
        if np.isfinite(limit):
            limit = p[-1]
    # the drive's supply, and its current limit where the samples do not show it
    if not np.isfinite(limit):
        limit = supply.current_limit_A
    supplied = LoopModel(measured, current, target, inputs, dt, loop.delay, angle_sd,
                          current_sd, bool(np.isfinite(limit)), True)
    # the armature's ratios enter as logarithms too
    armature = np.log([supply.supply_V / supply.L, supply.R / supply.L, supply.Kt / supply.L])
    start = np.concatenate([start, armature, [limit] if np.isfinite(limit) else []])
    if not saturated:
        # refitted only where the supply changes the fitted motion beyond what the noise
        # tells apart: the weighted sum of squares moves by more than the 95 % point of
        # χ² with one degree of freedom per added parameter
        moved = abs(float(np.sum(supplied.residuals(start) ** 2) - np.sum(model.residuals(p) ** 2)))
        if moved <= chi2.ppf(0.95, len(start) - len(p)):
            return fit
    fit, p = _solve(supplied, start, dt, SUPPLY_STEPS)
    if saturated and loop.delay > 0:
        # a drive whose supply slows its current looks delayed to the law: the delay of
        # the law trimmed of the saturated samples must beat none in the simulation too
        undelayed = LoopModel(measured, current, target, inputs, dt, 0, angle_sd,
                               current_sd, bool(np.isfinite(limit)), True)
        start0 = start.copy()
        start0[9] = current[0]
        fit0, p0 = _solve(undelayed, start0, dt, SUPPLY_STEPS)
        if not _fits_better(supplied, p, undelayed, p0):
            fit, start, supplied = fit0, start0, undelayed
    if not fit.holds:
        # a minimum of the solver's own: once more from a start nearer the run
        restart = _supplied_start(supplied, start, dt, saturated, supply)
        again = _solve(supplied, restart, dt, SUPPLY_STEPS)[0]
        if again.current_ratio < fit.current_ratio:
            fit = again
    return fit


def _supplied_start(model: LoopModel, start: np.ndarray, dt: float, saturated: bool,
                    supply: DriveSupply) -> np.ndarray:
    """A second start of the fit with the drive's supply, where the first one ends in a
    minimum of the solver's own: a sequence of the drive's modes that is not the run's,
    the armature's ratios run off to where the supply never binds.

    - Where the law was refused (``saturated``), the effects' coefficients start at none
      (the equation error chose them on a current whose kicks the samples miss), and
      the current limit at the told one (where the supply runs out first, the samples
      show the current the supply drives, not the limit), and the loop's gains at the
      drive's where they are told (a law fitted on the samples the supply leaves to it
      misses the integrator the drive holds at its limit, and its gains can be off by
      a factor of 2–20).
    - The armature's resistance is scaled by the factor of :data:`RESISTANCE_SCAN`
      whose simulation fits the run best (nearest the told value among equals), then
      refined between that factor's neighbours (:func:`_resistance_refined`): where
      the supply runs out the current follows ``(V − Kt·ω)/R``, and the resistance is
      the profile's least known value (a winding's rises by some 40 % from cold to hot).
    - The loop and the mechanics are fitted with the armature and the limit held there."""
    assert model.supply_at is not None
    at = model.supply_at
    start = start.copy()
    if saturated:
        start[model.FIXED:at] = 0.0
        if model.limited and np.isfinite(supply.current_limit_A):
            start[-1] = supply.current_limit_A
        if supply.speed_kp is not None and supply.speed_ki is not None:
            start[2:4] = supply.speed_kp, supply.speed_ki
    best, best_sse = start, np.inf
    for factor in sorted(RESISTANCE_SCAN, key=lambda f: abs(np.log(f))):   # 1 first
        trial = _resistance_scaled(model, start, np.log(factor))
        sse = _sse(model, trial)
        if sse < (1.0 - RESISTANCE_TIE) * best_sse:
            best, best_sse = trial, sse
    best = _resistance_refined(model, best, best_sse)

    def residuals(q: np.ndarray) -> np.ndarray:
        return model.residuals(np.concatenate([q, best[at:]]))

    res = least_squares(residuals, best[:at], x_scale=_scale(best, dt, model)[:at],
                        method="lm", max_nfev=SUPPLY_STEPS * (at + 1))
    return np.concatenate([res.x, best[at:]])


def _resistance_refined(model: LoopModel, p: np.ndarray, sse: float) -> np.ndarray:
    """``p`` with its armature resistance refined between the neighbours of its factor of
    :data:`RESISTANCE_SCAN` (a bounded Brent search on its logarithm): where the supply
    runs out for long the basin is narrower than the scan's step (seed 21 stand 14, a
    loaded run: ×0.794 of the told value leaves the current 1.3e6 in squared residuals,
    ×0.841, the truth, 2.7e3), and the fit from the scan's factor stays beside it."""
    step = np.log(RESISTANCE_SCAN[1] / RESISTANCE_SCAN[0])
    found = minimize_scalar(lambda x: _sse(model, _resistance_scaled(model, p, x)),
                            bounds=(-step, step), method="bounded",
                            options={"xatol": RESISTANCE_XTOL})
    return _resistance_scaled(model, p, float(found.x)) if found.fun < sse else p


def _resistance_scaled(model: LoopModel, p: np.ndarray, log_factor: float) -> np.ndarray:
    """``p`` with the armature's resistance scaled by ``exp(log_factor)``."""
    assert model.supply_at is not None
    q = p.copy()
    q[model.supply_at + 1] += log_factor
    return q


def _sse(model: LoopModel, p: np.ndarray) -> float:
    """Sum of the squared residuals of ``model`` at ``p``."""
    return float(np.sum(model.residuals(p) ** 2))


def _scale(start: np.ndarray, dt: float, model: LoopModel) -> np.ndarray:
    """The solver's scale of each parameter: its start's size; 1 for the logarithms (the
    lag, the armature's ratios), ``dt`` for the encoder's timing."""
    scale = np.abs(start)
    scale[scale == 0] = 1.0
    scale[4], scale[10] = 1.0, dt
    if model.supply_at is not None:
        scale[model.supply_at:model.supply_at + 3] = 1.0
    return scale


def _fits_better(model: LoopModel, p: np.ndarray, other: LoopModel,
                 q: np.ndarray) -> bool:
    """``model`` at ``p`` explains the run better than ``other`` at ``q``: the paired
    difference of their squared residuals, summed over each of ``BLOCKS`` contiguous
    blocks of samples (those both models have rows for), is positive by a t test over
    the blocks beyond ``DELAY_SIGMAS`` (non-nested models of as many parameters)."""
    last = min(model.rows, other.rows)
    edges = np.linspace(0, last, BLOCKS + 1)
    sums = []
    for m, params in ((model, p), (other, q)):
        rows = m.sample_of_row()
        keep = rows < last
        block = np.searchsorted(edges, rows[keep], side="right") - 1
        sums.append(np.bincount(block, m.residuals(params)[keep] ** 2, minlength=BLOCKS))
    gain = sums[1] - sums[0]
    se = gain.std(ddof=1) / np.sqrt(BLOCKS)
    return bool(gain.mean() > DELAY_SIGMAS * se)


def _solve(model: LoopModel, start: np.ndarray, dt: float,
           evaluations: int) -> tuple[ClosedLoopFit, np.ndarray]:
    """Levenberg-Marquardt from ``start`` (at most ``evaluations`` per parameter and one),
    and the fit with its block-sandwich covariance; also the parameters."""
    scale = _scale(start, dt, model)
    res = least_squares(model.residuals, start, x_scale=scale, method="lm",
                        max_nfev=evaluations * (len(start) + 1))
    p, J, e = res.x, res.jac, res.fun
    n_angle = len(model.theta)
    blocks = BLOCKS
    edges = np.linspace(0, n_angle, blocks + 1)
    block_of = np.searchsorted(edges, model.sample_of_row(), side="right") - 1
    cov = np.full((len(p), len(p)), np.nan)
    # a fit that ended where the loop diverges overflows here: its covariance stays
    # undefined, and it does not hold
    with np.errstate(over="ignore", invalid="ignore"):
        current_ratio = float(np.sqrt(np.mean(e[n_angle:] ** 2)))
        angle_ratio = float(np.sqrt(np.mean(e[:n_angle] ** 2)))
        # in the solver's scaled coordinates (the parameters span many decades); a
        # column the run does not excite (an effect's column zero throughout) is left out
        Js = J * scale[None, :]
        used = np.flatnonzero(np.linalg.norm(Js, axis=0) > 0)
        Js = Js[:, used]
        scores = np.stack([Js[block_of == b].T @ e[block_of == b] for b in range(blocks)])
        S = scores.T @ scores * blocks / (blocks - 1)
        try:
            Hinv = np.linalg.inv(Js.T @ Js)
            cov[np.ix_(used, used)] = (Hinv @ S @ Hinv) * np.outer(scale[used], scale[used])
        except (np.linalg.LinAlgError, ValueError):
            pass
    holds = bool(res.status >= 0 and current_ratio <= MAX_CURRENT_RATIO and p[0] > 0
                 and np.isfinite(cov[0, 0]))
    message = "" if holds else (
        f"the simulated speed loop explains the current only to {current_ratio:.2g} times "
        f"its noise (at most {MAX_CURRENT_RATIO}): the output-error refinement is not used")
    return ClosedLoopFit(float(p[0]), float(p[1]), float(np.sqrt(max(cov[0, 0], 0.0))),
                         float(np.sqrt(max(cov[1, 1], 0.0))), blocks - 1, float(p[2]),
                         float(p[3]), float(np.exp(np.clip(p[4], *LOG_LAG_RANGE))),
                         current_ratio, angle_ratio, holds, message), p
