"""The stand itself: GET /bus (nodes, NMT states, heartbeats, errors), POST /stop."""

from __future__ import annotations

from typing import Any

from fastapi import APIRouter
from fastapi.concurrency import run_in_threadpool

from api.deps import Authorized, JobsDep
from stand.jsonable import to_jsonable

router = APIRouter(tags=["stand"])


@router.get("/bus")
async def bus_status(jobs: JobsDep) -> dict[str, Any]:
    """Nodes, NMT states, heartbeat ages, error counters, current run, queue length."""
    return to_jsonable(await run_in_threadpool(jobs.status))


@router.post("/stop", dependencies=[Authorized])
def stop(jobs: JobsDep) -> dict[str, Any]:
    """CiA 402 quick stop to every drive at once; the current run stops, queued runs are
    cancelled. Runs in a worker thread so a busy event loop cannot delay it."""
    return to_jsonable(jobs.stop_all())
