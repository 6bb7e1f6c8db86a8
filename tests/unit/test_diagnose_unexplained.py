"""A gap the vocabulary does not explain is called ``unexplained``, never ``none``; an
effect of the vocabulary is named without it; the verdict's model and what remains.

The stand is that of :mod:`tests.unit.test_diagnose_effects` (Kt 0.05 N·m/A,
J 2e-5 kg·m², PRBS of ± 0.5 A, 1000-line encoder, 0.01 A current noise, 1 ms, 6 s).
The effect outside the vocabulary is a fan's drag ``Cd·ω·|ω|``, about 10 % of the drive
torque (25 mN·m) at the run's typical speed of about 100 rad/s (50 ms PRBS steps at
1250 rad/s²).
"""

from __future__ import annotations

import numpy as np
import pytest

from stand import effects
from stand.diagnosis import diagnose, drag, load_friction
from stand.diagnosis.noise import (
    APPROXIMATION_SHARE,
    NEAR_NOISE_SPEED_SHRINK,
    REPLAY_FACTOR,
    SPEED_LOOP_REPLAY_FACTOR,
    UNEXPLAINED_FACTOR,
    unexplained,
)
from stand.diagnosis.plots import worst_window
from stand.diagnosis.significance import FAMILY_ALPHA, MIN_SHRINK
from stand.effects import UNEXPLAINED
from tests.bench.diagnose.benchmark import case_runs, rescore
from tests.unit.test_diagnose_effects import MOTOR, PLANTED, stand_runs

#: Fan drag coefficient, N·m·s²/rad²: 2.5 mN·m at 100 rad/s.
FAN_CD = 2.5e-7


def _fan(theta: float, omega: float, i: float, t: float) -> float:
    return FAN_CD * omega * abs(omega)


def test_an_effect_outside_the_vocabulary_is_unexplained_never_none() -> None:
    result = diagnose(*stand_runs({}, extra_torque=_fan), kt=MOTOR.Kt)
    assert result.verdict.split("+")[-1] == UNEXPLAINED, result.message
    assert result.noise_gap_percent is not None
    assert result.verdict_gap_percent > UNEXPLAINED_FACTOR * result.noise_gap_percent
    assert result.residual_where is not None
    assert set(result.residual_where.velocity_sign_energy) == {"positive", "negative"}


def test_an_effect_outside_the_vocabulary_beside_a_named_one_is_unexplained_after_it() -> None:
    # a fan drag four times that of the test above (10 mN·m at 100 rad/s) beside the
    # planted Coulomb friction: what remains is far more than the friction explains
    def fan(theta: float, omega: float, i: float, t: float) -> float:
        return 4 * _fan(theta, omega, i, t)

    result = diagnose(*stand_runs({"coulomb_friction": PLANTED["coulomb_friction"]},
                                  extra_torque=fan), kt=MOTOR.Kt)
    assert result.verdict == f"coulomb_friction+{UNEXPLAINED}", result.message


def test_an_eddy_brake_beside_coulomb_friction_is_unexplained_after_it() -> None:
    # an eddy-current brake T·2x/(1 + x²), x = ω/ω_c, peaking at the run's typical speed
    # (ω_c = 100 rad/s) at twice the planted friction level (T = 8 mN·m): Coulomb friction
    # and D/J take most of it, and what is left (beyond the noise, less than the friction
    # explains) is a torque that grows with the speed other than a level and a slope
    def eddy(theta: float, omega: float, i: float, t: float) -> float:
        x = omega / 100.0
        return 0.008 * 2 * x / (1 + x * x)

    result = diagnose(*stand_runs({"coulomb_friction": PLANTED["coulomb_friction"]},
                                  extra_torque=eddy), kt=MOTOR.Kt)
    assert result.verdict == f"coulomb_friction+{UNEXPLAINED}", result.message
    assert result.speed_structure_p_value is not None
    assert result.speed_structure_p_value < FAMILY_ALPHA / 3
    assert any("grow" in note for note in result.notes), result.notes


