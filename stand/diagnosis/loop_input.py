"""The diagnosis' input current under a PI speed loop: the loop law's current over each
sample period instead of the sampled current.

A drive in speed mode kicks its current by ``kp·Δr`` at each change of the speed target
and pulls it back faster than the samples follow (:mod:`stand.ident.speed_loop`). Every
model of the diagnosis is driven by the current over each period; held or interpolated
from the samples, that current misses part of each kick, and a free run of the nominal
model drifts by it at every target change: a gap beyond noise on a run with no effect,
which the vocabulary has no word for and which the shape tests
(:mod:`stand.diagnosis.structure`) see as a speed or current shape.

Where the run holds its speed target (``speed_target_rad_s``) and the PI law explains the
sampled current to within its noise, the law gives the current over each period from
the measured angle (:func:`stand.ident.speed_loop.fit_speed_loop`, the reconstruction
the identification uses). :func:`loop_input` offers it in place of the sampled current
in the run's :class:`~stand.diagnosis.signals.Signals`; where the diagnosis takes it
(:func:`stand.diagnosis.engine.diagnose`: it simulates TRAIN better than the samples'
reconstructions), the nominal model, every effect model and the shape tests all see
it. It is placed on the samples' timeline (``delay`` samples late, as the fitted law
finds the current samples), so a ``delay`` candidate shifts it back just as it shifts
the samples; it is the period's own mean, so the nominal model takes it as held over
the period (input weight 0) instead of a reconstruction of the samples. Where the law
does not hold (a loop that saturates its voltage, another control law, a target that
changes at every sample), the sampled current stays and a note says why.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from stand.diagnosis.signals import Signals
from stand.ident.speed_loop import TARGET_COLUMN, speed_loop, tracking_errors
from stand.runfile import Run


@dataclass(frozen=True)
class LoopInput:
    """A run's signals with the input current the diagnosis drives its models with.

    Attributes
    ----------
    signals : Signals
        The run's signals; ``current`` is the loop law's current over each period where
        ``from_law``, else the sampled current (A).
    sampled : Signals
        The run's signals with the sampled current.
    from_law : bool
        The current comes from the PI speed law.
    note : str
        What was done with a speed-loop run, in words ("" for a run without a target).
    """

    signals: Signals
    sampled: Signals
    from_law: bool
    note: str = ""


def loop_input(run: Run, sig: Signals) -> LoopInput:
    """``sig`` (prepared from ``run``) driven by the speed loop's current where ``run``
    holds its speed target and the PI law holds; else the sampled current, with the
    target's changes (``target_change``, whose kicks the models may carry:
    :mod:`.kicks`) where the run holds its target, ``sig`` unchanged where not."""
    loop = speed_loop(run)
    if loop is None:
        return LoopInput(sig, sig, False)
    # the sampled current with the target's changes, whose kicks the input
    # reconstruction may carry (:mod:`.kicks`)
    target = np.asarray(run[TARGET_COLUMN], dtype=float)
    sig = replace(sig, target_change=np.diff(target, prepend=target[0]), cache={})
    if not loop.holds:
        return LoopInput(sig, sig, False,
                         f"{run.source}: the speed target is recorded, but {loop.message}; "
                         "the diagnosis is driven by the sampled current, whose misses of "
                         "the loop's kicks between samples may leave a gap no effect explains")
    period = loop.period_current
    # on the samples' timeline: the current sample n + delay shows the period after n
    current = _late(period, loop.delay)
    # the law's parts over each period: kp·(r − ω̄) and ki·(∫r − θ)
    error, lag = tracking_errors(sig.theta, target, sig.dt_s)
    parts = np.column_stack([_late(loop.kp * error, loop.delay),
                             _late(loop.ki * lag, loop.delay)])
    note = (f"{run.source}: kp {loop.kp:.3g} A·s/rad, ki {loop.ki:.3g} A/rad, the law "
            f"explaining the sampled current to {loop.residual_ratio:.2g} times its noise"
            + (f", its integrator fitted anew after each of {loop.resets} stretches at the "
               "current limit (the drive's anti-windup)" if loop.resets else ""))
    return LoopInput(replace(sig, current=current, loop_parts=parts, cache={}), sig, True, note)


def _late(values: np.ndarray, delay: int) -> np.ndarray:
    """``values[n − delay]`` (the first value repeated before the start)."""
    return np.concatenate([np.repeat(values[:1], delay), values[:len(values) - delay]])


def loop_inputs(train: Run, holdout: Run, tr: Signals, ho: Signals
                ) -> tuple[LoopInput, LoopInput]:
    """:func:`loop_input` of TRAIN and HOLDOUT, the law's current on both or on neither
    (a model identified on one input and simulated on the other would carry their
    difference as a gap); the notes say which and why."""
    if (TARGET_COLUMN in train) != (TARGET_COLUMN in holdout):
        # a target in one run only: neither the law's current nor the kicks on either
        return (LoopInput(tr, tr, False, "the speed target is recorded in one run only: "
                          "both are driven by the sampled current"),
                LoopInput(ho, ho, False))
    first, second = loop_input(train, tr), loop_input(holdout, ho)
    if first.from_law == second.from_law:
        return first, second
    refused = first.note if not first.from_law else second.note
    return (LoopInput(first.sampled, first.sampled, False, refused),
            LoopInput(second.sampled, second.sampled, False,
                      "the PI speed law holds on one run only: both are driven by the "
                      "sampled current"))


__all__ = ["LoopInput", "loop_input", "loop_inputs"]
