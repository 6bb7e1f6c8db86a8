"""The noise gap by replay (:mod:`stand.diagnosis.noise_replay`): the nominal model's own
motion read through the run's sensors, anchored and simulated as HOLDOUT is."""

from __future__ import annotations

import numpy as np
import pytest

from stand.diagnosis import diagnose
from stand.diagnosis.noise import REPLAY_FACTOR, UNEXPLAINED_FACTOR
from stand.diagnosis.noise_replay import _free_run
from tests.bench.diagnose.benchmark import case_runs
from tests.unit.test_diagnose_effects import stand_runs


@pytest.mark.parametrize("c_omega", [-25.0, 0.0, 1e-9])
def test_the_free_run_is_exact_over_each_period(c_omega: float) -> None:
    dt, n = 1e-3, 400
    drive = np.sin(np.arange(n) * 0.05) * 2000.0
    omega, theta = _free_run(c_omega, drive, dt, 3.0, 0.5)
    # the same motion in fine Runge-Kutta steps of the held drive
    state, fine = np.array([0.5, 3.0]), 100
    h = dt / fine
    for k in range(n):
        assert omega[k] == pytest.approx(state[1], rel=1e-9, abs=1e-9)
        assert theta[k] == pytest.approx(state[0], rel=1e-9, abs=1e-9)

        def slope(x: np.ndarray, drive_k: float = drive[k]) -> np.ndarray:
            return np.array([x[1], c_omega * x[1] + drive_k])

        for _ in range(fine):
            k1 = slope(state)
            k2 = slope(state + h / 2 * k1)
            k3 = slope(state + h / 2 * k2)
            k4 = slope(state + h * k3)
            state = state + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)


@pytest.mark.parametrize(("seed", "index", "held_out"), [
    (319, 95, True),    # a current PRBS, 1.42 times the noise gap
    (298, 423, False),  # a current sine, 1.42 times
    # a speed sine, 1.31 times: a speed loop's current under a one-tone target is a
    # smooth tone too, whose mean over each period (what the replay integrates) is what
    # moves the stand (not replayed before stop 71)
    (298, 37, False),
])
def test_a_run_with_no_effect_leaves_what_noise_leaves_on_its_replays(
        seed: int, index: int, held_out: bool) -> None:
    case, train, holdout = case_runs(index, seed, held_out=held_out, current_mean=True)
    assert case.truth == ["none"]
    result = diagnose(train, holdout)
    assert result.verdict == "none", result.message
    assert result.noise_gap_percent is not None
    assert result.replayed_noise_gap_percent is not None
    assert 1.3 < result.gap_percent / result.noise_gap_percent <= UNEXPLAINED_FACTOR
    # the formula's estimate is off by 1.4; the replay is within 10 %
    assert 0.9 < result.gap_percent / result.replayed_noise_gap_percent < 1.1


def test_a_run_that_holds_a_broadband_speed_target_is_not_replayed() -> None:
    # the fan stand of test_diagnose_unexplained is under a current PRBS; with a
    # speed target column its models would be driven by what the loop does between
    # samples, which a replay of the samples does not hold (not one tone)
    train, holdout = stand_runs({})
    for run in (train, holdout):
        run.columns["speed_target_rad_s"] = np.zeros(len(run))
    result = diagnose(train, holdout)
    assert result.replayed_noise_gap_percent is None
    assert REPLAY_FACTOR > 1.0


@pytest.mark.parametrize(("seed", "index", "effect"), [
    (313, 81, "backlash"),        # under a current sine, 2.0 times the noise gap
    (313, 101, "torque_ripple"),  # under a current sine, 1.3 times
])
def test_where_the_replay_shows_a_gap_the_effect_that_explains_it_is_named(
        seed: int, index: int, effect: str) -> None:
    # benchmark cases whose effect the first step's test, shared among the whole
    # vocabulary, did not pass (`none` before the replay, then `unexplained`): the replay
    # shows something beyond noise, and the effect takes the gap back within what noise
    # leaves there
    case, train, holdout = case_runs(index, seed, held_out=True, current_mean=True)
    assert case.truth == [effect]
    result = diagnose(train, holdout)
    assert result.verdict == effect, result.message
    first = {e.effect: e for e in result.effects}[effect]
    assert not first.significant
    assert result.replayed_noise_gap_percent is not None
    assert result.gap_percent > REPLAY_FACTOR * result.replayed_noise_gap_percent
    assert result.verdict_gap_percent <= REPLAY_FACTOR * result.replayed_noise_gap_percent
    assert [s.effect for s in result.steps] == [effect]
    assert any(note.startswith(f"{effect} is named at a second look") for note in result.notes)
