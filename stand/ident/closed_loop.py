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
from scipy.stats import chi2

from stand.diagnosis.model import ModelSpec, periodic_mean
from stand.ident.estimate import BLOCKS, t_interval
from stand.ident.speed_loop import DELAY_SIGMAS, SpeedLoop
from stand.ident.supply import DriveSupply

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
#: Most evaluations per parameter and one where the drive's supply is modelled (each
#: steps through the mode switches; the fit starts from the one without the supply).
SUPPLY_STEPS = 5
#: Sub-steps of a period within which the drive's mode changes (the current command
#: reaches or leaves its limit, the needed voltage the supply).
CLIP_SUBSTEPS = 16
#: Most mode switches located within one period (beyond them, whole sub-steps).
MAX_SWITCHES = 8
#: Periods first stepped in one mode before the mode is checked (doubled while it holds).
FIRST_STRETCH = 64
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


#: Modes of the drive between samples: the PI law's command followed with lag ``τ``,
#: the command clipped at the current limit ``±L`` (followed with ``τ``), and the supply
#: voltage ``±V`` applied (the armature's own dynamics).
LAW, LIMIT_UP, LIMIT_DOWN, SUPPLY_UP, SUPPLY_DOWN = range(5)


class _Mode:
    """One mode's continuous system ``x' = A·x + B·u`` (``u = [r, g…, 1]``) in modal form:
    its exact zero-order-hold step over any length."""

    def __init__(self, A: np.ndarray, B: np.ndarray) -> None:
        self.A, self.B = A, B
        lam, V = np.linalg.eig(A)
        self.general = bool(np.linalg.cond(V) > MAX_MODE_CONDITION)
        if not self.general:
            self.lam, self.V = lam, V
            self.Vinv = np.linalg.inv(V)
            self.VinvB = self.Vinv @ B

    def step(self, h: float) -> tuple[np.ndarray, np.ndarray]:
        """``Φ``, ``Γ`` over ``h`` s."""
        if self.general:   # (nearly) defective: the general way
            n, m = self.B.shape
            M = np.zeros((n + m, n + m))
            M[:n, :n], M[:n, n:] = self.A * h, self.B * h
            E = expm(M)
            return E[:n, :n], E[:n, n:]
        # Φ = V·e^Λh·V⁻¹, Γ = V·φ₁(Λh)·V⁻¹·B·h with φ₁(x) = (eˣ − 1)/x (1 at x = 0)
        x = self.lam * h
        grow = np.exp(x)
        small = np.abs(x) < 1e-8
        phi1 = np.where(small, 1.0 + x / 2, (grow - 1.0) / np.where(small, 1.0, x))
        Phi = np.real((self.V * grow) @ self.Vinv)
        Gamma = np.real((self.V * phi1) @ self.VinvB) * h
        return Phi, Gamma


def _grid(mode: _Mode, h: float) -> tuple[np.ndarray, np.ndarray]:
    """``Φ``, ``Γ`` of ``mode`` over ``h, 2h, …, CLIP_SUBSTEPS·h``, stacked."""
    steps = [mode.step(h * (j + 1)) for j in range(CLIP_SUBSTEPS)]
    return np.stack([s[0] for s in steps]), np.stack([s[1] for s in steps])


