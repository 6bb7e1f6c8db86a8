"""The effect vocabulary of CONTRACT §3 as switchable physics.

Each effect is a small frozen dataclass whose fields are its parameters in SI units;
:class:`Effects` holds at most one of each. ``Effects.from_mapping`` builds one from
plain data (a profile, the command line, JSON) and names the bad field when it fails.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from stand.errors import InputError


@dataclass(frozen=True)
class CoulombFriction:
    """Torque ``Tc·sign(ω)`` opposing motion.

    Parameters
    ----------
    Tc : float
        Coulomb friction torque, N·m (>= 0).
    """

    Tc: float


@dataclass(frozen=True)
class StribeckFriction:
    """``(Tc + (Ts − Tc)·exp(−(ω/ωs)²))·sign(ω)`` with ``Ts > Tc``.

    Parameters
    ----------
    Tc : float
        Coulomb level, N·m.
    Ts : float
        Static (breakaway) level, N·m, greater than ``Tc``.
    ws : float
        Stribeck velocity, rad/s (> 0).
    """

    Tc: float
    Ts: float
    ws: float


@dataclass(frozen=True)
class Cogging:
    """Torque ``Tcog·sin(N·θ + φ)``, independent of current.

    Parameters
    ----------
    Tcog : float
        Amplitude, N·m.
    N : int
        Cycles per revolution.
    phi : float
        Phase, rad.
    """

    Tcog: float
    N: int
    phi: float = 0.0


@dataclass(frozen=True)
class CurrentOffset:
    """Measured current = true current + ``i0`` (A)."""

    i0: float


@dataclass(frozen=True)
class Delay:
    """Current samples lag the encoder samples by ``k`` sample periods."""

    k: int


@dataclass(frozen=True)
class Backlash:
    """Dead zone of ± ``gap`` rad between the motor shaft and a load inertia.

    Parameters
    ----------
    gap : float
        Half width of the dead zone, rad.
    J_load : float
        Inertia of the load behind the dead zone, kg·m².
    stiffness : float
        Contact stiffness, N·m/rad; 0 picks one with a 150 Hz contact mode.
    """

    gap: float
    J_load: float
    stiffness: float = 0.0


@dataclass(frozen=True)
class TorqueRipple:
    """Torque ``Kt·i·(1 + ε·sin(N·θ + φ))``."""

    eps: float
    N: int
    phi: float = 0.0


#: Vocabulary name (CONTRACT §3) to the class that models it.
EFFECT_TYPES: dict[str, type] = {
    "coulomb_friction": CoulombFriction,
    "stribeck_friction": StribeckFriction,
    "cogging": Cogging,
    "current_offset": CurrentOffset,
    "delay": Delay,
    "backlash": Backlash,
    "torque_ripple": TorqueRipple,
}

#: Every name of the vocabulary, ``none`` first.
VOCABULARY: tuple[str, ...] = ("none", *EFFECT_TYPES)


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
        return present or ["none"]

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
            if name == "none":
                continue
            if name not in EFFECT_TYPES:
                raise InputError(
                    f"{where}: unknown effect {name!r}; known: {', '.join(VOCABULARY)}"
                )
            built[name] = _build(EFFECT_TYPES[name], params or {}, f"{where}.{name}")
        return cls(**built)


def _build(kind: type, params: Mapping[str, Any], where: str) -> Any:
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
    _check_physics(effect, where)
    return effect


def _check_physics(effect: Any, where: str) -> None:
    def need(condition: bool, text: str) -> None:
        if not condition:
            raise InputError(f"{where}: {text}")

    if isinstance(effect, CoulombFriction):
        need(effect.Tc >= 0, f"Tc must be >= 0 N·m, got {effect.Tc}")
    elif isinstance(effect, StribeckFriction):
        need(effect.Tc >= 0, f"Tc must be >= 0 N·m, got {effect.Tc}")
        need(effect.Ts > effect.Tc, f"Ts must exceed Tc, got Ts={effect.Ts}, Tc={effect.Tc}")
        need(effect.ws > 0, f"ws must be > 0 rad/s, got {effect.ws}")
    elif isinstance(effect, (Cogging, TorqueRipple)):
        need(effect.N >= 1, f"N must be a whole number >= 1 cycle/rev, got {effect.N}")
    elif isinstance(effect, Delay):
        need(effect.k >= 0, f"k must be a whole number >= 0 samples, got {effect.k}")
    elif isinstance(effect, Backlash):
        need(effect.gap >= 0, f"gap must be >= 0 rad, got {effect.gap}")
        need(effect.J_load > 0, f"J_load must be > 0 kg·m², got {effect.J_load}")
        need(effect.stiffness >= 0, f"stiffness must be >= 0 N·m/rad, got {effect.stiffness}")
