"""What cogging and torque ripple share: torques periodic in the shaft position, of an
order ``N`` searched over what the run resolves, fixed to the rotor in phase."""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from stand.diagnosis.model import FittedModel, ModelSpec, fit_residual_batch
from stand.diagnosis.signals import Signals
from stand.diagnosis.significance import MIN_SHRINK
from stand.effects.base import NO_FIT, Simulated, best, need, phase

#: Largest cogging / ripple order searched, cycles per revolution.
MAX_ORDER = 60
#: Highest order the identification tries, cycles per revolution.
IDENT_MAX_ORDER = 48
#: Finest position order searched relative to the encoder: at least this many counts a cycle.
MIN_COUNTS_PER_CYCLE = 16
#: Fewest cycles of a cogging / ripple order over the positions a run covers: below two
#: a harmonic is a slow function of position along the travel, which a level and a slope
#: would take as well. (At three, a ripple of order 2 on runs of 1.3 revolutions was out
#: of reach: benchmark seed 280 case 46.)
MIN_CYCLES_IN_RECORD = 2.0
#: Largest difference of the phases of an order fitted on TRAIN and on HOLDOUT that still
#: agrees, rad. Both are fixed to the rotor, so runs that share the encoder's zero (as
#: runs recorded from the drive's position actual value do) find the same phase; a
#: coincidence of one run has a phase at random.
PHASE_TOLERANCE_RAD = math.pi / 6
#: Phase a harmonic turns through in one sample period at the run's top speed, rad,
#: beyond which the equation error is not left to rank orders alone. Its acceleration,
#: the second difference over ±2 samples, passes a harmonic turning ``x`` rad a sample
#: at ``sinc²(x)`` of its size (92 % at 0.5 rad, 29 % at 1.8 rad), so there it holds
#: little of a fast order and a neighbouring one can rank first on the columns' small
#: errors; the free run integrates the torque itself (a ripple of order 7 turning 1.8
#: rad a sample ranked below order 6 by equation error, and simulated TRAIN 6 % and
#: HOLDOUT 53 % better). Beyond it the simulation of the run picks among the
#: :data:`SHORTLIST` orders of smallest equation error, and overrides the first of them
#: only when it simulates the run better by :data:`SIMULATION_MARGIN` (the overrides
#: measured: 1.6-20 %; the near tie that flipped a right order: 0.07 %).
FAST_PHASE_STEP = 0.5
SHORTLIST = 3
SIMULATION_MARGIN = 0.01


def orders(train: Signals) -> list[int]:
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


def in_phase(first: FittedModel, second: FittedModel, prefix: str
             ) -> tuple[bool, float, float]:
    """Whether the ``prefix`` terms of two fits are in phase within
    ``PHASE_TOLERANCE_RAD``, and their two amplitudes (per unit inertia, rad/s²)."""
    (size_a, phase_a), (size_b, phase_b) = phase(first, prefix), phase(second, prefix)
    ok = abs(math.remainder(phase_a - phase_b, 2 * math.pi)) <= PHASE_TOLERANCE_RAD
    return ok, size_a, size_b


def check_order(N: int, where: str) -> None:
    """Raise :class:`~stand.errors.InputError` naming ``where`` unless ``N >= 1``."""
    need(N >= 1, where, f"N must be a whole number >= 1 cycle/rev, got {N}")


def search_order(base: ModelSpec, train: Signals, of_order: Callable[[int], ModelSpec],
                 simulated: Simulated | None = None) -> ModelSpec:
    """``base`` plus the term ``of_order(N)`` of the order of smallest equation error on
    ``train`` among those it resolves (:func:`orders`); :data:`NO_FIT` if none. Where
    the fastest of the :data:`SHORTLIST` orders of smallest equation error turns more
    than :data:`FAST_PHASE_STEP` a sample at the run's top speed, the first of them
    shrinks the equation error by at least
    :data:`~stand.diagnosis.significance.MIN_SHRINK`, and ``simulated`` is given (a
    spec's gap simulating ``train``), the one that simulates ``train`` best among the
    :data:`SHORTLIST` of smallest equation error, by :data:`SIMULATION_MARGIN` at least
    over the first."""
    found = orders(train)
    if not found:
        return NO_FIT
    specs = [base.merged(of_order(n)) for n in found]
    if simulated is None:
        return best(specs, train)
    rms, _ = fit_residual_batch(specs, train)   # specs of one shape per batch
    ranked = [int(k) for k in np.argsort(rms) if np.isfinite(rms[k])][:SHORTLIST]
    if not ranked:
        return NO_FIT
    first = specs[ranked[0]]
    if max(found[k] for k in ranked) * train.top_speed * train.dt_s <= FAST_PHASE_STEP:
        return first
    # an order that barely moves the equation error is no effect the verdict could
    # name, however it ranks: not worth a simulation
    before = float(fit_residual_batch([base], train)[0][0])
    if not (before > 0 and 1.0 - rms[ranked[0]] / before >= MIN_SHRINK):
        return first
    gaps = simulated.many([specs[k] for k in ranked])   # ranked: finite fits only
    picked = int(np.argmin(gaps))
    # a near tie keeps the equation error's order (a flip there broke the agreement
    # of TRAIN's and HOLDOUT's searches for a ripple both had right)
    return specs[ranked[picked]] if gaps[picked] < (1 - SIMULATION_MARGIN) * gaps[0] else first


def ident_orders(of_order: Callable[[int], ModelSpec],
                 allowed: Callable[[int], bool] = lambda n: True) -> list[ModelSpec]:
    """``of_order(N)`` at each order the identification tries, 1 to ``IDENT_MAX_ORDER``
    cycles per revolution (those ``allowed``)."""
    return [of_order(n) for n in range(1, IDENT_MAX_ORDER + 1) if allowed(n)]


def harmonic_params(coef: Callable[[str], float], prefix: str, order: int | None,
                    size_key: str) -> dict[str, float]:
    """Size (per the ``current`` coefficient), order and phase of the harmonic whose
    columns are ``<prefix>_sin`` and ``<prefix>_cos``."""
    s, c = coef(f"{prefix}_sin"), coef(f"{prefix}_cos")
    return {size_key: math.hypot(s, c) / coef("current"), "N": float(order or 0),
            "phi_rad": math.atan2(c, s)}
