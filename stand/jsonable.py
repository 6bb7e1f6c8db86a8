"""Plain JSON data from results: dataclasses, numpy scalars and arrays, non-finite floats."""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from typing import Any

import numpy as np


def to_jsonable(value: Any) -> Any:
    """Convert ``value`` to JSON-ready data; NaN and ±Inf become ``None``."""
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return {f.name: to_jsonable(getattr(value, f.name)) for f in dataclasses.fields(value)}
    if isinstance(value, Mapping):
        return {str(k): to_jsonable(v) for k, v in value.items()}
    if isinstance(value, np.ndarray):
        return to_jsonable(value.tolist())
    if isinstance(value, (list, tuple)):
        return [to_jsonable(v) for v in value]
    if isinstance(value, (np.bool_, bool)):
        return bool(value)
    if isinstance(value, (np.integer, int)):
        return int(value)
    if isinstance(value, (np.floating, float)):
        number = float(value)
        return number if math.isfinite(number) else None
    return value


class JsonResult:
    """Base of the result dataclasses: :meth:`to_json` is what ``stand … --json`` prints."""

    def to_json(self) -> dict[str, Any]:
        """The result as plain JSON data (NaN and ±Inf as ``None``): exactly the object the
        command line prints with ``--json``."""
        data: dict[str, Any] = to_jsonable(self)
        return data
