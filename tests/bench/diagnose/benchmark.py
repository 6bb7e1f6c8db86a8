"""Blind benchmark of the diagnosis on simulated stands with withheld effects.

Each case draws a motor, a drive mode and excitation, sensors, and zero, one or two
effects of the vocabulary over wide ranges (:func:`draw_case`); an effect's parameters
are drawn again until it shows above the sensor noise on HOLDOUT (its SNR,
:mod:`tests.bench.diagnose.snr`, measured with the TRUE plant, at least ``min_snr``;
``min_snr=0`` keeps every first draw), and with ``until_shown`` an outside effect or
a pair's effect until it also shows against the case's twin runs without it; simulates
a TRAIN and a HOLDOUT run with the stand simulator (:mod:`stand.physics`); writes both
as CSV files (CONTRACT §1) and reads them back, so the diagnosis sees only what a user
has; and keeps the answer key apart until the verdict is in (:func:`run_case`).
:func:`summarize_cases` turns the cases into the figures of issue 5: confusion matrix,
top-1 accuracy, false alarms on effect-free cases, median shrink of the true effect.
"""

from __future__ import annotations

import math
import tempfile
import time
from collections import Counter
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from stand.diagnosis import coupling, diagnose, drag, load_friction
from stand.diagnosis.noise import unexplained
from stand.effects import EFFECTS, UNEXPLAINED, approximation_share, nested_in
from stand.errors import StandError
from stand.excitation import excitation
from stand.ident.speed_loop import TARGET_COLUMN
from stand.ident.supply import DriveSupply
from stand.physics.effects import Effects
from stand.physics.parts import DriveParams, MotorParams, SensorParams
from stand.physics.plant import MotorPlant
from stand.physics.simulate import simulate_motor
from stand.runfile import CURRENT_MEAN_COLUMN, Run, read_run, write_run
from tests.bench.diagnose.oracle import ENGINE_TESTS, resolved_truth, visibility, visible_against_twin
from tests.bench.diagnose.outside import (
    HELD_OUT,
    OUTSIDE,
    UNSEEN,
    UNSEEN_2,
    UNSEEN_3,
    UNSEEN_4,
    UNSEEN_5,
    UNSEEN_6,
    UNSEEN_7,
    UNSEEN_8,
    UNSEEN_9,
    draw_outside,
    outside_torque,
)
from tests.bench.diagnose.snr import added_snr, effect_snr

#: Length of each of TRAIN and HOLDOUT, s.
RUN_DURATION_S = 10.0
#: Share of effect-free cases and of two-effect cases (the rest have one effect).
NONE_SHARE = 0.2
PAIR_SHARE = 0.15
#: Relative effect strength range (of the run's typical drive torque): barely visible to strong.
STRENGTH_RANGE = (0.03, 0.3)
#: Highest cogging / torque-ripple order drawn, cycles per revolution (slot and
#: commutator orders of small brushed motors: 3 to 12 slots, two per slot).
MAX_ORDER_DRAWN = 24
#: Encoder resolutions drawn, lines per revolution (4x quadrature).
ENCODER_LINES = (500, 1000, 1024, 2000, 2500, 4096, 5000)
#: Least SNR of the planted effects on HOLDOUT (:mod:`tests.bench.diagnose.snr`): the RMS they
#: add to the exact nominal model's error at least equals what sensor noise gives.
MIN_EFFECT_SNR = 1.0
#: Draws of a case's effect parameters on one stand, and of stands, before the last
#: draw is kept whatever its SNR.
EFFECT_DRAWS = 5
STAND_DRAWS = 8
#: Re-anchoring horizon of the SNR measurement, s (the diagnosis' default).
SNR_HORIZON_S = 0.1


def _log_uniform(rng: np.random.Generator, low: float, high: float) -> float:
    return float(math.exp(rng.uniform(math.log(low), math.log(high))))


@dataclass
class Case:
    """One drawn stand and its answer key."""

    index: int
    seed: int
    motor: MotorParams
    drive: DriveParams
    sensors: SensorParams
    effects: dict[str, dict[str, float]]
    mode: str
    kind: str
    level: float
    amplitude: float
    hold: int
    dt_s: float
    truth: list[str] = field(default_factory=list)
    snr: float | None = None
    draws: int = 1
    current_ref: float = 0.0
    omega_ref: float = 0.0
    #: Effects outside the vocabulary (:mod:`tests.bench.diagnose.outside`).
    outside: dict[str, dict[str, float]] = field(default_factory=dict)
    #: Whether each planted effect of a pair, or the outside effect, shows against the
    #: case's twin runs without it (:func:`_visible_each`), where the draw measured it.
    shown: dict[str, bool] | None = None


#: The outside sets a benchmark can draw from (:mod:`tests.bench.diagnose.outside`).
OUTSIDE_SETS = {"tuning": OUTSIDE, "held_out": HELD_OUT, "unseen": UNSEEN,
                "unseen_2": UNSEEN_2, "unseen_3": UNSEEN_3, "unseen_4": UNSEEN_4,
                "unseen_5": UNSEEN_5, "unseen_6": UNSEEN_6,
                "unseen_7": UNSEEN_7, "unseen_8": UNSEEN_8, "unseen_9": UNSEEN_9}


