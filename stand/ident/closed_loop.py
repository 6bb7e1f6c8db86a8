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

Not modelled: the current limit and the supply voltage (a loop that saturates between
samples is left to the equation error), sticking friction (Karnopp) near zero speed.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.linalg import expm
from scipy.optimize import least_squares
from scipy.signal import lfilter

from stand.diagnosis.model import ModelSpec, periodic_mean
from stand.ident.estimate import BLOCKS, t_interval
from stand.ident.speed_loop import SpeedLoop

#: Start value of the drive's lag τ, s (a current loop of a few kHz).
START_LAG_S = 3e-4
#: Range of ``ln τ`` the simulation takes (1 µs … 1 s; a solver step beyond it is held
#: at its end).
LOG_LAG_RANGE = (np.log(1e-6), 0.0)
#: Largest RMS of the current's residual over its noise for which the simulation counts
#: as explaining the run (a loop that saturates, or another law, leaves far more).
MAX_CURRENT_RATIO = 2.0
#: Least encoder error for an unquantized angle, rad (only to keep the weights finite).
MIN_ANGLE_SD_RAD = 1e-9
#: Weighted residual of every row where the simulation diverges (a rejected step).
DIVERGED_RESIDUAL = 1e6
#: Largest condition number of the continuous system's eigenvectors for the modal
#: matrix exponential (beyond it, scipy's Padé ``expm``).
MAX_MODE_CONDITION = 1e8
#: Sub-steps of a period in which the current command reaches the drive's limit.
CLIP_SUBSTEPS = 16
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


