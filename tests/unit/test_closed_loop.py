"""Output-error refinement of speed-loop runs: the loop and the mechanics simulated
between samples and fitted to the sampled angle and current (issue 19)."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from scipy.linalg import expm

from stand.cli import main
from stand.diagnosis.model import ModelSpec
from stand.diagnosis.signals import quantization_step
from stand.errors import InputError
from stand.excitation import excitation
from stand.ident import loop_model
from stand.ident.closed_loop import effect_inputs, fit_closed_loop
from stand.ident.identify import SUPPLY_UNKNOWN, identify_run
from stand.ident.noise import noise_sigma
from stand.ident.speed_loop import TARGET_COLUMN, speed_loop
from stand.ident.supply import DriveSupply, motor_supply
from stand.physics.effects import Effects
from stand.physics.parts import DriveParams, MotorParams, SensorParams
from stand.physics.plant import MotorPlant
from stand.physics.simulate import simulate_motor
from stand.runfile import Run, write_run
from tests.unit.test_speed_loop import KT_OVER_J, MOTOR, speed_run


def test_fast_loop_gain_and_kt_over_j_are_separated_from_the_drive_lag() -> None:
    # A 20 Hz loop at 3 ms: the law's equation error puts the drive's 0.2 ms current-loop
    # lag into kp (high by 0.64 % on the continuous system: the former plant at 2 µs
    # sub-steps; 0.70 % on the plant at 0.1 ms; its former 0.1 ms Euler steps made it
    # 3.4 %). The simulated loop fits the lag itself: kp within 0.5 % of the drive's,
    # Kt/J within 0.2 % and inside its interval.
    run, drive = speed_run(20.0)
    loop = speed_loop(run)
    assert loop is not None and loop.holds
    assert loop.kp / drive.speed_kp - 1 > 0.005         # the bias the refinement removes
    theta = run["position_rad"]
    fit = fit_closed_loop(theta, run["current_A"], run[TARGET_COLUMN], run.dt_s, loop,
                          ModelSpec(), 0.97 * KT_OVER_J, MOTOR.D / MOTOR.J, np.zeros(0),
                          quantization_step(theta), noise_sigma(run["current_A"]))
    assert fit.holds
    assert abs(fit.kp / drive.speed_kp - 1) < 0.005
    assert abs(fit.Kt_over_J / KT_OVER_J - 1) < 0.002
    low, high = fit.interval(fit.Kt_over_J, fit.Kt_over_J_se)
    assert low <= KT_OVER_J <= high
    assert 0.0 < fit.lag_s < 1e-3


def test_identify_uses_the_refinement_under_a_speed_loop() -> None:
    run, _ = speed_run(20.0, seed=4)
    r = identify_run(run)
    low, high = r.Kt_over_J_ci95
    assert abs(r.Kt_over_J / KT_OVER_J - 1) < 0.005
    assert low <= KT_OVER_J <= high


def test_current_limit_between_samples_is_simulated() -> None:
    # The kicks reach a 3 A limit for a few ms after each reversal: the law's check
    # finds the limit in the samples, and the simulation clips the command there.
    run, drive = speed_run(20.0, current_limit_A=3.0)
    loop = speed_loop(run)
    assert loop is not None and loop.saturates
    theta = run["position_rad"]
    fit = fit_closed_loop(theta, run["current_A"], run[TARGET_COLUMN], run.dt_s, loop,
                          ModelSpec(), KT_OVER_J, MOTOR.D / MOTOR.J, np.zeros(0),
                          quantization_step(theta), noise_sigma(run["current_A"]))
    assert fit.holds
    assert abs(fit.Kt_over_J / KT_OVER_J - 1) < 0.005


def test_modal_step_matches_the_matrix_exponential() -> None:
    # every mode of the drive (the law, the command at its limit, the supply applied),
    # over a whole period and a part of one
    model = loop_model.LoopModel(np.zeros(10), np.zeros(10), np.zeros(10),
                                   np.ones((9, 1)), 3e-3, 0, 1.0, 1.0, True, True)
    a, d, kp, ki, tau, b = 1200.0, 12.0, 0.05, 0.7, 2e-4, 3.0
    volts, ohms, emf, limit = 2e4, 2e3, 50.0, 3.0
    p = np.array([a, d, kp, ki, np.log(tau), 0, 0, 0, 0, 0, 0, b,
                  np.log(volts), np.log(ohms), np.log(emf), limit])
    rows = {loop_model.LAW: ([0, -kp / tau, 1 / tau, -1 / tau], kp / tau, 0.0),
            loop_model.LIMIT_UP: ([0, 0, 0, -1 / tau], 0.0, limit / tau),
            loop_model.SUPPLY_DOWN: ([0, -emf, 0, -ohms], 0.0, -volts)}
    modes = model._modes(p)
    for mode, (row, from_target, constant) in rows.items():
        A = np.array([[0, 1, 0, 0], [0, -d, 0, a], [0, -ki, 0, 0], row], dtype=float)
        B = np.zeros((4, 3))
        B[2, 0], B[1, 1], B[3, 0], B[3, 2] = ki, b, from_target, constant
        for h in (3e-3, 1.3e-4):
            M = np.zeros((7, 7))
            M[:4, :4], M[:4, 4:] = A * h, B * h
            E = expm(M)
            Phi, Gamma = modes[mode].step(h)
            np.testing.assert_allclose(Phi, E[:4, :4], atol=1e-9)
            np.testing.assert_allclose(Gamma, E[:4, 4:], rtol=1e-9, atol=1e-12)


def supply_run(supply_V: float, loop_hz: float = 20.0) -> tuple[Run, DriveParams]:
    """``speed_run``'s reversals on a drive of ``supply_V``."""
    dt = 3e-3
    kp = 2 * math.pi * loop_hz * MOTOR.J / MOTOR.Kt
    drive = DriveParams(mode="speed", supply_V=supply_V, current_limit_A=50.0, speed_kp=kp,
                        speed_ki=kp * 2 * math.pi * loop_hz / 5)
    plant = MotorPlant(MOTOR, drive, SensorParams(encoder_lines=2000, current_noise_A=0.005),
                       Effects(), seed=3)
    command = excitation("prbs", int(6.0 / dt), dt, 0.0, 60.0, int(0.2 / dt), seed=3)
    return simulate_motor(plant, "speed", command, dt), drive


