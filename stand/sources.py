"""Reading the files a lab brings, by suffix, into named numeric variables.

| suffix | read as | by |
|---|---|---|
| ``.mat`` | every numeric variable, ``struct.field`` inside structs | scipy |
| ``.csv .txt .tsv .dat`` | one variable per column, the table as ``data`` | :mod:`stand.delimited` |
| ``.mf4 .mdf`` | one variable per channel, header properties as metadata | :mod:`stand.mdf` |
| ``.log .asc .blf`` | run columns of the drive TPDOs by SYNC; or DBC signals | :mod:`bus.tracereader` |

Only this module and the readers it calls touch files; the mapping of variables to run
columns is :mod:`stand.importer`'s.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from stand.delimited import TableFormat, read_table
from stand.errors import InputError
from stand.mdf import MDF_SUFFIXES, read_mdf
from stand.runfile import RunKind

MAT_SUFFIXES = (".mat",)
CSV_SUFFIXES = (".csv", ".txt", ".tsv", ".dat")
TRACE_SUFFIXES = (".log", ".asc", ".blf")
SUFFIXES = MAT_SUFFIXES + CSV_SUFFIXES + MDF_SUFFIXES + TRACE_SUFFIXES


@dataclass(frozen=True)
class ReadOptions:
    """How to read a file beyond its suffix.

    Parameters
    ----------
    table : TableFormat
        Delimited text: decimal mark, rows to skip.
    kind : {'single', 'step', 'reducer'}
        CAN traces: which run columns to build from the drives' samples.
    motor : str or None
        CAN traces: motor profile (name or path) giving the encoder counts per revolution
        and the rated current (default: the drives' 0x608F and 0x6075 in the trace), and
        the drive's period-mean current object where it names one.
    eds : str or None
        CAN traces: the drives' EDS (default: the simulated drive's).
    node : int or None
        CAN traces: decode this node only.
    period_s : float or None
        CAN traces: SYNC period, s, when the trace does not carry 0x1006.
    dbc : str or None
        CAN traces: decode every frame the DBC describes instead of CANopen PDOs.
    """

    table: TableFormat = TableFormat()
    kind: RunKind = "single"
    motor: str | None = None
    eds: str | None = None
    node: int | None = None
    period_s: float | None = None
    dbc: str | None = None


@dataclass
class Source:
    """What a file holds: ``variables`` by name, its ``meta`` (MF4 header properties,
    trace decoding facts), ``notes`` on how it was read, and ``warnings``."""

    variables: dict[str, np.ndarray]
    meta: dict[str, Any] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)



def _mat_variables(path: Path) -> dict[str, np.ndarray]:
    from scipy import io as sio
    from scipy.io.matlab import MatReadError

    try:
        raw = sio.loadmat(str(path), simplify_cells=True)
    except NotImplementedError as exc:  # MATLAB v7.3 files are HDF5
        raise InputError(
            f"{path}: MATLAB v7.3 (HDF5) files are not supported; save with "
            "save(..., '-v7') or export CSV"
        ) from exc
    except (ValueError, TypeError, OSError, MatReadError) as exc:  # MatReadError: empty file
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




def _trace(path: Path, options: ReadOptions) -> Source:
    from bus.dbc import decode_dbc
    from bus.simstand import scaling_for
    from bus.tracereader import decode_trace
    from stand.controller import run_columns
    from stand.profiles import load_motor

    if options.dbc:
        return Source(decode_dbc(path, options.dbc), {"dbc": options.dbc})
    motor = load_motor(options.motor) if options.motor else None
    decoded = decode_trace(path, scaling=scaling_for(motor) if motor else None, eds=options.eds,
                           node=options.node, period_s=options.period_s,
                           current_mean=motor.drive.current_mean() if motor else None)
    drives = len(decoded.samples.drives)
    if (options.kind == "reducer") != (drives == 2):
        raise InputError(f"{path}: the trace holds {drives} drive(s) with TPDOs "
                         f"({', '.join(map(str, decoded.mapping_from))}); a {options.kind} run "
                         f"needs {'two' if options.kind == 'reducer' else 'one'} (give --node)")
    warnings = list(decoded.warnings)
    unknown = [str(n) for n, origin in decoded.units_from.items() if origin == "default"]
    if unknown:
        warnings.append(f"node {', '.join(unknown)}: no --motor profile and no 0x6075/0x608F in "
                        "the trace: positions and currents use the default scaling (2^20 counts "
                        "per revolution, rated current 1 A)")
    meta = {"period_s": decoded.period_s, "period_from": decoded.period_from,
            "mapping_from": decoded.mapping_from, "units_from": decoded.units_from,
            "lost": decoded.samples.lost, "motor": options.motor}
    return Source(run_columns(options.kind, decoded.samples), meta, warnings=warnings)


def load_source(path: str | Path, options: ReadOptions | None = None) -> Source:
    """The variables of a MAT, delimited-text, MDF 4 or CAN trace file (module docstring).

    MAT files: every numeric variable (``struct.field`` for fields of structs; MATLAB column
    and row vectors become 1-D, 1×1 become scalars). Text files: one 1-D variable per header
    column, and the whole table as ``data``.

    Raises
    ------
    InputError
        A missing or unreadable file, an unknown suffix, a non-numeric cell, a trace that
        does not decode.
    """
    path = Path(path)
    options = options or ReadOptions()
    if not path.is_file():
        raise InputError(f"{path}: no such file")
    suffix = path.suffix.lower()
    if suffix in MAT_SUFFIXES:
        return Source(_mat_variables(path))
    if suffix in CSV_SUFFIXES:
        variables, notes = read_table(path, options.table)
        return Source(variables, notes=notes)
    if suffix in MDF_SUFFIXES:
        variables, meta = read_mdf(path)
        return Source(variables, dict(meta))
    if suffix in TRACE_SUFFIXES:
        return _trace(path, options)
    raise InputError(f"{path}: unknown file type {suffix or '(none)'}; expected {', '.join(SUFFIXES)}")
