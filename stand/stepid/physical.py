"""From transfer-function coefficients to the physical parameters R, L, K, J, Kf.

The fitted coefficients ``ĉ`` (3 from speed, 5 with current) and their covariance ``Σ``
are all the data say. The physical parameters not given by the user are found by
minimum distance: minimize ``(c(p) − ĉ)ᵀ Σ⁻¹ (c(p) − ĉ)`` over ``log p`` (asymptotically
the same estimate and covariance as fitting ``p`` to the samples directly).

Identifiability is decided from the rank of ``S = ∂c/∂log p`` over the free parameters:
a parameter is determined when it has no component in the null space of ``S``. From
speed alone ``S`` has rank 3, so with five unknowns nothing is determined; each known
value removes one unknown. With the current, all five are determined.

Starts come from the two-parameter family of :func:`stand.stepid.model.family`: for
``u = R/L`` on a grid over ``(0, a1)`` the scale ``x = 1/L`` that best matches the known
values (and ``c1``, ``c0``) is closed-form, and every local minimum of the mismatch is
polished. Two parameter sets can fit equally (the electrical and mechanical poles
swapped); the one with the faster electrical time constant (``R/L > Kf/J``), the usual
case for DC motors, is reported and the other is listed under ``alternatives``.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np
from scipy import stats
from scipy.optimize import least_squares

from stand.stepid.model import PARAM_NAMES, coefficient_jacobian, coefficients, family

#: Grid of u/a1 (logistic spacing, dense near both ends of (0, 1)) for the starts.
U_GRID = 1.0 / (1.0 + np.exp(-np.linspace(-14.0, 14.0, 801)))
#: Largest number of starts polished.
MAX_STARTS = 6
#: Relative size of a null-space component below which a parameter counts as determined.
NULL_TOLERANCE = 1e-3
#: Singular values below this fraction of the largest count as zero.
RANK_TOLERANCE = 1e-7
#: Singular values of the whitened sensitivity below this fraction count as null.
COVARIANCE_RCOND = 1e-10
#: Generic points at which identifiability is tested.
GENERIC_POINTS = 3
#: Chi-square difference within which two parameter sets fit equally well.
EQUAL_FIT_CHI2 = 1.0
#: Level beyond which the coefficients count as not reproduced by any parameter set.
CONSISTENCY_LEVEL = 0.99
#: Relative difference that makes two parameter sets distinct.
DISTINCT = 1e-3


@dataclass(frozen=True)
class PhysicalEstimate:
    """Physical parameters as far as the data and the known values determine them.

    Attributes
    ----------
    params : dict of str to float or None
        ``R`` Ω, ``L`` H, ``K`` N·m/A, ``J`` kg·m², ``Kf`` N·m·s/rad; ``None`` where not
        determined. Known values come back as given.
    std : dict of str to float or None
        Standard error of each estimate (0 for a known value).
    identifiable : list of str
        Parameters the data determine (known values excluded).
    alternatives : list of dict
        Other parameter sets that fit as well.
    chi2 : float
        Weighted distance between the fitted and the model coefficients (0 when the
        parameters reproduce them exactly).
    message : str
        A warning when no parameter set reproduces the coefficients.
    """

    params: dict[str, float | None]
    std: dict[str, float | None]
    identifiable: list[str]
    alternatives: list[dict[str, float]] = field(default_factory=list)
    chi2: float = 0.0
    message: str = ""


def _whitener(cov: np.ndarray) -> np.ndarray:
    """``W`` with ``Wᵀ W = cov⁻¹`` (pseudo-inverse on a near-singular covariance)."""
    values, vectors = np.linalg.eigh(cov)
    floor = max(float(values.max()), 1e-300) * 1e-14
    return (vectors / np.sqrt(np.maximum(values, floor))).T


def _targets(known: Mapping[str, float], coefs: np.ndarray) -> list[tuple[str, float]]:
    targets = [(name, float(np.log(value))) for name, value in known.items()]
    if len(coefs) > 3:
        targets += [(name, float(np.log(v))) for name, v in zip(("c1", "c0"), coefs[3:], strict=True)
                    if v > 0]
    return targets


def _starts(coefs: np.ndarray, known: Mapping[str, float]) -> list[np.ndarray]:
    """Full parameter vectors on the family, at the local minima of the mismatch."""
    b0, a1, a0 = coefs[:3]
    u = a1 * U_GRID
    K = (a0 - u * (a1 - u)) / b0
    valid = K > 0
    u, K = u[valid], K[valid]
    if not len(u):
        return []
    # log target = log f(u) + k·log x, with k the power of x in each quantity.
    logs = {
        "R": (np.log(u), -1), "L": (np.zeros_like(u), -1), "K": (np.log(K), 0),
        "J": (np.log(K / b0), 1), "Kf": (np.log((a1 - u) * K / b0), 1),
        "c1": (np.zeros_like(u), 1), "c0": (np.log(a1 - u), 1),
    }
    targets = _targets(known, coefs)
    scaled = [(value - logs[name][0], logs[name][1]) for name, value in targets]
    with_x = [k * d for d, k in scaled if k]
    log_x = np.mean(with_x, axis=0) if with_x else np.log(u)  # no scale: R = 1 Ω
    mismatch = sum(((d - k * log_x) ** 2 for d, k in scaled), np.zeros_like(u))
    inner = (mismatch[1:-1] <= mismatch[:-2]) & (mismatch[1:-1] <= mismatch[2:])
    minima = list(np.flatnonzero(inner) + 1) + [0, len(u) - 1]
    minima.sort(key=lambda i: mismatch[i])
    x = np.exp(log_x)
    return [family(u[i], x[i], b0, a1, a0) for i in minima[:MAX_STARTS]]


def _signature(p: np.ndarray) -> np.ndarray:
    """``log(R/L, 1/L, K)``: what tells two solutions apart (a parameter driven towards
    its bound 0 does not)."""
    R, L, K, _, _ = p
    return np.log([R / L, 1.0 / L, K])


def _determined(free: list[str], with_current: bool) -> list[str]:
    """Free parameters that are locally identifiable at generic parameter values.

    Identifiability is structural: it depends on the model and on which parameters are
    known, not on their values. It is tested at ``GENERIC_POINTS`` random points (not at
    the estimate, which may sit at an edge of the family where the test turns sloppy);
    a parameter counts as determined when it has no null-space component at any of them.
    """
    rng = np.random.default_rng(0)
    index = [PARAM_NAMES.index(name) for name in free]
    determined = set(free)
    for _ in range(GENERIC_POINTS):
        p = np.exp(rng.normal(0.0, 1.0, len(PARAM_NAMES)))
        # Sensitivity of log coefficients to log parameters: scale-free.
        S = coefficient_jacobian(p, with_current)[:, index] * p[index]
        S /= coefficients(p, with_current)[:, None]
        _, singular, vt = np.linalg.svd(S)
        rank = int(np.sum(singular > RANK_TOLERANCE * singular[0]))
        null = vt[rank:].T
        if null.size:
            determined -= {name for j, name in enumerate(free)
                           if np.linalg.norm(null[j]) > NULL_TOLERANCE}
    return [name for name in free if name in determined]


def physical_estimate(coefs: np.ndarray, cov: np.ndarray,
                      known: Mapping[str, float]) -> PhysicalEstimate:
    """Physical parameters from fitted coefficients.

    Parameters
    ----------
    coefs : ndarray
        ``(b0, a1, a0)`` or ``(b0, a1, a0, c1, c0)`` (:mod:`stand.stepid.model`).
    cov : ndarray
        Their covariance.
    known : mapping of str to float
        Values the user gives (> 0), by parameter name.
    """
    with_current = len(coefs) > 3
    free = [name for name in PARAM_NAMES if name not in known]
    index = [PARAM_NAMES.index(name) for name in free]
    W = _whitener(cov)

    def full(log_free: np.ndarray) -> np.ndarray:
        p = np.array([known.get(name, 0.0) for name in PARAM_NAMES])
        p[index] = np.exp(log_free)
        return p

    def residuals(log_free: np.ndarray) -> np.ndarray:
        return W @ (coefficients(full(log_free), with_current) - coefs)

    solutions: list[tuple[float, np.ndarray]] = []
    for start in _starts(coefs, known):
        if not np.all(start > 0):
            continue
        result = least_squares(residuals, np.log(start[index]), method="trf", x_scale=1.0,
                               ftol=1e-14, xtol=1e-14, gtol=1e-14, max_nfev=500)
        solutions.append((2.0 * float(result.cost), result.x))
    nothing: dict[str, float | None] = {name: None for name in PARAM_NAMES}
    given = {name: float(value) for name, value in known.items()}
    if not solutions or not free:
        std: dict[str, float | None] = {**nothing, **dict.fromkeys(given, 0.0)}
        return PhysicalEstimate({**nothing, **given}, std, [])
    solutions.sort(key=lambda s: s[0])
    best_chi2 = solutions[0][0]
    equal: list[np.ndarray] = []
    for chi2, log_free in solutions:
        if chi2 <= best_chi2 + EQUAL_FIT_CHI2 and all(
                np.max(np.abs(_signature(full(log_free)) - _signature(full(other)))) > DISTINCT
                for other in equal):
            equal.append(log_free)

    def electrical_faster(log_free: np.ndarray) -> bool:
        R, L, _, J, Kf = full(log_free)
        return bool(Kf / J < R / L)

    equal.sort(key=lambda lf: not electrical_faster(lf))
    chosen = equal[0]
    values = full(chosen)
    # Sensitivity per unit of each parameter (not per log unit), so that a parameter
    # driven to its bound 0 still gets its honest, large standard error.
    S = W @ coefficient_jacobian(values, with_current)[:, index]
    determined = _determined(free, with_current)
    # Covariance V·Σ⁻²·Vᵀ from the SVD of S, dropping only structurally null directions
    # (an ill-determined direction keeps its large variance).
    _, singular, vt = np.linalg.svd(S, full_matrices=False)
    keep = singular > COVARIANCE_RCOND * singular[0]
    cov = (vt[keep].T / singular[keep] ** 2) @ vt[keep]
    params: dict[str, float | None] = {**nothing, **given}
    std = {**nothing, **dict.fromkeys(given, 0.0)}
    for j, name in enumerate(free):
        if name in determined:
            params[name] = float(values[PARAM_NAMES.index(name)])
            std[name] = float(np.sqrt(max(cov[j, j], 0.0)))
    chi2 = float(np.sum(residuals(chosen) ** 2))
    dof = len(coefs) - min(len(free), len(coefs))
    message = ""
    if chi2 > stats.chi2.ppf(CONSISTENCY_LEVEL, max(dof, 1)):
        message = (f"no positive R, L, K, J, Kf with the known values reproduces the fitted "
                   f"coefficients (chi-square {chi2:.3g}); some estimate sits at its bound 0 "
                   "and its standard error is the guide. ")
    alternatives = []
    if determined:
        for other in equal[1:]:
            p = full(other)
            alternatives.append({name: float(p[PARAM_NAMES.index(name)]) for name in determined})
    return PhysicalEstimate(params, std, determined, alternatives, chi2, message)
