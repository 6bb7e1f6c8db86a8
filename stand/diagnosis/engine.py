"""The diagnosis: nominal gap, candidates scored on HOLDOUT, greedy selection, verdict.

1. Identify the nominal model of seed 000 on TRAIN (Q-matrix, filtered signals).
2. Simulate it on HOLDOUT from HOLDOUT's measured current, re-anchored to the measured
   positions every ``horizon_s`` (the same segments for every candidate;
   :mod:`.simulate`), and compare with HOLDOUT's measured speed: the gap.
3. For every effect of the vocabulary, extend the model, pick the effect's
   hyper-parameters and identify it on TRAIN, simulate it on HOLDOUT: its gap, shrink,
   and a paired per-segment test of the improvement (:mod:`.significance`).
   A candidate counts only when the same search on HOLDOUT finds the same effect
   again (same order or delay, similar size: each effect's ``agree``). An effect that
   a TRAIN run of one frequency cannot resolve (a delay) is picked across the two runs
   there instead (``Bench.across``).
4. Take the significant candidate with the smallest gap (an effect that nests it, as
   Stribeck friction nests Coulomb friction, wins over it when it is significant
   itself, i.e. when both runs resolve what it adds, and simulates HOLDOUT significantly
   better than the nested effect); then add further effects greedily while an addition
   still improves HOLDOUT significantly, the input reconstruction picked again on TRAIN
   once the first effect is in (:mod:`.input_weight`); then judge each with the others in
   the model (:mod:`.selection`).

The effects and everything effect-specific come from the registry (:mod:`stand.effects`).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace
from functools import partial
from typing import TYPE_CHECKING

import numpy as np

from stand import effects
from stand.diagnosis import coupling, drag, input_weight, kicks, load_friction, supply_limit
from stand.diagnosis.current_noise import current_noise
from stand.diagnosis.input_weight import PERIOD_MEAN_WEIGHT
from stand.diagnosis.loop_input import loop_inputs
from stand.diagnosis.model import (
    FittedModel,
    ModelSpec,
    equation_residual,
    lag_share,
    period_mean_current,
)
from stand.diagnosis.noise import (
    UNEXPLAINED_FACTOR,
    Replayed,
    beyond_approximation,
    beyond_noise_percent,
    beyond_replay,
    explained_percent,
    noise_floor,
    noise_gap_percent,
    unexplained,
    within_noise,
)
from stand.diagnosis.noise_replay import replayed_noise_gap
from stand.diagnosis.notes import aliases, limits
from stand.diagnosis.report import Diagnosis, EffectScore, SelectionStep, Traces
from stand.diagnosis.scoring import Bench, Scored
from stand.diagnosis.selection import improvement, select
from stand.diagnosis.signals import Signals, prepare
from stand.diagnosis.significance import PairedTest, paired_improvement
from stand.diagnosis.structure import (
    AFTER_NAMED_NUISANCE,
    DRIFT_SHAPES,
    FAMILIES,
    MAX_PHASE_SHARE,
    SPEED_SHAPES,
    along_travel_test,
    shapes_test,
    structure_test,
)
from stand.diagnosis.where import locate
from stand.effects import UNEXPLAINED
from stand.effects.base import NO_FIT
from stand.errors import InputError, NotExcitedError
from stand.ident.speed_loop import TARGET_COLUMN
from stand.runfile import CURRENT_MEAN_COLUMN, Run

if TYPE_CHECKING:
    from stand.ident.supply import DriveSupply

#: Free-run length between re-anchorings of the simulation, s.
ANCHOR_HORIZON_S = 0.1
#: Most effects combined in a verdict.
MAX_EFFECTS = 3
#: Largest refinement of the drive's lag in the speed law's current, in standard errors
#: of the laws' pooled fit of it (:func:`_law_spec`).
LAG_SIGMAS = 3.0


@dataclass(frozen=True)
class HoldoutComparison:
    """Two models simulated on HOLDOUT as the diagnosis simulates its candidates.

    Attributes
    ----------
    nominal_gap_percent, gap_percent : float
        Holdout gaps (CONTRACT §3) of the nominal model and of the other model, %.
    test : PairedTest
        The diagnosis' paired per-segment test of the other model against the
        reference model (no correction for the number of candidates).
    reference_gap_percent : float
        Holdout gap of the reference model, % (the nominal model's unless another
        reference was given).
    nominal_sse, sse : ndarray or None
        Per-segment squared errors of the nominal and of the other model on HOLDOUT
        (rows: simulated speed, (rad/s)², and equation error, (rad/s²)²), so that a
        model's errors on two pairs of runs with the same segments can be compared.
    """

    nominal_gap_percent: float
    gap_percent: float
    test: PairedTest
    reference_gap_percent: float = float("nan")
    nominal_sse: np.ndarray | None = None
    sse: np.ndarray | None = None


def compare_on_holdout(train: Run, holdout: Run,
                       model_of: Callable[[ModelSpec, Signals], FittedModel],
                       horizon_s: float = ANCHOR_HORIZON_S,
                       reference_of: Callable[[ModelSpec, Signals], FittedModel] | None = None,
                       supply: DriveSupply | None = None) -> HoldoutComparison:
    """The diagnosis' nominal model (or another reference) against another model, on
    HOLDOUT.

    The nominal model is the one :func:`diagnose` identifies on TRAIN (its input
    reconstruction picked the same way); ``model_of(nominal_spec, train_signals)``
    gives the other, built on the same nominal structure, and ``reference_of``, if
    given, the model it is tested against instead of the nominal one. Both are
    simulated on HOLDOUT with the same re-anchored segments and compared with the same
    paired test as the diagnosis' candidates. A benchmark uses it to ask whether a
    model it knows to be true (the planted effects at their true parameters) is
    visible at all, or beyond a simpler model.

    Raises
    ------
    InputError
        Runs too short for a holdout test.
    """
    bench, base_spec, _, _ = _driven(train, holdout, horizon_s, False, supply)
    nominal = bench.score(base_spec)
    reference = (nominal if reference_of is None
                 else bench.score_model(reference_of(base_spec, bench.train)))
    other = bench.score_model(model_of(base_spec, bench.train))
    return HoldoutComparison(nominal_gap_percent=nominal.gap, gap_percent=other.gap,
                             test=paired_improvement(reference.sse, other.sse),
                             reference_gap_percent=reference.gap,
                             nominal_sse=nominal.sse, sse=other.sse)


def diagnose(train: Run, holdout: Run, kt: float | None = None,
             horizon_s: float = ANCHOR_HORIZON_S, max_effects: int = MAX_EFFECTS,
             spring: bool = False, supply: DriveSupply | None = None) -> Diagnosis:
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
    spring : bool
        Keep the torsion-spring term ``C·θ`` of seed 000 eq. 2 in the nominal model. Off
        by default (``C = 0``): on a freely turning shaft the unwrapped angle grows
        without bound and a spring fitted to it only stands in for other errors (a
        constant torque over a position range away from zero, an inertia error under
        sine motion, where ``θ'' ∝ −θ``). Turn it on for a shaft held by a spring.
    supply : DriveSupply or None
        The drive's supply and current limit (a motor profile's,
        :func:`stand.ident.supply.motor_supply`). Its current limit clips the speed
        loop's kicks where the law's current drives the models: a kick can pass the
        limit early in a period and be back under it by the next sample, and then no
        sample shows the limit.

    Returns
    -------
    Diagnosis

    Raises
    ------
    InputError
        Runs that are too short, do not move, or have different sample periods.
    """
    return diagnose_with_traces(train, holdout, kt, horizon_s, max_effects, spring, supply)[0]


