"""Inverse dynamic identification by least squares (IDIM-LS) of a one-axis drive.

The recipe of Janot, Gautier and Brunot, *Data Set and Reference Models of EMPS* (2019),
for the inverse dynamic model of a prismatic or rotary axis::

    tau = M·q'' + Fv·q' + Fc·sign(q') + offset

1. low-pass the measured position with a zero-phase Butterworth filter (order 4, cutoff
   5 × the closed-loop bandwidth);
2. velocity and acceleration by central differences (one-sided at the two edges);
3. drop the first samples (edge effects of the filter and of the differences);
4. build the observation matrix ``X = [q'', q', sign(q'), 1]``;
5. *decimate* every column of X and the force (a Chebyshev anti-alias filter, zero phase,
   then 1 sample in ``nd`` with ``nd = round(0.8·f_nyquist / (2·bandwidth))``);
6. ordinary least squares ``theta = X \\ y``, standard deviations
   ``sigma = std(e)·sqrt(diag((XᵀX)⁻¹))`` and relative error ``100·‖e‖/‖y‖``.

The filters follow MATLAB's conventions (``filtfilt`` edge padding of ``3·(n − 1)``
samples, ``decimate`` keeping the samples aligned to the end of the record), so the
published EMPS values are reproduced to about 0.2 %. With ``friction="asymmetric"`` the
columns are ``[q'', q'·[q'>0], [q'>0], q'·[q'<0], −[q'<0]]`` (no separate offset: it is
collinear with the two Coulomb columns).

Pure numerical core: arrays in, :class:`IdimResult` out, no I/O.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np
from scipy import signal

from stand.errors import InputError, NotExcitedError
from stand.runfile import Run

Friction = Literal["symmetric", "asymmetric"]

#: Closed-loop (position-loop) bandwidth of EMPS, Hz; sets the filter and the decimation.
DEFAULT_BANDWIDTH_HZ = 20.0
#: Butterworth cutoff as a multiple of the closed-loop bandwidth.
CUTOFF_PER_BANDWIDTH = 5.0
#: Order of the Butterworth position filter.
FILTER_ORDER = 4
#: Samples dropped at the start of the record (MATLAB ``q(n_border:end)``, n_border = 50).
BORDER_SAMPLES = 49
#: Chebyshev type I anti-alias filter of ``decimate``: order and pass-band ripple, dB.
DECIMATE_ORDER = 8
DECIMATE_RIPPLE_DB = 0.05
#: Fewest decimated rows per parameter for a meaningful fit.
MIN_ROWS_PER_PARAM = 5

PARAM_NAMES: dict[str, tuple[str, ...]] = {
    "symmetric": ("M", "Fv", "Fc", "offset"),
    "asymmetric": ("M", "Fv_pos", "Fc_pos", "Fv_neg", "Fc_neg"),
}


@dataclass(frozen=True)
class IdimResult:
    """IDIM-LS estimate of the inverse dynamic model ``tau = M·q'' + Fv·q' + Fc·sign(q') + offset``.

    Attributes
    ----------
    params : dict of str to float
        ``M`` (kg or kg·m²), ``Fv`` (N·s/m or N·m·s/rad), ``Fc`` and ``offset`` (N or N·m);
        with asymmetric friction ``Fv_pos``, ``Fc_pos``, ``Fv_neg``, ``Fc_neg`` instead of
        ``Fv``, ``Fc`` and ``offset``.
    std : dict of str to float
        Standard deviation of each estimate, same units.
    relative_std_percent : dict of str to float
        ``100·std / |estimate|``.
    relative_error_percent : float
        ``100·‖e‖/‖y‖`` of the decimated fit, %.
    error_norm : float
        ``‖e‖``, N (or N·m).
    error_std : float
        Standard deviation of the residual, N (or N·m).
    condition_number : float
        Condition number of the decimated observation matrix.
    samples : int
        Rows of the decimated least-squares problem.
    friction : str
        ``symmetric`` or ``asymmetric``.
    cutoff_hz : float
        Butterworth cutoff used, Hz.
    decimation : int
        Decimation factor used.
    message : str
        One line on what was done.
    """

    params: dict[str, float]
    std: dict[str, float]
    relative_std_percent: dict[str, float]
    relative_error_percent: float
    error_norm: float
    error_std: float
    condition_number: float
    samples: int
    friction: str
    cutoff_hz: float
    decimation: int
    message: str


@dataclass(frozen=True)
class IdimCrossTest:
    """Fit of an :class:`IdimResult` on another record (same filtering and decimation).

    Attributes
    ----------
    relative_error_percent : float
        ``100·‖e‖/‖y‖`` on the other record, %.
    error_norm : float
        ``‖e‖``, N (or N·m).
    error_std : float
        Standard deviation of the residual, N (or N·m).
    samples : int
        Rows of the decimated problem.
    """

    relative_error_percent: float
    error_norm: float
    error_std: float
    samples: int


def _filtfilt(b: np.ndarray, a: np.ndarray, x: np.ndarray) -> np.ndarray:
    """Zero-phase filtering with MATLAB's edge padding (``3·(order)`` samples)."""
    padlen = 3 * (max(len(a), len(b)) - 1)
    return signal.filtfilt(b, a, x, axis=0, padtype="odd", padlen=padlen)


