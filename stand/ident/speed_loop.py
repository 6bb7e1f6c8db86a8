"""The current between samples under a PI speed loop, from the loop law.

A drive in speed mode sets its current command from the held speed target ``r`` (the
master's target over the period after each sample) by a PI law::

    i(t) = kp·(r − ω(t)) + I(t),      I' = ki·(r − ω)

Each change of the target kicks the current by ``kp·Δr``, and the loop pulls it back
faster than the samples follow, so the sampled current misses part of the current that
accelerated the rotor (about ``π·f_loop·Δt`` of it, ``f_loop = kp·Kt/(2π·J)``); in one
run this is indistinguishable from inertia. When the run holds the target
(``speed_target_rad_s``), the law gives that current exactly from what is measured:

- **Gains.** At the sample instants ``i_n = kp·(r_{n−1} − ω_n) + ki·(R_n − θ_n) + c``
  with ``R_n = Σ_{m<n} r_m·Δt`` and ``c`` the integrator's start plus any sensor offset.
  Weighted least squares gives ``kp``, ``ki``, ``c``, with ``ω_n`` from five-point
  differences of the angle that do not straddle a target change (``ω`` has a kink
  there), each row weighed by the current noise and the encoder step's error through
  its speed difference. The current samples' delay is the shortest shift
  (0 … ``MAX_DELAY``) that no longer one fits clearly better.
- **Check.** The law must explain the measured current to within its noise: a loop
  that saturates its voltage, or another control law, leaves a residual well above the
  noise, and then nothing is reconstructed (a warning says why). Samples at the largest
  current are left out of the fit; where the law goes beyond that current there, it is
  the drive's current limit.
- **Current over each period.** ``ī_n = kp·(r_n − ω̄_n) + c + ki·(R_n − θ_n + θ_0) +
  ki·Δt/2·(r_n − ω̄_n)`` with ``ω̄_n = (θ_{n+1} − θ_n)/Δt``, the period's exact mean speed.
  It needs no instantaneous speed and carries no current-sensor noise. Within a period
  whose start goes beyond the current limit the law is clipped at it.

What the reconstruction leaves out is the drive's own delay between speed and current
(its current loop's lag, the speed loop's computation): the samples read
``i ≈ i_cmd − τ·i_cmd'``, which inflates the fitted ``kp`` by about ``2π·f_loop·τ``.
The gains are also fitted with a lag term (the acceleration as a column); on the
loop's exponential transients lag and gain trade off, so the difference between the
two fits enters the uncertainty of Kt/J.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from stand.diagnosis.signals import quantization_step
from stand.ident.noise import noise_sigma
from stand.runfile import Run

#: Column of a single-motor run with the speed target held over the period after each
#: sample, rad/s (CONTRACT §1, optional).
TARGET_COLUMN = "speed_target_rad_s"
#: Largest delay of the current samples tried, samples.
MAX_DELAY = 6
#: A longer delay is taken when it lowers the law's mean square residual by this many
#: of its standard deviations.
DELAY_SIGMAS = 3.0
#: Largest RMS of the loop law's residual over the noise expected in each row (the
#: current's, from its sample-to-sample differences, which a fast loop inflates a little,
#: and the encoder step's through the speed) for which the law counts as holding.
MAX_RESIDUAL_RATIO = 1.5
#: Samples within this many noise deviations of the largest |current| may be at the
#: drive's current limit; it is reached when the law goes beyond it by as much at
#: ``MIN_LIMIT_SAMPLES`` of them.
LIMIT_SIGMAS = 4.0
MIN_LIMIT_SAMPLES = 3
#: Points per period on which a clipped current is averaged.
SUBSTEPS = 64
#: Fewest rows for the gains' fit.
MIN_ROWS = 50
#: A trimmed fit leaves out samples the law misses by more than this many of their noise
#: deviations (white noise alone: 6e-5 of them), in at most this many passes.
TRIM_SIGMAS = 4.0
TRIM_PASSES = 6


@dataclass(frozen=True)
class SpeedLoop:
    """A PI speed loop fitted to one run, and the current it gives over each period.

    Attributes
    ----------
    kp : float
        Proportional gain, A per rad/s.
    ki : float
        Integral gain, A per rad.
    offset_A : float
        Integrator start plus sensor offset, A.
    delay : int
        Samples the current samples lag the encoder.
    residual_ratio : float
        RMS of the law's residual over the current noise.
    kp_rel_sd : float
        Relative standard uncertainty of ``kp`` (statistical and current-loop lag).
    period_current : ndarray
        Current over the period after each sample, A (the last repeats the one before),
        or an empty array when the law does not hold.
    message : str
        Why nothing was reconstructed, or empty.
    limit_A : float
        The drive's current limit where the law reaches it (the period current is
        clipped there), A; infinite where it does not.
    """

    kp: float
    ki: float
    offset_A: float
    delay: int
    residual_ratio: float
    kp_rel_sd: float
    period_current: np.ndarray
    message: str = ""
    limit_A: float = np.inf

    @property
    def saturates(self) -> bool:
        """The law reaches the drive's current limit."""
        return bool(np.isfinite(self.limit_A))

    @property
    def holds(self) -> bool:
        """The law explains the measured current (the reconstruction is usable)."""
        return len(self.period_current) > 0


