"""An independent reading of CANopen frames (CiA 301) captured by candump.

Written from the standard, not from bus/: it decodes NMT, SYNC, SDO, heartbeat and PDO
frames from raw identifiers and bytes, so the checks in test_master.py compare what our
master really put on the wire against CiA 301, not against our own encoder.

Predefined connection set (CiA 301 §7.3.5), node id n:
NMT 0x000, SYNC 0x080, EMCY 0x080+n, TPDO1..4 0x180/0x280/0x380/0x480+n,
RPDO1..4 0x200/0x300/0x400/0x500+n, SDO server→client 0x580+n, client→server 0x600+n,
heartbeat/boot-up 0x700+n.
"""

from __future__ import annotations

import struct
from collections.abc import Sequence
from dataclasses import dataclass

from tests.vcan.canutils import Frame

NMT_ID = 0x000
SYNC_ID = 0x080
NMT_COMMANDS = {0x01: "start", 0x02: "stop", 0x80: "enter pre-operational", 0x81: "reset node",
                0x82: "reset communication"}
HEARTBEAT_STATES = {0x00: "boot-up", 0x04: "stopped", 0x05: "operational", 0x7F: "pre-operational"}
#: SDO client command specifiers (bits 7-5 of byte 0), CiA 301 §7.2.4.3.
CCS_DOWNLOAD_SEGMENT, CCS_DOWNLOAD_INITIATE, CCS_UPLOAD_INITIATE, CCS_UPLOAD_SEGMENT = 0, 1, 2, 3
CS_ABORT = 4
#: SDO server command specifiers.
SCS_UPLOAD_SEGMENT, SCS_DOWNLOAD_SEGMENT, SCS_UPLOAD_INITIATE, SCS_DOWNLOAD_INITIATE = 0, 1, 2, 3
#: PDO communication / mapping parameter indices.
RPDO_COMM, RPDO_MAP, TPDO_COMM, TPDO_MAP = 0x1400, 0x1600, 0x1800, 0x1A00
COB_ID_INVALID = 0x8000_0000


class ProtocolViolation(AssertionError):
    """A frame sequence that CiA 301 does not allow (the message says which rule)."""


@dataclass(frozen=True)
class SdoTransfer:
    """One expedited SDO transfer: the request, its response and the decoded value.

    Attributes
    ----------
    write : bool
        True for a download (client writes), False for an upload (client reads).
    index, subindex : int
        The object addressed.
    value : int or None
        The value written or read (little-endian, as many bytes as the frame says);
        None when the server aborted.
    abort_code : int or None
        The SDO abort code when the server aborted.
    """

    node_id: int
    write: bool
    index: int
    subindex: int
    value: int | None
    abort_code: int | None


def _need(cond: bool, rule: str, frame: Frame | None = None) -> None:
    if not cond:
        where = "" if frame is None else (
            f" (frame 0x{frame.arbitration_id:03X}#{frame.data.hex().upper()} at {frame.timestamp_s:.6f})")
        raise ProtocolViolation(rule + where)


def base_frames(frames: Sequence[Frame]) -> list[Frame]:
    """The 11-bit data frames: the only frames CANopen uses (29-bit ones are foreign)."""
    return [f for f in frames if not f.is_extended_id and not f.is_remote_frame]


def check_nmt(frames: Sequence[Frame]) -> list[tuple[str, int]]:
    """NMT node control (§7.2.8.3.1): DLC 2, a known command, node 0 (all) or 1..127.

    Returns (command name, node id) of each NMT frame, in order.
    """
    out = []
    for f in base_frames(frames):
        if f.arbitration_id != NMT_ID:
            continue
        _need(len(f.data) == 2, "NMT node control frames have exactly 2 data bytes", f)
        _need(f.data[0] in NMT_COMMANDS, f"NMT command 0x{f.data[0]:02X} is not one of CiA 301's", f)
        _need(f.data[1] <= 127, "NMT node id must be 0 (all) or 1..127", f)
        out.append((NMT_COMMANDS[f.data[0]], f.data[1]))
    return out


def check_sync(frames: Sequence[Frame], overflow: int) -> list[int]:
    """SYNC (§7.2.5): with counter overflow ``overflow`` (0x1019) > 1 every SYNC carries one
    byte, the counter, 1..overflow, each one more than the last (after ``overflow`` comes 1).
    A producer restarting its counter at 1 is allowed; any other jump is not. With
    ``overflow`` 0 every SYNC has no data.

    Returns the counter of every SYNC (0 when there is none).
    """
    counters = []
    last = None
    for f in base_frames(frames):
        if f.arbitration_id != SYNC_ID:
            continue
        if overflow == 0:
            _need(len(f.data) == 0, "SYNC without counter (0x1019 = 0) has no data", f)
            counters.append(0)
            continue
        _need(len(f.data) == 1, f"SYNC with counter (0x1019 = {overflow}) has exactly 1 data byte", f)
        value = f.data[0]
        _need(1 <= value <= overflow, f"SYNC counter must be within 1..{overflow}", f)
        if last is not None and value != 1:
            _need(value == last % overflow + 1, f"SYNC counter jumped from {last} to {value}", f)
        counters.append(value)
        last = value
    return counters


