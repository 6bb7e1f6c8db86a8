"""Torque constant from no-load and added-inertia runs: seed 000 eqs. 11-17 and §5.1.

Each no-load run gives ``b̂2 = Kt/J`` (eq. 11), each run with the disk ``Ĵ`` mounted gives
``b̃2 = Kt/(J + Ĵ)`` (eq. 15); eliminating ``J`` (eqs. 16-17)::

    Kt = b̃2·b̂2·Ĵ / (b̂2 − b̃2)

Run ``k`` of one kind pairs with run ``k`` of the other; the result is the mean and the
standard deviation over the repeats (5 in the seed).

No-load current (§5.1): a motor turning forward at no load draws a current that makes no
acceleration (Coulomb friction ``Tc/Kt`` and viscous ``D·ω/Kt``). The model of eq. 2 has
no constant term, so that current biases the estimates. Compensation subtracts the mean
no-load current of the no-load repeats from the measured current of every run. The
no-load current of one run is its current at zero acceleration (:func:`no_load_current`).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from stand.errors import InputError
from stand.ident.derivatives import state_derivatives
from stand.ident.identify import IdentifyResult, identify_run
from stand.jsonable import JsonResult
from stand.runfile import Run


@dataclass(frozen=True)
class TorqueConstantResult(JsonResult):
    """Torque constant and rotor parameters (CONTRACT §2 ``stand torque-constant``).

    Attributes
    ----------
    Kt : float
        Mean torque constant over the repeats, N·m/A.
    Kt_std : float
        Standard deviation of Kt over the repeats (one repeat: propagated standard error),
        N·m/A.
    J : float
        Rotor inertia, ``Kt / mean(b̂2)``, kg·m².
    D : float
        Viscous friction, ``J·mean(D/J)`` of the no-load runs, N·m·s/rad.
    C : float
        Spring constant, ``J·mean(C/J)`` of the no-load runs, N·m/rad.
    repeats : int
        Pairs of runs.
    no_load_current_A : float
        Mean no-load current of the no-load runs, A (subtracted when ``compensated``).
    compensated : bool
        Whether the no-load current was subtracted (§5.1).
    method : str
        Derivative method.
    Kt_repeats : list of float
        Kt of each pair, N·m/A.
    Kt_over_J_no_load, Kt_over_J_loaded : list of float
        ``b̂2`` and ``b̃2`` of each run, rad/(s²·A).
    no_load_current_repeats_A : list of float
        No-load current of each no-load run, A.
    added_inertia : float
        Disk inertia Ĵ, kg·m².
    """

    Kt: float
    Kt_std: float
    J: float
    D: float
    C: float
    repeats: int
    no_load_current_A: float
    compensated: bool
    method: str
    Kt_repeats: list[float]
    Kt_over_J_no_load: list[float]
    Kt_over_J_loaded: list[float]
    no_load_current_repeats_A: list[float]
    added_inertia: float


def kt_from_pair(b2_no_load: float, b2_loaded: float, added_inertia: float) -> float:
    """Eq. 17: ``Kt = b̃2·b̂2·Ĵ / (b̂2 − b̃2)``, N·m/A."""
    return b2_loaded * b2_no_load * added_inertia / (b2_no_load - b2_loaded)


def no_load_current(run: Run, method: str = "default",
                    half_width: int | None = None) -> float:
    """No-load current of one no-load run, A.

    The current at zero acceleration: the intercept ``i0`` of the least-squares line
    ``i = i0 + (J/Kt)·α`` through the run's (filtered) current and acceleration. It holds
    the Coulomb and the mean viscous friction current and none of the current that
    accelerates the rotor (a run that starts from rest has a net acceleration).
    """
    states = state_derivatives(run["position_rad"], run["current_A"], run.dt_s, method,
                               half_width)
    alpha, current = states.alpha, states.inputs[:, 0]
    design = np.column_stack([np.ones_like(alpha), alpha])
    (i0, _), *_ = np.linalg.lstsq(design, current, rcond=None)
    return float(i0)


def torque_constant(no_load_runs: Sequence[Run], loaded_runs: Sequence[Run],
                    added_inertia: float, method: str = "default", compensate: bool = True,
                    half_width: int | None = None) -> TorqueConstantResult:
    """Kt, J, D, C from repeated no-load and added-inertia runs (eqs. 11-17, §5.1).

    Parameters
    ----------
    no_load_runs, loaded_runs : sequence of Run
        Single-motor runs without and with the disk; equally many (paired in order), or
        one of either kind (paired with every run of the other).
    added_inertia : float
        Inertia of the disk Ĵ, kg·m².
    method : {'default', 'paper'}
        Derivative method (see :mod:`stand.ident.derivatives`).
    compensate : bool
        Subtract the mean no-load current (§5.1).

    Raises
    ------
    InputError
        No runs, unpairable counts, a non-positive inertia, or data in which the disk
        does not lower Kt/J.
    NotExcitedError
        A run that does not determine the model.
    """
    if not (np.isfinite(added_inertia) and added_inertia > 0):
        raise InputError(f"added inertia must be a finite number > 0 kg·m², got {added_inertia}")
    n_free, n_load = len(no_load_runs), len(loaded_runs)
    if n_free == 0 or n_load == 0:
        raise InputError("need at least one no-load run and one run with the added inertia")
    repeats = max(n_free, n_load)
    if n_free != n_load and min(n_free, n_load) != 1:
        raise InputError(
            f"got {n_free} no-load and {n_load} loaded runs; give equally many (paired in "
            "order) or one of either kind"
        )
    currents = [no_load_current(run, method, half_width) for run in no_load_runs]
    i_nl = float(np.mean(currents))
    offset = i_nl if compensate else 0.0
    free: list[IdentifyResult] = [identify_run(r, method, offset, half_width) for r in no_load_runs]
    loaded = [identify_run(r, method, offset, half_width) for r in loaded_runs]
    b_free = np.array([f.Kt_over_J for f in free])
    b_load = np.array([f.Kt_over_J for f in loaded])
    if np.mean(b_free) <= np.mean(b_load):
        raise InputError(
            f"Kt/J with the disk ({np.mean(b_load):.4g}) is not below Kt/J without it "
            f"({np.mean(b_free):.4g}): check that the runs are labelled the right way round "
            "and that the disk was mounted"
        )
    pairs = np.broadcast_arrays(b_free, b_load) if repeats > 1 else (b_free, b_load)
    kt = kt_from_pair(pairs[0], pairs[1], added_inertia)  # type: ignore[arg-type]
    kt_mean = float(np.mean(kt))
    if repeats > 1:
        kt_std = float(np.std(kt, ddof=1))
    else:  # propagate the standard errors of b̂2, b̃2 through eq. 17
        bf, bl = float(b_free[0]), float(b_load[0])
        sf, sl = free[0].Kt_over_J_se, loaded[0].Kt_over_J_se
        dkdf = -bl * bl * added_inertia / (bf - bl) ** 2
        dkdl = bf * bf * added_inertia / (bf - bl) ** 2
        kt_std = float(np.hypot(dkdf * sf, dkdl * sl))
    J = kt_mean / float(np.mean(b_free))
    return TorqueConstantResult(
        Kt=kt_mean, Kt_std=kt_std, J=J,
        D=J * float(np.mean([f.D_over_J for f in free])),
        C=J * float(np.mean([f.C_over_J for f in free])),
        repeats=repeats, no_load_current_A=i_nl, compensated=compensate, method=method,
        Kt_repeats=[float(k) for k in np.atleast_1d(kt)],
        Kt_over_J_no_load=b_free.tolist(), Kt_over_J_loaded=b_load.tolist(),
        no_load_current_repeats_A=currents, added_inertia=added_inertia,
    )
