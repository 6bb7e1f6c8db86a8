"""Uploaded run files and the two ways to call an analysis: JSON with run ids, or a form.

An analysis route takes either ``application/json`` (the request model, runs by stored
id) or ``multipart/form-data`` with the same field names, where a run field may be a CSV
file (CONTRACT §1) instead of an id. Uploaded files are stored as runs (origin
``upload``) so every result keeps its inputs; when the analysis is refused, the runs
uploaded for it are deleted again (their ids were never handed out).

Parsing a run file is pure Python. It runs in a worker process, :data:`PARSE_LANES`
files at once: in a thread it would hold the GIL that the event loop needs for every
request (with 40 parsing threads, GET /health stalled for seconds under 100 concurrent
uploads; with one, p99 was still 150 ms).
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import multiprocessing
import os
import threading
import time
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, field
from typing import Any, get_args, get_origin

import anyio
from fastapi import HTTPException, Request, UploadFile
from fastapi.concurrency import run_in_threadpool
from fastapi.exceptions import RequestValidationError
from pydantic import BaseModel, ValidationError
from starlette.datastructures import UploadFile as StarletteUpload

from api.forms import read_form
from stand.errors import RunFileError, StandError
from stand.runfile import Run, RunKind, parse_run
from stand.storage import Storage

#: Bytes read from an upload at a time.
READ_BLOCK_BYTES = 1 << 20
#: Uploads parsed at once (see the module docstring).
PARSE_LANES = 1
#: How often the parsing worker looks whether the service that started it is still there, s.
SERVICE_WATCH_S = 0.5


def _end_with_service(service_pid: int) -> None:
    """Initializer of the parsing worker: end it once the service is gone.

    After a crash (SIGKILL) nobody sends the pool's shutdown, and the worker, which holds
    both ends of its task queue, would wait for work forever, keeping the forkserver and
    the resource tracker alive with it."""

    def watch() -> None:
        while True:
            time.sleep(SERVICE_WATCH_S)
            try:
                os.kill(service_pid, 0)
            except (ProcessLookupError, PermissionError):  # gone (or its pid reused)
                os._exit(0)

    threading.Thread(target=watch, name="watch-service", daemon=True).start()


@dataclass
class ParseLanes:
    """Where uploads are parsed: threads for the multipart framing (``limiter``), a
    worker process for the run files (``pool``, started at the first upload)."""

    limiter: anyio.CapacityLimiter = field(
        default_factory=lambda: anyio.CapacityLimiter(PARSE_LANES))
    # forkserver, not fork: the service has threads (jobs, bus) that a fork would copy
    # mid-flight, locks held and all.
    pool: ProcessPoolExecutor = field(default_factory=lambda: ProcessPoolExecutor(
        PARSE_LANES, mp_context=multiprocessing.get_context("forkserver"),
        initializer=_end_with_service, initargs=(os.getpid(),)))

    def close(self) -> None:
        """Stop the worker process and wait for it (queued parses are cancelled), so that
        no process of the service outlives it."""
        self.pool.shutdown(wait=True, cancel_futures=True)


def parse_lanes() -> ParseLanes:
    """The parsing lanes of one app (made at start-up, closed at shutdown)."""
    return ParseLanes()


def too_large(limit: int) -> HTTPException:
    return HTTPException(413, f"upload larger than the limit of {limit} bytes "
                              "(setting STAND_UPLOAD_LIMIT_BYTES)")


def _read(file: UploadFile | StarletteUpload, limit: int) -> bytes:
    file.file.seek(0)
    data: bytes = file.file.read(limit + 1)
    if len(data) > limit:
        raise too_large(limit)
    return data


def parse_bytes(data: bytes, kind: RunKind, source: str) -> Run:
    """A run file's bytes as a validated run (in the parsing process)."""
    try:
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise RunFileError(f"{source}: not a UTF-8 text file ({exc.reason})") from exc
    return parse_run(text, kind, source)


