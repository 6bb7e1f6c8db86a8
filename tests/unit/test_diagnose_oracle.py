"""The benchmark's oracle visibility: a planted effect that changes the holdout speed
beyond noise is visible, one far below the noise is not (answer-key side only)."""

from __future__ import annotations

from tests.bench.diagnose.oracle import resolved_truth, visibility
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
