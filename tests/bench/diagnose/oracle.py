"""Oracle visibility of a planted effect (benchmark answer key only, never the diagnosis).

The benchmark knows the true motor and the true effect parameters. This module takes
the diagnosis' nominal model exactly as it is identified on TRAIN (its holdout gap is
the diagnosis' ``gap_percent``) and the model with the planted effects at their TRUE
parameters (only its nominal part, ``Kt/J`` and ``D/J``, identified on TRAIN as the
diagnosis would, so that both share the errors of identification), and compares both on
HOLDOUT with the diagnosis' own re-anchored simulation and noise-aware paired test
(:func:`stand.diagnosis.engine.compare_on_holdout`).

An effect is *visible* when even its exact model passes that test against the
identified nominal model: it changes the holdout speed (or acceleration) by more than
sensor noise and quantization explain. An invisible effect cannot be named by a
diagnosis that scores candidates on HOLDOUT, so the benchmark reports accuracy on the
visible cases separately (next to, not instead of, the headline over all cases).

An effect that nests another (Stribeck friction holds a Coulomb level) is visible *as
itself* only when what it adds to the nested effect shows: its exact model (with the
other planted effects) must pass the same test against the model that holds the nested
effect instead, searched and identified on TRAIN as the diagnosis would. Where it does
not, the data resolve only the nested effect (a static excess the run never shows is
Coulomb friction to any test on it), and the benchmark accepts that name too
(:func:`resolved_truth`).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from stand import effects as vocabulary
from stand.diagnosis.engine import compare_on_holdout
from stand.diagnosis.model import (
    EDGE_SAMPLES,
    FittedModel,
    ModelSpec,
    offset_ripple,
    regressors,
    ripple_on_offset,
)
from stand.diagnosis.signals import Signals
from stand.diagnosis.significance import paired_improvement
from stand.effects import EFFECTS
from stand.physics.effects import Effects
from stand.physics.parts import MotorParams
from stand.runfile import Run

#: Number of candidate tests the diagnosis corrects for in its first selection step (one
#: per effect of the vocabulary, as in :func:`stand.diagnosis.engine.diagnose`).
ENGINE_TESTS = len(EFFECTS)


@dataclass(frozen=True)
class Visibility:
    """Oracle figures of one case.

    Attributes
    ----------
    shrink : float
        ``1 − gap(true model) / gap(identified nominal model)`` on HOLDOUT.
    p_value : float
        The diagnosis' paired test of the true model against the identified nominal model.
    visible : bool
        Whether that test passes at the diagnosis' first-step level.
    nominal_gap_percent, true_gap_percent : float
        The two gaps, % (CONTRACT §3 definition).
    nested : dict of str to str
        Each planted effect whose addition to the effect it nests is NOT visible
        (its exact model does not pass the test against the nested effect searched on
        TRAIN), mapped to that nested effect.
    """

    shrink: float
    p_value: float
    visible: bool
    nominal_gap_percent: float
    true_gap_percent: float
    nested: dict[str, str] = field(default_factory=dict)


def _true_model(base: ModelSpec, motor: MotorParams, effects: Effects,
                sig: Signals, searched: str | None = None) -> FittedModel:
    """The model with the planted effects at their TRUE parameters, its nominal part
    (``Kt/J``, ``D/J``) identified on ``sig`` (least squares on the filtered signals,
    as the diagnosis' fit): every effect is folded into one known effective current.

    With ``searched`` (an effect name), that effect is not known: the diagnosis' own
    search for it on ``sig`` (beside the known effects) gives its structure, and its
    columns are identified with the nominal part."""
    spec = base
    per: dict[str, float] = {"current": 1.0}
    for effect in effects.present():
        spec = spec.merged(effect.structure())
        per.update(effect.true_coefficients(motor.Kt))
    free: list[str] = []
    if searched is not None:
        spec = vocabulary.get(searched).search(spec, sig)
        free = list(vocabulary.get(searched).columns)
    columns = regressors(spec, sig)
    effective = sum(per.get(name, 0.0) * column for name, column in columns.items()
                    if name not in free)
    if ripple_on_offset(spec) and "rip_sin" not in free:
        # the ripple acts on the true current, i − i0 (``one`` is −i0 per unit current)
        positions = regressors(ModelSpec(cogging_N=spec.ripple_N), sig)
        effective = effective + offset_ripple(
            lambda name: per.get(name, 0.0),
            np.column_stack([positions["cog_sin"], positions["cog_cos"]]))
    keep = slice(EDGE_SAMPLES, len(sig) - EDGE_SAMPLES - spec.delay)
    x = np.column_stack([sig.omega_f, sig.filt(np.asarray(effective)),
                         *(sig.filt(columns[name]) for name in free)])[keep]
    (c_omega, c_i, *c_free), *_ = np.linalg.lstsq(x, sig.accel_f[keep], rcond=None)
    coef = {name: float(c_i) * per.get(name, 0.0) for name in spec.names()}
    coef.update({name: float(c) for name, c in zip(free, c_free, strict=True)})
    return FittedModel(spec=spec, c_theta=0.0, c_omega=float(c_omega), coef=coef,
                       residual_rms=0.0, condition_number=1.0, samples=int(len(x)))


def visibility(train: Run, holdout: Run, motor: MotorParams,
               effects: dict[str, dict[str, float]]) -> Visibility:
    """How far the exact model of ``effects`` shrinks the identified nominal model's
    holdout gap, and whether the diagnosis' own test would call that beyond noise."""
    planted = Effects.from_mapping(effects, "planted effects")
    result = compare_on_holdout(
        train, holdout, lambda base, sig: _true_model(base, motor, planted, sig))
    nested = {}
    for name in effects:
        for inner in vocabulary.get(name).nests:
            if not _beyond_nested(train, holdout, motor, planted, name, inner):
                nested[name] = inner
    return Visibility(shrink=1.0 - result.gap_percent / result.nominal_gap_percent,
                      p_value=result.test.p_value,
                      visible=result.test.significant(ENGINE_TESTS),
                      nominal_gap_percent=result.nominal_gap_percent,
                      true_gap_percent=result.gap_percent, nested=nested)


def _beyond_nested(train: Run, holdout: Run, motor: MotorParams, planted: Effects,
                   name: str, inner: str) -> bool:
    """Whether the exact model of the planted effects passes the engine's test against
    the one with planted effect ``name`` replaced by the effect ``inner`` it nests,
    searched and identified on TRAIN (the other effects kept at their true values)."""
    others = Effects(**{**{f: getattr(planted, f) for f in planted.__dataclass_fields__},
                        name: None})
    result = compare_on_holdout(
        train, holdout, lambda base, sig: _true_model(base, motor, planted, sig),
        reference_of=lambda base, sig: _true_model(base, motor, others, sig, inner))
    return result.test.significant(ENGINE_TESTS)


def resolved_truth(truth: list[str], nested: dict[str, str]) -> list[str]:
    """``truth`` as far as the runs resolve it: each effect whose addition to the effect
    it nests is not visible (``nested``, :attr:`Visibility.nested`) named by that
    nested effect."""
    return [nested.get(name, name) for name in truth]


def visible_against_twin(runs: tuple[Run, Run], twin: tuple[Run, Run], motor: MotorParams,
                         others: dict[str, dict[str, float]], tests: int) -> bool:
    """Whether one planted effect shows at all, by the same physics for every effect
    (of the vocabulary or outside it): the exact model of the case's *other* planted
    effects (the nominal model when there are none), identified as the diagnosis would,
    errs more on the case's runs ``runs`` (TRAIN, HOLDOUT) than on its ``twin`` runs,
    the same command, sensors and noise seed without that effect, by the diagnosis' own
    paired test at the level of ``tests`` candidates (its first step: one per
    vocabulary effect; a second effect: one fewer) and its least shrink.

    A re-identified model takes up part of an effect it lacks (``Kt/J`` an elastic
    load far below its resonance, ``D/J`` most of a fan drag): an effect that leaves
    no more error than its twin's is invisible in that run, and no diagnosis can be
    asked to name it, nor to call its gap beyond noise."""
    planted = Effects.from_mapping(others, "other planted effects")

    def model_of(base: ModelSpec, sig: Signals) -> FittedModel:
        return _true_model(base, motor, planted, sig)

    with_it = compare_on_holdout(*runs, model_of)
    without = compare_on_holdout(*twin, model_of)
    if with_it.sse is None or without.sse is None or with_it.sse.shape != without.sse.shape:
        return True  # not comparable: count it, as the headline does
    return paired_improvement(with_it.sse, without.sse).significant(tests)


__all__ = ["Visibility", "resolved_truth", "visibility", "visible_against_twin"]