async def read_upload(file: UploadFile | StarletteUpload, kind: RunKind, limit: int,
                      name: str, lanes: ParseLanes) -> Run:
    """Read and validate one uploaded run file off the event loop and its GIL; 413 past
    ``limit`` bytes."""
    source = f"{name}: {file.filename or '<upload>'}"
    data = await anyio.to_thread.run_sync(_read, file, limit, limiter=lanes.limiter)
    loop = asyncio.get_running_loop()
    return await loop.run_in_executor(lanes.pool, parse_bytes, data, kind, source)


def forget_uploads(storage: Storage, run_ids: list[str]) -> None:
    """Delete runs uploaded for a request that was refused; best effort (a storage
    fault is already reported by /health)."""
    for run_id in run_ids:
        with contextlib.suppress(StandError):
            storage.delete_run(run_id)


def check_length(request: Request, limit: int) -> None:
    """413 at once when the declared body is larger than ``limit`` (plus form overhead)."""
    length = request.headers.get("content-length")
    if length is not None and length.isdigit() and int(length) > limit + READ_BLOCK_BYTES:
        raise too_large(limit)


def _is_list(annotation: Any) -> bool:
    return get_origin(annotation) is list


def _is_dict(annotation: Any) -> bool:
    return get_origin(annotation) is dict or any(get_origin(a) is dict for a in get_args(annotation))


async def parse_body(request: Request, model: type[BaseModel], run_fields: dict[str, RunKind],
                     storage: Storage, limit: int, uploaded: list[str]) -> BaseModel:
    """The validated request of an analysis, from JSON or from a multipart form.

    Uploaded files in ``run_fields`` are parsed as runs of the given kind, stored, and
    replaced by their new ids, which are appended to ``uploaded`` (so the caller can
    delete them when the analysis is refused). Errors: 422 naming the field, 413 past
    ``limit``.
    """
    check_length(request, limit)
    content_type = request.headers.get("content-type", "").split(";")[0].strip().lower()
    if content_type == "multipart/form-data":
        data = await _form_data(request, model, run_fields, storage, limit, uploaded)
    else:
        try:
            data = await request.json()
        except (ValueError, UnicodeDecodeError) as exc:
            raise RequestValidationError([{
                "type": "json_invalid", "loc": ("body",), "input": None,
                "msg": f"the body must be a JSON object ({exc}) or a multipart form"}]) from exc
    try:
        return model.model_validate(data)
    except ValidationError as exc:
        raise RequestValidationError(
            [{**e, "loc": ("body", *e["loc"])} for e in exc.errors(include_url=False)]) from exc


async def _form_data(request: Request, model: type[BaseModel], run_fields: dict[str, RunKind],
                     storage: Storage, limit: int, uploaded: list[str]) -> dict[str, Any]:
    form = await read_form(request, request.app.state.parse_lanes.limiter)
    data: dict[str, Any] = {}
    total = 0
    try:
        for name in form:
            values = form.getlist(name)
            annotation = model.model_fields[name].annotation if name in model.model_fields else None
            items: list[Any] = []
            for value in values:
                if isinstance(value, StarletteUpload):
                    if name not in run_fields:
                        raise RequestValidationError([{
                            "type": "value_error", "loc": ("body", name), "input": value.filename,
                            "msg": f"field {name!r} takes no file; files go in "
                                   f"{', '.join(run_fields)}"}])
                    run = await read_upload(value, run_fields[name], limit - total, name,
                                            request.app.state.parse_lanes)
                    total += value.size or 0
                    record = await run_in_threadpool(storage.store_run, run, run_fields[name],
                                                     "upload", {"filename": value.filename,
                                                                "field": name})
                    uploaded.append(record.id)
                    items.append(record.id)
                elif annotation is not None and _is_dict(annotation):
                    try:
                        items.append(json.loads(value))
                    except ValueError:
                        items.append(value)
                else:
                    items.append(value)
            data[name] = items if annotation is not None and _is_list(annotation) else items[-1]
    finally:
        await form.close()
    return data