class _LoopModel:
    """The loop and the mechanics as a function of the parameter vector
    ``[a, d, kp, ki, τ, off, θ0, ω0, I0, i0, δ, b_1 … b_m]`` (and the current limit
    ``L`` last when the loop reaches it)."""

    FIXED = 11

    def __init__(self, theta: np.ndarray, current: np.ndarray, target: np.ndarray,
                 inputs: np.ndarray, dt: float, delay: int, angle_sd: float,
                 current_sd: float, limited: bool) -> None:
        self.theta, self.current, self.dt, self.delay = theta, current, dt, delay
        self.u = np.column_stack([target[:-1], inputs])
        self.angle_sd, self.current_sd = angle_sd, current_sd
        self.rows = len(theta) - delay
        self.limited = limited

    def _discrete(self, p: np.ndarray, h: float, clipped: bool) -> tuple[np.ndarray, np.ndarray]:
        """Exact zero-order-hold ``Φ``, ``Γ`` over ``h`` s for the inputs ``[r, g…]``
        (and ``s·L`` last when the current command is clipped at ``±L``)."""
        a, d, kp, ki = p[:4]
        tau = float(np.exp(np.clip(p[4], *LOG_LAG_RANGE)))
        m = self.u.shape[1] + (1 if clipped else 0)
        A = np.array([[0.0, 1.0, 0.0, 0.0],
                      [0.0, -d, 0.0, a],
                      [0.0, -ki, 0.0, 0.0],
                      [0.0, 0.0 if clipped else -kp / tau, 0.0 if clipped else 1.0 / tau,
                       -1.0 / tau]])
        B = np.zeros((4, m))
        B[2, 0] = ki
        B[1, 1:self.u.shape[1]] = p[self.FIXED:self.FIXED + self.u.shape[1] - 1]
        if clipped:
            B[3, -1] = 1.0 / tau
        else:
            B[3, 0] = kp / tau
        lam, V = np.linalg.eig(A * h)
        if np.linalg.cond(V) > MAX_MODE_CONDITION:   # (nearly) defective: the general way
            M = np.zeros((4 + m, 4 + m))
            M[:4, :4], M[:4, 4:] = A * h, B * h
            E = expm(M)
            return E[:4, :4], E[:4, 4:]
        # Φ = V·e^Λ·V⁻¹, Γ = V·φ₁(Λ)·V⁻¹·B·h with φ₁(x) = (eˣ − 1)/x (1 at x = 0)
        Vinv = np.linalg.inv(V)
        grow = np.exp(lam)
        small = np.abs(lam) < 1e-8
        phi1 = np.where(small, 1.0 + lam / 2, (grow - 1.0) / np.where(small, 1.0, lam))
        Phi = np.real((V * grow) @ Vinv)
        Gamma = np.real((V * phi1) @ (Vinv @ B)) * h
        return Phi, Gamma

    def states(self, p: np.ndarray) -> np.ndarray:
        """States ``[θ, ω, I, i]`` at every sample, shape (samples, 4).

        Linear stretches are stepped as four first-order recursions in modal form;
        from a period whose current command starts beyond the limit ``±L``, periods are
        stepped in ``CLIP_SUBSTEPS`` exact sub-steps, each clipped or not by the command
        at its start, until a period starts within the limit again."""
        Phi, Gamma = self._discrete(p, self.dt, False)
        lam, V = np.linalg.eig(Phi)
        Vinv = np.linalg.inv(V)
        drive = self.u @ (Vinv @ Gamma).T            # (periods, 4) in modal coordinates
        n = len(self.theta)
        x = np.empty((n, 4))
        x[0] = p[6:10]
        kp = p[2]
        limit = p[-1] if self.limited else np.inf
        r = self.u[:, 0]
        first = 0
        sub: tuple[np.ndarray, ...] | None = None
        while True:
            z0 = Vinv @ x[first]
            z = np.empty((n - first - 1, 4), dtype=complex)
            for k in range(4):
                z[:, k] = lfilter([1.0], [1.0, -lam[k]], drive[first:, k],
                                  zi=np.array([lam[k] * z0[k]]))[0]
            x[first + 1:] = np.real(z @ V.T)
            if not np.isfinite(limit):
                return x
            command = kp * (r[first:] - x[first:-1, 1]) + x[first:-1, 2]
            beyond = np.flatnonzero(np.abs(command) > limit)
            if len(beyond) == 0:
                return x
            k = first + int(beyond[0])
            if sub is None:
                h = self.dt / CLIP_SUBSTEPS
                sub = (*self._discrete(p, self.dt, True), *self._discrete(p, h, False),
                       *self._discrete(p, h, True))
            Pw, Gw, Pu, Gu, Pc, Gc = sub
            while k < n - 1 and abs(kp * (r[k] - x[k, 1]) + x[k, 2]) > limit:
                u = self.u[k]
                side = np.sign(kp * (r[k] - x[k, 1]) + x[k, 2]) * limit
                # a command still beyond the limit at the period's end was beyond it
                # throughout (it falls back monotonically after a kick): one clipped step
                whole = Pw @ x[k] + Gw @ np.append(u, side)
                end = kp * (r[k] - whole[1]) + whole[2]
                if end * side > 0 and abs(end) > limit:
                    x[k + 1] = whole
                    k += 1
                    continue
                state = x[k].copy()
                for _ in range(CLIP_SUBSTEPS):
                    cmd = kp * (r[k] - state[1]) + state[2]
                    if abs(cmd) > limit:
                        state = Pc @ state + Gc @ np.append(u, np.sign(cmd) * limit)
                    else:
                        state = Pu @ state + Gu @ u
                x[k + 1] = state
                k += 1
            if k >= n - 1:
                return x
            first = k

    def residuals(self, p: np.ndarray) -> np.ndarray:
        """Weighted residuals: angle rows (the encoder read ``δ`` s from the sample
        instant), then current rows (the current read ``delay`` samples after the state
        it shows)."""
        try:
            with np.errstate(over="ignore", invalid="ignore"):
                x = self.states(p) if np.all(np.isfinite(p)) else None
        except np.linalg.LinAlgError:
            x = None
        if x is None or not np.all(np.isfinite(x)):
            # a solver step into an unstable or undefined loop: a residual it must reject
            return np.full(len(self.theta) + self.rows, DIVERGED_RESIDUAL)
        angle = (x[:, 0] + p[10] * x[:, 1] - self.theta) / self.angle_sd
        model_i = x[: self.rows, 3] + p[5]
        current = (model_i - self.current[self.delay:]) / self.current_sd
        return np.concatenate([angle, current])

    def sample_of_row(self) -> np.ndarray:
        """The sample each residual row belongs to (for the blocks)."""
        n = len(self.theta)
        return np.concatenate([np.arange(n), np.arange(self.rows)])


