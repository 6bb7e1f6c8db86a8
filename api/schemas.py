"""Request bodies of the routes (validated: a bad field is a 422 that names it)."""

from __future__ import annotations

from typing import Annotated, Any, Literal

from pydantic import BaseModel, ConfigDict, Field

#: A run id as the storage makes them (32 hex digits); anything else cannot exist.
RunId = Annotated[str, Field(min_length=1, max_length=64, description="stored run id (GET /runs)")]
Finite = Annotated[float, Field(allow_inf_nan=False)]
Positive = Annotated[float, Field(gt=0, allow_inf_nan=False)]


class _Body(BaseModel):
    model_config = ConfigDict(extra="forbid")


class RunRequest(_Body):
    """A job on the stand: an experiment profile plus what to change for this job.

    ``overrides`` may change the experiment's ``procedure`` (e.g. ``added_inertia`` on a
    no-load experiment), ``repeats``, ``duration_s``, ``period_s``,
    ``added_inertia_kgm2``, ``load_current_A``, ``step_V``, ``step_time_s``, ``seed``;
    every command is checked against the motor profile's limits before anything moves
    (422). An experiment of several runs becomes one job per run (``runs``).
    """

    profile: str = Field(min_length=1, max_length=200,
                         description="experiment profile name (GET /profiles: experiments)")
    overrides: dict[str, Any] = Field(default_factory=dict,
                                      description="experiment fields to change for this job")


class IdentifyRequest(_Body):
    """``stand identify``: Q-matrix identification of one single-motor run (seed 000)."""

    run: RunId
    method: Literal["default", "paper"] = "default"
    no_load_current_A: Annotated[float, Field(ge=0, allow_inf_nan=False)] = 0.0


class TorqueConstantRequest(_Body):
    """``stand torque-constant``: Kt from no-load and loaded (added-inertia) runs."""

    no_load: list[RunId] = Field(min_length=1, max_length=100)
    loaded: list[RunId] = Field(min_length=1, max_length=100)
    added_inertia: Positive = Field(description="inertia of the added disk, kg·m²")
    method: Literal["default", "paper"] = "default"
    compensate: bool = True


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