def draw_case(index: int, seed: int, min_snr: float = MIN_EFFECT_SNR,
              duration_s: float = RUN_DURATION_S, outside_share: float = 0.0,
              outside_set: str = "tuning", until_shown: bool = False,
              current_mean: bool = False) -> Case:
    """Draw case ``index`` of a benchmark seeded with ``seed`` (reproducible).

    Which effects a case has is drawn once. Their parameters are drawn again (up to
    ``EFFECT_DRAWS`` times) until their SNR on HOLDOUT is at least ``min_snr`` (of a
    pair, also what each adds beside the other, :func:`case_snr`); a stand
    and experiment on which they never reach it (backlash under a tight speed loop, a
    high-order ripple at speed) is drawn anew, up to ``STAND_DRAWS`` times, and the last
    draw is kept whatever its SNR. The first draw does not depend on ``min_snr``:
    ``min_snr=0`` gives the cases of an unconditioned draw.

    With ``outside_share``, that share of the cases (drawn from a stream of their own,
    so the other cases stay as without it) has one effect outside the vocabulary
    instead (:mod:`tests.bench.diagnose.outside`), of a strength in ``STRENGTH_RANGE``,
    drawn again like the others until it shows above the noise; ``outside_set`` names
    the set it comes from (a key of :data:`OUTSIDE_SETS`).

    With ``until_shown`` (the benchmark's draw since stop 67), the outside effect, and
    each effect of a pair, must also show against the case's twin runs without it
    (:func:`_visible_each`, on runs with the period-mean current where
    ``current_mean``): an effect that the re-identified nominal model takes up (``Kt/J``
    an elastic load under a sine far below its resonance) leaves no gap beyond noise,
    and ``none`` is then the right answer, not a miss. The check runs only on a draw
    the SNR accepts and consumes no random numbers, so a case whose effects show at
    once is the same draw either way."""
    rng = np.random.default_rng([seed, index])
    stand = _draw_stand(index, seed, rng)
    side = np.random.default_rng([seed, index, 11])
    shows = _shows(duration_s, current_mean) if until_shown else None
    if side.random() < outside_share:
        return _draw_outside_case(stand, side, min_snr, duration_s, OUTSIDE_SETS[outside_set],
                                  index=index, seed=seed, shows=shows)
    truth = _draw_truth(rng)
    draws = 0
    for on, stream in _stands(stand, rng, index, seed):
        for _ in range(EFFECT_DRAWS):
            draws += 1
            effects = {name: _draw_effect(name, stream, on) for name in truth}
            case = replace(on, effects=effects, truth=truth or ["none"], draws=draws)
            if not effects or min_snr <= 0:
                return case
            case.snr = case_snr(case, duration_s)
            if case.snr >= min_snr and (shows is None or len(effects) < 2 or shows(case)):
                return case
    return case


def _shows(duration_s: float, current_mean: bool) -> Callable[[Case], bool]:
    """The draw's test that every effect of a case shows against its twin runs
    (:func:`_visible_each`); it records the figures in ``case.shown``. A draw whose runs
    cannot be read (an effect that holds the shaft still: "position_rad never changes")
    is no case to diagnose and is drawn again."""
    def shows(case: Case) -> bool:
        with tempfile.TemporaryDirectory(prefix="diagnose-draw-") as folder:
            try:
                case.shown = _visible_each(case, None, Path(folder), duration_s, current_mean)
            except StandError:
                case.shown = {name: False for name in [*case.effects, *case.outside]}
        return all(case.shown.values())
    return shows


def _stands(stand: Case, rng: np.random.Generator, index: int, seed: int
            ) -> Iterator[tuple[Case, np.random.Generator]]:
    """The stands a case's effects are drawn on, each with the stream they are drawn
    from: case ``index`` of ``seed``'s own ``stand`` and ``rng``, then up to
    ``STAND_DRAWS − 1`` stands drawn anew, each from a stream of its own."""
    yield stand, rng
    for attempt in range(1, STAND_DRAWS):
        fresh = np.random.default_rng([seed, index, attempt])
        yield _draw_stand(index, seed, fresh), fresh


def _draw_truth(rng: np.random.Generator) -> list[str]:
    """The vocabulary effects of a case: none, one or two, drawn from ``rng`` right after
    the stand."""
    u = rng.random()
    count = 0 if u < NONE_SHARE else 2 if u < NONE_SHARE + PAIR_SHARE else 1
    names = sorted(rng.choice(len(EFFECTS), size=count, replace=False).tolist())
    truth = [EFFECTS[k] for k in names]
    # an effect nested in another drawn with it (Coulomb friction in Stribeck's) is
    # already there
    return [t for t in truth if not set(nested_in(t)) & set(truth)]


#: Case classes a benchmark can be restricted to (:func:`case_class`).
CLASSES = ("none", "single", "pairs", "outside")


