"""The candidate effects of CONTRACT §3 as model extensions, and their small searches.

Each candidate adds regressors to a base model (:class:`~stand.diagnosis.model.ModelSpec`).
Most are linear in their parameters; the delay ``k``, the order ``N`` of cogging and
torque ripple, the Stribeck velocity and the backlash gap are picked on TRAIN by the
smallest equation-error RMS over a grid (the Q-matrix solver, batched where the grid
keeps the number of columns), among fits of physical sign (a static level above the
Coulomb level, a positive load inertia), and for the delay and the gap only where the
grid brackets the optimum (:func:`search`). The backlash gap and restitution are
picked by simulating TRAIN instead when the caller gives the simulation.

Parameters come back relative to the torque constant (the current-driven model only
identifies torques per ``Kt``): ``Tc_over_Kt_A`` etc., in amperes of current that make
the same torque; with ``kt`` given also in N·m.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import replace

import numpy as np

from stand.diagnosis.model import FittedModel, ModelSpec, fit_residual_batch
from stand.diagnosis.signals import Signals
from stand.errors import InputError

#: Effect names in vocabulary order (``none`` excluded).
EFFECTS: tuple[str, ...] = ("coulomb_friction", "stribeck_friction", "cogging",
                            "current_offset", "delay", "backlash", "torque_ripple")
#: Largest current delay searched, samples.
MAX_DELAY_SAMPLES = 10
#: Largest cogging / ripple order searched, cycles per revolution.
MAX_ORDER = 60
#: Finest position order searched relative to the encoder: at least this many counts a cycle.
MIN_COUNTS_PER_CYCLE = 16
#: Fewest cycles of a cogging / ripple order over the positions a run covers.
MIN_CYCLES_IN_RECORD = 3.0
#: Grid size of the Stribeck velocity and backlash gap searches.
GRID_POINTS = 12
#: Range of backlash half-gaps searched, rad (from ``MIN_GAP_COUNTS`` encoder counts at
#: least).
MIN_GAP_RAD = 1e-4
MAX_GAP_RAD = 0.3
#: Smallest backlash half-gap searched, encoder counts. Quantization alone looks like a
#: dead zone of a few counts: around every reversal the count dwells at the turning point
#: and then steps, and the low-pass position spreads that over its kernel. On effect-free
#: sine runs (of a speed or a current loop) a backlash of 2 to 5 counts of half-gap fitted
#: it, simulated it again on the other run of the same motion, and shrank the gap by
#: 6-24 %, significantly and consistently: the false alarms with the old floor of 2.
MIN_GAP_COUNTS = 4
#: Halvings of the (logarithmic) gap step around the best grid gap, when the gap is
#: picked by simulation (a simulation error is not smooth enough in the gap between grid
#: points for the grid alone to be near its optimum).
GAP_REFINEMENTS = 3
#: Coefficients of restitution of the backlash contact searched (0: the load is carried).
RESTITUTIONS: tuple[float, ...] = (0.0, 0.5)


#: What :func:`search` returns when no grid point gives a physical fit.
NO_FIT = ModelSpec(input_weight=-1.0)


def _best(specs: list[ModelSpec], train: Signals, negative: tuple[str, ...] = (),
          simulated: Callable[[ModelSpec], float] | None = None) -> ModelSpec:
    """The spec of smallest equation-error RMS on ``train``; with ``negative``, only among
    fits whose coefficients of those columns are negative (the physical sign); with
    ``simulated`` (a spec's simulation error on ``train``), the one that simulates
    ``train`` best among those."""
    rms, coef = fit_residual_batch(specs, train)
    for name in negative:
        column = specs[0].names().index(name)
        rms = np.where(coef[:, column] < 0, rms, np.inf)
    if not np.isfinite(rms).any():
        return NO_FIT
    if simulated is not None:
        rms = np.array([simulated(spec) if np.isfinite(r) else np.inf
                        for spec, r in zip(specs, rms, strict=True)])
    return specs[int(np.argmin(rms))]


def _orders(train: Signals) -> list[int]:
    """Orders the run can tell apart from a smooth function of position: at most one
    cycle per ``MIN_COUNTS_PER_CYCLE`` encoder counts, and at least
    ``MIN_CYCLES_IN_RECORD`` cycles over the range of positions the run covers."""
    top = MAX_ORDER
    if train.quant_rad > 0:
        counts = 2 * math.pi / train.quant_rad
        top = max(1, min(top, int(counts // MIN_COUNTS_PER_CYCLE)))
    span_rev = float(np.ptp(train.theta_f)) / (2 * math.pi)
    low = max(1, math.ceil(MIN_CYCLES_IN_RECORD / span_rev)) if span_rev > 0 else top + 1
    return list(range(low, top + 1))


def delay_grid(base: ModelSpec) -> list[ModelSpec]:
    """``base`` with each delay searched, 1 to ``MAX_DELAY_SAMPLES`` samples and one
    beyond (where a best fit is an optimum the search does not bracket)."""
    return [base.merged(ModelSpec(delay=k)) for k in range(1, MAX_DELAY_SAMPLES + 2)]


def search(effect: str, base: ModelSpec, train: Signals,
           simulated: Callable[[ModelSpec], float] | None = None) -> ModelSpec:
    """The model ``base`` plus ``effect``, its hyper-parameters picked on ``train``.

    The delay and backlash searches go one grid step beyond the largest value they
    report (``MAX_DELAY_SAMPLES``, ``MAX_GAP_RAD``): a best fit there is an optimum the
    search did not bracket (the equation error still falls as the delay or gap grows:
    a fit of something else, such as the nominal model's own error on a speed loop, not
    a value the run resolves), and the search returns :data:`NO_FIT`. The backlash
    search also goes one step below its smallest gap (``MIN_GAP_COUNTS``), for the
    same reason: a best fit there is a dead zone the encoder does not resolve.

    ``simulated`` gives a spec's simulation error on ``train``. With it, the backlash
    gap and restitution are those that simulate ``train`` best among the fits of
    physical sign, rather than those of the smallest equation error: an impact within
    a sample period, through a contact that is not rigid, leaves an equation error the
    kinematic load estimate does not follow, and gaps near the true one differ there
    by little, while their free runs differ clearly.
    """
    if effect == "coulomb_friction":
        return base.merged(ModelSpec(coulomb=True))
    if effect == "current_offset":
        return base.merged(ModelSpec(offset=True))
    if effect == "delay":
        best = _best(delay_grid(base), train)
        return NO_FIT if (best.delay or 0) > MAX_DELAY_SAMPLES else best
    if effect in ("cogging", "torque_ripple"):
        orders = _orders(train)
        if not orders:
            return NO_FIT
        if effect == "cogging":
            return _best([base.merged(ModelSpec(cogging_N=n)) for n in orders], train)
        return _best([base.merged(ModelSpec(ripple_N=n)) for n in orders], train)
    if effect == "stribeck_friction":
        grid = train.top_speed * np.geomspace(0.01, 0.5, GRID_POINTS)
        return _best([base.merged(ModelSpec(stribeck_ws=float(w))) for w in grid], train,
                     negative=("stribeck",))
    if effect == "backlash":
        low = max(MIN_GAP_COUNTS * train.quant_rad, MIN_GAP_RAD)
        high = max(MAX_GAP_RAD, 4 * low)
        grid = np.geomspace(low, high, GRID_POINTS)
        ratio = grid[1] / grid[0]
        grid = np.concatenate([[low / ratio], grid, [high * ratio]])  # bracketed?
        best = _best([base.merged(ModelSpec(backlash_gap=float(g), backlash_restitution=e))
                      for g in grid for e in RESTITUTIONS], train, negative=("load_accel",),
                     simulated=simulated)
        if not low <= (best.backlash_gap or 0.0) <= high:
            return NO_FIT
        for _ in range(GAP_REFINEMENTS if simulated is not None else 0):
            ratio = math.sqrt(ratio)
            gaps = [g for g in ((best.backlash_gap or 0.0) * f for f in (1 / ratio, ratio))
                    if low <= g <= high]
            best = _best([best, *(replace(best, backlash_gap=float(g)) for g in gaps)], train,
                         negative=("load_accel",), simulated=simulated)
        return best
    raise InputError(f"effect must be one of {', '.join(EFFECTS)}, not {effect!r}")


def _torque(value_per_J: float, model: FittedModel, kt: float | None, name: str,
            out: dict[str, float | int | None]) -> None:
    """Store a torque given per unit inertia (rad/s²) as ``name_over_Kt_A`` and ``name``."""
    over_kt = value_per_J / model.coef["current"]
    out[f"{name}_over_Kt_A"] = over_kt
    if kt is not None:
        out[name] = over_kt * kt


def _phase(model: FittedModel, prefix: str) -> tuple[float, float]:
    s, c = model.coef[f"{prefix}_sin"], model.coef[f"{prefix}_cos"]
    return math.hypot(s, c), math.atan2(c, s)


#: Largest difference of the delays found on TRAIN and HOLDOUT that still agrees, samples.
DELAY_TOLERANCE_SAMPLES = 1
#: Largest ratio of an effect's size fitted on TRAIN and on HOLDOUT that still agrees.
AGREE_RATIO = 3.0
#: Largest difference of the phases of a cogging or ripple order fitted on TRAIN and on
#: HOLDOUT that still agrees, rad. Both are fixed to the rotor, so runs that share the
#: encoder's zero (as runs recorded from the drive's position actual value do) find the
#: same phase; a coincidence of one run has a phase at random.
PHASE_TOLERANCE_RAD = math.pi / 6


#: Smallest static excess ``(Ts − Tc)/Tc`` that makes friction Stribeck rather than
#: Coulomb friction (below it the two are the same within what the data resolve).
STRIBECK_MIN_EXCESS = 0.15
#: Stribeck velocities of TRAIN and HOLDOUT may differ by this factor (a flat optimum:
#: ωs trades against the static excess).
STRIBECK_WS_RATIO = 5.0


def _ratio_ok(a: float, b: float, limit: float = AGREE_RATIO) -> bool:
    return a * b > 0 and max(abs(a), abs(b)) <= limit * min(abs(a), abs(b))


def agree(effect: str, first: FittedModel, second: FittedModel) -> bool:
    """Whether ``effect`` fitted on two independent runs is the same effect: the same
    order or delay, and sizes (and grid parameters) of the same sign within
    ``AGREE_RATIO``; cogging and ripple also in the same phase (the runs must share the
    encoder's zero). A real effect is found again; one that fits a coincidence of TRAIN
    is not. Stribeck friction also needs a static excess of at least
    ``STRIBECK_MIN_EXCESS`` on both runs."""
    a, b = first.spec, second.spec
    ca, cb = first.coef, second.coef
    if NO_FIT in (a, b):
        return False
    if effect == "coulomb_friction":
        return ca["sign"] < 0 and _ratio_ok(ca["sign"], cb["sign"])
    if effect == "stribeck_friction":
        sa, sb = ca["sign"] + ca["stribeck"], cb["sign"] + cb["stribeck"]
        # a Coulomb level Tc >= 0 under a static level Ts >= Tc·(1 + excess) on both
        # runs: a fit whose "Coulomb" torque pushes the shaft along is not friction
        resolved = all(c["sign"] <= 0 and c["stribeck"] < -STRIBECK_MIN_EXCESS * abs(c["sign"])
                       for c in (ca, cb))
        return (sa < 0 and _ratio_ok(sa, sb) and resolved
                and a.stribeck_ws is not None
                and b.stribeck_ws is not None
                and _ratio_ok(a.stribeck_ws, b.stribeck_ws, STRIBECK_WS_RATIO))
    if effect == "current_offset":
        return _ratio_ok(ca["one"], cb["one"])
    if effect == "delay":  # a delay is resolved to a sample at best; the input
        # reconstruction weight of the nominal model already trades up to one sample
        return abs(a.delay - b.delay) <= DELAY_TOLERANCE_SAMPLES
    if effect in ("cogging", "torque_ripple"):
        prefix = "cog" if effect == "cogging" else "rip"
        order_a = a.cogging_N if effect == "cogging" else a.ripple_N
        order_b = b.cogging_N if effect == "cogging" else b.ripple_N
        (size_a, phase_a), (size_b, phase_b) = _phase(first, prefix), _phase(second, prefix)
        if abs(math.remainder(phase_a - phase_b, 2 * math.pi)) > PHASE_TOLERANCE_RAD:
            return False
        if effect == "torque_ripple":  # |ε| < 1: the torque keeps the sign of the current
            size_a, size_b = size_a / ca["current"], size_b / cb["current"]
            if not (0 < size_a < 1 and 0 < size_b < 1):
                return False
        return order_a == order_b and _ratio_ok(size_a, size_b)
    if effect == "backlash":
        return (a.backlash_gap is not None and b.backlash_gap is not None
                and ca["load_accel"] < 0 and cb["load_accel"] < 0
                and _ratio_ok(a.backlash_gap, b.backlash_gap, 2 * AGREE_RATIO))
    raise InputError(f"effect must be one of {', '.join(EFFECTS)}, not {effect!r}")


def params(effect: str, model: FittedModel, kt: float | None) -> dict[str, float | int | None]:
    """Physical parameters of ``effect`` in the fitted ``model``.

    Torques are reported as ``<name>_over_Kt_A`` (A), and as ``<name>`` in N·m when the
    torque constant ``kt`` (N·m/A) is known; ``J`` then follows as ``Kt/c_i``.
    """
    spec, c = model.spec, model.coef
    out: dict[str, float | int | None] = {}
    if spec == NO_FIT:
        return out
    if effect == "coulomb_friction":
        _torque(-c["sign"], model, kt, "Tc", out)
    elif effect == "stribeck_friction":
        _torque(-c["sign"], model, kt, "Tc", out)
        _torque(-c["sign"] - c["stribeck"], model, kt, "Ts", out)
        out["ws"] = spec.stribeck_ws
    elif effect == "cogging":
        amplitude, phase = _phase(model, "cog")
        _torque(amplitude, model, kt, "Tcog", out)
        out["N"] = spec.cogging_N
        out["phi"] = math.atan2(-math.sin(phase), -math.cos(phase))  # torque is −Tcog·sin
    elif effect == "current_offset":
        out["i0"] = -c["one"] / c["current"]
    elif effect == "delay":
        out["k"] = spec.delay
    elif effect == "backlash":
        out["gap"] = spec.backlash_gap
        out["restitution"] = spec.backlash_restitution
        ratio = max(-c["load_accel"], 0.0)
        out["J_load_over_J"] = ratio
        if kt is not None:
            out["J_load"] = ratio * kt / c["current"]
    elif effect == "torque_ripple":
        amplitude, phase = _phase(model, "rip")
        out["eps"] = amplitude / c["current"]
        out["N"] = spec.ripple_N
        out["phi"] = phase
    return out
