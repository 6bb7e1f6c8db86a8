"""The current between samples under a PI speed loop, from the loop law (issue 19)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from stand.excitation import excitation
from stand.ident.identify import identify_run
from stand.ident.speed_loop import TARGET_COLUMN, joint_speed_loops, speed_loop
from stand.physics.effects import Effects
from stand.physics.parts import DriveParams, MotorParams, SensorParams
from stand.physics.plant import MotorPlant
from stand.physics.simulate import simulate_motor
from stand.runfile import Run

MOTOR = MotorParams(R=2.0, L=1e-3, Kt=0.05, J=2e-5, D=4e-5)
KT_OVER_J = MOTOR.Kt / MOTOR.J


def speed_run(loop_hz: float, current_limit_A: float = 50.0, dt: float = 3e-3,
              seed: int = 3, amplitude: float = 60.0) -> tuple[Run, DriveParams]:
    """Reversing PRBS speed steps of ± ``amplitude`` rad/s under a PI loop of ``loop_hz``."""
    kp = 2 * math.pi * loop_hz * MOTOR.J / MOTOR.Kt
    drive = DriveParams(mode="speed", supply_V=48.0, current_limit_A=current_limit_A,
                        speed_kp=kp, speed_ki=kp * 2 * math.pi * loop_hz / 5)
    plant = MotorPlant(MOTOR, drive, SensorParams(encoder_lines=2000, current_noise_A=0.005),
                       Effects(), seed=seed)
    command = excitation("prbs", int(6.0 / dt), dt, 0.0, amplitude, int(0.2 / dt), seed=seed)
    return simulate_motor(plant, "speed", command, dt), drive


def test_loop_gains_are_found_from_the_target() -> None:
    # The law i = kp·(r − ω) + I holds at the samples; the fitted gain is within 1 % of
    # the drive's (the current loop's 0.2 ms lag is the main error, 2π·f·τ ≈ 0.6 %).
    run, drive = speed_run(5.0)
    loop = speed_loop(run)
    assert loop is not None and loop.holds
    assert abs(loop.kp / drive.speed_kp - 1) < 0.01
    assert loop.residual_ratio < 1.1


def test_runs_of_one_drive_share_its_gains_and_runs_of_two_do_not() -> None:
    # Two runs of the 10 Hz drive: one kp, ki and lag for both, each run's constant its
    # own, and each run's law still within its noise. A 10 Hz and a 20 Hz drive: the
    # shared gains would explain neither run, and no joint law is given.
    first, drive = speed_run(10.0, seed=3)
    second = speed_run(10.0, seed=4)[0]
    alone = [speed_loop(run) for run in (first, second, speed_run(20.0, seed=4)[0])]
    assert all(loop is not None for loop in alone)
    loops = joint_speed_loops(alone[:2])  # type: ignore[arg-type]
    assert loops is not None
    assert loops[0].kp == loops[1].kp and loops[0].ki == loops[1].ki
    assert loops[0].lag_s == loops[1].lag_s
    assert all(loop.runs == 2 and loop.residual_ratio < 1.1 for loop in loops)
    assert abs(loops[0].kp / drive.speed_kp - 1) < 0.01
    assert joint_speed_loops([alone[0], alone[2]]) is None  # type: ignore[list-item]


def test_reconstructed_current_removes_the_loop_bias() -> None:
    # At 5 Hz and 3 ms the sampled current misses about π·f·Δt ≈ 4.7 % of the current
    # that accelerates the rotor: without the target Kt/J is high by more than 2 %, with
    # it within 1 %. (Its interval does not yet hold the truth: docs/results/ident.md.)
    run, _ = speed_run(5.0)
    plain = Run({k: v for k, v in run.columns.items() if k != TARGET_COLUMN}, "plain")
    assert identify_run(plain).Kt_over_J / KT_OVER_J - 1 > 0.02
    r = identify_run(run)
    assert abs(r.Kt_over_J / KT_OVER_J - 1) < 0.01


@pytest.mark.parametrize("limit_A, loop_hz", [(1.0, 10.0), (1.5, 20.0), (2.0, 20.0)])
def test_a_loop_at_its_current_limit_is_reconstructed_with_its_integrator_reset(
        limit_A: float, loop_hz: float) -> None:
    # Each reversal's kick (kp·120 rad/s, 3-6 A) holds the current at a limit of 1-2 A
    # for 7-15 samples, and the drive clamps its integrator there. The law with one
    # integrator constant missed the current by 2-6 times its noise and was refused, and
    # the sampled current gave Kt/J +2.1 %, +5.5 % and +4.8 % (f662255); with the
    # integrator fitted anew after each stretch, kp is within 2 % and Kt/J within 0.5 %
    # (-0.1 … -0.4 %), inside its interval.
    run, drive = speed_run(loop_hz, current_limit_A=limit_A)
    loop = speed_loop(run)
    assert loop is not None and loop.holds and loop.resets >= 10
    assert abs(loop.kp / drive.speed_kp - 1) < 0.02
    r = identify_run(run)
    assert abs(r.Kt_over_J / KT_OVER_J - 1) < 0.005
    assert r.Kt_over_J_ci95[0] <= KT_OVER_J <= r.Kt_over_J_ci95[1]


@pytest.mark.parametrize("late", [1, 2])
def test_the_delay_of_a_loop_at_its_limit_is_read_from_its_kicks(late: int) -> None:
    # The same loop with its current samples `late` samples behind the encoder. Its kicks
    # sit at the limit, outside the law's fit, and the fit alone finds about as good a
    # fit at any delay with kp a seventh lower per sample (-47 % at two samples late on
    # the 2 A, 20 Hz loop above); the kicks' onset gives the delay.
    run, drive = speed_run(20.0, current_limit_A=1.5)
    current = np.asarray(run["current_A"])
    columns = {**run.columns,
               "current_A": np.concatenate([np.repeat(current[:1], late), current[:-late]])}
    loop = speed_loop(Run(columns, "late"))
    assert loop is not None and loop.holds and loop.delay == late
    assert abs(loop.kp / drive.speed_kp - 1) < 0.02


def _true_period_current(run: Run) -> np.ndarray:
    """The plant's mean current over each period, from its true speed (no effects):
    ``(J·Δω/Δt + D·ω̄)/Kt``."""
    omega, dt = run.meta["true_velocity_rad_s"], run.dt_s
    mean_speed = np.diff(run["position_rad"]) / dt
    return (MOTOR.J * np.diff(omega) / dt + MOTOR.D * mean_speed) / MOTOR.Kt


def test_the_period_current_carries_the_drives_lag() -> None:
    # The drive follows the law's command with its current loop's 0.2 ms lag, a delay of
    # 7 % of a 3 ms period: each kick (kp·120 rad/s ≈ 6 A at 20 Hz) puts that share of
    # itself into the period after. The law's mean command misses the true period
    # current by about 0.3 A at each kick; delayed by the fitted lag (0.19 ms), by a
    # tenth of that, and by the drive's own, by a hundredth.
    run, drive = speed_run(20.0, seed=1)
    loop = speed_loop(run)
    assert loop is not None and loop.holds
    assert abs(loop.lag_s / drive.current_tau_s - 1) < 0.1
    truth = _true_period_current(run)
    kicks = np.flatnonzero(np.diff(run[TARGET_COLUMN]) != 0) + 1
    kicks = kicks[kicks < len(truth)]

    def miss(period: np.ndarray) -> float:
        return float(np.sqrt(np.mean((period[:-1] - truth)[kicks] ** 2)))

    without = miss(loop.relagged(0.0, run.dt_s).period_current)
    assert without > 0.05 * drive.speed_kp * 120.0
    assert miss(loop.period_current) < 0.1 * without
    assert miss(loop.relagged(drive.current_tau_s, run.dt_s).period_current) < 0.02 * without


def test_target_column_is_optional() -> None:
    run, _ = speed_run(5.0)
    assert speed_loop(Run({k: v for k, v in run.columns.items() if k != TARGET_COLUMN})) is None
    assert np.all(np.abs(run[TARGET_COLUMN]) == 60.0)


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_the_noise_compensation_is_sized_on_the_model_it_compensates(seed: int) -> None:
    # An 18 Hz loop sampled every 4.9 ms with Stribeck friction: bc's uncertainty adds
    # the shift of its noise compensation against least squares. Least squares fitted
    # with the current's timing column (which the speed-loop fit leaves out) shifted by
    # the model's difference as well, inflated bc's variance past iv's, and iv read
    # Kt/J +6.3 … +8.0 % on these runs (bc with the shift of the same model: +1.6 … +2.7 %).
    motor = MotorParams(R=4.7, L=2e-3, Kt=0.09, J=2e-4, D=6e-4)
    kp = 2 * math.pi * 18.0 * motor.J / motor.Kt
    drive = DriveParams(mode="speed", supply_V=48.0, current_limit_A=36.0, speed_kp=kp,
                        speed_ki=kp * 2 * math.pi * 18.0 / 5)
    friction = {"stribeck_friction": {"Tc": 0.007, "Ts": 0.0145, "ws": 10.5}}
    plant = MotorPlant(motor, drive, SensorParams(encoder_lines=4096, current_noise_A=0.01),
                       Effects.from_mapping(friction), seed=seed)
    dt = 4.9e-3
    run = simulate_motor(plant, "speed",
                         excitation("prbs", int(6 / dt), dt, 0.0, 125.0, 58, seed=seed), dt)
    r = identify_run(run)
    assert abs(r.Kt_over_J / (motor.Kt / motor.J) - 1) < 0.04
