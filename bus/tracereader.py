"""Reading CAN traces back: drive TPDOs aligned by SYNC, or any frames through a DBC.

Traces are read with python-can's log readers (``.log`` candump, ``.asc``, ``.blf``).

:func:`decode_trace` rebuilds what the master recorded: each SYNC opens a window, the TPDOs
that follow it in the trace fill it, and the same :class:`~bus.sampler.Sampler` that
recorded the run counts what is lost or duplicated and converts raw values to SI units.
Which objects a TPDO carries comes, in this order, from

1. the trace's own SDO traffic (expedited downloads to 0x1800-0x1803 and 0x1A00-0x1A03,
   and the answers to expedited uploads of them), as a master configuring the drive wrote it;
2. the drive's EDS, where it gives a non-empty default mapping;
3. the mapping motorstand's master writes to a drive of that EDS (:func:`bus.drive.tpdo_objects`).

The RPDOs before a SYNC give each drive's target for that SYNC's window (the last one
before it; a drive holds its target until the next) where they carry a target that a run
file has a column for (:data:`bus.sampler.TARGET_FIELDS`: the target velocity). Their
mapping comes from the same three places as the TPDOs' (0x1400-0x1403 and 0x1600-0x1603;
motorstand's master maps RPDO1 to the controlword and the target of the drive's mode, and
the speed mode's is the only one of six bytes).

Each drive's units come from the scaling given, else from the trace's SDO traffic (the
answers to the master's reads of the motor rated current 0x6075 and the position encoder
resolution 0x608F, or writes of them), else the defaults (:class:`~bus.eds.Scaling`).

The SYNC period is the communication cycle period 0x1006 written over SDO when the trace
has it, else the one given, else the median spacing of the SYNC stamps (which is wall time,
not stand time, for a lockstep run: the result warns).

Any frame a DBC describes: :func:`bus.dbc.decode_dbc`.
"""

from __future__ import annotations

import math
from collections.abc import Collection, Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import can
import canopen
import numpy as np

from bus import cia402
from bus.cia301 import (
    COMMUNICATION_CYCLE_PERIOD,
    RPDO_BASES,
    RPDO_COMMUNICATION,
    RPDO_MAPPING,
    SDO_REQUEST_BASE,
    SDO_RESPONSE_BASE,
    TPDO_BASES,
)
from bus.device import eds_identity, is_simulated
from bus.drive import TPDO_COMM, TPDO_MAP, tpdo_objects
from bus.eds import MA_PER_A, Scaling, load_od
from bus.pdo import COB_ID_INVALID, Layout, entries_for
from bus.sampler import TARGET_FIELDS, Sampler, Samples
from bus.sync import SYNC_COB_ID
from bus.trace import TRACE_SUFFIXES
from stand.errors import InputError

#: SDO command specifiers (CiA 301 §7.2.4.3), from canopen.
_CCS_DOWNLOAD = canopen.sdo.constants.REQUEST_DOWNLOAD >> 5
_CCS_UPLOAD = canopen.sdo.constants.REQUEST_UPLOAD >> 5
_SCS_UPLOAD = canopen.sdo.constants.RESPONSE_UPLOAD >> 5


def read_frames(path: str | Path) -> list[can.Message]:
    """Every frame of a ``.log``, ``.asc`` or ``.blf`` trace, in file order.

    Raises
    ------
    InputError
        A missing file, another suffix, or a file python-can cannot parse.
    """
    path = Path(path)
    if not path.is_file():
        raise InputError(f"{path}: no such file")
    if path.suffix.lower() not in TRACE_SUFFIXES:
        raise InputError(f"{path}: a CAN trace must end in {', '.join(TRACE_SUFFIXES)}")
    try:
        with can.LogReader(str(path)) as reader:
            frames = list(reader)
    except (ValueError, OSError, can.CanError, IndexError, KeyError) as exc:
        raise InputError(f"{path}: not a readable {path.suffix} trace "
                         f"({type(exc).__name__}: {exc})") from exc
    if not frames:
        raise InputError(f"{path}: the trace holds no frames")
    return frames


def sdo_values(frames: list[can.Message]) -> dict[int, dict[tuple[int, int], int]]:
    """Node id → ``{(index, subindex): value}`` of every expedited SDO download request and
    every expedited upload answer in ``frames`` (the last one wins)."""
    values: dict[int, dict[tuple[int, int], int]] = {}
    for msg in frames:
        can_id, data = msg.arbitration_id, bytes(msg.data)
        if msg.is_extended_id or len(data) < 8 or can_id & 0x7F == 0:
            continue
        base, node = can_id & 0x780, can_id & 0x7F
        command = data[0]
        expedited = command & canopen.sdo.constants.EXPEDITED
        if not expedited or (base, command >> 5) not in ((SDO_REQUEST_BASE, _CCS_DOWNLOAD),
                                                         (SDO_RESPONSE_BASE, _SCS_UPLOAD)):
            continue
        size = 4 - ((command >> 2) & 0x3) if command & canopen.sdo.constants.SIZE_SPECIFIED else 4
        key = (int.from_bytes(data[1:3], "little"), data[3])
        values.setdefault(node, {})[key] = int.from_bytes(data[4:4 + size], "little")
    return values


