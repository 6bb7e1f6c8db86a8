"""GET /profiles: the shipped motor, stand and experiment profiles."""

from __future__ import annotations

from typing import Any

from fastapi import APIRouter

from stand.profiles import list_profiles

router = APIRouter(tags=["profiles"])


@router.get("/profiles")
def profiles() -> dict[str, Any]:
    """Profile names by kind (``motors``, ``stands``, ``experiments``, ...)."""
    return list_profiles()
