"""The one settings object (environment prefix ``STAND_``); nothing else reads os.environ."""

from __future__ import annotations

from functools import lru_cache
from pathlib import Path
from typing import Any, Literal

from pydantic import Field, SecretStr, field_validator
from pydantic_settings import BaseSettings, SettingsConfigDict


class Settings(BaseSettings):
    """Service and bus settings.

    Every field can be set from the environment as ``STAND_<FIELD>`` (upper case), e.g.
    ``STAND_API_KEY``, ``STAND_BUS_INTERFACE=socketcan``, ``STAND_BUS_CHANNEL=vcan0``.
    """

    model_config = SettingsConfigDict(env_prefix="STAND_", extra="ignore")

    api_key: SecretStr | None = Field(None, description="Bearer key for mutating routes; no default")
    data_dir: Path = Field(Path("stand-data"), description="run files, traces, plots")
    db_path: Path | None = Field(None, description="SQLite file (default: data_dir/stand.sqlite3)")
    host: str = "127.0.0.1"
    port: int = Field(8000, ge=0, le=65535)
    upload_limit_bytes: int = Field(64 * 1024 * 1024, gt=0)
    bus_interface: str = Field("virtual", description="python-can interface name")
    bus_channel: str = Field("motorstand", description="python-can channel")
    bus_bitrate: int = Field(1_000_000, gt=0)
    time_mode: Literal["lockstep", "realtime"] = "lockstep"
    db_max_bytes: int | None = Field(
        None, gt=0, description="largest size of the SQLite file, bytes (default: the disk's)")
    upload_retention_s: float | None = Field(
        None, gt=0, allow_inf_nan=False,
        description="uploaded runs older than this are deleted, s (default: kept)")

    @field_validator("api_key", mode="before")
    @classmethod
    def _blank_key_is_no_key(cls, value: Any) -> Any:
        """``STAND_API_KEY=`` (empty or blanks) is no key, not a key anyone can send."""
        if isinstance(value, SecretStr):
            value = value.get_secret_value()
        if isinstance(value, str) and not value.strip():
            return None
        return value

    @property
    def database(self) -> Path:
        """Path of the SQLite database file."""
        return self.db_path or self.data_dir / "stand.sqlite3"

    @property
    def runs_dir(self) -> Path:
        """Where each run on the stand writes its files: ``runs_dir/<run id>/``."""
        return self.data_dir / "runs"


@lru_cache(maxsize=1)
def get_settings() -> Settings:
    """The process-wide settings, read once from the environment."""
    return Settings()
