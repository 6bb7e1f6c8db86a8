"""The benchmark's oracle visibility: a planted effect that changes the holdout speed
beyond noise is visible, one far below the noise is not (answer-key side only)."""

from __future__ import annotations

from tests.bench.diagnose.oracle import ENGINE_TESTS, resolved_truth, visibility, visible_against_twin
from tests.unit.test_diagnose_effects import MOTOR, stand_runs


def test_clear_cogging_is_visible_and_its_exact_model_shrinks_the_gap() -> None:
    effects = {"cogging": {"Tcog": 0.003, "N": 12, "phi": 0.5}}
    result = visibility(*stand_runs(effects), MOTOR, effects)
    assert result.visible, result
    # 40 %: the engine's own cogging candidate shrinks this case by more than that
    # (test_diagnose_effects); the exact parameters must do at least as well.
    assert result.shrink > 0.4, result


def test_friction_far_below_the_noise_is_not_visible() -> None:
    # 2e-6 N·m is 0.1 % of the ± 0.025 N·m drive torque, below the 0.01 A current
    # noise (5e-4 N·m): nothing a holdout test can resolve.
    effects = {"coulomb_friction": {"Tc": 2e-6}}
    result = visibility(*stand_runs(effects), MOTOR, effects)
    assert not result.visible, result
    assert abs(result.shrink) < 0.05, result


def test_a_static_excess_the_runs_show_is_visible_beyond_coulomb_friction() -> None:
    # the planted Stribeck friction of test_diagnose_effects: Ts four times Tc
    effects = {"stribeck_friction": {"Tc": 0.002, "Ts": 0.008, "ws": 5.0}}
    result = visibility(*stand_runs(effects), MOTOR, effects)
    assert result.visible and result.nested == {}, result
    assert resolved_truth(["stribeck_friction"], result.nested) == ["stribeck_friction"]


def test_a_static_excess_below_the_noise_resolves_to_coulomb_friction() -> None:
    # Ts 1 % above Tc (4e-5 N·m, a tenth of the 0.01 A current noise's 5e-4 N·m): the
    # friction shows, its static excess does not
    effects = {"stribeck_friction": {"Tc": 0.004, "Ts": 0.00404, "ws": 5.0}}
    result = visibility(*stand_runs(effects), MOTOR, effects)
    assert result.visible, result
    assert result.nested == {"stribeck_friction": "coulomb_friction"}, result
    assert resolved_truth(["stribeck_friction", "cogging"], result.nested) == [
        "coulomb_friction", "cogging"]


def test_an_effect_shows_against_its_twin_runs_only_when_it_changes_the_errors() -> None:
    # twin runs: the same commands, sensors and noise seeds without the effect
    twin = stand_runs({})
    friction = {"coulomb_friction": {"Tc": 0.004}}
    assert visible_against_twin(stand_runs(friction), twin, MOTOR, {}, ENGINE_TESTS)
    # 2e-6 N·m, far below the current noise: no more error than the twin's
    weak = {"coulomb_friction": {"Tc": 2e-6}}
    assert not visible_against_twin(stand_runs(weak), twin, MOTOR, {}, ENGINE_TESTS)


def test_a_second_effect_shows_against_the_exact_model_of_the_first() -> None:
    # cogging beside the friction, judged with the friction's exact model in both
    friction = {"coulomb_friction": {"Tc": 0.004}}
    both = {**friction, "cogging": {"Tcog": 0.003, "N": 12, "phi": 0.5}}
    twin = stand_runs(friction)
    assert visible_against_twin(stand_runs(both), twin, MOTOR, friction, ENGINE_TESTS - 1)
    tiny = {**friction, "cogging": {"Tcog": 3e-6, "N": 12, "phi": 0.5}}
    assert not visible_against_twin(stand_runs(tiny), twin, MOTOR, friction, ENGINE_TESTS - 1)
