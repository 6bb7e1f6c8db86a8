"""The one place that turns :class:`~stand.errors.StandError` into HTTP status codes.

=====================  ======  =====================================================
error                  status  meaning
=====================  ======  =====================================================
InputError             422     bad input: a field, a run file, a profile
NotFoundError          404     an unknown run, result or profile
LimitError             422     a command beyond the profile's limits; nothing was sent
SolverError            422     the data did not let the method converge
RunAborted             409     the run stopped before its end
BusError               503     CAN / CANopen trouble (timeout, drive fault, heartbeat)
other StandError       500     a bug: reported with its message
=====================  ======  =====================================================
"""

from __future__ import annotations

import logging

from fastapi import FastAPI, Request
from fastapi.responses import JSONResponse

from stand.errors import (
    BusError,
    InputError,
    LimitError,
    NotFoundError,
    RunAborted,
    SolverError,
    StandError,
)

log = logging.getLogger("stand.api")

#: Error class to (HTTP status, error kind); the first match in this order wins.
STATUS: tuple[tuple[type[StandError], int, str], ...] = (
    (InputError, 422, "input"),
    (NotFoundError, 404, "not_found"),
    (LimitError, 422, "limit"),
    (SolverError, 422, "solver"),
    (RunAborted, 409, "aborted"),
    (BusError, 503, "bus"),
    (StandError, 500, "internal"),
)


def status_of(exc: StandError) -> tuple[int, str]:
    """HTTP status and error kind for ``exc``."""
    for cls, status, kind in STATUS:
        if isinstance(exc, cls):
            return status, kind
    return 500, "internal"


async def stand_error_handler(request: Request, exc: Exception) -> JSONResponse:
    """Answer a :class:`StandError` with its status and ``{"detail", "error"}``."""
    assert isinstance(exc, StandError)
    status, kind = status_of(exc)
    if status >= 500:
        log.error("%s %s: %s", request.method, request.url.path, exc)
    return JSONResponse({"detail": str(exc), "error": kind, "type": type(exc).__name__},
                        status_code=status)


def install(app: FastAPI) -> None:
    """Register the handler on ``app``."""
    app.add_exception_handler(StandError, stand_error_handler)
