"""Profiles: motors and stands described in YAML under ``profiles/``.

A motor profile names the motor's parameters, its drive, sensors, limits and the
effects present; a stand profile couples two motor profiles through a reducer. Values a
source does not give are listed under ``assumptions``. Loading validates everything and
names the file and the field that is wrong.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Literal

import yaml
from pydantic import BaseModel, ConfigDict, Field, ValidationError

from stand.errors import NotFoundError, ProfileError
from stand.physics.effects import Effects
from stand.physics.parts import DriveParams, MotorParams, ReducerParams, SensorParams

#: The profiles shipped with the project.
PROFILES_DIR = Path(__file__).resolve().parent.parent / "profiles"


class _Spec(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class MotorSpec(_Spec):
    R: float = Field(gt=0, description="armature resistance, Ω")
    L: float = Field(gt=0, description="armature inductance, H")
    Kt: float = Field(gt=0, description="torque constant = back-EMF constant, N·m/A")
    J: float = Field(gt=0, description="rotor inertia, kg·m²")
    D: float = Field(0.0, ge=0, description="viscous friction, N·m·s/rad")
    C: float = Field(0.0, ge=0, description="torsion spring constant, N·m/rad")


class DriveSpec(_Spec):
    mode: Literal["voltage", "current", "speed"] = "current"
    supply_V: float = Field(24.0, gt=0)
    current_limit_A: float = Field(5.0, gt=0)
    current_tau_s: float = Field(2e-4, gt=0)
    speed_kp: float = Field(0.02, ge=0, description="A per rad/s")
    speed_ki: float = Field(0.5, ge=0, description="A per rad")
    node_id: int = Field(1, ge=1, le=127, description="CANopen node id of the drive")
    rated_current_A: float = Field(1.0, gt=0, description="CiA 402 0x6075, A")


class SensorSpec(_Spec):
    encoder_lines: int = Field(2500, ge=0)
    current_noise_A: float = Field(0.0, ge=0)
    velocity_noise_rad_s: float | None = Field(None, ge=0)
    voltage_noise_V: float = Field(0.0, ge=0)


class Limits(_Spec):
    current_A: float = Field(gt=0, description="largest current command, A")
    voltage_V: float = Field(gt=0, description="largest voltage command, V")
    speed_rad_s: float = Field(gt=0, description="largest speed, rad/s")


class MotorProfile(_Spec):
    """A motor on its drive: everything needed to simulate or run it."""

    name: str
    description: str = ""
    motor: MotorSpec
    drive: DriveSpec = DriveSpec()
    sensors: SensorSpec = SensorSpec()
    limits: Limits
    sample_period_s: float = Field(1e-3, gt=0)
    effects: dict[str, dict[str, float]] = Field(default_factory=dict)
    assumptions: list[str] = Field(default_factory=list)
    source: str = ""

    def motor_params(self) -> MotorParams:
        return MotorParams(**self.motor.model_dump())

    def drive_params(self, mode: str | None = None) -> DriveParams:
        spec = self.drive.model_dump(exclude={"node_id", "rated_current_A"})
        if mode is not None:
            spec["mode"] = mode
        return DriveParams(**spec)

    def sensor_params(self) -> SensorParams:
        return SensorParams(**self.sensors.model_dump())

    def effect_set(self) -> Effects:
        return Effects.from_mapping(self.effects, f"{self.name}.effects")


class ReducerSpec(_Spec):
    ratio: float = Field(gt=0)
    efficiency: float = Field(gt=0, le=1)
    backlash_rad: float = Field(0.0, ge=0)


class StandProfile(_Spec):
    """Two motors coupled by a reducer (seed 000 §3.6)."""

    name: str
    description: str = ""
    motor_in: str
    motor_out: str
    node_in: int = Field(1, ge=1, le=127)
    node_out: int = Field(2, ge=1, le=127)
    reducer: ReducerSpec
    sample_period_s: float = Field(1e-3, gt=0)
    assumptions: list[str] = Field(default_factory=list)

    def reducer_params(self) -> ReducerParams:
        return ReducerParams(**self.reducer.model_dump())


def _describe(exc: ValidationError) -> str:
    parts = []
    for error in exc.errors():
        where = ".".join(str(p) for p in error["loc"]) or "(top level)"
        parts.append(f"{where}: {error['msg']} (got {error.get('input')!r})")
    return "; ".join(parts)


def _read_yaml(path: Path) -> dict[str, Any]:
    try:
        data = yaml.safe_load(path.read_text(encoding="utf-8"))
    except OSError as exc:
        raise ProfileError(f"{path}: cannot read profile: {exc.strerror}") from exc
    except yaml.YAMLError as exc:
        raise ProfileError(f"{path}: not valid YAML: {exc}") from exc
    if not isinstance(data, dict):
        raise ProfileError(f"{path}: a profile must be a mapping of fields, got {type(data).__name__}")
    return data


def resolve(name_or_path: str | Path, kind: str = "motors") -> Path:
    """Find a profile by file path or by name under ``profiles/<kind>/``."""
    path = Path(name_or_path)
    if path.suffix in (".yaml", ".yml") and path.exists():
        return path
    candidate = PROFILES_DIR / kind / f"{name_or_path}.yaml"
    if candidate.exists():
        return candidate
    known = ", ".join(sorted(p.stem for p in (PROFILES_DIR / kind).glob("*.yaml")))
    raise NotFoundError(f"no {kind[:-1]} profile {str(name_or_path)!r}; known: {known}")


def load_motor(name_or_path: str | Path, overrides: dict[str, Any] | None = None) -> MotorProfile:
    """Load and validate a motor profile, with optional top-level ``overrides``."""
    path = resolve(name_or_path, "motors")
    data = _read_yaml(path)
    for key, value in (overrides or {}).items():
        if isinstance(value, dict) and isinstance(data.get(key), dict):
            data[key] = {**data[key], **value}
        else:
            data[key] = value
    try:
        profile = MotorProfile(**data)
    except ValidationError as exc:
        raise ProfileError(f"{path}: {_describe(exc)}") from exc
    profile.effect_set()  # validates the effect parameters, naming the field
    return profile


def load_stand(name_or_path: str | Path) -> StandProfile:
    """Load and validate a two-motor stand profile."""
    path = resolve(name_or_path, "stands")
    try:
        return StandProfile(**_read_yaml(path))
    except ValidationError as exc:
        raise ProfileError(f"{path}: {_describe(exc)}") from exc


def list_profiles() -> dict[str, list[str]]:
    """Names of the shipped profiles by kind."""
    return {
        kind.name: sorted(p.stem for p in kind.glob("*.yaml"))
        for kind in sorted(PROFILES_DIR.iterdir()) if kind.is_dir()
    }