def test_a_speed_shape_after_a_named_effect_counts_near_the_noise_only_when_strong() -> None:
    noise = 0.2
    # the friction took 10 % to 1 %: its approximation, unless the speed shape is there
    assert not unexplained(10.0, 1.0, noise, named=True)
    assert unexplained(10.0, 1.0, noise, named=True, p_speed=1e-6, speed_shrink=MIN_SHRINK)
    # a shape too weak to count (below the least shrink) or not significant
    assert not unexplained(10.0, 1.0, noise, named=True, p_speed=1e-6, speed_shrink=0.01)
    assert not unexplained(10.0, 1.0, noise, named=True, p_speed=0.01, speed_shrink=0.2)
    # beyond the noise gap but within the noise factor the speed shape counts after a
    # named effect only from a shrink the vocabulary models' own small errors do not make
    assert not unexplained(10.0, 0.4, noise, named=True, p_speed=1e-6, speed_shrink=0.19)
    assert unexplained(10.0, 0.4, noise, named=True, p_speed=1e-6,
                       speed_shrink=NEAR_NOISE_SPEED_SHRINK)
    assert NEAR_NOISE_SPEED_SHRINK > MIN_SHRINK
    # within the noise gap itself, never
    assert not unexplained(10.0, 0.2, noise, named=True, p_speed=1e-6, speed_shrink=0.9)


def test_a_remainder_beyond_noise_smaller_than_what_the_effects_explain_is_their_model() -> None:
    noise = 0.2
    # nothing named: beyond the noise factor is unexplained, within it is not
    assert unexplained(10.0, 10.0, noise)
    assert not unexplained(0.5, 0.5, noise)
    # a named effect took the gap from 10 % to 1 %: 0.98 % beyond noise against the
    # 9.95 % it explains is its model's approximation
    assert not unexplained(10.0, 1.0, noise)
    # from 5 % to 4.5 %: 4.5 % left beyond noise against 2.2 % explained is not
    assert unexplained(5.0, 4.5, noise)
    # the boundary: left beyond noise == APPROXIMATION_SHARE times explained
    left = 3.0
    verdict = (left**2 + noise**2) ** 0.5
    nominal = (verdict**2 + (left / APPROXIMATION_SHARE) ** 2) ** 0.5
    assert unexplained(nominal * 0.999, verdict, noise)
    assert not unexplained(nominal * 1.001, verdict, noise)


def test_a_backlash_verdict_allows_its_rigid_contact_a_looser_approximation() -> None:
    noise = 0.2
    # a named effect took 5 % to 4 %: 4 % left beyond noise against the 3 % it explains
    assert unexplained(5.0, 4.0, noise)
    assert not unexplained(5.0, 4.0, noise, share=effects.get("backlash").approximation_share)
    assert effects.get("cogging").approximation_share == APPROXIMATION_SHARE
    # benchmark seed 260 case 15: a backlash named exactly, its rigid contact leaving
    # 1.08 times what it explains beyond noise (17 times the noise gap): was
    # `backlash+unexplained`
    case, train, holdout = case_runs(15, 260)
    assert case.truth == ["backlash"]
    result = diagnose(train, holdout)
    assert result.verdict == "backlash", result.message
    assert any("less than 2 times" in note for note in result.notes), result.notes


def test_a_current_offset_verdict_allows_no_more_than_estimation_leaves() -> None:
    noise = 0.2
    share = effects.get("current_offset").approximation_share
    # an offset took 5 % to 2 %: 2 % left beyond noise against the 4.6 % it explains,
    # within any friction's approximation, not within an offset's
    assert not unexplained(5.0, 2.0, noise)
    assert unexplained(5.0, 2.0, noise, share=share)
    # within UNEXPLAINED_FACTOR times the noise the share does not count: an offset
    # that took 0.6 % to 0.45 % (2.25 times the noise) leaves far more than a quarter of
    # what it explains beyond noise, and is `unexplained` only from 0.5 %
    assert not unexplained(0.6, UNEXPLAINED_FACTOR * noise * 0.9, noise, share=share)
    assert unexplained(0.6, UNEXPLAINED_FACTOR * noise * 1.1, noise, share=share)
    # a verdict allows the largest share of its effects
    assert effects.approximation_share(["current_offset", "cogging"]) == APPROXIMATION_SHARE
    assert effects.approximation_share(["current_offset", "coulomb_friction"]) \
        == effects.get("coulomb_friction").approximation_share