def diagnose_with_traces(train: Run, holdout: Run, kt: float | None = None,
                         horizon_s: float = ANCHOR_HORIZON_S, max_effects: int = MAX_EFFECTS,
                         spring: bool = False, supply: DriveSupply | None = None
                         ) -> tuple[Diagnosis, Traces]:
    """:func:`diagnose`, plus the :class:`Traces` the figures are drawn from."""
    if kt is not None and not kt > 0:
        raise InputError(f"kt must be a torque constant > 0 N·m/A, got {kt}")
    if horizon_s <= 0:
        raise InputError(f"horizon_s must be > 0 s, got {horizon_s}")
    if max_effects < 1:
        raise InputError(f"max_effects must be >= 1, got {max_effects}")
    bench, base_spec, sampled, input_notes = _driven(train, holdout, horizon_s, spring, supply)
    tr, ho = bench.train, bench.holdout
    base = bench.score(base_spec)
    singles = {name: bench.candidate(name, base) for name in effects.EFFECTS}
    n_tests = len(singles)
    scores = []
    for name, s in singles.items():
        test = improvement(base, s)
        scores.append(EffectScore(
            effect=name, gap_percent=s.gap, shrink=1.0 - s.gap / base.gap,
            significant=s.consistent and test.significant(n_tests),
            params=effects.get(name).params(s.model, kt) if s.spec != NO_FIT else {},
            p_value=test.p_value, consistent=s.consistent))
    scores.sort(key=lambda e: e.gap_percent)
    chosen, final, steps = select(bench, base, singles, {e.effect: e for e in scores},
                                   max_effects)
    floor = noise_floor(ho, bench.scale)
    noise_gap = noise_gap_percent(sampled, bench.scale, bench.seg.horizon, base.model)
    # with nothing named and a gap between the noise gap and the factor, the replay of
    # HOLDOUT's noise through the nominal model measures what the noise gap estimates
    replayed = (replayed_noise_gap(bench, base.model, sampled, _holds_target(train, holdout))
                if not chosen and noise_gap < base.gap <= UNEXPLAINED_FACTOR * noise_gap
                else None)
    # where the replay shows a gap beyond noise, the candidate that takes it back within
    # what noise leaves there is named at the level of the candidates that do
    second = second_look(base, singles, replayed)
    if second is not None:
        chosen, final, steps = [second.effect], singles[second.effect], [second]
    # a load behind the motor (a backlash) that one on a compliant coupling simulates
    # better is that coupling; a dry friction which a drag continuous through zero
    # simulates better is that drag, and one whose level grows with the torque carried
    # has that beside it (also within the noise gap: the paired test sees further)
    behind = next((name for name in chosen if effects.get(name).load_behind), None)
    friction = next((name for name in chosen if effects.get(name).jumps_at_reversal), None)
    replaced: coupling.Coupled | drag.Dragged | load_friction.Loaded | None = (
        None if behind is None else coupling.competitor(bench, final, behind))
    if replaced is None and friction is not None:
        replaced = (drag.competitor(bench, final, friction)
                    or load_friction.competitor(bench, final, friction))
    replaced_notes = [] if replaced is None else [replaced.note(final.gap)]
    if replaced is not None:
        chosen = [name for name in chosen if name != replaced.dropped]
        final = replaced.without
    residual_final = equation_residual(final.model, ho)
    residual_train = equation_residual(final.model, tr)
    noise = (current_noise(final.model, tr, residual_train),
             current_noise(final.model, ho, residual_final))
    structure = shapes_test(residual_train, tr, residual_final, ho, bench.seg.index,
                            noise=noise)
    along = along_travel_test(residual_train, tr, residual_final, ho, bench.seg.index)
    speed = (structure_test(residual_train, tr, residual_final, ho, bench.seg.index,
                            SPEED_SHAPES, AFTER_NAMED_NUISANCE, steady_current=True,
                            noise=noise).test
             if chosen else None)
    drift = structure.families[FAMILIES.index(DRIFT_SHAPES)] if chosen else None
    share = effects.approximation_share(chosen)
    rule = partial(unexplained, base.gap, final.gap, noise_gap, structure.test.p_value,
                   along.test.p_value, named=bool(chosen), along_shrink=along.test.shrink,
                   p_speed=speed.p_value if speed else 1.0,
                   speed_shrink=speed.shrink if speed else 0.0, share=share,
                   p_drift=drift.p_value if drift else 1.0,
                   drift_shrink=drift.shrink if drift else 0.0, replayed=replayed)
    # the coupled load, the drag and the friction growing with the torque are effects
    # outside the vocabulary that simulate HOLDOUT better than the verdict by the paired
    # test, which allows for the noise: the verdict is `unexplained` after its effects,
    # whatever the size of the gap they leave
    left = rule() or replaced is not None
    # a shape the rule reads beyond the noise gap, found within it (and no competitor
    # found an effect): said in a note
    held = not left and within_noise(final.gap, noise_gap) and rule(hold_within_noise=False)
    # what the rule says without the replay: the size and shapes of what is left, which
    # the structure note gives (a gap beyond the replays' alone has a note of its own)
    by_shape = left and rule(replayed=None)
    names = chosen + ([UNEXPLAINED] if left else [])
    verdict = "+".join(names) if names else effects.NONE
    message = (f"gap {base.gap:.1f} % (noise explains {noise_gap:.2f} %); verdict {verdict}"
               + (f", gap with it {final.gap:.1f} %" if chosen else ""))
    residual = equation_residual(base.model, ho)
    index = bench.seg.index
    traces = Traces(time_s=index * ho.dt_s, measured=bench.measured,
                    nominal=bench.measured + base.error, verdict=bench.measured + final.error,
                    theta=ho.theta_f, omega=ho.omega_f, residual=residual, dt_s=ho.dt_s)
    verdict_params = {name: effects.get(name).params(final.model, kt) for name in chosen}
    return Diagnosis(
        gap_percent=base.gap, where=locate(residual, ho),
        effects=scores, verdict=verdict, verdict_gap_percent=final.gap,
        verdict_params=verdict_params,
        nominal=_nominal_dict(base.model, kt),
        anchoring={"method": "re-anchored every horizon_s: filtered position one sample "
                             "before each segment, speed shot through the next measured "
                             "positions; simulated speed as the central difference of the "
                             "simulated position, like the measured speed",
                   "horizon_s": bench.seg.horizon * ho.dt_s,
                   "segments": int(len(bench.seg.starts))},
        noise_floor_percent=floor, message=message,
        residual_where=locate(residual_final, ho),
        model={**_nominal_dict(final.model, kt), **verdict_params},
        noise_gap_percent=noise_gap,
        structure_p_value=structure.test.p_value,
        position_structure_p_value=along.test.p_value,
        position_structure_shrink=along.test.shrink,
        speed_structure_p_value=speed.p_value if speed else None,
        speed_structure_shrink=speed.shrink if speed else None,
        drift_structure_p_value=drift.p_value if drift else None,
        drift_structure_shrink=drift.shrink if drift else None,
        replayed_noise_gap_percent=None if replayed is None else replayed.gap_percent,
        notes=(input_notes + limits(tr, bench.tone_hz) + aliases(bench.aliased)
               + bench.revisions + bench.set_aside + replaced_notes
               + _approximation_note(base.gap, final.gap, noise_gap, left, share)
               + (_structure_note(base.gap, final.gap, noise_gap, by_shape,
                                  structure.test.p_value, along.test.p_value, speed, share,
                                  drift)
                  if replaced is None else [])
               + _within_noise_note(held, final.gap, noise_gap, structure.test.p_value,
                                    along.test.p_value, speed, drift)
               + _second_look_note(second, replayed)
               + _replay_note(bool(chosen), base.gap, replayed)
               + _near_noise_note(bool(chosen) or left, base.gap, noise_gap,
                                  structure.test.p_value, along.test.p_value, replayed)
               + _phase_note(along.phase_share)),
        steps=steps), traces


