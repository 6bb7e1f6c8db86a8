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

What the two runs tell of the drive is pooled (:func:`_pooled`): where the law holds on
both with one integrator constant each, the drive's gains, lag and current samples'
delay are fitted to both at once, and where no one set explains both, neither run's law
is used; else a current limit one run's samples show clips the other's kicks too, and both
take the precision-weighted mean of the lags between the law's command and the drive's
current their fits give. The law's current
also carries its shape within each period (``Signals.current_shape``: a kick's current
comes early in its period and moves the angle more than its mean says), which the free
run puts into the angle (:mod:`.simulate`), and the lag's change of current and shape
(``Signals.lag_slopes``), with which the models may refine the lag
(``ModelSpec.lag``).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from stand.diagnosis.signals import Signals
from stand.ident.speed_loop import (
    TARGET_COLUMN,
    SpeedLoop,
    joint_speed_loops,
    lag_slopes,
    speed_loop,
    tracking_errors,
    within_limit,
)
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
    lag_sd_s : float
        Standard error of the drive's lag in the law's current, s (infinite where none).
    delay : int
        Samples the current samples lag the encoder, as the law's fit finds them (0
        where the law does not hold).
    """

    signals: Signals
    sampled: Signals
    from_law: bool
    note: str = ""
    lag_sd_s: float = np.inf
    delay: int = 0


def loop_input(run: Run, sig: Signals, loop: SpeedLoop | None = None) -> LoopInput:
    """``sig`` (prepared from ``run``) driven by the speed loop's current where ``run``
    holds its speed target and the PI law holds; else the sampled current, with the
    target's changes (``target_change``, whose kicks the models may carry:
    :mod:`.kicks`) where the run holds its target, ``sig`` unchanged where not.
    ``loop`` is the run's fitted loop (:func:`~stand.ident.speed_loop.speed_loop`,
    fitted here if not given)."""
    if loop is None:
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
    note = (f"{run.source}: kp {loop.kp:.3g} A·s/rad, ki {loop.ki:.3g} A/rad"
            + (f" (the drive's gains and lag fitted to {loop.runs} runs at once)"
               if loop.runs > 1 else "")
            + f", the law explaining the sampled current to {loop.residual_ratio:.2g} times "
            "its noise"
            + (f", clipped at the current limit of {loop.limit_A:.3g} A" if loop.saturates
               else "")
            + (f", its integrator fitted anew after each of {loop.resets} stretches at the "
               "current limit (the drive's anti-windup)" if loop.resets else ""))
    shape = _late(loop.period_shape, loop.delay)
    slopes = np.stack([_late(row, loop.delay) for row in lag_slopes(loop.command)])
    return LoopInput(replace(sig, current=current, loop_parts=parts, current_shape=shape,
                             lag_slopes=slopes, kick_scale_sd=loop.kp_rel_sd,
                             law_offset_sd_A=loop.offset_sd_A, cache={}),
                     sig, True, note, loop.lag_sd, loop.delay)


def _late(values: np.ndarray, delay: int) -> np.ndarray:
    """``values[n − delay]`` (the first value repeated before the start)."""
    return np.concatenate([np.repeat(values[:1], delay), values[:len(values) - delay]])


def loop_inputs(train: Run, holdout: Run, tr: Signals, ho: Signals,
                limit_A: float = np.inf) -> tuple[LoopInput, LoopInput]:
    """:func:`loop_input` of TRAIN and HOLDOUT, the law's current on both or on neither
    (a model identified on one input and simulated on the other would carry their
    difference as a gap); the notes say which and why. ``limit_A``: the drive's current
    limit where known (A), which clips the law where neither run's samples show one."""
    if (TARGET_COLUMN in train) != (TARGET_COLUMN in holdout):
        # a target in one run only: neither the law's current nor the kicks on either
        return (LoopInput(tr, tr, False, "the speed target is recorded in one run only: "
                          "both are driven by the sampled current"),
                LoopInput(ho, ho, False))
    first, second = (loop_input(run, sig, loop) for run, sig, loop
                     in zip((train, holdout), (tr, ho), _pooled(train, holdout, limit_A),
                            strict=True))
    if first.from_law == second.from_law:
        return first, second
    refused = first.note if not first.from_law else second.note
    return (LoopInput(first.sampled, first.sampled, False, refused),
            LoopInput(second.sampled, second.sampled, False,
                      "the PI speed law holds on one run only: both are driven by the "
                      "sampled current"))


def _pooled(train: Run, holdout: Run, limit_A: float = np.inf
            ) -> tuple[SpeedLoop | None, SpeedLoop | None]:
    """The two runs' speed loops with what they tell of the drive pooled where both hold.

    Where the law with one integrator constant holds on both, the gains, the lag and the
    current samples' delay are fitted to both runs at once
    (:func:`~stand.ident.speed_loop.joint_speed_loops`: each run's own fit errs its own
    way with a coarse encoder, and a model identified on TRAIN's law current carried the
    difference into HOLDOUT at every kick). Where no one set of them explains both runs,
    the runs disagree on the drive, and neither run's law drives the models. Else (a
    run's integrator fitted anew after each stretch at the current limit):

    * A current limit one run's samples show is the other's too, where the other's
      samples stay within it: there it clips kicks that reach it within a period and
      have left it by the next sample.
    * Each takes the mean of the drive's lags both fits give, weighted by their
      precision: one run's fit of it can be off by tens of percent (a run of small
      kicks), and on a kick of a few amperes a percent of the lag is a
      milliampere-second.
    """
    runs = (train, holdout)
    first, second = (speed_loop(run, limit_A) for run in runs)
    if first is None or second is None or not (first.holds and second.holds):
        return first, second
    joint = joint_speed_loops([first, second], limit_A)
    if joint is not None:
        return joint[0], joint[1]
    if not (first.resets or second.resets):
        # each run's law holds with one constant, but no one set of the drive's gains
        # and delay explains both: one fit is wrong (a run at its current limit much of
        # the time fits kp a tenth of the drive's and still passes), or the drive
        # changed; a model identified on one run's law current misplaces the other's
        message = (f"the PI speed law's fits of the two runs disagree on the drive (kp "
                   f"{first.kp:.3g} and {second.kp:.3g} A·s/rad, the current samples "
                   f"late by {first.delay} and {second.delay} samples), and no one set of "
                   "its gains explains both runs")
        refused = [replace(loop, period_current=np.empty(0), message=message)
                   for loop in (first, second)]
        return refused[0], refused[1]
    loops = [first, second]
    limits = [loop.limit_A for loop in loops]
    if np.isfinite(min(limits)) and not np.isfinite(max(limits)):
        for k, run in enumerate(runs):
            if np.isinf(loops[k].limit_A) and within_limit(run["current_A"], min(limits)):
                refit = speed_loop(run, min(limits))
                assert refit is not None  # the run holds its target
                loops[k] = refit
    fitted = [loop for loop in loops if loop.holds and loop.lag_s > 0 and loop.lag_sd > 0]
    if len(fitted) < len(loops):
        return loops[0], loops[1]
    weights = np.array([loop.lag_sd ** -2.0 for loop in fitted])
    lag = float(np.sum(weights * [loop.lag_s for loop in fitted]) / np.sum(weights))
    sd = float(np.sum(weights) ** -0.5)
    return loops[0].relagged(lag, train.dt_s, sd), loops[1].relagged(lag, holdout.dt_s, sd)


__all__ = ["LoopInput", "loop_input", "loop_inputs"]
