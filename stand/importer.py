"""Import measured data into runs (CONTRACT §1), by column mapping.

Sources: MAT files, delimited text (:mod:`stand.delimited`: decimal comma, units row,
skipped preamble), ASAM MDF 4 (:mod:`stand.mdf`), and CAN traces (``.log``, ``.asc``,
``.blf``), whose drive PDOs the bus package decodes into run columns (or any signals,
given a DBC).

A mapping says which run column comes from which source expression::

    time_s=t   position_rad=qm   current_A=vir*gtau   position_rad=data[:,2]   current_A=-I/1000

An expression is a product of factors joined by ``*`` or ``/``, with an optional leading
``-``. A factor is a number (``1000``, ``2.5e-3``), a variable of the file (a MAT
variable, ``struct.field`` inside a MAT struct, or a CSV column by its header name), or a
column or row of a 2-D variable (``data[:,3]``, ``data[3,:]``; indices count from 0, as
in numpy; negative indices count from the end), the constant ``pi``, or a function of
:data:`FUNCTIONS` applied to an expression (``deg2rad(angle)``, ``sqrt(x*x)``).
Variables with one element are scalars (``gtau``); every other factor must be a vector of
the run's length. A name that is not a plain identifier (a CSV header with spaces) may be
quoted: ``"Motor current (mA)"/1000``.

A CSV file's columns are its variables; the whole numeric table is also the 2-D variable
``data`` (unless a column has that name), so ``data[:,3]`` works for files without a header.

Without a mapping, every run column the file holds by name maps to itself (MF4 files this
tool wrote, decoded traces). Reading (:func:`load_source`) is the only I/O here;
:func:`evaluate` and :func:`map_columns` are pure. Errors name the file and the variable.
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path

import numpy as np

from stand.delimited import NUMBER as _NUMBER
from stand.delimited import TABLE_VARIABLE as TABLE_VARIABLE  # re-exported
from stand.errors import InputError, RunFileError
from stand.runfile import COLUMNS, Run, RunKind, check_columns
from stand.sources import ReadOptions, load_source

#: Most variable names an error message lists.
MAX_LISTED = 30
#: Sample rates a motor stand records at, Hz: below, the mechanical time constants (10 ms
#: to 1 s) are not resolved; above, no drive reports position and current that fast. A
#: rate outside is most often a time column in ms or µs read as s.
PLAUSIBLE_RATE_HZ = (20.0, 200e3)
#: Constants and functions a --map expression may use (element-wise).
CONSTANTS = {"pi": math.pi}
FUNCTIONS: dict[str, Callable[[np.ndarray], np.ndarray]] = {
    "sin": np.sin, "cos": np.cos, "tan": np.tan, "sqrt": np.sqrt, "abs": np.abs,
    "exp": np.exp, "log": np.log, "log10": np.log10, "deg2rad": np.deg2rad,
    "rad2deg": np.rad2deg, "unwrap": np.unwrap,
}
_CALL = re.compile(r"^(?P<name>[A-Za-z_][A-Za-z0-9_]*)\((?P<inner>.*)\)$")
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
        elif char in "[(":
            depth += 1
        elif char in "])":
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
    if text in CONSTANTS and text not in variables:
        return CONSTANTS[text]
    call = _CALL.match(text)
    if call and call["name"] in FUNCTIONS and call["name"] not in variables:
        with np.errstate(all="ignore"):  # non-finite results are caught by evaluate()
            return FUNCTIONS[call["name"]](np.asarray(_product(call["inner"], variables, source)))
    if call and call["name"] not in variables:
        raise InputError(f"{source}: unknown function {call['name']!r} in {text!r}; known: "
                         f"{', '.join(FUNCTIONS)}")
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


def _product(expression: str, variables: Mapping[str, np.ndarray], source: str) -> float | np.ndarray:
    """The value of a product of factors (a number or a vector)."""
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
    return result


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
    result = _product(expression, variables, source)
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


def load_variables(path: str | Path, options: ReadOptions | None = None) -> dict[str, np.ndarray]:
    """The variables of a file (see :func:`stand.sources.load_source`)."""
    return load_source(path, options).variables


def default_mapping(variables: Mapping[str, np.ndarray], kind: RunKind) -> list[tuple[str, str]]:
    """Each column of a ``kind`` run that ``variables`` holds by name, mapped to itself, in
    the file's order."""
    columns = {*COLUMNS[kind][0], *COLUMNS[kind][1]}
    return [(name, name) for name in variables if name in columns]


def rate_warnings(run: Run) -> list[str]:
    """A warning when the run's sample rate is implausible for a motor stand
    (:data:`PLAUSIBLE_RATE_HZ`), naming the likely cause."""
    rate = 1.0 / run.dt_s
    low, high = PLAUSIBLE_RATE_HZ
    if low <= rate <= high:
        return []
    cause = ("is time in ms or µs? map time_s=t/1000 (ms) or t/1e6 (µs)" if rate < low
             else "is time in s while the values are ms apart? check the time column's unit")
    return [f"{run.source}: the sample rate {rate:.4g} Hz (period {run.dt_s:.4g} s) is "
            f"implausible for a motor stand (expected {low:g} Hz to {high:g} Hz): {cause}"]


def import_run(
    path: str | Path,
    mapping: Sequence[tuple[str, str]],
    kind: RunKind = "single",
    period_s: float | None = None,
    options: ReadOptions | None = None,
) -> Run:
    """Read ``path`` and map its variables to a validated run of ``kind``.

    An empty ``mapping`` maps every run column the file holds by name
    (:func:`default_mapping`). ``Run.meta`` holds the mapping, the file's metadata, notes
    on how it was read and ``warnings`` (:func:`rate_warnings`). See :func:`map_columns`
    for the arguments and errors.
    """
    source = load_source(path, options)
    if not mapping:
        mapping = default_mapping(source.variables, kind)
        if not mapping:
            raise InputError(f"{path}: no variable is named after a {kind} run column; give "
                             "--map TARGET=EXPR (see --list for the variables)")
    run = map_columns(source.variables, mapping, kind, str(path), period_s)
    meta = {**run.meta, "file_meta": source.meta, "notes": source.notes,
            "warnings": [*source.warnings, *rate_warnings(run)]}
    return Run(run.columns, run.source, meta)
