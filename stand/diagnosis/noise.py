"""What noise alone explains of a holdout gap: the floor below which a gap is ``none``
and above which what the verdict's effects leave is ``unexplained`` (CONTRACT §3)."""

from __future__ import annotations

import math

import numpy as np

from stand.diagnosis.model import FittedModel
from stand.diagnosis.signals import Signals
from stand.ident.noise import MAD_TO_SIGMA

#: A gap that remains above this many times the gap noise explains
#: (:func:`noise_gap_percent`) is ``unexplained``. The noise gap is an estimate of an RMS
#: (quantization and current noise through the free run), uncertain by a factor of
#: about 1.5 from run to run; calibrated on in-vocabulary benchmark cases
#: (docs/results/diagnose.md) so that their remaining gaps stay below it.
UNEXPLAINED_FACTOR = 3.0


def noise_floor(sig: Signals, scale: float) -> float:
    """Gap from encoder quantization alone: central-difference noise over the speed RMS."""
    noise = sig.quant_rad / (np.sqrt(24.0) * sig.dt_s)
    return 100.0 * float(noise) / scale


def noise_gap_percent(sig: Signals, scale: float, horizon: int, model: FittedModel) -> float:
    """The holdout gap that sensor noise alone gives, %: quantization of the measured
    speed (:func:`noise_floor`) and current noise carried through the free run.

    White current noise of standard deviation ``σ_i`` drives the simulated speed as a
    random walk, ``Kt/J·Δt·σ_i·√k`` after ``k`` samples; over a segment of ``H``
    samples its mean square is about ``(Kt/J·Δt·σ_i)²·H/2``. ``σ_i`` is read off the
    second difference of the current (``6σ²`` for white noise), by its median absolute
    deviation, which the steps of a command or the motion of a loop barely move.
    """
    quant = noise_floor(sig, scale)
    second = np.diff(sig.current, 2)
    mad = float(np.median(np.abs(second - np.median(second))))
    sigma_i = MAD_TO_SIGMA * mad / math.sqrt(6.0)
    walk = abs(model.coef["current"]) * sig.dt_s * sigma_i * math.sqrt(horizon / 2)
    return math.hypot(quant, 100.0 * walk / scale)
