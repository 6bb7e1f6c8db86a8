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
- **Anti-windup.** At its current limit a drive keeps its integrator from winding up,
  each drive its own way, and after each stretch at the limit the integrator holds a
  state the one constant ``c`` misses. Where the law with one ``c`` is refused and the
  current holds a limit, ``c`` is fitted anew after each stretch (:func:`_with_resets`),
  at the delay the kicks show (:func:`kick_delay`).
- **Current over each period.** ``ī_n = kp·(r_n − ω̄_n) + c + ki·(R_n − θ_n + θ_0) +
  ki·Δt/2·(r_n − ω̄_n)`` with ``ω̄_n = (θ_{n+1} − θ_n)/Δt``, the period's exact mean speed.
  It needs no instantaneous speed and carries no current-sensor noise. Within a period
  whose start goes beyond the current limit the law is clipped at it.
- **The drive's lag.** The drive follows the law's command with its own lag ``τ``
  (current loop, computation): the samples read ``i ≈ i_cmd − τ·i_cmd'``, which
  inflates a fitted ``kp`` by about ``2π·f_loop·τ``. The gains are therefore also fitted
  with a lag term (the acceleration as a column), which gives ``τ``; on the loop's
  exponential transients lag and gain trade off, so the difference between the two
  fits enters the uncertainty of Kt/J. Over a period the lag acts as a delay of ``τ``:
  the current's mean is the command's over ``[t_n − τ, t_{n+1} − τ]``, the law's mean
  less ``τ/Δt`` times the command's change from the end of the period before to the end
  of this one, whose largest part is the kick ``kp·Δr`` at its start (:func:`_lagged`).
  Left out, each kick carried ``τ/Δt`` too much current into its own period (8 % at
  0.2 ms and 2.5 ms), and a free run drifted by it at every target change.
- **Runs of one drive.** The gains are the drive's, but each run's fit of them errs its
  own way where the encoder is coarse; :func:`joint_speed_loops` fits them, the lag
  and the current samples' delay to several runs at once (each keeping its integrator
  constant).
