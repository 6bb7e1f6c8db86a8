"""Coulomb friction: a torque ``Tc·sign(ω)`` opposing motion."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import ClassVar

from stand.diagnosis.model import FittedModel, ModelSpec
from stand.diagnosis.signals import Signals
from stand.effects.base import REVERSING_COMMAND, Effect, Params, Simulated, fitted, need, ratio_ok, torque


@dataclass(frozen=True)
class CoulombFriction(Effect):
    """Torque ``Tc·sign(ω)`` opposing motion.

    Parameters
    ----------
    Tc : float
        Coulomb friction torque, N·m (>= 0).
    """

    name: ClassVar[str] = "coulomb_friction"
    columns: ClassVar[tuple[str, ...]] = ("sign",)
    spec_fields: ClassVar[tuple[str, ...]] = ("coulomb",)
    units: ClassVar[dict[str, str]] = {"Tc_over_Kt_A": "A", "Tc": "N·m"}
    # friction changes sign with the speed, a constant torque does not
    separated_by: ClassVar[str] = REVERSING_COMMAND

    Tc: float

    def check(self, where: str) -> None:
        need(self.Tc >= 0, where, f"Tc must be >= 0 N·m, got {self.Tc}")

    def structure(self) -> ModelSpec:
        return ModelSpec(coulomb=True)

    def true_coefficients(self, Kt: float) -> dict[str, float]:
        return {"sign": -self.Tc / Kt}

    @classmethod
    def present(cls, spec: ModelSpec) -> bool:
        return spec.coulomb

    @classmethod
    def search(cls, base: ModelSpec, train: Signals,
               simulated: Simulated | None = None) -> ModelSpec:
        return base.merged(ModelSpec(coulomb=True))

    @classmethod
    def agree(cls, first: FittedModel, second: FittedModel) -> bool:
        ca, cb = first.coef, second.coef
        return fitted(first, second) and ca["sign"] < 0 and ratio_ok(ca["sign"], cb["sign"])

    @classmethod
    def params(cls, model: FittedModel, kt: float | None) -> Params:
        out: Params = {}
        torque(-model.coef["sign"], model, kt, "Tc", out)
        return out

    @classmethod
    def ident_grid(cls, base: ModelSpec, sig: Signals) -> list[ModelSpec]:
        return [replace(base, coulomb=True)]

    @classmethod
    def ident_params(cls, spec: ModelSpec, coef: Callable[[str], float]) -> dict[str, float]:
        return {"Tc_over_Kt_A": -coef("sign") / coef("current")}
