"""Which effects the identification model holds: chosen by the data or named.

``auto`` grows the model greedily. Each round fits every effect not yet in the model
(an effect with a hyper-parameter, e.g. the cogging order, at each value of its grid,
keeping the value with the least held-out equation error,
:func:`stand.ident.estimate.solve_blocks`, leave-one-block-out) and keeps those whose
added coefficients are significantly non-zero: a Wald test with the block-sandwich
covariance (right for residuals coloured within a block), at ``SELECT_ALPHA`` after a
Bonferroni factor for the grid searched (a delay adds no column: it must lower the
held-out error, by a paired t test over the blocks). Of those it takes the one of least
held-out error, and stops when none passes. The models are nested and linear in their
coefficients, so the Wald test is the textbook one; the held-out error only ranks.

The timing of the current relative to the encoder (:data:`INPUT_WEIGHTS`, parts of a
sample period) is part of the nominal model, picked first by the least held-out error:
how a drive samples and actuates is not an effect of the motor.

On a shaft that never reverses, ``sign(θ')`` is a constant: Coulomb friction and a
current offset are one column, offered as ``coulomb_friction`` (its torque then holds
any offset) and named in a warning.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np
from scipy.stats import f as f_dist
from scipy.stats import t as student_t

from stand import effects as effect_registry
from stand.diagnosis.model import (
    RIPPLE_OFFSET_PASSES,
    ModelSpec,
    offset_ripple,
    ripple_on_offset,
)
from stand.effects.coulomb_friction import (
    MAX_LEVEL_SLOPE_FACTOR,
    CoulombFriction,
    level_slope_factor,
)
from stand.effects.current_offset import CurrentOffset
from stand.errors import InputError, NotExcitedError
from stand.ident.columns import RAMP_COLUMN, TIMING_COLUMN, Design
from stand.ident.estimate import Estimate, block_count, solve_blocks

#: Effects the identification model can hold (CONTRACT §3 vocabulary, backlash aside:
#: a load behind a gap is a second inertia, not a term of the one-inertia model).
IDENT_EFFECTS: tuple[str, ...] = tuple(e.name for e in effect_registry.all_effects() if e.identified)
#: One-sided level of the paired test that admits an effect.
SELECT_ALPHA = 1e-3
#: Timings of the current tried for the nominal model: the current at ``t + w·Δt``.
INPUT_WEIGHTS: tuple[float, ...] = (0.0, 0.5, 1.0)
#: Level at which a competing model's larger held-out error rejects it (paired t over the
#: blocks): models not rejected at this level enter the model uncertainty of Kt/J.
COMPETITOR_ALPHA = 0.05
#: Columns whose coefficient over the current's is a timing ``w`` within the period.
TIMING_COLUMNS: tuple[str, ...] = (TIMING_COLUMN, RAMP_COLUMN)
#: Least share of samples in the rarer direction for the shaft to count as reversing.
MIN_REVERSE_SHARE = 0.02


@dataclass(frozen=True)
class Selection:
    """The chosen model and its estimate.

    Attributes
    ----------
    spec : ModelSpec
        The model's structure.
    effects : list of str
        Its effects, in the order they were admitted (or named).
    estimate : Estimate
        Its coefficients and their covariance.
    notes : list of str
        What the selection had to decide for the data (for the warnings).
    pool : list of str
        The effects it could choose from (empty when they were named).
    """

    spec: ModelSpec
    effects: list[str]
    estimate: Estimate
    notes: list[str]
    pool: list[str] = field(default_factory=list)


def reverses(design: Design) -> bool:
    """Whether the shaft turns both ways for at least ``MIN_REVERSE_SHARE`` of the run."""
    sign = np.sign(design.sig.omega_f)
    moving = max(1, int(np.count_nonzero(sign)))
    return min(np.sum(sign > 0), np.sum(sign < 0)) >= MIN_REVERSE_SHARE * moving


def parse_effects(text: str) -> list[str] | None:
    """``auto`` → ``None``; ``none`` → ``[]``; ``A,B`` → the names, checked.

    Raises
    ------
    InputError
        An unknown name, or ``none``/``auto`` mixed with names.
    """
    words = [w.strip() for w in text.split(",") if w.strip()]
    if words == ["auto"]:
        return None
    if words == ["none"]:
        return []
    bad = [w for w in words if w not in IDENT_EFFECTS]
    if bad or not words:
        raise InputError(
            f"effects: {', '.join(bad) or repr(text)} not understood; expected 'auto', 'none' "
            f"or a comma-separated list of {', '.join(IDENT_EFFECTS)}")
    return list(dict.fromkeys(words))


class Fitter:
    """Fits specs on one design by one estimator, with the blocks fixed for every model.

    Parameters
    ----------
    design : Design
        The run prepared for the extended model.
    estimator : {'iv', 'bc', 'ls'}
        Instrumental variables, bias-compensated least squares (the filtered current
        noise of :meth:`Design.filtered_noise` subtracted), or least squares.

    Attributes
    ----------
    timing : bool
        The timing of the current within the period is fitted (the
        :data:`~stand.ident.columns.TIMING_COLUMN`): with ``bc`` and ``ls``. An
        instrument for the current's change within a period would have to predict a
        step from the current ``L`` samples away, which it cannot: ``iv`` takes the
        timing as given by the spec.
    """

    def __init__(self, design: Design, estimator: str, source: str = "run") -> None:
        self.design = design
        self.estimator = estimator
        self.source = source
        self.timing = estimator in ("bc", "ls")
        self._fits: dict[tuple[ModelSpec, bool], Estimate | NotExcitedError] = {}
        lag = design.lag if estimator == "iv" else 0
        self.blocks = block_count(int(np.count_nonzero(design.moving)) - 2 * lag,
                                  2 * design.half_width + 1)

    def fit(self, spec: ModelSpec) -> Estimate:
        """Fit ``spec`` (each spec once: the selection and the competitors of
        :func:`model_variance` share the fits)."""
        key = (spec, self.timing)
        if key not in self._fits:
            try:
                self._fits[key] = self._fit(spec)
            except NotExcitedError as exc:
                self._fits[key] = exc
        found = self._fits[key]
        if isinstance(found, NotExcitedError):
            raise found
        return found

    def _fit(self, spec: ModelSpec) -> Estimate:
        """Fit ``spec``; with the timing fitted, twice: the settling placed at the
        period's start, then ``1 − w`` of a period after it (the centroid of a
        first-order loop's deficit, :meth:`Design._settling`)."""
        est = self._solve(spec, 0.0)
        if self.timing and spec.input_weight == 0.0 and TIMING_COLUMN in est.names:
            share = 1.0 - est.value(TIMING_COLUMN) / est.value("current")
            if 0.0 < share <= 1.0:
                est = self._solve(spec, share)
        return est

    def _solve(self, spec: ModelSpec, settling_share: float) -> Estimate:
        iv = self.estimator == "iv"
        names, y, X, Z = self.design.matrices(spec, iv, self.timing, settling_share)
        noise = None
        if self.estimator == "bc":
            noise = self.design.noise_gram(spec, names, self.design.rows(spec, False),
                                           settling_share)
        est = self._bounded(names, y, X, Z, noise, spec)
        if ripple_on_offset(spec):
            # the ripple multiplies the true current, i − i0 (i0 = −one/current): its
            # share of the position-periodic torque at the ripple's order, by a fixed
            # point as the diagnosis fits it (:func:`stand.diagnosis.model.fit`)
            order = replace(spec, cogging_N=spec.ripple_N)
            positions = np.column_stack([self.design.column(order, name)
                                         for name in ("cog_sin", "cog_cos")])
            positions = positions[self.design.rows(spec, iv)]
            for _ in range(RIPPLE_OFFSET_PASSES):
                est = self._bounded(names, y - offset_ripple(est.value, positions), X, Z,
                                    noise, spec)
        return est

    def _bounded(self, names: list[str], y: np.ndarray, X: np.ndarray, Z: np.ndarray,
                 noise: np.ndarray | None, spec: ModelSpec) -> Estimate:
        """The estimate of ``y`` on ``X`` (instruments ``Z``) with every timing column's
        share of the period held within its bounds."""
        est = solve_blocks(names, y, X, Z, self.blocks, self.source, noise)
        fixed: dict[str, float] = {}
        # with a delay k ≥ 1, a timing w < 0 is the delay k − 1 read later in its period
        # (a spurious delay); without one it is a current read after the encoder's sample
        # (EMPS: w = −1.2, the force computed after the position is latched), kept
        lowest = 0.0 if spec.delay else -np.inf
        while outside := _timing_outside(est, fixed, lowest):
            # least squares under the bound 0 ≤ w ≤ 1: a timing beyond it is held at the
            # bound (its column merged into the current's) and the others refitted
            fixed.update(outside)
            T = timing_restriction(names, fixed)
            kept = [n for n in names if n not in fixed]
            restricted = solve_blocks(kept, y, X @ T, Z @ T, self.blocks, self.source,
                                      None if noise is None else T.T @ noise @ T)
            est = restricted.expanded(names, T)
        return est

    def best(self, specs: list[ModelSpec]) -> tuple[ModelSpec, Estimate] | None:
        """The spec of least total held-out error (``None`` if none can be fitted)."""
        found: tuple[ModelSpec, Estimate] | None = None
        for spec in specs:
            try:
                est = self.fit(spec)
            except NotExcitedError:
                continue
            if found is None or est.cv_sse.sum() < found[1].cv_sse.sum():
                found = (spec, est)
        return found


