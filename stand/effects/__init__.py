"""The effect vocabulary of CONTRACT §3: one module per effect, found by name.

Like python-can's ``BACKENDS`` table, :data:`REGISTRY` maps each name to the module and
class that define it, imported when first asked for. Each class
(:class:`~stand.effects.base.Effect`) holds the effect's physical parameters (what the
stand simulator uses) and how the diagnosis models, searches and checks it. Adding an
effect is one new module here, one row in :data:`REGISTRY`, and its tests; the
diagnosis, the simulator's ``Effects`` and the benchmark iterate the registry.

>>> from stand import effects
>>> effects.get("coulomb_friction")(Tc=0.01).structure().coulomb
True
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING

from stand.errors import InputError

if TYPE_CHECKING:
    from stand.effects.base import Effect

#: Vocabulary name to (module, class), in vocabulary order (the order candidates are
#: scored and listed in).
REGISTRY: dict[str, tuple[str, str]] = {
    "coulomb_friction": ("stand.effects.coulomb_friction", "CoulombFriction"),
    "stribeck_friction": ("stand.effects.stribeck_friction", "StribeckFriction"),
    "cogging": ("stand.effects.cogging", "Cogging"),
    "current_offset": ("stand.effects.current_offset", "CurrentOffset"),
    "delay": ("stand.effects.delay", "Delay"),
    "backlash": ("stand.effects.backlash", "Backlash"),
    "torque_ripple": ("stand.effects.torque_ripple", "TorqueRipple"),
}

#: Effect names in vocabulary order (the verdict words ``none`` and ``unexplained``
#: excluded).
EFFECTS: tuple[str, ...] = tuple(REGISTRY)
#: The verdict when the nominal gap is within what noise and quantization explain.
NONE = "none"
#: The verdict word for a gap beyond noise that the verdict's effects leave (CONTRACT §3).
UNEXPLAINED = "unexplained"


def get(name: str) -> type[Effect]:
    """The class of effect ``name``.

    Raises
    ------
    InputError
        ``name`` is not an effect of the vocabulary.
    """
    if name not in REGISTRY:
        raise InputError(f"effect must be one of {', '.join(EFFECTS)}, not {name!r}")
    module, cls = REGISTRY[name]
    effect: type[Effect] = getattr(importlib.import_module(module), cls)
    return effect


def all_effects() -> list[type[Effect]]:
    """Every effect class, in vocabulary order."""
    return [get(name) for name in EFFECTS]


def nested_in(name: str) -> list[str]:
    """Names of the effects that contain effect ``name`` as a special case."""
    return [outer.name for outer in all_effects() if name in outer.nests]


def approximation_share(names: list[str]) -> float:
    """What a verdict naming ``names`` may leave beyond noise, as a share of what it
    explains: the largest of its effects' :attr:`~stand.effects.base.Effect.
    approximation_share` (:data:`stand.diagnosis.noise.APPROXIMATION_SHARE` with none)."""
    from stand.diagnosis.noise import APPROXIMATION_SHARE  # stand.diagnosis imports this

    return max((get(name).approximation_share for name in names), default=APPROXIMATION_SHARE)


__all__ = ["EFFECTS", "NONE", "UNEXPLAINED", "REGISTRY", "all_effects", "approximation_share",
           "get", "nested_in"]
