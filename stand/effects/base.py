"""What every effect of the vocabulary (CONTRACT §3) says about itself, and the helpers
their searches and checks share.

An effect is one frozen dataclass (:class:`Effect`): an instance holds the effect's
physical parameters in SI units, as the stand simulator uses them
(:class:`stand.physics.effects.Effects`); the class says how the diagnosis models it —
the :class:`~stand.diagnosis.model.ModelSpec` extension and its input columns, the search
of its hyper-parameters on one run, the check that two runs found the same effect, its
fitted parameters with units, and which other effects it contains.

Parameters come back relative to the torque constant (the current-driven model only
identifies torques per ``Kt``): ``Tc_over_Kt_A`` etc., in amperes of current that make
the same torque; with ``kt`` given also in N·m.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import ClassVar, Protocol

import numpy as np

from stand.diagnosis.model import FittedModel, ModelSpec, fit_residual_batch
from stand.diagnosis.noise import APPROXIMATION_SHARE
from stand.diagnosis.signals import Signals
from stand.errors import InputError

#: What a search returns when no grid point gives a physical fit.
NO_FIT = ModelSpec(input_weight=-1.0)

#: Largest ratio of an effect's size fitted on TRAIN and on HOLDOUT that still agrees.
AGREE_RATIO = 3.0

#: The experiment that separates a constant torque from friction (``separated_by``).
REVERSING_COMMAND = "a command that crosses zero, so that the shaft turns both ways"


class Simulated(Protocol):
    """Specs' simulation errors on the run they were searched on (:meth:`Effect.search`),
    the specs simulated together."""

    def many(self, specs: list[ModelSpec]) -> list[float]: ...


#: Fitted parameters of an effect, by name (units in each effect's ``units``).
Params = dict[str, float | int | None]


@dataclass(frozen=True)
class Effect:
    """One effect of the vocabulary: its physical parameters (the dataclass fields, SI)
    and, on the class, how the diagnosis models, searches and checks it.

    Class attributes
    ----------------
    name : str
        The vocabulary name (CONTRACT §3).
    columns : tuple of str
        Input columns the effect adds to a :class:`ModelSpec` (``ModelSpec.names``).
    units : dict of str to str
        Unit of each parameter :meth:`params` reports.
    nests : tuple of str
        Names of effects this one contains as a special case (Stribeck friction holds a
        Coulomb level): never in a verdict beside it, replaced by it when it wins.
    refit_on_holdout : bool
        Whether its consistency is checked by re-fitting TRAIN's structure on HOLDOUT
        rather than searching HOLDOUT afresh (a hyper-parameter with a flat optimum).
    picked_by_simulation : bool
        Whether its search picks hyper-parameters by simulating the run it searches
        (it then takes ``simulated``).
    speed_test_only : bool
        Whether its holdout test uses the simulated speed alone (a regressor built from
        the measured motion makes its HOLDOUT equation error meaningless).
    across_runs_on_one_tone : bool
        Whether a TRAIN whose current is one frequency cannot resolve it, so it is
        picked across TRAIN and HOLDOUT over :meth:`grid`.
    separated_by : str
        The experiment that tells this effect apart from others it can alias with, in
        words (said when a run cannot).
    approximation_share : float
        What its model may leave beyond noise of the effect, as a share of what it
        explains, before a verdict naming it ends in ``unexplained`` by the remainder's
        size (:data:`stand.diagnosis.noise.APPROXIMATION_SHARE`).
    spec_fields : tuple of str
        The :class:`ModelSpec` fields that model it (reset by :meth:`without`).
    load_behind : bool
        Whether its model is a load inertia behind the motor: a verdict naming it meets a
        load on a compliant coupling (:mod:`stand.diagnosis.coupling`).
    jumps_at_reversal : bool
        Whether it is a dry friction, a torque that jumps with the sign of the speed: a
        verdict naming it meets a drag continuous through zero (:mod:`stand.diagnosis.drag`)
        and a level growing with the torque carried (:mod:`stand.diagnosis.load_friction`).
    """

    name: ClassVar[str]
    columns: ClassVar[tuple[str, ...]] = ()
    units: ClassVar[dict[str, str]] = {}
    nests: ClassVar[tuple[str, ...]] = ()
    refit_on_holdout: ClassVar[bool] = False
    picked_by_simulation: ClassVar[bool] = False
    speed_test_only: ClassVar[bool] = False
    across_runs_on_one_tone: ClassVar[bool] = False
    separated_by: ClassVar[str] = "a broadband command (e.g. a PRBS) that crosses zero"
    approximation_share: ClassVar[float] = APPROXIMATION_SHARE
    spec_fields: ClassVar[tuple[str, ...]] = ()
    load_behind: ClassVar[bool] = False
    jumps_at_reversal: ClassVar[bool] = False

    # --- physics ---------------------------------------------------------------------

    def check(self, where: str) -> None:
        """Raise :class:`~stand.errors.InputError` naming ``where`` when a parameter is
        outside the physics."""

    def structure(self) -> ModelSpec:
        """The model extension of this effect at its true hyper-parameters."""
        raise NotImplementedError

    def true_coefficients(self, Kt: float) -> dict[str, float]:
        """The effect's input-column coefficients per unit of the ``current``
        coefficient (torques as the current that makes them, A), for a torque constant
        ``Kt`` (N·m/A)."""
        return {}

    # --- diagnosis -------------------------------------------------------------------

    @classmethod
    def present(cls, spec: ModelSpec) -> bool:
        """Whether ``spec`` models this effect."""
        return any(column in spec.names() for column in cls.columns)

    @classmethod
    def without(cls, spec: ModelSpec) -> ModelSpec:
        """``spec`` with this effect taken out, the other effects' hyper-parameters as
        they are."""
        nominal = ModelSpec()
        return replace(spec, **{f: getattr(nominal, f) for f in cls.spec_fields})

    @classmethod
    def search(cls, base: ModelSpec, train: Signals,
               simulated: Simulated | None = None) -> ModelSpec:
        """The model ``base`` plus this effect, its hyper-parameters picked on
        ``train``; :data:`NO_FIT` when no choice gives a physical fit."""
        raise NotImplementedError

    @classmethod
    def agree(cls, first: FittedModel, second: FittedModel) -> bool:
        """Whether the effect fitted on two independent runs is the same effect."""
        raise NotImplementedError

    @classmethod
    def params(cls, model: FittedModel, kt: float | None) -> Params:
        """Physical parameters of the effect in the fitted ``model`` (``kt``: the torque
        constant, N·m/A, when known)."""
        raise NotImplementedError

    @classmethod
    def kick_share(cls, model: FittedModel) -> float | None:
        """The relative change of the shaft's acceleration over a speed loop's kicks by
        which the effect in ``model`` shows, where it shows only there; None for an
        effect that does not (most). Such an effect cannot be told from an error of the
        kicks' size in the input (the speed law's ``kp``,
        :attr:`~stand.diagnosis.signals.Signals.kick_scale_sd`)."""
        return None

    @classmethod
    def law_offset_A(cls, model: FittedModel) -> float | None:
        """The constant current, A, as which the effect in ``model`` shows, where it shows
        only as one; None for an effect that does not (most). Such an effect cannot be
        told from an error of the speed law's constant in the input
        (:attr:`~stand.diagnosis.signals.Signals.law_offset_sd_A`)."""
        return None

    @classmethod
    def grid(cls, base: ModelSpec) -> list[ModelSpec]:
        """For ``across_runs_on_one_tone`` effects: the specs picked from across runs."""
        return []

    @classmethod
    def bracketed(cls, spec: ModelSpec) -> bool:
        """Whether a best spec of :meth:`grid` lies within the range the effect reports."""
        return True

    @classmethod
    def same(cls, a: ModelSpec, b: ModelSpec) -> bool:
        """Whether two specs of :meth:`grid` pick the same value within its resolution."""
        return a == b

    # --- identification (stand.ident) -------------------------------------------------

    #: Whether the one-inertia identification model holds the effect.
    identified: ClassVar[bool] = True
    #: Whether it adds no column (it moves the current instead), so that it is admitted by
    #: a lower held-out error rather than by a test of its coefficients.
    moves_the_current: ClassVar[bool] = False

    @classmethod
    def ident_grid(cls, base: ModelSpec, sig: Signals) -> list[ModelSpec]:
        """``base`` with the effect at each value the identification tries on the run
        ``sig`` (one spec for an effect without a hyper-parameter)."""
        raise NotImplementedError

    @classmethod
    def ident_params(cls, spec: ModelSpec, coef: Callable[[str], float]) -> dict[str, float]:
        """The effect's parameters from the identified coefficients ``coef(column)``:
        torques as the current that makes them (per the ``current`` coefficient), A."""
        raise NotImplementedError


def need(condition: bool, where: str, text: str) -> None:
    """Raise :class:`InputError` ``"{where}: {text}"`` unless ``condition``."""
    if not condition:
        raise InputError(f"{where}: {text}")


def best(specs: list[ModelSpec], train: Signals, negative: tuple[str, ...] = (),
         simulated: Simulated | None = None) -> ModelSpec:
    """The spec of smallest equation-error RMS on ``train``; with ``negative``, only among
    fits whose coefficients of those columns are negative (the physical sign); with
    ``simulated`` (a spec's simulation error on ``train``), the one that simulates
    ``train`` best among those."""
    rms, coef = fit_residual_batch(specs, train)
    for name in negative:
        column = specs[0].names().index(name)
        rms = np.where(coef[:, column] < 0, rms, np.inf)
    if not np.isfinite(rms).any():
        return NO_FIT
    if simulated is not None:
        finite = np.flatnonzero(np.isfinite(rms))
        rms = np.full(len(specs), np.inf)
        rms[finite] = simulated.many([specs[k] for k in finite])
    return specs[int(np.argmin(rms))]


def torque(value_per_J: float, model: FittedModel, kt: float | None, name: str,
           out: Params) -> None:
    """Store a torque given per unit inertia (rad/s²) as ``name_over_Kt_A`` (A) and, with
    ``kt``, as ``name`` (N·m)."""
    over_kt = value_per_J / model.coef["current"]
    out[f"{name}_over_Kt_A"] = over_kt
    if kt is not None:
        out[name] = over_kt * kt


def ratio_ok(a: float, b: float, limit: float = AGREE_RATIO) -> bool:
    """Same sign, and sizes within a factor ``limit``."""
    return a * b > 0 and max(abs(a), abs(b)) <= limit * min(abs(a), abs(b))


def fitted(first: FittedModel, second: FittedModel) -> bool:
    """Whether both searches found a fit at all (neither is :data:`NO_FIT`)."""
    return NO_FIT not in (first.spec, second.spec)


def phase(model: FittedModel, prefix: str) -> tuple[float, float]:
    """Amplitude and phase (rad) of the ``{prefix}_sin``/``{prefix}_cos`` columns."""
    s, c = model.coef[f"{prefix}_sin"], model.coef[f"{prefix}_cos"]
    return math.hypot(s, c), math.atan2(c, s)