def test_a_loop_that_saturates_its_supply_is_simulated_when_the_supply_is_told() -> None:
    # A 20 Hz loop on a 6 V drive: each reversal's kick (kp·120 rad/s ≈ 6 A) needs far
    # more than 6 V, so the current ramps at the armature's own rate. The loop law misses
    # the current (refused), and the sampled current gives Kt/J about 10 % high; without
    # the supply a warning says it could not be modelled, and the interval takes the
    # loop's missed kick as a bound (before: ±2 %, the truth outside it). The law
    # trimmed of the saturated samples takes the slowed current for a one-sample delay
    # (the plant has none); the simulation with the supply (R, L, Kt told 10-20 % off)
    # tests that delay against none and keeps none (with the delay, Kt/J +22 %): Kt/J
    # within 1 % of the truth, inside its interval.
    run, drive = supply_run(6.0)
    assert np.max(np.abs(run["voltage_V"])) >= 6.0 * 0.999
    loop = speed_loop(run)
    assert loop is not None and not loop.holds
    plain = identify_run(run)
    assert plain.Kt_over_J / KT_OVER_J - 1 > 0.05
    assert plain.Kt_over_J_ci95[0] <= KT_OVER_J <= plain.Kt_over_J_ci95[1]
    assert SUPPLY_UNKNOWN in plain.warnings
    assert any("PI speed law explains the current only" in w for w in plain.warnings)
    told = DriveSupply(6.0, MOTOR.R * 1.2, MOTOR.L / 1.2, MOTOR.Kt * 1.1)
    r = identify_run(run, supply=told)
    assert abs(r.Kt_over_J / KT_OVER_J - 1) < 0.01
    assert r.Kt_over_J_ci95[0] <= KT_OVER_J <= r.Kt_over_J_ci95[1]
    assert not any("explains the current only" in w for w in r.warnings)