class _LoopModel:
    """The loop and the mechanics as a function of the parameter vector
    ``[a, d, kp, ki, ln τ, off, θ0, ω0, I0, i0, δ, b_1 … b_m]``, then, when the drive's
    supply is modelled, ``[ln(V/L), ln(R/L), ln(Kt/L)]`` of the armature, and the current
    limit last when the loop reaches it."""

    FIXED = 11

    def __init__(self, theta: np.ndarray, current: np.ndarray, target: np.ndarray,
                 inputs: np.ndarray, dt: float, delay: int, angle_sd: float,
                 current_sd: float, limited: bool, supplied: bool = False) -> None:
        self.theta, self.current, self.dt, self.delay = theta, current, dt, delay
        self.u = np.column_stack([target[:-1], inputs, np.ones(len(target) - 1)])
        self.effects = inputs.shape[1]
        self.angle_sd, self.current_sd = angle_sd, current_sd
        self.rows = len(theta) - delay
        self.limited = limited
        self.supply_at = self.FIXED + self.effects if supplied else None

    def _modes(self, p: np.ndarray) -> dict[int, _Mode]:
        """The continuous system of each mode the parameters can reach."""
        a, d, kp, ki = p[:4]
        tau = float(np.exp(np.clip(p[4], *LOG_LAG_RANGE)))
        m = self.u.shape[1]
        A = np.array([[0.0, 1.0, 0.0, 0.0], [0.0, -d, 0.0, a], [0.0, -ki, 0.0, 0.0],
                      [0.0, 0.0, 0.0, 0.0]])
        B = np.zeros((4, m))
        B[2, 0] = ki
        B[1, 1:m - 1] = p[self.FIXED:self.FIXED + self.effects]
        law_A, law_B = A.copy(), B.copy()
        law_A[3] = [0.0, -kp / tau, 1.0 / tau, -1.0 / tau]
        law_B[3, 0] = kp / tau
        modes = {LAW: _Mode(law_A, law_B)}
        if self.limited:
            limit = p[-1]
            clip_A = A.copy()
            clip_A[3, 3] = -1.0 / tau
            for mode, side in ((LIMIT_UP, 1.0), (LIMIT_DOWN, -1.0)):
                clip_B = B.copy()
                clip_B[3, -1] = side * limit / tau
                modes[mode] = _Mode(clip_A, clip_B)
        if self.supply_at is not None:
            volts, ohms, emf = np.exp(np.clip(p[self.supply_at:self.supply_at + 3], -50, 50))
            arm_A = A.copy()
            arm_A[3] = [0.0, -emf, 0.0, -ohms]
            for mode, side in ((SUPPLY_UP, 1.0), (SUPPLY_DOWN, -1.0)):
                arm_B = B.copy()
                arm_B[3, -1] = side * volts
                modes[mode] = _Mode(arm_A, arm_B)
        return modes

    def _bounds(self, p: np.ndarray) -> tuple[float, float, float, float, float, float]:
        """``kp``, ``τ``, the current limit, and ``V/L``, ``R/L``, ``Kt/L`` (infinite,
        0, 0 without a supply)."""
        tau = float(np.exp(np.clip(p[4], *LOG_LAG_RANGE)))
        limit = float(p[-1]) if self.limited else np.inf
        if self.supply_at is None:
            return float(p[2]), tau, limit, np.inf, 0.0, 0.0
        volts, ohms, emf = np.exp(np.clip(p[self.supply_at:self.supply_at + 3], -50, 50))
        return float(p[2]), tau, limit, float(volts), float(ohms), float(emf)

    @staticmethod
    def _demand(x: np.ndarray, r: np.ndarray | float,
                b: tuple[float, float, float, float, float, float]
                ) -> tuple[np.ndarray, np.ndarray]:
        """The law's current command, and the voltage the current loop asks for over
        ``L`` (A/s), at states ``x`` under targets ``r``."""
        kp, tau, limit, _, ohms, emf = b
        command = kp * (r - x[..., 1]) + x[..., 2]
        rate = (np.clip(command, -limit, limit) - x[..., 3]) / tau
        return command, rate + ohms * x[..., 3] + emf * x[..., 1]

    def mode_of(self, x: np.ndarray, r: np.ndarray | float,
                b: tuple[float, float, float, float, float, float]) -> np.ndarray:
        """The drive's mode at states ``x`` under targets ``r``."""
        command, need = self._demand(x, r, b)
        limit, volts = b[2], b[3]
        mode = np.full(np.shape(command), LAW)
        mode[command > limit] = LIMIT_UP
        mode[command < -limit] = LIMIT_DOWN
        mode[need > volts] = SUPPLY_UP
        mode[need < -volts] = SUPPLY_DOWN
        return mode

    def _margins(self, mode: int, x: np.ndarray, r: float,
                 b: tuple[float, float, float, float, float, float]) -> np.ndarray:
        """How far states ``x`` (rows) are inside ``mode`` by each of its conditions
        (columns; positive inside)."""
        command, need = self._demand(x, r, b)
        limit, volts = b[2], b[3]
        if mode == SUPPLY_UP:
            return (need - volts)[:, None]
        if mode == SUPPLY_DOWN:
            return (-need - volts)[:, None]
        supply = volts - np.abs(need)
        if mode == LIMIT_UP:
            return np.column_stack([command - limit, supply])
        if mode == LIMIT_DOWN:
            return np.column_stack([-command - limit, supply])
        return np.column_stack([limit - np.abs(command), supply])

    def _period(self, x: np.ndarray, k: int, modes: dict[int, _Mode],
                b: tuple[float, float, float, float, float, float],
                grids: dict[int, tuple[np.ndarray, np.ndarray]]) -> np.ndarray:
        """Step period ``k`` from ``x`` through the drive's mode switches: in each mode,
        the states ``1/CLIP_SUBSTEPS`` of the period apart are checked, and the step
        ends at the first switch (where the mode's margin, linear between two of them,
        reaches zero)."""
        r, u = float(self.u[k, 0]), self.u[k]
        t, events = 0.0, 0
        mode = int(self.mode_of(x, r, b))
        while t < 1.0 - 1e-9:
            if mode not in grids:
                grids[mode] = _grid(modes[mode], self.dt / CLIP_SUBSTEPS)
            Phis, Gammas = grids[mode]
            count = min(CLIP_SUBSTEPS, int(np.floor((1.0 - t) * CLIP_SUBSTEPS + 1e-6)))
            states = Phis[:count] @ x + Gammas[:count] @ u
            margins = self._margins(mode, np.vstack([x, states]), r, b)
            crossed = (margins[1:] < 0) & (margins[:-1] > 0)
            rows = np.flatnonzero(np.any(crossed, axis=1))
            if len(rows) == 0 or events >= MAX_SWITCHES:
                rest = 1.0 - t - count / CLIP_SUBSTEPS
                x = states[count - 1] if count else x
                if rest > 1e-9:
                    Phi, Gamma = modes[mode].step(rest * self.dt)
                    x = Phi @ x + Gamma @ u
                return x
            j = int(rows[0])
            before, after = margins[j], margins[j + 1]
            hit = crossed[j]
            share = (j + float(np.min(before[hit] / (before[hit] - after[hit])))) / CLIP_SUBSTEPS
            Phi, Gamma = modes[mode].step(share * self.dt)
            x = Phi @ x + Gamma @ u
            t += share
            new = int(self.mode_of(x, r, b))
            # just short of the switch: the mode beyond it
            mode = new if new != mode else int(self.mode_of(states[j], r, b))
            events += 1
        return x

    def states(self, p: np.ndarray) -> np.ndarray:
        """States ``[θ, ω, I, i]`` at every sample, shape (samples, 4).

        A stretch of periods in one mode of the drive is stepped as four first-order
        recursions in modal form; a period within which the mode changes is stepped
        through its switches (:meth:`_period`)."""
        modes = self._modes(p)
        b = self._bounds(p)
        constrained = bool(np.isfinite(b[2]) or np.isfinite(b[3]))
        n = len(self.theta)
        x = np.empty((n, 4))
        x[0] = p[6:10]
        r = self.u[:, 0]
        grids: dict[int, tuple[np.ndarray, np.ndarray]] = {}
        k, chunk = 0, FIRST_STRETCH
        while k < n - 1:
            mode = int(self.mode_of(x[k], r[k], b)) if constrained else LAW
            count = n - 1 - k if not constrained else min(n - 1 - k, chunk)
            stretch = self._stretch(modes[mode], x[k], k, count)
            if not constrained:
                x[k + 1:] = stretch
                break
            starts = np.vstack([x[k:k + 1], stretch[:-1]])
            leaves = (self.mode_of(starts, r[k:k + count], b) != mode)
            ends = self.mode_of(stretch, r[k:k + count], b) != mode
            bad = np.flatnonzero(leaves | ends)
            if len(bad) == 0:
                x[k + 1:k + count + 1] = stretch
                k += count
                chunk *= 2
                continue
            j = int(bad[0])
            x[k + 1:k + j + 1] = stretch[:j]
            k += j
            chunk = FIRST_STRETCH
            if not leaves[j]:   # the mode changes within period k
                x[k + 1] = self._period(x[k], k, modes, b, grids)
                k += 1
        return x

    def _stretch(self, mode: _Mode, x0: np.ndarray, k: int, count: int) -> np.ndarray:
        """States after periods ``k … k + count − 1`` in one mode, from ``x0``."""
        u = self.u[k:k + count]
        if mode.general:
            Phi, Gamma = mode.step(self.dt)
            out = np.empty((count, 4))
            state = x0
            for j in range(count):
                state = Phi @ state + Gamma @ u[j]
                out[j] = state
            return out
        lam = mode.lam * self.dt
        grow = np.exp(lam)
        small = np.abs(lam) < 1e-8
        phi1 = np.where(small, 1.0 + lam / 2, (grow - 1.0) / np.where(small, 1.0, lam))
        gain = ((phi1[:, None] * mode.VinvB) * self.dt).T
        drive = u @ gain.real + 1j * (u @ gain.imag)
        z0 = mode.Vinv @ x0
        z = np.empty((count, 4), dtype=complex)
        for c in range(4):
            z[:, c] = lfilter([1.0], [1.0, -grow[c]], drive[:, c],
                              zi=np.array([grow[c] * z0[c]]))[0]
        # the real part of z·Vᵀ (numpy's complex matrix product is far slower)
        return np.asarray(z.real @ mode.V.real.T - z.imag @ mode.V.imag.T)

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
    model = _LoopModel(measured, current, target, inputs, dt, loop.delay, angle_sd,
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
    supplied = _LoopModel(measured, current, target, inputs, dt, loop.delay, angle_sd,
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
        undelayed = _LoopModel(measured, current, target, inputs, dt, 0, angle_sd,
                               current_sd, bool(np.isfinite(limit)), True)
        start[9] = current[0]
        fit0, p0 = _solve(undelayed, start, dt, SUPPLY_STEPS)
        if not _fits_better(supplied, p, undelayed, p0):
            return fit0
    return fit


def _fits_better(model: _LoopModel, p: np.ndarray, other: _LoopModel,
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


def _solve(model: _LoopModel, start: np.ndarray, dt: float,
           evaluations: int) -> tuple[ClosedLoopFit, np.ndarray]:
    """Levenberg-Marquardt from ``start`` (at most ``evaluations`` per parameter and one),
    and the fit with its block-sandwich covariance; also the parameters."""
    scale = np.abs(start)
    scale[scale == 0] = 1.0
    scale[4], scale[10] = 1.0, dt
    if model.supply_at is not None:
        scale[model.supply_at:model.supply_at + 3] = 1.0
    res = least_squares(model.residuals, start, x_scale=scale, method="lm",
                        max_nfev=evaluations * (len(start) + 1))
    p, J, e = res.x, res.jac, res.fun
    n_angle = len(model.theta)
    current_ratio = float(np.sqrt(np.mean(e[n_angle:] ** 2)))
    angle_ratio = float(np.sqrt(np.mean(e[:n_angle] ** 2)))
    blocks = BLOCKS
    edges = np.linspace(0, n_angle, blocks + 1)
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
                         current_ratio, angle_ratio, holds, message), p