def _approximation_note(nominal_gap: float, verdict_gap: float, noise_gap: float,
                        left: bool, share: float) -> list[str]:
    """Why a remainder beyond noise is not ``unexplained``: it is smaller than ``share``
    times what the verdict's effects explain (:func:`stand.diagnosis.noise.unexplained`)."""
    if left or verdict_gap <= UNEXPLAINED_FACTOR * noise_gap:
        return []
    beyond = beyond_noise_percent(verdict_gap, noise_gap)
    return [f"the verdict's effects leave {beyond:.2f} % beyond the noise "
            f"({noise_gap:.2f} %), less than {share:g} times the "
            f"{explained_percent(nominal_gap, verdict_gap):.2f} % they explain: taken as "
            "their models' approximation of the physics, not as another effect; "
            "residual_where locates it"]


def _within_noise_note(held: bool, verdict_gap: float, noise_gap: float, p_shapes: float,
                       p_along: float, speed: PairedTest | None,
                       drift: PairedTest | None) -> list[str]:
    """Why a remainder whose shape the rule reads is not ``unexplained`` (``held``: the
    rule finds the shape, and the gap is within the noise gap,
    :func:`stand.diagnosis.noise.within_noise`); the shapes it reads there (``speed``
    and ``drift``: the speed and the drift shapes' tests after named effects, None with
    nothing named)."""
    if not held:
        return []
    if speed is None or drift is None:  # nothing named
        named, shapes = False, (f"speed, current-level, time, drift and current-speed "
                                f"shapes p = {p_shapes:.2g}")
    else:
        named, shapes = True, (f"a torque growing with the speed beyond a friction level "
                               f"and a slope p = {speed.p_value:.2g}, a drag or friction "
                               f"level drifting over the run p = {drift.p_value:.2g}")
    return [f"the equation error {'left ' if named else ''}holds a shape ({shapes}, along "
            f"the travel p = {p_along:.2g}), but the gap {'left ' if named else ''}"
            f"({verdict_gap:.2f} %) is within what noise explains ({noise_gap:.2f} %): not "
            "`unexplained`, which is a gap beyond the noise (CONTRACT §3); the nominal "
            "model's own structure (a quantized motion that repeats, a speed loop's kicks "
            "between samples) shows there too"]


