"""The diagnosis: nominal gap, candidates scored on HOLDOUT, greedy selection, verdict.

1. Identify the nominal model of seed 000 on TRAIN (Q-matrix, filtered signals).
2. Simulate it on HOLDOUT from HOLDOUT's measured current, re-anchored to the measured
   state every ``horizon_s`` (the same segments for every candidate), and compare with
   HOLDOUT's measured speed: the gap.
3. For every effect of the vocabulary, extend the model, pick the effect's
   hyper-parameters and identify it on TRAIN, simulate it on HOLDOUT: its gap, shrink,
   and a paired per-segment test of the improvement (:mod:`.significance`).
4. Take the significant candidate with the smallest gap (a nested simpler candidate,
   Coulomb inside Stribeck, is kept unless the richer one is significantly better); then
   add further effects greedily while an addition still improves HOLDOUT significantly.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from stand.diagnose import candidates
from stand.diagnose.model import FittedModel, ModelSpec, Segments, fit, segments, simulate
from stand.diagnose.model import equation_residual as _residual
from stand.diagnose.report import Diagnosis, EffectScore
from stand.diagnose.significance import PairedTest, paired_improvement
from stand.diagnose.signals import Signals, prepare
from stand.diagnose.where import locate
from stand.errors import InputError, NotExcitedError
from stand.runfile import Run

#: Free-run length between re-anchorings of the simulation, s.
ANCHOR_HORIZON_S = 0.1
#: Fewest segments for the paired test (the horizon shrinks on short runs).
MIN_SEGMENTS = 12
#: Most effects combined in a verdict.
MAX_EFFECTS = 3
#: Input reconstructions tried for the nominal model (see ``ModelSpec.input_weight``).
INPUT_WEIGHTS: tuple[float, ...] = (0.5, 0.625, 0.75, 0.875, 1.0)


@dataclass(frozen=True)
class _Scored:
    spec: ModelSpec
    model: FittedModel
    sse: np.ndarray
    gap: float


class _Bench:
    """TRAIN and HOLDOUT prepared once; scores a model spec on them."""

    def __init__(self, train: Signals, holdout: Signals, horizon_s: float) -> None:
        self.train, self.holdout = train, holdout
        self.seg: Segments = segments(len(holdout), holdout.dt_s, horizon_s, MIN_SEGMENTS)
        if len(self.seg.starts) < 2:
            raise InputError(f"{holdout.source}: too short for a holdout test; record longer")
        self.measured = holdout.omega_meas[self.seg.index]
        self.scale = float(np.sqrt(np.mean((self.measured - self.measured.mean()) ** 2)))
        if self.scale == 0.0:
            raise NotExcitedError(f"{holdout.source}: the speed never varies; nothing to compare")

    def score(self, spec: ModelSpec) -> _Scored:
        model = fit(spec, self.train)
        error = simulate(model, self.holdout, self.seg) - self.measured
        error = np.where(np.isfinite(error), error, 1e6 * self.scale)
        error = np.clip(error, -1e6 * self.scale, 1e6 * self.scale)
        sse = np.sum(error**2, axis=1)
        gap = 100.0 * float(np.sqrt(np.mean(error**2))) / self.scale
        return _Scored(spec, model, sse, gap)


def diagnose(train: Run, holdout: Run, kt: float | None = None,
             horizon_s: float = ANCHOR_HORIZON_S, max_effects: int = MAX_EFFECTS) -> Diagnosis:
    """Diagnose the sim-to-real gap of the nominal seed-000 model (CONTRACT §3).

    Parameters
    ----------
    train, holdout : Run
        Single-motor runs (``time_s``, ``current_A``, ``position_rad``). Models are
        identified on ``train`` and scored on ``holdout``.
    kt : float or None
        Torque constant, N·m/A, if known: torque parameters are then also given in N·m.
        Without it they are given relative to it (``*_over_Kt_A``, in A).
    horizon_s : float
        Free-run length between re-anchorings of the simulation, s.
    max_effects : int
        Most effects combined in the verdict.

    Returns
    -------
    Diagnosis

    Raises
    ------
    InputError
        Runs that are too short, do not move, or have different sample periods.
    """
    if kt is not None and not kt > 0:
        raise InputError(f"kt must be a torque constant > 0 N·m/A, got {kt}")
    if horizon_s <= 0:
        raise InputError(f"horizon_s must be > 0 s, got {horizon_s}")
    tr, ho = prepare(train), prepare(holdout)
    if abs(tr.dt_s - ho.dt_s) > 0.01 * tr.dt_s:
        raise InputError(
            f"{train.source} is sampled every {tr.dt_s:.6g} s, {holdout.source} every "
            f"{ho.dt_s:.6g} s; TRAIN and HOLDOUT need the same sample period"
        )
    bench = _Bench(tr, ho, horizon_s)
    nominal = _input_reconstruction(tr, horizon_s)
    base = bench.score(nominal)
    singles = {name: bench.score(candidates.search(name, nominal, tr))
               for name in candidates.EFFECTS}
    tests = {name: paired_improvement(base.sse, s.sse) for name, s in singles.items()}
    n_tests = len(singles)
    scores = [
        EffectScore(effect=name, gap_percent=s.gap, shrink=1.0 - s.gap / base.gap,
                    significant=tests[name].significant(n_tests),
                    params=candidates.params(name, s.model, kt), p_value=tests[name].p_value)
        for name, s in singles.items()
    ]
    scores.sort(key=lambda e: e.gap_percent)
    chosen, final = _select(bench, base, singles, tests, max_effects)
    verdict = "+".join(chosen) if chosen else "none"
    floor = _noise_floor(ho, bench.scale)
    message = (f"gap {base.gap:.1f} % (noise floor {floor:.1f} %); verdict {verdict}"
               + (f", gap with it {final.gap:.1f} %" if chosen else ""))
    return Diagnosis(
        gap_percent=base.gap, where=locate(_residual(base.model, ho), ho), effects=scores,
        verdict=verdict, verdict_gap_percent=final.gap, nominal=_nominal_dict(base.model, kt),
        anchoring={"method": "re-anchored to the filtered measured state every horizon_s",
                   "horizon_s": bench.seg.horizon * ho.dt_s,
                   "segments": int(len(bench.seg.starts))},
        noise_floor_percent=floor, message=message)


def _select(bench: _Bench, base: _Scored, singles: dict[str, _Scored],
            tests: dict[str, PairedTest], max_effects: int) -> tuple[list[str], _Scored]:
    significant = [n for n in singles if tests[n].significant(len(singles))]
    if not significant:
        return [], base
    first = min(significant, key=lambda n: singles[n].gap)
    if first == "stribeck_friction" and "coulomb_friction" in significant:
        richer = paired_improvement(singles["coulomb_friction"].sse, singles[first].sse)
        if not richer.significant(1):
            first = "coulomb_friction"
    chosen, current = [first], singles[first]
    while len(chosen) < max_effects:
        remaining = [n for n in candidates.EFFECTS if n not in chosen
                     and not (n == "coulomb_friction" and "stribeck_friction" in chosen)]
        trials = {n: bench.score(candidates.search(n, current.spec, bench.train))
                  for n in remaining}
        passed = {n: s for n, s in trials.items()
                  if paired_improvement(current.sse, s.sse).significant(len(trials))}
        if not passed:
            break
        best = min(passed, key=lambda n: passed[n].gap)
        if best == "stribeck_friction" and "coulomb_friction" in chosen:
            chosen.remove("coulomb_friction")
        chosen.append(best)
        current = passed[best]
    return chosen, current


def _input_reconstruction(train: Signals, horizon_s: float) -> ModelSpec:
    """The nominal model with the input reconstruction that simulates TRAIN best."""
    on_train = _Bench(train, train, horizon_s)
    specs = [ModelSpec(input_weight=w) for w in INPUT_WEIGHTS]
    return min(specs, key=lambda spec: on_train.score(spec).gap)


def _noise_floor(sig: Signals, scale: float) -> float:
    """Gap from encoder quantization alone: central-difference noise over the speed RMS."""
    noise = sig.quant_rad / (np.sqrt(24.0) * sig.dt_s)
    return 100.0 * float(noise) / scale


def _nominal_dict(model: FittedModel, kt: float | None) -> dict[str, float]:
    b = model.coef["current"]
    out = {"Kt_over_J": b, "D_over_J": -model.c_omega, "C_over_J": -model.c_theta,
           "condition_number": model.condition_number,
           "input_weight": model.spec.input_weight}
    if kt is not None:
        J = kt / b
        out.update(J=J, D=-model.c_omega * J, C=-model.c_theta * J)
    return out
