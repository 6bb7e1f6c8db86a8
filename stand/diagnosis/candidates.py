"""The candidate effects of CONTRACT §3 as model extensions, by name.

Each effect's search, agreement check and parameters live in its own module of
:mod:`stand.effects`; these functions find it in the registry by name. The constants
below are re-exported from there for callers that read them here.
"""

from __future__ import annotations

from stand.diagnosis.model import FittedModel, ModelSpec
from stand.diagnosis.signals import Signals
from stand.effects import EFFECTS, get
from stand.effects.backlash import MAX_GAP_RAD, MIN_GAP_COUNTS, MIN_GAP_RAD
from stand.effects.base import AGREE_RATIO, NO_FIT, Simulated
from stand.effects.delay import DELAY_TOLERANCE_SAMPLES, MAX_DELAY_SAMPLES, delay_grid
from stand.effects.periodic import MAX_ORDER, PHASE_TOLERANCE_RAD
from stand.effects.stribeck_friction import STRIBECK_MIN_EXCESS, STRIBECK_WS_RATIO


def search(effect: str, base: ModelSpec, train: Signals,
           simulated: Simulated | None = None) -> ModelSpec:
    """The model ``base`` plus ``effect``, its hyper-parameters picked on ``train``
    (:meth:`stand.effects.base.Effect.search`); ``simulated`` gives a spec's simulation
    error on ``train`` for the effects picked by simulation."""
    return get(effect).search(base, train, simulated)


def agree(effect: str, first: FittedModel, second: FittedModel) -> bool:
    """Whether ``effect`` fitted on two independent runs is the same effect
    (:meth:`stand.effects.base.Effect.agree`)."""
    return get(effect).agree(first, second)


def params(effect: str, model: FittedModel, kt: float | None) -> dict[str, float | int | None]:
    """Physical parameters of ``effect`` in the fitted ``model``
    (:meth:`stand.effects.base.Effect.params`); none for :data:`NO_FIT`."""
    if model.spec == NO_FIT:
        return {}
    return get(effect).params(model, kt)


__all__ = ["AGREE_RATIO", "DELAY_TOLERANCE_SAMPLES", "EFFECTS", "MAX_DELAY_SAMPLES",
           "MAX_GAP_RAD", "MAX_ORDER", "MIN_GAP_COUNTS", "MIN_GAP_RAD", "NO_FIT",
           "PHASE_TOLERANCE_RAD", "STRIBECK_MIN_EXCESS", "STRIBECK_WS_RATIO", "agree",
           "delay_grid", "params", "search"]
