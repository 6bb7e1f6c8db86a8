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


def test_current_step_moves_the_shaft_as_the_continuous_system() -> None:
    # A held current step through the first-order loop, i = I·(1 − e^(−t/τ)), on a shaft
    # without damping: ω = (Kt·I/J)·(t − τ·(1 − e^(−t/τ))) and
    # θ = (Kt·I/J)·(t²/2 − τ·t + τ²·(1 − e^(−t/τ))). Holding the current at a sub-step's
    # end value, or stepping the angle with the new speed, is off by ~h/2 in time
    # (relative errors ~1e-3 here); the exact mean current and the Verlet angle are not.
    motor = MotorParams(R=1.9, L=1.5e-3, Kt=0.0527, J=1.2e-5)
    drive = DriveParams(mode="current", supply_V=1e3, current_limit_A=10.0, current_tau_s=2e-4)
    plant = MotorPlant(motor, drive, IDEAL)
    I, dt = 0.5, 2e-3
    run = simulate_motor(plant, "current", np.full(20, I), dt)
    t = run["time_s"]
    tau, a = drive.current_tau_s, motor.Kt * I / motor.J
    decay = 1.0 - np.exp(-t / tau)
    assert_allclose(run["current_A"], I * decay, rtol=1e-12, atol=1e-14)
    assert_allclose(run.meta["true_velocity_rad_s"], a * (t - tau * decay), rtol=1e-9, atol=1e-12)
    assert_allclose(run["position_rad"], a * (t**2 / 2 - tau * t + tau**2 * decay),
                    rtol=1e-9, atol=1e-14)


def test_coulomb_friction_stops_the_shaft_where_the_speed_reaches_zero() -> None:
    # Spinning at ω0 with no current, the shaft decelerates at Tc/J and stops after
    # J·ω0/Tc s, having turned J·ω0²/(2·Tc) rad. The stop falls inside a sub-step; it is
    # located there rather than the speed zeroed for the whole sub-step.
    motor = MotorParams(R=1.9, L=1.5e-3, Kt=0.0527, J=1.2e-5)
    Tc = 0.011
    plant = MotorPlant(motor, DriveParams(mode="current"), IDEAL,
                       Effects.from_mapping({"coulomb_friction": {"Tc": Tc}}))
    omega0 = 100.0 + math.pi  # a stop between sub-step ends
    plant.omega = omega0
    run = simulate_motor(plant, "current", np.zeros(300), 1e-3)
    t_stop = motor.J * omega0 / Tc
    moving = run["time_s"] < t_stop
    t = run["time_s"][moving]
    assert_allclose(run["position_rad"][moving], omega0 * t - Tc / motor.J * t**2 / 2, rtol=1e-12)
    assert_allclose(run["position_rad"][-1], motor.J * omega0**2 / (2 * Tc), rtol=1e-12)
    assert run.meta["true_velocity_rad_s"][-1] == 0.0


@pytest.mark.parametrize("mode, effects", [
    ("speed", {}),
    ("speed", {"stribeck_friction": {"Tc": 0.002, "Ts": 0.005, "ws": 3.0}}),
    ("current", {"cogging": {"Tcog": 0.003, "N": 12, "phi": 0.3},
                 "torque_ripple": {"eps": 0.1, "N": 6, "phi": 1.0}}),
    ("current", {"backlash": {"gap": 0.01, "J_load": 1e-5}}),
])
def test_default_substep_is_converged(mode: str, effects: dict, monkeypatch: pytest.MonkeyPatch) -> None:
    # The same run at the default sub-step (0.1 ms) and at 2 µs: the sampled angle within
    # 1e-4 of its range and the current within 1e-3 of its largest value (the former
    # semi-implicit Euler was off by 2-5e-4 and, in speed mode, 2-8e-3).
    import stand.physics.plant as plant_module

    level = 40.0 if mode == "speed" else 0.3
    kp = 2 * math.pi * 20.0 * MOTOR.J / MOTOR.Kt
    drive = DriveParams(mode=mode, supply_V=48.0, current_limit_A=10.0,  # type: ignore[arg-type]
                        speed_kp=kp, speed_ki=kp * 2 * math.pi * 4.0)
    command = np.repeat([level, -level, 0.5 * level, -level], 50)

    def sampled(substep_s: float) -> tuple[np.ndarray, np.ndarray]:
        monkeypatch.setattr(plant_module, "MAX_SUBSTEP_S", substep_s)
        plant = MotorPlant(MOTOR, drive, IDEAL, Effects.from_mapping(effects))
        run = simulate_motor(plant, mode, command, 2e-3)
        return run["position_rad"], run["current_A"]

    theta, i = sampled(1e-4)
    theta_ref, i_ref = sampled(2e-6)
    assert np.max(np.abs(theta - theta_ref)) <= 1e-4 * np.ptp(theta_ref)
    assert np.max(np.abs(i - i_ref)) <= 1e-3 * np.max(np.abs(i_ref))