def _timing_outside(est: Estimate, fixed: dict[str, float],
                    lowest: float = 0.0) -> dict[str, float]:
    """The timing columns of ``est`` (not yet ``fixed``) whose share ``w`` of the period
    lies outside ``[lowest, 1]``, each with the bound it is to be held at.

    A current loop settles within the period after its sample, so its timing ``w`` (the
    coefficient of :data:`~stand.ident.columns.TIMING_COLUMN` or
    :data:`~stand.ident.columns.RAMP_COLUMN` over that of the current) is ``1 − τ/Δt``
    for a loop of time constant ``τ`` ≤ Δt: ``w < 0`` would read the current before its
    own sample was taken, ``w > 1`` after the next one.
    """
    if "current" not in est.names or not est.value("current") > 0:
        return {}
    out = {}
    for name in TIMING_COLUMNS:
        if name in est.names and name not in fixed:
            w = est.value(name) / est.value("current")
            if not lowest <= w <= 1.0:
                out[name] = float(np.clip(w, lowest, 1.0))
    return out


def timing_restriction(names: list[str], fixed: dict[str, float]) -> np.ndarray:
    """``T`` with ``β = T·γ`` for the columns ``names`` when each timing column of
    ``fixed`` has the coefficient ``w·β_current``: the restricted fit's columns are
    ``X·T`` (the current's column plus ``w`` times each fixed timing column, the others
    as they are)."""
    kept = [n for n in names if n not in fixed]
    T = np.zeros((len(names), len(kept)))
    for j, name in enumerate(kept):
        T[names.index(name), j] = 1.0
    current = kept.index("current")
    for name, w in fixed.items():
        T[names.index(name), current] = w
    return T


