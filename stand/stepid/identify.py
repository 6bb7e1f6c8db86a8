"""Voltage-step identification of a DC motor (seed 001): the front door.

Steps:

1. equation-error start (:mod:`stand.stepid.equation_error`): linear least squares,
   no hand-tuned starting point;
2. output-error fit of the transfer-function coefficients to the measured speed (and
   current) of every run jointly, by ``trf``, ``lm``, ``gd`` or ``pattern``
   (:mod:`stand.stepid.search`), each channel weighted by its noise level;
3. standard errors from the Jacobian and the residual variance;
4. physical parameters and their identifiability from the coefficients and the values
   the user knows (:mod:`stand.stepid.physical`);
5. fit % and a residual whiteness test (:mod:`stand.stepid.stats`).
"""

from __future__ import annotations

import math
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from stand.errors import InputError
from stand.jsonable import JsonResult
from stand.runfile import Run
from stand.stepid.equation_error import equation_error, noise_level
from stand.stepid.model import PARAM_NAMES, StepData, respond, step_data
from stand.stepid.physical import physical_estimate
from stand.stepid.search import Minimum, minimize
from stand.stepid.stats import Whiteness, fit_percent, interval, whiteness

#: Refit once with the residual levels as channel weights when they differ from the
#: first guess by more than this factor.
REWEIGHT_FACTOR = 1.2


@dataclass(frozen=True)
class StepResult(JsonResult):
    """Result of :func:`identify_steps` (CONTRACT §2 ``stand step-identify``).

    Attributes
    ----------
    transfer_function : dict
        ``{"num": [b0], "den": [1, a1, a0]}`` of ω(s)/v(s), highest power first.
    params : dict of str to float or None
        ``R`` Ω, ``L`` H, ``K`` N·m/A (= V·s/rad), ``J`` kg·m², ``Kf`` N·m·s/rad; ``None``
        where the data and the known values do not determine it. Known values come back
        as given.
    identifiable : list of str
        Parameters the data determine (known ones excluded).
    fit_percent : float
        Speed fit over all runs, ``100·(1 − ‖ω − ω̂‖/‖ω − mean ω‖)``, %.
    known : dict of str to float
        The values given by the user.
    std, interval95 : dict
        Standard error and 95 % interval of each parameter (``None`` where not
        determined; 0 and the value itself for a known one).
    transfer_function_std : dict
        Standard errors of ``num`` and ``den`` (0 for the leading 1).
    current_transfer_function : dict or None
        ``{"num": [c1, c0], "den": [1, a1, a0]}`` of i(s)/v(s) when the current was used.
    fit_percent_current : float or None
        Current fit, %, when the current was used.
    whiteness : dict of str to Whiteness
        Residual whiteness test per channel (``velocity_rad_s``, ``current_A``).
    start : dict
        The equation-error transfer function the fit started from.
    initial_voltage_V : list of float
        Per run, the voltage whose steady state the run starts in (0 for a run from rest), V.
    files : list of str
        The runs identified (their file names), in order.
    plot : str or None
        The figure written by the command line's ``--plot``, if any.
    """

    transfer_function: dict[str, list[float]]
    params: dict[str, float | None]
    identifiable: list[str]
    fit_percent: float
    known: dict[str, float]
    std: dict[str, float | None]
    interval95: dict[str, list[float] | None]
    transfer_function_std: dict[str, list[float]]
    current_transfer_function: dict[str, list[float]] | None
    fit_percent_current: float | None
    whiteness: dict[str, Whiteness]
    start: dict[str, list[float]]
    method: str
    converged: bool
    nfev: int
    elapsed_s: float
    samples: int
    runs: int
    used_current: bool
    noise_std: dict[str, float]
    hold: str
    initial_voltage_V: list[float]
    alternatives: list[dict[str, float]] = field(default_factory=list)
    message: str = ""
    files: list[str] = field(default_factory=list)
    plot: str | None = None


def _check_known(known: Mapping[str, float]) -> dict[str, float]:
    checked = {}
    for name, value in known.items():
        if name not in PARAM_NAMES:
            raise InputError(f"known: unknown parameter {name!r}; use one of {', '.join(PARAM_NAMES)}")
        value = float(value)
        if not (math.isfinite(value) and value > 0):
            raise InputError(f"known: {name} must be a finite number > 0, got {value}")
        checked[name] = value
    return checked


