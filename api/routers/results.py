"""Stored analysis results with their inputs."""

from __future__ import annotations

from typing import Annotated, Any

from fastapi import APIRouter, Query
from fastapi.concurrency import run_in_threadpool
from fastapi.responses import HTMLResponse

from api.deps import StorageDep
from api.routers.analysis import OPERATIONS
from stand.jsonable import to_jsonable
from stand.report import load_limits, render_report, section_for
from stand.runfile import Run
from stand.storage import Storage

router = APIRouter(prefix="/results", tags=["results"])

#: Largest list offset a query may ask for (SQLite integers are 64-bit).
MAX_OFFSET = 10**12
#: Most input runs drawn in a report (a torque-constant result may have dozens).
REPORT_MAX_RUNS = 6


@router.get("")
async def list_results(storage: StorageDep, limit: Annotated[int, Query(ge=1, le=1000)] = 100,
                       offset: Annotated[int, Query(ge=0, le=MAX_OFFSET)] = 0) -> list[dict[str, Any]]:
    """Stored results, newest first."""
    return [to_jsonable(r) for r in await run_in_threadpool(storage.list_results, limit, offset)]


@router.get("/{result_id}")
async def get_result(result_id: str, storage: StorageDep) -> dict[str, Any]:
    """One result with its inputs."""
    return to_jsonable(await run_in_threadpool(storage.get_result, result_id))


def _report(storage: Storage, result_id: str, limits: str | None) -> str:
    record = storage.get_result(result_id)
    op = OPERATIONS.get(record.operation)
    runs: dict[str, Run] = {}
    for name, kind in (op.run_fields.items() if op else ()):
        value = record.inputs.get(name)
        for run_id in (value if isinstance(value, list) else [value]):
            if isinstance(run_id, str) and len(runs) < REPORT_MAX_RUNS:
                runs[f"{name} {run_id[:8]}"] = storage.load_run(run_id, kind)
    result = {**record.result, "operation": record.operation}
    section = section_for(f"{record.operation} {result_id}", result, runs)
    return render_report([section], f"motorstand: {record.operation} {result_id[:8]}",
                         load_limits(limits) if limits else None)


@router.get("/{result_id}/report", response_class=HTMLResponse)
async def result_report(result_id: str, storage: StorageDep,
                        limits: Annotated[str | None, Query(
                            description="end-of-line limits profile under profiles/limits, by name",
                            pattern=r"^[A-Za-z0-9_-]{1,100}$")] = None) -> HTMLResponse:
    """The result as one self-contained HTML report: parameters with units and intervals,
    figures of its input runs, the verdict, and pass/fail against ``limits``."""
    return HTMLResponse(await run_in_threadpool(_report, storage, result_id, limits))