def case_class(index: int, seed: int, outside_share: float = 0.0) -> str:
    """The class of case ``index`` of seed ``seed`` (one of :data:`CLASSES`), from the
    first draws of :func:`draw_case` alone: no simulation, so a benchmark restricted to
    one class skips the others at no cost and keeps their case numbers."""
    rng = np.random.default_rng([seed, index])
    _draw_stand(index, seed, rng)
    if np.random.default_rng([seed, index, 11]).random() < outside_share:
        return "outside"
    return {0: "none", 1: "single", 2: "pairs"}[len(_draw_truth(rng))]


def _draw_outside_case(stand: Case, rng: np.random.Generator, min_snr: float,
                       duration_s: float, names: dict[str, Any], *, index: int, seed: int,
                       shows: Callable[[Case], bool] | None = None) -> Case:
    """``stand`` (case ``index`` of ``seed``) with one outside effect of ``names``, drawn
    until its SNR reaches ``min_snr`` (and, with ``shows``, until it passes that test);
    as for the vocabulary's effects, a stand on which it never does (a drive's braking
    limit on a run that never brakes hard) is drawn anew (:func:`_stands`), the effect
    kept."""
    name = str(rng.choice(sorted(names)))
    case, draws = stand, 0
    for on, _ in _stands(stand, rng, index, seed):
        for _ in range(EFFECT_DRAWS):
            draws += 1
            strength = _log_uniform(rng, *STRENGTH_RANGE)
            params = draw_outside(name, rng, on.motor.Kt, _torque_ref(on), on.current_ref,
                                  on.omega_ref, strength, on.motor.J, on.dt_s,
                                  duration_s=duration_s)
            case = replace(on, outside={name: params}, truth=[f"outside:{name}"], draws=draws)
            case.snr = case_snr(case, duration_s)
            if case.snr >= min_snr and (shows is None or shows(case)):
                return case
    return case


def _draw_stand(index: int, seed: int, rng: np.random.Generator) -> Case:
    """A motor, drive, sensors and experiment, without effects."""
    J = _log_uniform(rng, 5e-6, 5e-4)
    Kt = _log_uniform(rng, 0.02, 0.2)
    tau = _log_uniform(rng, 0.05, 2.0)
    motor = MotorParams(R=_log_uniform(rng, 0.5, 5.0), L=_log_uniform(rng, 2e-4, 3e-3),
                        Kt=Kt, J=J, D=J / tau)
    dt = float(rng.uniform(1e-3, 5e-3))
    mode = "current" if rng.random() < 0.6 else "speed"
    kind = str(rng.choice(["prbs", "noise", "sine"]))
    omega_ref = min(_log_uniform(rng, 20.0, 300.0), 0.4 * 48.0 / Kt)
    switch_s = _log_uniform(rng, 0.02, 0.3)
    hold = max(1, int(round(switch_s / dt)))
    if kind == "sine":  # excitation's sine runs at 0.1 / (hold·dt) Hz: 0.3 .. 3 Hz
        hold = max(1, int(round(0.1 / (_log_uniform(rng, 0.3, 3.0) * dt))))
        switch_s = 0.25 / (0.1 / (hold * dt))
    current_ref = J * omega_ref / (Kt * min(tau, switch_s)) + motor.D * omega_ref / Kt
    bandwidth_hz = _log_uniform(rng, 10.0, 40.0)
    kp = 2 * math.pi * bandwidth_hz * J / Kt
    drive = DriveParams(mode=mode, supply_V=48.0, current_limit_A=20.0 * current_ref,  # type: ignore[arg-type]
                        current_tau_s=2e-4, speed_kp=kp, speed_ki=kp * 2 * math.pi * bandwidth_hz / 5)
    sensors = SensorParams(encoder_lines=int(rng.choice(ENCODER_LINES)),
                           current_noise_A=_log_uniform(rng, 0.003, 0.03) * current_ref)
    amplitude = current_ref if mode == "current" else omega_ref
    return Case(index, seed, motor, drive, sensors, {}, mode, kind, 0.0, amplitude, hold, dt,
                current_ref=current_ref, omega_ref=omega_ref)


def case_snr(case: Case, duration_s: float = RUN_DURATION_S) -> float:
    """SNR of the case's effects on its HOLDOUT run (:func:`tests.bench.diagnose.snr.effect_snr`);
    of a pair, the least of the pair's together and of what each adds beside the other
    (:func:`tests.bench.diagnose.snr.added_snr`): a member that adds less than the
    sensors' noise to the other is no more to be named than a single effect below it."""
    holdout, bare = _simulate(case, 1, duration_s), _simulate(case, 1, duration_s, {})
    motor, J_with = case.motor, _rigid_J(case, case.effects)
    snr = effect_snr(holdout, bare, motor.J, J_with, motor.D, motor.Kt, SNR_HORIZON_S)
    if len(case.effects) < 2:
        return snr
    for name in case.effects:
        others = {k: v for k, v in case.effects.items() if k != name}
        beside = _simulate(case, 1, duration_s, others)
        snr = min(snr, added_snr(holdout, beside, bare, J_with, _rigid_J(case, others),
                                 motor.J, motor.D, motor.Kt, SNR_HORIZON_S))
    return snr


