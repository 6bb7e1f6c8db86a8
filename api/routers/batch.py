"""Batches of stored runs as jobs: ``POST /batch``, its state, and progress over SSE."""

from __future__ import annotations

import asyncio
import threading
from collections.abc import AsyncIterator
from typing import Annotated, Any, Literal

from fastapi import APIRouter, Depends, Request, Response
from fastapi.concurrency import run_in_threadpool
from fastapi.responses import StreamingResponse
from pydantic import BaseModel, ConfigDict, Field

from api.deps import Authorized
from api.routers.runs import _event
from stand.batch.jobs import BatchJob, BatchJobs
from stand.jsonable import to_jsonable

router = APIRouter(prefix="/batch", tags=["batch"])

#: How often the event stream looks at the job's progress, s.
EVENT_POLL_S = 0.2
#: Most processes of a LocalCluster a request may ask for.
MAX_WORKERS = 8
_jobs_lock = threading.Lock()


class BatchRequest(BaseModel):
    """One operation over many stored runs, as a job (202; progress at ``/batch/{id}/events``)."""

    model_config = ConfigDict(extra="forbid")

    operation: Literal["identify", "torque-constant", "efficiency", "step-identify", "diagnose"]
    inputs: list[Annotated[str, Field(min_length=1, max_length=300)]] = Field(
        min_length=1, max_length=10_000,
        description="stored runs: ID or run:ID, query:KEY=VALUE[,...] (kind, state, profile, "
                    "origin, limit), or FIRST,SECOND pairs for diagnose and torque-constant")
    options: dict[str, Any] = Field(default_factory=dict,
                                    description="the operation's options, as the CLI's")
    pool: str = Field("auto", max_length=200, description="auto, all, none, dir, profile or re:REGEX")
    workers: int = Field(0, ge=0, le=MAX_WORKERS,
                         description="processes of a local Dask cluster; 0: in the service")


def get_batch_jobs(request: Request) -> BatchJobs:
    """The app's batch jobs, made on first use."""
    with _jobs_lock:
        jobs: BatchJobs | None = getattr(request.app.state, "batch_jobs", None)
        if jobs is None:
            jobs = BatchJobs(request.app.state.storage, request.app.state.settings.database)
            request.app.state.batch_jobs = jobs
    return jobs


BatchJobsDep = Annotated[BatchJobs, Depends(get_batch_jobs)]


def _view(job: BatchJob) -> dict[str, Any]:
    data: dict[str, Any] = to_jsonable(job)
    data["links"] = {"self": f"/batch/{job.id}", "events": f"/batch/{job.id}/events"}
    if job.result_id:
        data["links"]["result"] = f"/results/{job.result_id}"
    return data


@router.post("", status_code=202, dependencies=[Authorized])
async def start_batch(body: BatchRequest, jobs: BatchJobsDep, response: Response) -> dict[str, Any]:
    """Check the request and start the batch; 202 with the job and its ``Location``."""
    job = await run_in_threadpool(jobs.submit, body.operation, body.inputs, body.options,
                                  body.pool, body.workers)
    response.headers["Location"] = f"/batch/{job.id}"
    return _view(job)


@router.get("/{job_id}")
async def get_batch(job_id: str, jobs: BatchJobsDep) -> dict[str, Any]:
    """The job: state, items done, errors, and once done its summary and result link."""
    return _view(jobs.get(job_id))


@router.get("/{job_id}/events", response_class=StreamingResponse,
            responses={200: {"content": {"text/event-stream": {}}}})
async def batch_events(job_id: str, jobs: BatchJobsDep) -> StreamingResponse:
    """Server-Sent Events: ``progress`` (state, done, total) and a final ``end``."""
    jobs.get(job_id)  # 404 before the stream starts
    return StreamingResponse(_events(jobs, job_id), media_type="text/event-stream",
                             headers={"Cache-Control": "no-cache"})


async def _events(jobs: BatchJobs, job_id: str) -> AsyncIterator[str]:
    sent = None
    while True:
        job = jobs.get(job_id)
        now = (job.state, job.done)
        if now != sent:
            yield _event("progress", {"id": job.id, "state": job.state, "done": job.done,
                                      "total": job.total})
            sent = now
        if job.state in ("done", "failed"):
            yield _event("end", {"id": job.id, "state": job.state, "errors": job.errors,
                                 "result_id": job.result_id, "message": job.message})
            return
        await asyncio.sleep(EVENT_POLL_S)
