"""Import measured data from MAT or CSV files into runs (CONTRACT §1), by column mapping.

A mapping says which run column comes from which source expression::

    time_s=t   position_rad=qm   current_A=vir*gtau   position_rad=data[:,2]   current_A=-I/1000

An expression is a product of factors joined by ``*`` or ``/``, with an optional leading
``-``. A factor is a number (``1000``, ``2.5e-3``), a variable of the file (a MAT
variable, ``struct.field`` inside a MAT struct, or a CSV column by its header name), or a
column or row of a 2-D variable (``data[:,3]``, ``data[3,:]``; indices count from 0, as
in numpy; negative indices count from the end). Variables with one element are scalars
(``gtau``); every other factor must be a vector of the run's length. A name that is not a
plain identifier (a CSV header with spaces) may be quoted: ``"Motor current (mA)"/1000``.

A CSV file's columns are its variables; the whole numeric table is also the 2-D variable
``data`` (unless a column has that name), so ``data[:,3]`` works for files without a header.

Reading (:func:`load_variables`) is the only I/O here; :func:`evaluate` and
:func:`map_columns` are pure. Errors name the file and the variable.
"""

from __future__ import annotations

import csv
import io
import re
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np

from stand.errors import InputError, RunFileError
from stand.runfile import COLUMNS, Run, RunKind, check_columns, read_text

#: The 2-D variable that holds a whole CSV table.
TABLE_VARIABLE = "data"
#: File suffixes read as MAT and as delimited text.
MAT_SUFFIXES = (".mat",)
CSV_SUFFIXES = (".csv", ".txt", ".tsv", ".dat")
#: Most variable names an error message lists.
MAX_LISTED = 30

_NUMBER = re.compile(r"^[+-]?(\d+\.?\d*|\.\d+)([eE][+-]?\d+)?$")
_INDEXED = re.compile(r"^(?P<name>.+?)\s*\[\s*(?P<rows>[^,\]]*)\s*,\s*(?P<cols>[^,\]]*)\s*\]$")
_INDEX = re.compile(r"^[+-]?\d+$")


def parse_mapping(text: str) -> tuple[str, str]:
    """``TARGET=EXPRESSION`` to ``(target, expression)``.

    Raises
    ------
    InputError
        No ``=``, or an empty side.
    """
    target, sep, expression = text.partition("=")
    target, expression = target.strip(), expression.strip()
    if not sep or not target or not expression:
        raise InputError(
            f"--map {text!r}: expected TARGET=SOURCE, e.g. time_s=t or current_A=vir*gtau"
        )
    return target, expression


def _split_factors(expression: str) -> list[tuple[str, str]]:
    """Split at top-level ``*`` and ``/`` (not inside quotes or brackets): (operator, factor)."""
    factors: list[tuple[str, str]] = []
    depth, quote, start, operator = 0, "", 0, "*"
    for pos, char in enumerate(expression):
        if quote:
            quote = "" if char == quote else quote
        elif char in "\"'":
            quote = char
        elif char == "[":
            depth += 1
        elif char == "]":
            depth -= 1
        elif char in "*/" and depth == 0:
            factors.append((operator, expression[start:pos].strip()))
            operator, start = char, pos + 1
    factors.append((operator, expression[start:].strip()))
    return factors


def _index(text: str, size: int, what: str) -> int | slice:
    text = text.strip()
    if text == ":":
        return slice(None)
    if not _INDEX.match(text):
        raise InputError(f"{what}: index {text!r} must be ':' or an integer")
    index = int(text)
    if not -size <= index < size:
        raise InputError(f"{what}: index {index} is out of range for size {size}")
    return index


def _lookup(name: str, variables: Mapping[str, np.ndarray], source: str) -> np.ndarray:
    if len(name) >= 2 and name[0] == name[-1] and name[0] in "\"'":
        name = name[1:-1]
    if name in variables:
        return variables[name]
    names = sorted(variables)
    listed = ", ".join(names[:MAX_LISTED]) + (f" and {len(names) - MAX_LISTED} more"
                                              if len(names) > MAX_LISTED else "")
    raise InputError(f"{source}: no variable {name!r}; the file has {listed or 'none'}")


