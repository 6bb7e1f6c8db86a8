"""Minimizers of a sum of squared residuals: the four algorithms seed 001 compares.

``trf`` and ``lm`` are :func:`scipy.optimize.least_squares` (trust-region reflective and
Levenberg-Marquardt). ``gd`` is gradient descent and ``pattern`` a generalized pattern
search (compass search on the 2·n coordinate directions, as MATLAB's ``patternsearch``
with its default GPS poll), written here because SciPy has neither. All four work on
the same residual function of a parameter vector that is already scaled to order one.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares

from stand.errors import InputError

METHODS: tuple[str, ...] = ("trf", "lm", "gd", "pattern")
#: Relative tolerance on the cost and the step for every method.
TOLERANCE = 1e-10
#: Iteration budget of gradient descent (each iteration costs one Jacobian).
GD_MAX_ITERATIONS = 1000
#: Gradient descent counts as converged when every column of the Jacobian is this close
#: to orthogonal to the residuals (cosine).
GD_OPTIMALITY = 1e-4
#: Residual-evaluation budget of pattern search per parameter (MATLAB's default 2000·n).
PATTERN_EVALUATIONS_PER_PARAMETER = 2000
#: First mesh size of pattern search, in scaled parameter units (log units: ~10 %).
PATTERN_INITIAL_MESH = 0.1
#: Pattern search stops when the mesh is this small.
PATTERN_MIN_MESH = 1e-7
#: Relative step of the forward-difference Jacobian.
FD_STEP = 1e-7

Residuals = Callable[[np.ndarray], np.ndarray]


@dataclass(frozen=True)
class Minimum:
    """Where a minimizer stopped.

    Attributes
    ----------
    x : ndarray
        Scaled parameters at the end.
    residuals : ndarray
        Residuals there.
    jacobian : ndarray
        Jacobian of the residuals there (``n_residuals x n_params``).
    nfev : int
        Residual evaluations used.
    converged : bool
        Whether the method met its tolerance (rather than its budget).
    elapsed_s : float
        Wall time, s.
    message : str
        What stopped it.
    """

    x: np.ndarray
    residuals: np.ndarray
    jacobian: np.ndarray
    nfev: int
    converged: bool
    elapsed_s: float
    message: str


def jacobian(fun: Residuals, x: np.ndarray, r0: np.ndarray) -> np.ndarray:
    """Forward-difference Jacobian of ``fun`` at ``x`` (``r0 = fun(x)``)."""
    columns = []
    for j in range(len(x)):
        h = FD_STEP * max(1.0, abs(x[j]))
        step = x.copy()
        step[j] += h
        columns.append((fun(step) - r0) / h)
    return np.column_stack(columns)


def _least_squares(fun: Residuals, x0: np.ndarray, method: str) -> tuple[np.ndarray, int, bool, str]:
    result = least_squares(fun, x0, method=method, x_scale="jac", ftol=TOLERANCE,
                           xtol=TOLERANCE, gtol=TOLERANCE, max_nfev=2000)
    return result.x, int(result.nfev), bool(result.status > 0), str(result.message)


def _optimality(J: np.ndarray, r: np.ndarray) -> float:
    """Largest cosine between a Jacobian column and the residuals (0 at a stationary point)."""
    norms = np.linalg.norm(J, axis=0) * (np.linalg.norm(r) or 1.0)
    return float(np.max(np.abs(J.T @ r) / np.where(norms > 0, norms, 1.0)))


def _gradient_descent(fun: Residuals, x0: np.ndarray) -> tuple[np.ndarray, int, bool, str]:
    """Steepest descent with Armijo backtracking, scaled by the Jacobian's column norms."""
    x, r = x0.copy(), fun(x0)
    cost, nfev, rate = 0.5 * r @ r, 1, 1.0
    for iteration in range(GD_MAX_ITERATIONS):
        J = jacobian(fun, x, r)
        nfev += len(x)
        scale = np.sum(J * J, axis=0) + 1e-300
        gradient = J.T @ r
        direction = -gradient / scale
        slope = gradient @ direction
        while True:
            trial = x + rate * direction
            r_trial = fun(trial)
            nfev += 1
            cost_trial = 0.5 * r_trial @ r_trial
            if cost_trial <= cost + 1e-4 * rate * slope:
                break
            rate *= 0.5
            if rate < 1e-20:
                return x, nfev, True, f"no descent along the gradient after {iteration} iterations"
        improvement = cost - cost_trial
        x, r, cost = trial, r_trial, cost_trial
        if improvement <= TOLERANCE * cost:
            cosine = _optimality(jacobian(fun, x, r), r)
            stationary = cosine < GD_OPTIMALITY
            verdict = "stationary" if stationary else "not yet stationary: stalled in a valley"
            return x, nfev + len(x), stationary, (
                f"cost change below tolerance after {iteration + 1} iterations; gradient "
                f"cosine {cosine:.2g} ({verdict})"
            )
        rate = min(rate * 2.0, 1.0)
    return x, nfev, False, f"stopped at the budget of {GD_MAX_ITERATIONS} iterations"


def _pattern_search(fun: Residuals, x0: np.ndarray) -> tuple[np.ndarray, int, bool, str]:
    """Compass search: poll ±mesh along each coordinate, expand on success, halve on failure."""
    x, r = x0.copy(), fun(x0)
    cost, nfev, mesh = 0.5 * r @ r, 1, PATTERN_INITIAL_MESH
    n = len(x)
    directions = np.vstack([np.eye(n), -np.eye(n)])
    budget = PATTERN_EVALUATIONS_PER_PARAMETER * n
    while nfev < budget:
        if mesh < PATTERN_MIN_MESH:
            return x, nfev, True, f"mesh below {PATTERN_MIN_MESH:g} after {nfev} evaluations"
        for direction in directions:
            trial = x + mesh * direction
            r_trial = fun(trial)
            nfev += 1
            cost_trial = 0.5 * r_trial @ r_trial
            if cost_trial < cost:
                x, cost = trial, cost_trial
                mesh *= 2.0
                break
        else:
            mesh *= 0.5
    return x, nfev, False, f"stopped at the budget of {budget} evaluations"


def minimize(fun: Residuals, x0: np.ndarray, method: str = "trf") -> Minimum:
    """Minimize ``0.5·‖fun(x)‖²`` from ``x0`` with ``method``.

    Parameters
    ----------
    fun : callable
        Residuals of scaled parameters.
    x0 : ndarray
        Start.
    method : {'trf', 'lm', 'gd', 'pattern'}
        Trust-region reflective, Levenberg-Marquardt, gradient descent, pattern search.

    Raises
    ------
    InputError
        Unknown ``method``.
    """
    if method not in METHODS:
        raise InputError(f"method must be one of {', '.join(METHODS)}, not {method!r}")
    started = time.perf_counter()
    if method in ("trf", "lm"):
        x, nfev, converged, message = _least_squares(fun, x0, method)
    elif method == "gd":
        x, nfev, converged, message = _gradient_descent(fun, x0)
    else:
        x, nfev, converged, message = _pattern_search(fun, x0)
    elapsed = time.perf_counter() - started
    r = fun(x)
    return Minimum(x, r, jacobian(fun, x, r), nfev, converged, elapsed, message)