def _candidates(design: Design, spec: ModelSpec, name: str) -> list[ModelSpec]:
    """``spec`` with effect ``name`` added, at every value of its grid."""
    return effect_registry.get(name).ident_grid(spec, design.sig)


def _significant(base: Estimate, cand: Estimate, tried: int) -> float:
    """p value of the Wald test that the columns ``cand`` adds to ``base`` are zero.

    The statistic ``βᵀ·V⁻¹·β/m`` of the ``m`` added coefficients, with their block-sandwich
    covariance ``V``, is taken as F(m, blocks − 1) distributed (Hotelling's statistic for
    a covariance estimated from the blocks). ``tried`` grid values were searched for the
    best one; the p value is multiplied by it (Bonferroni).
    """
    added = [k for k, name in enumerate(cand.names) if name not in base.names]
    if not added:
        return 1.0
    beta = cand.beta[added]
    cov = cand.cov[np.ix_(added, added)]
    try:
        stat = float(beta @ np.linalg.solve(cov, beta)) / len(added)
    except np.linalg.LinAlgError:
        return 1.0
    dof = cand.dof
    if dof <= len(added) - 1 or not np.isfinite(stat):
        return 1.0
    # Hotelling T² with m columns and dof degrees of freedom, as an F(m, dof − m + 1).
    m = len(added)
    f = stat * (dof - m + 1) / dof
    return min(1.0, tried * float(f_dist.sf(f, m, dof - m + 1)))