class _Problem:
    """Scaled parameters: ``(log b0, log a1, log a0[, log c1, c0/c0_scale])`` then, per run,
    the initial voltage over the largest voltage (the run starts in its steady state)."""

    def __init__(self, data: Sequence[StepData], start: np.ndarray, hold: str,
                 sigma: list[float]) -> None:
        self.data, self.hold, self.sigma = data, hold, sigma
        self.n = len(start)
        self.c0_scale = start[3] * start[2] / start[1] if self.n > 3 else 1.0
        self.v_scale = max(float(np.max(np.abs(run.voltage_V))) for run in data) or 1.0

    def coefs(self, theta: np.ndarray) -> np.ndarray:
        c = np.exp(theta[:self.n])
        if self.n > 3:
            c[4] = theta[4] * self.c0_scale
        return c

    def initial_voltages(self, theta: np.ndarray) -> np.ndarray:
        return theta[self.n:] * self.v_scale

    def theta(self, coefs: np.ndarray, initial_voltages: np.ndarray) -> np.ndarray:
        t = np.log(np.abs(coefs))
        if self.n > 3:
            t[4] = coefs[4] / self.c0_scale
        return np.concatenate([t, initial_voltages / self.v_scale])

    def dcoefs_dtheta(self, theta: np.ndarray) -> np.ndarray:
        d = np.exp(theta[:self.n])
        if self.n > 3:
            d[4] = self.c0_scale
        return d

    def simulate(self, theta: np.ndarray) -> list[list[np.ndarray]]:
        c = self.coefs(theta)
        return [respond(c, run, self.hold, v0)
                for run, v0 in zip(self.data, self.initial_voltages(theta), strict=True)]

    def channels(self, run: StepData) -> list[np.ndarray]:
        return [run.velocity_rad_s] + ([run.current_A] if self.n > 3 and run.current_A is not None
                                       else [])

    def residuals(self, theta: np.ndarray) -> np.ndarray:
        parts = []
        for run, outputs in zip(self.data, self.simulate(theta), strict=True):
            for ch, (model, measured) in enumerate(zip(outputs, self.channels(run), strict=True)):
                parts.append((model - measured) / self.sigma[ch])
        return np.concatenate(parts)


#: Samples averaged for the initial speed of the start.
INITIAL_SAMPLES = 5


def _initial_voltages(data: Sequence[StepData], coefs: np.ndarray) -> np.ndarray:
    """Start of each run's initial voltage: the one whose steady speed is the first speeds."""
    return np.array([float(np.mean(run.velocity_rad_s[:INITIAL_SAMPLES])) * coefs[2] / coefs[0]
                     for run in data])


def _start(data: Sequence[StepData], use_current: bool, hold: str) -> tuple[np.ndarray, str]:
    coefs = equation_error(data, use_current, hold)
    if coefs[0] < 0:
        raise InputError(
            "the speed falls as the voltage rises (negative gain): the tacho or the motor is "
            "wired reversed; flip the sign of velocity_rad_s or voltage_V"
        )
    note = ""
    bad = [name for name, value in zip(("b0", "a1", "a0", "c1"), coefs, strict=False) if value <= 0]
    if bad:
        note = f"equation-error start had non-positive {', '.join(bad)}; started from |value|. "
        coefs = coefs.copy()
        floor = 1e-6 * float(np.max(np.abs(coefs[:3])))
        coefs[:4] = np.maximum(np.abs(coefs[:4]), floor)
    return coefs, note


def _fit(problem: _Problem, theta0: np.ndarray, method: str) -> Minimum:
    return minimize(problem.residuals, theta0, method)


def identify_steps(runs: Sequence[Run], known: Mapping[str, float] | None = None,
                   method: str = "trf", hold: str = "preceding",
                   use_current: bool = True) -> StepResult:
    """Identify the seed 001 motor model from voltage-step runs (all runs jointly).

    Parameters
    ----------
    runs : sequence of Run
        Step runs: ``time_s``, ``voltage_V``, ``velocity_rad_s``, optional ``current_A``.
        The current is used when every run has it.
    known : mapping of str to float, optional
        Known parameter values (``R`` Ω, ``L`` H, ``K`` N·m/A, ``J`` kg·m², ``Kf``
        N·m·s/rad), e.g. ``{"R": 2.937}`` from an ohmmeter; they come back as given.
    method : {'trf', 'lm', 'gd', 'pattern'}
        Output-error minimizer (:func:`stand.stepid.search.minimize`).
    hold : {'preceding', 'following'}
        Which sample period a voltage sample belongs to (:mod:`stand.stepid.model`).
    use_current : bool
        Use the measured current when every run has it.

    Returns
    -------
    StepResult

    Raises
    ------
    InputError
        Bad known values, method or hold; reversed wiring.
    NotExcitedError
        No voltage change in any run.
    """
    started = time.perf_counter()
    known_values = _check_known(known or {})
    data = step_data(runs)
    with_current = use_current and all(run.current_A is not None for run in data)
    notes = []
    if use_current and not with_current and any(run.current_A is not None for run in data):
        notes.append("current_A is missing in some runs, so only the speed is used. ")
    coefs0, note = _start(data, with_current, hold)
    notes.append(note)
    sigma = [float(np.median([noise_level(run.velocity_rad_s) for run in data]))]
    if with_current:
        sigma.append(float(np.median([noise_level(run.current_A) for run in data
                                      if run.current_A is not None])))
    problem = _Problem(data, coefs0, hold, sigma)
    best = _fit(problem, problem.theta(coefs0, _initial_voltages(data, coefs0)), method)
    nfev = best.nfev
    if with_current:
        rms = _channel_rms(problem, best.x)
        ratio = (rms[1] / sigma[1]) / (rms[0] / sigma[0])
        if not 1 / REWEIGHT_FACTOR < ratio < REWEIGHT_FACTOR:
            problem = _Problem(data, coefs0, hold, rms)
            best = _fit(problem, best.x, method)
            nfev += best.nfev
    result = _result(problem, best, coefs0, known_values, method, hold, nfev,
                     time.perf_counter() - started, "".join(notes))
    return replace(result, files=[run.source for run in runs])


