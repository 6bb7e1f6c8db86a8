"""The batch table: one row per item, written as CSV or Parquet.

A row holds ``item``, ``input``, ``group``, ``error`` ("" when the item succeeded),
``seconds`` and ``cpu_seconds`` (the item's wall and CPU time in its worker), then the
operation's JSON fields (CONTRACT §2) as columns, in the order the first successful
result gives them. A field whose value is a list or an object (``A``,
``effects``, ``params``) is stored as its JSON text, so every column has one scalar type
and a row reads back as the command's ``--json`` object. Numbers are written with 17
significant digits in CSV (they read back to the same float); a failed item leaves its
result columns empty.
"""

from __future__ import annotations

import csv
import json
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from stand.batch.inputs import Item
from stand.batch.operations import Outcome
from stand.errors import InputError

#: Columns every table starts with.
LEAD_COLUMNS = ("item", "input", "group", "error", "seconds", "cpu_seconds")
FORMATS = (".csv", ".parquet")


def rows(items: Sequence[Item], outcomes: Sequence[Outcome]) -> list[dict[str, Any]]:
    """The table's rows, in item order, all with the same columns."""
    fields: dict[str, None] = {}
    for outcome in outcomes:
        for name in outcome.result or {}:
            fields.setdefault(name, None)
    table = []
    for item, outcome in zip(items, outcomes, strict=True):
        row: dict[str, Any] = {"item": item.index, "input": item.input, "group": item.group,
                               "error": outcome.error, "seconds": outcome.seconds,
                               "cpu_seconds": outcome.cpu_seconds}
        result = outcome.result or {}
        for name in fields:
            value = result.get(name)
            row[name] = json.dumps(value, allow_nan=False) if isinstance(value, (list, dict)) else value
        table.append(row)
    return table


def check_output(path: str | Path) -> Path:
    """``path`` if it ends in .csv or .parquet and its folder can be made; else InputError."""
    out = Path(path)
    if out.suffix.lower() not in FORMATS:
        raise InputError(f"-o {path}: the results file must end in .csv or .parquet")
    if out.suffix.lower() == ".parquet":
        _pyarrow(path)
    if out.exists() and out.is_dir():
        raise InputError(f"-o {path}: is a folder; give a file name")
    return out


def write_table(path: str | Path, table: list[dict[str, Any]]) -> Path:
    """Write ``table`` as CSV or Parquet (by the suffix), atomically: a crash leaves the
    old file or none."""
    out = check_output(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    partial = out.with_name(out.name + ".partial")
    columns = list(table[0]) if table else list(LEAD_COLUMNS)
    if out.suffix.lower() == ".csv":
        with partial.open("w", newline="", encoding="utf-8") as handle:
            writer = csv.writer(handle)
            writer.writerow(columns)
            writer.writerows([_cell(row.get(c)) for c in columns] for row in table)
    else:
        pa, pq = _pyarrow(path)
        arrays = []
        for c in columns:
            kind = _arrow_type(pa, table, c)
            values = [row.get(c) for row in table]
            if kind == pa.string():
                values = [None if v is None else str(v) for v in values]
            arrays.append(pa.array(values, type=kind))
        pq.write_table(pa.Table.from_arrays(arrays, names=columns), partial)
    partial.replace(out)
    return out


def _cell(value: Any) -> str:
    if value is None:
        return ""
    if isinstance(value, float):
        return repr(value)
    return str(value)


def _arrow_type(pa: Any, table: list[dict[str, Any]], column: str) -> Any:
    values = [row.get(column) for row in table if row.get(column) is not None]
    if values and all(isinstance(v, bool) for v in values):
        return pa.bool_()
    if values and all(isinstance(v, int) and not isinstance(v, bool) for v in values):
        return pa.int64()
    if values and all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in values):
        return pa.float64()
    return pa.string()


def _pyarrow(path: str | Path) -> tuple[Any, Any]:
    try:
        import pyarrow as pa
        import pyarrow.parquet as pq
    except ImportError:
        raise InputError(f"-o {path}: Parquet needs pyarrow: pip install 'motorstand[parquet]' "
                         "(or write .csv)") from None
    return pa, pq
