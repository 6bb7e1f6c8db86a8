"""Output-error refinement of speed-loop runs: the loop and the mechanics simulated
between samples and fitted to the sampled angle and current (issue 19)."""

from __future__ import annotations

import numpy as np
from scipy.linalg import expm

from stand.diagnosis.model import ModelSpec
from stand.diagnosis.signals import quantization_step
from stand.ident import closed_loop
from stand.ident.closed_loop import effect_inputs, fit_closed_loop
from stand.ident.identify import identify_run
from stand.ident.noise import noise_sigma
from stand.ident.speed_loop import TARGET_COLUMN, speed_loop
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


def test_modal_step_matches_the_matrix_exponential(monkeypatch: object) -> None:
    model = closed_loop._LoopModel(np.zeros(10), np.zeros(10), np.zeros(10),
                                   np.ones((9, 1)), 3e-3, 0, 1.0, 1.0, False)
    p = np.array([1200.0, 12.0, 0.05, 0.7, np.log(2e-4), 0, 0, 0, 0, 0, 0, 3.0])
    for clipped in (False, True):
        Phi, Gamma = model._discrete(p, 3e-3, clipped)
        m = Gamma.shape[1]
        a, d, kp, ki, tau = 1200.0, 12.0, 0.05, 0.7, 2e-4
        A = np.array([[0, 1, 0, 0], [0, -d, 0, a], [0, -ki, 0, 0],
                      [0, 0 if clipped else -kp / tau, 0 if clipped else 1 / tau, -1 / tau]])
        B = np.zeros((4, m))
        B[2, 0], B[1, 1] = ki, 3.0
        B[3, -1 if clipped else 0] = (1.0 if clipped else kp) / tau
        M = np.zeros((4 + m, 4 + m))
        M[:4, :4], M[:4, 4:] = A * 3e-3, B * 3e-3
        E = expm(M)
        np.testing.assert_allclose(Phi, E[:4, :4], atol=1e-9)
        np.testing.assert_allclose(Gamma, E[:4, 4:], atol=1e-12)


def test_effect_columns_follow_the_spec() -> None:
    theta = np.linspace(0.0, 10.0, 101)
    spec = ModelSpec(coulomb=True, cogging_N=6)
    g = effect_inputs(spec, theta, np.ones(101), 1e-3, 0.0)
    assert g.shape == (100, 3)
    assert np.all(g[:, 0] == 1.0)                       # turning forward throughout
    assert effect_inputs(ModelSpec(offset=True), theta, np.ones(101), 1e-3, 0.0).shape == (100, 0)
