"""Dependencies shared by the routers: settings, storage, the job manager, the key check."""

from __future__ import annotations

import secrets
from typing import Annotated

from fastapi import Depends, HTTPException, Request
from fastapi.security import HTTPAuthorizationCredentials, HTTPBearer

from stand.jobs import JobManager
from stand.settings import Settings
from stand.storage import Storage

_bearer = HTTPBearer(auto_error=False, description="STAND_API_KEY of the service")


def get_settings(request: Request) -> Settings:
    """The settings the app was created with."""
    settings: Settings = request.app.state.settings
    return settings


def get_storage(request: Request) -> Storage:
    """The app's storage."""
    storage: Storage = request.app.state.storage
    return storage


def get_jobs(request: Request) -> JobManager:
    """The app's run-job manager."""
    jobs: JobManager = request.app.state.jobs
    return jobs


SettingsDep = Annotated[Settings, Depends(get_settings)]
StorageDep = Annotated[Storage, Depends(get_storage)]
JobsDep = Annotated[JobManager, Depends(get_jobs)]


def require_key(settings: SettingsDep,
                credentials: Annotated[HTTPAuthorizationCredentials | None, Depends(_bearer)]) -> None:
    """Mutating routes: ``Authorization: Bearer <STAND_API_KEY>``.

    Without a key configured the service is bound to loopback only (see
    :mod:`stand.cli.serve`) and every local caller may mutate.
    """
    if settings.api_key is None:
        return
    expected = settings.api_key.get_secret_value()
    if credentials is None or credentials.scheme.lower() != "bearer":
        raise HTTPException(401, "this route needs 'Authorization: Bearer <STAND_API_KEY>'",
                            headers={"WWW-Authenticate": "Bearer"})
    if not secrets.compare_digest(credentials.credentials.encode(), expected.encode()):
        raise HTTPException(401, "wrong API key", headers={"WWW-Authenticate": "Bearer"})


def require_key_to_move(settings: SettingsDep,
                        credentials: Annotated[HTTPAuthorizationCredentials | None,
                                               Depends(_bearer)]) -> None:
    """Routes that start a motor: the key check, and no key configured is no excuse.

    Without ``STAND_API_KEY`` only the simulated stand (python-can ``virtual`` bus, drives
    simulated in-process) may be started from loopback; real drives never move on an
    unauthenticated call.
    """
    if settings.api_key is None and settings.bus_interface != "virtual":
        raise HTTPException(401, f"starting a motor on the {settings.bus_interface!r} bus needs "
                                 "STAND_API_KEY set and 'Authorization: Bearer <key>'",
                            headers={"WWW-Authenticate": "Bearer"})
    require_key(settings, credentials)


Authorized = Depends(require_key)
MovesMotor = Depends(require_key_to_move)
