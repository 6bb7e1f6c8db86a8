"""Dry friction along the speed's path within a step (stand.diagnosis.dry_friction): one
step of the simulation against the same shaft in fine steps, and the fit's friction
columns as means over a sample period."""

from __future__ import annotations

import math

import numpy as np
import pytest
from numpy.testing import assert_allclose

from stand.diagnosis.dry_friction import friction_step, period_mean

#: A Stribeck friction per inertia (rad/s²) whose hump (ωs, rad/s) is narrower than the
#: speed change of one step (5000 rad/s² over 2.2 ms is 11 rad/s), and a Coulomb one.
FRICTIONS = [(324.0, 356.0, 7.0), (324.0, 0.0, 1.0)]
STEP_S = 2.2e-3


def _fine(omega: float, accel: float, coulomb: float, excess: float, ws: float,
          steps: int = 4000) -> tuple[float, float]:
    """Speed at the end of one step and the angle it turns (rad), in ``steps`` sub-steps."""
    w, angle, h = np.array([omega]), 0.0, STEP_S / steps
    for _ in range(steps):
        w, mean = friction_step(w, w + h * accel, h, coulomb, excess, ws)
        angle += h * float(mean[0])
    return float(w[0]), angle


@pytest.mark.parametrize(("coulomb", "excess", "ws"), FRICTIONS)
@pytest.mark.parametrize("accel", [5000.0, 500.0, -300.0, 2000.0])
def test_one_step_moves_as_the_shaft_does_in_fine_steps(coulomb: float, excess: float,
                                                        ws: float, accel: float) -> None:
    """Through a zero crossing, sticking (the push 500 rad/s² is below the static level
    680 rad/s²), breakaway from rest and across a hump narrower than the step: the one
    step ends within 2 % of the step's speed change of the fine steps, and turns the
    same angle within 2 % of the step's travel. (A step that holds the friction of its
    start can miss by the step's whole static friction impulse, 680 rad/s² × 2.2 ms =
    1.5 rad/s, 9 % of the 5000 rad/s² step's change.)"""
    start = np.array([-11.6, -5.0, -1.0, 0.0, 3.0, 20.0])
    new, mean = friction_step(start, start + STEP_S * accel, STEP_S, coulomb, excess, ws)
    for k, omega in enumerate(start):
        end, angle = _fine(float(omega), accel, coulomb, excess, ws)
        change = STEP_S * (abs(accel) + coulomb + excess)
        assert abs(new[k] - end) < 0.02 * change, (omega, new[k], end)
        travel = STEP_S * (abs(omega) + change)
        assert abs(STEP_S * mean[k] - angle) < 0.02 * travel, (omega, mean[k] * STEP_S, angle)


def test_a_shaft_below_the_static_level_sticks_and_stays() -> None:
    new, mean = friction_step(np.array([-1.0, 0.0]), np.array([-1.0, 0.0]) + STEP_S * 500.0,
                              STEP_S, 324.0, 356.0, 7.0)
    assert new[0] == 0.0 and new[1] == 0.0
    assert mean[1] == 0.0 and mean[0] < 0.0


def test_period_mean_of_the_sign_across_a_crossing_holds_both_signs() -> None:
    # from −1 to 3 rad/s: a quarter of the period at negative speed
    assert_allclose(period_mean(np.array([-1.0, 3.0]))[0], 0.5, atol=1e-12)
    assert_allclose(period_mean(np.array([2.0, 4.0]))[0], 1.0, atol=1e-12)
    assert period_mean(np.array([0.0, 0.0]))[0] == 0.0


@pytest.mark.parametrize(("start", "end"), [(-3.0, 5.0), (0.5, 9.0), (-8.0, -7.5), (2.0, 2.0)])
def test_period_mean_of_the_hump_is_the_mean_along_the_path(start: float, end: float) -> None:
    ws = 2.5
    path = np.linspace(start, end, 200_001)
    expected = np.mean(np.sign(path) * np.exp(-((path / ws) ** 2)))
    assert_allclose(period_mean(np.array([start, end]), ws)[0], expected, atol=1e-4)
    assert math.isfinite(period_mean(np.array([start, end]), ws)[1])
