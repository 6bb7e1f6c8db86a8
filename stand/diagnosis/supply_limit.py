"""The current between samples where the drive's voltage sits at its supply, as part of
the input reconstruction.

Where the drive follows its command, its current loop brings the current to the
command within a small part of the period, and ``(1 − w)·i[n] + w·i[n + 1]`` with one
weight ``w`` near 1 is the current over the period (``ModelSpec.input_weight``). Where
the voltage the loop needs exceeds the supply, the current follows the armature instead
(``L·i' = ±V − R·i − Kt·ω``): near the motor's top speed it falls as the back-EMF
rises, and it slews, rather than steps, to a new command. Its shape over the period is
then another one, and a model driven by the one weight misses part of the current at
every such period: a gap on a stand without any effect.

A run that records the drive's voltage (``voltage_V``) shows where this happens: the
voltage sits at one extreme, the supply, the same on every such sample
(:func:`at_supply`). What the one weight misses there is, to first order, a share of
the current's change over the period, and which share depends on where in the period
the supply limits it: all through (the current follows the motion, a trapezoid), from
its start only (it slews, then holds), or towards its end only (it holds the command
until the back-EMF takes it). On four benchmark drives at their supply these three
shares were −0.2 to −0.4, 0 and −0.5 to −0.6 of the change, and fitting them took
65-88 % of the one weight's miss (RMS). So the current over period ``n`` gains (A)::

    s_both·Δi[n]·B[n] + s_end·Δi[n]·E[n] + s_start·Δi[n]·S[n]

with ``Δi[n] = i[n + 1] − i[n]`` and ``B``, ``E``, ``S`` the periods whose both ends,
end only or start only find the voltage at the supply (:func:`basis`). The shares are
the drive's and the motor's, unknown here: the columns ``supply_both``, ``supply_end``
and ``supply_start`` are fitted with every model's others (``ModelSpec.supply``: the
classes with at least :data:`MIN_PERIODS` periods on TRAIN, :func:`classes`), and
whether a run's models carry them is picked with the input weight, by simulating TRAIN
(:func:`stand.diagnosis.input_weight.pick`), as a speed loop's kicks are
(:mod:`.kicks`). No supply, resistance or torque constant is needed.

Only where the drive follows a current (torque) command: under a speed loop the
current over a period is the loop's response to the speed, not a step to a command,
and a share of the samples' change does not describe it (offered there on the
benchmark, the shares fitted on TRAIN doubled one speed-mode run's HOLDOUT gap and grew
another's 13-fold); the loop's kicks are that input's reconstruction there.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from stand.diagnosis.signals import Signals
from stand.ident.noise import second_difference_sigma
from stand.runfile import Run

#: The periods' classes, by where the voltage is at the supply: at both ends, at the end
#: only, at the start only (:func:`basis`).
CLASSES: tuple[str, ...] = ("both", "end", "start")
#: Fewest periods of a class (with a change of the current) for its share to be fitted:
#: a share fitted on a handful of periods takes their noise, and carries it to HOLDOUT.
MIN_PERIODS = 20
#: Fewest samples at the supply for it to count: a single sample at the run's largest
#: voltage is a peak, not a limit the drive keeps running into.
MIN_SAMPLES = 3
#: Most share of the samples at the supply for the columns to be fitted on a run
#: (:func:`classes`): where the drive is at its supply almost always (or the voltage is
#: a held command, as in voltage mode), the columns are the input weight's own and say
#: nothing new. A run they are carried to (HOLDOUT) has them wherever its voltage is.
MAX_SHARE = 0.5
#: A sample is at the supply when its voltage's magnitude is within three standard
#: deviations of the voltage's noise of the level near the run's largest (this share of
#: it where the voltage has no noise: rounding).
TOLERANCE_SHARE = 1e-6
#: A supply is a level the voltage sits at, not a peak it passes through: the band of the
#: tolerance below the level holds at least this many times as many samples as the band
#: as wide below it. Near a smooth
#: peak of a noisy voltage the two hold about 2.4 : 1 (the density of a sine's values
#: at its peak); at a supply most of the samples near the top sit at it.
MIN_LEVEL_RATIO = 4.0


def at_supply(voltage: np.ndarray) -> np.ndarray | None:
    """Where the drive's voltage ``voltage`` (V, one per sample) sits at its supply: the
    samples within the tolerance of the level at the top of its magnitude (the median
    of the samples within twice the tolerance of the largest), both signs
    (:data:`TOLERANCE_SHARE`; the voltage's noise is read off its second difference);
    None where fewer than :data:`MIN_SAMPLES` of them do, where they are not a level
    (:data:`MIN_LEVEL_RATIO`), or the voltage is never nonzero."""
    magnitude = np.abs(np.asarray(voltage, dtype=float))
    top = float(np.max(magnitude)) if magnitude.size else 0.0
    if not np.isfinite(top) or top <= 0.0:
        return None
    tolerance = max(TOLERANCE_SHARE * top, 3.0 * second_difference_sigma(magnitude))
    # the level: the median of the samples near the top (the largest sample of a noisy
    # reading lies its noise above the level)
    level = float(np.median(magnitude[magnitude >= top - 2.0 * tolerance]))
    flagged = magnitude >= level - tolerance
    count = int(np.count_nonzero(flagged))
    below = int(np.count_nonzero((magnitude >= level - 2.0 * tolerance) & ~flagged))
    if count < MIN_SAMPLES or count < MIN_LEVEL_RATIO * below:
        return None
    return flagged


def marked(run: Run, sig: Signals) -> Signals:
    """``sig`` (prepared from ``run``) with the samples at the drive's supply
    (:func:`at_supply` of the run's ``voltage_V``; ``sig`` unchanged without one)."""
    if "voltage_V" not in run:
        return sig
    return replace(sig, at_supply=at_supply(np.asarray(run["voltage_V"], dtype=float)))


def _masks(flagged: np.ndarray) -> dict[str, np.ndarray]:
    """Each class's periods (bool, one per sample: the period after it)."""
    start = flagged
    end = np.append(flagged[1:], False)
    return {"both": start & end, "end": end & ~start, "start": start & ~end}


def classes(current: np.ndarray, flagged: np.ndarray) -> tuple[str, ...]:
    """The classes of :data:`CLASSES` with at least :data:`MIN_PERIODS` periods over
    which the current ``current`` changes (``flagged``: :func:`at_supply`); none where
    more than :data:`MAX_SHARE` of the samples are at the supply."""
    if np.count_nonzero(flagged) > MAX_SHARE * len(flagged):
        return ()
    changed = np.append(np.diff(current) != 0, False)
    return tuple(name for name, mask in _masks(flagged).items()
                 if np.count_nonzero(mask & changed) >= MIN_PERIODS)


def basis(current: np.ndarray, flagged: np.ndarray | None,
          names: tuple[str, ...]) -> np.ndarray:
    """The supply columns of classes ``names`` over each period, shape (samples,
    classes): the current's change over the period (A) where the class holds
    (``flagged``: :func:`at_supply`, one per sample; None: nowhere), 0 elsewhere and
    over the last period."""
    change = np.append(np.diff(current), 0.0)
    if flagged is None:
        return np.zeros((len(change), len(names)))
    masks = _masks(flagged)
    return np.column_stack([change * masks[name] for name in names])


__all__ = ["CLASSES", "MAX_SHARE", "MIN_LEVEL_RATIO", "MIN_PERIODS", "MIN_SAMPLES",
           "TOLERANCE_SHARE", "at_supply", "basis", "classes", "marked"]
