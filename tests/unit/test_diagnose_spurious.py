"""No spurious effects in a verdict (issue 21, item 4), and every effect of a verdict
explained (item 6).

The case of the issue: the Crouzet profile (its own Coulomb friction of 0.012 N·m) with
a planted cogging torque, two 10 s runs at 1 kHz under a noise speed command that
crosses zero. Nothing else is planted, so a verdict naming anything beyond Coulomb
friction and cogging names an effect that is not there.
"""

from __future__ import annotations

import pytest

from stand.diagnosis import Diagnosis, diagnose
from stand.runfile import Run
from stand.simulation import simulate

CROUZET = "crouzet_82800502"
#: The profile's torque constant, N·m/A.
CROUZET_KT = 0.0527
#: Cogging planted on it: 3 mN·m (a quarter of its Coulomb friction), 12 cycles/rev.
PLANTED_COGGING = {"Tcog": 0.003, "N": 12, "phi": 0.5}


def _crouzet_runs() -> tuple[Run, Run]:
    train, holdout = (simulate(CROUZET, 10.0, period_s=0.001, excitation="noise", level=0.0,
                               amplitude=100.0, hold=50,
                               effects={"cogging": PLANTED_COGGING}, seed=seed)
                      for seed in (1, 2))
    return train, holdout


@pytest.fixture(scope="module")
def crouzet() -> Diagnosis:
    return diagnose(*_crouzet_runs(), kt=CROUZET_KT)


@pytest.mark.xfail(strict=True, reason=(
    "issue 21 item 4 open: a light load (J_l/J 0.05) behind a half-gap of 0.19 rad is "
    "consistent on both runs and needed beside the others (joint removal p ~1e-15); "
    "docs/results/diagnose.md, 'Pairs named exactly'"))
def test_crouzet_with_cogging_names_no_backlash(crouzet: Diagnosis) -> None:
    assert sorted(crouzet.verdict.split("+")) == ["coulomb_friction", "cogging"], \
        crouzet.message


def test_crouzet_with_cogging_names_both_planted_effects(crouzet: Diagnosis) -> None:
    named = crouzet.verdict.split("+")
    assert named[0] == "coulomb_friction" and "cogging" in named, crouzet.message
    cogging = crouzet.verdict_params["cogging"]
    assert cogging["N"] == PLANTED_COGGING["N"]
    # 30 %: a cogging torque a quarter of the friction, under a speed loop
    assert cogging["Tcog"] == pytest.approx(PLANTED_COGGING["Tcog"], rel=0.3)


def test_every_verdict_effect_has_its_test(crouzet: Diagnosis) -> None:
    """Item 6: an effect that is "significant: no" in the table (scored alone against
    the nominal model) is in the verdict only with the test that let it in, as an
    addition to the effects before it, and that test passed."""
    named = crouzet.verdict.split("+")
    assert [s.effect for s in crouzet.steps] == named
    table = {e.effect: e for e in crouzet.effects}
    for k, step in enumerate(crouzet.steps):
        assert step.after == named[:k]
        assert step.p_value < 0.01 and step.shrink >= 0.05, step
        if k == 0:
            assert table[step.effect].significant
    as_json = crouzet.to_json()
    assert [s["effect"] for s in as_json["steps"]] == named
