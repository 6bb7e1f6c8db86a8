"""The noise gap by replay: the run's own sensors through the nominal model.

:func:`stand.diagnosis.noise.noise_gap_percent` estimates what noise alone leaves of a
holdout gap from two formulas (the quantized speed, the current noise's random walk).
Both miss what the diagnosis' own pipeline does to noise: the re-anchoring of each
segment to quantized positions adds to the quantization's share, the nominal model's
damping and the anchoring's shot take from the walk's. On 268 effect-free benchmark runs
under a current loop (stored rows of seeds 297-319) the nominal gap was 0.73 times the
formula's where the walk dominates it and 1.32 times where the quantization does: the
formula is right only to within a factor of about 1.4 either way, and a ``none`` has to
allow ``UNEXPLAINED_FACTOR`` times it.

The replay measures the same quantity on the run itself: the nominal model's own motion,
driven by the input it integrates over each period on HOLDOUT, read through the run's
encoder (its count, at a random phase) and a current sensor of the noise the run's
current has (:func:`stand.ident.noise.second_difference_sigma`), then anchored, simulated
and compared exactly as the diagnosis compares HOLDOUT. On those 268 runs (a first
version of the replay, run beside the diagnosis) the nominal gap is 0.98 times the
replayed one at the median, 1.16 at the 99th percentile, 1.32 at most; in the diagnosis,
on the 121 of them whose gap lies between the noise gap and 2.5 times it (where it
replays), 1.00, 1.22 and 1.24. Three replays differ by about 3 %
(docs/results/diagnose.md).

It replays the runs whose models the current alone drives (with a current offset at
most). Under a speed loop that holds its target, the loop's current between samples
moves the stand, and that no replay of the samples holds, unless the target is one tone
on both runs: the loop's current is then a smooth tone too, whose mean over each period
is what moves the stand. On the stored effect-free runs under a speed sine whose gap lies
in the band the nominal gap is at most 1.30 times the replayed one (44 runs), under
speed PRBS and noise targets up to 1.72 (23); the factor under a speed loop is
:data:`~stand.diagnosis.noise.SPEED_LOOP_REPLAY_FACTOR`.
"""

from __future__ import annotations

import math

import numpy as np

from stand.diagnosis.model import FittedModel, period_current
from stand.diagnosis.noise import REPLAY_FACTOR, SPEED_LOOP_REPLAY_FACTOR, Replayed
from stand.diagnosis.notes import single_tone_hz
from stand.diagnosis.scoring import Bench
from stand.diagnosis.signals import Signals, prepare
from stand.diagnosis.simulate import phi1
from stand.ident.noise import second_difference_sigma
from stand.runfile import Run

#: Replays averaged (in mean square): each differs from the others by about 3 %.
REPLAYS = 3
#: The columns a replayed model may have: the current and a constant (an offset).
REPLAYED_COLUMNS = frozenset({"current", "one"})
#: A replayed motion faster than this many times the run's fastest is not the run's
#: regime (an unstable nominal model run freely): no replay.
MAX_SPEED_RATIO = 10.0


def replayed_noise_gap(bench: Bench, model: FittedModel, sampled: Signals,
                       speed_loop: bool) -> Replayed | None:
    """The holdout gap (%, of HOLDOUT's speed scale) that sensor noise leaves the
    nominal ``model`` on replays of HOLDOUT (see the module docstring), with the factor
    beyond which a nominal gap is more than noise there; ``sampled``: HOLDOUT with the
    current whose noise the noise gap counts. None where the run holds a speed target
    (``speed_loop``) that is not one tone on both runs, or its current's shape within
    each period, the model has columns beyond the current and an offset or a spring,
    or its free motion leaves the run's regime."""
    names = set(model.spec.names())
    if not names <= REPLAYED_COLUMNS or model.c_theta != 0.0:
        return None
    if speed_loop and (bench.tone_hz is None or single_tone_hz(bench.holdout) is None):
        return None
    ho = bench.holdout
    if ho.current_shape is not None:
        return None
    # what the free run integrates over the period after each sample
    drive = model.coef["current"] * period_current(model, ho) + model.coef.get("one", 0.0)
    omega, theta = _free_run(model.c_omega, np.asarray(drive, dtype=float), ho.dt_s,
                             float(ho.omega_f[0]), float(ho.theta_f[0]))
    if not np.all(np.isfinite(omega)) or (
            np.max(np.abs(omega)) > MAX_SPEED_RATIO * np.max(np.abs(ho.omega_f))):
        return None
    sigma = second_difference_sigma(sampled.current)
    time = np.arange(len(ho)) * ho.dt_s
    squares = []
    for replay in range(REPLAYS):
        rng = np.random.default_rng(replay)
        position = theta
        if ho.quant_rad > 0:
            phase = rng.uniform(0.0, ho.quant_rad)
            position = np.floor((theta + phase) / ho.quant_rad) * ho.quant_rad
        current = ho.current + sigma * rng.standard_normal(len(ho))
        signals = prepare(Run(columns={"time_s": time, "position_rad": position,
                                       "current_A": current}, source="<replay>"))
        replayed = Bench(signals, signals, bench.horizon_s)
        rms = replayed.score_model(model).gap * replayed.scale
        squares.append(rms * rms)
    return Replayed(math.sqrt(float(np.mean(squares))) / bench.scale,
                    SPEED_LOOP_REPLAY_FACTOR if speed_loop else REPLAY_FACTOR)


def _free_run(c_omega: float, drive: np.ndarray, dt_s: float, omega0: float,
              theta0: float) -> tuple[np.ndarray, np.ndarray]:
    """Speed (rad/s) and position (rad) at each sample of ``ω' = c_omega·ω + drive``,
    the drive held over the period after each sample (exact over each period)."""
    x = c_omega * dt_s
    # (e^x − 1)/c (the simulation's exact step) and ((e^x − 1)/c − Δt)/c, by its series
    # near x = 0
    gain = dt_s * phi1(x)
    lift = (dt_s * dt_s * ((math.expm1(x) - x) / (x * x)) if abs(x) > 1e-4
            else dt_s * dt_s * (0.5 + x / 6))
    decay = math.exp(x)
    # ω[k+1] = decay·ω[k] + gain·drive[k];  θ[k+1] = θ[k] + gain·ω[k] + lift·drive[k]
    # (a loop: a run's samples cost a few ms, and the diagnosis stays off scipy.signal)
    omega = np.empty(len(drive))
    w = omega0
    for k, d in enumerate(drive.tolist()):
        omega[k] = w
        w = decay * w + gain * d
    theta = theta0 + np.concatenate([[0.0], np.cumsum(gain * omega + lift * drive)[:-1]])
    return omega, theta


__all__ = ["MAX_SPEED_RATIO", "REPLAYED_COLUMNS", "REPLAYS", "replayed_noise_gap"]
