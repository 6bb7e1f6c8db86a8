"""CAN traces through a DBC: every frame the DBC describes, decoded by cantools.

:func:`decode_dbc` gives one variable per signal (``Message.Signal``) and its times
(``Message.t``, s from the trace's first frame); the frames come from
:func:`bus.tracereader.read_frames`.
"""

from __future__ import annotations

from pathlib import Path
from typing import cast

import numpy as np

from bus.tracereader import read_frames
from stand.errors import InputError


def decode_dbc(path: str | Path, dbc: str | Path) -> dict[str, np.ndarray]:
    """Every signal of the frames of trace ``path`` that the DBC ``dbc`` describes.

    Returns ``{"Message.Signal": values, "Message.t": times_s}`` (times from the trace's
    first frame, s); a signal name found in one message only is also given bare.

    Raises
    ------
    InputError
        An unreadable trace or DBC, or a trace with no frame the DBC knows.
    """
    import cantools

    try:
        database = cantools.database.load_file(str(dbc))
    except (OSError, cantools.database.UnsupportedDatabaseFormatError) as exc:
        raise InputError(f"{dbc}: not a readable DBC file ({exc})") from exc
    if not isinstance(database, cantools.database.can.Database):
        raise InputError(f"{dbc}: a diagnostics database, not a CAN database (DBC, ARXML, KCD, SYM)")
    frames = read_frames(path)
    t0 = frames[0].timestamp
    columns: dict[str, list[float]] = {}
    for msg in frames:
        try:
            message = database.get_message_by_frame_id(msg.arbitration_id)
        except KeyError:
            continue
        try:
            decoded = cast(dict[str, float], message.decode(bytes(msg.data), decode_choices=False))
        except (cantools.database.DecodeError, ValueError) as exc:
            raise InputError(f"{path}: frame 0x{msg.arbitration_id:X} at {msg.timestamp:.6f} s "
                             f"does not decode as {message.name}: {exc}") from exc
        columns.setdefault(f"{message.name}.t", []).append(msg.timestamp - t0)
        for name, value in decoded.items():
            columns.setdefault(f"{message.name}.{name}", []).append(float(value))
    if not columns:
        raise InputError(f"{path}: no frame of the trace is described by {dbc}")
    variables = {name: np.asarray(values) for name, values in columns.items()}
    bare: dict[str, list[str]] = {}
    for name in variables:
        _, _, signal = name.partition(".")
        if signal != "t":
            bare.setdefault(signal, []).append(name)
    for signal, names in bare.items():
        if len(names) == 1 and signal not in variables:
            variables[signal] = variables[names[0]]
    return variables


__all__ = ["decode_dbc"]
