"""Runs: jobs on the stand (POST /runs), uploads, their state, samples and live events."""

from __future__ import annotations

import asyncio
import json
import shutil
from collections.abc import AsyncIterator
from typing import Annotated, Any, Literal, get_args

from fastapi import APIRouter, Query, Request, Response
from fastapi.concurrency import run_in_threadpool
from fastapi.exceptions import RequestValidationError
from fastapi.responses import JSONResponse, PlainTextResponse, StreamingResponse
from starlette.datastructures import FormData, UploadFile

from api.deps import Authorized, JobsDep, MovesMotor, SettingsDep, StorageDep
from api.forms import read_form
from api.schemas import RunRequest
from api.uploads import read_upload
from stand.jsonable import to_jsonable
from stand.runfile import format_run
from stand.storage import LIVE_STATES, RunRecord, Storage

router = APIRouter(prefix="/runs", tags=["runs"])

#: Largest list offset a query may ask for (SQLite integers are 64-bit).
MAX_OFFSET = 10**12

#: How often the event stream looks for new samples and progress, s.
EVENT_POLL_S = 0.2
#: Most samples sent in one ``samples`` event.
EVENT_MAX_SAMPLES = 5000


def _view(record: RunRecord) -> dict[str, Any]:
    data: dict[str, Any] = to_jsonable(record)
    data["links"] = {"self": f"/runs/{record.id}", "samples": f"/runs/{record.id}/samples",
                     "events": f"/runs/{record.id}/events"}
    return data


@router.post("", status_code=202, dependencies=[MovesMotor])
async def start_run(body: RunRequest, jobs: JobsDep, response: Response) -> dict[str, Any]:
    """Queue the runs of an experiment on the stand; 202 with the first run, its
    ``Location``, and ``runs``: the ids of every run of the job, in order."""
    records = await run_in_threadpool(jobs.submit, body.job())
    response.headers["Location"] = f"/runs/{records[0].id}"
    return {**_view(records[0]), "runs": [r.id for r in records]}


RunKindField = Literal["single", "step", "reducer"]
_UPLOAD_FORM = {"requestBody": {"required": True, "content": {"multipart/form-data": {"schema": {
    "type": "object", "required": ["file"], "properties": {
        "file": {"type": "string", "format": "binary", "description": "run file, CSV (CONTRACT §1)"},
        "kind": {"type": "string", "enum": list(get_args(RunKindField)), "default": "single"},
    }}}}}}


def _upload_fields(form: FormData) -> tuple[UploadFile, RunKindField]:
    """The form's ``file`` and ``kind``; 422 naming the field otherwise."""
    file, kind = form.get("file"), form.get("kind", "single")
    errors: list[dict[str, Any]] = []
    if not isinstance(file, UploadFile):
        errors.append({"type": "missing", "loc": ("body", "file"), "input": None,
                       "msg": "a run file (CSV) is required in the form field 'file'"})
    if kind not in get_args(RunKindField):
        errors.append({"type": "literal_error", "loc": ("body", "kind"), "input": None,
                       "msg": "kind must be 'single', 'step' or 'reducer'"})
    if errors:
        raise RequestValidationError(errors)
    return file, kind  # type: ignore[return-value]


@router.post("/upload", status_code=201, dependencies=[Authorized], openapi_extra=_UPLOAD_FORM)
async def upload_run(storage: StorageDep, settings: SettingsDep, request: Request,
                     ) -> dict[str, Any]:
    """Store an uploaded run file (multipart form: ``file``, ``kind``); 201 with the new
    run. Uploads older than ``STAND_UPLOAD_RETENTION_S`` (when set) are deleted."""
    form = await read_form(request, request.app.state.parse_lanes.limiter)
    try:
        file, kind = _upload_fields(form)
        run = await read_upload(file, kind, settings.upload_limit_bytes, "file",
                                request.app.state.parse_lanes)
    finally:
        await form.close()
    record = await run_in_threadpool(storage.store_run, run, kind, "upload",
                                     {"filename": file.filename})
    if settings.upload_retention_s is not None:
        await run_in_threadpool(storage.prune_uploads, settings.upload_retention_s)
    return _view(record)