def _factor(text: str, variables: Mapping[str, np.ndarray], source: str) -> float | np.ndarray:
    if not text:
        raise InputError(f"{source}: empty factor in a --map expression")
    if _NUMBER.match(text):
        return float(text)
    match = _INDEXED.match(text)
    if match and not (text[0] in "\"'" and text[-1] == text[0]):
        name = match["name"].strip()
        array = _lookup(name, variables, source)
        if array.ndim != 2:
            raise InputError(
                f"{source}: variable {name!r} has shape {array.shape}; only 2-D variables take "
                f"[rows, cols] indices"
            )
        what = f"{source}: {text}"
        rows, cols = _index(match["rows"], array.shape[0], what), _index(match["cols"], array.shape[1], what)
        if isinstance(rows, slice) == isinstance(cols, slice):
            raise InputError(f"{what}: select one column (data[:,k]) or one row (data[k,:])")
        value = np.asarray(array[rows, cols])
    else:
        name = text
        value = np.asarray(_lookup(text, variables, source))
    if value.dtype.kind not in "biuf":
        raise InputError(
            f"{source}: variable {name!r} is not numeric (MATLAB class or dtype {value.dtype}); "
            "map a numeric variable"
        )
    if value.size == 1:
        return float(value.reshape(-1)[0])
    if value.ndim != 1:
        raise InputError(
            f"{source}: variable {name!r} has shape {value.shape}; pick a column with "
            f"{name}[:,k] (k from 0 to {value.shape[1] - 1})"
        )
    return value


def evaluate(expression: str, variables: Mapping[str, np.ndarray], source: str) -> np.ndarray:
    """The vector a mapping expression denotes (see the module docstring).

    Parameters
    ----------
    expression : str
        E.g. ``vir*gtau``, ``qm*1000``, ``data[:,6]``, ``-x/2``.
    variables : mapping of str to ndarray
        The file's variables (:func:`load_variables`).
    source : str
        File name for messages.

    Raises
    ------
    InputError
        Unknown variable, bad index, vectors of different lengths, a non-numeric variable,
        non-finite values, or an expression without any vector.
    """
    text = expression.strip()
    sign = 1.0
    if text.startswith("-"):
        sign, text = -1.0, text[1:].strip()
    result: float | np.ndarray = sign
    vector_from = ""
    for operator, factor_text in _split_factors(text):
        value = _factor(factor_text, variables, source)
        if isinstance(value, np.ndarray):
            if vector_from and len(value) != np.size(result):
                raise InputError(
                    f"{source}: in {expression!r}, {factor_text} has {len(value)} samples but "
                    f"{vector_from} has {np.size(result)}; vectors must have the same length"
                )
            vector_from = vector_from or factor_text
        try:
            with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
                result = result * value if operator == "*" else result / value
        except TypeError:
            raise InputError(f"{source}: {factor_text} in {expression!r} is not numeric") from None
    if not isinstance(result, np.ndarray):
        raise InputError(
            f"{source}: {expression!r} is a single number; a run column needs a vector "
            "(a variable with one value per sample)"
        )
    bad = np.flatnonzero(~np.isfinite(result))
    if bad.size:
        raise InputError(
            f"{source}: {expression!r} is not finite at sample {bad[0]} (of {len(result)}, "
            f"{bad.size} such); every value must be a finite number"
        )
    return result


def map_columns(
    variables: Mapping[str, np.ndarray],
    mapping: Sequence[tuple[str, str]],
    kind: RunKind,
    source: str,
    period_s: float | None = None,
) -> Run:
    """Build and validate a run of ``kind`` from the file's variables.

    Parameters
    ----------
    variables : mapping of str to ndarray
        The file's variables (:func:`load_variables`).
    mapping : sequence of (target, expression)
        Run column (CONTRACT §1) and its source expression, see :func:`evaluate`.
    kind : {"single", "step", "reducer"}
        Kind of run to build.
    source : str
        File name for messages and :attr:`Run.source`.
    period_s : float, optional
        Sample period, s, used to make ``time_s = k·period_s`` when ``time_s`` is not mapped.

    Raises
    ------
    InputError
        A target that is not a column of ``kind``, a target mapped twice, a bad expression
        (see :func:`evaluate`), or a run that fails :func:`stand.runfile.check_columns`.
    """
    if kind not in COLUMNS:
        raise InputError(f"kind must be one of {', '.join(COLUMNS)}, not {kind!r}")
    allowed = [*COLUMNS[kind][0], *COLUMNS[kind][1]]
    columns: dict[str, np.ndarray] = {}
    for target, expression in mapping:
        if target not in allowed:
            raise InputError(
                f"--map {target}={expression}: {target!r} is not a column of a {kind} run; "
                f"choose from {', '.join(allowed)}"
            )
        if target in columns:
            raise InputError(f"--map: {target} is mapped twice")
        columns[target] = evaluate(expression, variables, source)
    if "time_s" not in columns and period_s is not None:
        if not period_s > 0:
            raise InputError(f"period_s must be > 0 s, got {period_s}")
        lengths = {len(v) for v in columns.values()}
        if lengths:
            columns["time_s"] = np.arange(max(lengths)) * float(period_s)
    if len({len(values) for values in columns.values()}) > 1:
        expressions = dict(mapping)
        detail = ", ".join(f"{name}={expressions.get(name, f'k*{period_s}')} has {len(values)}"
                           for name, values in columns.items())
        raise InputError(f"{source}: mapped columns differ in length ({detail} samples); "
                         "map variables of one record")
    try:
        run = check_columns(columns, kind, source)
    except RunFileError as exc:
        raise InputError(f"{exc} (after mapping {_describe(mapping)})") from exc
    return Run(run.columns, source, {"mapping": dict(mapping), "kind": kind})


