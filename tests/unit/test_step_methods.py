"""The four minimizers of seed 001's comparison, on the same step data."""

from __future__ import annotations

import numpy as np
import pytest

from stand.errors import InputError
from stand.stepid.search import METHODS, minimize


def rosenbrock(x: np.ndarray) -> np.ndarray:
    return np.array([10.0 * (x[1] - x[0] ** 2), 1.0 - x[0]])


@pytest.mark.parametrize("method", METHODS)
def test_every_method_reaches_the_minimum_of_an_easy_problem(method: str) -> None:
    # A well-conditioned bowl: every method must get there.
    result = minimize(lambda x: np.array([x[0] - 1.0, 2.0 * (x[1] + 0.5)]),
                      np.array([0.3, 0.4]), method)
    assert np.allclose(result.x, [1.0, -0.5], atol=1e-4)
    assert result.converged


def test_gradient_descent_says_when_it_stalls_in_a_valley() -> None:
    result = minimize(rosenbrock, np.array([-1.2, 1.0]), "gd")
    # Rosenbrock's curved valley: either it gets there or it must not claim convergence.
    assert result.converged == bool(np.allclose(result.x, [1.0, 1.0], atol=1e-2))


def test_unknown_method_is_refused() -> None:
    with pytest.raises(InputError, match="'trf', 'lm', 'gd', 'pattern'|trf, lm, gd, pattern"):
        minimize(rosenbrock, np.zeros(2), "simplex")

# Gradient descent and pattern search on real step data take seconds each: they are
# compared in tests/bench/bench_step_methods.py, which prints seed 001's table.