def test_a_current_offset_named_exactly_under_a_speed_loop_stays_as_it_is() -> None:
    # benchmark seed 289 case 73: a current offset under a speed loop sampled every
    # 4.5 ms, named exactly; the nominal model's own error under the loop leaves 0.41 %
    # (3.9 times the noise gap), 0.034 times what the offset explains
    case, train, holdout = case_runs(73, 289, held_out=True, current_mean=True)
    assert case.truth == ["current_offset"]
    result = diagnose(train, holdout)
    assert result.verdict == "current_offset", result.message
    assert result.verdict_gap_percent > UNEXPLAINED_FACTOR * result.noise_gap_percent


def test_a_current_sensor_of_direction_dependent_gain_is_more_than_an_offset() -> None:
    # benchmark seed 293 (outside set UNSEEN_3) case 8: a sensor reading positive currents
    # 1.43 times too high; an offset takes the mean of the loss and leaves 14 % of the
    # holdout speed (35 times the noise gap), 0.9 times what it explains: the verdict
    # was `current_offset`
    case, train, holdout = case_runs(8, 293, outside_set="unseen_3", current_mean=True)
    assert list(case.outside) == ["sense_asymmetry"]
    result = diagnose(train, holdout)
    assert result.verdict == f"current_offset+{UNEXPLAINED}", result.message


def test_a_dry_friction_verdict_allows_a_real_axis_friction_not_what_a_mesh_leaves() -> None:
    share = effects.get("coulomb_friction").approximation_share
    # the real EMPS axis: Coulomb friction and an offset leave 0.25 of what they explain
    # beyond noise (test_real_emps_axis_has_coulomb_friction); twice that is allowed
    assert 0.25 < share < APPROXIMATION_SHARE
    assert effects.get("stribeck_friction").approximation_share == share
    # held-out benchmark seed 289 case 8: a gear mesh's friction growing with the torque
    # it carries; Coulomb friction takes its mean and leaves 0.99 % of the holdout speed
    # (16 times the noise gap), 0.98 times what it explains: the verdict was
    # `coulomb_friction`
    case, train, holdout = case_runs(8, 289, held_out=True, current_mean=True)
    assert list(case.outside) == ["mesh_friction"]
    result = diagnose(train, holdout)
    assert result.verdict == f"coulomb_friction+{UNEXPLAINED}", result.message


def test_a_gap_beyond_the_effect_free_runs_spread_of_the_noise_gap_is_unexplained() -> None:
    # effect-free benchmark runs (fresh seeds 297-298, 177 runs) leave at most 1.62 times
    # the noise gap, but for three speed loops beyond 3: 1.5 times that is beyond noise
    assert unexplained(2.8, 2.8, 1.0) and not unexplained(1.62, 1.62, 1.0)
    # benchmark seed 296 (outside set UNSEEN_6) case 27: a ball detent on the load, a
    # narrow well once a load revolution; nothing named, the nominal gap 2.99 times the
    # noise gap: the verdict was `none`
    case, train, holdout = case_runs(27, 296, outside_set="unseen_6", current_mean=True)
    assert list(case.outside) == ["ball_detent"]
    result = diagnose(train, holdout)
    assert result.verdict == UNEXPLAINED, result.message


