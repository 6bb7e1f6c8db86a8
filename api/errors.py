"""The one place that turns :class:`~stand.errors.StandError` into HTTP status codes.

=====================  ======  =====================================================
error                  status  meaning
=====================  ======  =====================================================
InputError             422     bad input: a field, a run file, a profile
NotFoundError          404     an unknown run, result or profile
LimitError             422     a command beyond the profile's limits; nothing was sent
SolverError            422     the data did not let the method converge
RunAborted             409     the run stopped before its end
StorageError           503     the database cannot be written (disk full, I/O error)
BusError               503     CAN / CANopen trouble (timeout, drive fault, heartbeat)
other StandError       500     a bug: reported with its message
=====================  ======  =====================================================

Request validation errors (422) list each bad field as ``{"type", "loc", "msg"}`` plus
the ``input`` only when it is plain finite JSON: NaN or Infinity in a body cannot be
written back as JSON, and echoing it made the default handler fail with a 500.
"""

from __future__ import annotations

import json
import logging
from typing import Any

from fastapi import FastAPI, Request
from fastapi.encoders import jsonable_encoder
from fastapi.exception_handlers import http_exception_handler
from fastapi.exceptions import RequestValidationError
from fastapi.responses import JSONResponse, Response
from starlette.exceptions import HTTPException as StarletteHTTPException

from stand.errors import (
    BusError,
    InputError,
    LimitError,
    NotFoundError,
    RunAborted,
    SolverError,
    StandError,
    StorageError,
)

log = logging.getLogger("stand.api")

#: Error class to (HTTP status, error kind); the first match in this order wins.
STATUS: tuple[tuple[type[StandError], int, str], ...] = (
    (InputError, 422, "input"),
    (NotFoundError, 404, "not_found"),
    (LimitError, 422, "limit"),
    (SolverError, 422, "solver"),
    (RunAborted, 409, "aborted"),
    (StorageError, 503, "storage"),
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


#: Longest echoed input in a validation error, characters of JSON.
MAX_ECHO_CHARS = 200


def _plain(error: dict[str, Any]) -> dict[str, Any]:
    """One validation error as finite JSON: ``input`` only when it is plain and short."""
    out: dict[str, Any] = {"type": str(error.get("type", "value_error")),
                           "loc": [p if isinstance(p, int) else str(p) for p in error.get("loc", ())],
                           "msg": str(error.get("msg", ""))}
    if "input" in error:
        try:
            echo = json.dumps(jsonable_encoder(error["input"]), allow_nan=False)
        except (ValueError, TypeError):  # NaN, Infinity, bytes, files: not echoed
            echo = ""
        if echo and len(echo) <= MAX_ECHO_CHARS:
            out["input"] = json.loads(echo)
    return out


async def http_error_handler(request: Request, exc: Exception) -> Response:
    """FastAPI's answer, except that a body it could not spool because the server's
    disk is full (an OSError behind its 400) is the server's fault: 503."""
    assert isinstance(exc, StarletteHTTPException)
    cause = exc.__cause__
    if exc.status_code == 400 and isinstance(cause, OSError):
        log.error("%s %s: cannot store the request body: %s", request.method, request.url.path,
                  cause)
        return JSONResponse({"detail": f"the server cannot store the request body: {cause}",
                             "error": "storage"}, status_code=503)
    return await http_exception_handler(request, exc)


async def validation_error_handler(request: Request, exc: Exception) -> JSONResponse:
    """422 with ``detail``: the bad fields, never a 500 for input that is not JSON."""
    assert isinstance(exc, RequestValidationError)
    return JSONResponse({"detail": [_plain(e) for e in exc.errors()]}, status_code=422)


def install(app: FastAPI) -> None:
    """Register the handlers on ``app``."""
    app.add_exception_handler(StandError, stand_error_handler)
    app.add_exception_handler(RequestValidationError, validation_error_handler)
    app.add_exception_handler(StarletteHTTPException, http_error_handler)
