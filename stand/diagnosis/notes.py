"""What the runs cannot resolve, in words: the notes of a diagnosis.

A run that turns one way only, or whose current is one frequency, cannot tell some
effects apart; a model whose regressors are linearly dependent on a run is not
determined there. The diagnosis answers anyway and says so here, with the experiment
that would resolve it.
"""

from __future__ import annotations

import numpy as np

from stand import effects
from stand.diagnosis.signals import Signals
from stand.effects.coulomb_friction import (
    MAX_LEVEL_SLOPE_FACTOR,
    CoulombFriction,
    level_slope_factor,
)
from stand.effects.current_offset import CurrentOffset
from stand.effects.stribeck_friction import StribeckFriction

#: Share of moving samples below which a direction of rotation counts as absent.
ONE_DIRECTION_SHARE = 0.01
#: Share of the current's power (mean removed, Hann window) within
#: ``SINGLE_TONE_BINS`` bins of its strongest frequency above which TRAIN counts as
#: exciting one frequency only.
SINGLE_TONE_SHARE = 0.9
SINGLE_TONE_BINS = 3


def limits(train: Signals, tone_hz: float | None) -> list[str]:
    """Limits of what TRAIN can resolve, in words (``tone_hz``: TRAIN's current
    frequency when it is one frequency, else None)."""
    notes = []
    moving = train.omega_f[np.abs(train.omega_f) > 0]
    if moving.size and min(np.mean(moving > 0), np.mean(moving < 0)) < ONE_DIRECTION_SHARE:
        notes.append(f"the shaft turns one way only on TRAIN: {CoulombFriction.name} and "
                     f"{CurrentOffset.name} are the same constant torque there and cannot be "
                     "told apart (record a run that reverses)")
    factor = level_slope_factor(train.omega_f)
    if factor > MAX_LEVEL_SLOPE_FACTOR:
        notes.append(f"the speed on TRAIN holds nearly one magnitude (median |ω| "
                     f"{np.median(np.abs(train.omega_f)):.3g} rad/s): a friction torque that "
                     f"does not grow with the speed ({CoulombFriction.name}, "
                     f"{StribeckFriction.name}) and the viscous slope D/J are nearly one "
                     f"column there (the variance of their split is {factor:.0f} times "
                     "what two orthogonal columns give), so a friction may go unnamed or "
                     "its level and D/J come out far off (record a run at "
                     "several speeds, e.g. a staircase or a ramp of the speed target)")
    if tone_hz is not None:
        notes.append(f"the current on TRAIN is one frequency ({tone_hz:.3g} Hz): a delay of the "
                     "current cannot be told from Kt/J and D/J there, so it is picked across "
                     "TRAIN and HOLDOUT (fitted on one, simulated on the other) and is "
                     "diagnosable only if HOLDOUT runs at another frequency (better: record "
                     "a run with a broadband command, e.g. PRBS)")
    return notes


def aliases(aliased: dict[str, tuple[str, ...]]) -> list[str]:
    """In words, the effects the runs could not tell apart (the diagnosis' bench records them) and
    the experiment that would."""
    notes = []
    for name, others in aliased.items():
        ways = dict.fromkeys(effects.get(n).separated_by for n in (*others, name))
        pair = f"{name} and {' + '.join(others)}" if others else name
        notes.append(f"{pair} cannot be told apart on these runs (the model with "
                     f"{'both' if others else 'it'} is not determined: its regressors are "
                     f"linearly dependent), so {name} is left out; record a run with "
                     f"{' or '.join(ways)} to separate them")
    return notes


def single_tone_hz(train: Signals) -> float | None:
    """The frequency of TRAIN's current, Hz, when nearly all its power is at one
    frequency (``SINGLE_TONE_SHARE``); else None."""
    current = train.current - np.mean(train.current)
    power = np.abs(np.fft.rfft(current * np.hanning(len(current)))) ** 2
    power[0] = 0.0
    total = float(np.sum(power))
    if total == 0.0:
        return None
    peak = int(np.argmax(power))
    near = float(np.sum(power[max(peak - SINGLE_TONE_BINS, 0):peak + SINGLE_TONE_BINS + 1]))
    if near < SINGLE_TONE_SHARE * total:
        return None
    return peak / (len(current) * train.dt_s)


__all__ = ["aliases", "limits", "single_tone_hz"]