def sdo_transfers(frames: Sequence[Frame], node_id: int) -> list[SdoTransfer]:
    """Pair the expedited SDO requests of ``node_id``'s server with their responses.

    Checks §7.2.4: both directions use 8 data bytes; one transfer at a time per server
    (a response follows each request before the next request); the response repeats the
    request's multiplexer (index, sub-index); the command specifiers match the transfer
    (download initiate → 0x60, upload initiate → 0x4x with e=1) or the server aborts (0x80).
    """
    rx, tx = 0x600 + node_id, 0x580 + node_id
    out: list[SdoTransfer] = []
    pending: Frame | None = None
    for f in base_frames(frames):
        if f.arbitration_id not in (rx, tx):
            continue
        _need(len(f.data) == 8, "SDO frames have exactly 8 data bytes", f)
        if f.arbitration_id == rx:
            _need(pending is None, "a new SDO request before the last one was answered", f)
            ccs = f.data[0] >> 5
            _need(ccs in (CCS_DOWNLOAD_INITIATE, CCS_UPLOAD_INITIATE),
                  f"client command specifier {ccs}: only expedited initiate transfers expected", f)
            if ccs == CCS_DOWNLOAD_INITIATE:
                _need(f.data[0] & 0x03 == 0x03, "download initiate with e=1, s=1 (expedited, size set)", f)
            pending = f
            continue
        _need(pending is not None, "an SDO response without a request", f)
        assert pending is not None
        _need(f.data[1:4] == pending.data[1:4], "the SDO response repeats the request's multiplexer", f)
        index, subindex = struct.unpack_from("<HB", pending.data, 1)
        write = pending.data[0] >> 5 == CCS_DOWNLOAD_INITIATE
        scs = f.data[0] >> 5
        if scs == CS_ABORT:
            abort = struct.unpack_from("<I", f.data, 4)[0]
            out.append(SdoTransfer(node_id, write, index, subindex, None, abort))
        elif write:
            _need(f.data[0] == 0x60, "download initiate response is 0x60", f)
            size = 4 - ((pending.data[0] >> 2) & 0x03)
            value = int.from_bytes(pending.data[4:4 + size], "little")
            out.append(SdoTransfer(node_id, True, index, subindex, value, None))
        else:
            _need(scs == SCS_UPLOAD_INITIATE and bool(f.data[0] & 0x02),
                  "upload initiate response has scs=2 and e=1 (expedited)", f)
            size = 4 - ((f.data[0] >> 2) & 0x03) if f.data[0] & 0x01 else 4
            value = int.from_bytes(f.data[4:4 + size], "little")
            out.append(SdoTransfer(node_id, False, index, subindex, value, None))
        pending = None
    _need(pending is None, "the last SDO request was never answered")
    return out


@dataclass(frozen=True)
class PdoConfig:
    """A PDO as the master configured it over SDO: COB-ID, transmission type, mapping."""

    comm_index: int
    cob_id: int
    transmission_type: int
    mapping: tuple[tuple[int, int, int], ...]  # (index, sub-index, bits)

    @property
    def length_bytes(self) -> int:
        return sum(bits for _, _, bits in self.mapping) // 8


def pdo_configs(transfers: Sequence[SdoTransfer]) -> dict[int, PdoConfig]:
    """Replay the SDO writes to PDO parameters and check the CiA 301 §7.2.2 procedure:
    a PDO's mapping is only changed while the PDO is invalid (COB-ID bit 31 set) and its
    number of entries is 0, and the count written at the end matches the entries written.

    Returns the PDOs valid at the end, by communication parameter index.
    """
    cob: dict[int, int] = {}
    ttype: dict[int, int] = {}
    count: dict[int, int] = {}
    entries: dict[int, dict[int, int]] = {}
    for t in transfers:
        if t.abort_code is not None or t.value is None:
            continue
        if RPDO_COMM <= t.index < RPDO_COMM + 0x200 or TPDO_COMM <= t.index < TPDO_COMM + 0x200:
            comm_index = t.index
            if t.subindex == 1:
                cob[comm_index] = t.value
            elif t.subindex == 2 and t.write:
                ttype[comm_index] = t.value
            continue
        if not t.write or not (RPDO_MAP <= t.index < RPDO_MAP + 0x200
                               or TPDO_MAP <= t.index < TPDO_MAP + 0x200):
            continue
        comm_index = t.index - 0x200
        _need(cob.get(comm_index, 0) & COB_ID_INVALID != 0,
              f"mapping 0x{t.index:04X} changed while PDO 0x{comm_index:04X} was valid (bit 31 clear)")
        if t.subindex == 0:
            written = entries.get(comm_index, {})
            if t.value:
                _need(sorted(written) == list(range(1, t.value + 1)),
                      f"0x{t.index:04X}:00 = {t.value} but entries {sorted(written)} were written")
            else:
                entries[comm_index] = {}
            count[comm_index] = t.value
        else:
            _need(count.get(comm_index) == 0,
                  f"mapping entry 0x{t.index:04X}:{t.subindex} written while the count was not 0")
            entries.setdefault(comm_index, {})[t.subindex] = t.value
    out = {}
    for comm_index, cob_id in cob.items():
        if cob_id & COB_ID_INVALID or not count.get(comm_index):
            continue
        mapping = tuple((v >> 16, (v >> 8) & 0xFF, v & 0xFF)
                        for _, v in sorted(entries[comm_index].items()))
        out[comm_index] = PdoConfig(comm_index, cob_id & 0x7FF, ttype.get(comm_index, -1), mapping)
    return out


def heartbeats(frames: Sequence[Frame], node_id: int) -> list[Frame]:
    """Heartbeat / boot-up frames of ``node_id`` (§7.2.8.3.2): DLC 1, a known state."""
    out = []
    for f in base_frames(frames):
        if f.arbitration_id == 0x700 + node_id:
            _need(len(f.data) == 1, "heartbeat frames have exactly 1 data byte", f)
            _need(f.data[0] & 0x7F in HEARTBEAT_STATES, f"unknown NMT state 0x{f.data[0]:02X}", f)
            out.append(f)
    return out
