"""Profiles: motors, stands and experiments described in YAML.

A motor profile names the motor's parameters, its drive, sensors, limits and the
effects present; a stand profile couples two motor profiles through a reducer. Values a
source does not give are listed under ``assumptions``. Loading validates everything and
names the file and the field that is wrong.

The shipped profiles (``profiles/`` in the repository) install as the package
:data:`PROFILE_PACKAGE` and are found with :mod:`importlib.resources`, so an installed
``stand`` reads them from any directory. This module is the one place that reads a
profile's YAML and the one that turns a pydantic validation error into a message.
"""

from __future__ import annotations

import re
from importlib import resources
from pathlib import Path
from typing import Any, Literal, TypeVar

import yaml
from pydantic import BaseModel, ConfigDict, Field, ValidationError, field_validator

from stand.errors import NotFoundError, ProfileError
from stand.physics.effects import Effects
from stand.physics.parts import DriveParams, MotorParams, ReducerParams, SensorParams

#: The package the shipped profiles install as (``profiles/`` in the repository).
PROFILE_PACKAGE = "stand.profile_data"
#: Kinds of profile, each a folder of YAML files.
KINDS = ("motors", "stands", "experiments", "limits")


def _shipped_dir() -> Path:
    root = resources.files(PROFILE_PACKAGE)
    if not isinstance(root, Path):  # pragma: no cover - pip always installs unpacked
        raise ProfileError(f"the shipped profiles ({PROFILE_PACKAGE}) are not files on disk: "
                           f"{root}; reinstall motorstand with pip")
    return root


#: The folder of the shipped profiles.
PROFILES_DIR = _shipped_dir()

Model = TypeVar("Model", bound=BaseModel)


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
    current_mean_object: int | str | None = Field(
        None, description="the drive's object holding its current averaged over each SYNC "
                          "period (column current_mean_A): an index, or 'index:subindex' in hex")
    current_mean_unit_A: float | None = Field(
        None, gt=0, description="A per count of current_mean_object (default: per mille of "
                                "the rated current, as 0x6078)")

    @field_validator("current_mean_object")
    @classmethod
    def _object_address(cls, value: int | str | None) -> int | str | None:
        if value is not None:
            object_address(value)
        return value

    def current_mean(self) -> tuple[int, int] | None:
        """``current_mean_object`` as (index, subindex), or None."""
        return None if self.current_mean_object is None else object_address(self.current_mean_object)


#: What a drive object's address looks like in a profile: ``0x30D1`` or ``0x30D1:01``.
_ADDRESS = re.compile(r"(?:0x)?([0-9A-Fa-f]{1,4})(?::(?:0x)?([0-9A-Fa-f]{1,2}))?")


def object_address(value: int | str) -> tuple[int, int]:
    """(index, subindex) of an object named as an index (``0x2002``, YAML reads it as an
    integer) or as ``"index:subindex"`` in hex (``"0x30D1:01"``)."""
    if isinstance(value, int):
        index, sub = value, 0
    else:
        match = _ADDRESS.fullmatch(value.strip())
        if match is None:
            raise ValueError(f"an object is an index or 'index:subindex' in hex, such as "
                             f"0x30D1:01; got {value!r}")
        index, sub = int(match[1], 16), int(match[2] or "0", 16)
    if not 0x1000 <= index <= 0xFFFF:
        raise ValueError(f"object index 0x{index:X} is outside the object dictionary's "
                         "0x1000-0xFFFF")
    return index, sub


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
        spec = self.drive.model_dump(exclude={"node_id", "rated_current_A", "current_mean_object",
                                              "current_mean_unit_A"})
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


def describe(exc: ValidationError, prefix: str = "", echo: bool = True) -> str:
    """One message for all of a pydantic error's fields: ``field: problem (got value)``.

    ``prefix`` names where the fields live (``overrides.``); ``echo=False`` leaves the
    offending values out (for input whose values must not be shown back).
    """
    parts = []
    for error in exc.errors():
        where = prefix + (".".join(str(p) for p in error["loc"]) or "(top level)")
        got = f" (got {error.get('input')!r})" if echo and "input" in error else ""
        parts.append(f"{where}: {error['msg']}{got}")
    return "; ".join(parts)


def validate(model: type[Model], data: dict[str, Any], where: str | Path) -> Model:
    """``model(**data)``, a validation error becoming a :class:`ProfileError` that names
    ``where`` and every wrong field."""
    try:
        return model(**data)
    except ValidationError as exc:
        raise ProfileError(f"{where}: {describe(exc)}") from exc


def read_profile(path: Path) -> dict[str, Any]:
    """The fields of the profile YAML file ``path``, as a mapping."""
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
    """Find a profile by file path or by name among the shipped ``<kind>`` profiles."""
    if kind not in KINDS:
        raise ValueError(f"kind must be one of {', '.join(KINDS)}, got {kind!r}")
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
    data = read_profile(path)
    for key, value in (overrides or {}).items():
        if isinstance(value, dict) and isinstance(data.get(key), dict):
            data[key] = {**data[key], **value}
        else:
            data[key] = value
    profile = validate(MotorProfile, data, path)
    profile.effect_set()  # validates the effect parameters, naming the field
    return profile


def load_stand(name_or_path: str | Path) -> StandProfile:
    """Load and validate a two-motor stand profile."""
    path = resolve(name_or_path, "stands")
    return validate(StandProfile, read_profile(path), path)


def list_profiles() -> dict[str, list[str]]:
    """Names of the shipped profiles by kind (``eds``: the object dictionaries' files)."""
    names = {kind: sorted(p.stem for p in (PROFILES_DIR / kind).glob("*.yaml")) for kind in KINDS}
    names["eds"] = sorted(p.name for p in (PROFILES_DIR / "eds").iterdir()
                          if p.suffix.lower() in (".eds", ".dcf"))
    return names