def _channel_rms(problem: _Problem, theta: np.ndarray) -> list[float]:
    sums = np.zeros(2)
    counts = np.zeros(2)
    for run, outputs in zip(problem.data, problem.simulate(theta), strict=True):
        for ch, (model, measured) in enumerate(zip(outputs, problem.channels(run), strict=True)):
            sums[ch] += float(np.sum((model - measured) ** 2))
            counts[ch] += len(model)
    return [float(np.sqrt(s / c)) for s, c in zip(sums, counts, strict=True) if c]


def _result(problem: _Problem, best: Minimum, coefs0: np.ndarray, known: dict[str, float],
            method: str, hold: str, nfev: int, elapsed_s: float, note: str) -> StepResult:
    theta = best.x
    coefs = problem.coefs(theta)
    n_res, n_par = best.jacobian.shape  # n_par counts the initial voltages too
    dof = n_res - n_par
    s2 = float(best.residuals @ best.residuals) / max(dof, 1)
    d = problem.dcoefs_dtheta(theta)
    n = problem.n  # the coefficients' block of the covariance (initial voltages marginalized)
    cov = s2 * np.linalg.pinv(best.jacobian.T @ best.jacobian)[:n, :n] * np.outer(d, d)
    coef_std = np.sqrt(np.maximum(np.diag(cov), 0.0))
    physical = physical_estimate(coefs, cov, known)
    speed = [run.velocity_rad_s for run in problem.data]
    outputs = problem.simulate(theta)
    residual_w = np.concatenate([o[0] - y for o, y in zip(outputs, speed, strict=True)])
    tests: dict[str, Any] = {"velocity_rad_s": whiteness(residual_w)}
    fit_current = None
    current_tf = None
    if problem.n > 3:
        current = [run.current_A for run in problem.data if run.current_A is not None]
        residual_i = np.concatenate([o[1] - y for o, y in zip(outputs, current, strict=True)])
        tests["current_A"] = whiteness(residual_i)
        fit_current = fit_percent(np.concatenate(current), np.concatenate([o[1] for o in outputs]))
        current_tf = {"num": [float(coefs[3]), float(coefs[4])],
                      "den": [1.0, float(coefs[1]), float(coefs[2])]}
    undetermined = [n for n in PARAM_NAMES if physical.params[n] is None]
    if undetermined:
        note += (f"{', '.join(undetermined)} not determined: "
                 + ("speed alone fixes only the 3 transfer-function coefficients; give "
                    f"{5 - 3 - len(known)} more known value(s) (R from an ohmmeter, L from an "
                    "LCR meter, K from the open-circuit voltage at a known speed) or measure "
                    "the current. " if problem.n == 3 else
                    "the data do not determine them. "))
    note += physical.message
    if physical.alternatives:
        note += ("another parameter set fits equally (electrical and mechanical poles "
                 "swapped); reported the one with R/L > Kf/J. ")
    if not best.converged:
        note += f"{method} did not converge: {best.message}. "
    return StepResult(
        transfer_function={"num": [float(coefs[0])],
                           "den": [1.0, float(coefs[1]), float(coefs[2])]},
        params=physical.params,
        identifiable=physical.identifiable,
        fit_percent=fit_percent(np.concatenate(speed), np.concatenate([o[0] for o in outputs])),
        known=known,
        std=physical.std,
        interval95={n: interval(physical.params[n], physical.std[n], dof) for n in PARAM_NAMES},
        transfer_function_std={"num": [float(coef_std[0])],
                               "den": [0.0, float(coef_std[1]), float(coef_std[2])]},
        current_transfer_function=current_tf,
        fit_percent_current=fit_current,
        whiteness=tests,
        start={"num": [float(coefs0[0])], "den": [1.0, float(coefs0[1]), float(coefs0[2])]},
        method=method,
        converged=best.converged,
        nfev=nfev,
        elapsed_s=elapsed_s,
        samples=n_res // (2 if problem.n > 3 else 1),
        runs=len(problem.data),
        used_current=problem.n > 3,
        noise_std={"velocity_rad_s": problem.sigma[0],
                   **({"current_A": problem.sigma[1]} if problem.n > 3 else {})},
        hold=hold,
        initial_voltage_V=[float(v) for v in problem.initial_voltages(theta)],
        alternatives=physical.alternatives,
        message=note.strip() or f"{method}: {best.message}",
    )


def simulated_response(result: StepResult, run: Run, index: int = 0) -> list[np.ndarray]:
    """The identified model's speed (and current) for ``run``, the ``index``-th identified run."""
    coefs = list(result.transfer_function["num"]) + list(result.transfer_function["den"][1:])
    if result.current_transfer_function is not None:
        coefs += list(result.current_transfer_function["num"])
    return respond(np.array(coefs), step_data([run])[0], result.hold,
                   result.initial_voltage_V[index])