def test_drive_supply_names_a_bad_field() -> None:
    with pytest.raises(InputError, match="R must be a number > 0"):
        DriveSupply(24.0, -1.0, 1e-3, 0.05)
    with pytest.raises(InputError, match="supply_V must be finite"):
        DriveSupply(math.inf, 1.0, 1e-3, 0.05)
    with pytest.raises(InputError, match="speed_ki must be a number > 0, got -1.5"):
        DriveSupply(24.0, 1.0, 1e-3, 0.05, 3.0, 0.04, -1.5)


def test_effect_columns_follow_the_spec() -> None:
    theta = np.linspace(0.0, 10.0, 101)
    spec = ModelSpec(coulomb=True, cogging_N=6)
    g = effect_inputs(spec, theta, np.ones(101), 1e-3, 0.0)
    assert g.shape == (100, 3)
    assert np.all(g[:, 0] == 1.0)                       # turning forward throughout
    assert effect_inputs(ModelSpec(offset=True), theta, np.ones(101), 1e-3, 0.0).shape == (100, 0)


def test_cli_motor_profile_tells_the_supply(tmp_path: Path, capsys: Any) -> None:
    # `stand identify --motor PROFILE` reads the drive's supply, current limit and speed
    # gains and the motor's armature from the profile; an unknown profile is bad input
    # (exit 2, named on stderr).
    assert motor_supply("crouzet_82800502") == DriveSupply(24.0, 1.9, 1.5e-3, 0.0527, 3.0,
                                                           0.04, 1.5)
    run, _ = speed_run(5.0)
    path = write_run(tmp_path / "run.csv", {c: run[c] for c in (
        "time_s", "current_A", "position_rad", TARGET_COLUMN)})
    assert main(["identify", str(path), "--json", "--motor", "crouzet_82800502"]) == 0
    assert json.loads(capsys.readouterr().out)["Kt_over_J"] > 0
    assert main(["identify", str(path), "--motor", "no_such_motor"]) == 2
    assert "no_such_motor" in capsys.readouterr().err


def test_the_integrator_held_at_the_current_limit_is_simulated() -> None:
    # A 20 Hz loop at a 1 A limit: each reversal's kick holds the command at the limit
    # for some 50 ms, and the drive holds its integrator there too (it would wind up to
    # 4 A). Simulated with the true parameters and no noise, the loop follows the plant
    # to 0.4 mA and 1.2e-5 rad; with an integrator that runs on through the limit
    # (before) it is 0.96 A and 2 rad off.
    dt, limit = 3e-3, 1.0
    kp = 2 * math.pi * 20.0 * MOTOR.J / MOTOR.Kt
    drive = DriveParams(mode="speed", supply_V=48.0, current_limit_A=limit, speed_kp=kp,
                        speed_ki=kp * 2 * math.pi * 20.0 / 5)
    plant = MotorPlant(MOTOR, drive, SensorParams(encoder_lines=0, current_noise_A=0.0),
                       Effects(), seed=3)
    command = excitation("prbs", int(6.0 / dt), dt, 0.0, 60.0, int(0.2 / dt), seed=3)
    run = simulate_motor(plant, "speed", command, dt)
    theta, current = run["position_rad"], run["current_A"]
    assert np.mean(np.abs(current) > 0.99 * limit) > 0.05
    model = loop_model.LoopModel(theta, current, run[TARGET_COLUMN],
                                 np.zeros((len(theta) - 1, 0)), dt, 0, 1e-3, 1e-3, True)
    p = np.array([KT_OVER_J, MOTOR.D / MOTOR.J, drive.speed_kp, drive.speed_ki,
                  np.log(drive.current_tau_s), 0, theta[0], 0, 0, current[0], 0, limit])
    x = model.states(p)
    assert np.max(np.abs(x[:, 3] - current)) < 1e-3
    assert np.max(np.abs(x[:, 0] - theta)) < 1e-4


