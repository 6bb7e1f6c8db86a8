"""What an identified model says about its effects, and what the data cannot support.

:func:`effect_params` turns the coefficients of the effect columns into each effect's
physical parameters. :func:`run_warnings` names what in a run limits the answer: a
sampling period too long for the motion, a low fit, weak excitation, a shaft that never
reverses or whose speed holds one magnitude; :func:`rest_warning`, a shaft that rests
over much of the run. Warnings are plain sentences; the command line prints them on
stderr.
"""

from __future__ import annotations

import numpy as np

from stand import effects as effect_registry
from stand.diagnosis.model import ModelSpec
from stand.ident.columns import Design
from stand.ident.estimate import Estimate
from stand.ident.noise import noise_sigma
from stand.runfile import Run

#: Least correlation between consecutive samples of the current's signal (its noise
#: removed): below it the current changes within a sample period by so much that the
#: timing of the current between samples decides the answer.
MIN_SAMPLE_CORRELATION = 0.8
#: Largest ``Δt·D/J``: a longer period samples the mechanical time constant J/D too coarsely.
MAX_PERIOD_OVER_TAU = 0.1
#: Fit below which the model leaves most of the acceleration unexplained, %.
LOW_FIT_PERCENT = 50.0
#: Relative standard error of Kt/J above which the excitation counts as weak.
WEAK_RELATIVE_SE = 0.05
#: Condition number above which the columns are nearly dependent.
HIGH_CONDITION = 1e4
#: Share of the fit's rows left out where the shaft rests (:func:`rest_warning`) above
#: which the run is named as one that mostly sticks.
MAX_REST_SHARE = 0.25


def effect_params(spec: ModelSpec, effects: list[str], est: Estimate) -> dict[str, dict[str, float]]:
    """Parameters of each effect of the model, from its coefficients.

    Torques are given as currents ``T/Kt`` (A), which the model determines without J.
    """
    return {name: effect_registry.get(name).ident_params(spec, est.value) for name in effects}


def sample_correlation(current: np.ndarray) -> float:
    """Correlation of consecutive samples of the current's signal, its white noise removed."""
    i = np.asarray(current, dtype=float) - float(np.mean(current))
    signal_var = float(np.var(i)) - noise_sigma(current) ** 2
    if not signal_var > 0:
        return 1.0
    return float(np.mean(i[1:] * i[:-1]) / signal_var)


def rest_warning(design: Design) -> list[str]:
    """A sentence when the shaft rests over much of the run: the rows whose kernel meets
    a stretch at rest are left out of the fit (:attr:`Design.moving`), since static
    friction holds any torque up to its breakaway level there."""
    share = 1.0 - float(np.mean(design.moving))
    if share <= MAX_REST_SHARE:
        return []
    return [f"the shaft rests (static friction holds it, or it turns slower than the encoder "
            f"resolves) within the kernel of {100 * share:.0f} % of the fit's samples, which "
            "are left out: the friction torque is unknown there; a command that keeps the "
            "shaft moving (faster reversals, a speed loop that breaks away sooner) gives "
            "more data"]


def run_warnings(run: Run, est: Estimate, notes: list[str]) -> list[str]:
    """Sentences naming what in ``run`` limits the identified model ``est``."""
    out: list[str] = []
    dt = run.dt_s
    rho = sample_correlation(run["current_A"])
    d_over_j = -est.value("omega")
    if rho < MIN_SAMPLE_CORRELATION:
        out.append(
            f"sampling too coarse: the current changes within one {dt * 1e3:.3g} ms period "
            f"(consecutive samples correlate {rho:.2f}, under {MIN_SAMPLE_CORRELATION}); "
            "Kt/J depends on how the current runs between samples; sample faster")
    if d_over_j > 0 and dt * d_over_j > MAX_PERIOD_OVER_TAU:
        out.append(
            f"sampling too coarse for the mechanical time constant J/D = {1 / d_over_j:.3g} s "
            f"(period {dt:.3g} s, over {MAX_PERIOD_OVER_TAU:.0%} of it); sample faster")
    if est.fit_percent < LOW_FIT_PERCENT:
        out.append(f"low fit: {est.fit_percent:.1f} % of the acceleration explained (under "
                   f"{LOW_FIT_PERCENT:.0f} %): noise or an effect outside the model dominates")
    b, se = est.value("current"), float(est.se[est.names.index("current")])
    if se > WEAK_RELATIVE_SE * abs(b):
        out.append(f"weak excitation: Kt/J is known to ±{100 * se / abs(b):.1f} % (standard "
                   "error); larger or faster command changes or a longer run narrow it")
    if est.condition_number > HIGH_CONDITION:
        out.append(f"weak excitation: the model's columns are nearly dependent (condition "
                   f"number {est.condition_number:.3g}); vary speed and direction more")
    if "one_speed" in notes:
        out.append("the speed holds nearly one magnitude: a friction level (Coulomb or "
                   "Stribeck friction) and the viscous slope D/J are nearly the same column "
                   "here, so their split, D/J and the friction level are poorly determined; "
                   "run the speed through several levels to tell them apart")
    if "never_reverses" in notes:
        out.append("the shaft never reverses: Coulomb friction and a current offset are the "
                   "same constant torque here and cannot be separated; reported as "
                   "coulomb_friction; reverse the shaft to tell them apart")
    return out
