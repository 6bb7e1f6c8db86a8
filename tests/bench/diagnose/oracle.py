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


__all__ = ["Visibility", "visibility"]