def _describe(mapping: Sequence[tuple[str, str]]) -> str:
    return ", ".join(f"{t}={e}" for t, e in mapping) or "nothing"


def _mat_variables(path: Path) -> dict[str, np.ndarray]:
    from scipy import io as sio

    try:
        raw = sio.loadmat(str(path), simplify_cells=True)
    except NotImplementedError as exc:  # MATLAB v7.3 files are HDF5
        raise InputError(
            f"{path}: MATLAB v7.3 (HDF5) files are not supported; save with "
            "save(..., '-v7') or export CSV"
        ) from exc
    except (ValueError, TypeError, OSError) as exc:
        raise InputError(f"{path}: not a readable MAT file ({exc})") from exc
    variables: dict[str, np.ndarray] = {}

    def add(prefix: str, value: object) -> None:
        if isinstance(value, dict):
            for key, item in value.items():
                add(f"{prefix}.{key}", item)
            return
        try:
            array = np.asarray(value)
        except ValueError:  # a ragged cell array
            array = np.asarray(None, dtype=object)
        variables[prefix] = array.astype(float) if array.dtype.kind in "biuf" else array

    for name, value in raw.items():
        if not name.startswith("__"):
            add(name, value)
    return variables


def _csv_variables(path: Path) -> dict[str, np.ndarray]:
    text = read_text(path)
    lines = [line for line in text.splitlines() if line.strip() and not line.lstrip().startswith("#")]
    if not lines:
        raise InputError(f"{path}: no data rows")
    try:
        delimiter = csv.Sniffer().sniff(lines[0] + "\n" + "\n".join(lines[1:5]), ",;\t ").delimiter
    except csv.Error:
        delimiter = ","
    rows = list(csv.reader(io.StringIO("\n".join(lines)), delimiter=delimiter,
                           skipinitialspace=True))
    first = [cell.strip() for cell in rows[0] if cell.strip() or delimiter != " "]
    has_header = not all(_NUMBER.match(cell) or cell.lower() in ("nan", "inf", "-inf")
                         for cell in first)
    header = first if has_header else [str(k) for k in range(len(first))]
    body = rows[1:] if has_header else rows
    table = np.empty((len(body), len(header)))
    for row_number, row in enumerate(body, start=2 if has_header else 1):
        cells = [cell.strip() for cell in row if cell.strip() or delimiter != " "]
        if len(cells) != len(header):
            raise InputError(
                f"{path}: row {row_number} has {len(cells)} cells; the header has {len(header)}"
            )
        for col, cell in enumerate(cells):
            try:
                table[row_number - (2 if has_header else 1), col] = float(cell)
            except ValueError:
                raise InputError(
                    f"{path}: row {row_number}, column {header[col]!r}: {cell!r} is not a number"
                ) from None
    variables = {name: table[:, k] for k, name in enumerate(header)} if has_header else {}
    variables.setdefault(TABLE_VARIABLE, table)
    return variables


def load_variables(path: str | Path) -> dict[str, np.ndarray]:
    """The variables of a MAT or CSV file; numeric ones as float arrays.

    MAT files: every numeric variable (``struct.field`` for fields of structs; MATLAB
    column and row vectors become 1-D, 1×1 become scalars). CSV files: one 1-D variable per
    header column, and the whole table as ``data``.

    Raises
    ------
    InputError
        A missing or unreadable file, an unknown suffix, a non-numeric CSV cell.
    """
    path = Path(path)
    if not path.is_file():
        raise InputError(f"{path}: no such file")
    suffix = path.suffix.lower()
    if suffix in MAT_SUFFIXES:
        return _mat_variables(path)
    if suffix in CSV_SUFFIXES:
        return _csv_variables(path)
    raise InputError(
        f"{path}: unknown file type {suffix or '(none)'}; expected "
        f"{', '.join(MAT_SUFFIXES + CSV_SUFFIXES)}"
    )


def import_run(
    path: str | Path,
    mapping: Sequence[tuple[str, str]],
    kind: RunKind = "single",
    period_s: float | None = None,
) -> Run:
    """Read ``path`` (MAT or CSV) and map its variables to a validated run of ``kind``.

    See :func:`map_columns` for the arguments and errors.
    """
    return map_columns(load_variables(path), mapping, kind, str(path), period_s)