- **The current's shape within a period.** A kick's current comes early in its period
  and moves the angle more than its mean says: the angle takes the current's
  ramp-weighted mean (``period_shape`` is its excess over the mean), which a simulation
  between samples needs (:mod:`stand.diagnosis.simulate`).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field, replace

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
#: Median length, in samples, of the stretches at a level for the current to hold it
#: (a current limit, :func:`_with_resets`).
HELD_SAMPLES = 2
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
    resets : int
        Stretches at the current limit after which the integrator's state was fitted
        anew (the drive's anti-windup, :func:`_with_resets`); 0 for one constant.
    lag_s : float
        The drive's lag between the law's command and its current (``τ``), s, by which
        the period current is delayed; 0 where the fit gives none.
    lag_sd : float
        Standard error of the fitted lag, s (infinite where there is none).
    period_shape : ndarray
        How much the current's ramp-weighted mean over each period (``2/Δt²·∫(Δt − s)·
        i(s)·ds``, what the angle takes of it) exceeds its mean, A: a kick's current
        early in its period moves the angle more than its mean says.
    command : ndarray
        The law's command, clipped, over each period before the drive's lag, shape
        (3, samples): its mean, its ramp-weighted mean and its value at the period's end
        (A; :func:`_command`), from which :meth:`relagged` delays it anew.
    runs : int
        Runs of the drive the gains and the lag were fitted to at once
        (:func:`joint_speed_loops`); 1 for this run's own fit.
    offset_sd_A : float
        Standard error of ``offset_A`` (of the fit with the lag), A; infinite for a
        refusal.
    law : _Law or None
        The fit this loop's current comes from (None for a refusal), from which
        :func:`joint_speed_loops` refits the gains with other runs'.
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
    resets: int = 0
    lag_s: float = 0.0
    lag_sd: float = np.inf
    period_shape: np.ndarray = field(default_factory=lambda: np.empty(0))
    command: np.ndarray = field(default_factory=lambda: np.empty((3, 0)))
    runs: int = 1
    offset_sd_A: float = np.inf
    law: _Law | None = field(default=None, repr=False, compare=False)

    def relagged(self, lag_s: float, dt: float, lag_sd: float = np.inf) -> SpeedLoop:
        """This loop with the drive's lag ``lag_s`` (s, of standard error ``lag_sd``;
        ``dt``: the sample period) in its period current instead of its own fit's (e.g.
        the lag of another run's fit of the same drive pooled with it)."""
        if not self.holds:
            return self
        period, shape = _lagged(self.command, lag_s / dt)
        return replace(self, lag_s=lag_s, lag_sd=lag_sd, period_current=period,
                       period_shape=shape)

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
                   dt: float, quant_rad: float = 0.0, trim: bool = False,
                   known_limit_A: float = np.inf) -> SpeedLoop:
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
    known_limit_A : float
        The drive's current limit where another run of it shows one, or where it is
        known (a motor profile's), A: where this run's samples do not show one (a kick
        that reaches it within a period and has left it by the next sample), the law's
        current is clipped there too.
    """
    n = len(theta)
    sigma = noise_sigma(current)
    if not sigma > 0:
        return SpeedLoop(0.0, 0.0, 0.0, 0, np.inf, np.inf, np.empty(0),
                         "a noise-free current: the speed loop's gains cannot be fitted")
    rows = _Rows(theta, current, target, dt, quant_rad, sigma)
    # samples at the largest |current| may sit at the drive's current limit: fitted
    # without them, and the limit is taken as reached where the law exceeds it there
    at_limit, limit = rows.largest()
    law = rows.fit(at_limit, np.zeros(n, dtype=int), trim)
    if law is None:
        smooth = int(np.count_nonzero(rows.keep))
        reason = (f"only {smooth} of {n} samples have a speed free of a target change "
                  "around them (a target that changes at almost every sample, such as a "
                  "sine, leaves no window without a kink; hold the target over a few "
                  "samples)" if smooth < MIN_ROWS else
                  "too few samples away from the current limit")
        return SpeedLoop(0.0, 0.0, 0.0, 0, np.inf, np.inf, np.empty(0),
                         f"{reason}: the speed loop's gains cannot be fitted")
    limit_A = limit if law.beyond(at_limit, limit) >= MIN_LIMIT_SAMPLES else known_limit_A
    if law.kp > 0 and law.ratio <= MAX_RESIDUAL_RATIO:
        return law.loop(-limit_A, limit_A, limit_A)
    if not trim:
        reset = _with_resets(rows)
        if reset is not None:
            return reset
    return SpeedLoop(law.kp, law.ki, float(law.plain[2]), law.delay, law.ratio, np.inf,
                     np.empty(0), limit_A=limit_A, message=
                     f"the PI speed law explains the current only to {law.ratio:.2g} times its "
                     f"noise (at most {MAX_RESIDUAL_RATIO} for the law to hold): the loop "
                     "saturates its voltage or follows another law, so the current between "
                     "samples is not reconstructed and Kt/J may be high by up to "
                     "π·f_loop·Δt")


def joint_speed_loops(loops: Sequence[SpeedLoop], known_limit_A: float = np.inf
                      ) -> list[SpeedLoop] | None:
    """Runs of one drive (``loops``: each run's own loop, :func:`speed_loop`) with its
    gains and lag fitted to all of them at once at one delay of the current samples
    (:func:`_at_one_delay`; each run keeps its own integrator constant), and a current
    limit one run's samples show (else
    ``known_limit_A``, the drive's own where known) clipping every run's law; None where
    the law with one constant does not hold on every run, or the joint gains explain
    some run's current only beyond ``MAX_RESIDUAL_RATIO`` times its noise (the gains
    changed between the runs).

    The gains are the drive's, but each run's fit of them errs its own way, beyond its
    statistical error: the encoder step enters the speed and the acceleration the law
    is fitted on as a pattern set by the speeds the run holds, not as white noise
    (two runs of one 500-line stand: ``kp`` +0.9 % and −1.2 %, each ±0.15 %). A model
    identified on one run's law current and simulated on the other's then carries the
    difference at every kick.
    """
    laws = [loop.law for loop in loops
            if loop.holds and not loop.resets and loop.law is not None]
    if len(laws) < len(loops):
        return None
    shared = _at_one_delay(laws)
    if shared is None:
        return None
    joint = _joint(shared)
    if any(law.ratio > MAX_RESIDUAL_RATIO or not law.kp > 0 for law in joint):
        return None
    shown = _shown_limit(joint)
    known = shown if np.isfinite(shown) else known_limit_A
    return [replace(law.loop(-known, known, known), runs=len(joint)) for law in joint]


def _shown_limit(laws: Sequence[_Law]) -> float:
    """The drive's current limit the runs' samples show, A (infinite where none): the
    least of the runs' largest |currents| at which the run's law goes beyond it
    (:meth:`_Law.beyond`, at ``MIN_LIMIT_SAMPLES``) and which every run's samples stay
    within (:func:`within_limit`). A drive's current never passes its limit: a level
    that another run of the drive passes is the law's own small errors at one run's
    peaks (two runs of one drive whose samples reach 2.82 A and 3.28 A, with a limit of
    7.07 A: both laws were clipped at 2.82 A, and HOLDOUT's kicks with them)."""
    shown = [limit for law in laws for at_limit, limit in [law.rows.largest()]
             if law.beyond(at_limit, limit) >= MIN_LIMIT_SAMPLES
             and all(within_limit(other.rows.current, limit) for other in laws)]
    return min(shown, default=np.inf)


def within_limit(current: np.ndarray, limit_A: float) -> bool:
    """Whether a run's sampled ``current`` (A) stays within a current limit of
    ``limit_A`` (A) up to ``LIMIT_SIGMAS`` of its noise (:func:`~stand.ident.noise.
    noise_sigma`), as the current of a drive with that limit does."""
    return bool(np.max(np.abs(current)) <= limit_A + LIMIT_SIGMAS * noise_sigma(current))


def _at_one_delay(laws: list[_Law]) -> list[_Law] | None:
    """``laws`` refitted at one delay of the current samples, the drive's: the shortest
    of the delays their own fits found unless a longer one fits all runs at once better
    beyond the sampling error of a mean square (:meth:`_Rows.fit`'s rule); None where a
    run leaves too few rows at it.

    One run's fit can trade a delay of one sample for the lag and a larger ``kp`` (the
    lag's acceleration column stands for most of a period's shift where the target
    changes often): two runs of one drive found 1 and 0 samples, ``kp`` −2 % and +15 %.
    Each run's law current is then placed on a timeline of its own, and a delay fitted
    on TRAIN misplaces every current of HOLDOUT by a sample."""
    delays = sorted({law.delay for law in laws})
    if len(delays) == 1:
        return laws
    best: tuple[float, list[_Law]] | None = None
    for delay in delays:
        refits = [law.rows.fit(law.rows.largest()[0], law.segment, False, [delay])
                  for law in laws]
        if any(law is None for law in refits):
            continue
        at = [law for law in refits if law is not None]
        fit = _JointFit(at, lag=True)
        rows = sum(len(law.used) for law in at)
        if best is None or fit.mean_square < best[0] * (1 - DELAY_SIGMAS * np.sqrt(2 / rows)):
            best = (fit.mean_square, at)
    return None if best is None else best[1]


def _joint(laws: list[_Law]) -> list[_Law]:
    """``laws`` (one constant each) refitted with their gains, plain and lagged, shared:
    each keeps its rows, delay and constant; ``A``, ``mean_square`` and the covariances
    are the joint fit's, ``ratio`` each run's RMS of the lagged residual over its noise."""
    plain, lagged = _JointFit(laws, lag=False), _JointFit(laws, lag=True)
    cov = np.linalg.pinv(lagged.design.T @ lagged.design) * lagged.mean_square
    return [replace(law, plain=plain.beta[plain.order[k]], lagged=lagged.beta[lagged.order[k]],
                    A=plain.design, mean_square=plain.mean_square, ratio=lagged.ratios[k],
                    lag_cov=cov[np.ix_(lagged.order[k], lagged.order[k])])
            for k, law in enumerate(laws)]


class _JointFit:
    """Weighted least squares of several runs' laws with the gains (``kp``, ``ki`` and,
    with ``lag``, the acceleration's coefficient) shared and each run's constant its own.
    ``order[k]`` picks run ``k``'s parameters from ``beta`` in the order of its own fit
    (:meth:`_Rows.columns`); ``ratios[k]`` is its rows' RMS of the weighted residual."""

    def __init__(self, laws: list[_Law], lag: bool) -> None:
        blocks = [law.rows.weighed(law.used, law.delay, law.segment, lag, law.kp)
                  for law in laws]
        gains = [0, 1, -1] if lag else [0, 1]
        own = [A.shape[1] - len(gains) for A, _ in blocks]
        starts = np.cumsum([len(gains), *own])
        lengths = [len(b) for _, b in blocks]
        self.design = np.zeros((sum(lengths), int(starts[-1])))
        ends = np.cumsum(lengths)
        for k, (A, _) in enumerate(blocks):
            rows = slice(ends[k] - lengths[k], ends[k])
            self.design[rows, :len(gains)] = A[:, gains]
            self.design[rows, starts[k]:starts[k + 1]] = A[:, 2:2 + own[k]]
        b = np.concatenate([b for _, b in blocks])
        self.beta = np.linalg.lstsq(self.design, b, rcond=None)[0]
        residual = b - self.design @ self.beta
        self.mean_square = float(residual @ residual) / (len(b) - self.design.shape[1])
        self.ratios = [float(np.sqrt(np.mean(part**2)))
                       for part in np.split(residual, ends[:-1])]
        self.order = [np.array([0, 1, *range(starts[k], starts[k + 1]), *([2] if lag else [])])
                      for k in range(len(blocks))]


def _with_resets(rows: _Rows) -> SpeedLoop | None:
    """The law with the integrator's state unknown after each stretch at the current
    limit (one constant per stretch), where that explains the current; else None.

    At its limit a drive keeps its integrator from winding up: it clamps it, freezes it
    or bleeds it off, each drive its own way. After the stretch the integrator holds
    what that left, which the law's one constant misses by a step at each stretch. Each
    side's level is the median of the samples within ``LIMIT_SIGMAS`` of that side's
    extreme (a current sensor's offset moves the two apart), and the samples within
    ``LIMIT_SIGMAS`` of it are at the limit; a side is a limit where the law goes beyond
    its level at ``MIN_LIMIT_SAMPLES`` of them, and where the current holds that level
    (:func:`_held`; a current at the supply's reach peaks there for one sample). The fit
    leaves out the samples whose speed stencil reaches into a stretch (the acceleration
    has a kink where the current leaves the limit, as it has at a target change). Left
    out with them are the kicks, which tell the current samples' delay: the law's fit
    then finds nearly as good a fit at any delay, with ``kp`` off by a seventh per
    sample. The delay is the kicks' own instead (:func:`kick_delay`).
    """
    current, sigma = rows.current, rows.sigma
    levels = [float(np.median(current[current <= current.min() + LIMIT_SIGMAS * sigma])),
              float(np.median(current[current >= current.max() - LIMIT_SIGMAS * sigma]))]
    sides = [current <= levels[0] + LIMIT_SIGMAS * sigma,
             current >= levels[1] - LIMIT_SIGMAS * sigma]
    sides = [side if _held(side) else np.zeros_like(side) for side in sides]
    if not any(side.any() for side in sides):
        return None
    reach = len(CENTRAL[0]) // 2
    delays = [kick_delay(current, rows.target)]
    for _ in range(len(sides)):
        at_limit = sides[0] | sides[1]
        starts = at_limit & ~np.concatenate([[False], at_limit[:-1]])
        near = np.convolve(at_limit, np.ones(2 * reach + 1), mode="same") > 0
        law = rows.fit(near, np.cumsum(starts), False, delays)
        if law is None:
            return None
        limits = [side.any() and law.beyond(side, abs(level)) >= MIN_LIMIT_SAMPLES
                  for side, level in zip(sides, levels, strict=True)]
        if all(limits[k] or not sides[k].any() for k in range(len(sides))):
            break
        # a side the law does not go beyond is no limit: its samples are fitted
        sides = [side if ok else np.zeros_like(side) for side, ok in zip(sides, limits, strict=True)]
        if not any(side.any() for side in sides):
            return None
    else:
        return None
    if not (law.kp > 0 and law.ratio <= MAX_RESIDUAL_RATIO and law.resets > 0):
        return None
    low = levels[0] if sides[0].any() else -np.inf
    high = levels[1] if sides[1].any() else np.inf
    limit_A = max(abs(level) for level, side in zip(levels, sides, strict=True) if side.any())
    return law.loop(low, high, limit_A, sides)


def _held(at_level: np.ndarray) -> bool:
    """Whether the current holds a level: the samples at it come in stretches of a median
    length of at least ``HELD_SAMPLES`` (a drive at its current limit holds it while the
    law asks for more; a current slowed by the supply voltage reaches its peak and turns)."""
    edges = np.diff(np.concatenate([[0], at_level.astype(int), [0]]))
    lengths = np.flatnonzero(edges == -1) - np.flatnonzero(edges == 1)
    return bool(len(lengths) and np.median(lengths) >= HELD_SAMPLES)


def kick_delay(current: np.ndarray, target: np.ndarray) -> int:
    """The current samples' delay (samples, 0 … ``MAX_DELAY``) at which the current
    moves most with the target's changes: the target held from sample ``n`` kicks the
    current sampled at ``n + 1 + delay`` (``Σ sign(Δr)·Δi`` over the changes, largest),
    whether or not the kick reaches the current limit."""
    changes = np.flatnonzero(np.diff(target) != 0) + 1
    scores = []
    for delay in range(MAX_DELAY + 1):
        n = changes[changes + 1 + delay < len(current)]
        step = current[n + 1 + delay] - current[n + delay]
        scores.append(float(np.sum(np.sign(target[n] - target[n - 1]) * step)))
    return int(np.argmax(scores))


class _Rows:
    """What the law is fitted from: the kink-free speed and acceleration at the samples,
    the tracking error's integral, and the current and its noise."""

    def __init__(self, theta: np.ndarray, current: np.ndarray, target: np.ndarray,
                 dt: float, quant_rad: float, sigma: float) -> None:
        n = len(theta)
        self.theta, self.current, self.target, self.dt = theta, current, target, dt
        self.omega, self.alpha, self.spread = kink_free_derivatives(theta, target, dt)
        self.angle_sd = quant_rad / np.sqrt(12.0)
        self.error_int = tracking_errors(theta, target, dt)[1]
        self.error = np.concatenate([target[:1], target[:-1]]) - self.omega
        self.sigma = sigma
        keep = np.isfinite(self.omega)
        keep[0] = False   # read before the first target: the one before it is unknown
        keep[n - MAX_DELAY:] = False
        self.keep = keep

    def largest(self) -> tuple[np.ndarray, float]:
        """The samples within ``LIMIT_SIGMAS`` of the largest |current| (which may sit at
        the drive's current limit), and that current, A."""
        limit = float(np.max(np.abs(self.current)))
        return np.abs(self.current) >= limit - LIMIT_SIGMAS * self.sigma, limit

    def fit(self, at_limit: np.ndarray, segment: np.ndarray, trim: bool,
            delays: list[int] | None = None) -> _Law | None:
        """The law fitted on the samples off ``at_limit``, one constant per ``segment``
        label (of the current sample), at the delay of ``delays`` (default 0 …
        ``MAX_DELAY``) that fits best; None where too few samples are left."""
        n = len(self.theta)
        best: tuple[float, int, np.ndarray, np.ndarray, np.ndarray] | None = None
        for delay in range(MAX_DELAY + 1) if delays is None else delays:
            rows = np.flatnonzero(self.keep[:n - delay] & ~at_limit[delay:])
            if len(rows) < MIN_ROWS:
                continue
            if trim:
                rows = self._trimmed(rows, delay, segment)
            lagged, A_lag, mean_square = self._weighted(rows, delay, segment, True)
            # a longer delay must fit better beyond the sampling error of a mean square
            # (relative standard deviation √(2/rows)), else the shorter one stays; trimmed,
            # it must also explain as many samples (a drive whose supply slows the current
            # looks delayed here: the simulation that models the supply tests the delay
            # against none, :func:`~stand.ident.closed_loop.fit_closed_loop`)
            if best is None or (
                    mean_square < best[0] * (1 - DELAY_SIGMAS * np.sqrt(2 / len(rows)))
                    and (not trim or len(rows) >= len(best[2]))):
                best = (mean_square, delay, rows, lagged, A_lag)
        if best is None:
            return None
        lag_square, delay, rows, lagged, A_lag = best
        plain, A, mean_square = self._weighted(rows, delay, segment, False)
        labels = np.unique(segment[rows + delay])
        return _Law(self, delay, segment, labels, plain, lagged, A, mean_square,
                    float(np.sqrt(lag_square)),
                    np.linalg.pinv(A_lag.T @ A_lag) * lag_square, rows)

    def columns(self, rows: np.ndarray, delay: int, segment: np.ndarray,
                lag: bool) -> np.ndarray:
        """The law's columns at ``rows``: ``r − ω``, the error's integral, a constant per
        segment the rows' current samples are in, and with ``lag`` the acceleration."""
        labels, which = np.unique(segment[rows + delay], return_inverse=True)
        constants = np.zeros((len(rows), len(labels)))
        constants[np.arange(len(rows)), which] = 1.0
        parts = [self.error[rows, None], self.error_int[rows, None], constants]
        return np.hstack(parts + [self.alpha[rows, None]] if lag else parts)

    def _weighted(self, rows: np.ndarray, delay: int, segment: np.ndarray,
                  lag: bool) -> tuple[np.ndarray, np.ndarray, float]:
        """Weighted least squares (weights from the rows' noise at the plain fit's kp)."""
        X = self.columns(rows, delay, segment, lag)
        y = self.current[rows + delay]
        beta, *_ = np.linalg.lstsq(X, y, rcond=None)
        A, b = self.weighed(rows, delay, segment, lag, float(beta[0]))
        beta, *_ = np.linalg.lstsq(A, b, rcond=None)
        return beta, A, float(np.sum((b - A @ beta) ** 2)) / (len(rows) - X.shape[1])

    def weighed(self, rows: np.ndarray, delay: int, segment: np.ndarray, lag: bool,
                kp: float) -> tuple[np.ndarray, np.ndarray]:
        """The law's columns at ``rows`` and the current there, each row divided by its
        noise: the current's and the encoder step's through the speed at ``kp``."""
        X = self.columns(rows, delay, segment, lag)
        sd = np.sqrt(self.sigma**2 + (kp * self.angle_sd * self.spread[rows]) ** 2)
        return X / sd[:, None], self.current[rows + delay] / sd

    def _trimmed(self, rows: np.ndarray, delay: int, segment: np.ndarray) -> np.ndarray:
        """``rows`` less those the law misses by more than ``TRIM_SIGMAS``, repeatedly."""
        for _ in range(TRIM_PASSES):
            beta = self._weighted(rows, delay, segment, False)[0]
            A, b = self.weighed(rows, delay, segment, False, float(beta[0]))
            inside = np.abs(b - A @ beta) <= TRIM_SIGMAS
            if inside.all() or inside.sum() < MIN_ROWS:
                break
            rows = rows[inside]
        return rows


@dataclass(frozen=True)
class _Law:
    """The PI law fitted at one delay: ``plain`` is ``[kp, ki, c…]`` (a constant per
    segment label in ``labels``), ``lagged`` the same with the acceleration's coefficient
    last (the drive's lag); ``A`` and ``mean_square`` are the plain fit's weighted
    design and residual mean square, ``ratio`` the lagged fit's RMS over the noise,
    ``lag_cov`` its covariance and ``used`` the rows fitted."""

    rows: _Rows
    delay: int
    segment: np.ndarray
    labels: np.ndarray
    plain: np.ndarray
    lagged: np.ndarray
    A: np.ndarray
    mean_square: float
    ratio: float
    lag_cov: np.ndarray
    used: np.ndarray

    @property
    def kp(self) -> float:
        return float(self.plain[0])

    @property
    def ki(self) -> float:
        return float(self.plain[1])

    @property
    def resets(self) -> int:
        """Integrator constants beyond the first."""
        return len(self.labels) - 1

    def constant_at(self, samples: np.ndarray, constants: np.ndarray) -> np.ndarray:
        """The constant of the segment each current sample is in (a segment the fit has
        no rows of takes the one before it)."""
        k = np.searchsorted(self.labels, self.segment[samples], side="right") - 1
        return constants[np.clip(k, 0, len(self.labels) - 1)]

    def beyond(self, at_side: np.ndarray, level: float) -> int:
        """How many more samples of ``at_side`` whose speed the law can use it (with the
        lag) puts beyond ``level`` (a magnitude, A) by ``LIMIT_SIGMAS`` of the noise than
        short of it by as much. At a limit the law asks for more than the drive gives at
        the samples held there, and never for less; at the largest currents of a loop
        that reaches no limit (a current noise of a milliampere, the law's own small
        errors at the peaks), it misses them by as much either way."""
        r, n = self.rows, len(at_side)
        rows = np.flatnonzero(r.keep[:n - self.delay] & at_side[self.delay:])
        b = self.lagged
        law = (b[0] * r.error[rows] + b[1] * r.error_int[rows]
               + self.constant_at(rows + self.delay, b[2:-1]) + b[-1] * r.alpha[rows])
        margin = LIMIT_SIGMAS * r.sigma
        return int(np.sum(np.abs(law) > level + margin) - np.sum(np.abs(law) < level - margin))

    def loop(self, low: float, high: float, limit_A: float,
             sides: list[np.ndarray] | None = None) -> SpeedLoop:
        """The :class:`SpeedLoop` of this fit, its current over each period clipped to
        ``[low, high]`` (and at the level of a side both of whose samples are on it,
        ``sides``: the samples at the low and the high limit)."""
        r = self.rows
        n = len(r.theta)
        cov = np.linalg.inv(self.A.T @ self.A) * self.mean_square
        kp, ki, constants = self.kp, self.ki, self.plain[2:]
        lagged = self.lagged
        # with the drive's delay τ (current loop, computation): i ≈ i_cmd − τ·i_cmd'
        # = … + τ·kp·α − τ·ki·(r − ω); on exponential transients τ and kp trade off, so
        # the two fits' difference enters the uncertainty
        tau = float(lagged[-1] / lagged[0]) if lagged[0] > 0 else -1.0
        kp_other = kp
        if 0.0 <= tau * ki < 1.0:
            kp, kp_other = float(lagged[0] + tau * lagged[1]), kp
            ki, constants = float(lagged[1]), lagged[2:-1]
        rel_sd = float(np.hypot(np.sqrt(cov[0, 0]) / kp, (kp_other - kp) / kp))
        shown = np.minimum(np.arange(n - 1) + self.delay, n - 1)
        c = self.constant_at(shown, constants)
        # a lag the fit cannot give (negative, or a period or more: the delay's) is none
        lag_s = tau if 0.0 < tau < r.dt else 0.0
        # its standard error (τ = b_α/b_kp, to first order)
        grad = np.zeros(len(lagged))
        grad[0], grad[-1] = -tau / lagged[0], 1.0 / lagged[0]
        lag_sd = float(np.sqrt(max(grad @ self.lag_cov @ grad, 0.0))) if lag_s else np.inf
        command = _command(r.theta, r.target, r.omega, r.error_int, r.dt, kp, ki, c,
                           low, high)
        if sides is not None:
            ends = np.minimum(shown + 1, n - 1)
            for side, level in zip(sides, (low, high), strict=True):
                held = np.append(side[shown] & side[ends], False)
                command[:, held] = level
        period, shape = _lagged(command, lag_s / r.dt)
        return SpeedLoop(kp, ki, float(constants[0]), self.delay, self.ratio, rel_sd, period,
                         limit_A=limit_A, resets=self.resets, lag_s=lag_s, lag_sd=lag_sd,
                         period_shape=shape, command=command,
                         offset_sd_A=float(np.sqrt(max(self.lag_cov[2, 2], 0.0))), law=self)


def _command(theta: np.ndarray, target: np.ndarray, omega: np.ndarray,
             error_int: np.ndarray, dt: float, kp: float, ki: float, c: np.ndarray,
             low: float, high: float) -> np.ndarray:
    """The law's command over the period after each sample (``c``: the constant of each
    period), clipped to ``[low, high]``: its mean, its ramp-weighted mean and its value
    at the period's end, shape (3, samples), A (the last period repeats the one before).

    The speed within a period is the quadratic through the speeds at its ends and its
    mean ``ω̄`` (:func:`_sample_speeds`). Unclipped, the mean is exact from ``ω̄`` and
    the ramp-weighted mean is ``kp`` times the quadratic's ``ω̄ + (ω₀ − ω₁)/6`` below the
    target (the integrator's growth, a ramp, enters both). Where the law's current at a
    period's start or end is beyond a limit, the law's current on ``SUBSTEPS`` points of
    the quadratic is clipped and both means are taken of it.
    """
    mean_speed = np.diff(theta) / dt
    r = target[:-1]
    w0, w1 = _sample_speeds(target, mean_speed, omega)
    base = c + ki * error_int[:-1]
    growth = ki * dt * (r - mean_speed)
    mean = kp * (r - mean_speed) + base + growth / 2
    ramp = mean - kp * (w0 - w1) / 6 - growth / 6
    start = kp * (r - w0) + base
    end = kp * (r - w1) + c + ki * error_int[1:]
    s = (np.arange(SUBSTEPS) + 0.5) / SUBSTEPS
    for k in np.flatnonzero((np.maximum(start, end) > high) | (np.minimum(start, end) < low)):
        b2 = 3 * (w0[k] + w1[k]) - 6 * mean_speed[k]
        speed = w0[k] + (w1[k] - w0[k] - b2) * s + b2 * s**2
        drift = ki * dt * np.cumsum(r[k] - speed) / SUBSTEPS
        law = np.clip(kp * (r[k] - speed) + base[k] + drift, low, high)
        mean[k], ramp[k] = float(np.mean(law)), float(2 * np.mean((1 - s) * law))
    command = np.stack([mean, ramp, np.clip(end, low, high)])
    return np.concatenate([command, command[:, -1:]], axis=1)


def _sample_speeds(target: np.ndarray, mean_speed: np.ndarray,
                   omega: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The speed at the start and at the end of each period (rad/s): the angle's
    kink-free derivative where it has one (:func:`kink_free_derivatives`), else the
    mean of the two periods around the sample, or, where the target changes at that
    sample, the period before carried on by its change from the one before it (the
    kick bends the speed there: the period after says nothing of the speed before)."""
    centred = np.append((mean_speed[:-1] + mean_speed[1:]) / 2, mean_speed[-1])
    left = mean_speed + np.diff(mean_speed, prepend=mean_speed[0]) / 2
    estimate = np.where(np.diff(target) != 0, left, centred)   # at each period's end
    at_end = np.where(np.isfinite(omega[1:]), omega[1:], estimate)
    at_start = np.where(np.isfinite(omega[:-1]), omega[:-1],
                        np.insert(estimate[:-1], 0, mean_speed[0]))
    return at_start, at_end


def lag_slopes(command: np.ndarray) -> np.ndarray:
    """How the current over each period and its shape (A) change per share of a period
    of the drive's lag (:func:`_lagged` is linear in it), shape (2, samples)."""
    mean, _, end = command
    before = np.insert(end[:-1], 0, mean[0])
    return np.stack([before - end, 2 * (before - mean) + (end - before)])


def _lagged(command: np.ndarray, share: float) -> tuple[np.ndarray, np.ndarray]:
    """The current over each period and its shape (:attr:`SpeedLoop.period_shape`), A,
    from the law's ``command`` (:func:`_command`) delayed by ``share`` of a period.

    The drive's lag acts as a delay of ``τ``: the current over a period is the command
    over ``[t_n − τ, t_{n+1} − τ]``. To first order in ``τ/Δt`` its mean loses
    ``τ/Δt`` of the command's change from the end of the period before to this one's end
    (the kick ``kp·Δr`` at the start its largest part), and its ramp-weighted mean,
    which weighs the period's start twice, gains ``2·τ/Δt`` of the step from the end of
    the period before to this one's mean."""
    mean, ramp, _ = command
    slopes = lag_slopes(command)
    return mean + share * slopes[0], ramp - mean + share * slopes[1]


def speed_loop(run: Run, known_limit_A: float = np.inf) -> SpeedLoop | None:
    """The PI loop of ``run`` when it holds the speed target, else None
    (``known_limit_A``: :func:`fit_speed_loop`'s)."""
    if TARGET_COLUMN not in run:
        return None
    theta = run["position_rad"]
    return fit_speed_loop(theta, run["current_A"], run[TARGET_COLUMN], run.dt_s,
                          quantization_step(theta), known_limit_A=known_limit_A)
