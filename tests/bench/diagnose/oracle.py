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
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from stand.diagnosis.engine import compare_on_holdout
from stand.diagnosis.model import EDGE_SAMPLES, FittedModel, ModelSpec, regressors
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
    """

    shrink: float
    p_value: float
    visible: bool
    nominal_gap_percent: float
    true_gap_percent: float


def _true_model(base: ModelSpec, motor: MotorParams, effects: Effects,
                sig: Signals) -> FittedModel:
    """The model with the planted effects at their TRUE parameters, its nominal part
    (``Kt/J``, ``D/J``) identified on ``sig`` (least squares on the filtered signals,
    as the diagnosis' fit): every effect is folded into one known effective current."""
    spec = base
    per: dict[str, float] = {"current": 1.0}
    for effect in effects.present():
        spec = spec.merged(effect.structure())
        per.update(effect.true_coefficients(motor.Kt))
    columns = regressors(spec, sig)
    effective = sum(per.get(name, 0.0) * column for name, column in columns.items())
    keep = slice(EDGE_SAMPLES, len(sig) - EDGE_SAMPLES - spec.delay)
    x = np.column_stack([sig.omega_f, sig.filt(np.asarray(effective))])[keep]
    (c_omega, c_i), *_ = np.linalg.lstsq(x, sig.accel_f[keep], rcond=None)
    coef = {name: float(c_i) * per.get(name, 0.0) for name in spec.names()}
    return FittedModel(spec=spec, c_theta=0.0, c_omega=float(c_omega), coef=coef,
                       residual_rms=0.0, condition_number=1.0, samples=int(len(x)))


def visibility(train: Run, holdout: Run, motor: MotorParams,
               effects: dict[str, dict[str, float]]) -> Visibility:
    """How far the exact model of ``effects`` shrinks the identified nominal model's
    holdout gap, and whether the diagnosis' own test would call that beyond noise."""
    planted = Effects.from_mapping(effects, "planted effects")
    result = compare_on_holdout(
        train, holdout, lambda base, sig: _true_model(base, motor, planted, sig))
    return Visibility(shrink=1.0 - result.gap_percent / result.nominal_gap_percent,
                      p_value=result.test.p_value,
                      visible=result.test.significant(ENGINE_TESTS),
                      nominal_gap_percent=result.nominal_gap_percent,
                      true_gap_percent=result.gap_percent)


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


__all__ = ["Visibility", "visibility", "visible_against_twin"]
