"""How the verdict is built and what it says it cannot tell: each effect of a verdict
with its test as an addition to the ones before it, and an answer (with the pair that
cannot be separated, and the experiment that would) on runs that never reverse."""

from __future__ import annotations

from stand import effects
from stand.diagnosis import Diagnosis, diagnose
from stand.excitation import excitation
from stand.physics.effects import Effects
from stand.physics.parts import DriveParams
from stand.physics.plant import MotorPlant
from stand.physics.simulate import simulate_motor
from stand.runfile import Run
from tests.unit.test_diagnose_effects import DT_S, MOTOR, PLANTED, SENSORS, stand_runs

#: A current command of 0.6 ± 0.3 A: the shaft of the test motor (Kt 0.05 N·m/A, 4 mN·m
#: of Coulomb friction) is driven one way only, from standstill to about 600 rad/s.
ONE_WAY_LEVEL_A, ONE_WAY_AMPLITUDE_A = 0.6, 0.3


def _one_way_runs(planted: dict[str, dict[str, float]]) -> tuple[Run, Run]:
    runs = []
    for k, hold in enumerate((50, 35)):
        plant = MotorPlant(MOTOR, DriveParams(mode="current"), SENSORS,
                           Effects.from_mapping(planted), seed=1 + k)
        command = excitation("prbs", 6000, DT_S, ONE_WAY_LEVEL_A, ONE_WAY_AMPLITUDE_A, hold,
                             seed=1 + k)
        runs.append(simulate_motor(plant, "current", command, DT_S))
    return runs[0], runs[1]


def _assert_steps_build_the_verdict(result: Diagnosis) -> None:
    names = result.verdict.split("+")
    assert [s.effect for s in result.steps] == names, result.steps
    for k, step in enumerate(result.steps):
        assert step.after == names[:k]
        assert step.shrink == 1.0 - step.gap_percent / step.gap_before_percent
    assert result.steps[0].gap_before_percent == result.gap_percent
    assert result.steps[-1].gap_percent == result.verdict_gap_percent


def test_a_run_that_never_reverses_gets_an_answer_naming_the_pair() -> None:
    """Coulomb friction and a current offset are the same constant torque on a shaft
    that turns one way: the model with both is not determined. The diagnosis answers
    with one of them, says which pair it cannot separate, and which run would."""
    train, holdout = _one_way_runs({"coulomb_friction": PLANTED["coulomb_friction"]})
    assert min(train["velocity_rad_s"][100:]) > 0 and min(holdout["velocity_rad_s"][100:]) > 0
    result = diagnose(train, holdout, kt=MOTOR.Kt)
    first = result.verdict.split("+")[0]
    assert first in ("coulomb_friction", "current_offset"), result.message
    assert "current_offset" not in result.verdict.split("+")[1:]
    other = ({"coulomb_friction", "current_offset"} - {first}).pop()
    note = next(n for n in result.notes if n.startswith(f"{other} and {first} cannot"))
    assert effects.get(first).separated_by in note and "crosses zero" in note, note
    _assert_steps_build_the_verdict(result)


def test_steps_of_a_verdict_of_one_effect() -> None:
    result = diagnose(*stand_runs({"cogging": PLANTED["cogging"]}))
    assert result.verdict == "cogging", result.message
    _assert_steps_build_the_verdict(result)
    table = next(e for e in result.effects if e.effect == "cogging")
    assert result.steps[0].gap_percent == table.gap_percent
    assert result.steps[0].p_value == table.p_value


def test_an_effect_free_verdict_has_no_steps() -> None:
    result = diagnose(*stand_runs({}))
    assert result.verdict == "none" and result.steps == []
