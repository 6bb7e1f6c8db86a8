"""The speed loop and the mechanics simulated between samples, as a function of the
fitted parameters (:class:`LoopModel`, for :mod:`stand.ident.closed_loop`).

The drive is in one of five modes between two samples: the PI law's command followed
with the current loop's lag, the command held at ``±`` the current limit, or ``±`` the
supply voltage applied to the armature (``L·i' = ±V − R·i − Kt·ω``); and in each of them
the speed loop's integrator runs, or is held at ``±`` the current limit while the error
would wind it beyond (the drive's clamp against wind-up). Within each mode the
system is linear and its exact zero-order-hold step is taken in modal form; a stretch of
periods in one mode is four first-order recursions, and a period within which the mode
changes is stepped through its switches, each located within the period.
"""

from __future__ import annotations

import numpy as np
from scipy.linalg import expm
from scipy.signal import lfilter

#: Range of ``ln τ`` the simulation takes (1 µs … 1 s; a solver step beyond it is held
#: at its end).
LOG_LAG_RANGE = (np.log(1e-6), 0.0)
#: Weighted residual of every row where the simulation diverges (a rejected step).
DIVERGED_RESIDUAL = 1e6
#: Largest condition number of the continuous system's eigenvectors for the modal
#: matrix exponential (beyond it, scipy's Padé ``expm``).
MAX_MODE_CONDITION = 1e8
#: Sub-steps of a period within which the drive's mode changes (the current command
#: reaches or leaves its limit, the needed voltage the supply).
CLIP_SUBSTEPS = 16
#: Most mode switches located within one period (beyond them, whole sub-steps).
MAX_SWITCHES = 8
#: Periods first stepped in one mode before the mode is checked (doubled while it holds).
FIRST_STRETCH = 64


#: Modes of the drive between samples: the PI law's command followed with lag ``τ``,
#: the command clipped at the current limit ``±L`` (followed with ``τ``), and the supply
#: voltage ``±V`` applied (the armature's own dynamics).
LAW, LIMIT_UP, LIMIT_DOWN, SUPPLY_UP, SUPPLY_DOWN = range(5)
#: Added to a mode where the drive holds the speed loop's integrator at ``±`` the current
#: limit (a clamp against wind-up: the integrator stops while the error pushes it
#: beyond the limit, and runs again once the error turns).
HELD_UP, HELD_DOWN = 5, 10
#: Relative tolerance within which the integrator counts as at its limit.
HELD_TOLERANCE = 1e-9


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


class LoopModel:
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
        systems = {LAW: (law_A, law_B)}
        if self.limited:
            limit = p[-1]
            clip_A = A.copy()
            clip_A[3, 3] = -1.0 / tau
            for mode, side in ((LIMIT_UP, 1.0), (LIMIT_DOWN, -1.0)):
                clip_B = B.copy()
                clip_B[3, -1] = side * limit / tau
                systems[mode] = (clip_A, clip_B)
        if self.supply_at is not None:
            volts, ohms, emf = np.exp(np.clip(p[self.supply_at:self.supply_at + 3], -50, 50))
            arm_A = A.copy()
            arm_A[3] = [0.0, -emf, 0.0, -ohms]
            for mode, side in ((SUPPLY_UP, 1.0), (SUPPLY_DOWN, -1.0)):
                arm_B = B.copy()
                arm_B[3, -1] = side * volts
                systems[mode] = (arm_A, arm_B)
        modes = {mode: _Mode(*system) for mode, system in systems.items()}
        if self.limited:
            # the integrator held at the limit: I' = 0
            for mode, (sys_A, sys_B) in systems.items():
                held_A, held_B = sys_A.copy(), sys_B.copy()
                held_A[2], held_B[2] = 0.0, 0.0
                held = _Mode(held_A, held_B)
                modes[mode + HELD_UP] = modes[mode + HELD_DOWN] = held
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
        """The drive's mode at states ``x`` under targets ``r`` (the integrator's
        hold added: :data:`HELD_UP`, :data:`HELD_DOWN`)."""
        command, need = self._demand(x, r, b)
        limit, volts = b[2], b[3]
        mode = np.full(np.shape(command), LAW)
        mode[command > limit] = LIMIT_UP
        mode[command < -limit] = LIMIT_DOWN
        mode[need > volts] = SUPPLY_UP
        mode[need < -volts] = SUPPLY_DOWN
        if np.isfinite(limit):
            error = r - x[..., 1]
            at = limit * (1.0 - HELD_TOLERANCE)
            mode = mode + np.where((x[..., 2] >= at) & (error > 0), HELD_UP, 0)
            mode = mode + np.where((x[..., 2] <= -at) & (error < 0), HELD_DOWN, 0)
        return mode

    def _margins(self, mode: int, x: np.ndarray, r: float,
                 b: tuple[float, float, float, float, float, float]) -> np.ndarray:
        """How far states ``x`` (rows) are inside ``mode`` by each of its conditions
        (columns; positive inside)."""
        command, need = self._demand(x, r, b)
        limit, volts = b[2], b[3]
        drive, hold = mode % HELD_UP, mode - mode % HELD_UP
        if hold == HELD_UP:
            held = (r - x[:, 1])[:, None]
        elif hold == HELD_DOWN:
            held = (x[:, 1] - r)[:, None]
        else:
            held = (limit - np.abs(x[:, 2]))[:, None] if np.isfinite(limit) else x[:, :0]
        if drive == SUPPLY_UP:
            return np.column_stack([need - volts, held])
        if drive == SUPPLY_DOWN:
            return np.column_stack([-need - volts, held])
        supply = volts - np.abs(need)
        if drive == LIMIT_UP:
            return np.column_stack([command - limit, supply, held])
        if drive == LIMIT_DOWN:
            return np.column_stack([-command - limit, supply, held])
        return np.column_stack([limit - np.abs(command), supply, held])

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
            if mode >= HELD_UP:   # the integrator reaches its limit: held there
                x = x.copy()
                x[2] = b[2] if mode < HELD_DOWN else -b[2]
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
        with np.errstate(over="ignore", invalid="ignore"):
            angle = (x[:, 0] + p[10] * x[:, 1] - self.theta) / self.angle_sd
            model_i = x[: self.rows, 3] + p[5]
            current = (model_i - self.current[self.delay:]) / self.current_sd
        rows = np.concatenate([angle, current])
        return rows if np.all(np.isfinite(rows)) else np.full(len(rows), DIVERGED_RESIDUAL)

    def sample_of_row(self) -> np.ndarray:
        """The sample each residual row belongs to (for the blocks)."""
        n = len(self.theta)
        return np.concatenate([np.arange(n), np.arange(self.rows)])


__all__ = ["LAW", "LIMIT_DOWN", "LIMIT_UP", "LOG_LAG_RANGE", "LoopModel", "SUPPLY_DOWN",
           "SUPPLY_UP"]
