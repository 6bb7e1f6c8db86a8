"""A drag continuous through zero speed: its column, and the dry friction verdict it is
checked against (stand.diagnosis.drag)."""

from __future__ import annotations

import re

import numpy as np
import pytest

from stand.diagnosis import diagnose, drag
from stand.diagnosis.signals import prepare
from stand.diagnosis.smooth_drag import drag_mean
from stand.effects import UNEXPLAINED
from stand.runfile import Run
from tests.bench.diagnose.benchmark import case_runs
from tests.unit.test_diagnose_effects import MOTOR, PLANTED, stand_runs


def test_the_drag_column_is_the_mean_of_tanh_along_the_speeds_path() -> None:
    speed = np.array([-30.0, -2.0, 0.5, 4.0, 4.0, 40.0])
    ws = 3.0
    got = drag_mean(speed, ws)
    for n in range(len(speed) - 1):
        path = np.linspace(speed[n], speed[n + 1], 200001)
        assert got[n] == pytest.approx(np.mean(np.tanh(path / ws)), abs=1e-5)
    assert got[-1] == pytest.approx(np.tanh(40.0 / ws))  # the last period holds its speed


def _drag_scale(notes: list[str]) -> float:
    found = [note for note in notes if drag.DROPPED in note]
    assert found, notes
    match = re.search(r"ω_d ([0-9.e+-]+) rad/s", found[0])
    assert match, found[0]
    return float(match.group(1))


@pytest.mark.parametrize(("seed", "index"), [(309, 4), (301, 50)])
def test_an_eddy_brake_a_coulomb_friction_stood_in_for_is_unexplained(seed: int,
                                                                       index: int) -> None:
    # Held-out benchmark cases of an eddy-current brake T·2x/(1 + x²), x = ω/ω_c, that the
    # selection names Coulomb friction: 309/4 (ω_c 27.3 rad/s, a current noise command;
    # the friction and D/J fit it to 1.5 times the noise gap, the verdict was
    # `coulomb_friction`), 301/50 (ω_c 223 rad/s, a current PRBS; 2.1 times, the
    # verdict `coulomb_friction+unexplained` by the speed shape it left). A drag
    # T_d·tanh(ω/ω_d) simulates HOLDOUT significantly better than the friction, at a
    # speed scale HOLDOUT finds too: the friction is dropped, and what is left is beyond
    # the noise. Its ω_d is near ω_c/2, where the two have the same slope and level.
    case, train, holdout = case_runs(index, seed, held_out=True, current_mean=True)
    assert list(case.outside) == ["eddy_brake"]
    result = diagnose(train, holdout)
    assert result.verdict == UNEXPLAINED, result.message
    assert result.verdict_gap_percent == pytest.approx(result.gap_percent)
    ws = _drag_scale(result.notes)
    assert 0.5 < ws / (case.outside["eddy_brake"]["omega_c"] / 2) < 2, result.notes


@pytest.mark.parametrize(("seed", "index"), [(289, 80), (313, 51), (313, 198)])
def test_an_eddy_brake_a_coulomb_friction_fits_within_the_noise_gap_is_unexplained(
        seed: int, index: int) -> None:
    # Held-out benchmark cases of an eddy-current brake under a current noise command
    # (289/80: ω_c 61.7 rad/s; 313/51: 57.4 rad/s; 313/198: 662 rad/s) whose Coulomb
    # friction simulates HOLDOUT to within the noise gap (0.64, 0.80 and 0.67 % against
    # 0.86, 0.86 and 4.28 %): the verdict was `coulomb_friction`, the drag never tried.
    # The paired test, which allows for the noise, still finds the drag better (p 2e-06,
    # 6e-10, 3e-05): the friction is dropped and the verdict is `unexplained`, the drag's
    # ω_d near ω_c/2. On 313/198 even the nominal gap (0.76 %) is within the noise gap:
    # no note calls it not `unexplained`.
    case, train, holdout = case_runs(index, seed, held_out=True, current_mean=True)
    assert list(case.outside) == ["eddy_brake"]
    result = diagnose(train, holdout)
    assert result.verdict == UNEXPLAINED, result.message
    note = next(note for note in result.notes if drag.DROPPED in note)
    friction_gap = re.search(r"the friction to ([0-9.]+) %", note)
    assert friction_gap, note
    assert float(friction_gap.group(1)) <= result.noise_gap_percent, note
    ws = _drag_scale(result.notes)
    assert 0.5 < ws / (case.outside["eddy_brake"]["omega_c"] / 2) < 2, result.notes
    assert not any("not `unexplained`" in note for note in result.notes), result.notes


