"""The simulator against physics worked by hand (seed 000 eqs. 1-2, 18; seed 001 eq. 1)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from numpy.testing import assert_allclose

from stand.physics.effects import Effects
from stand.physics.parts import DriveParams, MotorParams, ReducerParams, SensorParams
from stand.physics.plant import MotorPlant
from stand.physics.reducer import ReducerPlant
from stand.physics.simulate import simulate_motor

MOTOR = MotorParams(R=1.9, L=1.5e-3, Kt=0.0527, J=1.2e-5, D=2e-6)
IDEAL = SensorParams(encoder_lines=0)


def test_steady_speed_in_voltage_mode() -> None:
    # L·i' = V − R·i − K·ω and J·ω' = K·i − D·ω at rest give ω = K·V / (R·D + K²).
    V = 12.0
    plant = MotorPlant(MOTOR, DriveParams(mode="voltage"), IDEAL)
    tau = MOTOR.J * MOTOR.R / (MOTOR.Kt**2 + MOTOR.R * MOTOR.D)   # ≈ 8 ms
    run = simulate_motor(plant, "voltage", np.full(int(30 * tau / 1e-3), V), 1e-3)
    expected = MOTOR.Kt * V / (MOTOR.R * MOTOR.D + MOTOR.Kt**2)
    # After 30 time constants the transient is below e^-30; the integrator is exact for the
    # current and first order in 1e-4 s sub-steps for the speed (relative error ≪ 1e-6).
    assert_allclose(run.meta["true_velocity_rad_s"][-1], expected, rtol=1e-6)
    assert_allclose(run.meta["true_current_A"][-1], MOTOR.D * expected / MOTOR.Kt, rtol=1e-4)


@pytest.mark.parametrize("fraction, moves", [(0.9, False), (1.1, True)])
def test_coulomb_friction_holds_the_shaft_below_breakaway(fraction: float, moves: bool) -> None:
    Tc = 0.012
    effects = Effects.from_mapping({"coulomb_friction": {"Tc": Tc}})
    plant = MotorPlant(MOTOR, DriveParams(mode="current"), IDEAL, effects)
    i = fraction * Tc / MOTOR.Kt                  # torque 0.9 or 1.1 times the breakaway
    run = simulate_motor(plant, "current", np.full(200, i), 1e-3)
    if moves:
        assert plant.omega > 0 and plant.theta > 0
    else:
        assert plant.omega == 0.0 and plant.theta == 0.0
        assert np.all(run["position_rad"] == 0.0)


def test_encoder_quantization_step_is_2pi_over_10000() -> None:
    plant = MotorPlant(MOTOR, DriveParams(mode="voltage"), SensorParams(encoder_lines=2500))
    run = simulate_motor(plant, "voltage", np.full(400, 0.3), 1e-3)   # slow: many counts
    step = 2 * math.pi / 10000
    counts = run["position_rad"] / step
    assert_allclose(counts, np.round(counts), atol=1e-9)               # whole counts only
    assert np.min(np.diff(np.unique(run["position_rad"]))) == pytest.approx(step, rel=1e-9)
    truth = np.cumsum(np.concatenate([[0.0], run.meta["true_velocity_rad_s"][:-1]])) * 1e-3
    assert np.max(np.abs(run["position_rad"] - truth)) < step + 0.05   # floor of the angle


def test_current_offset_and_delay_appear_in_the_measured_current() -> None:
    i0, k = 0.05, 3
    effects = Effects.from_mapping({"current_offset": {"i0": i0}, "delay": {"k": k}})
    plant = MotorPlant(MOTOR, DriveParams(mode="current"), IDEAL, effects)
    command = np.where(np.arange(100) >= 20, 0.5, 0.2)
    run = simulate_motor(plant, "current", command, 1e-3)
    true_i = run.meta["true_current_A"]
    # measured[n] = true[n − k] + i0 (the first k samples repeat the first true value).
    assert_allclose(run["current_A"][k:], true_i[:-k] + i0, atol=1e-12)
    # The 0.2 → 0.5 A step shows k samples late in the measurement.
    first_true = int(np.argmax(true_i > 0.35))
    assert int(np.argmax(run["current_A"] - i0 > 0.35)) == first_true + k


def test_reducer_steady_state_obeys_eq_18() -> None:
    # Input motor in speed mode, output motor in current mode: two steady loads give
    # η = K_out·Δi_out / (n·K_in·Δi_in) exactly (seed 000 eq. 18).
    n, eta = 11.0, 0.8
    currents = []
    for load in (-0.1, -0.6):
        plant = ReducerPlant(MOTOR, MOTOR, ReducerParams(ratio=n, efficiency=eta),
                             DriveParams(mode="speed", speed_kp=0.04, speed_ki=1.5),
                             DriveParams(mode="current"), IDEAL)
        plant.command("speed", 150.0, 0)
        plant.command("current", load, 1)
        for _ in range(1500):
            plant.advance(1e-3)
        assert_allclose(plant.omega[0], 150.0, rtol=1e-4)      # the speed loop has settled
        assert_allclose(plant.omega[1], 150.0 / n, rtol=1e-3)
        currents.append((plant.armatures[0].i, plant.armatures[1].i))
    d_in = currents[1][0] - currents[0][0]
    d_out = currents[1][1] - currents[0][1]
    assert_allclose(abs(d_out) / (n * abs(d_in)), eta, rtol=1e-3)