def fit_closed_loop(theta: np.ndarray, current: np.ndarray, target: np.ndarray, dt: float,
                    loop: SpeedLoop, spec: ModelSpec, kt_over_j: float, d_over_j: float,
                    effect_start: np.ndarray, quant_rad: float,
                    current_sd: float) -> ClosedLoopFit:
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
    """
    # the ripple's current over each period: the law's where it holds, else the samples'
    period_current = loop.period_current if loop.holds else current
    inputs = effect_inputs(spec, theta, period_current, dt, quant_rad)
    angle_sd = max(quant_rad / np.sqrt(12.0), MIN_ANGLE_SD_RAD)
    # a floor()-quantized encoder reads half a step low on average
    measured = theta + 0.5 * quant_rad
    model = _LoopModel(measured, current, target, inputs, dt, loop.delay, angle_sd,
                       current_sd, loop.saturates)
    # τ enters as its logarithm (positive, and unbounded for the Levenberg-Marquardt
    # solver, whose QR steps are far cheaper here than a bounded solver's SVD)
    start = np.concatenate([[kt_over_j, d_over_j, loop.kp, loop.ki, np.log(START_LAG_S), 0.0,
                             measured[0], 0.0, loop.offset_A,
                             current[min(loop.delay, len(current) - 1)], 0.0],
                            effect_start, [loop.limit_A] if loop.saturates else []])
    scale = np.abs(start)
    scale[scale == 0] = 1.0
    scale[4], scale[10] = 1.0, dt
    res = least_squares(model.residuals, start, x_scale=scale, method="lm",
                        max_nfev=MAX_EVALUATIONS * (len(start) + 1))
    p, J, e = res.x, res.jac, res.fun
    n_angle = len(measured)
    current_ratio = float(np.sqrt(np.mean(e[n_angle:] ** 2)))
    angle_ratio = float(np.sqrt(np.mean(e[:n_angle] ** 2)))
    blocks = BLOCKS
    edges = np.linspace(0, len(measured), blocks + 1)
    block_of = np.searchsorted(edges, model.sample_of_row(), side="right") - 1
    # in the solver's scaled coordinates (the parameters span many decades); a column the
    # run does not excite (an effect's column zero throughout) is left out
    Js = J * scale[None, :]
    used = np.flatnonzero(np.linalg.norm(Js, axis=0) > 0)
    Js = Js[:, used]
    scores = np.stack([Js[block_of == b].T @ e[block_of == b] for b in range(blocks)])
    S = scores.T @ scores * blocks / (blocks - 1)
    cov = np.full((len(p), len(p)), np.nan)
    try:
        Hinv = np.linalg.inv(Js.T @ Js)
        cov[np.ix_(used, used)] = (Hinv @ S @ Hinv) * np.outer(scale[used], scale[used])
    except np.linalg.LinAlgError:
        pass
    holds = bool(res.status >= 0 and current_ratio <= MAX_CURRENT_RATIO and p[0] > 0
                 and np.isfinite(cov[0, 0]))
    message = "" if holds else (
        f"the simulated speed loop explains the current only to {current_ratio:.2g} times "
        f"its noise (at most {MAX_CURRENT_RATIO}): the output-error refinement is not used")
    return ClosedLoopFit(float(p[0]), float(p[1]), float(np.sqrt(max(cov[0, 0], 0.0))),
                         float(np.sqrt(max(cov[1, 1], 0.0))), blocks - 1, float(p[2]),
                         float(p[3]), float(np.exp(np.clip(p[4], *LOG_LAG_RANGE))),
                         current_ratio, angle_ratio, holds, message)