def test_a_fit_with_the_supply_that_misses_the_run_starts_once_more() -> None:
    # A 16 Hz loop on a 48 V drive whose kicks need some 85 V: the supply binds for
    # 30 ms after each reversal, and the loop law is refused. Told R 19 % low (L, Kt
    # 18 % and 15 % high), the fit with the supply from the law's start ends in a
    # minimum of its own (the simulation explains the current only to twice its noise);
    # the second start (the effects the equation error chose at none, the resistance
    # scanned, the loop fitted with the armature held) reaches the run: Kt/J within
    # 0.5 %, inside its interval, and no warning.
    motor = MotorParams(R=3.25, L=2e-4, Kt=0.023, J=3.3e-4, D=4.1e-4)
    dt, loop_hz = 4e-3, 15.8
    kp = 2 * math.pi * loop_hz * 2.06e-4 / motor.Kt
    drive = DriveParams(mode="speed", supply_V=48.0, current_limit_A=26.0, speed_kp=kp,
                        speed_ki=kp * 2 * math.pi * loop_hz / 5)
    plant = MotorPlant(motor, drive, SensorParams(encoder_lines=2000, current_noise_A=0.02),
                       Effects(), seed=3)
    command = excitation("prbs", int(8.0 / dt), dt, 0.0, 26.0, 70, seed=3)
    run = simulate_motor(plant, "speed", command, dt)
    assert np.max(np.abs(run["voltage_V"])) >= 48.0 * 0.999
    told = DriveSupply(48.0, motor.R * 0.81, motor.L * 1.18, motor.Kt * 1.15, 26.0)
    r = identify_run(run, supply=told)
    truth = motor.Kt / motor.J
    assert abs(r.Kt_over_J / truth - 1) < 0.005
    assert r.Kt_over_J_ci95[0] <= truth <= r.Kt_over_J_ci95[1]
    assert not any("explains the current only" in w for w in r.warnings)


def test_a_loop_held_at_its_supply_is_simulated_with_its_told_gains() -> None:
    # A 40 Hz loop (kp 0.79 A·s/rad, ki 39 A/rad) on a 48 V drive, its motor loaded by
    # 1.5 times its own inertia, sampled every 3.8 ms: after each reversal the supply
    # binds and the integrator sits at the current limit, and the PI law fitted on the
    # samples is refused (26 times the current's noise). Told the drive's gains (a
    # motor profile's `drive.speed_kp`, `speed_ki`) and R 19 % high, the second start of
    # the fit with the supply begins at those gains, and the resistance refined between
    # the scan's factors (×0.794 and ×0.891 of the told one; the truth ×0.841) reaches
    # the run: Kt/J within 0.2 % and no warning. Without the gains, or with the scan's
    # factor alone, the fit ends in a minimum of its own, Kt/J +1.7 %.
    motor = MotorParams(R=1.975, L=6.91e-4, Kt=0.03725, J=2.944e-4, D=7.0e-5)
    dt = 3.84e-3
    drive = DriveParams(mode="speed", supply_V=48.0, current_limit_A=46.2,
                        current_tau_s=2e-4, speed_kp=0.788, speed_ki=39.35)
    plant = MotorPlant(motor, drive, SensorParams(encoder_lines=500, current_noise_A=0.0455),
                       Effects(), seed=2_114_073)
    command = excitation("prbs", int(round(6.0 / dt)), dt, 0.0, 167.5, 69, seed=2_114_073)
    run = simulate_motor(plant, "speed", command, dt)
    told = DriveSupply(48.0, motor.R * 1.19, motor.L, motor.Kt * 1.033, 46.2,
                       speed_kp=0.788, speed_ki=39.35)
    r = identify_run(run, supply=told)
    truth = motor.Kt / motor.J
    assert abs(r.Kt_over_J / truth - 1) < 0.002
    assert r.Kt_over_J_ci95[0] <= truth <= r.Kt_over_J_ci95[1]
    assert not any("explains the current only" in w for w in r.warnings)
