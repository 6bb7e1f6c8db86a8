"""The effect registry: one class per effect, found by name, used by the diagnosis, the
simulator's effect set and the benchmark; no effect dispatched by a string elsewhere."""

from __future__ import annotations

import ast
import dataclasses
from pathlib import Path
from typing import ClassVar

import pytest

from stand import effects
from stand.diagnosis import diagnose
from stand.diagnosis.model import ModelSpec
from stand.effects.coulomb_friction import CoulombFriction
from stand.errors import InputError
from stand.physics.effects import EFFECT_TYPES, VOCABULARY, Effects
from tests.bench.diagnose.benchmark import DRAWS
from tests.unit.test_diagnose_effects import PLANTED, stand_runs

ROOT = Path(__file__).resolve().parents[2]
#: Where effect names may appear as string literals: the registry itself.
REGISTRY_DIR = ROOT / "stand" / "effects"


def test_every_name_maps_to_its_own_class_in_vocabulary_order() -> None:
    assert effects.EFFECTS == ("coulomb_friction", "stribeck_friction", "cogging",
                               "current_offset", "delay", "backlash", "torque_ripple")
    for name in effects.EFFECTS:
        assert effects.get(name).name == name
    assert list(EFFECT_TYPES) == list(effects.EFFECTS)
    assert ("none", *effects.EFFECTS) == VOCABULARY


def test_the_simulators_effect_set_has_one_field_per_registered_effect() -> None:
    fields = [f.name for f in dataclasses.fields(Effects)]
    assert fields == list(effects.EFFECTS)


def test_every_effect_has_a_benchmark_draw_and_a_planted_test_case() -> None:
    assert set(DRAWS) == set(effects.EFFECTS)
    assert set(PLANTED) == set(effects.EFFECTS)


def test_unknown_effect_names_the_known_ones() -> None:
    with pytest.raises(InputError, match="effect must be one of coulomb_friction, .*not 'friction'"):
        effects.get("friction")


def test_stribeck_nests_coulomb_friction() -> None:
    assert effects.nested_in("coulomb_friction") == ["stribeck_friction"]
    assert effects.nested_in("stribeck_friction") == []


@pytest.mark.parametrize("name", effects.EFFECTS)
def test_true_structure_is_the_effect_and_only_it(name: str) -> None:
    """The structure of a planted effect models that effect, and no other effect reads
    it as present (not even Coulomb friction in Stribeck's, which holds its column)."""
    planted = Effects.from_mapping({name: PLANTED[name]}).present()
    assert [type(e).name for e in planted] == [name]
    spec = planted[0].structure()
    present = {e.name for e in effects.all_effects() if e.present(spec)}
    assert present == {name}
    assert ModelSpec().merged(spec) == spec


@pytest.mark.parametrize(("name", "params", "message"), [
    ("coulomb_friction", {"Tc": -1.0}, "x.coulomb_friction: Tc must be >= 0 N·m, got -1.0"),
    ("stribeck_friction", {"Tc": 0.2, "Ts": 0.1, "ws": 1.0}, "Ts must exceed Tc"),
    ("cogging", {"Tcog": 0.1, "N": 0}, "N must be a whole number >= 1"),
    ("delay", {"k": -1}, "k must be a whole number >= 0 samples"),
    ("backlash", {"gap": 0.01, "J_load": 0.0}, "J_load must be > 0 kg·m²"),
    ("torque_ripple", {"eps": 0.1, "N": 0}, "N must be a whole number >= 1"),
])
def test_physics_outside_its_range_names_the_field(name: str, params: dict[str, float],
                                                   message: str) -> None:
    with pytest.raises(InputError, match=message):
        Effects.from_mapping({name: params}, "x")


def _effect_literals(path: Path) -> list[str]:
    names = set(effects.EFFECTS)
    tree = ast.parse(path.read_text(encoding="utf-8"))
    return [f"{path.relative_to(ROOT)}:{node.lineno} {node.value!r}" for node in ast.walk(tree)
            if isinstance(node, ast.Constant) and node.value in names]


def test_no_effect_name_is_a_string_literal_outside_the_registry() -> None:
    """Effects are found by name in the registry only (STYLE.md principle 14): the
    product dispatches on no effect name anywhere else."""
    found = [hit for package in ("stand", "bus", "api")
             for path in sorted((ROOT / package).rglob("*.py"))
             if REGISTRY_DIR not in path.parents
             for hit in _effect_literals(path)]
    assert not found, found


@dataclasses.dataclass(frozen=True)
class _SecondCoulomb(CoulombFriction):
    """A registered effect the vocabulary does not have: Coulomb friction again."""

    name: ClassVar[str] = "second_coulomb"


def test_a_new_registered_effect_is_scored_by_the_diagnosis(monkeypatch: pytest.MonkeyPatch
                                                            ) -> None:
    """Adding an effect is one module and one registry row: the diagnosis scores it
    without any change of its own."""
    monkeypatch.setitem(effects.REGISTRY, _SecondCoulomb.name, (__name__, "_SecondCoulomb"))
    monkeypatch.setattr(effects, "EFFECTS", (*effects.EFFECTS, _SecondCoulomb.name))
    train, holdout = stand_runs({"coulomb_friction": PLANTED["coulomb_friction"]})
    result = diagnose(train, holdout)
    scores = {e.effect: e for e in result.effects}
    assert scores[_SecondCoulomb.name].gap_percent == scores["coulomb_friction"].gap_percent
    assert scores[_SecondCoulomb.name].significant