@pytest.mark.xfail(strict=True, reason=(
    "known wrong unexplained (stop 66): within the noise gap the drag meets every dry "
    "friction verdict, and under a speed loop a Coulomb friction's zero crossings fit a "
    "steep drag (ω_d 2.12 rad/s) slightly better (1.18 against 1.25 %, p 4e-05); stop 65 "
    "gated the drag to a gap beyond the noise gap for this case, which cost 6 held-out eddy "
    "brakes and 3 unseen drags a verdict of `unexplained`. Since stop 69 no drag below "
    "the run's reversal step (6.7 rad/s) replaces it, but a friction growing with the "
    "torque carried is found beside it (μ 0.056, p 0.0004): coulomb_friction+unexplained"))
def test_a_coulomb_friction_under_a_speed_loop_within_the_noise_gap_is_no_drag() -> None:
    # Held-out benchmark seed 311 case 158: a Coulomb friction under a speed-loop PRBS,
    # named, leaving 1.25 % against a noise gap of 2.52 %.
    case, train, holdout = case_runs(158, 311, held_out=True, current_mean=True)
    assert case.truth == ["coulomb_friction"]
    result = diagnose(train, holdout)
    assert result.verdict == "coulomb_friction", result.notes


def test_a_coulomb_friction_is_no_drag() -> None:
    # the planted Coulomb friction of the effect tests: named, and no drag replaces it
    result = diagnose(*stand_runs({"coulomb_friction": PLANTED["coulomb_friction"]}),
                      kt=MOTOR.Kt)
    assert result.verdict == "coulomb_friction", result.message
    assert not any(drag.DROPPED in note or drag.BESIDE in note for note in result.notes)


def test_a_coulomb_friction_that_simulates_better_beside_the_drag_stays() -> None:
    # Held-out benchmark seed 309 case 95: an eddy-current brake (ω_c 85.9 rad/s) under
    # a speed loop following a sine, which the selection names Coulomb friction (gap
    # 3.26 -> 1.31 %, noise 0.20 %; the verdict was `coulomb_friction`). The drag in its
    # place simulates HOLDOUT to 0.53 %, and the friction beside the drag better still:
    # the friction stays, and the drag is `unexplained` after it.
    case, train, holdout = case_runs(95, 309, held_out=True, current_mean=True)
    assert list(case.outside) == ["eddy_brake"]
    result = diagnose(train, holdout)
    assert result.verdict == f"coulomb_friction+{UNEXPLAINED}", result.message
    assert any(note.startswith(f"coulomb_friction {drag.BESIDE}") for note in result.notes), \
        result.notes



def _run(position: np.ndarray, dt: float) -> Run:
    t = np.arange(len(position)) * dt
    return Run({"time_s": t, "current_A": np.zeros_like(t), "position_rad": position})


def test_the_reversal_step_is_the_speeds_change_over_a_sample_where_it_reverses() -> None:
    dt, w = 1e-3, 4 * np.pi
    t = np.arange(4000) * dt
    # θ = sin(w·t): the speed w·cos(w·t) changes by w²·Δt a sample where it crosses zero
    step = drag.reversal_step(prepare(_run(np.sin(w * t), dt)))
    assert step == pytest.approx(w * w * dt, rel=0.05)
    assert drag.reversal_step(prepare(_run(3.0 * t + 0.1 * np.sin(w * t), dt))) == 0.0


def test_a_drag_crossed_within_a_sample_at_reversal_is_the_frictions_jump() -> None:
    # benchmark 318/103: a Coulomb friction under a speed PRBS, driven by the period
    # means. A drag of ω_d 1.69 rad/s simulated HOLDOUT better than the friction (the
    # sign smoothed between samples) and replaced it (`unexplained`), where the speed
    # changes by 14 rad/s over the sample of each reversal: the friction is named
    case, train, holdout = case_runs(103, 318, held_out=True, current_mean=True)
    assert case.truth == ["coulomb_friction"] and case.mode == "speed"
    result = diagnose(train, holdout)
    assert result.verdict.split("+")[0] == "coulomb_friction", result.message
    assert not any(drag.DROPPED in note for note in result.notes), result.notes