def test_a_gap_within_the_noise_gap_is_never_unexplained_whatever_its_shape() -> None:
    # CONTRACT §3: `unexplained` is a gap beyond the noise; shapes that pass their tests
    # at any level do not make one of a gap within it, named effects or not
    strong = {"p_shapes": 1e-12, "p_along": 1e-12, "along_shrink": 0.5}
    assert not unexplained(0.99, 0.99, 1.0, **strong)
    assert unexplained(1.01, 1.01, 1.0, **strong)
    after = {"p_along": 1e-12, "along_shrink": 0.5, "p_drift": 1e-12, "drift_shrink": 0.5}
    assert not unexplained(5.0, 0.99, 1.0, named=True, **after)
    assert unexplained(5.0, 1.01, 1.0, named=True, **after)
    # fresh effect-free benchmark seed 298 case 273: a current sine of 0.9 Hz; the
    # nominal gap 0.74 times the noise gap, the quantized sine's own shapes p 4e-12 and
    # 3e-23 along the travel: the verdict was `unexplained`
    case, train, holdout = case_runs(273, 298, current_mean=True)
    assert case.truth == ["none"] and case.kind == "sine"
    result = diagnose(train, holdout)
    assert result.gap_percent < result.noise_gap_percent
    assert result.verdict == "none", result.message
    assert any("within what noise explains" in note and "CONTRACT §3" in note
               for note in result.notes), result.notes
    assert not any("cannot be told from noise" in note for note in result.notes)


def test_a_strong_speed_shape_within_the_noise_gap_is_noted_not_unexplained() -> None:
    # held-out benchmark seed 303 case 117: an eddy-current brake that Coulomb friction,
    # a backlash and D/J fit to 0.92 times the noise gap; what they leave grows with the
    # speed (p 2e-31, shrink 0.68), which the rule counts beyond the noise gap only
    case, train, holdout = case_runs(117, 303, held_out=True, current_mean=True)
    assert list(case.outside) == ["eddy_brake"]
    result = diagnose(train, holdout)
    assert result.verdict_gap_percent < result.noise_gap_percent
    assert UNEXPLAINED not in result.verdict, result.message
    assert result.speed_structure_p_value is not None
    assert result.speed_structure_p_value < FAMILY_ALPHA / 3
    assert any("a torque growing with the speed" in note and "within what noise explains"
               in note for note in result.notes), result.notes


def test_a_friction_level_drifting_over_the_run_is_no_named_models_approximation() -> None:
    noise = 0.2
    # a named effect leaving a gap within the noise: the drift shapes count from the
    # least shrink, at the level shared with the along-travel and speed tests
    assert unexplained(5.0, 0.3, noise, named=True, p_drift=FAMILY_ALPHA / 4,
                       drift_shrink=MIN_SHRINK)
    assert not unexplained(5.0, 0.3, noise, named=True, p_drift=FAMILY_ALPHA / 2,
                           drift_shrink=MIN_SHRINK)
    assert not unexplained(5.0, 0.3, noise, named=True, p_drift=1e-9,
                           drift_shrink=MIN_SHRINK / 2)
    # benchmark seed 296 (outside set UNSEEN_6) case 8: a bearing's friction falling
    # as its grease spreads with the travel; Coulomb friction takes its mean and leaves
    # a gap within the noise, its level's drift p 6e-13 (shrink 0.24): the verdict was
    # `coulomb_friction`
    case, train, holdout = case_runs(8, 296, outside_set="unseen_6", current_mean=True)
    assert list(case.outside) == ["friction_run_in"]
    result = diagnose(train, holdout)
    assert result.verdict == f"coulomb_friction+{UNEXPLAINED}", result.message
    assert result.drift_structure_p_value is not None
    assert result.drift_structure_p_value < FAMILY_ALPHA / 3
    assert any("drifting over the run" in note for note in result.notes), result.notes


def test_the_benchmark_rescores_a_row_with_its_verdicts_share() -> None:
    # a named effect took 5 % to 4 % (4 % left beyond noise, 3 % explained): a backlash's
    # approximation, but more than a cogging's model leaves
    row = {"gap_percent": 5.0, "verdict_gap_percent": 4.0, "noise_gap_percent": 0.2,
           "structure_p_value": 1.0, "position_structure_p_value": 1.0,
           "position_structure_shrink": 0.0, "speed_structure_p_value": 1.0,
           "speed_structure_shrink": 0.0}
    backlash = rescore({**row, "verdict": "backlash+unexplained", "truth": ["backlash"]})
    assert backlash["verdict"] == "backlash" and not backlash["unexplained"]
    cogging = rescore({**row, "verdict": "cogging", "truth": ["cogging"]})
    assert cogging["verdict"] == f"cogging+{UNEXPLAINED}" and cogging["unexplained"]