def _near_noise_note(named: bool, nominal_gap: float, noise_gap: float, p_shapes: float,
                     p_along: float, replayed: Replayed | None = None) -> list[str]:
    """What a ``none`` claims where the nominal gap is beyond the noise gap but within
    ``UNEXPLAINED_FACTOR`` times it, with no shape of an effect in its equation error
    (:func:`stand.diagnosis.noise.unexplained`), and within ``replayed``'s factor times
    the gap noise leaves on replays of HOLDOUT where the run is replayed: not
    that nothing is there, only that these runs cannot tell it from noise, as on many
    runs with no effect (``named``: the verdict names an effect or ``unexplained``, and
    then says nothing of this)."""
    if named or not noise_gap < nominal_gap <= UNEXPLAINED_FACTOR * noise_gap:
        return []
    replay = ("" if replayed is None else
              f", {nominal_gap / replayed.gap_percent:.2f} times what it leaves on replays "
              f"of HOLDOUT through the nominal model ({replayed.gap_percent:.2f} %; within "
              f"the {replayed.factor:g} "
              "times that runs with no effect reach)")
    return [f"the nominal gap ({nominal_gap:.2f} %) is {nominal_gap / noise_gap:.1f} times "
            f"what noise explains ({noise_gap:.2f} %), within the {UNEXPLAINED_FACTOR:g} "
            "times that runs with no effect reach (the noise gap is an estimate, uncertain "
            f"by a factor of about 1.5 from run to run){replay}, and its equation error "
            f"holds no shape an effect makes (p = {p_shapes:.2g}, along the travel "
            f"p = {p_along:.2g}): an effect that the re-identified nominal model takes up "
            "in Kt/J and D/J cannot be told from noise on these runs; runs of another "
            "command (one that reverses, a broadband PRBS) test it again"]


