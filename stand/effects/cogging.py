"""Cogging: a torque ``Tcog·sin(N·θ + φ)`` independent of current."""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import ClassVar

from stand.diagnosis.model import FittedModel, ModelSpec
from stand.diagnosis.signals import Signals
from stand.effects.base import Effect, Params, Simulated, fitted, phase, ratio_ok, torque
from stand.effects.periodic import (
    check_order,
    harmonic_params,
    ident_orders,
    in_phase,
    search_order,
)


@dataclass(frozen=True)
class Cogging(Effect):
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

    name: ClassVar[str] = "cogging"
    columns: ClassVar[tuple[str, ...]] = ("cog_sin", "cog_cos")
    spec_fields: ClassVar[tuple[str, ...]] = ("cogging_N",)
    picked_by_simulation: ClassVar[bool] = True
    units: ClassVar[dict[str, str]] = {"Tcog_over_Kt_A": "A", "Tcog": "N·m",
                                       "N": "cycles/rev", "phi": "rad"}

    Tcog: float
    N: int
    phi: float = 0.0

    def check(self, where: str) -> None:
        check_order(self.N, where)

    def structure(self) -> ModelSpec:
        return ModelSpec(cogging_N=int(self.N))

    def true_coefficients(self, Kt: float) -> dict[str, float]:
        # the plant subtracts Tcog·sin(Nθ + φ)
        return {"cog_sin": -self.Tcog / Kt * math.cos(self.phi),
                "cog_cos": -self.Tcog / Kt * math.sin(self.phi)}

    @classmethod
    def search(cls, base: ModelSpec, train: Signals,
               simulated: Simulated | None = None) -> ModelSpec:
        """The order of smallest equation error among those the run resolves, or among
        the few smallest the one that simulates the run best where orders turn fast
        within a sample (:func:`~stand.effects.periodic.search_order`)."""
        return search_order(base, train, lambda n: ModelSpec(cogging_N=n), simulated)

    @classmethod
    def agree(cls, first: FittedModel, second: FittedModel) -> bool:
        """The same order, in phase (the runs must share the encoder's zero), sizes
        within ``AGREE_RATIO``."""
        if not fitted(first, second):
            return False
        ok, size_a, size_b = in_phase(first, second, "cog")
        return (ok and first.spec.cogging_N == second.spec.cogging_N
                and ratio_ok(size_a, size_b))

    @classmethod
    def params(cls, model: FittedModel, kt: float | None) -> Params:
        amplitude, angle = phase(model, "cog")
        out: Params = {}
        torque(amplitude, model, kt, "Tcog", out)
        out["N"] = model.spec.cogging_N
        out["phi"] = math.atan2(-math.sin(angle), -math.cos(angle))  # torque is −Tcog·sin
        return out

    @classmethod
    def ident_grid(cls, base: ModelSpec, sig: Signals) -> list[ModelSpec]:
        return ident_orders(lambda n: replace(base, cogging_N=n))

    @classmethod
    def ident_params(cls, spec: ModelSpec, coef: Callable[[str], float]) -> dict[str, float]:
        return harmonic_params(coef, "cog", spec.cogging_N, "Tcog_over_Kt_A")
