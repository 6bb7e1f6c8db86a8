"""Torque ripple: a torque ``Kt·i·(1 + ε·sin(N·θ + φ))``."""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import ClassVar

import numpy as np

from stand.diagnosis.model import FittedModel, ModelSpec
from stand.diagnosis.signals import Signals
from stand.effects.base import Effect, Params, Simulated, fitted, phase, ratio_ok
from stand.effects.periodic import (
    check_order,
    harmonic_params,
    ident_orders,
    in_phase,
    search_order,
)


@dataclass(frozen=True)
class TorqueRipple(Effect):
    """Torque ``Kt·i·(1 + ε·sin(N·θ + φ))``.

    Parameters
    ----------
    eps : float
        Relative ripple amplitude ε, 1 (below 1).
    N : int
        Cycles per revolution.
    phi : float
        Phase, rad.
    """

    name: ClassVar[str] = "torque_ripple"
    columns: ClassVar[tuple[str, ...]] = ("rip_sin", "rip_cos")
    spec_fields: ClassVar[tuple[str, ...]] = ("ripple_N",)
    picked_by_simulation: ClassVar[bool] = True
    units: ClassVar[dict[str, str]] = {"eps": "1", "N": "cycles/rev", "phi": "rad"}

    eps: float
    N: int
    phi: float = 0.0

    def check(self, where: str) -> None:
        check_order(self.N, where)

    def structure(self) -> ModelSpec:
        return ModelSpec(ripple_N=int(self.N))

    def true_coefficients(self, Kt: float) -> dict[str, float]:
        return {"rip_sin": self.eps * math.cos(self.phi),
                "rip_cos": self.eps * math.sin(self.phi)}

    @classmethod
    def search(cls, base: ModelSpec, train: Signals,
               simulated: Simulated | None = None) -> ModelSpec:
        """The order of smallest equation error among those the run resolves, or among
        the few smallest the one that simulates the run best where orders turn fast
        within a sample (:func:`~stand.effects.periodic.search_order`)."""
        return search_order(base, train, lambda n: ModelSpec(ripple_N=n), simulated)

    @classmethod
    def agree(cls, first: FittedModel, second: FittedModel) -> bool:
        """The same order, in phase, ``0 < ε < 1`` on both runs (the torque keeps the
        sign of the current), sizes within ``AGREE_RATIO``."""
        if not fitted(first, second):
            return False
        ok, size_a, size_b = in_phase(first, second, "rip")
        if not ok:
            return False
        size_a, size_b = size_a / first.coef["current"], size_b / second.coef["current"]
        if not (0 < size_a < 1 and 0 < size_b < 1):
            return False
        return first.spec.ripple_N == second.spec.ripple_N and ratio_ok(size_a, size_b)

    @classmethod
    def params(cls, model: FittedModel, kt: float | None) -> Params:
        amplitude, angle = phase(model, "rip")
        return {"eps": amplitude / model.coef["current"], "N": model.spec.ripple_N,
                "phi": angle}

    @classmethod
    def ident_grid(cls, base: ModelSpec, sig: Signals) -> list[ModelSpec]:
        """The orders of which the run's travel spans at least one whole cycle: ``Kt`` is
        the torque per current averaged over a revolution, and over less than a cycle
        ``i·sin(N·θ + φ)`` is nearly ``i`` times a constant, which trades with ``Kt``
        (EMPS, 0.25 m of travel: order 1 takes ``ε`` 0.63 and Kt/J 2.7 times the
        truth, and explains the run as well)."""
        travel = float(np.ptp(sig.theta))
        return ident_orders(lambda n: replace(base, ripple_N=n),
                            lambda n: n * travel >= 2 * math.pi)

    @classmethod
    def ident_params(cls, spec: ModelSpec, coef: Callable[[str], float]) -> dict[str, float]:
        return harmonic_params(coef, "rip", spec.ripple_N, "eps")
