"""The benchmark's SNR of a planted effect (true plant, answer-key side only), the
redraw of cases below it, and the physical checks that the SNR-drawn benchmark leans on:
a rebounding backlash load and a Stribeck fit that must be friction."""

from __future__ import annotations

import numpy as np
import pytest

from stand.diagnosis.backlash_load import load_estimate
from stand.diagnosis.candidates import agree
from stand.diagnosis.model import FittedModel, ModelSpec
from tests.bench.diagnose import benchmark
from tests.bench.diagnose.benchmark import EFFECT_DRAWS, MIN_EFFECT_SNR, case_snr, draw_case
from tests.bench.diagnose.snr import added_snr, effect_snr
from tests.unit.test_diagnose_effects import MOTOR, stand_runs


def _snr(effects: dict[str, dict[str, float]]) -> float:
    with_effect, _ = stand_runs(effects, seed=3)
    without, _ = stand_runs({}, seed=3)
    J_with = MOTOR.J + effects.get("backlash", {}).get("J_load", 0.0)
    return effect_snr(with_effect, without, MOTOR.J, J_with, MOTOR.D, MOTOR.Kt, 0.1)


def test_clear_effect_is_far_above_the_noise_and_a_tiny_one_below() -> None:
    assert _snr({"coulomb_friction": {"Tc": 0.004}}) > 5.0
    assert _snr({"cogging": {"Tcog": 0.003, "N": 12, "phi": 0.5}}) > 2.0
    # 2e-6 N·m: 0.4 % of the current noise's torque (5e-4 N·m)
    assert _snr({"coulomb_friction": {"Tc": 2e-6}}) < 0.3


def test_the_same_run_has_no_effect() -> None:
    run, _ = stand_runs({}, seed=3)
    assert effect_snr(run, run, MOTOR.J, MOTOR.J, MOTOR.D, MOTOR.Kt, 0.1) == 0.0


def test_a_member_of_a_pair_counts_by_what_it_adds_to_the_other() -> None:
    strong, tiny = ({"coulomb_friction": {"Tc": 0.004}},
                    {"cogging": {"Tcog": 2e-6, "N": 12, "phi": 0.5}})
    pair, _ = stand_runs({**strong, **tiny}, seed=3)
    beside, _ = stand_runs(strong, seed=3)
    bare, _ = stand_runs({}, seed=3)
    J = MOTOR.J
    # together the pair shows far above the noise, the cogging beside the friction not
    assert effect_snr(pair, bare, J, J, MOTOR.D, MOTOR.Kt, 0.1) > 5.0
    assert added_snr(pair, beside, bare, J, J, J, MOTOR.D, MOTOR.Kt, 0.1) < 0.5 * MIN_EFFECT_SNR
    # what the friction adds beside the tiny cogging is the friction's own SNR, nearly
    cogging, _ = stand_runs(tiny, seed=3)
    alone = effect_snr(beside, bare, J, J, MOTOR.D, MOTOR.Kt, 0.1)
    assert added_snr(pair, cogging, bare, J, J, J, MOTOR.D, MOTOR.Kt, 0.1) == pytest.approx(
        alone, rel=0.1)


def test_a_pair_is_drawn_again_until_each_member_shows_beside_the_other() -> None:
    # case 3 of seed 260: together its first draw's Coulomb friction and torque ripple
    # show far above the noise, the ripple beside the friction not
    first = draw_case(3, 260, min_snr=0.0)
    assert first.truth == ["coulomb_friction", "torque_ripple"]
    holdout, bare = benchmark._simulate(first, 1, 10.0), benchmark._simulate(first, 1, 10.0, {})
    assert effect_snr(holdout, bare, first.motor.J, first.motor.J, first.motor.D,
                      first.motor.Kt, 0.1) > 5.0
    assert case_snr(first) < 0.5 * MIN_EFFECT_SNR
    case = draw_case(3, 260)
    assert case.truth == first.truth and case.draws > 1
    assert case.snr is not None and case.snr >= MIN_EFFECT_SNR


def test_weak_draws_are_drawn_again_until_they_show() -> None:
    # case 139 of seed 1: its first draw (Coulomb friction) is below the noise
    first = draw_case(139, 1, min_snr=0.0)
    case = draw_case(139, 1)
    assert first.draws == 1 and first.snr is None
    assert case.truth == first.truth == ["coulomb_friction"]
    assert case.draws > 1
    assert case.snr is not None and case.snr >= MIN_EFFECT_SNR
    assert case.effects != first.effects


def test_a_case_drawn_on_another_stand_is_measured_against_that_stands_twin() -> None:
    # case 108 of seed 260 (torque ripple): no draw shows on its first stand, so the
    # case is drawn again on another one; its effect-free twin must be that stand's
    # (it was the first stand's: every draw then measured 0, and the 40th was kept)
    case = draw_case(108, 260)
    assert case.draws > EFFECT_DRAWS
    reported = case.snr
    benchmark._TWINS.clear()
    assert reported == pytest.approx(case_snr(case), rel=1e-9)
    assert reported >= MIN_EFFECT_SNR


def test_an_outside_effect_that_never_shows_on_its_stand_is_drawn_on_another() -> None:
    # case 49 of seed 300 (UNSEEN_8): a drive's braking limit that its first stand's run
    # never brakes beyond, whatever its draw, as the vocabulary's effects are: on another
    # stand (it was kept at SNR 0, an effect-free case labelled outside)
    first = draw_case(49, 300, outside_share=0.3, outside_set="unseen_8", min_snr=0.0)
    case = draw_case(49, 300, outside_share=0.3, outside_set="unseen_8")
    assert set(first.outside) == set(case.outside) == {"regen_clipping"}
    assert first.snr is not None and first.snr < 0.5 * MIN_EFFECT_SNR
    assert case.draws > EFFECT_DRAWS and case.motor != first.motor
    assert case.snr is not None and case.snr >= MIN_EFFECT_SNR

def test_backlash_load_rebounds_with_the_restitution() -> None:
    dt, speed, gap = 1e-3, 2.0, 0.01
    theta = speed * dt * np.arange(40)
    omega = np.r_[0.0, np.full(39, speed)]  # the load starts at rest where the motor is
    _, carried = load_estimate(theta, omega, gap, dt, restitution=0.0)
    _, rebound = load_estimate(theta, omega, gap, dt, restitution=0.5)
    hit = int(np.argmax(carried > 0))
    assert hit == int(np.argmax(rebound > 0)) > 1  # struck once the motor closes the gap
    assert carried[hit] == pytest.approx(speed)  # carried along
    assert rebound[hit] == pytest.approx(1.5 * speed)  # relative speed reversed times 0.5


def _model(sign: float, stribeck: float) -> FittedModel:
    return FittedModel(spec=ModelSpec(stribeck_ws=5.0), c_theta=0.0, c_omega=-1.0,
                       coef={"current": 100.0, "sign": sign, "stribeck": stribeck},
                       residual_rms=0.0, condition_number=1.0, samples=1000)


def test_stribeck_needs_a_coulomb_level_that_opposes_motion() -> None:
    physical = _model(sign=-10.0, stribeck=-8.0)
    assert agree("stribeck_friction", physical, physical)
    # a static level above the sliding one, but a "Coulomb" torque that pushes along:
    # a speed-dependent torque of some other cause, not friction
    pushing = _model(sign=+10.0, stribeck=-30.0)
    assert not agree("stribeck_friction", pushing, pushing)
