"""ASAM MDF 4 (``.mf4``) files of runs, through asammdf.

:func:`write_mdf` writes a run's columns as channels of one channel group, with their units
(read off the column names of CONTRACT §1), ``time_s`` as the master channel, and the run's
metadata (profile, motor, seed, ...) as common properties of the file header comment, the
place MDF 4 tools show them. :func:`read_mdf` gives back every channel by name, as
:func:`stand.importer.load_variables` does for MAT and CSV files.
"""

from __future__ import annotations

import logging
import re
from collections.abc import Mapping
from pathlib import Path
from typing import Any, cast
from xml.sax.saxutils import escape, unescape

import numpy as np

from stand.errors import InputError

MDF_SUFFIXES = (".mf4", ".mdf")
#: MDF version written (4.10: the version most tools read).
MDF_VERSION = "4.10"
#: Column-name endings of CONTRACT §1 and their units, longest first.
UNITS = (("_rad_s", "rad/s"), ("_rad", "rad"), ("_A", "A"), ("_V", "V"), ("_s", "s"))

_PROPERTY = re.compile(r'<e name="(?P<name>[^"]+)"[^>]*>(?P<value>[^<]*)</e>')


def unit_of(column: str) -> str:
    """The SI unit a run column's name carries (``velocity_rad_s`` → ``rad/s``), or ``""``."""
    return next((unit for end, unit in UNITS if column.endswith(end)), "")


def _comment(meta: Mapping[str, object]) -> str:
    properties = "".join(f'<e name="{escape(str(k))}">{escape(str(v))}</e>'
                         for k, v in meta.items())
    return (f"<HDcomment><TX>motorstand run</TX>"
            f"<common_properties>{properties}</common_properties></HDcomment>")


def write_mdf(path: str | Path, columns: Mapping[str, np.ndarray],
              meta: Mapping[str, object] | None = None) -> Path:
    """Write run ``columns`` (with ``time_s``) to an MDF 4 file.

    Parameters
    ----------
    path : str or Path
        Output file, ``.mf4``.
    columns : mapping of str to ndarray
        Run columns (CONTRACT §1), ``time_s`` in s; every other column becomes a float64
        channel with the unit its name carries.
    meta : mapping, optional
        Metadata stored as header properties (e.g. ``profile``, ``motor``, ``seed``).

    Raises
    ------
    InputError
        No ``time_s`` column or a path that does not end in ``.mf4``.
    """
    from asammdf import MDF, Signal

    path = Path(path)
    if path.suffix.lower() not in MDF_SUFFIXES:
        raise InputError(f"{path}: an MDF 4 file must end in .mf4")
    if "time_s" not in columns:
        raise InputError(f"{path}: the run has no time_s column to use as the master channel")
    time_s = np.asarray(columns["time_s"], dtype=float)
    signals = [Signal(np.asarray(values, dtype=float), time_s, name=name, unit=unit_of(name))
               for name, values in columns.items() if name != "time_s"]
    mdf = MDF(version=MDF_VERSION)
    try:
        mdf.append(signals, comment="motorstand run")
        mdf.header.comment = _comment(dict(meta or {}))
        path.parent.mkdir(parents=True, exist_ok=True)
        mdf.save(path, overwrite=True)
    finally:
        mdf.close()
    return path


def read_mdf(path: str | Path) -> tuple[dict[str, np.ndarray], dict[str, str]]:
    """The channels of an MDF file by name, and the header's properties.

    Every channel group's master channel is also given as ``time_s`` when its unit is s (the
    first such group wins), so a run written by :func:`write_mdf` maps back by name. A name
    that occurs in several groups keeps the first group's channel.

    Raises
    ------
    InputError
        A file asammdf cannot read.
    """
    from asammdf import MDF

    path = Path(path)
    logging.getLogger("asammdf").setLevel(logging.ERROR)  # it warns on every foreign block
    try:
        mdf = MDF(path)
    except Exception as exc:  # asammdf raises bare Exception subclasses of many kinds
        raise InputError(f"{path}: not a readable MDF file ({type(exc).__name__}: {exc})") from exc
    variables: dict[str, np.ndarray] = {}
    try:
        for group_index, group in enumerate(mdf.groups):
            for channel_index, channel in enumerate(cast(Any, group).channels):
                if channel.name in variables:
                    continue
                signal = mdf.get(group=group_index, index=channel_index, raw=False)
                samples = np.asarray(signal.samples)
                if samples.dtype.kind not in "biuf" or samples.ndim != 1:
                    continue  # byte arrays, strings, structures: not a run column
                is_master = mdf.masters_db.get(group_index) == channel_index
                variables[channel.name] = samples.astype(float)
                if is_master and signal.unit == "s":
                    variables.setdefault("time_s", samples.astype(float))
        comment = str(mdf.header.comment or "")
    finally:
        mdf.close()
    meta = {unescape(m["name"]): unescape(m["value"]) for m in _PROPERTY.finditer(comment)}
    return variables, meta
