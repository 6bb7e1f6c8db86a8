"""Reducer efficiency from a two-motor run: seed 000 eq. 18.

With the input motor held at a constant speed and the output motor applying load steps,
each step changes the steady currents by ``Δi_in`` and ``Δi_out``, and::

    η = K_out·|Δi_out| / (n·K_in·|Δi_in|)

The steps are found in the output current without being told where they are: a
step detector (the difference of the means of the ``w`` samples after and before each
sample) is compared with the noise of the output current (from its sample-to-sample
differences); peaks beyond ``STEP_THRESHOLD_SIGMA`` standard deviations of the detector's
noise are steps. The steady level on either side of a step is the mean over the settled
part of the plateau (all but its first ``SETTLE_FRACTION``), so the speed loop's
transient after a step does not enter. Each step gives one η; the result is their mean.
Its uncertainty is the larger of (a) the standard errors of the plateau means propagated
through eq. 18 to first order (adjacent steps share a plateau, so their errors correlate)
and (b) the standard error of the mean over the steps (which also sees slow drifts).
``efficiency_ci95`` is the mean ± Student's t with steps − 1 degrees of freedom times it
when (b) dominates, the normal quantile when (a) does (it rests on thousands of samples).

Friction on each shaft: eq. 18 holds because Coulomb and viscous friction are the same
on both plateaus of a step at one speed, and cancel in ``Δi``. Where the input shaft
turns the other way (or stands) on one side of a step, the friction of both shafts
changes sign with it and ``Δi`` holds twice its torque: such steps are left out, and a
warning says how many. So are steps where the output motor's load turns with the
output shaft (a load of one sign on an input that reverses): there the output motor
drives the reducer, power flows backwards, and the ratio of eq. 18 is the inverse of
the back-driving efficiency, which in a real reducer differs from the forward one. A
shaft turns one way on a plateau when its reading never goes back by more than an
encoder's dither (``DITHER_COUNTS`` counts of the run's own encoder step).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.stats import norm

from stand.diagnosis.signals import quantization_step
from stand.errors import InputError, NotExcitedError
from stand.ident.estimate import CONFIDENCE, t_quantile
from stand.ident.noise import noise_sigma
from stand.jsonable import JsonResult
from stand.runfile import Run

#: Samples averaged on each side by the step detector.
DETECTOR_SAMPLES = 25
#: Detector peaks beyond this many noise standard deviations are steps.
STEP_THRESHOLD_SIGMA = 12.0
#: Leading fraction of each plateau left out as the transient after a step.
SETTLE_FRACTION = 0.25
#: Fewest samples in a plateau to take its level.
MIN_PLATEAU_SAMPLES = 8
#: Fewest load steps for a spread over the steps worth reporting without a warning.
MIN_STEPS = 3
#: Encoder counts a shaft's reading may go back against its travel within a plateau: a
#: reading that flips to the neighbouring count on either side of the true one spans two
#: counts. Counts are the run's own encoder step (:func:`quantization_step`).
DITHER_COUNTS = 2


@dataclass(frozen=True)
class EfficiencyResult(JsonResult):
    """Efficiency of a reducer (CONTRACT §2 ``stand efficiency``).

    Attributes
    ----------
    efficiency : float
        η of eq. 18, mean over the load steps.
    efficiency_std : float
        Standard uncertainty of ``efficiency``: the larger of the plateau noise propagated
        through eq. 18 and the standard error of the mean over the steps.
    delta_i_in_A, delta_i_out_A : float
        Mean magnitude of the current changes at the steps, A.
    steps : int
        Load steps found.
    step_times_s : list of float
        Where the steps are, s.
    efficiency_steps : list of float
        η of each step.
    ratio, k_in, k_out : float
        Inputs: reduction ratio, torque constants of the input and output motors (N·m/A).
    source : str
        The run analysed (its file name).
    efficiency_ci95 : list of float
        95 % interval ``[low, high]`` of ``efficiency``.
    warnings : list of str
        What limits the answer (few steps, steps left out at a reversal).
    """

    efficiency: float
    efficiency_std: float
    delta_i_in_A: float
    delta_i_out_A: float
    steps: int
    step_times_s: list[float]
    efficiency_steps: list[float]
    ratio: float
    k_in: float
    k_out: float
    source: str = ""
    efficiency_ci95: list[float] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)


def find_steps(signal: np.ndarray, window: int = DETECTOR_SAMPLES) -> np.ndarray:
    """Indices of the steps of a piecewise-constant noisy signal (first sample after each)."""
    n = len(signal)
    if n < 4 * window:
        raise NotExcitedError(f"{n} samples are too few to find load steps (need {4 * window})")
    c = np.concatenate([[0.0], np.cumsum(signal)])
    k = np.arange(window, n - window + 1)
    detector = (c[k + window] - c[k]) / window - (c[k] - c[k - window]) / window
    sigma = noise_sigma(signal) * np.sqrt(2.0 / window)
    threshold = STEP_THRESHOLD_SIGMA * max(sigma, np.finfo(float).tiny)
    above = np.abs(detector) > threshold
    steps: list[int] = []
    start = None
    for idx in np.flatnonzero(np.diff(np.concatenate([[False], above, [False]]).astype(int))):
        if start is None:
            start = idx
        else:  # one run of samples above the threshold: its peak is the step
            steps.append(int(k[start + int(np.argmax(np.abs(detector[start:idx])))]))
            start = None
    return np.array(steps, dtype=int)


def _level(x: np.ndarray) -> tuple[float, float]:
    """Mean of the settled part of a plateau and its standard error."""
    settled = x[int(np.ceil(SETTLE_FRACTION * len(x))):]
    return float(np.mean(settled)), float(np.std(settled, ddof=1) / np.sqrt(len(settled)))


def efficiency(run: Run, ratio: float, k_in: float, k_out: float) -> EfficiencyResult:
    """η of eq. 18 from a two-motor run with output load steps.

    Parameters
    ----------
    run : Run
        Reducer run (``current_in_A``, ``current_out_A``, ...).
    ratio : float
        Reduction ratio n = ω_in/ω_out.
    k_in, k_out : float
        Torque constants of the input and output motors, N·m/A.

    Raises
    ------
    InputError
        Non-positive ratio or torque constant.
    NotExcitedError
        No load step in the output current, or plateaus too short.
    """
    for name, value in (("ratio", ratio), ("k_in", k_in), ("k_out", k_out)):
        if not (np.isfinite(value) and value > 0):
            raise InputError(f"{name} must be a finite number > 0, got {value}")
    i_in, i_out = run["current_in_A"], run["current_out_A"]
    steps = find_steps(i_out)
    if steps.size == 0:
        raise NotExcitedError(
            f"{run.source}: no load step in current_out_A (noise {noise_sigma(i_out):.3g} A); "
            "the efficiency run needs output load steps well above the current noise"
        )
    bounds = np.concatenate([[0], steps, [len(i_out)]])
    if np.min(np.diff(bounds)) < MIN_PLATEAU_SAMPLES:
        raise NotExcitedError(
            f"{run.source}: a load plateau is shorter than {MIN_PLATEAU_SAMPLES} samples; "
            "hold each load longer"
        )
    plateaus = [slice(bounds[j], bounds[j + 1]) for j in range(len(bounds) - 1)]
    level_in, se_in = np.array([_level(i_in[p]) for p in plateaus]).T
    level_out, se_out = np.array([_level(i_out[p]) for p in plateaus]).T
    step_in, step_out = np.diff(level_in), np.diff(level_out)
    position_in = run["position_in_rad"]
    dither_in = _dither_rad(position_in)
    direction = np.array([_direction(position_in[p], dither_in) for p in plateaus])
    same_way = (direction[:-1] == direction[1:]) & (direction[1:] != 0)
    forward = _brakes(level_out, run["position_out_rad"], plateaus)
    kept = np.flatnonzero(same_way & forward)
    warnings: list[str] = []
    if not np.all(same_way):
        warnings.append(
            f"{int(np.sum(~same_way))} of {len(step_in)} load step(s) left out: the input "
            "shaft turns the other way or stands on one side, so the friction of both shafts "
            "changes with it and does not cancel in eq. 18")
    if np.any(same_way & ~forward):
        warnings.append(
            f"{int(np.sum(same_way & ~forward))} of {len(step_in)} load step(s) left out: the "
            "output motor drives the reducer there (its torque turns with the output shaft), "
            "so power flows backwards and eq. 18 would give the inverse of the back-driving "
            "efficiency; load the output against its motion")
    if kept.size == 0:
        raise NotExcitedError(f"{run.source}: no load step with the input turning the same way "
                              "on both sides and the load opposing the motion; hold the input "
                              "speed constant across the steps and brake the output")
    if np.any(step_in[kept] == 0):
        raise NotExcitedError(f"{run.source}: the input current did not change at a load step")
    di_in, di_out = np.abs(step_in), np.abs(step_out)
    etas_all = k_out * di_out / (ratio * k_in * np.where(di_in == 0, np.inf, di_in))
    etas = etas_all[kept]
    m = len(etas)
    if m < MIN_STEPS:
        warnings.append(f"few load steps: {m}; the spread over the steps rests on "
                        f"{max(m - 1, 0)} degree(s) of freedom; apply at least {MIN_STEPS}")
    # Propagate the plateau-mean errors to the mean η exactly to first order: adjacent steps
    # share a plateau, so their errors are correlated.
    grad_in, grad_out = np.zeros(len(plateaus)), np.zeros(len(plateaus))
    for k in kept:
        d_in = -etas_all[k] / di_in[k] * np.sign(step_in[k]) / m  # ∂η̄/∂(L_in[k+1] − L_in[k])
        d_out = etas_all[k] / di_out[k] * np.sign(step_out[k]) / m
        grad_in[k + 1] += d_in
        grad_in[k] -= d_in
        grad_out[k + 1] += d_out
        grad_out[k] -= d_out
    propagated = float(np.sqrt(np.sum((grad_in * se_in) ** 2 + (grad_out * se_out) ** 2)))
    scatter = float(np.std(etas, ddof=1) / np.sqrt(m)) if m > 1 else 0.0
    std = max(propagated, scatter)
    quantile = (t_quantile(m - 1) if scatter > propagated
                else float(norm.ppf(0.5 + CONFIDENCE / 2)))
    eta = float(np.mean(etas))
    return EfficiencyResult(
        efficiency=eta, efficiency_std=std,
        delta_i_in_A=float(np.mean(di_in[kept])), delta_i_out_A=float(np.mean(di_out[kept])),
        steps=m, step_times_s=[float(run.time_s[steps[k]]) for k in kept],
        efficiency_steps=[float(e) for e in etas], ratio=ratio, k_in=k_in, k_out=k_out,
        source=run.source, efficiency_ci95=[eta - quantile * std, eta + quantile * std],
        warnings=warnings,
    )


def _brakes(level_out: np.ndarray, position_out: np.ndarray, plateaus: list[slice]
            ) -> np.ndarray:
    """For each step, whether the output motor brakes the output shaft on the step's
    loaded side (the plateau of larger output current): its current opposes the output's
    travel, so the reducer drives the load (power flows forwards, as eq. 18 assumes).
    The output's own travel decides (a reducer may reverse the direction)."""
    dither = _dither_rad(position_out)
    out_dir = np.array([_direction(position_out[p], dither) for p in plateaus])
    loaded = np.where(np.abs(level_out[1:]) >= np.abs(level_out[:-1]),
                      np.arange(1, len(level_out)), np.arange(len(level_out) - 1))
    return np.asarray(np.sign(level_out[loaded]) * out_dir[loaded] < 0)


def _direction(position: np.ndarray, dither_rad: float) -> int:
    """Sign of the travel over the settled part of a plateau: ``+1`` or ``−1`` when the
    shaft turns that way throughout it, its reading never going back by more than
    ``dither_rad`` (an encoder flipping between neighbouring counts); 0 when it stands
    (travels no more than that) or turns both ways (a plateau that holds a reversal: its
    mean current mixes the frictions of both directions)."""
    settled = position[int(np.ceil(SETTLE_FRACTION * len(position))):]
    if settled.size < 2 or abs(settled[-1] - settled[0]) <= dither_rad:
        return 0
    sign = 1 if settled[-1] > settled[0] else -1
    along = sign * settled
    went_back = float(np.max(np.maximum.accumulate(along) - along))
    return sign if went_back <= dither_rad else 0


def _dither_rad(position: np.ndarray) -> float:
    """How far, rad, a reading of ``position``'s encoder may go back: ``DITHER_COUNTS``
    counts, and half a count more, as readings on the count grid differ by whole counts
    up to their rounding (0 for a position that is not quantized)."""
    return (DITHER_COUNTS + 0.5) * quantization_step(position)
