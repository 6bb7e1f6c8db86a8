"""Stored analysis results with their inputs."""

from __future__ import annotations

from typing import Annotated, Any

from fastapi import APIRouter, Query
from fastapi.concurrency import run_in_threadpool

from api.deps import StorageDep
from stand.jsonable import to_jsonable

router = APIRouter(prefix="/results", tags=["results"])

#: Largest list offset a query may ask for (SQLite integers are 64-bit).
MAX_OFFSET = 10**12


@router.get("")
async def list_results(storage: StorageDep, limit: Annotated[int, Query(ge=1, le=1000)] = 100,
                       offset: Annotated[int, Query(ge=0, le=MAX_OFFSET)] = 0) -> list[dict[str, Any]]:
    """Stored results, newest first."""
    return [to_jsonable(r) for r in await run_in_threadpool(storage.list_results, limit, offset)]


@router.get("/{result_id}")
async def get_result(result_id: str, storage: StorageDep) -> dict[str, Any]:
    """One result with its inputs."""
    return to_jsonable(await run_in_threadpool(storage.get_result, result_id))