@router.delete("/{run_id}", status_code=204, dependencies=[Authorized])
async def delete_run(run_id: str, storage: StorageDep, settings: SettingsDep) -> Response:
    """Delete a finished run (an upload or a job's), its samples and its files on the stand
    (run file, CAN trace); 204. A queued or running run is refused (422): POST /stop first.
    Results keep their inputs."""
    await run_in_threadpool(storage.delete_run, run_id)  # an unknown id ends here (404)
    await run_in_threadpool(shutil.rmtree, settings.runs_dir / run_id, True)
    return Response(status_code=204)


@router.get("")
async def list_runs(storage: StorageDep,
                    limit: Annotated[int, Query(ge=1, le=1000)] = 100,
                    offset: Annotated[int, Query(ge=0, le=MAX_OFFSET)] = 0,
                    state: Literal["queued", "running", "done", "stopped", "aborted", "failed"]
                    | None = None) -> list[dict[str, Any]]:
    """Stored runs, newest first."""
    records = await run_in_threadpool(storage.list_runs, limit, offset, state)
    return [_view(r) for r in records]


@router.get("/{run_id}")
async def get_run(run_id: str, storage: StorageDep) -> dict[str, Any]:
    """One run: state, progress, columns, samples so far."""
    return _view(await run_in_threadpool(storage.get_run, run_id))


@router.get("/{run_id}/samples", response_model=None,
            responses={200: {"content": {"text/csv": {}, "application/json": {}}}})
async def get_samples(run_id: str, storage: StorageDep,
                      format: Literal["csv", "json"] = "csv",
                      start: Annotated[int, Query(ge=0)] = 0) -> Response:
    """The samples as a run file (CSV, CONTRACT §1) or JSON ``{column: [values]}``."""
    columns = await run_in_threadpool(storage.samples, run_id, start)
    if format == "json":
        return JSONResponse(to_jsonable(columns))
    text = await run_in_threadpool(format_run, columns) if columns else ""
    return PlainTextResponse(text, media_type="text/csv")


@router.get("/{run_id}/events", response_class=StreamingResponse,
            responses={200: {"content": {"text/event-stream": {}}}})
async def run_events(run_id: str, storage: StorageDep) -> StreamingResponse:
    """Server-Sent Events: ``progress`` (state, progress, samples), ``samples`` (new
    samples, column to values) and a final ``end`` when the run is over."""
    await run_in_threadpool(storage.get_run, run_id)  # 404 before the stream starts
    return StreamingResponse(_events(run_id, storage), media_type="text/event-stream",
                             headers={"Cache-Control": "no-cache"})


def _event(name: str, data: Any) -> str:
    return f"event: {name}\ndata: {json.dumps(to_jsonable(data), allow_nan=False)}\n\n"


async def _events(run_id: str, storage: Storage) -> AsyncIterator[str]:
    sent = 0
    while True:
        record: RunRecord = await run_in_threadpool(storage.get_run, run_id)
        yield _event("progress", {"id": run_id, "state": record.state, "progress": record.progress,
                                  "samples": record.samples})
        while record.samples > sent:
            columns = await run_in_threadpool(storage.samples, run_id, sent)
            count = min(len(next(iter(columns.values()))), EVENT_MAX_SAMPLES) if columns else 0
            if count == 0:
                break
            yield _event("samples", {"start": sent,
                                     "columns": {k: v[:count] for k, v in columns.items()}})
            sent += count
        if record.state not in LIVE_STATES:
            yield _event("end", {"id": run_id, "state": record.state, "message": record.message})
            return
        await asyncio.sleep(EVENT_POLL_S)