def _default(od: canopen.ObjectDictionary, index: int, subindex: int) -> int:
    var = od.get_variable(index, subindex)
    try:
        return int(var.default or 0) if var is not None else 0
    except (TypeError, ValueError):
        return 0


def _mapped(node: int, od: canopen.ObjectDictionary, sdo: Mapping[tuple[int, int], int],
            seen: Collection[int], comm_base: int, map_base: int, cob_bases: Sequence[int]
            ) -> Iterator[tuple[int, int, list[int] | None]]:
    """(PDO number, COB-ID, mapping entries) of each PDO of ``node`` (TPDOs or RPDOs, by the
    object and COB-ID bases) whose COB-ID occurs in the trace: the entries as the trace's SDO
    traffic wrote them, else the EDS's defaults, else None. The simulated drive's EDS holds
    CiA 402's power-on mapping, which motorstand's master always replaces: for it, None."""
    ours = _is_simulated_eds(od)
    for p, base in enumerate(cob_bases):
        comm, mapping = comm_base + p, map_base + p
        cob = sdo.get((comm, 1), _default(od, comm, 1) or base + node)
        if cob & COB_ID_INVALID or (cob & 0x7FF) not in seen:
            continue
        entries: list[int] | None = None
        if (mapping, 0) in sdo:
            entries = [sdo.get((mapping, k), 0) for k in range(1, sdo[(mapping, 0)] + 1)]
        elif _default(od, mapping, 0) and not ours:
            entries = [_default(od, mapping, k) for k in range(1, _default(od, mapping, 0) + 1)]
        yield p, cob & 0x7FF, entries


def _tpdos(node: int, od: canopen.ObjectDictionary, sdo: Mapping[tuple[int, int], int],
           seen: set[int], current_mean: tuple[int, int] | None = None
           ) -> Iterator[tuple[int, Layout]]:
    """(COB-ID, layout) of each TPDO of ``node`` whose COB-ID occurs in the trace; where
    neither the trace nor the EDS maps it, the mapping motorstand's master writes (with
    the period-mean current object ``current_mean`` in TPDO3)."""
    standard = tpdo_objects(od, current_mean=current_mean)
    for p, cob, entries in _mapped(node, od, sdo, seen, TPDO_COMM, TPDO_MAP, TPDO_BASES):
        if entries is None and p >= len(standard):
            continue
        yield cob, Layout.from_entries(od, entries if entries is not None
                                       else entries_for(od, standard[p]))


def _targets(node: int, od: canopen.ObjectDictionary, sdo: Mapping[tuple[int, int], int],
             lengths: Mapping[int, int]) -> Iterator[tuple[int, int, Layout]]:
    """(COB-ID, target object, layout) of each RPDO of ``node`` in the trace that carries a
    target of :data:`~bus.sampler.TARGET_FIELDS`: mapped over SDO in the trace, by the EDS's
    defaults, or, on the simulated drive, as motorstand's master maps RPDO1 (controlword and
    the target of the one mode whose PDO has the length of the frames, ``lengths``: COB-ID →
    bytes of its first frame)."""
    ours = _is_simulated_eds(od)
    for p, cob, entries in _mapped(node, od, sdo, lengths, RPDO_COMMUNICATION, RPDO_MAPPING,
                                   RPDO_BASES):
        if entries is not None:
            candidates = [entries]
        elif p == 0 and ours:
            candidates = [entries_for(od, [cia402.CONTROLWORD, index])
                          for index, _, _ in cia402.TARGET_OBJECT.values() if index in od]
        else:
            continue
        fitting = [layout for layout in (Layout.from_entries(od, e) for e in candidates)
                   if len(candidates) == 1 or layout.packer.size == lengths[cob]]
        if len(fitting) != 1:
            continue
        layout = fitting[0]
        for index in layout.indices:
            if index in TARGET_FIELDS:
                yield cob, index, layout
                break


