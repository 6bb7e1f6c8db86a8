"""The effect vocabulary of CONTRACT §3 as switchable physics.

Each effect is a small frozen dataclass whose fields are its parameters in SI units, one
module each in :mod:`stand.effects`; :class:`Effects` holds at most one of each.
``Effects.from_mapping`` builds one from plain data (a profile, the command line, JSON)
and names the bad field when it fails.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from stand.effects import NONE, UNEXPLAINED, all_effects
from stand.effects.backlash import Backlash
from stand.effects.base import Effect
from stand.effects.cogging import Cogging
from stand.effects.coulomb_friction import CoulombFriction
from stand.effects.current_offset import CurrentOffset
from stand.effects.delay import Delay
from stand.effects.stribeck_friction import StribeckFriction
from stand.effects.torque_ripple import TorqueRipple
from stand.errors import InputError

#: Vocabulary name (CONTRACT §3) to the class that models it (:mod:`stand.effects`).
EFFECT_TYPES: dict[str, type[Effect]] = {effect.name: effect for effect in all_effects()}

#: Every name of the vocabulary, ``none`` first.
VOCABULARY: tuple[str, ...] = (NONE, *EFFECT_TYPES)
#: Every word a verdict may hold (CONTRACT §3): the vocabulary and ``unexplained``.
VERDICT_WORDS: tuple[str, ...] = (*VOCABULARY, UNEXPLAINED)


@dataclass(frozen=True)
class Effects:
    """The unmodelled effects present in a simulated stand (each ``None`` when absent)."""

    coulomb_friction: CoulombFriction | None = None
    stribeck_friction: StribeckFriction | None = None
    cogging: Cogging | None = None
    current_offset: CurrentOffset | None = None
    delay: Delay | None = None
    backlash: Backlash | None = None
    torque_ripple: TorqueRipple | None = None

    def names(self) -> list[str]:
        """Names of the effects present, in vocabulary order (``["none"]`` if none)."""
        present = [f.name for f in dataclasses.fields(self) if getattr(self, f.name)]
        return present or [NONE]

    def present(self) -> list[Effect]:
        """The effects present, in vocabulary order."""
        return [getattr(self, f.name) for f in dataclasses.fields(self)
                if getattr(self, f.name) is not None]

    def to_mapping(self) -> dict[str, dict[str, float]]:
        """Plain data: effect name to its parameters."""
        return {
            f.name: dataclasses.asdict(getattr(self, f.name))
            for f in dataclasses.fields(self)
            if getattr(self, f.name) is not None
        }

    @classmethod
    def from_mapping(cls, data: Mapping[str, Any] | None, where: str = "effects") -> Effects:
        """Build from ``{name: {param: value}}``; ``none`` entries are skipped.

        Raises
        ------
        InputError
            Unknown effect or parameter, missing or non-finite value, or a value outside
            the physics (negative friction, ``Ts <= Tc``, ...), naming ``where.name.param``.
        """
        if not data:
            return cls()
        built: dict[str, Any] = {}
        for name, params in data.items():
            if name == NONE:
                continue
            if name not in EFFECT_TYPES:
                raise InputError(
                    f"{where}: unknown effect {name!r}; known: {', '.join(VOCABULARY)}"
                )
            built[name] = _build(EFFECT_TYPES[name], params or {}, f"{where}.{name}")
        return cls(**built)


def _build(kind: type[Effect], params: Mapping[str, Any], where: str) -> Effect:
    fields = {f.name: f for f in dataclasses.fields(kind)}
    unknown = set(params) - set(fields)
    if unknown:
        raise InputError(
            f"{where}: unknown parameter(s) {', '.join(sorted(unknown))}; "
            f"expected {', '.join(fields)}"
        )
    values: dict[str, Any] = {}
    for name, field in fields.items():
        if name not in params:
            if field.default is dataclasses.MISSING:
                raise InputError(f"{where}.{name}: missing; expected a number")
            continue
        try:
            value = float(params[name])
        except (TypeError, ValueError):
            raise InputError(
                f"{where}.{name}: {params[name]!r} is not a number"
            ) from None
        if not math.isfinite(value):
            raise InputError(f"{where}.{name}: {value} is not finite")
        if field.type in ("int", int) and value != round(value):
            raise InputError(f"{where}.{name}: {value:g} is not a whole number")
        values[name] = int(round(value)) if field.type in ("int", int) else value
    effect = kind(**values)
    effect.check(where)
    return effect


__all__ = ["EFFECT_TYPES", "VERDICT_WORDS", "VOCABULARY", "Backlash", "Cogging", "CoulombFriction",
           "CurrentOffset", "Delay", "Effects", "StribeckFriction", "TorqueRipple"]