def decimate(x: np.ndarray, factor: int) -> np.ndarray:
    """MATLAB-style ``decimate``: Chebyshev I anti-alias filter, zero phase, 1 in ``factor``.

    The kept samples are aligned to the end of the record, as MATLAB does.

    Parameters
    ----------
    x : ndarray
        Samples along axis 0 (1-D or 2-D, columns decimated independently).
    factor : int
        Keep one sample in ``factor`` (>= 1).
    """
    if factor == 1:
        return np.asarray(x, dtype=float)
    b, a = signal.cheby1(DECIMATE_ORDER, DECIMATE_RIPPLE_DB, 0.8 / factor)
    smooth = _filtfilt(b, a, np.asarray(x, dtype=float))
    n = len(smooth)
    first = factor - (factor * int(np.ceil(n / factor)) - n)  # MATLAB's nbeg, 1-based
    return smooth[first - 1 :: factor]


def _observation(
    time_s: np.ndarray, position: np.ndarray, force: np.ndarray, cutoff_hz: float,
    decimation: int, friction: str,
) -> tuple[np.ndarray, np.ndarray]:
    """Decimated observation matrix X and force vector y of the recipe."""
    dt = float(np.median(np.diff(time_s)))
    nyquist_hz = 0.5 / dt
    if not 0 < cutoff_hz < nyquist_hz:
        raise InputError(
            f"cutoff_hz must be in (0, {nyquist_hz:.6g}) Hz (the Nyquist frequency), got {cutoff_hz}"
        )
    b, a = signal.butter(FILTER_ORDER, cutoff_hz / nyquist_hz)
    q = _filtfilt(b, a, position)
    qd = np.gradient(q, dt)
    qdd = np.gradient(qd, dt)
    qd, qdd, y = qd[BORDER_SAMPLES:], qdd[BORDER_SAMPLES:], force[BORDER_SAMPLES:]
    if friction == "symmetric":
        columns = [qdd, qd, np.sign(qd), np.ones_like(qd)]
    else:
        pos, neg = (qd > 0).astype(float), (qd < 0).astype(float)
        columns = [qdd, qd * pos, pos, qd * neg, -neg]
    X = decimate(np.column_stack(columns), decimation)
    return X, decimate(y, decimation)