def _held_out_better(base: Estimate, cand: Estimate, tried: int) -> float:
    """p value of the paired test that ``cand`` lowers the held-out error of ``base``.

    For an effect that adds no column (a delay moves the current column): a one-sided
    t test over the blocks of the log ratio of their held-out errors (blocks differ in
    excitation by orders of magnitude; the ratio weighs each alike), times ``tried``.
    """
    with np.errstate(divide="ignore", invalid="ignore"):
        d = np.log(base.cv_sse / cand.cv_sse)
    if not np.all(np.isfinite(d)):
        return 1.0
    spread = float(np.std(d, ddof=1))
    if spread == 0.0:
        return 0.0 if d.mean() > 0 else 1.0
    t = float(d.mean()) / (spread / np.sqrt(len(d)))
    return min(1.0, tried * float(student_t.sf(t, len(d) - 1)))


def competitors(fitter: Fitter, chosen: Selection, pool: list[str]) -> list[Estimate]:
    """Estimates of the models the data do not reject beside ``chosen``.

    The competitors are ``chosen`` with each of its effects at every other value of its
    grid (a Stribeck velocity, a cogging order, a delay), with each of its effects
    replaced by one it nests (Coulomb friction for Stribeck friction: a run that spends
    little time near standstill tells them apart by little), with each effect of
    ``pool`` not in it added at every value of its grid, and, when the fitter fits the
    current's timing, with the timing fixed at each of :data:`INPUT_WEIGHTS`. One is
    rejected when its held-out error exceeds that of ``chosen`` by the paired test over
    the blocks at :data:`COMPETITOR_ALPHA`; the others explain the run as well as
    ``chosen`` does.
    """
    design, spec = fitter.design, chosen.spec
    specs: list[ModelSpec] = []
    for name in dict.fromkeys([*chosen.effects, *pool]):
        if name in chosen.effects or not set(effect_registry.nested_in(name)) & set(chosen.effects):
            specs += [s for s in _candidates(design, spec, name) if s != spec]
    for name in chosen.effects:
        outer = effect_registry.get(name)
        specs += [s for inner in outer.nests
                  for s in _candidates(design, outer.without(spec), inner) if s != spec]
    found = []
    for candidate in specs:
        try:
            found.append(fitter.fit(candidate))
        except NotExcitedError:
            continue
    if fitter.timing:
        fitter.timing = False
        try:
            for w in INPUT_WEIGHTS:
                try:
                    found.append(fitter.fit(replace(spec, input_weight=w)))
                except NotExcitedError:
                    continue
        finally:
            fitter.timing = True
    return [est for est in found
            if _held_out_better(est, chosen.estimate, 1) > COMPETITOR_ALPHA]


def model_variance(fitter: Fitter, chosen: Selection) -> float:
    """Variance of Kt/J over the models the data do not reject (:func:`competitors`),
    (rad/(s²·A))²: the largest squared difference of a competitor's Kt/J from that of
    ``chosen`` beyond what the noise alone makes it.

    The block sandwich sees the scatter of the blocks about the chosen model; a bias that
    every block shares (an effect taken for a similar one, a hyper-parameter between grid
    values) it cannot see. Where several models explain the run equally well, Kt/J is
    known no better than they agree. Two fits of one run differ by noise too: for nested
    fits the variance of their difference is the difference of their variances
    (Hausman), which is taken off each squared difference, so that a noisy run does not
    count its noise twice.
    """
    spread = [model_disagreement(est, chosen.estimate, "current")
              for est in competitors(fitter, chosen, chosen.pool)]
    return float(max(spread, default=0.0))


def model_disagreement(one: Estimate, other: Estimate, name: str) -> float:
    """:func:`disagreement` of coefficient ``name`` between two models' estimates."""
    k, j = one.names.index(name), other.names.index(name)
    return disagreement(float(one.beta[k]), float(one.cov[k, k]),
                        float(other.beta[j]), float(other.cov[j, j]))


def disagreement(one: float, one_variance: float, other: float, other_variance: float) -> float:
    """Squared difference of two fits' estimates of one value, less the part their own
    noise makes (the difference of their variances, as for nested fits: Hausman), at
    least 0."""
    return max(0.0, (one - other) ** 2 - abs(one_variance - other_variance))


