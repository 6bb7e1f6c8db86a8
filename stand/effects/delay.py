"""Delay: the current samples lag the encoder samples by ``k`` sample periods."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import ClassVar

from stand.diagnosis.model import FittedModel, ModelSpec
from stand.diagnosis.signals import Signals
from stand.effects.base import NO_FIT, Effect, Params, Simulated, best, fitted, need

#: Largest current delay searched, samples.
MAX_DELAY_SAMPLES = 10
#: Largest current delay the identification tries, samples.
IDENT_MAX_DELAY_SAMPLES = 6
#: Largest difference of the delays found on TRAIN and HOLDOUT that still agrees, samples.
DELAY_TOLERANCE_SAMPLES = 1


def delay_grid(base: ModelSpec) -> list[ModelSpec]:
    """``base`` with each delay searched, 1 to ``MAX_DELAY_SAMPLES`` samples and one
    beyond (where a best fit is an optimum the search does not bracket)."""
    return [base.merged(ModelSpec(delay=k)) for k in range(1, MAX_DELAY_SAMPLES + 2)]


@dataclass(frozen=True)
class Delay(Effect):
    """Current samples lag the encoder samples by ``k`` sample periods.

    Parameters
    ----------
    k : int
        Delay, samples (>= 0).
    """

    name: ClassVar[str] = "delay"
    spec_fields: ClassVar[tuple[str, ...]] = ("delay",)
    units: ClassVar[dict[str, str]] = {"k": "samples"}
    # on a current of one frequency a delay is a phase lag that Kt/J and D/J absorb
    across_runs_on_one_tone: ClassVar[bool] = True

    k: int

    def check(self, where: str) -> None:
        need(self.k >= 0, where, f"k must be a whole number >= 0 samples, got {self.k}")

    def structure(self) -> ModelSpec:
        return ModelSpec(delay=int(self.k))

    @classmethod
    def present(cls, spec: ModelSpec) -> bool:
        return spec.delay > 0

    @classmethod
    def search(cls, base: ModelSpec, train: Signals,
               simulated: Simulated | None = None) -> ModelSpec:
        """The delay of smallest equation error; :data:`NO_FIT` when that is beyond
        ``MAX_DELAY_SAMPLES`` (the error still falls at the end of the grid: a fit of
        something else, such as the nominal model's own error on a speed loop)."""
        found = best(delay_grid(base), train)
        return found if cls.bracketed(found) else NO_FIT

    @classmethod
    def agree(cls, first: FittedModel, second: FittedModel) -> bool:
        # a delay is resolved to a sample at best; the input reconstruction weight of the
        # nominal model already trades up to one sample
        return fitted(first, second) and cls.same(first.spec, second.spec)

    @classmethod
    def params(cls, model: FittedModel, kt: float | None) -> Params:
        return {"k": model.spec.delay}

    @classmethod
    def grid(cls, base: ModelSpec) -> list[ModelSpec]:
        return delay_grid(base)

    @classmethod
    def bracketed(cls, spec: ModelSpec) -> bool:
        return (spec.delay or 0) <= MAX_DELAY_SAMPLES

    @classmethod
    def same(cls, a: ModelSpec, b: ModelSpec) -> bool:
        return abs(a.delay - b.delay) <= DELAY_TOLERANCE_SAMPLES

    moves_the_current: ClassVar[bool] = True

    @classmethod
    def ident_grid(cls, base: ModelSpec, sig: Signals) -> list[ModelSpec]:
        return [replace(base, delay=k) for k in range(1, IDENT_MAX_DELAY_SAMPLES + 1)]

    @classmethod
    def ident_params(cls, spec: ModelSpec, coef: Callable[[str], float]) -> dict[str, float]:
        return {"k": float(spec.delay)}
