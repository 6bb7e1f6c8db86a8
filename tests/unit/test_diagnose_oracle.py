"""The benchmark's oracle visibility: a planted effect that changes the holdout speed
beyond noise is visible, one far below the noise is not (answer-key side only)."""

from __future__ import annotations

from tests.bench.diagnose.oracle import visibility
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