def _replay_note(named: bool, nominal_gap: float, replayed: Replayed | None) -> list[str]:
    """Why a gap within ``UNEXPLAINED_FACTOR`` times the noise gap with nothing named is
    ``unexplained`` by its size: it is beyond ``replayed``'s factor times the gap noise
    leaves on replays of HOLDOUT (:func:`stand.diagnosis.noise.beyond_replay`)."""
    if named or not beyond_replay(nominal_gap, replayed):
        return []
    assert replayed is not None
    return [f"the nominal gap ({nominal_gap:.2f} %) is "
            f"{nominal_gap / replayed.gap_percent:.2f} times what noise leaves on replays "
            f"of HOLDOUT ({replayed.gap_percent:.2f} %: the nominal model's "
            "own motion read through the run's encoder and current noise, anchored and "
            f"simulated as HOLDOUT is), beyond the {replayed.factor:g} times that runs with "
            "no effect reach: an effect the re-identified nominal model takes up in part, "
            "which no vocabulary effect explains; residual_where locates what remains"]


def second_look(base: Scored, singles: dict[str, Scored],
                replayed: Replayed | None) -> SelectionStep | None:
    """The effect named where nothing passed the first step's test but the nominal gap
    is beyond ``replayed``'s factor times the gap noise leaves on replays of HOLDOUT
    (:func:`stand.diagnosis.noise.beyond_replay`): among the candidates
    ``singles`` that the same search on HOLDOUT finds again and that take the gap back
    within that, the one that simulates HOLDOUT best, if its paired test passes at
    ``FAMILY_ALPHA`` shared among them (Bonferroni); else None.

    The first step tests every effect of the vocabulary against the nominal model at
    ``FAMILY_ALPHA`` shared among all of them, since each is asked whether anything is
    there. The replay has answered that, and the second look asks only which of the
    effects that explain what it found it is."""
    if not beyond_replay(base.gap, replayed):
        return None
    assert replayed is not None
    fits = {name: s for name, s in singles.items()
            if s.spec != NO_FIT and s.consistent
            and s.gap <= replayed.factor * replayed.gap_percent}
    if not fits:
        return None
    name = min(fits, key=lambda n: fits[n].gap)
    test = improvement(base, fits[name])
    if not test.significant(len(fits)):
        return None
    return SelectionStep(effect=name, after=[], gap_before_percent=base.gap,
                         gap_percent=fits[name].gap, shrink=1.0 - fits[name].gap / base.gap,
                         p_value=min(1.0, test.p_value * len(fits)))


def _second_look_note(second: SelectionStep | None, replayed: Replayed | None) -> list[str]:
    """Why an effect that did not pass the first step's test is in the verdict
    (:func:`second_look`)."""
    if second is None or replayed is None:
        return []
    return [f"{second.effect} is named at a second look: no effect passed the test against "
            f"the nominal model shared among the whole vocabulary, but the nominal gap "
            f"({second.gap_before_percent:.2f} %) is "
            f"{second.gap_before_percent / replayed.gap_percent:.2f} times what noise leaves "
            f"on replays of HOLDOUT ({replayed.gap_percent:.2f} %), beyond the "
            f"{replayed.factor:g} times that runs with no effect reach, and {second.effect} "
            f"takes it back to {second.gap_percent:.2f} % (p = {second.p_value:.2g}, shared "
            "among the effects that take it within that)"]


def _holds_target(train: Run, holdout: Run) -> bool:
    """Whether a run holds a speed loop's target (column ``speed_target_rad_s``)."""
    return any(TARGET_COLUMN in run for run in (train, holdout))


def _structure_note(nominal_gap: float, verdict_gap: float, noise_gap: float, left: bool,
                    p_shapes: float, p_along: float, speed: PairedTest | None,
                    share: float, drift: PairedTest | None = None) -> list[str]:
    """Why a remainder is ``unexplained`` by its shape rather than its size (``speed``
    and ``drift``: the speed and the drift shapes' tests after named effects, None with
    nothing named)."""
    if not left:
        return []
    if beyond_approximation(nominal_gap, verdict_gap, noise_gap, share):
        return []
    shapes = (f"a torque growing with the speed beyond a friction level and a slope "
              f"p = {speed.p_value:.2g} (shrink of the equation error {speed.shrink:.2f})"
              + (f", a drag or friction level drifting over the run p = {drift.p_value:.2g} "
                 f"(shrink {drift.shrink:.2f})" if drift else "")
              if speed else f"speed, current-level, time, drift and current-speed shapes "
                            f"p = {p_shapes:.2g}")
    return [f"the gap left ({verdict_gap:.2f} %, noise {noise_gap:.2f} %) is "
            f"{'within what the effects approximate' if speed else 'small'}, but its "
            f"equation error holds a shape no noise makes"
            f"{', nor the vocabulary models named' if speed else ''}: "
            f"{shapes}, a friction level or torque along the travel p = {p_along:.2g} "
            "(fitted on TRAIN, tested on HOLDOUT)"]