@pytest.mark.parametrize(("note", "truth"), [
    (f"coulomb_friction {drag.BESIDE}: ...", "outside:eddy_brake"),
    (f"the level of coulomb_friction {load_friction.GROWS}", "outside:mesh_friction")])
def test_the_benchmark_rescores_a_row_whose_friction_met_a_competitor_as_unexplained(
        note: str, truth: str) -> None:
    # a friction left 1.0 % of 5 % (0.5 of what it explains beyond noise would be its
    # approximation): with the note of a drag beside it, or of its level growing with
    # the torque carried (stand.diagnosis.drag, .load_friction), the row stays unexplained,
    # also where the gap left is within the noise gap (0.15 % against 0.2 %)
    row = {"gap_percent": 5.0, "verdict_gap_percent": 1.0, "noise_gap_percent": 0.2,
           "structure_p_value": 1.0, "position_structure_p_value": 1.0,
           "position_structure_shrink": 0.0, "speed_structure_p_value": 1.0,
           "speed_structure_shrink": 0.0, "verdict": f"coulomb_friction+{UNEXPLAINED}",
           "truth": [truth]}
    assert rescore(row)["verdict"] == "coulomb_friction"
    noted = rescore({**row, "notes": [note]})
    assert noted["verdict"] == f"coulomb_friction+{UNEXPLAINED}" and noted["unexplained"]
    # the competitor's paired test allows for the noise: within the noise gap too
    within = rescore({**row, "verdict_gap_percent": 0.15, "notes": [note]})
    assert within["verdict"] == f"coulomb_friction+{UNEXPLAINED}"


def test_an_effect_of_the_vocabulary_leaves_nothing_unexplained() -> None:
    result = diagnose(*stand_runs({"coulomb_friction": PLANTED["coulomb_friction"]}),
                      kt=MOTOR.Kt)
    assert result.verdict == "coulomb_friction", result.message
    assert result.noise_gap_percent is not None
    assert result.verdict_gap_percent <= UNEXPLAINED_FACTOR * result.noise_gap_percent


def test_the_model_holds_the_nominal_parameters_fitted_with_the_verdicts_effects() -> None:
    result = diagnose(*stand_runs({"coulomb_friction": PLANTED["coulomb_friction"]}),
                      kt=MOTOR.Kt)
    model = result.model
    # 2 % on Kt/J and Tc: a 6 s run with 0.01 A current noise identifies them to ~0.5 %;
    # D/J (2.5 1/s, a weak term beside friction) to 30 %
    np.testing.assert_allclose(model["Kt_over_J"], MOTOR.Kt / MOTOR.J, rtol=0.02)
    np.testing.assert_allclose(model["D_over_J"], MOTOR.D / MOTOR.J, rtol=0.3)
    friction = model["coulomb_friction"]
    assert isinstance(friction, dict)
    np.testing.assert_allclose(friction["Tc"], PLANTED["coulomb_friction"]["Tc"], rtol=0.02)
    # the nominal model without friction takes some of it as viscous damping
    assert abs(result.nominal["D_over_J"] - MOTOR.D / MOTOR.J) > abs(
        model["D_over_J"] - MOTOR.D / MOTOR.J)


def test_an_effect_free_run_is_none_within_the_noise() -> None:
    result = diagnose(*stand_runs({}), kt=MOTOR.Kt)
    assert result.verdict == "none", result.message
    assert result.noise_gap_percent is not None
    assert result.gap_percent <= UNEXPLAINED_FACTOR * result.noise_gap_percent
    assert result.model["Kt_over_J"] == result.nominal["Kt_over_J"]


def test_the_speed_figure_shows_the_window_where_the_nominal_model_errs_most() -> None:
    time = np.arange(0.0, 10.0, 0.01)
    error = np.where((time >= 6.0) & (time < 6.5), 1.0, 0.01)
    keep = worst_window(time, error, 3.0)
    assert keep[(time >= 6.0) & (time < 6.5)].all()
    # 3 s of samples, within one sample period (the grid of float times)
    np.testing.assert_allclose(np.ptp(time[keep]), 3.0, atol=0.011)
    assert worst_window(time, error, 12.0).all()  # a run shorter than it: all of it


