"""Torque constant from no-load and added-inertia runs: seed 000 eqs. 11-17 and §5.1.

Each no-load run gives ``b̂2 = Kt/J`` (eq. 11), each run with the disk ``Ĵ`` mounted gives
``b̃2 = Kt/(J + Ĵ)`` (eq. 15); eliminating ``J`` (eqs. 16-17)::

    Kt = b̃2·b̂2·Ĵ / (b̂2 − b̃2)

Run ``k`` of one kind pairs with run ``k`` of the other; each pair gives a Kt
(``Kt_repeats``), and the seed reports their mean and standard deviation over the
repeats (5 in the seed).

No-load current (§5.1): a motor turning forward at no load draws a current that makes no
acceleration (Coulomb friction ``Tc/Kt`` and viscous ``D·ω/Kt``). The model of eq. 2 has
no constant term, so that current biases the estimates. With ``effects='none'``,
compensation subtracts the mean no-load current of the no-load repeats from the
measured current of every run (:func:`no_load_current`: the current at zero
acceleration). That is right only while the shaft turns one way. With effects (the
default, ``auto``), every run is identified with the friction model of
:mod:`stand.ident.select` instead: ``Tc·sign(ω)`` reverses with the shaft, and on a
shaft that never reverses it is the constant §5.1 subtracts, fitted per run.

With effects, the repeats of one kind are pooled before eq. 17, each run weighed by its
precision (:func:`pooled_mean`): the runs of one stand are not equally informative (a
speed loop whose law the run pins down gives ``Kt/J`` to 0.05 %, a repeat whose law it
does not to 2 %), and eq. 17 on the pooled ``b̂2`` and ``b̃2`` does not carry the noisy
runs' error into the mean as the mean over the pairs does. ``Kt_ci95`` and ``J_ci95``
are then eq. 17's first-order spread of the two pooled means, with Student's t
(repeats − 1 degrees of freedom). With seed 000's model (``effects='none'``), as in
the seed, Kt is the mean over the pairs and ``Kt_ci95`` that mean ± t times its
standard error.

The runs are of one motor: a position harmonic (cogging, torque ripple) is the
motor's at one order. One that the runs choose at orders no majority of them shares
(:func:`stray_harmonics`) is a run's artefact, not the motor's: the runs that chose
it are identified again without it, and their Kt/J's interval holds what it moved.

``Kt_std`` is the standard deviation of one pair: the larger of the scatter over the
pairs and the spread eq. 17 gets from each run's own interval
(:func:`kt_std_from_runs`): two repeats that agree by chance do not make the answer
more certain than its runs.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from functools import partial

import numpy as np

from stand.diagnosis.signals import MIN_DIAGNOSE_SAMPLES
from stand.errors import InputError
from stand.ident.derivatives import state_derivatives
from stand.ident.estimate import MIN_BLOCKS, t_interval, t_quantile
from stand.ident.identify import IdentifyResult, identify_run
from stand.ident.select import disagreement, parse_effects
from stand.ident.supply import DriveSupply
from stand.jsonable import JsonResult
from stand.runfile import Run

#: Fewest repeats for a spread over the pairs worth reporting without a warning.
MIN_REPEATS = 3


@dataclass(frozen=True)
class TorqueConstantResult(JsonResult):
    """Torque constant and rotor parameters (CONTRACT §2 ``stand torque-constant``).

    Attributes
    ----------
    Kt : float
        Torque constant, N·m/A: eq. 17 on the precision-weighted means of ``b̂2`` and
        ``b̃2`` (with effects), or the mean over the pairs (seed 000's model).
    Kt_std : float
        Standard deviation of Kt over the repeats (one repeat: propagated standard error),
        N·m/A.
    J : float
        Rotor inertia, ``Kt / b̂2`` (``b̂2`` pooled as for Kt), kg·m².
    D : float
        Viscous friction, ``J·mean(D/J)`` of the no-load runs, N·m·s/rad.
    C : float
        Spring constant, ``J·mean(C/J)`` of the no-load runs, N·m/rad.
    repeats : int
        Pairs of runs.
    no_load_current_A : float
        Mean no-load current of the no-load runs, A (subtracted when ``compensated``).
    compensated : bool
        Whether the no-load current was accounted for: subtracted (§5.1, seed 000's
        model) or held by each run's friction model (with effects).
    method : str
        Derivative method.
    Kt_repeats : list of float
        Kt of each pair, N·m/A.
    Kt_over_J_no_load, Kt_over_J_loaded : list of float
        ``b̂2`` and ``b̃2`` of each run, rad/(s²·A).
    no_load_current_repeats_A : list of float
        No-load current of each no-load run, A.
    added_inertia : float
        Disk inertia Ĵ, kg·m².
    Kt_ci95, J_ci95 : list of float
        95 % intervals ``[low, high]`` of Kt (N·m/A) and J (kg·m²).
    effects : list of str
        Effects in the model of any run (CONTRACT §3 names).
    warnings : list of str
        What limits the answer (too few repeats; each run's own warnings, named by run).
    """

    Kt: float
    Kt_std: float
    J: float
    D: float
    C: float
    repeats: int
    no_load_current_A: float
    compensated: bool
    method: str
    Kt_repeats: list[float]
    Kt_over_J_no_load: list[float]
    Kt_over_J_loaded: list[float]
    no_load_current_repeats_A: list[float]
    added_inertia: float
    Kt_ci95: list[float]
    J_ci95: list[float]
    effects: list[str]
    warnings: list[str]


def kt_from_pair(b2_no_load: float, b2_loaded: float, added_inertia: float) -> float:
    """Eq. 17: ``Kt = b̃2·b̂2·Ĵ / (b̂2 − b̃2)``, N·m/A."""
    return b2_loaded * b2_no_load * added_inertia / (b2_no_load - b2_loaded)


def no_load_current(run: Run, method: str = "default",
                    half_width: int | None = None) -> float:
    """No-load current of one no-load run, A.

    The current at zero acceleration: the intercept ``i0`` of the least-squares line
    ``i = i0 + (J/Kt)·α`` through the run's (filtered) current and acceleration. It holds
    the Coulomb and the mean viscous friction current and none of the current that
    accelerates the rotor (a run that starts from rest has a net acceleration).
    """
    states = state_derivatives(run["position_rad"], run["current_A"], run.dt_s, method,
                               half_width)
    alpha, current = states.alpha, states.inputs[:, 0]
    design = np.column_stack([np.ones_like(alpha), alpha])
    (i0, _), *_ = np.linalg.lstsq(design, current, rcond=None)
    return float(i0)


def stray_harmonics(fits: Sequence[IdentifyResult]) -> list[str]:
    """Position harmonics (effects with an order ``N``: cogging, torque ripple) that runs
    of one motor chose, but at no one order that more than half of those runs share.

    A motor's cogging or ripple has one order, whatever the run. A harmonic that one run
    takes at order 25, the next at 31 and the next at 18 fits what each run's model
    lacks (a harmonic beyond the sampling's Nyquist rate met by a current that moves
    within the period, seed 29's stand 6 in docs/results/ident.md), and it moves Kt/J by
    a bias the runs share and their intervals do not hold. A harmonic that some runs do
    not choose at all is not stray for that: a weak one shows in the runs that excite it.
    """
    names = {name for fit in fits for name in fit.effects
             if "N" in fit.effect_params.get(name, {})}
    counts = {name: Counter(_orders(name, fits)) for name in names}
    return sorted(name for name, c in counts.items() if 2 * c.most_common(1)[0][1] <= c.total())


def _orders(name: str, fits: Sequence[IdentifyResult]) -> list[int]:
    """The order ``N`` at which each of ``fits`` that holds harmonic ``name`` took it."""
    return [int(round(f.effect_params[name]["N"])) for f in fits if name in f.effects]


def _without(run: Run, fit: IdentifyResult, stray: list[str],
             identify: Callable[..., IdentifyResult], estimator: str | None) -> IdentifyResult:
    """``fit`` of ``run`` again by ``identify`` (:func:`identify_run` with the run's other
    arguments), its effects but ``stray`` named; ``fit`` if it holds none of them.

    The stray harmonic took part of something the model lacks; left out, that part goes
    elsewhere, and which of the two fits is nearer the truth the run cannot say. Kt/J's
    variance takes their disagreement (less what their own noise makes of it, as for
    nested fits: Hausman), and its interval widens in proportion."""
    if not set(fit.effects) & set(stray):
        return fit
    kept = [name for name in fit.effects if name not in stray]
    out = identify(run, effects=",".join(kept) or "none", estimator=estimator or "auto")
    se = out.Kt_over_J_se
    wider = float(np.sqrt(se**2 + disagreement(out.Kt_over_J, se**2, fit.Kt_over_J,
                                               fit.Kt_over_J_se**2)))
    low, high = out.Kt_over_J_ci95
    half = 0.5 * (high - low) * (wider / se if se > 0 else 1.0)
    return replace(out, Kt_over_J_se=wider,
                   Kt_over_J_ci95=[out.Kt_over_J - half, out.Kt_over_J + half])


def _stray_warning(name: str, fits: Sequence[IdentifyResult]) -> str:
    """The sentence that says which runs chose the stray harmonic ``name``, at which orders."""
    orders = sorted(_orders(name, fits))
    return (f"{name} left out of the {len(orders)} of {len(fits)} runs that chose it: they took "
            f"it at orders {', '.join(map(str, orders))}, no one of them in more than half of "
            "those runs, which a motor's own harmonic does not do; their Kt/J intervals "
            "hold what it moved")


def kt_spread(b2_no_load: float, se_no_load: float, b2_loaded: float, se_loaded: float,
              added_inertia: float) -> float:
    """Standard error of eq. 17's Kt from those of ``b̂2`` and ``b̃2`` (first order,
    independent), N·m/A."""
    bf, bl = b2_no_load, b2_loaded
    scale = added_inertia / (bf - bl) ** 2
    return float(np.hypot(bl * bl * scale * se_no_load, bf * bf * scale * se_loaded))


def kt_std_from_runs(free: Sequence[IdentifyResult], loaded: Sequence[IdentifyResult],
                     added_inertia: float) -> float:
    """Standard deviation of one pair's Kt from the runs' own standard errors (eq. 17
    to first order, mean over the pairs), N·m/A."""
    return float(np.mean([kt_spread(f.Kt_over_J, f.Kt_over_J_se, g.Kt_over_J,
                                    g.Kt_over_J_se, added_inertia)
                          for f, g in zip(free, loaded, strict=False)]))


def pooled_mean(values: Sequence[float], ses: Sequence[float]) -> tuple[float, float]:
    """Precision-weighted mean of repeated estimates and its variance.

    Random effects (DerSimonian-Laird): each value weighs ``1/(se² + τ²)``, ``τ²`` the
    scatter beyond the standard errors ``ses`` (0 where they explain it). The variance is
    the larger of ``1/Σw`` and the weighted scatter about the mean (Hartung-Knapp's,
    ``Σw·(y − ȳ)²/((n − 1)·Σw)``): values that agree by chance do not make the mean more
    certain than their own errors, nor do small errors hide values that disagree.
    """
    y, s2 = np.asarray(values, dtype=float), np.asarray(ses, dtype=float) ** 2
    n = len(y)
    if n == 1:
        return float(y[0]), float(s2[0])
    # an exact run (no noise) weighs as one known to a part in 10⁹, not infinitely
    s2 = np.maximum(s2, (1e-9 * np.abs(y)) ** 2 + np.finfo(float).tiny)
    w = 1.0 / s2
    total = float(np.sum(w))
    q = float(np.sum(w * (y - np.sum(w * y) / total) ** 2))
    tau2 = max(0.0, (q - (n - 1)) / (total - float(np.sum(w * w)) / total))
    w = 1.0 / (s2 + tau2)
    total = float(np.sum(w))
    mean = float(np.sum(w * y)) / total
    scatter = float(np.sum(w * (y - mean) ** 2)) / ((n - 1) * total)
    return mean, max(1.0 / total, scatter)


def _pooled_pair(free: Sequence[IdentifyResult], loaded: Sequence[IdentifyResult],
                 added_inertia: float, dof: int) -> tuple[float, float, list[float], list[float]]:
    """Kt and J by eqs. 17 and 16 on the pooled ``b̂2`` and ``b̃2`` (:func:`pooled_mean`),
    and their 95 % intervals from the two means' variances to first order."""
    bf, var_f = pooled_mean([f.Kt_over_J for f in free], [f.Kt_over_J_se for f in free])
    bl, var_l = pooled_mean([g.Kt_over_J for g in loaded], [g.Kt_over_J_se for g in loaded])
    if bf <= bl:
        raise InputError(f"Kt/J with the disk ({bl:.4g}) is not below Kt/J without it "
                         f"({bf:.4g}), each pooled over its runs: check that the runs are "
                         "labelled the right way round and that the disk was mounted")
    kt = kt_from_pair(bf, bl, added_inertia)
    J = added_inertia * bl / (bf - bl)
    kt_se = kt_spread(bf, np.sqrt(var_f), bl, np.sqrt(var_l), added_inertia)
    J_se = added_inertia / (bf - bl) ** 2 * float(np.hypot(bl * np.sqrt(var_f),
                                                           bf * np.sqrt(var_l)))
    return kt, J, t_interval(kt, kt_se, dof), t_interval(J, J_se, dof)


def _interval(values: np.ndarray, std: float, dof: int) -> list[float]:
    """Mean of ``values`` ± t(dof)·std/√n."""
    half = t_quantile(dof) * std / np.sqrt(len(values))
    centre = float(np.mean(values))
    return [centre - half, centre + half]


def torque_constant(no_load_runs: Sequence[Run], loaded_runs: Sequence[Run],
                    added_inertia: float, method: str = "default", compensate: bool = True,
                    half_width: int | None = None, effects: str = "auto",
                    estimator: str | None = None,
                    supply: DriveSupply | None = None) -> TorqueConstantResult:
    """Kt, J, D, C from repeated no-load and added-inertia runs (eqs. 11-17, §5.1).

    Parameters
    ----------
    no_load_runs, loaded_runs : sequence of Run
        Single-motor runs without and with the disk; equally many (paired in order), or
        one of either kind (paired with every run of the other).
    added_inertia : float
        Inertia of the disk Ĵ, kg·m².
    method : {'default', 'paper'}
        Derivative method (see :mod:`stand.ident.derivatives`).
    compensate : bool
        Subtract the mean no-load current (§5.1); only with ``effects='none'`` (with
        effects the friction model of each run holds that current).
    effects : str
        ``auto``, ``none`` or effect names, as for
        :func:`~stand.ident.identify.identify_run` (the paper method takes none).
    estimator : {'auto', 'iv', 'bc', 'ls'} or None
        Each run's estimator, as for :func:`~stand.ident.identify.identify_run`.
    supply : DriveSupply or None
        The drive's supply and the motor's armature, for each speed-loop run's
        refinement (:func:`~stand.ident.identify.identify_run`).

    Raises
    ------
    InputError
        No runs, unpairable counts, a non-positive inertia, or data in which the disk
        does not lower Kt/J.
    NotExcitedError
        A run that does not determine the model.
    """
    if not (np.isfinite(added_inertia) and added_inertia > 0):
        raise InputError(f"added inertia must be a finite number > 0 kg·m², got {added_inertia}")
    n_free, n_load = len(no_load_runs), len(loaded_runs)
    if n_free == 0 or n_load == 0:
        raise InputError("need at least one no-load run and one run with the added inertia")
    repeats = max(n_free, n_load)
    if n_free != n_load and min(n_free, n_load) != 1:
        raise InputError(
            f"got {n_free} no-load and {n_load} loaded runs; give equally many (paired in "
            "order) or one of either kind"
        )
    shortest = min(len(r.time_s) for r in (*no_load_runs, *loaded_runs))
    if effects == "auto" and (method == "paper" or shortest < MIN_DIAGNOSE_SAMPLES):
        effects = "none"  # too short to choose effects: seed 000's model with §5.1
    seed_model = parse_effects(effects) == []
    currents = [no_load_current(run, method, half_width) for run in no_load_runs]
    i_nl = float(np.mean(currents))
    offset = i_nl if compensate and seed_model else 0.0
    free: list[IdentifyResult] = [identify_run(r, method, offset, half_width, effects, estimator,
                                               supply) for r in no_load_runs]
    loaded = [identify_run(r, method, offset, half_width, effects, estimator, supply)
              for r in loaded_runs]
    chosen = [*free, *loaded]
    stray = stray_harmonics(chosen) if parse_effects(effects) is None else []
    stray_warnings = [_stray_warning(name, chosen) for name in stray]
    if stray:
        again = partial(identify_run, method=method, no_load_current_A=offset,
                        half_width=half_width, supply=supply)
        free = [_without(r, f, stray, again, estimator)
                for r, f in zip(no_load_runs, free, strict=True)]
        loaded = [_without(r, f, stray, again, estimator)
                  for r, f in zip(loaded_runs, loaded, strict=True)]
    b_free = np.array([f.Kt_over_J for f in free])
    b_load = np.array([f.Kt_over_J for f in loaded])
    if np.mean(b_free) <= np.mean(b_load):
        raise InputError(
            f"Kt/J with the disk ({np.mean(b_load):.4g}) is not below Kt/J without it "
            f"({np.mean(b_free):.4g}): check that the runs are labelled the right way round "
            "and that the disk was mounted"
        )
    pairs = np.broadcast_arrays(b_free, b_load) if repeats > 1 else (b_free, b_load)
    kt = np.atleast_1d(kt_from_pair(pairs[0], pairs[1], added_inertia))  # type: ignore[arg-type]
    kt_mean = float(np.mean(kt))
    own = kt_std_from_runs(free, loaded, added_inertia)
    scatter = float(np.std(kt, ddof=1)) if repeats > 1 else 0.0
    kt_std = max(scatter, own)
    # One pair: the spread is the runs' own, with the fewest blocks' degrees of freedom.
    dof = repeats - 1 if repeats > 1 else MIN_BLOCKS - 1
    if seed_model:
        J = kt_mean / float(np.mean(b_free))
        J_pairs = kt / np.broadcast_to(b_free, kt.shape)
        J_std = J * kt_std / kt_mean  # b̂2 is known far better than Kt
        kt_ci95, J_ci95 = _interval(kt, kt_std, dof), _interval(J_pairs, J_std, dof)
    else:
        kt_mean, J, kt_ci95, J_ci95 = _pooled_pair(free, loaded, added_inertia, dof)
    warnings = []
    if repeats < MIN_REPEATS:
        warnings.append(f"too few repeats: {repeats} pair(s); the interval of Kt rests on "
                        f"{'the runs alone' if repeats == 1 else 'one degree of freedom'}; "
                        f"record at least {MIN_REPEATS} (seed 000: 5)")
    for label, runs, fits in (("no-load", no_load_runs, free), ("loaded", loaded_runs, loaded)):
        for run, fit in zip(runs, fits, strict=True):
            warnings += [f"{label} run {run.source}: {w}" for w in fit.warnings]
    warnings += stray_warnings
    found = sorted({name for fit in (*free, *loaded) for name in fit.effects})
    return TorqueConstantResult(
        Kt=kt_mean, Kt_std=kt_std, J=J,
        D=J * float(np.mean([f.D_over_J for f in free])),
        C=J * float(np.mean([f.C_over_J for f in free])),
        repeats=repeats, no_load_current_A=i_nl, compensated=compensate, method=method,
        Kt_repeats=[float(k) for k in kt],
        Kt_over_J_no_load=b_free.tolist(), Kt_over_J_loaded=b_load.tolist(),
        no_load_current_repeats_A=currents, added_inertia=added_inertia,
        Kt_ci95=kt_ci95, J_ci95=J_ci95,
        effects=found, warnings=warnings,
    )