def _driven(train: Run, holdout: Run, horizon_s: float, spring: bool,
            supply: DriveSupply | None) -> tuple[Bench, ModelSpec, Signals, list[str]]:
    """The two runs prepared with the input current that simulates TRAIN best, and the
    nominal spec for it; also HOLDOUT with the current whose noise the noise gap
    counts (the sensor's samples, or the drive's period means where those drive the
    models) and notes on what drives the models (``supply``: the drive's, whose current
    limit clips the speed law, where known).

    Where both runs hold the drive's current averaged over each period
    (``current_mean_A``), that current drives the models: it is what every model
    integrates over a period, which the samples only approximate where the current
    moves between them (a speed loop's kicks, a current at the supply). Where the
    speed target's changes are resolvable (:func:`stand.diagnosis.kicks.resolvable`),
    the kicks' columns are offered with it as with the samples, and they take up the
    kicks' shape within their periods, which moves the angle beyond what the mean says;
    where the speed law drives the samples' models, its shape within each period
    comes along. The samples' best reconstruction (:func:`_sample_driven`) drives
    instead only where it simulates TRAIN significantly better (the paired test of
    :func:`stand.diagnosis.selection.improvement`; the law's current has no sensor
    noise), where the run holds its speed target also beside a dry friction level
    (:func:`_beside_friction`).
    """
    tr, ho = (supply_limit.marked(run, prepare(run)) for run in (train, holdout))
    if abs(tr.dt_s - ho.dt_s) > 0.01 * tr.dt_s:
        raise InputError(
            f"{train.source} is sampled every {tr.dt_s:.6g} s, {holdout.source} every "
            f"{ho.dt_s:.6g} s; TRAIN and HOLDOUT need the same sample period"
        )
    driven = _sample_driven(train, holdout, tr, ho, horizon_s, spring, supply)
    if not all(CURRENT_MEAN_COLUMN in run for run in (train, holdout)):
        return driven
    bench, spec, _, notes = driven
    # the samples' signals keep the speed target's changes and, where the law drives,
    # its current's shape within each period; the law's own parts and lag go
    means = [replace(sig, current=period_mean_current(run), loop_parts=None,
                     lag_slopes=None, cache={})
             for run, sig in ((train, bench.train), (holdout, bench.holdout))]
    mean_bench = Bench(means[0], means[1], horizon_s)
    measured = mean_bench.on_train.score(ModelSpec(input_weight=PERIOD_MEAN_WEIGHT,
                                                   spring=spring))
    change = means[0].target_change
    if change is not None and kicks.resolvable(change):
        try:  # a target of two levels makes the kick columns one
            kicked = mean_bench.on_train.score(replace(measured.spec, kicks=True))
        except NotExcitedError:
            kicked = None
        if kicked is not None and kicked.gap < measured.gap:
            measured = kicked
    sampled = bench.on_train.score(spec)
    # the measurement unless a reconstruction does significantly better, also beside a
    # dry friction level where a speed loop kicks the current (_beside_friction):
    # picked on TRAIN, a weight can match the period means there (a run of one
    # frequency takes its error into Kt/J) and still miss them on HOLDOUT
    better = improvement(measured, sampled).significant(1)
    friction_note = ""
    if better and change is not None:
        beside = _beside_friction((mean_bench, measured.spec), (bench, spec))
        if beside is not None and not improvement(*beside).significant(1):
            better = False
            friction_note = (f"; the samples simulate it significantly better only without "
                             f"a dry friction level: with one, {beside[0].gap:.2f} % against "
                             f"{beside[1].gap:.2f} %")
    if not better:
        return mean_bench, measured.spec, means[1], [
            f"driven by the drive's current averaged over each sample period "
            f"({CURRENT_MEAN_COLUMN}; TRAIN simulated to {measured.gap:.2f} %, "
            f"{sampled.gap:.2f} % with the current's samples"
            + (", with the speed loop's kicks' shape within their periods fitted"
               if measured.spec.kicks else "") + friction_note + ")"]
    return (*driven[:3], [*notes, f"the drive's current averaged over each period "
                          f"({CURRENT_MEAN_COLUMN}) simulates TRAIN to {measured.gap:.2f} %, "
                          f"the current's samples significantly better, to "
                          f"{sampled.gap:.2f} %: the samples drive the models"])