def test_structure_along_the_travel_counts_only_with_a_candidates_shrink() -> None:
    # benchmark seed 261 case 69: a current-mode PRBS with a delay of the current alone.
    # With the delay named, what remains (0.47 % of HOLDOUT's speed, noise 0.33 %)
    # passes the along-travel test at p 7e-4 but shrinks HOLDOUT's equation error by
    # 0.034 only, and the verdict was `delay+unexplained`; a torque along the travel that
    # the test is for shrinks it by 0.37-0.86 (the benchmark's load unbalances)
    case, train, holdout = case_runs(69, 261)
    assert list(case.effects) == ["delay"]
    result = diagnose(train, holdout)
    assert result.verdict == "delay", result.message
    assert result.position_structure_p_value < FAMILY_ALPHA / 3
    assert result.position_structure_shrink < MIN_SHRINK


def test_a_none_beyond_the_noise_gap_says_what_it_does_not_rule_out() -> None:
    # held-out benchmark seed 310 case 6: a friction that changes along the travel
    # under a current sine, which the re-identified nominal model takes up to 1.4 times
    # the noise gap, 1.07 times what noise leaves on replays of the run, with no shape
    # left: `none`, which must not read as "nothing there"
    case, train, holdout = case_runs(6, 310, held_out=True, current_mean=True)
    assert list(case.outside) == ["position_friction"]
    result = diagnose(train, holdout)
    assert result.verdict == "none", result.message
    assert result.noise_gap_percent is not None
    assert result.replayed_noise_gap_percent is not None
    ratio = result.gap_percent / result.noise_gap_percent
    assert 1.0 < ratio <= UNEXPLAINED_FACTOR
    replayed = result.gap_percent / result.replayed_noise_gap_percent
    assert replayed <= REPLAY_FACTOR
    assert any(f"is {ratio:.1f} times what noise explains" in note
               and f"{replayed:.2f} times what it leaves on replays" in note
               and "cannot be told from noise" in note for note in result.notes), result.notes


@pytest.mark.parametrize(("seed", "index", "outside", "factor"), [
    # a friction along the travel under a current sine: 2.4 times the noise gap, 2.7
    # times the replays'
    (316, 144, "position_friction", REPLAY_FACTOR),
    # a load on an elastic shaft under a current sine: 2.1 and 1.5 times
    (318, 102, "elastic_load", REPLAY_FACTOR),
    # one under a speed sine (fresh seed 321): 2.3 and 1.66 times, not replayed before
    # stop 71
    (321, 82, "elastic_load", SPEED_LOOP_REPLAY_FACTOR),
])
def test_a_gap_beyond_what_noise_leaves_on_replays_of_the_run_is_unexplained(
        seed: int, index: int, outside: str, factor: float) -> None:
    # held-out benchmark cases the re-identified nominal model takes up to within
    # UNEXPLAINED_FACTOR times the noise gap with no shape left (both `none` before the
    # replay): the gap noise leaves on replays of HOLDOUT is sharper than that estimate
    case, train, holdout = case_runs(index, seed, held_out=True, current_mean=True)
    assert list(case.outside) == [outside]
    result = diagnose(train, holdout)
    assert result.verdict == UNEXPLAINED, result.message
    assert result.noise_gap_percent is not None
    assert result.replayed_noise_gap_percent is not None
    assert result.gap_percent <= UNEXPLAINED_FACTOR * result.noise_gap_percent
    replayed = result.gap_percent / result.replayed_noise_gap_percent
    assert replayed > factor >= REPLAY_FACTOR
    assert any(f"is {replayed:.2f} times what noise leaves on replays of HOLDOUT" in note
               and f"beyond the {factor:g} times" in note for note in result.notes), \
        result.notes
    # its size decides, not a shape: no note claims one
    assert not any("holds a shape no noise makes" in note for note in result.notes), \
        result.notes
