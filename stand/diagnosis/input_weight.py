"""How the current between two samples is reconstructed (``ModelSpec.input_weight``),
picked by simulating TRAIN.

Where in a sample period the drive's current changes (a current loop that follows a step
within a fraction of a period, a speed loop whose current moves all through it) varies
from stand to stand; an input off by a few hundredths of a period leaves a structural
error at every step of the current that effect candidates then absorb.

The weight is a property of the drive, not of an effect, but the run shows it only
through a model: picked for the nominal model alone, it is picked against the largest
effect that model lacks. On a speed-loop run with Coulomb friction the friction's error
swamps the weight's, and the weight that simulates TRAIN best without friction is not
the one that does with it (the Crouzet profile at 1 ms: 0.5 without, 0.75 with; the
gap left with friction 2.9 % at 0.5, 1.9 % at 0.75, a wide load behind a backlash
absorbing part of the difference). So the selection picks it again once the first
effect, the one that explains most of the gap, is in the model, before it tries further
effects (:func:`stand.diagnosis.selection.select`; not after each later one: those
explain less, and a model with a position-periodic term costs about 0.1 s a
simulation, 11 of them a pick).
"""

from __future__ import annotations

import math
from dataclasses import replace
from typing import TYPE_CHECKING

from stand.diagnosis import kicks
from stand.diagnosis.model import ModelSpec, supply_classes, supply_within_period
from stand.errors import NotExcitedError

if TYPE_CHECKING:
    from stand.diagnosis.scoring import Bench

#: Input reconstructions tried (see ``ModelSpec.input_weight``).
INPUT_WEIGHTS: tuple[float, ...] = (0.5, 0.625, 0.75, 0.875, 1.0)
#: Input weight of a current that is already the mean over each period (the speed loop's
#: law current, :mod:`stand.diagnosis.loop_input`): kept as it is by :func:`pick`.
PERIOD_MEAN_WEIGHT = 0.0
#: Halvings of the weight step around the best grid weight (to 1/64 of a period).
WEIGHT_REFINEMENTS = 3


def pick(on_train: Bench, spec: ModelSpec) -> ModelSpec:
    """``spec`` with the input weight that simulates TRAIN best (``on_train``: TRAIN
    against itself, :attr:`Bench.on_train`), with or without a speed loop's kicks
    (:mod:`.kicks`) and the current's shape at the drive's supply
    (:mod:`.supply_limit`) where the run shows them.

    A current that is already each period's mean (:data:`PERIOD_MEAN_WEIGHT`) keeps it.
    Otherwise the weight is picked on the grid ``INPUT_WEIGHTS`` and then refined by halving the
    step around the best one ``WEIGHT_REFINEMENTS`` times, within the grid's range.

    Shares of the current's change at the supply that put its weight outside the period
    are skipped (:func:`~stand.diagnosis.model.supply_within_period`). Weights under
    which TRAIN gives no positive current gain are skipped (on a run whose
    current moves in steps much faster than the shaft, a reconstruction off by most of
    a sample can invert the fitted gain); if none gives one, the run is not excited and
    :class:`~stand.errors.NotExcitedError` is raised.
    """
    if spec.input_weight == PERIOD_MEAN_WEIGHT:
        return spec  # the speed loop's current, already each period's mean: nothing to pick
    sig = on_train.train
    gaps: dict[tuple[float, bool, tuple[str, ...]], float] = {}
    error: NotExcitedError | None = None

    def weighted(w: float, kicked: bool, supplied: tuple[str, ...]) -> ModelSpec:
        return replace(spec, input_weight=w, kicks=kicked, supply=supplied)

    def gap(w: float, kicked: bool, supplied: tuple[str, ...]) -> None:
        nonlocal error
        if (w, kicked, supplied) in gaps or not INPUT_WEIGHTS[0] <= w <= INPUT_WEIGHTS[-1]:
            return
        try:
            scored = on_train.score(weighted(w, kicked, supplied))
        except NotExcitedError as exc:
            gaps[w, kicked, supplied], error = math.inf, exc
            return
        gaps[w, kicked, supplied] = (scored.gap if supply_within_period(scored.model)
                                     else math.inf)

    kick_choices = ((False, True) if sig.target_change is not None
                    and kicks.resolvable(sig.target_change) else (False,))
    present = supply_classes(sig)
    supply_choices = ((), present) if present else ((),)
    for w in INPUT_WEIGHTS:
        for kicked in kick_choices:
            for supplied in supply_choices:
                gap(w, kicked, supplied)
    best = min(gaps, key=gaps.__getitem__)
    if not math.isfinite(gaps[best]):
        assert error is not None
        raise error
    step = (INPUT_WEIGHTS[1] - INPUT_WEIGHTS[0]) / 2
    for _ in range(WEIGHT_REFINEMENTS):
        gap(best[0] - step, *best[1:])
        gap(best[0] + step, *best[1:])
        best = min(gaps, key=gaps.__getitem__)
        step /= 2
    return weighted(*best)


__all__ = ["INPUT_WEIGHTS", "WEIGHT_REFINEMENTS", "pick"]
