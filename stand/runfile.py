"""Run files: the CSV format of CONTRACT §1, read strictly and written plainly.

A run is a set of equally long, finite, float columns sampled on one uniform time base.
Reading is all or nothing: a bad file raises :class:`~stand.errors.RunFileError` naming
the file, the row and the column, and returns no partial data.
"""

from __future__ import annotations

import csv
import io
import math
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal

import numpy as np

from stand.errors import RunFileError

RunKind = Literal["single", "step", "reducer"]

#: Optional column of a single-motor run: the drive's current averaged over the sample
#: period that ends at the row's instant (the mean of its current loop's samples since
#: the previous SYNC), A. Where both runs of a diagnosis hold it, it drives the models
#: in place of a reconstruction of the current between samples
#: (:func:`stand.diagnosis.engine.diagnose`).
CURRENT_MEAN_COLUMN = "current_mean_A"

#: Required and optional columns of each kind of run file (CONTRACT §1).
COLUMNS: dict[str, tuple[tuple[str, ...], tuple[str, ...]]] = {
    "single": (("time_s", "current_A", "position_rad"),
               ("voltage_V", "velocity_rad_s", "speed_target_rad_s", CURRENT_MEAN_COLUMN)),
    "step": (("time_s", "voltage_V", "velocity_rad_s"), ("current_A", "position_rad")),
    "reducer": (
        ("time_s", "current_in_A", "position_in_rad", "current_out_A", "position_out_rad"),
        ("voltage_in_V", "voltage_out_V"),
    ),
}

MIN_SAMPLES = 20
#: Largest allowed relative deviation of one sample period from the median period.
PERIOD_TOLERANCE = 0.01
#: Shortest sample period a run may have, s. No drive samples faster than 1 MHz; a period
#: of 1e-300 s makes the identification's 1/period² terms overflow to infinity.
MIN_PERIOD_S = 1e-6


@dataclass(frozen=True)
class Run:
    """One recorded or simulated run.

    Attributes
    ----------
    columns : dict of str to ndarray
        Column name (with its unit, e.g. ``current_A``) to a 1-D float array.
    source : str
        Where the run came from (a file name, ``<upload>``, ``<simulated>``).
    """

    columns: dict[str, np.ndarray]
    source: str = "<memory>"
    meta: dict[str, object] = field(default_factory=dict)

    def __getitem__(self, name: str) -> np.ndarray:
        try:
            return self.columns[name]
        except KeyError:
            raise RunFileError(
                f"{self.source}: no column {name!r}; it has {', '.join(self.columns)}"
            ) from None

    def __contains__(self, name: object) -> bool:
        return name in self.columns

    def __len__(self) -> int:
        return len(self.columns["time_s"])

    @property
    def time_s(self) -> np.ndarray:
        """Sample times, s."""
        return self.columns["time_s"]

    @property
    def dt_s(self) -> float:
        """Sample period, s (median of the differences of ``time_s``)."""
        return float(np.median(np.diff(self.time_s)))


def check_columns(columns: Mapping[str, np.ndarray], kind: RunKind, source: str) -> Run:
    """Validate arrays as a run of ``kind`` and return the :class:`Run`.

    Raises
    ------
    RunFileError
        Missing column, unequal lengths, non-finite value, too few samples, time not
        increasing or not uniform within 1 %.
    """
    required, optional = _kind_columns(kind)
    missing = [name for name in required if name not in columns]
    if missing:
        raise RunFileError(
            f"{source}: missing column(s) {', '.join(missing)}; a {kind} run needs "
            f"{', '.join(required)} (optional: {', '.join(optional)})"
        )
    wanted = [name for name in (*required, *optional) if name in columns]
    arrays = {name: np.asarray(columns[name], dtype=float).reshape(-1) for name in wanted}
    n = len(arrays["time_s"])
    for name, values in arrays.items():
        if len(values) != n:
            raise RunFileError(
                f"{source}: column {name} has {len(values)} samples, time_s has {n}"
            )
        bad = np.flatnonzero(~np.isfinite(values))
        if bad.size:
            raise RunFileError(
                f"{source}: row {bad[0] + 2}, column {name}: value {values[bad[0]]} is not "
                "finite; every cell must be a finite number"
            )
    if n < MIN_SAMPLES:
        raise RunFileError(f"{source}: rows 2-{n + 1}, column time_s: {n} samples; a run "
                           f"needs at least {MIN_SAMPLES}")
    _check_time(arrays["time_s"], source)
    return Run(arrays, source)


def _kind_columns(kind: str) -> tuple[tuple[str, ...], tuple[str, ...]]:
    if kind not in COLUMNS:
        raise RunFileError(f"run kind must be one of {', '.join(COLUMNS)}, not {kind!r}")
    return COLUMNS[kind]


