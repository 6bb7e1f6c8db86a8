"""Request bodies of the routes (validated: a bad field is a 422 that names it)."""

from __future__ import annotations

from typing import Annotated, Any, Literal

from pydantic import AfterValidator, BaseModel, ConfigDict, Field

from stand.errors import InputError
from stand.ident.select import parse_effects

#: A run id as the storage makes them (32 hex digits); anything else cannot exist.
RunId = Annotated[str, Field(min_length=1, max_length=64, description="stored run id (GET /runs)")]
Finite = Annotated[float, Field(allow_inf_nan=False)]
Positive = Annotated[float, Field(gt=0, allow_inf_nan=False)]


class _Body(BaseModel):
    model_config = ConfigDict(extra="forbid")


#: Shortest SYNC period a run may ask for, s. One SYNC (47 bits) and an RPDO and a TPDO
#: of 8 bytes (up to 135 bits each, CiA 301 frames with stuffing) take about 0.3 ms of a
#: 1 Mbit/s bus: below 0.25 ms a cycle cannot carry even one drive's process data.
MIN_PERIOD_S = 2.5e-4
#: Longest SYNC period, s: slower than any identification in the papers samples (1 ms).
MAX_PERIOD_S = 1.0
#: Longest run, s (the experiment profile's own bound).
MAX_DURATION_S = 3600.0
#: Largest seed: numpy's legacy seeding range, 2**32 - 1.
MAX_SEED = 2**32 - 1
#: A shipped profile's name: letters, digits, ``_`` and ``-``; no path, no suffix.
PROFILE_NAME = r"^[A-Za-z0-9][A-Za-z0-9_-]{0,63}$"


def _effects(text: str) -> str:
    """The text of an ``effects`` field, checked by the CLI's own parser."""
    try:
        parse_effects(text)
    except InputError as exc:
        raise ValueError(str(exc)) from None
    return text


#: ``--effects`` of the CLI: ``auto``, ``none`` or comma-separated effect names.
Effects = Annotated[str, AfterValidator(_effects), Field(
    min_length=1, max_length=200,
    description="effects in the model: 'auto' (the data choose), 'none' (seed 000's model) "
                "or comma-separated names of the identifiable effects (CONTRACT §3)")]
#: ``--estimator`` of the CLI (``None``: ``auto`` with effects, ``ls`` without).
Estimator = Annotated[Literal["auto", "iv", "bc", "ls"] | None, Field(
    description="how current noise is kept from biasing Kt/J: instrumental variables, "
                "bias-compensated or plain least squares, or 'auto' (the better of bc and "
                "iv); null: auto with effects, ls for effects 'none'")]


def _bounded(low: float | None = None, high: float | None = None, *, gt: float | None = None,
             description: str) -> Any:
    return Field(None, ge=low, le=high, gt=gt, allow_inf_nan=False, description=description)


class RunOverrides(_Body):
    """Experiment fields a job may change; each finite and in range (422 naming it).

    The motor and stand are not here: their profiles hold the limits. Every command is
    still checked against those limits before anything moves, and a run of more than
    ``stand.runner.MAX_RUN_SAMPLES`` samples (duration_s / period_s) is refused before it
    is planned.
    """

    procedure: Literal["torque_constant", "no_load", "added_inertia", "efficiency",
                       "voltage_step"] | None = Field(None, description="the experiment's procedure")
    repeats: int | None = Field(None, ge=1, le=100, description="no-load/loaded run pairs")
    duration_s: float | None = _bounded(high=MAX_DURATION_S, gt=0,
                                        description="stand time of one run, s")
    period_s: float | None = _bounded(MIN_PERIOD_S, MAX_PERIOD_S, description="SYNC period, s")
    added_inertia_kgm2: float | None = _bounded(high=10.0, gt=0,
                                                description="inertia of the added disk, kg·m²")
    load_current_A: float | None = _bounded(high=1000.0, gt=0,
                                            description="output-motor load step, A")
    step_V: float | None = _bounded(-1000.0, 1000.0, description="voltage step height, V")
    step_time_s: float | None = _bounded(0.0, MAX_DURATION_S, description="time of the step, s")
    seed: int | None = Field(None, ge=0, le=MAX_SEED, description="seed of the simulated noise")


class RunRequest(_Body):
    """A job on the stand: an experiment profile, by name, plus what to change for this job.

    Every command is checked against the motor profile's limits before anything moves
    (422). An experiment of several runs becomes one job per run (``runs``).
    """

    profile: str = Field(pattern=PROFILE_NAME,
                         description="experiment profile name (GET /profiles: experiments)")
    overrides: RunOverrides = Field(default_factory=RunOverrides,
                                    description="experiment fields to change for this job")

    def job(self) -> dict[str, Any]:
        """The request as the job manager takes it (only the overrides given)."""
        return {"profile": self.profile, "overrides": self.overrides.model_dump(exclude_none=True)}


#: ``--motor`` of the CLI: a shipped motor profile whose drive supply, current limit and
#: armature start the speed-loop refinement's model of a loop that saturates.
Motor = Annotated[str | None, Field(
    pattern=PROFILE_NAME,
    description="motor profile name (GET /profiles: motors) whose drive supply, current "
                "limit, R, L and Kt model a speed loop that saturates its supply; null: "
                "not modelled")]


class IdentifyRequest(_Body):
    """``stand identify``: Q-matrix identification of one single-motor run (seed 000)."""

    run: RunId
    method: Literal["default", "paper"] = "default"
    no_load_current_A: Annotated[float, Field(ge=0, allow_inf_nan=False)] = 0.0
    effects: Effects = "auto"
    estimator: Estimator = None
    motor: Motor = None


class TorqueConstantRequest(_Body):
    """``stand torque-constant``: Kt from no-load and loaded (added-inertia) runs."""

    no_load: list[RunId] = Field(min_length=1, max_length=100)
    loaded: list[RunId] = Field(min_length=1, max_length=100)
    added_inertia: Positive = Field(description="inertia of the added disk, kg·m²")
    method: Literal["default", "paper"] = "default"
    compensate: bool = True
    effects: Effects = "auto"
    estimator: Estimator = None
    motor: Motor = None


class EfficiencyRequest(_Body):
    """``stand efficiency``: reducer efficiency from a two-motor run (seed 000 eq. 18)."""

    run: RunId
    ratio: Positive = Field(description="reduction ratio n")
    k_in: Positive = Field(description="torque constant of the input motor, N·m/A")
    k_out: Positive = Field(description="torque constant of the output motor, N·m/A")


class StepIdentifyRequest(_Body):
    """``stand step-identify``: R, L, K, J, Kf from voltage-step runs (seed 001)."""

    runs: list[RunId] = Field(min_length=1, max_length=100)
    known: dict[Literal["R", "L", "K", "J", "Kf"], Positive] = Field(
        default_factory=dict, description="parameters known beforehand, SI units")
    method: Literal["trf", "lm", "gd", "pattern"] = "trf"


class DiagnoseRequest(_Body):
    """``stand diagnose``: the sim-to-real gap of the nominal model on a holdout run."""

    train: RunId
    holdout: RunId
    kt: Positive | None = Field(None, description="torque constant if known, N·m/A")
    horizon_s: Annotated[float, Field(gt=0, le=10, allow_inf_nan=False)] | None = Field(
        None, description="re-anchoring horizon of the simulation, s")
    max_effects: int | None = Field(None, ge=1, le=8, description="most effects in a verdict")
    motor: Motor = None
