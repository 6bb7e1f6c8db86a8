"""Seed 000 eq. 18: reducer efficiency from a two-motor run with output load steps."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from numpy.testing import assert_allclose

from stand.cli import main
from stand.errors import InputError, NotExcitedError
from stand.ident.efficiency import efficiency, find_steps
from stand.procedures import efficiency_procedure, simulate_stand_procedure
from stand.profiles import load_motor, load_stand
from stand.runfile import Run, check_columns

STAND = "cycloidal_two_motor"


def _synthetic(di_in: float, di_out: float, noise: float, seed: int = 0):
    """Plateaus of 400 samples: output current 0, −di_out, 0, −di_out; input follows."""
    rng = np.random.default_rng(seed)
    level = np.repeat([0.0, 1.0, 0.0, 1.0], 400)
    n = len(level)
    return check_columns({
        "time_s": np.arange(n) * 1e-3,
        "current_in_A": 0.26 + di_in * level + noise * rng.standard_normal(n),
        "position_in_rad": np.arange(n) * 0.168,
        "current_out_A": -di_out * level + noise * rng.standard_normal(n),
        "position_out_rad": np.arange(n) * 0.168 / 11,
    }, "reducer", "synthetic")


def test_eq_18_by_hand() -> None:
    # Δi_out = 0.5 A, Δi_in = 0.05 A, n = 10, K_in = 0.05, K_out = 0.04:
    # η = 0.04·0.5 / (10·0.05·0.05) = 0.8 at every one of the 3 steps.
    r = efficiency(_synthetic(0.05, 0.5, 0.0), 10.0, 0.05, 0.04)
    assert r.steps == 3
    assert_allclose(r.efficiency, 0.8, rtol=1e-12)
    assert_allclose([r.delta_i_in_A, r.delta_i_out_A], [0.05, 0.5], rtol=1e-12)
    assert_allclose(r.step_times_s, [0.4, 0.8, 1.2])


def test_steps_are_found_in_noise_and_uncertainty_is_honest() -> None:
    # 5 mA white noise: over 100 independent runs the errors divided by the reported
    # uncertainty must have unit spread (±20 % ≈ 3 sampling standard deviations of a
    # standard deviation from 100 draws) and no outlier beyond 4.5.
    z = []
    for seed in range(100):
        r = efficiency(_synthetic(0.05, 0.5, 0.005, seed), 10.0, 0.05, 0.04)
        assert r.steps == 3
        z.append((r.efficiency - 0.8) / r.efficiency_std)
    assert 0.8 < np.std(z) < 1.2
    assert np.max(np.abs(z)) < 4.5


def test_no_step_is_not_excited() -> None:
    run = _synthetic(0.0, 0.0, 0.005)
    assert find_steps(run["current_out_A"]).size == 0
    with pytest.raises(NotExcitedError, match="no load step"):
        efficiency(run, 10.0, 0.05, 0.05)
    with pytest.raises(InputError, match="ratio"):
        efficiency(run, 0.0, 0.05, 0.05)


@pytest.mark.parametrize("eta", [0.5, 0.65, 0.8, 0.95])
def test_simulated_stand_sweep_within_0_01(eta: float) -> None:
    stand = load_stand(STAND)
    motor_in, motor_out = load_motor(stand.motor_in), load_motor(stand.motor_out)
    proc = efficiency_procedure(stand, motor_in, load_current_A=0.5)
    run = simulate_stand_procedure(proc, stand, motor_in, motor_out, seed=7, efficiency=eta)
    r = efficiency(run, stand.reducer.ratio, motor_in.motor.Kt, motor_out.motor.Kt)
    assert r.steps == 7
    assert abs(r.efficiency - eta) < 0.01   # issue 2, done 2


def test_cli_on_stand_simulate_output(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "x.csv"
    assert main(["simulate", STAND, "-o", str(path), "--seed", "3"]) == 0
    capsys.readouterr()
    assert main(["efficiency", str(path), "--json", "--ratio", "11", "--k-in", "0.0527",
                 "--k-out", "0.0527"]) == 0
    result = json.loads(capsys.readouterr().out)
    assert abs(result["efficiency"] - 0.80) < 0.01
    assert 0 < result["efficiency_std"] < 0.01
    assert result["delta_i_out_A"] == pytest.approx(0.5, rel=0.01)


def reversing_run(brake: bool) -> Run:
    """Coulomb friction on both shafts (0.1 A in, 0.08 A out), an input that reverses
    after three plateaus, 2 mA current noise; the output load of 0.5 A opposes the
    motion in both directions (``brake``) or keeps one sign."""
    rng = np.random.default_rng(4)
    level = np.repeat([0.0, 1.0, 0.0, 1.0, 0.0, 1.0], 400)
    direction = np.repeat([1.0, 1.0, 1.0, -1.0, -1.0, -1.0], 400)
    # the load's sign on the output shaft: against the motion, or always negative
    load = level * direction if brake else level
    # forward power flow: the input adds 0.05 A against the load, η = 0.04·0.5/(10·0.05·0.05);
    # backward (the load turns with the shaft): the input takes η·(its share) back
    share = np.where(load * direction > 0, 1.0, 0.8 * 0.8)
    n = len(level)
    return check_columns({
        "time_s": np.arange(n) * 1e-3,
        "current_in_A": 0.05 * share * load + 0.1 * direction + 0.002 * rng.standard_normal(n),
        "position_in_rad": np.cumsum(direction) * 0.168,
        "current_out_A": -0.5 * load - 0.08 * direction + 0.002 * rng.standard_normal(n),
        "position_out_rad": np.cumsum(direction) * 0.168 / 10,
    }, "reducer", "reversing")


def test_steps_across_a_reversal_are_left_out() -> None:
    # Within one direction the friction cancels in Δi and η = 0.8; the step across the
    # reversal holds twice the friction and is left out. Tolerance 0.005: a few standard
    # deviations of η from 300 settled samples a plateau.
    r = efficiency(reversing_run(brake=True), 10.0, 0.05, 0.04)
    assert r.steps == 4
    assert abs(r.efficiency - 0.8) < 0.005
    assert any("turns the other way" in w for w in r.warnings)
    assert r.efficiency_ci95[0] <= r.efficiency <= r.efficiency_ci95[1]


def test_steps_with_power_flowing_backwards_are_left_out() -> None:
    # A load of one sign on a reversing input: after the reversal the output motor drives
    # the reducer, and Δi_out/Δi_in there is 1/η (1.25 here), not η. Those two steps are
    # left out and named; the two forward steps give η = 0.8.
    r = efficiency(reversing_run(brake=False), 10.0, 0.05, 0.04)
    assert r.steps == 2
    assert abs(r.efficiency - 0.8) < 0.005
    assert any("power flows backwards" in w for w in r.warnings)


#: A 2500-line encoder read 4x, rad a count.
COUNT_RAD = 2 * np.pi / 10_000


def _read_by_dithering_encoder(true_rad: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Each reading is the true count or one of its neighbours at random: it dithers by
    up to two counts between samples."""
    return (np.floor(true_rad / COUNT_RAD) + rng.integers(-1, 2, len(true_rad))) * COUNT_RAD


