"""The seed 001 model: coefficients, the two-parameter family, and the exact response."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_allclose

from stand.errors import InputError
from stand.stepid.model import coefficients, family, respond, step_data
from stand.stepid.simulated import simulate_step_run

#: Seed 001 §3: R Ω, L H, K N·m/A, J kg·m², Kf N·m·s/rad.
SEED_PARAMS = np.array([2.937, 0.040437, 0.6571, 0.064744, 0.04867])


def test_seed_parameters_give_the_seed_transfer_function() -> None:
    # The seed prints 251 / (s² + 73.38 s + 219.5), rounded to 4 significant digits.
    assert_allclose(coefficients(SEED_PARAMS, False), [251.0, 73.38, 219.5], rtol=5e-4)


def test_current_coefficients_are_one_over_L_and_Kf_over_LJ() -> None:
    R, L, K, J, Kf = SEED_PARAMS
    assert_allclose(coefficients(SEED_PARAMS, True)[3:], [1 / L, Kf / (L * J)], rtol=1e-12)


def test_family_reproduces_every_motor_with_the_same_speed_transfer_function() -> None:
    R, L, K, J, Kf = SEED_PARAMS
    b0, a1, a0 = coefficients(SEED_PARAMS, False)
    assert_allclose(family(R / L, 1 / L, b0, a1, a0), SEED_PARAMS, rtol=1e-12)
    # Any other (u, x) on the family gives another motor with the same speed response.
    other = family(0.5 * R / L, 3.0 / L, b0, a1, a0)
    assert_allclose(coefficients(other, False), [b0, a1, a0], rtol=1e-12)
    assert not np.allclose(other, SEED_PARAMS, rtol=0.1)


def test_response_matches_the_physics_simulation_without_noise() -> None:
    run = simulate_step_run("ms150_dcm150f", [8.5, 3.0], 3.0, seed=0)
    data = step_data([run])[0]
    speed, current = respond(coefficients(SEED_PARAMS, True), data, "preceding")
    true_speed = run.meta["true_velocity_rad_s"]
    # The physics integrates the shaft with 0.1 ms semi-implicit Euler sub-steps; the
    # model is exact, so they agree to the simulator's own discretization error.
    assert np.max(np.abs(speed - true_speed)) < 2e-3 * np.max(np.abs(true_speed))
    assert np.max(np.abs(current - run.meta["true_current_A"])) < 5e-3 * 8.5 / SEED_PARAMS[0]
    # The wrong hold convention is off by one sample: clearly worse.
    late, _ = respond(coefficients(SEED_PARAMS, True), data, "following")
    assert np.max(np.abs(late - true_speed)) > 5 * np.max(np.abs(speed - true_speed))


def test_unknown_hold_is_refused() -> None:
    data = step_data([simulate_step_run("ms150_dcm150f", [8.5], 0.1, seed=0)])[0]
    with pytest.raises(InputError, match="hold must be one of"):
        respond(coefficients(SEED_PARAMS, False), data, "middle")
