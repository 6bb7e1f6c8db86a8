"""GET /health: is the service up, which storage, is the key set."""

from __future__ import annotations

from typing import Any

from fastapi import APIRouter

from api.deps import SettingsDep, StorageDep

router = APIRouter(tags=["health"])


@router.get("/health")
def health(settings: SettingsDep, storage: StorageDep) -> dict[str, Any]:
    """Service status."""
    keyed = settings.api_key is not None
    return {
        "status": "ok",
        "database": str(storage.path),
        "auth": "bearer key" if keyed else "none: no STAND_API_KEY, loopback only",
    }
