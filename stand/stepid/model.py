"""The seed 001 DC motor model (eqs. 1-10) as transfer-function coefficients, and its response.

Voltage in, speed out (and current, when measured), with ``K = Kt = Kb``::

    ω(s)/v(s) = K / ((L·s + R)(J·s + Kf) + K²) = b0 / (s² + a1·s + a0)
    i(s)/v(s) = (J·s + Kf) / ((L·s + R)(J·s + Kf) + K²) = (c1·s + c0) / (s² + a1·s + a0)

so ``b0 = K/(L·J)``, ``a1 = R/L + Kf/J``, ``a0 = (R·Kf + K²)/(L·J)``, ``c1 = 1/L`` and
``c0 = Kf/(L·J)``. Speed alone determines (b0, a1, a0); with the current all five.

The response is computed exactly for a voltage held constant over each sample period
(zero-order hold). Which period a voltage sample belongs to is ``hold``:

- ``"preceding"`` (default): ``voltage_V[k]`` was applied over the period that ends at
  ``time_s[k]``, as a drive reports the voltage it applied (and as :mod:`stand.physics`
  simulates: the sample is read, then the next command is applied);
- ``"following"``: ``voltage_V[k]`` is applied over the period that starts at ``time_s[k]``,
  as a command log or a DAQ sampling the command before it acts.

Every run is assumed to start in equilibrium: at rest, or at the steady speed of some
voltage ``v_eq`` (its *initial voltage*, fitted per run, so a file may start at the step
instant with the motor at rest, or in steady state at its first voltage).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy.linalg import expm
from scipy.signal import lfilter

from stand.errors import InputError
from stand.runfile import Run

#: Physical parameters of seed 001, in the order used everywhere.
PARAM_NAMES: tuple[str, ...] = ("R", "L", "K", "J", "Kf")
#: Units of the physical parameters.
PARAM_UNITS: dict[str, str] = {"R": "Ω", "L": "H", "K": "N·m/A", "J": "kg·m²", "Kf": "N·m·s/rad"}
#: Transfer-function coefficients: speed (b0, a1, a0), then current (c1, c0).
COEF_NAMES: tuple[str, ...] = ("b0", "a1", "a0", "c1", "c0")
HOLDS: tuple[str, ...] = ("preceding", "following")


@dataclass(frozen=True)
class StepData:
    """One voltage-step run, as arrays.

    Attributes
    ----------
    time_s : ndarray
        Sample times from 0, s.
    dt_s : float
        Sample period, s.
    voltage_V : ndarray
        Armature voltage, V.
    velocity_rad_s : ndarray
        Measured speed, rad/s.
    current_A : ndarray or None
        Measured armature current, A, when recorded.
    source : str
        Where the run came from.
    """

    time_s: np.ndarray
    dt_s: float
    voltage_V: np.ndarray
    velocity_rad_s: np.ndarray
    current_A: np.ndarray | None
    source: str


def step_data(runs: Sequence[Run]) -> list[StepData]:
    """Arrays of ``runs`` (run kind ``step``); validates that they can be identified.

    Raises
    ------
    InputError
        No runs, a run without ``voltage_V`` or ``velocity_rad_s``.
    NotExcitedError
        Raised later by the fit when no run's voltage changes.
    """
    if not runs:
        raise InputError("runs: give at least one voltage-step run")
    data = []
    for run in runs:
        for name in ("time_s", "voltage_V", "velocity_rad_s"):
            if name not in run:
                raise InputError(
                    f"{run.source}: no column {name}; a step run needs time_s, voltage_V, "
                    "velocity_rad_s (optional current_A)"
                )
        time_s = run.time_s - run.time_s[0]
        current = run.columns.get("current_A")
        data.append(StepData(time_s, run.dt_s, run["voltage_V"], run["velocity_rad_s"],
                             current, run.source))
    return data


def coefficients(params: np.ndarray, with_current: bool) -> np.ndarray:
    """Transfer-function coefficients of physical parameters ``(R, L, K, J, Kf)``.

    Returns
    -------
    ndarray
        ``(b0, a1, a0)`` in 1/(V·s²)·rad, 1/s, 1/s², and with ``with_current`` also
        ``(c1, c0)`` in 1/H and A/(V·s).
    """
    R, L, K, J, Kf = params
    LJ = L * J
    coefs = [K / LJ, R / L + Kf / J, (R * Kf + K * K) / LJ]
    if with_current:
        coefs += [1.0 / L, Kf / LJ]
    return np.array(coefs)


def coefficient_jacobian(params: np.ndarray, with_current: bool) -> np.ndarray:
    """``∂(b0, a1, a0[, c1, c0])/∂(R, L, K, J, Kf)``, analytic (rows: coefficients)."""
    R, L, K, J, Kf = params
    LJ = L * J
    b0, a1, a0 = K / LJ, R / L + Kf / J, (R * Kf + K * K) / LJ
    rows = [
        [0.0, -b0 / L, 1.0 / LJ, -b0 / J, 0.0],
        [1.0 / L, -R / L**2, 0.0, -Kf / J**2, 1.0 / J],
        [Kf / LJ, -a0 / L, 2.0 * K / LJ, -a0 / J, R / LJ],
    ]
    if with_current:
        c0 = Kf / LJ
        rows += [[0.0, -1.0 / L**2, 0.0, 0.0, 0.0], [0.0, -c0 / L, 0.0, -c0 / J, 1.0 / LJ]]
    del a1
    return np.array(rows)


def family(u: np.ndarray, x: np.ndarray, b0: float, a1: float, a0: float) -> np.ndarray:
    """Every ``(R, L, K, J, Kf)`` with the speed transfer function ``b0/(s² + a1·s + a0)``.

    The speed-only model leaves two degrees of freedom: ``u = R/L`` in ``(0, a1)`` and
    ``x = 1/L`` > 0. Then ``K = (a0 − u·(a1 − u))/b0``, ``R = u/x``, ``L = 1/x``,
    ``J = K·x/b0`` and ``Kf = (a1 − u)·J``; ``K`` must come out > 0.

    Returns
    -------
    ndarray, shape (5, ...)
        ``R, L, K, J, Kf`` for each ``(u, x)``.
    """
    K = (a0 - u * (a1 - u)) / b0
    J = K * x / b0
    return np.array([u / x, 1.0 / x, K, J, (a1 - u) * J])


def _discrete(coefs: np.ndarray, dt_s: float) -> tuple[np.ndarray, list[np.ndarray]]:
    """Zero-order-hold discretization: denominator and one numerator a measured output."""
    b0, a1, a0 = coefs[:3]
    A = np.array([[0.0, 1.0], [-a0, -a1]])
    block = np.zeros((3, 3))
    block[:2, :2] = A * dt_s
    block[1, 2] = dt_s
    phi = expm(block)
    Ad, Bd = phi[:2, :2], phi[:2, 2]
    (a, b), (c, d) = Ad
    den = np.array([1.0, -(a + d), a * d - b * c])
    adjugate = np.array([[-d, b], [c, -a]])
    outputs = [np.array([b0, 0.0])]
    if len(coefs) > 3:
        outputs.append(np.array([coefs[4], coefs[3]]))
    nums = [np.array([C @ Bd, C @ adjugate @ Bd]) for C in outputs]
    return den, nums


def respond(coefs: np.ndarray, data: StepData, hold: str = "preceding",
            initial_voltage_V: float | None = None) -> list[np.ndarray]:
    """Model response of a run to its measured voltage.

    Parameters
    ----------
    coefs : ndarray
        ``(b0, a1, a0)`` or ``(b0, a1, a0, c1, c0)``.
    data : StepData
        The run (its voltage and sample times).
    hold : {'preceding', 'following'}
        Which sample period a voltage sample belongs to (module docstring).
    initial_voltage_V : float, optional
        The voltage whose steady state the run starts in, V (default: the first sample).

    Returns
    -------
    list of ndarray
        Speed, rad/s, and with five coefficients also the current, A.
    """
    if hold not in HOLDS:
        raise InputError(f"hold must be one of {', '.join(HOLDS)}, not {hold!r}")
    den, nums = _discrete(coefs, data.dt_s)
    v0 = data.voltage_V[0] if initial_voltage_V is None else initial_voltage_V
    dv = data.voltage_V - v0
    gains = [coefs[0] / coefs[2]]
    if len(coefs) > 3:
        gains.append(coefs[4] / coefs[2])
    out = []
    for num, gain in zip(nums, gains, strict=True):
        taps = num if hold == "preceding" else np.concatenate([[0.0], num])
        out.append(gain * v0 + lfilter(taps, den, dv))
    return out