def _sample_driven(train: Run, holdout: Run, tr: Signals, ho: Signals, horizon_s: float,
                   spring: bool, supply: DriveSupply | None
                   ) -> tuple[Bench, ModelSpec, Signals, list[str]]:
    """:func:`_driven` from the current's samples (``tr``, ``ho``: the runs' signals
    from :func:`~stand.diagnosis.signals.prepare`), and HOLDOUT with its sampled
    current (the noise gap's current noise is the sensor's).

    The sampled current's reconstructions (:func:`_nominal_spec`) compete on TRAIN with
    the speed loop's current where both runs hold their target and the PI law holds on
    both (:mod:`.loop_input`): the law's current is one more reconstruction of the
    current between samples, picked the same way, and kept where it simulates TRAIN
    better either with the nominal model or beside a dry friction level
    (:func:`_beside_friction`). A law that holds at the samples can
    still miss the current between them (a kick that needs more than the supply
    voltage); its current then simulates TRAIN worse and the samples' stays.
    """
    limit = supply.current_limit_A if supply is not None else np.inf
    law_train, law_holdout = loop_inputs(train, holdout, tr, ho, limit)
    # the sampled current, with the speed target's changes where both runs hold it
    bench = Bench(law_train.sampled, law_holdout.sampled, horizon_s)
    spec = _nominal_spec(bench.on_train, spring)
    notes = [x.note for x in (law_train, law_holdout) if x.note and not x.from_law]
    notes = notes[:1] + _kick_note(spec) + _supply_note(spec, bench.train)
    if not law_train.from_law:
        return bench, spec, ho, notes
    law_bench = Bench(law_train.signals, law_holdout.signals, horizon_s)
    # both inputs compared with the current samples shifted back by the delay the law's
    # fit finds them late by: a model that misplaces every current by it tells nothing
    # of which input reconstructs the current between samples better
    delay = law_train.delay
    law_spec, law_gap = _law_spec(law_bench, spring, law_train.lag_sd_s, delay)
    gap = bench.on_train.score(replace(spec, delay=delay)).gap
    late = (f", both with the current samples taken {delay} sample{'s' if delay > 1 else ''} "
            "late, as the law's fit finds them" if delay else "")
    with_friction = (None if law_gap < gap else
                     _beside_friction((law_bench, replace(law_spec, delay=delay)),
                                      (bench, replace(spec, delay=delay))))
    if law_gap < gap or (with_friction is not None
                         and with_friction[0].gap < with_friction[1].gap):
        beside = ("" if with_friction is None else
                  f"; the sampled current simulates it better only without a dry friction "
                  f"level: with one, {with_friction[0].gap:.2f} % against "
                  f"{with_friction[1].gap:.2f} %")
        return law_bench, law_spec, ho, [
            f"driven by the PI speed loop's current over each sample period ({law_train.note}; "
            f"TRAIN simulated to {law_gap:.2f} %, {gap:.2f} % with the sampled current{late}"
            + beside
            + ("; the drive's lag between the law's command and its current, from both "
               "runs, refined with each model" if law_spec.lag else "") + ")"]
    return bench, spec, ho, [
        f"the PI speed law holds at the samples ({law_train.note}), but its current "
        f"simulates TRAIN to {law_gap:.2f} %, the sampled current to {gap:.2f} %{late}: the "
        "sampled current drives the models (the loop may saturate its voltage between "
        "samples)", *_kick_note(spec), *_supply_note(spec, bench.train)]


def _beside_friction(measured: tuple[Bench, ModelSpec], sampled: tuple[Bench, ModelSpec]
                     ) -> tuple[Scored, Scored] | None:
    """TRAIN's scores of the ``measured`` input's model (the drive's period means or the
    speed law's current) and the ``sampled`` current's, each as (bench, spec), both
    with a dry friction level; None where a run does not determine one (a shaft that
    never reverses).

    The inputs differ in the current between samples, and under a speed loop most of
    that is the kick at each target change: on a run whose target reverses the motion,
    the kick's current that the samples miss opposes the new motion, as a dry
    friction does. A nominal model without the shaft's friction then simulates TRAIN
    better from the samples, whose error stands in for the friction (benchmark 318/185,
    a Coulomb friction under a speed PRBS: the law's current 1.63 %, the period means
    1.08 %, the samples 0.68 %); the models built on them fit the friction with that
    error (`unexplained`). Compared beside a friction level, the inputs differ in the
    current between samples alone. Only runs that hold their speed target are
    compared so (the kicks are at its changes): a current loop has no kicks, and on
    benchmark 306/56 (a cogging and a current offset under a current PRBS) the period
    means that the comparison beside a friction level picked there added a torque
    ripple the samples' models had not."""
    (m_bench, m_spec), (s_bench, s_spec) = measured, sampled
    try:
        return (m_bench.on_train.score(replace(m_spec, coulomb=True)),
                s_bench.on_train.score(replace(s_spec, coulomb=True)))
    except NotExcitedError:
        return None


