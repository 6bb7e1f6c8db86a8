"""What cogging and torque ripple share: torques periodic in the shaft position, of an
order ``N`` searched over what the run resolves, fixed to the rotor in phase."""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from stand.diagnosis.model import FittedModel, ModelSpec
from stand.diagnosis.signals import Signals
from stand.effects.base import NO_FIT, best, need, phase

#: Largest cogging / ripple order searched, cycles per revolution.
MAX_ORDER = 60
#: Highest order the identification tries, cycles per revolution.
IDENT_MAX_ORDER = 48
#: Finest position order searched relative to the encoder: at least this many counts a cycle.
MIN_COUNTS_PER_CYCLE = 16
#: Fewest cycles of a cogging / ripple order over the positions a run covers.
MIN_CYCLES_IN_RECORD = 3.0
#: Largest difference of the phases of an order fitted on TRAIN and on HOLDOUT that still
#: agrees, rad. Both are fixed to the rotor, so runs that share the encoder's zero (as
#: runs recorded from the drive's position actual value do) find the same phase; a
#: coincidence of one run has a phase at random.
PHASE_TOLERANCE_RAD = math.pi / 6


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


def search_order(base: ModelSpec, train: Signals, of_order: Callable[[int], ModelSpec]
                 ) -> ModelSpec:
    """``base`` plus the term ``of_order(N)`` of the order of smallest equation error on
    ``train`` among those it resolves (:func:`orders`); :data:`NO_FIT` if none."""
    found = orders(train)
    if not found:
        return NO_FIT
    return best([base.merged(of_order(n)) for n in found], train)


def ident_orders(of_order: Callable[[int], ModelSpec]) -> list[ModelSpec]:
    """``of_order(N)`` at each order the identification tries, 1 to ``IDENT_MAX_ORDER``
    cycles per revolution."""
    return [of_order(n) for n in range(1, IDENT_MAX_ORDER + 1)]


def harmonic_params(coef: Callable[[str], float], prefix: str, order: int | None,
                    size_key: str) -> dict[str, float]:
    """Size (per the ``current`` coefficient), order and phase of the harmonic whose
    columns are ``<prefix>_sin`` and ``<prefix>_cos``."""
    s, c = coef(f"{prefix}_sin"), coef(f"{prefix}_cos")
    return {size_key: math.hypot(s, c) / coef("current"), "N": float(order or 0),
            "phi_rad": math.atan2(c, s)}
