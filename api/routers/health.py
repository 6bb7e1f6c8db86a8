"""GET /health: is the service up, can it store, is the key set.

``status`` is ``ok``, or ``degraded`` with ``storage.reason`` when the last database
write failed (disk full, I/O error) or a finished run's state is still waiting to be
written. Reading needs no database access, so /health answers while the disk is full.
"""

from __future__ import annotations

from typing import Any

from fastapi import APIRouter

from api.deps import JobsDep, SettingsDep, StorageDep

router = APIRouter(tags=["health"])


@router.get("/health")
async def health(settings: SettingsDep, storage: StorageDep, jobs: JobsDep) -> dict[str, Any]:
    """Service status."""
    keyed = settings.api_key is not None
    reasons = [r for r in (storage.fault, jobs.fault) if r]
    return {
        "status": "degraded" if reasons else "ok",
        "storage": {"ok": not reasons, "reason": "; ".join(reasons) or None},
        "database": str(storage.path),
        "auth": "bearer key" if keyed else "none: no STAND_API_KEY, loopback only",
    }