#: Five-point differences of the angle at a sample (first, second derivative; times
#: ``1/(12·Δt)`` and ``1/(12·Δt²)``), over samples ``n − 2 … n + 2`` (central) or
#: ``n − 4 … n`` (left; the right one is its mirror).
CENTRAL = (np.array([1.0, -8.0, 0.0, 8.0, -1.0]), np.array([-1.0, 16.0, -30.0, 16.0, -1.0]))
LEFT = (np.array([3.0, -16.0, 36.0, -48.0, 25.0]), np.array([11.0, -56.0, 114.0, -104.0, 35.0]))


def kink_free_derivatives(theta: np.ndarray, target: np.ndarray,
                          dt: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Speed and acceleration at the samples from five-point differences of the angle
    that do not straddle a change of the target (the acceleration jumps there): central
    where they can, else one-sided. NaN where no stencil fits. The third array is the
    speed's sensitivity to independent angle errors (its error's standard deviation per
    rad of angle error), 1/s."""
    n = len(theta)
    kinks = np.zeros(n + 8, dtype=bool)
    kinks[np.flatnonzero(np.diff(target) != 0) + 1] = True
    omega, alpha = np.full(n, np.nan), np.full(n, np.nan)
    spread = np.full(n, np.nan)
    stencils = [(np.arange(-2, 3), CENTRAL, 1.0), (np.arange(-4, 1), LEFT, 1.0),
                (np.arange(4, -1, -1), LEFT, -1.0)]
    filled = np.zeros(n, dtype=bool)
    for offsets, (first, second), sign in stencils:
        lo, hi = int(offsets.min()), int(offsets.max())
        rows = np.arange(max(0, -lo), n - max(0, hi))
        inside = np.zeros(len(rows), dtype=bool)
        for k in range(lo + 1, hi):   # a kink strictly inside the stencil's span
            inside |= kinks[rows + k]
        rows = rows[~inside & ~filled[rows]]
        window = theta[rows[:, None] + offsets[None, :]]
        omega[rows] = sign * window @ first / (12 * dt)
        alpha[rows] = window @ second / (12 * dt**2)
        spread[rows] = float(np.linalg.norm(first)) / (12 * dt)
        filled[rows] = True
    return omega, alpha, spread


def tracking_errors(theta: np.ndarray, target: np.ndarray,
                    dt: float) -> tuple[np.ndarray, np.ndarray]:
    """The loop's speed error over the period after each sample, ``r_n − ω̄_n`` with
    ``ω̄_n = (θ_{n+1} − θ_n)/Δt`` (rad/s; 0 after the last sample), and its integral at
    each sample, ``Σ_{m<n} r_m·Δt − (θ_n − θ_0)`` (rad): what the PI law's proportional
    and integral gains multiply."""
    speed_error = np.append(target[:-1] - np.diff(theta) / dt, 0.0)
    integral = np.concatenate([[0.0], np.cumsum(target[:-1] * dt)])
    return speed_error, integral - (theta - theta[0])


def fit_speed_loop(theta: np.ndarray, current: np.ndarray, target: np.ndarray,
                   dt: float, quant_rad: float = 0.0, trim: bool = False) -> SpeedLoop:
    """Fit the PI law to a speed-mode run and reconstruct the current over each period.

    Parameters
    ----------
    theta : ndarray
        Measured angle, rad.
    current : ndarray
        Measured current, A.
    target : ndarray
        Speed target held over the period after each sample, rad/s.
    dt : float
        Sample period, s.
    quant_rad : float
        Encoder step, rad: its error (``q/√12``) enters the speed at each sample, and
        the law's residual is weighed by the current and speed noise of its row.
    trim : bool
        Leave out, and refit without, the samples the law misses by more than
        ``TRIM_SIGMAS`` of their noise (repeated until none is left out): samples within
        a stretch where the drive's voltage saturates, when the law is wanted only as
        the start of a simulation that models that (:mod:`stand.ident.closed_loop`).
    """
    n = len(theta)
    omega, alpha, spread = kink_free_derivatives(theta, target, dt)
    angle_sd = quant_rad / np.sqrt(12.0)
    error_int = tracking_errors(theta, target, dt)[1]
    previous = np.concatenate([target[:1], target[:-1]])
    sigma = noise_sigma(current)
    # samples at the largest |current| may sit at the drive's current limit: fitted
    # without them, and the limit is taken as reached where the law exceeds it there
    limit = float(np.max(np.abs(current)))
    at_limit = np.abs(current) >= limit - LIMIT_SIGMAS * sigma
    keep = np.isfinite(omega)
    keep[0] = False   # read before the first target: the one before it is unknown
    keep[n - MAX_DELAY:] = False
    X = np.column_stack([previous - omega, error_int, np.ones(n), alpha])
    if not sigma > 0:
        return SpeedLoop(0.0, 0.0, 0.0, 0, np.inf, np.inf, np.empty(0),
                         "a noise-free current: the speed loop's gains cannot be fitted")

    def weighted(rows: np.ndarray, y: np.ndarray, columns: int
                 ) -> tuple[np.ndarray, np.ndarray, float]:
        """Weighted least squares (weights from the rows' noise at the plain fit's kp)."""
        beta, *_ = np.linalg.lstsq(X[rows, :columns], y, rcond=None)
        sd = np.sqrt(sigma**2 + (beta[0] * angle_sd * spread[rows]) ** 2)
        A, b = X[rows, :columns] / sd[:, None], y / sd
        beta, *_ = np.linalg.lstsq(A, b, rcond=None)
        return beta, A, float(np.sum((b - A @ beta) ** 2)) / (len(rows) - columns)

    def trimmed(rows: np.ndarray, delay: int) -> np.ndarray:
        """``rows`` less those the law misses by more than ``TRIM_SIGMAS``, repeatedly."""
        for _ in range(TRIM_PASSES):
            beta = weighted(rows, current[rows + delay], 3)[0]
            sd = np.sqrt(sigma**2 + (beta[0] * angle_sd * spread[rows]) ** 2)
            inside = np.abs(current[rows + delay] - X[rows, :3] @ beta) <= TRIM_SIGMAS * sd
            if inside.all() or inside.sum() < MIN_ROWS:
                break
            rows = rows[inside]
        return rows

    best: tuple[float, int, np.ndarray] | None = None
    for delay in range(MAX_DELAY + 1):
        rows = np.flatnonzero(keep[:n - delay] & ~at_limit[delay:])
        if len(rows) < MIN_ROWS:
            continue
        if trim:
            rows = trimmed(rows, delay)
        mean_square = weighted(rows, current[rows + delay], 4)[2]
        # a longer delay must fit better beyond the sampling error of a mean square
        # (relative standard deviation √(2/rows)), else the shorter one stays; trimmed, it
        # must also explain as many samples (a drive whose supply slows the current looks
        # delayed here: the simulation that models the supply tests the delay against none,
        # :func:`~stand.ident.closed_loop.fit_closed_loop`)
        if best is None or (
                mean_square < best[0] * (1 - DELAY_SIGMAS * np.sqrt(2 / len(rows)))
                and (not trim or len(rows) >= len(best[2]))):
            best = (mean_square, delay, rows)
    if best is None:
        smooth = int(np.count_nonzero(keep))
        reason = (f"only {smooth} of {n} samples have a speed free of a target change "
                  "around them (a target that changes at almost every sample, such as a "
                  "sine, leaves no window without a kink; hold the target over a few "
                  "samples)" if smooth < MIN_ROWS else
                  "too few samples away from the current limit")
        return SpeedLoop(0.0, 0.0, 0.0, 0, np.inf, np.inf, np.empty(0),
                         f"{reason}: the speed loop's gains cannot be fitted")
    _, delay, rows = best
    y = current[rows + delay]
    plain, A, mean_square = weighted(rows, y, 3)
    lagged, _, lag_square = weighted(rows, y, 4)
    ratio = float(np.sqrt(lag_square))
    kp, ki, c = (float(v) for v in plain)
    limited = np.flatnonzero(keep[:n - delay] & at_limit[delay:])
    beyond = np.abs(X[limited] @ lagged) > limit + LIMIT_SIGMAS * sigma
    limit_A = limit if int(np.sum(beyond)) >= MIN_LIMIT_SAMPLES else np.inf
    if not (kp > 0 and ratio <= MAX_RESIDUAL_RATIO):
        return SpeedLoop(kp, ki, c, delay, ratio, np.inf, np.empty(0),
                         limit_A=limit_A, message=
                         f"the PI speed law explains the current only to {ratio:.2g} times its "
                         f"noise (at most {MAX_RESIDUAL_RATIO} for the law to hold): the loop "
                         "saturates its voltage or follows another law, so the current between "
                         "samples is not reconstructed and Kt/J may be high by up to "
                         "π·f_loop·Δt")
    cov = np.linalg.inv(A.T @ A) * mean_square
    # with the drive's delay τ (current loop, computation): i ≈ i_cmd − τ·i_cmd'
    # = … + τ·kp·α − τ·ki·(r − ω); on exponential transients τ and kp trade off, so the
    # two fits' difference enters the uncertainty
    tau = float(lagged[3] / lagged[0]) if lagged[0] > 0 else -1.0
    kp_other = kp
    if 0.0 <= tau * ki < 1.0:
        kp, kp_other = float(lagged[0] + tau * lagged[1]), kp
        ki, c = float(lagged[1]), float(lagged[2])
    rel_sd = float(np.hypot(np.sqrt(cov[0, 0]) / kp, (kp_other - kp) / kp))
    period = _period_current(theta, target, omega, error_int, dt, kp, ki, c, limit_A)
    return SpeedLoop(kp, ki, c, delay, ratio, rel_sd, period, limit_A=limit_A)


def _period_current(theta: np.ndarray, target: np.ndarray, omega: np.ndarray,
                    error_int: np.ndarray, dt: float, kp: float, ki: float, c: float,
                    limit: float) -> np.ndarray:
    """Mean of the law's current over the period after each sample, clipped at
    ``±limit`` (the last period repeats the one before).

    Unclipped, the mean is exact from the period's mean speed. Where the law's current
    at a period's start exceeds the limit, the speed within the period is taken as the
    quadratic through the speeds at its ends and its mean, and the law's current on
    ``SUBSTEPS`` points of it is clipped and averaged.
    """
    mean_speed = np.diff(theta) / dt
    r = target[:-1]
    period = kp * (r - mean_speed) + c + ki * error_int[:-1] + ki * dt / 2 * (r - mean_speed)
    if np.isfinite(limit):
        start = kp * (r - omega[:-1]) + c + ki * error_int[:-1]
        w0, w1 = omega[:-1], omega[1:]
        for k in np.flatnonzero(np.isfinite(w0) & np.isfinite(w1) & (np.abs(start) > limit)):
            s = (np.arange(SUBSTEPS) + 0.5) / SUBSTEPS
            # quadratic ω(s) with ω(0) = w0, ω(1) = w1 and mean ω̄
            b2 = 3 * (w0[k] + w1[k]) - 6 * mean_speed[k]
            speed = w0[k] + (w1[k] - w0[k] - b2) * s + b2 * s**2
            drift = ki * dt * np.cumsum(r[k] - speed) / SUBSTEPS
            law = kp * (r[k] - speed) + c + ki * error_int[k] + drift
            period[k] = float(np.mean(np.clip(law, -limit, limit)))
    return np.concatenate([period, period[-1:]])


def speed_loop(run: Run) -> SpeedLoop | None:
    """The PI loop of ``run`` when it holds the speed target, else None."""
    if TARGET_COLUMN not in run:
        return None
    theta = run["position_rad"]
    return fit_speed_loop(theta, run["current_A"], run[TARGET_COLUMN], run.dt_s,
                          quantization_step(theta))