def _rigid_J(case: Case, effects: dict[str, dict[str, float]]) -> float:
    """The rigid inertia of ``case``'s stand with ``effects``: the motor's, plus a
    backlash load's."""
    return case.motor.J + effects.get("backlash", {}).get("J_load", 0.0)


def _draw_effect(name: str, rng: np.random.Generator, stand: Case) -> dict[str, float]:
    """Parameters of effect ``name`` on ``stand``, of a strength drawn in
    ``STRENGTH_RANGE`` of its typical drive torque."""
    strength = _log_uniform(rng, *STRENGTH_RANGE)
    return DRAWS[name](rng, stand, strength)


def _max_order(stand: Case) -> int:
    return max(2, min(MAX_ORDER_DRAWN, 4 * stand.sensors.encoder_lines // 16))


def _torque_ref(stand: Case) -> float:
    return stand.motor.Kt * stand.current_ref


def _stribeck(rng: np.random.Generator, stand: Case, strength: float) -> dict[str, float]:
    Ts = strength * _torque_ref(stand)
    return {"Tc": Ts * rng.uniform(0.2, 0.6), "Ts": Ts,
            "ws": stand.omega_ref * _log_uniform(rng, 0.03, 0.3)}


#: How the benchmark draws each effect's parameters: (rng, stand, strength) -> params.
DRAWS: dict[str, Callable[[np.random.Generator, Case, float], dict[str, float]]] = {
    "coulomb_friction": lambda rng, stand, strength: {"Tc": strength * _torque_ref(stand)},
    "stribeck_friction": _stribeck,
    "cogging": lambda rng, stand, strength: {
        "Tcog": strength * _torque_ref(stand), "N": int(rng.integers(2, _max_order(stand) + 1)),
        "phi": rng.uniform(0, 2 * math.pi)},
    "current_offset": lambda rng, stand, strength: {
        "i0": strength * stand.current_ref * float(rng.choice([-1.0, 1.0]))},
    "delay": lambda rng, stand, strength: {"k": int(rng.integers(1, 5))},
    "backlash": lambda rng, stand, strength: {
        "gap": _log_uniform(rng, 0.002, 0.05), "J_load": stand.motor.J * _log_uniform(rng, 0.3, 3.0)},
    "torque_ripple": lambda rng, stand, strength: {
        "eps": _log_uniform(rng, 0.03, 0.3), "N": int(rng.integers(2, _max_order(stand) + 1)),
        "phi": rng.uniform(0, 2 * math.pi)},
}


def simulate_case(case: Case, which: int, duration_s: float = RUN_DURATION_S,
                  effects: dict[str, dict[str, float]] | None = None,
                  current_mean: bool = False) -> dict[str, np.ndarray]:
    """Columns of the TRAIN (``which=0``) or HOLDOUT (1) run of ``case``; ``effects``
    replaces its effects and drops its outside effect (a twin run: the same command,
    sensors and noise seed); ``current_mean``: the drive also reports its current
    averaged over each period (``current_mean_A``; the other columns are the same
    either way)."""
    run = _simulate(case, which, duration_s, effects)
    # a speed-mode run holds its target, as the stand controller records it
    names = ("time_s", "current_A", "position_rad", "voltage_V", TARGET_COLUMN,
             *((CURRENT_MEAN_COLUMN,) if current_mean else ()))
    return {k: run[k] for k in names if k in run}


def case_runs(index: int, seed: int, held_out: bool = False, *,
              outside_set: str | None = None, current_mean: bool = False
              ) -> tuple[Case, Run, Run]:
    """Case ``index`` of the benchmark seeded ``seed`` and its TRAIN and HOLDOUT runs, as
    tests take them (``held_out``: its held-out outside effects drawn at a share of 0.3,
    as the benchmark runs it; ``outside_set``: that set's instead; else none), with the
    drive's period-mean current where ``current_mean`` (``--current-mean``). Drawn by
    the SNR alone, as every seed before 316 was (``--no-until-shown``): a case whose
    effects show at once is the same draw either way."""
    drawn_from = "held_out" if held_out else outside_set
    case = (draw_case(index, seed, outside_share=0.3, outside_set=drawn_from) if drawn_from
            else draw_case(index, seed))
    train, holdout = (Run(simulate_case(case, k, current_mean=current_mean), name)
                      for k, name in enumerate(("train", "holdout")))
    return case, train, holdout


#: Twin runs of the stand simulated last (the SNR's and the visibility's share the
#: effect-free HOLDOUT), by (stand, run, duration, effects).
_TWINS: dict[tuple[str, int, float, str], Run] = {}


def _stand_key(case: Case) -> str:
    """What a run of ``case`` depends on besides its effects: the seed and case number
    (the noise), the motor, drive, sensors and command. A case whose effects never show
    on its first stand is drawn on another (:func:`draw_case`) under the same seed and
    number: keyed on these two alone, its twins stayed those of the first stand, and
    every draw on the new one was measured against another stand's runs (47 of 319
    in-vocabulary cases of dev seeds 260 and 261 ended as the 40th draw at an SNR of 0)."""
    return repr((case.seed, case.index, case.motor, case.drive, case.sensors, case.mode,
                 case.kind, case.level, case.amplitude, case.hold, case.dt_s))


def _simulate(case: Case, which: int, duration_s: float,
              effects: dict[str, dict[str, float]] | None = None) -> Run:
    """The TRAIN (``which=0``) or HOLDOUT (1) run of ``case``, with the truth in ``meta``;
    ``effects`` replaces the case's effects (same command, sensors and noise seed)."""
    if effects is None:
        return _simulated(case, which, duration_s, None)
    key = (_stand_key(case), which, duration_s, repr(sorted(effects.items())))
    if any(k[0] != key[0] for k in _TWINS):
        _TWINS.clear()
    if key not in _TWINS:
        _TWINS[key] = _simulated(case, which, duration_s, effects)
    return _TWINS[key]


def _simulated(case: Case, which: int, duration_s: float,
               effects: dict[str, dict[str, float]] | None) -> Run:
    """:func:`_simulate` without the cache."""
    seed = case.seed * 100_003 + case.index * 2 + which
    chosen = case.effects if effects is None else effects
    plant = MotorPlant(case.motor, case.drive, case.sensors, Effects.from_mapping(chosen),
                       seed=seed)
    if effects is None:
        plant.extra_torque = outside_torque(case.outside, duration_s)
    samples = int(round(duration_s / case.dt_s))
    hold, amplitude = case.hold, case.amplitude
    if which:  # HOLDOUT is another experiment: other rate and excursion of the command
        rng = np.random.default_rng([case.seed, case.index, 7])
        hold = max(1, int(round(hold * _log_uniform(rng, 0.6, 1.6))))
        amplitude *= rng.uniform(0.7, 1.3)
    command = excitation(case.kind, samples, case.dt_s, case.level, amplitude, hold, seed=seed)
    return simulate_motor(plant, case.mode, command, case.dt_s, current_mean=True)


def run_case(index: int, seed: int, duration_s: float = RUN_DURATION_S,
             min_snr: float = MIN_EFFECT_SNR, outside_share: float = 0.0,
             outside_set: str = "tuning", tell_limit: bool = False,
             current_mean: bool = False, until_shown: bool = False) -> dict[str, Any]:
    """Draw, simulate, write, read back and diagnose one case blind; then score it.
    ``tell_limit``: the diagnosis is told the drive's supply and current limit, as a
    motor profile tells them (``stand diagnose --motor``); ``current_mean``: the runs
    also hold the drive's current averaged over each period (:func:`simulate_case`);
    ``until_shown``: :func:`draw_case`'s."""
    case = draw_case(index, seed, min_snr, duration_s, outside_share, outside_set,
                     until_shown=until_shown, current_mean=current_mean)
    with tempfile.TemporaryDirectory(prefix="diagnose-bench-") as folder:
        train, holdout = _read_back(case, Path(folder), duration_s, current_mean)
        start = time.perf_counter()
        try:
            result = diagnose(train, holdout, supply=_supply(case) if tell_limit else None)
        except StandError as exc:  # the engine refused the case: a miss, kept in the count
            return _refused(case, exc, time.perf_counter() - start, len(holdout))
        elapsed = time.perf_counter() - start
        oracle = (visibility(train, holdout, case.motor, case.effects)
                  if case.effects else None)
        each = (case.shown if case.shown is not None
                else _visible_each(case, (train, holdout), Path(folder), duration_s,
                                   current_mean))
    predicted = result.verdict.split("+")
    named = [p for p in predicted if p != UNEXPLAINED] or predicted
    gaps = {e.effect: e for e in result.effects}
    true_shrink = max((gaps[t].shrink for t in case.truth if t in gaps), default=None)
    resolved = resolved_truth(case.truth, oracle.nested if oracle else {})
    return {
        "index": index, "truth": case.truth, "resolved_truth": resolved,
        "verdict": result.verdict, **_named_right(named, case.truth, resolved),
        "unexplained": UNEXPLAINED in predicted, "noise_gap_percent": result.noise_gap_percent,
        "structure_p_value": result.structure_p_value,
        "position_structure_p_value": result.position_structure_p_value,
        "position_structure_shrink": result.position_structure_shrink,
        "speed_structure_p_value": result.speed_structure_p_value,
        "speed_structure_shrink": result.speed_structure_shrink,
        "drift_structure_p_value": result.drift_structure_p_value,
        "drift_structure_shrink": result.drift_structure_shrink,
        "gap_percent": result.gap_percent, "verdict_gap_percent": result.verdict_gap_percent,
        "replayed_noise_gap_percent": result.replayed_noise_gap_percent,
        "noise_floor_percent": result.noise_floor_percent,
        "true_shrink": true_shrink,
        "visible": oracle.visible if oracle else True,
        # each planted effect against its twin runs without it (oracle.visible_against_twin)
        "visible_each": each,
        "oracle_shrink": oracle.shrink if oracle else None,
        "oracle_p": oracle.p_value if oracle else None, "seconds": elapsed, "samples": len(holdout),
        "mode": case.mode, "kind": case.kind, "dt_s": case.dt_s, "effects": case.effects,
        "outside": case.outside, "snr": case.snr, "draws": case.draws,
        "scores": {e.effect: {"shrink": e.shrink, "p": e.p_value, "consistent": e.consistent,
                              "significant": e.significant} for e in result.effects},
        # how the verdict was built: each effect's test as an addition to those before it
        "steps": [{"effect": s.effect, "gap_before": s.gap_before_percent, "gap": s.gap_percent,
                   "p": s.p_value} for s in result.steps],
        "notes": result.notes, "current_mean": current_mean, "until_shown": until_shown,
    }


def _visible_each(case: Case, runs: tuple[Run, Run] | None, folder: Path, duration_s: float,
                  current_mean: bool = False) -> dict[str, bool]:
    """Whether each planted effect of a pair, or the outside effect, shows against the
    case's twin runs without it (:func:`tests.bench.diagnose.oracle.visible_against_twin`):
    alone or first at the first step's level, beside another planted effect at the
    second step's. ``runs``: the case's TRAIN and HOLDOUT as read back (simulated into
    ``folder`` when ``None``)."""
    planted = [*case.effects, *case.outside]
    out: dict[str, bool] = {}
    if len(planted) < 2 and not case.outside:
        return out  # a single vocabulary effect: the oracle's "visible" judges it
    if runs is None:
        runs = _read_back(case, folder, duration_s, current_mean)
    for name in planted:
        others = {k: v for k, v in case.effects.items() if k != name}
        twin = _read_back(case, folder, duration_s, current_mean, others, f"twin_{name}_")
        tests = ENGINE_TESTS - 1 if len(planted) > 1 else ENGINE_TESTS
        out[name] = visible_against_twin(runs, twin, case.motor, others, tests)
    return out


def _read_back(case: Case, folder: Path, duration_s: float, current_mean: bool,
               effects: dict[str, dict[str, float]] | None = None, prefix: str = ""
               ) -> tuple[Run, Run]:
    """The TRAIN and HOLDOUT runs of ``case`` (``effects``, ``current_mean``:
    :func:`simulate_case`'s) written as CSV files into ``folder`` (``prefix`` before
    their names) and read back: what a user has."""
    train, holdout = (read_run(write_run(folder / f"{prefix}{name}.csv",
                                         simulate_case(case, k, duration_s, effects,
                                                       current_mean)), "single")
                      for k, name in enumerate(("train", "holdout")))
    return train, holdout


def rescore(row: dict[str, Any]) -> dict[str, Any]:
    """``row`` with its ``unexplained`` word decided again by the current rule
    (:func:`stand.diagnosis.noise.unexplained`) from the gaps it holds: the rule reads
    nothing else, so this is the verdict the current engine gives on that case when only
    the rule changed since the row was written."""
    if row["verdict"] == "error":
        return row
    named = [p for p in row["verdict"].split("+") if p not in (UNEXPLAINED, "none")]
    p_shapes, p_along = (1.0 if row.get(key) is None else row[key]
                         for key in ("structure_p_value", "position_structure_p_value"))
    p_speed = 1.0 if row.get("speed_structure_p_value") is None else row["speed_structure_p_value"]
    left = unexplained(row["gap_percent"], row["verdict_gap_percent"], row["noise_gap_percent"],
                       p_shapes, p_along, named=bool(named), p_speed=p_speed,
                       speed_shrink=row.get("speed_structure_shrink") or 0.0,
                       # rows written before the drift shapes counted after named effects
                       p_drift=(1.0 if row.get("drift_structure_p_value") is None
                                else row["drift_structure_p_value"]),
                       drift_shrink=row.get("drift_structure_shrink") or 0.0,
                       # rows written before the along test's shrink counted: any shrink
                       along_shrink=row.get("position_structure_shrink", 1.0),
                       share=approximation_share(named))
    # a verdict that dropped backlash for a compliant coupling (stand.diagnosis.coupling),
    # or met a drag continuous through zero speed (stand.diagnosis.drag) or a friction
    # growing with the torque carried (stand.diagnosis.load_friction): unexplained after
    # its effects, whatever the gap they leave
    left = left or any(word in note for note in row.get("notes", [])
                       for word in (coupling.DROPPED, drag.DROPPED, drag.BESIDE,
                                    load_friction.GROWS))
    words = named + ([UNEXPLAINED] if left else [])
    verdict = "+".join(words) if words else "none"
    shown = [p for p in verdict.split("+") if p != UNEXPLAINED] or [verdict]
    return {**row, "verdict": verdict, "unexplained": left,
            **_named_right(shown, row["truth"], row.get("resolved_truth", row["truth"]))}


def _named_right(named: list[str], truth: list[str], resolved: list[str]) -> dict[str, bool]:
    """Whether the verdict's first effect is planted (``top1``) and whether it names
    the planted set (``exact``), against the truth or the truth as far as the runs
    resolve it (:func:`tests.bench.diagnose.oracle.resolved_truth`: Coulomb friction for
    a Stribeck friction whose static excess never shows); ``*_strict``: against the
    truth alone."""
    top1, exact = named[0] in truth, sorted(named) == sorted(truth)
    return {"top1": top1 or named[0] in resolved,
            "exact": exact or sorted(named) == sorted(resolved),
            "top1_strict": top1, "exact_strict": exact}


def _refused(case: Case, exc: StandError, seconds: float, samples: int) -> dict[str, Any]:
    """The row of a case the engine refused to diagnose (counted as wrong)."""
    return {
        "index": case.index, "truth": case.truth, "verdict": "error", "top1": False,
        "exact": False, "gap_percent": None, "verdict_gap_percent": None,
        "true_shrink": None, "visible": True, "oracle_shrink": None, "oracle_p": None,
        "seconds": seconds, "samples": samples, "mode": case.mode, "kind": case.kind,
        "dt_s": case.dt_s, "effects": case.effects, "snr": case.snr, "draws": case.draws,
        "scores": {}, "error": str(exc),
    }


def summarize_cases(rows: list[dict[str, Any]]) -> dict[str, Any]:
    """Figures of the benchmark: accuracy, false alarms, shrink, confusion matrix."""
    labels = ["none", *EFFECTS, UNEXPLAINED]
    confusion: dict[str, Counter[str]] = {label: Counter() for label in labels[:-1]}
    for row in rows:
        confusion.setdefault(row["truth"][0], Counter())[row["verdict"].split("+")[0]] += 1
    none_rows = [r for r in rows if r["truth"] == ["none"]]
    effect_rows = [r for r in rows if r["truth"] != ["none"]]
    outside = [r for r in rows if r["truth"][0].startswith("outside:")]
    inside = [r for r in effect_rows if r not in outside]
    pairs = [r for r in inside if len(r["truth"]) == 2]

    def share(subset: list[dict[str, Any]], key: Callable[[dict[str, Any]], bool]
              ) -> float | None:
        return float(np.mean([key(r) for r in subset])) if subset else None

    def shown(subset: list[dict[str, Any]]) -> list[dict[str, Any]]:
        return [r for r in subset if all(r.get("visible_each", {}).values())]

    classes = {
        "in_vocabulary_cases": len(inside),
        "in_vocabulary_top1": share(inside, lambda r: r["top1"]),
        "in_vocabulary_top1_strict": share(inside, lambda r: r.get("top1_strict", r["top1"])),
        "resolved_differs": sum(r.get("resolved_truth", r["truth"]) != r["truth"] for r in inside),
        "in_vocabulary_wrongly_unexplained": share(inside, lambda r: r.get("unexplained", False)),
        # of those: the planted effects all named (and unexplained after them), and
        # nothing named at all (a missed effect called unexplained instead of none)
        "in_vocabulary_unexplained_after_exact": sum(
            r.get("unexplained", False) and r["exact"] for r in inside),
        "in_vocabulary_unexplained_nothing_named": sum(
            r["verdict"] == UNEXPLAINED for r in inside),
        "pair_cases": len(pairs), "pairs_exact": share(pairs, lambda r: r["exact"]),
        "pairs_exact_strict": share(pairs, lambda r: r.get("exact_strict", r["exact"])),
        # a diagnostic beside the headline: the cases whose every planted effect shows
        # against its twin runs without it (row "visible_each"; rows before it count)
        "pairs_shown": len(shown(pairs)), "pairs_shown_exact": share(shown(pairs), lambda r: r["exact"]),
        "outside_shown": len(shown(outside)),
        "outside_shown_unexplained": share(shown(outside), lambda r: r.get("unexplained", False)),
        "outside_shown_none": sum(r["verdict"] == "none" for r in shown(outside)),
        "outside_cases": len(outside),
        "outside_unexplained": share(outside, lambda r: r.get("unexplained", False)),
        "outside_none": sum(r["verdict"] == "none" for r in outside),
        "outside_by_effect": {
            name: [sum(r.get("unexplained", False) for r in outside if r["truth"][0] == f"outside:{name}"),
                   sum(r["truth"][0] == f"outside:{name}" for r in outside)]
            for name in sorted({r["truth"][0].split(":", 1)[1] for r in outside})},
    }
    shrinks = [r["true_shrink"] for r in effect_rows if r["true_shrink"] is not None]
    visible = [r for r in rows if r.get("visible", True)]
    measured = [r for r in effect_rows if r.get("snr") is not None]
    return {
        "cases": len(rows),
        "redrawn_cases": sum(r.get("draws", 1) > 1 for r in rows),
        # rows drawn with draw_case's until_shown (rows before it: none)
        "until_shown_cases": sum(r.get("until_shown", False) for r in rows),
        "snr_measured_cases": len(measured),
        "median_snr": float(np.median([r["snr"] for r in measured])) if measured else None,
        "refused": sum(r["verdict"] == "error" for r in rows),
        "visible_cases": len(visible),
        "visible_top1_accuracy": (float(np.mean([r["top1"] for r in visible]))
                                  if visible else None),
        "top1_accuracy": float(np.mean([r["top1"] for r in rows])) if rows else None,
        "exact_accuracy": float(np.mean([r["exact"] for r in rows])) if rows else None,
        "none_cases": len(none_rows),
        "false_alarm_rate": (float(np.mean([r["verdict"] != "none" for r in none_rows]))
                             if none_rows else None),
        "missed_rate": (float(np.mean([r["verdict"] == "none" for r in effect_rows]))
                        if effect_rows else None),
        "median_true_shrink": float(np.median(shrinks)) if shrinks else None,
        "median_seconds": float(np.median([r["seconds"] for r in rows])) if rows else None,
        "confusion": {t: dict(c) for t, c in confusion.items()},
        **classes,
        "labels": labels,
    }


def confusion_table(summary: dict[str, Any]) -> str:
    """The confusion matrix as text (rows: the first true effect in vocabulary order;
    columns: the first effect of the verdict)."""
    labels = summary["labels"]
    short = {name: name.replace("_friction", "").replace("current_", "")[:8] for name in labels}
    head = "truth \\ verdict".ljust(18) + "".join(short[c].rjust(9) for c in labels)
    lines = [head]
    for t in [*labels[:-1], *sorted(set(summary["confusion"]) - set(labels))]:
        row = summary["confusion"].get(t, {})
        name = t.replace("outside:", "out:")[:18].ljust(18)
        lines.append(name + "".join(str(row.get(c, 0)).rjust(9) for c in labels))
    return "\n".join(lines)


def _supply(case: Case) -> DriveSupply:
    """The drive's supply and current limit and the motor's armature, as its profile
    holds them."""
    return DriveSupply(case.drive.supply_V, case.motor.R, case.motor.L, case.motor.Kt,
                       case.drive.current_limit_A)


def _run_case_args(args: tuple[int, int, float, float, float, str, bool, bool, bool]
                   ) -> dict[str, Any]:
    return run_case(*args)


def run_benchmark(cases: int, seed: int, workers: int = 2, duration_s: float = RUN_DURATION_S,
                  min_snr: float = MIN_EFFECT_SNR, outside_share: float = 0.0,
                  first: int = 0, outside_set: str = "tuning",
                  on_row: Callable[[dict[str, Any]], None] | None = None,
                  classes: tuple[str, ...] | None = None,
                  tell_limit: bool = False, current_mean: bool = False,
                  until_shown: bool = False) -> list[dict[str, Any]]:
    """Run the blind cases ``first`` .. ``first + cases - 1`` with ``workers`` processes;
    with ``classes``, only those of these classes (:func:`case_class`). Rows in case
    order, each also handed to ``on_row`` as soon as it is in. ``tell_limit``,
    ``current_mean``, ``until_shown``: :func:`run_case`'s."""
    jobs = [(index, seed, duration_s, min_snr, outside_share, outside_set, tell_limit,
             current_mean, until_shown)
            for index in range(first, first + cases)
            if classes is None or case_class(index, seed, outside_share) in classes]
    rows = []
    if workers <= 1:
        for job in jobs:
            rows.append(_run_case_args(job))
            if on_row:
                on_row(rows[-1])
        return rows
    import multiprocessing

    with multiprocessing.get_context("spawn").Pool(workers) as pool:
        for row in pool.imap(_run_case_args, jobs, chunksize=1):
            rows.append(row)
            if on_row:
                on_row(row)
    return rows


def timing_case(duration_s: float = 20.0, dt_s: float = 1e-3, seed: int = 0) -> dict[str, float]:
    """Wall time of reading and diagnosing ``duration_s`` of data at ``1/dt_s`` Hz.

    The stand: a current-mode PRBS run with Coulomb friction, 2500-line encoder.
    """
    motor = MotorParams(R=2.0, L=1e-3, Kt=0.05, J=2e-5, D=4e-5)
    sensors = SensorParams(encoder_lines=2500, current_noise_A=0.01)
    samples = int(round(duration_s / dt_s))
    with tempfile.TemporaryDirectory(prefix="diagnose-timing-") as folder:
        paths = []
        for k in range(2):
            plant = MotorPlant(motor, DriveParams(mode="current"), sensors,
                               Effects.from_mapping({"coulomb_friction": {"Tc": 0.004}}),
                               seed=seed + k)
            command = excitation("prbs", samples, dt_s, 0.0, 0.5, 50, seed=seed + k)
            run = simulate_motor(plant, "current", command, dt_s)
            paths.append(write_run(Path(folder) / f"run{k}.csv",
                                   {c: run[c] for c in ("time_s", "current_A", "position_rad")}))
        start = time.perf_counter()
        train, holdout = (read_run(p, "single") for p in paths)
        diagnose(train, holdout)
        elapsed = time.perf_counter() - start
    return {"duration_s": duration_s, "rate_hz": 1.0 / dt_s, "seconds": elapsed}