def _check(time_s: np.ndarray, position: np.ndarray, force: np.ndarray, friction: str,
           decimation: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    if friction not in PARAM_NAMES:
        raise InputError(f"friction must be 'symmetric' or 'asymmetric', not {friction!r}")
    if decimation < 1:
        raise InputError(f"decimation must be an integer >= 1, got {decimation}")
    arrays = [np.asarray(v, dtype=float).reshape(-1) for v in (time_s, position, force)]
    if len({len(v) for v in arrays}) != 1:
        raise InputError(
            f"time_s, position and force must have equal lengths, got {[len(v) for v in arrays]}"
        )
    rows = (len(arrays[0]) - BORDER_SAMPLES) // decimation
    if rows < MIN_ROWS_PER_PARAM * len(PARAM_NAMES[friction]):
        raise NotExcitedError(
            f"{len(arrays[0])} samples give {rows} decimated rows; IDIM-LS needs at least "
            f"{MIN_ROWS_PER_PARAM * len(PARAM_NAMES[friction])} (record longer or lower decimation)"
        )
    return arrays[0], arrays[1], arrays[2]


def _settings(time_s: np.ndarray, bandwidth_hz: float, cutoff_hz: float | None,
              decimation: int | None) -> tuple[float, int]:
    if bandwidth_hz <= 0:
        raise InputError(f"bandwidth_hz must be > 0 Hz, got {bandwidth_hz}")
    nyquist_hz = 0.5 / float(np.median(np.diff(time_s)))
    cutoff = CUTOFF_PER_BANDWIDTH * bandwidth_hz if cutoff_hz is None else float(cutoff_hz)
    factor = max(1, round(0.8 * nyquist_hz / (2 * bandwidth_hz))) if decimation is None else decimation
    return cutoff, int(factor)


def idim_ls(
    time_s: np.ndarray,
    position: np.ndarray,
    force: np.ndarray,
    *,
    bandwidth_hz: float = DEFAULT_BANDWIDTH_HZ,
    cutoff_hz: float | None = None,
    decimation: int | None = None,
    friction: Friction = "symmetric",
) -> IdimResult:
    """IDIM-LS estimate of M, Fv, Fc and offset from position and force records.

    Parameters
    ----------
    time_s : ndarray
        Sample times, s (uniform).
    position : ndarray
        Measured position, m (or rad for a rotary axis).
    force : ndarray
        Actuator force, N (or torque, N·m), e.g. drive gain × controller output.
    bandwidth_hz : float
        Closed-loop bandwidth, Hz; sets the defaults of ``cutoff_hz`` (5×) and
        ``decimation`` (``round(0.8·f_nyquist / (2·bandwidth))``).
    cutoff_hz : float, optional
        Butterworth cutoff of the position filter, Hz.
    decimation : int, optional
        Decimation factor of the observation matrix.
    friction : {"symmetric", "asymmetric"}
        Friction model (see the module docstring).

    Returns
    -------
    IdimResult

    Raises
    ------
    InputError
        Unequal lengths, a bad option.
    NotExcitedError
        Too few samples, or an observation matrix without full rank (no motion, or
        motion in one direction only for the asymmetric model).
    """
    if friction not in PARAM_NAMES:
        raise InputError(f"friction must be 'symmetric' or 'asymmetric', not {friction!r}")
    time_s = np.asarray(time_s, dtype=float).reshape(-1)
    cutoff, factor = _settings(time_s, bandwidth_hz, cutoff_hz, decimation)
    time_s, position, force = _check(time_s, position, force, friction, factor)
    X, y = _observation(time_s, position, force, cutoff, factor, friction)
    names = PARAM_NAMES[friction]
    if np.linalg.matrix_rank(X) < len(names):
        raise NotExcitedError(
            f"the observation matrix [{', '.join(names)}] is rank deficient: the record does not "
            "excite every parameter (it needs motion, acceleration, and both directions)"
        )
    theta, *_ = np.linalg.lstsq(X, y, rcond=None)
    error = y - X @ theta
    error_std = float(np.std(error, ddof=1))
    sigma = error_std * np.sqrt(np.diag(np.linalg.inv(X.T @ X)))
    norm_y = float(np.linalg.norm(y))
    relative_error = 100 * float(np.linalg.norm(error)) / norm_y if norm_y > 0 else float("inf")
    params = {n: float(v) for n, v in zip(names, theta, strict=True)}
    std = {n: float(s) for n, s in zip(names, sigma, strict=True)}
    return IdimResult(
        params=params,
        std=std,
        relative_std_percent={n: 100 * std[n] / abs(params[n]) if params[n] else float("inf")
                              for n in names},
        relative_error_percent=relative_error,
        error_norm=float(np.linalg.norm(error)),
        error_std=error_std,
        condition_number=float(np.linalg.cond(X)),
        samples=len(y),
        friction=friction,
        cutoff_hz=cutoff,
        decimation=factor,
        message=(f"IDIM-LS, {friction} friction: Butterworth {FILTER_ORDER} at {cutoff:.4g} Hz, "
                 f"decimation {factor}, {len(y)} rows, relative error {relative_error:.3g} %"),
    )


def idim_cross_test(
    result: IdimResult, time_s: np.ndarray, position: np.ndarray, force: np.ndarray
) -> IdimCrossTest:
    """Relative error of ``result``'s parameters on another record (same recipe).

    Parameters
    ----------
    result : IdimResult
        Parameters identified on the estimation record.
    time_s, position, force : ndarray
        The other record: s, m (or rad), N (or N·m).
    """
    time_s, position, force = _check(time_s, position, force, result.friction, result.decimation)
    X, y = _observation(time_s, position, force, result.cutoff_hz, result.decimation,
                        result.friction)
    theta = np.array([result.params[n] for n in PARAM_NAMES[result.friction]])
    error = y - X @ theta
    return IdimCrossTest(
        relative_error_percent=100 * float(np.linalg.norm(error) / np.linalg.norm(y)),
        error_norm=float(np.linalg.norm(error)),
        error_std=float(np.std(error, ddof=1)),
        samples=len(y),
    )


def idim_run(
    run: Run,
    *,
    Kt: float = 1.0,
    bandwidth_hz: float = DEFAULT_BANDWIDTH_HZ,
    cutoff_hz: float | None = None,
    decimation: int | None = None,
    friction: Friction = "symmetric",
) -> IdimResult:
    """IDIM-LS on a single-motor run: position ``position_rad``, force ``Kt·current_A``.

    Parameters
    ----------
    run : Run
        A run of kind ``single``.
    Kt : float
        Force (torque) per unit of ``current_A``, N/A (N·m/A); 1 when the run already
        carries the force in ``current_A`` (EMPS imports).
    bandwidth_hz, cutoff_hz, decimation, friction
        As in :func:`idim_ls`.
    """
    return idim_ls(run.time_s, run["position_rad"], Kt * run["current_A"],
                   bandwidth_hz=bandwidth_hz, cutoff_hz=cutoff_hz, decimation=decimation,
                   friction=friction)
