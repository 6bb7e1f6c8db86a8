"""One single-motor run to the model of seed 000 eqs. 2-5: A, B and the physical ratios.

The state is ``x = [θ, ω]`` and the input ``u = i − i_nl`` (measured current less the
no-load current of §5.1, 0 when not compensating). Eq. 10 gives::

    A = [[0, 1], [−C/J, −D/J]],   B = [[0], [Kt/J]]

``fit_percent`` is the equation-error fit of the acceleration row (the row that carries
the physics; the first row is the kinematic identity θ' = ω).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.stats import chi2

from stand.errors import NotExcitedError
from stand.ident.derivatives import state_derivatives
from stand.ident.noise import noise_sigma
from stand.ident.qmatrix import QSums, solve
from stand.jsonable import JsonResult
from stand.runfile import Run

#: Blocks the current is split into to test that it varies beyond its noise.
EXCITATION_BLOCKS = 20
#: Significance level of that test: a current whose block means vary no more than white
#: noise would make them, at this level, counts as constant.
EXCITATION_SIGNIFICANCE = 1e-3
#: Largest relative standard error of Kt/J for which a run counts as exciting the model;
#: beyond it the current carries no information distinguishable from noise (e.g. a
#: constant current at a constant speed).
MAX_RELATIVE_SE = 0.25


@dataclass(frozen=True)
class IdentifyResult(JsonResult):
    """Identified model of one run (CONTRACT §2 ``stand identify``).

    Attributes
    ----------
    A : list of list of float
        System matrix (2x2): rows θ', ω'; columns θ, ω.
    B : list of list of float
        Input matrix (2x1), per A of current, rad/s² per A in the second row.
    Kt_over_J : float
        ``B[1][0]``, rad/(s²·A).
    D_over_J : float
        ``−A[1][1]``, 1/s.
    C_over_J : float
        ``−A[1][0]``, 1/s².
    Kt_over_J_se, D_over_J_se, C_over_J_se : float
        Standard errors (white equation error assumed; see :class:`QResult`).
    fit_percent : float
        Equation-error fit of the acceleration row, %.
    condition_number : float
        Of the equilibrated normal matrix of eq. 10.
    samples : int
        Rows used in eq. 10.
    method : str
        ``default`` or ``paper``.
    dt_s : float
        Sample period, s.
    no_load_current_A : float
        Current subtracted from the measured current, A.
    half_width : int
        Half width of the default method's kernel, samples (0 for ``paper``).
    source : str
        The run identified (its file name).
    """

    A: list[list[float]]
    B: list[list[float]]
    Kt_over_J: float
    D_over_J: float
    C_over_J: float
    Kt_over_J_se: float
    D_over_J_se: float
    C_over_J_se: float
    fit_percent: float
    condition_number: float
    samples: int
    method: str
    dt_s: float
    no_load_current_A: float
    half_width: int
    source: str = ""


def _check_current_varies(current: np.ndarray, source: str) -> None:
    """Refuse a current that is constant but for noise (it cannot separate Kt·i from
    constant torques such as Coulomb friction or an offset).

    The run is cut into ``EXCITATION_BLOCKS`` blocks of ``b`` samples; under "constant plus
    white noise of standard deviation σ" the variance of the block means times ``b/σ²``
    is χ²-distributed with ``blocks − 1`` degrees of freedom divided by them. The current
    must exceed its upper ``EXCITATION_SIGNIFICANCE`` quantile. σ comes from the
    sample-to-sample differences, so slow variation (the signal) does not inflate it.
    """
    blocks = min(EXCITATION_BLOCKS, len(current) // 2)
    b = len(current) // blocks
    means = current[: blocks * b].reshape(blocks, b).mean(axis=1)
    sigma = noise_sigma(current)
    observed = float(np.var(means, ddof=1))
    limit = chi2.ppf(1 - EXCITATION_SIGNIFICANCE, blocks - 1) / (blocks - 1) * sigma**2 / b
    if not observed > limit:
        raise NotExcitedError(
            f"{source}: current_A is constant but for its noise ({sigma:.3g} A): the means of "
            f"{blocks} blocks of {b} samples vary by {np.sqrt(observed):.3g} A, not beyond the "
            f"{np.sqrt(limit):.3g} A noise explains; a constant current cannot separate Kt "
            "from constant torques; excite the motor with a varying command (e.g. a "
            "band-limited or PRBS speed command)"
        )


def identify_run(run: Run, method: str = "default", no_load_current_A: float = 0.0,
                 half_width: int | None = None) -> IdentifyResult:
    """Identify A and B of one single-motor run by seed 000 eq. 10.

    Parameters
    ----------
    run : Run
        Single-motor run with ``position_rad`` and ``current_A``.
    method : {'default', 'paper'}
        Derivatives: kernel filtering or the paper's forward Euler differences.
    no_load_current_A : float
        No-load current subtracted from the measured current (§5.1), A.
    half_width : int or None
        Half width of the default kernel, samples; ``None`` (default) chooses it from the
        current's noise (:func:`~stand.ident.derivatives.auto_half_width`).

    Raises
    ------
    NotExcitedError
        The run does not determine the model.
    """
    dt = run.dt_s
    position = run["position_rad"]
    if np.ptp(position) == 0:
        raise NotExcitedError(
            f"{run.source}: position_rad never changes: the motor is at rest, which does not "
            "excite the model; command a varying speed"
        )
    measured = run["current_A"]
    _check_current_varies(measured, run.source)
    current = measured - no_load_current_A
    states = state_derivatives(position, current, dt, method, half_width)
    sums = QSums.zeros(2, 1).add(states.xdot, states.x, states.inputs, dt)
    try:
        q = solve(sums, names=["angle θ", "speed ω", "current i"])
    except NotExcitedError as exc:
        raise NotExcitedError(f"{run.source}: {exc}") from None
    b2, b2_se = float(q.B[1, 0]), float(q.B_se[1, 0])
    if not abs(b2) > MAX_RELATIVE_SE ** -1 * b2_se:
        raise NotExcitedError(
            f"{run.source}: Kt/J = {b2:.4g} ± {b2_se:.2g}: the run does not determine Kt/J "
            f"(relative standard error above {MAX_RELATIVE_SE:.0%}); excite the motor more "
            "(larger or faster command changes, a longer run) or use the default method"
        )
    return IdentifyResult(
        A=q.A.tolist(), B=q.B.tolist(),
        Kt_over_J=b2, D_over_J=-float(q.A[1, 1]), C_over_J=-float(q.A[1, 0]),
        Kt_over_J_se=b2_se, D_over_J_se=float(q.A_se[1, 1]), C_over_J_se=float(q.A_se[1, 0]),
        fit_percent=float(q.fit_percent[1]), condition_number=float(q.condition_number),
        samples=int(q.samples), method=method, dt_s=dt, no_load_current_A=no_load_current_A,
        half_width=states.first if method == "default" else 0, source=run.source,
    )
