"""Signals a diagnosis works on, derived from one single-motor run.

Velocity and acceleration come from the (possibly quantized) measured position, not from
a velocity column, so every run is treated alike. Two versions exist:

* ``omega_meas``: the central difference of the measured position, rad/s. This is the
  "measured speed" the gap of CONTRACT §3 is computed against.
* the *filtered* signals (suffix ``_f``): every signal passed through the same zero-phase
  low-pass filter (a state-variable filter in the sense of equation-error
  identification). Because the filter is linear and the same for every signal, the
  equation ``θ'' = Σ c_j·φ_j`` still holds between filtered quantities, while the
  quantization noise of the twice-differentiated position is removed.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from scipy.linalg import lapack

from stand.errors import InputError
from stand.runfile import Run

#: Cut-off of the zero-phase filter as a fraction of the Nyquist frequency.
FILTER_FRACTION_OF_NYQUIST = 0.2
#: Order of the Butterworth low-pass (applied forward and backward).
FILTER_ORDER = 2
#: Fewest samples a run needs for a diagnosis.
MIN_DIAGNOSE_SAMPLES = 200
#: The smallest position change seen is tried as 1 .. this many encoder counts.
MAX_COUNT_DIVISOR = 64
#: Largest distance from the grid, in counts, of a position that lies on it.
GRID_TOLERANCE = 0.05
#: Counts around the first position over which a step read off two positions is first
#: refined (the range then doubles until it covers the run).
REFINE_COUNTS = 64
#: A shaft whose encoder reads one angle over at least this many consecutive sample
#: periods is at rest (held by static friction, which balances whatever torque the drive
#: makes up to the breakaway level) or turns slower than the encoder resolves: either
#: way no friction model knows its torque there (``sign θ'`` reads 0). One such period
#: is a reversal within it; two or more are a stretch an equation error cannot describe
#: (:func:`still_periods`).
MIN_STILL_PERIODS = 2


@dataclass(frozen=True)
class Signals:
    """One run prepared for diagnosis.

    Attributes
    ----------
    dt_s : float
        Sample period, s.
    theta : ndarray
        Measured position, rad (or the run's position unit).
    current : ndarray
        Measured current, A (or the run's input unit).
    omega_meas : ndarray
        Central-difference velocity of ``theta``, rad/s.
    theta_f, omega_f, accel_f : ndarray
        Filtered position (rad), velocity (rad/s) and acceleration (rad/s²).
    quant_rad : float
        Estimated position quantization step, rad (0 if not quantized).
    top_speed : float
        95th percentile of ``|omega_f|``, rad/s: the run's typical top speed (the scale
        of the Stribeck search, of the friction smoothing and of the shooting nudge).
    """

    dt_s: float
    theta: np.ndarray
    current: np.ndarray
    omega_meas: np.ndarray
    theta_f: np.ndarray
    omega_f: np.ndarray
    accel_f: np.ndarray
    quant_rad: float
    top_speed: float
    source: str
    #: Under a speed loop whose law drives the models (:mod:`.loop_input`): the law's
    #: proportional and integral parts over each period (samples × 2, A), whose gains'
    #: errors the shape tests take as nuisance; None otherwise.
    loop_parts: np.ndarray | None = None
    #: Under a speed loop whose law drives the models: how much the law's current's
    #: ramp-weighted mean over each period exceeds its mean (A, on the samples' timeline
    #: like ``current``; :attr:`stand.ident.speed_loop.SpeedLoop.period_shape`), which the
    #: free run puts into the angle (:mod:`.simulate`); None otherwise (a current held over
    #: the period).
    current_shape: np.ndarray | None = None
    #: With ``current_shape``: how ``current`` and ``current_shape`` change per share of
    #: a period of the drive's lag (2 × samples, A; :func:`stand.ident.speed_loop.
    #: lag_slopes`), whose error the models may take up (``ModelSpec.lag``).
    lag_slopes: np.ndarray | None = None
    #: Under a speed loop whose law drives the models: the relative standard uncertainty
    #: of the law's ``kp`` (:attr:`stand.ident.speed_loop.SpeedLoop.kp_rel_sd`), that
    #: is of the size of every kick of its current; None otherwise.
    kick_scale_sd: float | None = None
    #: Under a speed loop whose law drives the models: the standard error of the law's
    #: constant (the integrator's start and the current sensor's offset,
    #: :attr:`stand.ident.speed_loop.SpeedLoop.offset_sd_A`), A; None otherwise.
    law_offset_sd_A: float | None = None
    #: Under a speed loop whose run holds its target (``speed_target_rad_s``): the
    #: target's change at the start of each period, ``r[n] − r[n − 1]`` (rad/s), whose
    #: kicks of the current between samples the input reconstruction may carry
    #: (:mod:`.kicks`); None otherwise.
    target_change: np.ndarray | None = None
    #: Where the run records the drive's voltage (``voltage_V``) and it sits at the
    #: supply on some samples (:func:`stand.diagnosis.supply_limit.marked`, which the
    #: diagnosis applies; :func:`prepare` leaves it None): those samples (bool, one per
    #: sample), whose periods' current the input reconstruction may reshape
    #: (:mod:`.supply_limit`); None otherwise.
    at_supply: np.ndarray | None = None
    cache: dict[tuple[object, ...], np.ndarray] = field(default_factory=dict, repr=False,
                                                        compare=False)

    def __len__(self) -> int:
        return len(self.theta)

    def filt(self, values: np.ndarray, axis: int = 0) -> np.ndarray:
        """``values`` through the same zero-phase low-pass as the filtered signals, along
        time ``axis``."""
        return lowpass(values, axis)


def _butterworth2(fraction_of_nyquist: float) -> tuple[np.ndarray, np.ndarray]:
    """Numerator and denominator of the second-order Butterworth low-pass at
    ``fraction_of_nyquist`` (the bilinear transform with pre-warping, as
    ``scipy.signal.butter(2, fraction_of_nyquist)``)."""
    k = math.tan(math.pi * fraction_of_nyquist / 2.0)
    norm = 1.0 + math.sqrt(2.0) * k + k * k
    b = np.array([1.0, 2.0, 1.0]) * (k * k / norm)
    a = np.array([1.0, 2.0 * (k * k - 1.0) / norm, (1.0 - math.sqrt(2.0) * k + k * k) / norm])
    return b, a


_B, _A = _butterworth2(FILTER_FRACTION_OF_NYQUIST)
#: The filter's state after a long constant input of 1 (``scipy.signal.lfilter_zi``): the
#: passes start from the steady state of their first value, as ``filtfilt`` does.
_ZI = np.linalg.solve(np.eye(2) - np.array([[-_A[1], 1.0], [-_A[2], 0.0]]),
                      _B[1:] - _A[1:] * _B[0])
#: Padding at each end, samples (``filtfilt``'s odd extension).
PAD_SAMPLES = 60
#: Signals filtered together (their working arrays stay within a CPU cache).
CHUNK_ROWS = 8


def lowpass(values: np.ndarray, axis: int = 0) -> np.ndarray:
    """Zero-phase Butterworth low-pass at ``FILTER_FRACTION_OF_NYQUIST`` (any 1-D/2-D),
    along time ``axis``: ``scipy.signal.filtfilt`` with odd padding of ``PAD_SAMPLES``
    (fewer on short runs), the same to rounding.

    Each pass solves the filter's difference equation as a banded triangular system
    (LAPACK ``dtbtrs``, a few signals at a time), so the diagnosis needs neither
    ``scipy.signal`` nor what it imports (about half a second of start-up)."""
    x = np.moveaxis(np.asarray(values, dtype=float), axis, -1)
    rows = x.reshape(-1, x.shape[-1])
    pad = min(PAD_SAMPLES, rows.shape[1] - 1)
    band = np.zeros((3, rows.shape[1] + 2 * pad))  # the denominator below the diagonal
    band[1, :-1] = _A[1]
    band[2, :-2] = _A[2]
    out = np.empty_like(rows)
    for first in range(0, len(rows), CHUNK_ROWS):  # a few rows at a time stay in cache
        chunk = rows[first:first + CHUNK_ROWS]
        ext = np.concatenate([2.0 * chunk[:, :1] - chunk[:, pad:0:-1], chunk,
                              2.0 * chunk[:, -1:] - chunk[:, -2:-pad - 2:-1]], axis=1)
        both = _pass(_pass(ext, band)[:, ::-1], band)[:, ::-1]
        out[first:first + CHUNK_ROWS] = both[:, pad:both.shape[1] - pad]
    return np.moveaxis(out.reshape(x.shape), -1, axis)


def _pass(x: np.ndarray, band: np.ndarray) -> np.ndarray:
    """One causal pass of the filter along the rows of ``x`` (columns, time), started
    from the steady state of each row's first value: ``y[n] + a1·y[n−1] + a2·y[n−2] =
    b0·x[n] + b1·x[n−1] + b2·x[n−2]``, the initial state entering the first two
    samples (``band``: the left side's lower band, LAPACK band storage)."""
    rhs = _B[0] * x
    term = _B[1] * x[:, :-1]
    rhs[:, 1:] += term
    np.multiply(x[:, :-2], _B[2], out=term[:, :-1])
    rhs[:, 2:] += term[:, :-1]
    rhs[:, :2] += x[:, :1] * _ZI
    # a unit diagonal (a0 = 1): forward substitution without divisions, never singular
    y = lapack.dtbtrs(band, rhs.T, uplo="L", diag="U", overwrite_b=1)[0]
    return np.asarray(y).T


def central_difference(values: np.ndarray, dt_s: float) -> np.ndarray:
    """Central difference quotient (one-sided at the ends), unit of ``values`` per s."""
    return np.gradient(values, dt_s)


def still_periods(theta: np.ndarray, least: int = MIN_STILL_PERIODS) -> np.ndarray:
    """Periods (``θ[n] → θ[n + 1]``, the last sample's none) within a stretch of at least
    ``least`` consecutive periods over which the angle does not change."""
    flat = np.append(np.diff(theta) == 0.0, False)
    edges = np.flatnonzero(np.diff(np.concatenate([[0], flat.astype(np.int8), [0]])))
    out = np.zeros(len(theta), dtype=bool)
    for start, stop in zip(edges[::2], edges[1::2], strict=True):
        if stop - start >= least:
            out[start:stop] = True
    return out


def near_rest(theta: np.ndarray, reach: int, least: int = MIN_STILL_PERIODS) -> np.ndarray:
    """Samples within ``reach`` periods of a still period (:func:`still_periods` of
    ``least``): those whose filter of that reach on either side meets the shaft at rest
    (bool, one per sample)."""
    still = still_periods(theta, least).astype(float)
    return np.asarray(np.convolve(still, np.ones(2 * reach + 1), mode="same") > 0.0)


def quantization_step(theta: np.ndarray) -> float:
    """The encoder count: the largest step on whose grid (nearly) every position lies,
    0 if the position is not quantized. The smallest distance between two positions
    visited is tried as 1 .. ``MAX_COUNT_DIVISOR`` counts."""
    steps = np.diff(np.unique(theta))
    steps = steps[steps > 1e-9 * max(1.0, float(np.max(np.abs(theta))))]
    if steps.size < 10:
        return 0.0
    smallest = float(np.min(steps))
    offsets = theta - theta[0]
    for divisor in range(1, MAX_COUNT_DIVISOR + 1):
        step = _refined(offsets, smallest / divisor)
        ratio = offsets / step
        if np.mean(np.abs(ratio - np.round(ratio)) < GRID_TOLERANCE) > 0.95:
            return step
    return 0.0


def _refined(offsets: np.ndarray, step: float) -> float:
    """The grid step that fits the positions best, from a first guess ``step``.

    A step read off the difference of two positions carries their rounding (a file
    stores about nine significant digits, 5e-8 rad at 30 rad); over a long run at speed
    (10⁴–10⁶ counts) that error adds up to whole counts and no position seems to lie on
    the grid. The step is therefore fitted by least squares to the positions within
    ``REFINE_COUNTS`` counts of the first, where the count of each is unambiguous, and
    the range doubles until it covers the run."""
    top = float(np.max(np.abs(offsets)))
    reach = REFINE_COUNTS * step
    while True:
        near = offsets[np.abs(offsets) <= reach]
        counts = np.round(near / step)
        if np.any(counts):
            step = float(np.dot(counts, near) / np.dot(counts, counts))
        if reach >= top:
            return step
        reach *= 2.0


def prepare(run: Run) -> Signals:
    """The :class:`Signals` of a single-motor run (``current_A``, ``position_rad``).

    Raises
    ------
    InputError
        Too few samples, or a position that never moves.
    """
    theta = np.asarray(run["position_rad"], dtype=float)
    current = np.asarray(run["current_A"], dtype=float)
    if len(theta) < MIN_DIAGNOSE_SAMPLES:
        raise InputError(
            f"{run.source}: {len(theta)} samples; a diagnosis needs at least "
            f"{MIN_DIAGNOSE_SAMPLES} (record a longer run)"
        )
    if np.ptp(theta) == 0.0:
        raise InputError(f"{run.source}: position_rad never changes; the motor did not move")
    dt = run.dt_s
    theta_f = lowpass(theta)
    omega_f = central_difference(theta_f, dt)
    accel_f = central_difference(omega_f, dt)
    return Signals(dt_s=dt, theta=theta, current=current,
                   omega_meas=central_difference(theta, dt), theta_f=theta_f,
                   omega_f=omega_f, accel_f=accel_f, quant_rad=quantization_step(theta),
                   top_speed=float(np.quantile(np.abs(omega_f), 0.95)), source=run.source)


def correlation_time(x: np.ndarray) -> float:
    """Integrated autocorrelation time of ``x`` in samples (at least 1)."""
    spectrum = np.abs(np.fft.rfft(x - x.mean(), 2 * len(x))) ** 2
    acf = np.fft.irfft(spectrum)[: len(x)]
    acf /= acf[0] if acf[0] else 1.0
    first_negative = np.flatnonzero(acf < 0)
    stop = int(first_negative[0]) if first_negative.size else len(acf)
    return max(1.0, 1.0 + 2.0 * float(np.sum(acf[1:stop])))


def power_spectral_density(values: np.ndarray, dt_s: float, segment: int
                           ) -> tuple[np.ndarray, np.ndarray]:
    """Welch's one-sided power spectral density of ``values`` (unit² per Hz) and its
    frequencies (Hz): Hann-windowed segments of ``segment`` samples overlapping by half,
    each less its mean, averaged (``scipy.signal.welch``'s defaults)."""
    step = segment - segment // 2
    count = (len(values) - segment // 2) // step
    window = 0.5 - 0.5 * np.cos(2.0 * np.pi * np.arange(segment) / segment)
    starts = step * np.arange(count)
    pieces = values[starts[:, None] + np.arange(segment)[None, :]]
    pieces = pieces - pieces.mean(axis=1, keepdims=True)
    power = np.abs(np.fft.rfft(pieces * window, axis=1)) ** 2 * (dt_s / np.sum(window**2))
    power[:, 1:-1 if segment % 2 == 0 else None] *= 2.0  # the other half's power
    return np.fft.rfftfreq(segment, dt_s), power.mean(axis=0)

