"""Seed 000 eqs. 6-10: the Q-matrix solver, its batching and streaming, and the derivatives."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_allclose

from stand.errors import InputError, NotExcitedError
from stand.ident.derivatives import kernel, state_derivatives
from stand.ident.identify import identify_run
from stand.ident.qmatrix import QSums, solve
from stand.runfile import check_columns

A_TRUE = np.array([[0.0, 1.0], [-3.0, -2.0]])
B_TRUE = np.array([[0.0], [5.0]])


def _data(rng: np.random.Generator, shape: tuple[int, ...], noise: float = 0.0):
    x = rng.standard_normal((*shape, 2))
    u = rng.standard_normal((*shape, 1))
    xdot = x @ A_TRUE.T + u @ B_TRUE.T + noise * rng.standard_normal((*shape, 2))
    return xdot, x, u


def test_q_blocks_are_the_integrals_of_eq_10() -> None:
    # Two samples worked by hand: x = [1, 0], [0, 2]; u = 1, 3; ẋ = [0, 1], [1, 0]; Δt = 0.5.
    x = np.array([[1.0, 0.0], [0.0, 2.0]])
    u = np.array([[1.0], [3.0]])
    xdot = np.array([[0.0, 1.0], [1.0, 0.0]])
    s = QSums.zeros(2, 1).add(xdot, x, u, dt_s=0.5)
    assert_allclose(s.Q1, 0.5 * np.array([[0.0, 2.0], [1.0, 0.0]]))   # Σ ẋ xᵀ Δt
    assert_allclose(s.Q2, 0.5 * np.array([[3.0], [1.0]]))             # Σ ẋ uᵀ Δt
    assert_allclose(s.Q11, 0.5 * np.array([[1.0, 0.0], [0.0, 4.0]]))  # Σ x xᵀ Δt
    assert_allclose(s.Q12, 0.5 * np.array([[1.0], [6.0]]))            # Σ x uᵀ Δt
    assert_allclose(s.Q22, 0.5 * np.array([[10.0]]))                  # Σ u uᵀ Δt
    assert int(s.samples) == 2


def test_exact_data_give_exact_a_and_b_with_full_fit() -> None:
    xdot, x, u = _data(np.random.default_rng(1), (50,))
    r = solve(QSums.zeros(2, 1).add(xdot, x, u, 1e-3))
    assert_allclose(r.A, A_TRUE, atol=1e-12)   # eq. 10 is exact when d(t) = 0
    assert_allclose(r.B, B_TRUE, atol=1e-12)
    assert_allclose(r.fit_percent, 100.0, atol=1e-6)
    assert 1.0 <= float(r.condition_number) < 10.0  # independent unit-variance regressors


def test_fit_percent_is_one_minus_relative_residual_norm() -> None:
    # Row 2 of ẋ is 5·u + e with e ⟂ the regressors; fit = 100·(1 − ‖e‖/‖ẋ2 − mean‖).
    rng = np.random.default_rng(2)
    xdot, x, u = _data(rng, (400,), noise=0.5)
    r = solve(QSums.zeros(2, 1).add(xdot, x, u))
    z = np.concatenate([x, u], axis=-1)
    theta, *_ = np.linalg.lstsq(z, xdot[:, 1], rcond=None)
    e = xdot[:, 1] - z @ theta
    expected = 100 * (1 - np.linalg.norm(e) / np.linalg.norm(xdot[:, 1] - xdot[:, 1].mean()))
    assert_allclose(r.fit_percent[1], expected, rtol=1e-9)
    assert_allclose(r.B[1, 0], theta[2], rtol=1e-9)


def test_batched_and_streamed_equal_one_shot() -> None:
    rng = np.random.default_rng(3)
    xdot, x, u = _data(rng, (7, 1000), noise=0.1)
    batched = solve(QSums.zeros(2, 1, (7,)).add(xdot, x, u, 1e-3))
    streamed = QSums.zeros(2, 1, (7,))
    for start in range(0, 1000, 137):  # uneven chunks
        streamed.add(xdot[:, start:start + 137], x[:, start:start + 137],
                     u[:, start:start + 137], 1e-3)
    halves = QSums.zeros(2, 1, (7,)).add(xdot[:, :400], x[:, :400], u[:, :400], 1e-3).merge(
        QSums.zeros(2, 1, (7,)).add(xdot[:, 400:], x[:, 400:], u[:, 400:], 1e-3))
    for run in range(7):
        one = solve(QSums.zeros(2, 1).add(xdot[run], x[run], u[run], 1e-3))
        for other in (batched, solve(streamed), solve(halves)):
            assert_allclose(other.A[run], one.A, rtol=1e-9, atol=1e-12)
            assert_allclose(other.B[run], one.B, rtol=1e-9, atol=1e-12)
            assert_allclose(other.B_se[run], one.B_se, rtol=1e-9)
            assert_allclose(other.fit_percent[run], one.fit_percent, rtol=1e-9)


def test_extra_regressors_plug_in_as_inputs() -> None:
    # ẋ2 = −2·x2 + 5·u + 0.7·sign(x2) − 1.5: sign and a constant column as extra inputs.
    rng = np.random.default_rng(4)
    x = rng.standard_normal((300, 1))
    u = np.column_stack([rng.standard_normal(300), np.sign(x[:, 0]), np.ones(300)])
    xdot = -2 * x + u @ np.array([[5.0], [0.7], [-1.5]])
    r = solve(QSums.zeros(1, 3).add(xdot, x, u))
    assert_allclose(r.A, [[-2.0]], atol=1e-10)
    assert_allclose(r.B, [[5.0, 0.7, -1.5]], atol=1e-10)


def test_standard_errors_match_the_scatter_of_repeated_estimates() -> None:
    # 400 independent problems with white equation error: the z-scores of B must have unit
    # spread; ±15 % covers the sampling error of a standard deviation from 400 draws (≈3.5 %).
    rng = np.random.default_rng(5)
    xdot, x, u = _data(rng, (400, 200), noise=0.3)
    r = solve(QSums.zeros(2, 1, (400,)).add(xdot, x, u))
    z = (r.B[:, 1, 0] - B_TRUE[1, 0]) / r.B_se[:, 1, 0]
    assert abs(np.std(z) - 1.0) < 0.15
    assert abs(np.mean(z)) < 0.2


@pytest.mark.parametrize("case", ["zero_state", "dependent", "too_few"])
def test_unexcited_data_raise_not_excited(case: str) -> None:
    rng = np.random.default_rng(6)
    xdot, x, u = _data(rng, (100,))
    if case == "zero_state":
        x[:, 1] = 0.0
    elif case == "dependent":
        u[:, 0] = 2 * x[:, 1]           # the input is a copy of a state: singular
    else:
        xdot, x, u = xdot[:5], x[:5], u[:5]
    with pytest.raises(NotExcitedError, match="excite|samples"):
        solve(QSums.zeros(2, 1).add(xdot, x, u))


def test_unexcited_batch_member_is_named_or_nan() -> None:
    xdot, x, u = _data(np.random.default_rng(7), (3, 100))
    x[1, :, 1] = 0.0
    sums = QSums.zeros(2, 1, (3,)).add(xdot, x, u)
    with pytest.raises(NotExcitedError, match="run 1"):
        solve(sums)
    r = solve(sums, check=False)
    assert np.isnan(r.B[1]).all() and np.isfinite(r.B[[0, 2]]).all()


def test_shape_errors_are_input_errors() -> None:
    with pytest.raises(InputError, match="samples"):
        QSums.zeros(2, 1).add(np.zeros((10, 2)), np.zeros((10, 2)), np.zeros((9, 1)))


# Derivatives -------------------------------------------------------------------------

def test_paper_forward_euler_matches_hand_differences() -> None:
    theta = np.array([0.0, 1.0, 4.0, 9.0, 16.0])   # θ = k²  (Δt = 0.5 s)
    s = state_derivatives(theta, np.zeros(5), 0.5, "paper")
    assert_allclose(s.omega, [2.0, 6.0, 10.0])     # (θ_{k+1} − θ_k)/Δt
    assert_allclose(s.alpha, [8.0, 8.0, 8.0])      # (ω_{k+1} − ω_k)/Δt = 2/Δt²
    assert_allclose(s.theta, theta[:3])


def test_default_kernel_is_exact_on_quadratics_and_commutes_with_derivatives() -> None:
    dt = 1e-3
    t = np.arange(400) * dt
    theta = 100.0 + 30.0 * t + 0.5 * 40.0 * t**2    # ω = 30 + 40 t, α = 40
    s = state_derivatives(theta, t, dt)
    tc = t[s.first:len(t) - s.first]
    assert_allclose(s.alpha, 40.0, rtol=1e-9)
    # g∗θ of a quadratic is the quadratic shifted by the kernel's second moment only.
    assert_allclose(s.omega, 30.0 + 40.0 * tc, rtol=1e-9)
    assert_allclose(s.inputs[:, 0], tc, atol=1e-12)  # symmetric kernel: no lag
    g, g1, g2 = kernel(8, dt)
    assert_allclose(g.sum() * dt, 1.0)
    assert_allclose(np.sum(g2) * dt, 0.0, atol=1e-9)


def test_identify_recovers_a_linear_motor_without_noise() -> None:
    # J·θ'' + D·θ' = Kt·i with a smooth current, integrated exactly on a fine grid.
    Kt_over_J, D_over_J = 4000.0, 2.0
    dt, n = 1e-3, 3000
    t = np.arange(n) * dt
    i = 0.3 + 0.2 * np.sin(2 * np.pi * 3 * t) + 0.1 * np.sin(2 * np.pi * 7.3 * t)
    from scipy.integrate import solve_ivp
    sol = solve_ivp(lambda tt, y: [y[1], Kt_over_J * np.interp(tt, t, i) - D_over_J * y[1]],
                    (0, t[-1]), [0.0, 0.0], t_eval=t, rtol=1e-10, atol=1e-10, max_step=dt)
    run = check_columns({"time_s": t, "current_A": i, "position_rad": sol.y[0]}, "single", "ode")
    r = identify_run(run)
    # Tolerance: the sampled kernel sums approximate the continuous convolution (O(Δt²)).
    assert_allclose(r.Kt_over_J, Kt_over_J, rtol=2e-3)
    assert_allclose(r.D_over_J, D_over_J, atol=0.05)
    assert abs(r.C_over_J) < 0.05
    assert r.fit_percent > 99.0


def test_auto_half_width_widens_with_noise() -> None:
    from stand.ident.derivatives import DEFAULT_HALF_WIDTH, auto_half_width
    rng = np.random.default_rng(8)
    signal = np.sin(2 * np.pi * np.arange(20000) / 4000)       # slow, unit amplitude
    quiet = auto_half_width(signal + 0.01 * rng.standard_normal(20000), 0.01)
    noisy = auto_half_width(signal + 1.0 * rng.standard_normal(20000), 1.0)
    assert quiet == DEFAULT_HALF_WIDTH < noisy <= 1000       # 1000 = 5 % of the record


# Command line ------------------------------------------------------------------------

def test_identify_cli_fields_and_not_excited_exit_code(tmp_path, capsys) -> None:
    import json

    from stand.cli import main
    from stand.runfile import read_run, write_run
    path = tmp_path / "run.csv"
    assert main(["simulate", "crouzet_82800502", "-o", str(path), "--period", "0.001",
                 "--duration", "3", "--seed", "2"]) == 0
    capsys.readouterr()
    assert main(["identify", str(path), "--json"]) == 0
    result = json.loads(capsys.readouterr().out)
    for name in ("A", "B", "Kt_over_J", "D_over_J", "C_over_J", "fit_percent",
                 "condition_number", "samples"):
        assert name in result
    assert np.shape(result["A"]) == (2, 2) and np.shape(result["B"]) == (2, 1)
    # Kt/J = 0.0527/1.2e-5 = 4392; PRBS speed steps at 1 kHz: within 5 % (sampled current
    # of a speed loop, Coulomb friction not compensated here).
    assert abs(result["Kt_over_J"] / 4392 - 1) < 0.05
    # A constant speed command, its last second (settled): constant current: exit 2.
    simulated_constant = tmp_path / "constant.csv"
    assert main(["simulate", "crouzet_82800502", "-o", str(simulated_constant), "--period",
                 "0.001", "--duration", "3", "--excitation", "constant", "--seed", "2"]) == 0
    run = read_run(simulated_constant)
    steady = write_run(tmp_path / "steady.csv", {k: v[-1000:] for k, v in run.columns.items()})
    capsys.readouterr()
    assert main(["identify", str(steady), "--json"]) == 2
    captured = capsys.readouterr()
    assert captured.out == "" and "excite" in captured.err and "steady.csv" in captured.err
    assert main(["identify", str(path), "--method", "paper", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["method"] == "paper"