@pytest.mark.parametrize("seed", range(5))
def test_an_encoder_that_dithers_by_a_count_or_two_keeps_the_steps(seed: int) -> None:
    # A slow input (0.3 counts a sample; its output 11 times slower) read by dithering
    # encoders: the shaft still turns one way on every plateau, so all 3 steps count.
    rng = np.random.default_rng(seed)
    run = _synthetic(0.05, 0.5, 0.0)
    slow_in = np.arange(len(run)) * 0.3 * COUNT_RAD
    dithered = check_columns({**run.columns,
                              "position_in_rad": _read_by_dithering_encoder(slow_in, rng),
                              "position_out_rad": _read_by_dithering_encoder(slow_in / 11, rng)},
                             "reducer", "dithering")
    assert np.any(np.diff(dithered["position_in_rad"]) < 0)  # it does go back
    r = efficiency(dithered, 10.0, 0.05, 0.04)
    assert r.steps == 3 and not r.warnings
    assert_allclose(r.efficiency, 0.8, rtol=1e-12)


def test_a_dithering_encoder_on_a_standing_shaft_is_no_direction() -> None:
    # The same dither on a shaft that stands: no plateau has a direction, no step counts.
    rng = np.random.default_rng(0)
    run = _synthetic(0.05, 0.5, 0.0)
    standing = np.full(len(run), 100.5 * COUNT_RAD)
    still = check_columns({**run.columns,
                           "position_in_rad": _read_by_dithering_encoder(standing, rng),
                           "position_out_rad": _read_by_dithering_encoder(standing, rng)},
                          "reducer", "standing")
    with pytest.raises(NotExcitedError, match="no load step with the input turning the same way"):
        efficiency(still, 10.0, 0.05, 0.04)
