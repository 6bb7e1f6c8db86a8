"""The speed loop's kicks of the current between samples, as part of the input
reconstruction.

A drive in speed mode kicks its current at each change of the speed target, by
``kp·Δr`` where its supply lets it, and pulls it back within a few milliseconds, most
of it between two samples (:mod:`stand.ident.speed_loop`). Where the PI law explains the
sampled current, its current over each period drives the models
(:mod:`.loop_input`). Where it does not (the loop saturates its voltage, or the law is
another), the samples alone miss the charge of each kick, and a free run of any model
drifts by it at every target change: a gap on a stand that has no effect.

What the samples miss of a kick lies in the period the target changes in: the next
sample already holds what is left of it (on five saturating drives of the benchmark
the miss in the next period was 1–3 % of that in the first, RMS). To first order it is proportional
to the change. Where the supply limits the current's slew it falls short of that by a
share that grows with the change (a slew at ``V/L`` up to ``kp·Δr`` loses
``½·(kp·Δr)²·L/V`` of it), and the voltage left for the slew is the supply less the
back-EMF, ``V − Kt·ω``. So the current over period ``n`` gains (A)::

    g₁·Δr[n] + g₂·Δr[n]·|Δr[n]| + g₃·Δr[n]²·ω[n]

with ``Δr[n]`` the target's change at the start of period ``n`` and ``ω[n]`` the speed
there (:func:`basis`). The gains are a property of the drive, but what the samples miss
of a kick depends on how they are read (the input weight, a delay of the current): so
the columns ``kick0``, ``kick1``, ``kick2`` are fitted with every model's others
(:class:`stand.diagnosis.model.ModelSpec` ``kicks``), and whether a run's models carry
them is picked with the input weight, by simulating TRAIN
(:func:`stand.diagnosis.input_weight.pick`). Kicks spread over the following periods as
well would mimic a current read late: a delay, which the vocabulary names.
"""

from __future__ import annotations

import numpy as np

#: Most share of the periods that may start with a change of the target for the kicks
#: to be fitted: a target that changes at almost every sample (a sine) makes the kick
#: columns a smooth function of the motion, which on a run of one frequency trades
#: with ``Kt/J`` and ``D/J`` like a delay does, and their fit would not carry to
#: another run.
MAX_CHANGE_SHARE = 0.5
#: Columns of :func:`basis`.
COLUMNS = 3
#: Its first columns, those of the target's change alone (without the speed).
TARGET_COLUMNS = 2


def resolvable(change: np.ndarray) -> bool:
    """Whether the kicks of a target changing by ``change`` (per period, rad/s) can be
    told from the motion: it changes, and it holds over most periods."""
    changed = np.count_nonzero(change)
    return bool(0 < changed <= MAX_CHANGE_SHARE * len(change))


def basis(change: np.ndarray, omega: np.ndarray) -> np.ndarray:
    """The kick columns over each period, shape (samples, :data:`COLUMNS`): the target's
    change at the start of the period (rad/s), its signed square ((rad/s)²), and its
    square times the speed ``omega`` there ((rad/s)³)."""
    return np.column_stack([change, change * np.abs(change), change * change * omega])


__all__ = ["COLUMNS", "MAX_CHANGE_SHARE", "TARGET_COLUMNS", "basis", "resolvable"]