def select(fitter: Fitter, wanted: list[str] | None, spring: bool = False,
           input_weight: float | None = None) -> Selection:
    """Choose (``wanted`` is ``None``) or fit the named effects with ``fitter``.

    Parameters
    ----------
    fitter : Fitter
        The run and the estimator.
    wanted : list of str or None
        Effects to fit; ``None`` lets the data choose among :data:`IDENT_EFFECTS`.
    spring : bool
        Keep seed 000's ``C·θ`` term. Off by default: a motor on a stand has no spring,
        and on a shaft that turns one way the angle is a ramp that the term uses to
        absorb slow drifts (and extrapolates badly to a held-out block).
    input_weight : float or None
        The current's timing when it is known (a current reconstructed over each period,
        :mod:`stand.ident.speed_loop`): the nominal model takes it, and ``auto`` does not
        look for a delay. None: picked from :data:`INPUT_WEIGHTS`.
    """
    design, source = fitter.design, fitter.source
    notes: list[str] = []
    reversing = reverses(design)
    # on a shaft that never reverses, sign(ω) is a constant: Coulomb friction and a
    # current offset are one column, reported as the friction
    coulomb, offset = CoulombFriction.name, CurrentOffset.name
    pool = [e for e in (IDENT_EFFECTS if wanted is None else wanted)
            if (reversing or e != offset)
            and (input_weight is None or wanted is not None
                 or not effect_registry.get(e).moves_the_current)]
    if not reversing and (wanted is None or {coulomb, offset} & set(wanted)):
        notes.append("never_reverses")
        if wanted is not None and offset in wanted and coulomb not in pool:
            pool.append(coulomb)
    friction = any(e == coulomb or e in effect_registry.nested_in(coulomb) for e in pool)
    if friction and level_slope_factor(design.sig.omega_f) > MAX_LEVEL_SLOPE_FACTOR:
        # a run at one speed magnitude: a friction level and D/J are nearly one column
        notes.append("one_speed")
    if input_weight is not None:  # a current rebuilt over the period: its timing is known
        weights: tuple[float, ...] = (input_weight,)
    else:
        weights = (0.0,) if fitter.timing else INPUT_WEIGHTS  # the timing column fits it
    nominal = fitter.best([ModelSpec(input_weight=w, spring=spring) for w in weights])
    if nominal is None:
        raise NotExcitedError(f"{source}: the nominal model cannot be fitted: the data do not "
                              "excite it; excite the motor with a varying command")
    spec, est = nominal
    chosen: list[str] = []
    if wanted is not None:
        for name in pool:
            found = fitter.best(_candidates(design, spec, name))
            if found is None:
                raise NotExcitedError(f"{source}: effect {name} cannot be fitted together with "
                                      f"{', '.join(chosen) or 'the nominal model'}: the data do "
                                      "not separate it")
            spec, est = found
            chosen.append(name)
        return Selection(spec, chosen, est, notes)
    while True:
        best: tuple[str, ModelSpec, Estimate] | None = None
        for name in pool:
            if name in chosen or set(effect_registry.nested_in(name)) & set(chosen):
                continue  # a model that nests it already holds it (Stribeck: a Coulomb level)
            grid = _candidates(design, spec, name)
            found = fitter.best(grid)
            effect = effect_registry.get(name)
            test = _held_out_better if effect.moves_the_current else _significant
            if found is None or test(est, found[1], len(grid)) > SELECT_ALPHA:
                continue
            if best is None or found[1].cv_sse.sum() < best[2].cv_sse.sum():
                best = (name, *found)
        if best is None:
            return Selection(spec, chosen, est, notes, pool)
        chosen.append(best[0])
        spec, est = _revisit_current_timing(fitter, best[1], best[2], chosen)


def _revisit_current_timing(fitter: Fitter, spec: ModelSpec, est: Estimate,
                            chosen: list[str]) -> tuple[ModelSpec, Estimate]:
    """``spec`` with the grid value of each chosen effect that moves the current (the
    delay) picked again, by the held-out error, now that ``chosen[-1]`` is in the model.

    With the timing ``w`` bounded to the period, a delay of ``k`` at ``w`` = 1 and one of
    ``k + 1`` at ``w`` = 0 read the current at nearly the same instant, and which of the
    two fits better can change once another effect takes its part of the motion: a delay
    admitted before that effect keeps its value only if it is still the best.
    """
    for name in chosen[:-1]:
        if effect_registry.get(name).moves_the_current:
            found = fitter.best(_candidates(fitter.design, spec, name))
            if found is not None and found[1].cv_sse.sum() < est.cv_sse.sum():
                spec, est = found
    return spec, est
