"""Voltage-step identification (seed 001) on simulated runs of the seed's motor."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_allclose

from stand.errors import InputError, NotExcitedError
from stand.physics.effects import CoulombFriction, Effects
from stand.physics.plant import MotorPlant
from stand.physics.simulate import simulate_motor
from stand.profiles import load_motor
from stand.runfile import Run, check_columns
from stand.stepid import PARAM_NAMES, identify_steps
from stand.stepid.simulated import simulate_step_run, step_voltages

#: Seed 001 §3: R Ω, L H, K N·m/A, J kg·m², Kf N·m·s/rad.
SEED = dict(zip(PARAM_NAMES, (2.937, 0.040437, 0.6571, 0.064744, 0.04867), strict=True))
#: The transfer function the seed's parameters give: 251.0 / (s² + 73.38 s + 219.5).
SEED_TF = np.array([250.988, 73.3832, 219.5235])


def tf_of(result) -> np.ndarray:
    return np.array(result.transfer_function["num"] + result.transfer_function["den"][1:])


def tf_std_of(result) -> np.ndarray:
    return np.array(result.transfer_function_std["num"] + result.transfer_function_std["den"][1:])


@pytest.fixture(scope="module")
def step_run() -> Run:
    """One 8.5 V step of the seed's motor, 5 s at 1 kHz, tacho 0.05 rad/s, current 5 mA noise."""
    return simulate_step_run("ms150_dcm150f", [8.5], 5.0, seed=11)


@pytest.fixture(scope="module")
def speed_only(step_run: Run) -> Run:
    return check_columns({k: step_run[k] for k in ("time_s", "voltage_V", "velocity_rad_s")},
                         "step", "speed only")


def test_with_current_the_transfer_function_is_within_1_percent(step_run: Run) -> None:
    result = identify_steps([step_run])
    assert result.used_current and result.converged
    assert_allclose(tf_of(result), SEED_TF, rtol=0.01)
    assert result.transfer_function["den"][0] == 1.0


def test_with_current_all_five_parameters_are_within_3_percent(step_run: Run) -> None:
    result = identify_steps([step_run])
    assert result.identifiable == list(PARAM_NAMES)
    for name in PARAM_NAMES:
        assert result.params[name] == pytest.approx(SEED[name], rel=0.03), name
        # The reported uncertainty covers the error (4 σ: a test, not a coin toss).
        assert abs(result.params[name] - SEED[name]) < 4 * result.std[name] + 1e-4 * SEED[name]
        low, high = result.interval95[name]
        assert low < result.params[name] < high
    assert result.fit_percent > 95.0
    assert result.whiteness["velocity_rad_s"].passed and result.whiteness["current_A"].passed


def test_speed_only_identifies_the_transfer_function_and_no_parameter(speed_only: Run) -> None:
    result = identify_steps([speed_only])
    assert not result.used_current
    assert result.identifiable == []
    assert all(result.params[name] is None for name in PARAM_NAMES)
    # One step from speed alone fixes the coefficients to about 1.4 % (1 σ): the fast
    # pole shows only in the first 50 ms. Check the error against the reported σ.
    error = tf_of(result) - SEED_TF
    assert np.all(np.abs(error) < 4 * tf_std_of(result))
    assert np.all(tf_std_of(result) / SEED_TF < 0.03)
    assert "not determined" in result.message


@pytest.fixture(scope="module")
def pulse_train() -> Run:
    """Five 8.5 V pulses, speed only: ten transitions show the fast pole ten times."""
    return simulate_step_run("ms150_dcm150f", [8.5, 0.0] * 5, 15.0, seed=12, with_current=False)


def test_speed_only_pulse_train_narrows_the_transfer_function(pulse_train: Run) -> None:
    result = identify_steps([pulse_train])
    # σ falls about as 1/√(transitions): 1.4 % for one step, about 0.45 % for ten.
    assert np.all(tf_std_of(result) / SEED_TF < 0.006)
    # The 0.1 ms sub-steps of the physics shift a noise-free fit by about 0.4 % along
    # the one ill-determined direction, hence 4 σ plus 0.5 %.
    assert np.all(np.abs(tf_of(result) - SEED_TF) < 4 * tf_std_of(result) + 0.005 * SEED_TF)


def test_one_known_value_is_not_enough_from_speed_alone(speed_only: Run) -> None:
    # Speed gives 3 equations for 5 unknowns: R alone leaves a one-parameter family.
    result = identify_steps([speed_only], known={"R": SEED["R"]})
    assert result.params["R"] == SEED["R"] and result.std["R"] == 0.0
    assert result.identifiable == []
    assert all(result.params[name] is None for name in ("L", "K", "J", "Kf"))


@pytest.mark.parametrize("known", [("R", "K"), ("R", "J"), ("J", "Kf"), ("K", "Kf")])
def test_two_known_values_from_speed_alone_give_the_rest_within_3_percent(
        pulse_train: Run, known: tuple[str, str]) -> None:
    result = identify_steps([pulse_train], known={name: SEED[name] for name in known})
    rest = [name for name in PARAM_NAMES if name not in known]
    assert sorted(result.identifiable) == sorted(rest)
    for name in known:
        assert result.params[name] == SEED[name]
    for name in rest:
        assert result.params[name] == pytest.approx(SEED[name], rel=0.03), name