def _check_time(time_s: np.ndarray, source: str) -> None:
    steps = np.diff(time_s)
    not_increasing = np.flatnonzero(steps <= 0)
    if not_increasing.size:
        row = not_increasing[0] + 3  # header is row 1, first sample row 2
        raise RunFileError(
            f"{source}: row {row}, column time_s: {time_s[row - 2]} does not increase "
            f"after {time_s[row - 3]}; time_s must be strictly increasing"
        )
    period = float(np.median(steps))
    if period < MIN_PERIOD_S:
        raise RunFileError(
            f"{source}: column time_s: sample period {period:.3g} s is shorter than "
            f"{MIN_PERIOD_S:g} s; time_s must be in seconds"
        )
    deviation = np.abs(steps - period) / period
    worst = int(np.argmax(deviation))
    if deviation[worst] > PERIOD_TOLERANCE:
        raise RunFileError(
            f"{source}: row {worst + 3}, column time_s: step {steps[worst]:.6g} s differs "
            f"{100 * deviation[worst]:.1f} % from the sample period {period:.6g} s; samples "
            f"must be uniform within {100 * PERIOD_TOLERANCE:.0f} % (resample the run)"
        )


def parse_run(text: str, kind: RunKind, source: str = "<upload>") -> Run:
    """Parse CSV text as a run of ``kind`` (CONTRACT §1). All or nothing.

    A file of plain numbers is read by NumPy's C reader; anything it does not take as
    such (quotes, blank cells, a short row, a cell that is no number, a value that is
    not finite) is read again row by row, so that the error names the row and column.
    """
    _kind_columns(kind)
    fast = _parse_plain(text, kind)
    if fast is not None:
        return check_columns(fast, kind, source)
    reader = csv.reader(io.StringIO(text))
    try:
        return _parse_rows(reader, kind, source)
    except csv.Error as exc:  # e.g. a field past the csv module's size limit
        raise RunFileError(
            f"{source}: row {reader.line_num}: not readable as CSV ({exc})"
        ) from exc


def _parse_plain(text: str, kind: RunKind) -> dict[str, np.ndarray] | None:
    """The columns of ``kind`` of a CSV of finite numbers only, read in one pass; None
    for anything else (the row-by-row reader then names what is wrong)."""
    required, optional = _kind_columns(kind)
    first_line, _, body = text.partition("\n")
    header = [name.strip() for name in next(csv.reader([first_line]), [])]
    index = {name: col for col, name in enumerate(header) if name in (*required, *optional)}
    if '"' in first_line or any(name not in index for name in required) or not body.strip():
        return None
    try:
        table = np.loadtxt(io.StringIO(body), delimiter=",", comments=None, ndmin=2,
                           usecols=tuple(index.values()), dtype=float)
    except ValueError:
        return None
    if table.shape[1] != len(index) or not np.isfinite(table).all():
        return None
    return {name: table[:, j].copy() for j, name in enumerate(index)}


def _parse_rows(reader: Iterator[list[str]], kind: RunKind, source: str) -> Run:
    required, optional = _kind_columns(kind)
    try:
        header = [name.strip() for name in next(reader)]
    except StopIteration:
        raise RunFileError(f"{source}: empty file; expected a header row") from None
    index = {name: col for col, name in enumerate(header) if name in (*required, *optional)}
    missing = [name for name in required if name not in index]
    if missing:
        raise RunFileError(
            f"{source}: row 1 (header): missing column(s) {', '.join(missing)} in header "
            f"{','.join(header)!r}; a {kind} run needs {', '.join(required)}"
        )
    values: dict[str, list[float]] = {name: [] for name in index}
    for row_number, row in enumerate(reader, start=2):
        if not row or all(not cell.strip() for cell in row):
            continue
        for name, col in index.items():
            cell = row[col].strip() if col < len(row) else ""
            try:
                number = float(cell)
            except ValueError:
                raise RunFileError(
                    f"{source}: row {row_number}, column {name}: {cell!r} is not a number"
                ) from None
            if not math.isfinite(number):
                raise RunFileError(
                    f"{source}: row {row_number}, column {name}: {cell!r} is not finite; "
                    "every cell must be a finite number"
                )
            values[name].append(number)
    return check_columns({k: np.array(v) for k, v in values.items()}, kind, source)


def read_text(path: Path) -> str:
    """The UTF-8 text of a CSV file; RunFileError naming the file when it can't be read."""
    try:
        return path.read_text(encoding="utf-8-sig")
    except OSError as exc:
        raise RunFileError(f"{path}: cannot read: {exc.strerror}") from exc
    except UnicodeDecodeError as exc:
        raise RunFileError(f"{path}: not a UTF-8 text file ({exc.reason})") from exc


def read_run(path: str | Path, kind: RunKind = "single") -> Run:
    """Read a run file of ``kind`` from ``path``. All or nothing."""
    path = Path(path)
    return parse_run(read_text(path), kind, str(path))


def format_run(columns: Mapping[str, Sequence[float] | np.ndarray]) -> str:
    """CSV text of ``columns`` (header row, then one row a sample, 9 significant digits)."""
    names = list(columns)
    table = np.column_stack([np.asarray(columns[name], dtype=float) for name in names])
    buffer = io.StringIO()
    buffer.write(",".join(names) + "\n")
    np.savetxt(buffer, table, delimiter=",", fmt="%.9g")
    return buffer.getvalue()


def write_run(path: str | Path, columns: Mapping[str, Sequence[float] | np.ndarray]) -> Path:
    """Write ``columns`` as a run file, atomically (a crash leaves the old file or none)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    partial = path.with_name(path.name + ".partial")
    partial.write_text(format_run(columns), encoding="utf-8")
    partial.replace(path)
    return path
