"""The shipped diagnosis experiment (profiles/experiments/diagnosis_reversing.yaml): runs
that turn the shaft both ways, so that a diagnosis of them names Coulomb friction instead
of the pair it cannot separate on forward-only runs."""

from __future__ import annotations

import numpy as np
import pytest

from stand.controller import load_experiment, plan
from stand.diagnosis import diagnose
from stand.procedures import simulate_procedure
from stand.profiles import load_motor

#: Long enough for a holdout test of 29 segments, short enough for a unit test.
DURATION_S = 3.0


def test_the_diagnosis_profile_commands_both_ways() -> None:
    experiment = load_experiment("diagnosis_reversing")
    runs = plan(experiment)
    assert len(runs) == 2  # TRAIN and HOLDOUT
    for procedure, _drives in runs:
        (port,) = procedure.commands
        assert port.mode == "speed"
        assert port.values.min() < 0 < port.values.max()
    first, second = (p.commands[0].values for p, _ in runs)
    assert not np.allclose(first, second)  # two experiments, not one twice


def test_a_diagnosis_of_its_runs_names_the_coulomb_friction() -> None:
    experiment = load_experiment("diagnosis_reversing").model_copy(
        update={"duration_s": DURATION_S})
    motor = load_motor(experiment.motor or "")
    train, holdout = (simulate_procedure(p, motor, seed=k + 1)
                      for k, (p, _) in enumerate(plan(experiment)))
    for run in (train, holdout):
        assert run["velocity_rad_s"].min() < 0 < run["velocity_rad_s"].max()
    result = diagnose(train, holdout, kt=motor.motor.Kt)
    assert result.verdict.split("+")[0] == "coulomb_friction", result.message
    assert not any("cannot be told apart" in note for note in result.notes), result.notes
    # 10 %: a 3 s run at 10 mA current noise; the friction is about 0.23 A of current
    planted = motor.effects["coulomb_friction"]["Tc"]
    assert result.verdict_params["coulomb_friction"]["Tc"] == pytest.approx(planted, rel=0.1)