@pytest.mark.parametrize("known", [("R", "K"), ("R", "L"), ("L", "J")])
def test_errors_from_one_step_stay_within_the_reported_uncertainty(
        speed_only: Run, known: tuple[str, str]) -> None:
    result = identify_steps([speed_only], known={name: SEED[name] for name in known})
    for name in result.identifiable:
        assert abs(result.params[name] - SEED[name]) < 4 * result.std[name], name


def test_R_and_L_leave_friction_ill_determined_from_one_step(speed_only: Run) -> None:
    # Kf/J = a1 − R/L is a small difference of two large numbers (0.75 of 73.4 1/s):
    # the answer must say so through its standard error, not hide it.
    result = identify_steps([speed_only], known={"R": SEED["R"], "L": SEED["L"]})
    assert result.std["Kf"] > 0.3 * SEED["Kf"]


def test_swapped_poles_are_reported_as_an_alternative(speed_only: Run) -> None:
    result = identify_steps([speed_only], known={"R": SEED["R"], "K": SEED["K"]})
    # Electrical and mechanical poles swapped: L about 4 H fits the speed equally.
    assert len(result.alternatives) == 1
    assert result.alternatives[0]["L"] > 10 * SEED["L"]
    assert result.params["L"] == pytest.approx(SEED["L"], rel=0.03)


def test_several_runs_are_identified_jointly() -> None:
    runs = [simulate_step_run("ms150_dcm150f", [level], 3.0, seed=20 + k)
            for k, level in enumerate((4.0, 8.5))]
    result = identify_steps(runs)
    assert result.runs == 2 and result.samples == 6000
    for name in PARAM_NAMES:
        assert result.params[name] == pytest.approx(SEED[name], rel=0.03), name


def test_unmodelled_coulomb_friction_fails_the_whiteness_test() -> None:
    spec = load_motor("ms150_dcm150f")
    plant = MotorPlant(spec.motor_params(), spec.drive_params("voltage"), spec.sensor_params(),
                       Effects(coulomb_friction=CoulombFriction(Tc=0.1)), seed=13)
    run = simulate_motor(plant, "voltage", step_voltages(5000, [8.5, 0.0, 8.5]), 1e-3)
    step = check_columns({k: run[k] for k in ("time_s", "voltage_V", "velocity_rad_s")},
                         "step", "friction")
    result = identify_steps([step])
    assert not result.whiteness["velocity_rad_s"].passed


@pytest.mark.parametrize("known, match", [
    ({"X": 1.0}, "unknown parameter"), ({"R": -1.0}, "> 0"), ({"L": float("nan")}, "> 0"),
])
def test_bad_known_values_are_refused(speed_only: Run, known: dict, match: str) -> None:
    with pytest.raises(InputError, match=match):
        identify_steps([speed_only], known=known)


def test_bad_method_is_refused(speed_only: Run) -> None:
    with pytest.raises(InputError, match="method must be one of"):
        identify_steps([speed_only], method="newton")


def test_constant_voltage_is_not_excited() -> None:
    t = np.arange(200) * 1e-3
    run = check_columns({"time_s": t, "voltage_V": np.full(200, 5.0),
                         "velocity_rad_s": np.full(200, 2.0)}, "step", "flat")
    with pytest.raises(NotExcitedError, match="voltage never changes"):
        identify_steps([run])


def test_reversed_tacho_is_named(speed_only: Run) -> None:
    flipped = check_columns({"time_s": speed_only.time_s, "voltage_V": speed_only["voltage_V"],
                             "velocity_rad_s": -speed_only["velocity_rad_s"]}, "step", "flipped")
    with pytest.raises(InputError, match="wired reversed"):
        identify_steps([flipped])


def test_a_file_that_starts_at_the_step_instant(step_run: Run) -> None:
    # Many recordings start when the step is applied: first voltage 8.5 V, motor at rest.
    first = int(np.argmax(step_run["voltage_V"] > 0))
    cut = check_columns({k: v[first:] for k, v in step_run.columns.items()}, "step", "cut")
    assert cut["voltage_V"][0] == 8.5 and abs(cut["velocity_rad_s"][0]) < 0.5
    result = identify_steps([cut])
    assert abs(result.initial_voltage_V[0]) < 0.05  # it started from rest, not at 8.5 V
    for name in PARAM_NAMES:
        assert result.params[name] == pytest.approx(SEED[name], rel=0.03), name


def test_a_run_that_starts_in_steady_state_at_its_first_voltage() -> None:
    run = simulate_step_run("ms150_dcm150f", [4.0, 8.5], 8.0, seed=14)
    settled = int(np.argmax(run.time_s > 3.0))  # 2.6 s at 4 V: eight mechanical time constants
    cut = check_columns({k: v[settled:] for k, v in run.columns.items()}, "step", "settled")
    result = identify_steps([cut])
    assert result.initial_voltage_V[0] == pytest.approx(4.0, rel=0.01)
    for name in PARAM_NAMES:
        assert result.params[name] == pytest.approx(SEED[name], rel=0.03), name