def _units(sdo: Mapping[tuple[int, int], int]) -> Scaling | None:
    """A drive's units from its rated current 0x6075 and encoder resolution 0x608F in the
    trace's SDO traffic; None unless both are there (and a whole number of increments per
    revolution)."""
    rated_mA = sdo.get((cia402.RATED_CURRENT, 0))
    resolution = cia402.POSITION_ENCODER_RESOLUTION
    increments = sdo.get((resolution, cia402.ENCODER_INCREMENTS))
    revolutions = sdo.get((resolution, cia402.MOTOR_REVOLUTIONS))
    if not rated_mA or not increments or not revolutions or increments % revolutions:
        return None
    return Scaling(counts_per_rev=increments // revolutions, rated_current_A=rated_mA / MA_PER_A)


def _is_simulated_eds(od: canopen.ObjectDictionary) -> bool:
    identity = eds_identity(od)
    return identity is not None and is_simulated(identity)


@dataclass
class DecodedTrace:
    """The samples a trace holds, and how they were found.

    Attributes
    ----------
    samples : Samples
        SYNC-aligned samples of each drive, SI units (NaN where a TPDO is missing).
    period_s : float
        SYNC period, s.
    period_from : str
        ``sdo 0x1006``, ``given`` or ``sync stamps``.
    mapping_from : dict
        Node id → ``sdo``, ``eds`` or ``motorstand master`` (where its TPDO mapping came from).
    warnings : list of str
    units_from : dict
        Node id → ``given``, ``sdo 0x6075 0x608F`` or ``default`` (where its units came from).
    """

    samples: Samples
    period_s: float
    period_from: str
    mapping_from: dict[int, str]
    warnings: list[str] = field(default_factory=list)
    units_from: dict[int, str] = field(default_factory=dict)


def decode_trace(path: str | Path, *, scaling: Scaling | None = None,
                 eds: str | Path | None = None, node: int | None = None,
                 period_s: float | None = None,
                 current_mean: tuple[int, int] | None = None) -> DecodedTrace:
    """The drive samples of a CAN trace (see the module docstring).

    Parameters
    ----------
    path : str or Path
        ``.log``, ``.asc`` or ``.blf`` trace.
    scaling : Scaling, optional
        Units of the drives' raw values (default: each drive's from the trace's SDO traffic,
        0x6075 and 0x608F, else the :class:`~bus.eds.Scaling` defaults).
    eds : path, optional
        The drives' EDS (default: the simulated drive's).
    node : int, optional
        Decode this node only (default: every node with TPDOs in the trace).
    period_s : float, optional
        SYNC period, s, when the trace does not carry 0x1006.
    current_mean : (int, int), optional
        The drives' object (index, subindex) holding their current averaged over each
        period (a motor profile's ``drive.current_mean_object``; its unit is
        ``scaling.current_mean_unit_A``): decoded as ``current_mean_A``, and mapped into
        TPDO3 where neither the trace nor the EDS maps it.

    Raises
    ------
    InputError
        An unreadable trace, no SYNC, no TPDO of a known node, or a bad ``node``/``period_s``.
    """
    frames = read_frames(path)
    if node is not None and not 1 <= node <= 127:
        raise InputError(f"node must be a CANopen node id 1..127, got {node}")
    if period_s is not None and not period_s > 0:
        raise InputError(f"period_s must be > 0 s, got {period_s}")
    syncs = [m for m in frames if m.arbitration_id == SYNC_COB_ID and not m.is_extended_id]
    if not syncs:
        raise InputError(f"{path}: no SYNC frame (COB-ID 0x080) in the trace; samples are "
                         "aligned by SYNC")
    lengths: dict[int, int] = {}  # COB-ID → bytes of its first frame
    for m in frames:
        if not m.is_extended_id:
            lengths.setdefault(m.arbitration_id, len(m.data))
    seen = set(lengths)
    sdo = sdo_values(frames)
    candidates = sorted({cob - base for cob in seen for base in TPDO_BASES
                         if 1 <= cob - base <= 127} | {n for n, v in sdo.items()
                                                        if any(k[0] in range(TPDO_COMM, TPDO_COMM + 4)
                                                               for k in v)})
    nodes = [node] if node is not None else candidates
    tpdos: dict[int, tuple[int, int, Layout]] = {}
    rpdos: dict[int, tuple[int, int, Layout]] = {}  # COB-ID → (drive, field in the PDO, layout)
    targets: list[int | None] = []
    node_ids: list[int] = []
    simulated: list[bool] = []  # the drive's EDS is the simulated drive's
    mapping_from: dict[int, str] = {}
    for n in nodes:
        od = load_od(eds, n)
        found = list(_tpdos(n, od, sdo.get(n, {}), seen, current_mean))
        if not found or any(cob in tpdos for cob, _ in found):
            continue
        target = next(_targets(n, od, sdo.get(n, {}), lengths), None)
        if target is not None and target[0] not in tpdos:
            cob, index, layout = target
            rpdos[cob] = (len(node_ids), layout.indices.index(index), layout)
        targets.append(target[1] if target is not None else None)
        own = sdo.get(n, {})
        mapping_from[n] = ("sdo" if any((TPDO_MAP + p, 0) in own for p in range(4))
                           else "eds" if _default(od, TPDO_MAP, 0) and not _is_simulated_eds(od)
                           else "motorstand master")
        for p, (cob, layout) in enumerate(found):
            tpdos[cob] = (len(node_ids), p, layout)
        node_ids.append(n)
        simulated.append(_is_simulated_eds(od))
    if not node_ids:
        raise InputError(f"{path}: no TPDO of {'node ' + str(node) if node else 'any node'} "
                         f"in the trace (COB-IDs seen: {', '.join(f'0x{c:03X}' for c in sorted(seen))})")
    warnings: list[str] = []
    cycles = [v[(COMMUNICATION_CYCLE_PERIOD, 0)] for v in sdo.values()
              if v.get((COMMUNICATION_CYCLE_PERIOD, 0))]
    if cycles:
        period, period_from = cycles[-1] * 1e-6, "sdo 0x1006"
    elif period_s is not None:
        period, period_from = float(period_s), "given"
    else:
        stamps = np.array([m.timestamp for m in syncs])
        period = float(np.median(np.diff(stamps))) if len(stamps) > 1 else math.nan
        period_from = "sync stamps"
        warnings.append(f"the SYNC period {period:.6g} s is the median spacing of the SYNC "
                        "stamps: wall time, not stand time, if the run was in lockstep; give "
                        "the period when it is known")
        if not period > 0:
            raise InputError(f"{path}: one SYNC and no period; give the SYNC period")
    own_units = {n: _units(sdo.get(n, {})) for n in node_ids}
    units_from = {n: "given" if scaling is not None else "default" if own_units[n] is None
                  else "sdo 0x6075 0x608F" for n in node_ids}
    scalings = [scaling or own_units[n] or Scaling() for n in node_ids]
    for n, units in own_units.items():
        if scaling is not None and units is not None and units != scaling:
            warnings.append(f"node {n}: the trace says {units.counts_per_rev} counts per revolution "
                            f"and {units.rated_current_A:g} A rated current (0x608F, 0x6075); the "
                            "given units are used")
    # The trace's order says which SYNC a TPDO answers: each TPDO is judged against the
    # stamp of the SYNC before it, and no synchronous window bounds the delay (a lockstep
    # run's stamps are wall time).
    sampler = Sampler(tpdos, node_ids, scalings, len(syncs), period, window_s=math.inf,
                      targets=targets,
                      current_means=[current_mean] * len(node_ids),
                      simulated=simulated)
    k, stamp = -1, 0.0
    held: dict[int, int] = {}  # drive → the raw target of its last RPDO
    for msg in frames:
        can_id = msg.arbitration_id
        if msg.is_extended_id:
            continue
        if can_id == SYNC_COB_ID:
            k, stamp = k + 1, msg.timestamp
            counter = msg.data[0] if len(msg.data) else 0
            sampler.open(k, stamp, counter)
            sampler.sent(stamp, counter)
            for d, raw in held.items():
                sampler.command(d, k, raw)
        elif can_id in tpdos:
            sampler.on_tpdo(can_id, bytearray(msg.data), stamp)
        elif can_id in rpdos:
            d, position, layout = rpdos[can_id]
            if len(msg.data) < layout.packer.size:
                raise InputError(f"{path}: RPDO 0x{can_id:03X} at {msg.timestamp:.6f} s has "
                                 f"{len(msg.data)} bytes; its mapping needs {layout.packer.size}")
            held[d] = layout.unpack(msg.data)[position]
    sampler.close()
    samples = sampler.result(len(syncs))
    for drive in samples.drives:
        for name in TARGET_FIELDS.values():
            values = drive.columns.get(name)
            if values is not None and np.isnan(values[drive.valid]).any():
                del drive.columns[name]
                warnings.append(f"node {drive.node_id}: SYNCs before its first RPDO; its "
                                f"{name} is left out")
    for drive in samples.drives:
        if drive.short:
            warnings.append(f"node {drive.node_id}: {drive.short} TPDOs shorter than their "
                            "mapping; those samples are left out")
    if not samples.complete:
        warnings.append(f"TPDOs missing in the trace: {samples.lost} (node: count); those "
                        "samples are left out")
    return DecodedTrace(samples, period, period_from, mapping_from, warnings, units_from)


__all__ = ["DecodedTrace", "decode_trace", "read_frames", "sdo_values"]
