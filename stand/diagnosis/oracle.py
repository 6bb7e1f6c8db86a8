"""Oracle visibility of a planted effect (benchmark answer key only, never the diagnosis).

The benchmark knows the true motor and the true effect parameters. This module takes
the engine's nominal model exactly as the engine identifies it on TRAIN (its holdout
gap is the diagnosis' ``gap_percent``) and the engine's model with the planted effects
at their TRUE parameters (only its nominal part, ``Kt/J`` and ``D/J``, identified on
TRAIN as the engine would, so that both share the errors of identification), simulates
both on HOLDOUT with the engine's own re-anchoring
(:func:`stand.diagnosis.simulate.simulate`: same segments, same input reconstruction)
and applies the engine's own noise-aware paired test
(:func:`stand.diagnosis.significance.paired_improvement`) to the pair.

An effect is *visible* when even its exact model passes that test against the
identified nominal model: it changes the holdout speed (or acceleration) by more than
sensor noise and quantization explain. An invisible effect cannot be named by a
diagnosis that scores candidates on HOLDOUT, so the benchmark reports accuracy on the
visible cases separately (next to, not instead of, the headline over all cases).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from stand.diagnosis.candidates import EFFECTS
from stand.diagnosis.engine import ANCHOR_HORIZON_S, _Bench, _nominal_spec
from stand.diagnosis.model import (
    EDGE_SAMPLES,
    FittedModel,
    ModelSpec,
    equation_residual,
    fit,
    regressors,
)
from stand.diagnosis.signals import Signals, prepare
from stand.diagnosis.significance import paired_improvement
from stand.diagnosis.simulate import simulate
from stand.physics.parts import MotorParams
from stand.runfile import Run

#: Number of candidate tests the engine corrects for in its first selection step (one
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
        The engine's paired test of the true model against the identified nominal model.
    visible : bool
        Whether that test passes at the engine's first-step level.
    nominal_gap_percent, true_gap_percent : float
        The two gaps, % (CONTRACT §3 definition).
    """

    shrink: float
    p_value: float
    visible: bool
    nominal_gap_percent: float
    true_gap_percent: float


def _true_spec(base: ModelSpec, effects: dict[str, dict[str, float]]) -> ModelSpec:
    """``base`` with the planted effects' structure (their true order, delay, ωs, gap)."""
    spec = base
    for name, p in effects.items():
        if name == "coulomb_friction":
            spec = spec.merged(ModelSpec(coulomb=True))
        elif name == "stribeck_friction":
            spec = spec.merged(ModelSpec(stribeck_ws=float(p["ws"])))
        elif name == "cogging":
            spec = spec.merged(ModelSpec(cogging_N=int(p["N"])))
        elif name == "torque_ripple":
            spec = spec.merged(ModelSpec(ripple_N=int(p["N"])))
        elif name == "current_offset":
            spec = spec.merged(ModelSpec(offset=True))
        elif name == "delay":
            spec = spec.merged(ModelSpec(delay=int(p["k"])))
        elif name == "backlash":
            spec = spec.merged(ModelSpec(backlash_gap=float(p["gap"])))
    return spec


def _effect_currents(motor: MotorParams, effects: dict[str, dict[str, float]]
                     ) -> dict[str, float]:
    """The true effect coefficients of each input column per unit of ``current``
    coefficient (torques as the current that makes them, A; ε; J_load/Kt)."""
    Kt = motor.Kt
    per: dict[str, float] = {"current": 1.0}
    for name, p in effects.items():
        if name == "coulomb_friction":
            per["sign"] = -p["Tc"] / Kt
        elif name == "stribeck_friction":
            per["sign"] = -p["Tc"] / Kt
            per["stribeck"] = -(p["Ts"] - p["Tc"]) / Kt
        elif name == "cogging":  # the plant subtracts Tcog·sin(Nθ + φ)
            per["cog_sin"] = -p["Tcog"] / Kt * math.cos(p["phi"])
            per["cog_cos"] = -p["Tcog"] / Kt * math.sin(p["phi"])
        elif name == "torque_ripple":
            per["rip_sin"] = p["eps"] * math.cos(p["phi"])
            per["rip_cos"] = p["eps"] * math.sin(p["phi"])
        elif name == "current_offset":  # measured current = true current + i0
            per["one"] = -p["i0"]
        elif name == "backlash":
            per["load_accel"] = -p["J_load"] / Kt  # the load's torque J_load·θ_l'' as a current
    return per


def _true_model(base: ModelSpec, motor: MotorParams, effects: dict[str, dict[str, float]],
                sig: Signals) -> FittedModel:
    """The model with the planted effects at their TRUE parameters, its nominal part
    (``Kt/J``, ``D/J``) identified on ``sig`` (least squares on the filtered signals,
    as the engine's fit): every effect is folded into one known effective current."""
    spec = _true_spec(base, effects)
    per = _effect_currents(motor, effects)
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
    """How far the exact model of ``effects`` shrinks the exact nominal model's holdout
    gap, and whether the engine's own test would call that beyond noise."""
    tr, ho = prepare(train), prepare(holdout)
    bench = _Bench(tr, ho, ANCHOR_HORIZON_S)
    base_spec = _nominal_spec(bench.on_train, False)
    sse, gaps = [], []
    for model in (fit(base_spec, tr), _true_model(base_spec, motor, effects, tr)):
        error = simulate(model, ho, bench.seg) - bench.measured
        error = np.clip(np.where(np.isfinite(error), error, 1e6 * bench.scale),
                        -1e6 * bench.scale, 1e6 * bench.scale)
        gaps.append(100.0 * float(np.sqrt(np.mean(error**2))) / bench.scale)
        residual = equation_residual(model, ho)[bench.seg.index]
        sse.append(np.stack([np.sum(error**2, axis=1), np.sum(residual**2, axis=1)]))
    test = paired_improvement(sse[0], sse[1])
    return Visibility(shrink=1.0 - gaps[1] / gaps[0], p_value=test.p_value,
                      visible=test.significant(ENGINE_TESTS),
                      nominal_gap_percent=gaps[0], true_gap_percent=gaps[1])


__all__ = ["Visibility", "visibility"]