def _law_spec(law_bench: Bench, spring: bool, lag_sd_s: float,
              delay: int = 0) -> tuple[ModelSpec, float]:
    """The nominal spec driven by the speed law's current, with the lag's refinement
    (``ModelSpec.lag``) where it simulates TRAIN better within what the laws' fits of
    the lag allow (``LAG_SIGMAS`` of ``lag_sd_s``, its standard error); and its TRAIN gap
    with the current shifted back by ``delay`` samples (the spec has none: a delay is
    the vocabulary's, which the candidates search).

    Each run's law gives the drive's lag to several tens of percent on a run of small
    kicks (:mod:`.loop_input` pools the two by their precision); at each target change
    the period's current is then off by that share of the kick. The refinement fits the
    lag's error with the model, from the motion the kicks cause, once for the drive
    (TRAIN), as the input weight of a sampled current is picked. A correction beyond
    what the laws allow, or by a period or more where they give no lag, takes up
    something else (a shaft that sticks at each reversal, whose missing friction a free
    lag of 30 periods traded with ``Kt/J``)."""
    plain = ModelSpec(input_weight=PERIOD_MEAN_WEIGHT, spring=spring)
    gap = law_bench.on_train.score(replace(plain, delay=delay)).gap
    try:
        lagged = law_bench.on_train.score(replace(plain, lag=True, delay=delay))
    except NotExcitedError:
        return plain, gap
    dt = law_bench.train.dt_s
    # a lag is less than a period (beyond, it is a delay, which the vocabulary names)
    if lagged.gap < gap and abs(lag_share(lagged.model)) * dt <= min(LAG_SIGMAS * lag_sd_s, dt):
        return replace(lagged.spec, delay=0), lagged.gap
    return plain, gap


def _kick_note(spec: ModelSpec) -> list[str]:
    """What the models' input carries of a speed loop's kicks (:mod:`.kicks`)."""
    if not spec.kicks:
        return []
    return ["the speed loop's kicks of the current between samples are in every model's "
            "input: the current over each period is the samples' plus terms in the speed "
            "target's change at the period's start (in proportion, slewed as the supply "
            "limits it, and against the back-EMF), fitted with each model; they simulate "
            "TRAIN better than the samples alone"]


def _supply_note(spec: ModelSpec, train: Signals) -> list[str]:
    """What the models' input carries of the current's shape where the drive's voltage
    is at its supply (:mod:`.supply_limit`)."""
    if not spec.supply or train.at_supply is None:
        return []
    return [f"the drive's voltage sits at its supply on {int(np.count_nonzero(train.at_supply))} "
            f"of {len(train)} samples of TRAIN: there the current follows the armature, "
            "not the command, and the current over each such period is the samples' plus "
            "a share of its change, one for each kind of period (at the supply at both "
            f"ends, at its end, at its start; here: {', '.join(spec.supply)}), fitted with "
            "each model; they simulate TRAIN better than the samples alone"]


def _phase_note(share: float) -> list[str]:
    """Why the along-travel test did not run (:func:`.structure.along_travel_test`)."""
    if share <= MAX_PHASE_SHARE:
        return []
    return [f"the test for a level along the travel is not run: on TRAIN the speed at a "
            f"position hardly varies between passes ({100 * share:.1f} % of its position "
            "terms is a function of the motion's phase), so a torque along the travel "
            "cannot be told from one that depends on the speed (record a broadband run, "
            "e.g. PRBS, for that test)"]


def _nominal_spec(on_train: Bench, spring: bool) -> ModelSpec:
    """The nominal model with the input reconstruction that simulates TRAIN best
    (``on_train``: TRAIN against itself, :attr:`Bench.on_train`;
    :func:`stand.diagnosis.input_weight.pick`)."""
    return input_weight.pick(on_train, ModelSpec(spring=spring))


def _nominal_dict(model: FittedModel, kt: float | None) -> dict[str, float]:
    b = model.coef["current"]
    out = {"Kt_over_J": b, "D_over_J": -model.c_omega, "C_over_J": -model.c_theta,
           "condition_number": model.condition_number,
           "input_weight": model.spec.input_weight, "spring": model.spec.spring}
    if kt is not None:
        J = kt / b
        out.update(J=J, D=-model.c_omega * J, C=-model.c_theta * J)
    return out


__all__ = ["ANCHOR_HORIZON_S", "MAX_EFFECTS", "HoldoutComparison", "Traces", "compare_on_holdout",
           "diagnose", "diagnose_with_traces"]
