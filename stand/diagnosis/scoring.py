"""Model specs scored as the diagnosis scores them: identified on TRAIN, simulated on HOLDOUT.

:class:`Bench` prepares the two runs once (segments, measured speed, its scale) and scores
a spec or a fitted model on them; for each effect of the registry it builds the candidate
``base + effect`` and checks it on HOLDOUT (the same search there must find the same
effect). The engine (:mod:`.engine`) selects among the candidates.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace
from functools import cached_property

import numpy as np

from stand import effects
from stand.diagnosis.model import (
    FittedModel,
    ModelSpec,
    equation_residual,
    fit,
    supply_classes,
)
from stand.diagnosis.notes import single_tone_hz
from stand.diagnosis.signals import Signals
from stand.diagnosis.significance import MIN_SHRINK
from stand.diagnosis.simulate import Segments, segments, simulate_many
from stand.effects.base import NO_FIT, Effect, Simulated
from stand.errors import InputError, NotExcitedError

#: Fewest segments for the paired test (the horizon shrinks on short runs).
MIN_SEGMENTS = 12
#: Where a speed law's current drives the models, an effect that shows only as an error
#: of that current would (a share of its kicks, a constant) must exceed this many of the
#: law's standard uncertainties of it (a two-sided 95 % level).
LAW_SIGMAS = 2.0


@dataclass(frozen=True)
class Scored:
    """A model spec identified on one run and simulated on the other: its free-run error
    and gap, per-segment squared errors, and whether the other run's own search found
    the same effect (``consistent``)."""

    spec: ModelSpec
    model: FittedModel
    sse: np.ndarray
    gap: float
    error: np.ndarray
    consistent: bool = False
    #: HOLDOUT scorings a hyper-parameter of the spec was picked from (1: picked on
    #: TRAIN alone); the holdout test pays a Bonferroni factor of this many.
    looks: int = 1


class Bench:
    """TRAIN and HOLDOUT prepared once; scores a model spec on them."""

    def __init__(self, train: Signals, holdout: Signals, horizon_s: float) -> None:
        self.train, self.holdout, self.horizon_s = train, holdout, horizon_s
        self.seg: Segments = segments(len(holdout), holdout.dt_s, horizon_s, MIN_SEGMENTS)
        if len(self.seg.starts) < 2:
            raise InputError(f"{holdout.source}: too short for a holdout test; record longer")
        self.measured = holdout.omega_meas[self.seg.index]
        self.scale = float(np.sqrt(np.mean((self.measured - self.measured.mean()) ** 2)))
        if self.scale == 0.0:
            raise NotExcitedError(f"{holdout.source}: the speed never varies; nothing to compare")
        #: Effects a run could not identify beside a base model, each with the effects
        #: of that base model (their regressors were linearly dependent there).
        self.aliased: dict[str, tuple[str, ...]] = {}
        #: What the selection's backward pass changed in the verdict, in words.
        self.revisions: list[str] = []
        #: Candidates set aside although both runs found them, and why, in words.
        self.set_aside: list[str] = []

    def score(self, spec: ModelSpec) -> Scored:
        """``spec`` identified on TRAIN, simulated on HOLDOUT."""
        return self.score_model(fit(spec, self.train))

    def score_many(self, specs: list[ModelSpec]) -> list[Scored]:
        """:meth:`score` of each of ``specs``, simulated together."""
        return self.score_models([fit(spec, self.train) for spec in specs])

    def score_model(self, model: FittedModel) -> Scored:
        """``model`` simulated on HOLDOUT: its error, gap and per-segment squared errors."""
        return self.score_models([model])[0]

    def score_models(self, models: list[FittedModel]) -> list[Scored]:
        """:meth:`score_model` of each of ``models``, simulated together."""
        speeds = simulate_many(models, self.holdout, self.seg)
        return [self._scored(model, speed) for model, speed in zip(models, speeds, strict=True)]

    def _scored(self, model: FittedModel, speed: np.ndarray) -> Scored:
        spec = model.spec
        error = speed - self.measured
        error = np.where(np.isfinite(error), error, 1e6 * self.scale)
        error = np.clip(error, -1e6 * self.scale, 1e6 * self.scale)
        gap = 100.0 * float(np.sqrt(np.mean(error**2))) / self.scale
        residual = equation_residual(model, self.holdout)[self.seg.index]
        sse = np.stack([np.sum(error**2, axis=1), np.sum(residual**2, axis=1)])
        return Scored(spec, model, sse, gap, error)

    @cached_property
    def tone_hz(self) -> float | None:
        """TRAIN's current frequency when it is one frequency (:func:`.notes.single_tone_hz`)."""
        return single_tone_hz(self.train)

    @cached_property
    def reverse(self) -> Bench:
        """The same runs the other way round: identified on HOLDOUT, scored on TRAIN."""
        return Bench(self.holdout, self.train, self.horizon_s)

    def candidate(self, name: str, base: Scored,
                  worth_checking: Callable[[Scored], bool] | None = None) -> Scored:
        """``base`` plus effect ``name``, identified on TRAIN, scored on HOLDOUT, and
        checked for consistency: the same search on HOLDOUT must find the same effect
        (or, for an effect whose TRAIN structure is re-fitted there, the same sizes: a
        hyper-parameter with a flat optimum, such as the Stribeck velocity, can land
        elsewhere in a fresh search for a real effect).

        An effect whose model with ``base`` one of the runs does not determine (its
        regressors linearly dependent on the base model's there: a current offset
        beside Coulomb friction on a shaft that never reverses) is no fit, and noted in
        :attr:`aliased`: that run cannot tell them apart, which is an answer, not a
        reason to refuse the diagnosis.

        With ``worth_checking``, the search on HOLDOUT runs only for a candidate it
        accepts (its holdout test, say); any other is left not consistent unchecked.
        """
        effect = effects.get(name)
        try:
            return self._candidate(effect, base, worth_checking)
        except NotExcitedError:
            self.aliased.setdefault(name, tuple(e.name for e in effects.all_effects()
                                                if e.present(base.spec)))
            return replace(base, spec=NO_FIT, consistent=False)

    def _on_holdout(self, spec: ModelSpec) -> ModelSpec:
        """``spec`` as HOLDOUT's own fits of it start: with those of the classes of
        periods at the drive's supply TRAIN picked that HOLDOUT has
        (:func:`~stand.diagnosis.model.supply_classes`). A class HOLDOUT has no period
        of is a column of zeros there, which no fit determines: every consistency check
        of a run whose supply TRAIN alone reaches failed (seed 255 case 44, a cogging of
        order 22 found on TRAIN, p 4e-9, shrink 0.59, named `none`)."""
        present = supply_classes(self.holdout)
        return replace(spec, supply=tuple(name for name in spec.supply if name in present))

    def _candidate(self, effect: type[Effect], base: Scored,
                   worth_checking: Callable[[Scored], bool] | None) -> Scored:
        if effect.across_runs_on_one_tone and self.tone_hz is not None:
            return self.across(effect, base)
        spec = effect.search(base.spec, self.train, self.simulated(effect, self.train))
        if spec == NO_FIT:
            return replace(base, spec=NO_FIT, consistent=False)
        scored = self.score(spec)
        if worth_checking is not None and not worth_checking(scored):
            return scored
        if effect.refit_on_holdout:
            again = self._on_holdout(spec)
        else:
            again = effect.search(self._on_holdout(base.spec), self.holdout,
                                  self.simulated(effect, self.holdout))
            if again == NO_FIT:
                return scored
        consistent = effect.agree(scored.model, fit(again, self.holdout))
        if consistent and self._within_law_error(effect, scored.model):
            return replace(scored, consistent=False)
        return replace(scored, consistent=consistent)

    def _within_law_error(self, effect: type[Effect], model: FittedModel) -> bool:
        """Whether ``effect`` in ``model`` shows only as what an error of the speed law's
        current would make, within ``LAW_SIGMAS`` of the law's uncertainty of it, where
        the law's current drives the models (noted once per effect): a share of the
        kicks (:meth:`~stand.effects.base.Effect.kick_share`) against the law's ``kp``,
        or a constant current (:meth:`~stand.effects.base.Effect.law_offset_A`) against
        its constant."""
        share, offset = effect.kick_share(model), effect.law_offset_A(model)
        kp_sd, offset_sd = self.train.kick_scale_sd, self.train.law_offset_sd_A
        if share is not None and kp_sd is not None and share <= LAW_SIGMAS * kp_sd:
            note = (f"{effect.name} set aside: it shows only at the speed loop's kicks, as "
                    f"{100 * share:.2g} % more acceleration there, within {LAW_SIGMAS:g} "
                    f"times the {100 * kp_sd:.2g} % uncertainty of the kicks' size in the "
                    "speed law's current (its kp); an error of kp makes the same motion")
        elif (offset is not None and offset_sd is not None
              and offset <= LAW_SIGMAS * offset_sd):
            note = (f"{effect.name} set aside: its {1e3 * offset:.2g} mA is within "
                    f"{LAW_SIGMAS:g} times the {1e3 * offset_sd:.2g} mA uncertainty of the "
                    "speed law's constant (the integrator's start and the current sensor's "
                    "offset), whose error makes the same torque")
        else:
            return False
        if note not in self.set_aside:
            self.set_aside.append(note)
        return True

    def simulated(self, effect: type[Effect], sig: Signals
                  ) -> Simulated | None:
        """For an effect whose search picks by simulation, a spec's gap when identified
        on ``sig`` and simulated on ``sig`` itself (TRAIN or HOLDOUT: each run's search
        stays within that run); else None."""
        if not effect.picked_by_simulation:
            return None
        return self.self_gaps(sig)

    def self_gaps(self, sig: Signals) -> Simulated:
        """Specs' gaps when identified on ``sig`` (TRAIN or HOLDOUT) and simulated on
        ``sig`` itself, each spec scored once."""
        return _Gaps(self.on_train if sig is self.train else self.reverse.on_train)

    @cached_property
    def on_train(self) -> Bench:
        """TRAIN against itself: identified and simulated on TRAIN."""
        return Bench(self.train, self.train, self.horizon_s)

    def across(self, effect: type[Effect], base: Scored) -> Scored:
        """``base`` plus ``effect`` (a delay), when TRAIN's current is one frequency.

        There a delay is a phase lag of the current, which ``Kt/J`` and ``D/J`` absorb:
        every delay fits TRAIN alike, each with its own ``Kt/J`` and ``D/J``, and
        simulates another frequency differently. Two runs at different frequencies
        resolve it together, as two-fold cross-validation: each spec of the effect's
        ``grid`` is fitted on TRAIN and simulated on HOLDOUT, and fitted on HOLDOUT and
        simulated on TRAIN. The candidate is the spec that simulates HOLDOUT best,
        unless that is the grid's unbracketed end (no fit). It is consistent when the
        spec that simulates TRAIN best is the same within the effect's resolution
        (``same``), bracketed too, and shrinks TRAIN's gap of the base model fitted on
        HOLDOUT by ``MIN_SHRINK`` at least. Having been picked on HOLDOUT, its holdout
        test pays for the grid (``looks``).
        """
        grid = effect.grid(base.spec)
        forward = [self.score(spec) for spec in grid]
        reverse = self.reverse
        backward = [reverse.score(spec).gap for spec in grid]
        ahead = int(np.argmin([s.gap for s in forward]))
        back = int(np.argmin(backward))
        if not effect.bracketed(grid[ahead]):
            return replace(base, spec=NO_FIT, consistent=False)
        consistent = (effect.bracketed(grid[back])
                      and effect.same(grid[ahead], grid[back])
                      and backward[back] <= (1.0 - MIN_SHRINK) * reverse.score(base.spec).gap)
        return replace(forward[ahead], consistent=consistent, looks=len(grid))


class _Gaps:
    """Specs' gaps on ``bench`` (:class:`~stand.effects.base.Simulated`), each spec
    scored once."""

    def __init__(self, bench: Bench) -> None:
        self.bench = bench
        self.known: dict[ModelSpec, float] = {}

    def many(self, specs: list[ModelSpec]) -> list[float]:
        new = [spec for spec in dict.fromkeys(specs) if spec not in self.known]
        for spec, scored in zip(new, self.bench.score_many(new), strict=True):
            self.known[spec] = scored.gap
        return [self.known[spec] for spec in specs]
