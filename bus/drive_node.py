"""A simulated CiA 402 drive: a canopen LocalNode with stand physics behind it.

canopen's LocalNode answers SDO and follows NMT commands, but does no PDO work (canopen
issue #555). This node adds: boot-up after an NMT reset, no SDO while STOPPED (CiA 301
§7.3.2.2), RPDO reception (a synchronous RPDO, transmission type 0-240, is buffered and
acts at the next SYNC; an event-driven one at once), TPDOs only when OPERATIONAL (their
mapping and transmission type read from its own object dictionary, as a master wrote them
or as CiA 402 predefines them at power-on: a synchronous TPDO of type n every n-th SYNC,
any other when its data changed, looked at on each SYNC), the CiA 402 state machine, and
EMCY on a fault and on its reset. The SYNC itself is handled by
:class:`bus.simstand.SimStand`, which owns the plant that one or two nodes share.
"""

from __future__ import annotations

import logging
import math
import struct
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any, Protocol

import canopen
from canopen.sdo import SdoAbortedError

from bus import cia402
from bus.cia301 import (
    EMCY_BASE,
    EMCY_ERROR_RESET,
    HEARTBEAT_BASE,
    MANUFACTURER_END,
    MANUFACTURER_FIRST,
    NMT_BOOT_UP,
    NMT_COB_ID,
    NMT_OPERATIONAL,
    NMT_PRE_OPERATIONAL,
    NMT_RESET_COMMUNICATION,
    NMT_RESET_NODE,
    NMT_STOPPED,
    PRODUCER_HEARTBEAT_TIME,
    RPDO_COMMUNICATION,
    RPDO_MAPPING,
    SYNCHRONOUS_WINDOW_LENGTH,
    TPDO_COMMUNICATION,
    TPDO_MAPPING,
)
from bus.eds import Scaling, load_od
from bus.heartbeat_producer import HeartbeatProducer
from bus.pdo import COB_ID_INVALID, Layout
from stand.physics.plant import Measurement

log = logging.getLogger(__name__)

#: Most PDOs of one direction CiA 301 predefines (the node offers those its EDS has).
PDO_COUNT = 4
#: Over-current trips when the measured current exceeds this multiple of 0x6073.
OVER_CURRENT_MARGIN = 1.0
#: A speed error beyond the following window for this long is a fault, s.
FOLLOWING_ERROR_TIME_S = 0.5
#: SDO abort: object cannot be mapped / general parameter incompatibility.
ABORT_GENERAL = 0x0800_0000
#: Highest PDO transmission type that is synchronous (CiA 301 §7.5.2.35): 0 acyclic,
#: 1-240 every n-th SYNC; 252-255 are RTR-only or event-driven.
LAST_SYNCHRONOUS_TYPE = 240
#: The target objects of the drive modes.
TARGETS = tuple(index for index, _, _ in cia402.TARGET_OBJECT.values())


class Plant(Protocol):
    def command(self, mode: str, target: float, port: int = 0) -> None: ...
    def measure(self, dt_s: float, port: int = 0) -> Measurement: ...
    def advance(self, dt_s: float) -> None: ...


class SimDriveNode:
    """One simulated drive on ``network``, driving ``port`` of the plant ``plant()``.

    Parameters
    ----------
    network : canopen.Network
        The (connected) network of the simulated stand.
    node_id : int
        CANopen node id, 1-127.
    plant : callable
        Returns the current plant (it is rebuilt on NMT reset).
    port : int
        Port of the plant this drive drives (0 input motor, 1 output motor).
    scaling : Scaling
        Units of its raw process data.
    max_current_A : float
        Over-current threshold (0x6073), A.
    eds : path or None
        EDS of the node (default: the shipped simulated drive).
    on_reset : callable or None
        Called after an NMT reset node, before the boot-up message.
    on_write : callable or None
        Called as ``on_write(node, index, value)`` after an SDO write of a manufacturer
        object (0x2000-0x5FFF).
    """

    def __init__(self, network: canopen.Network, node_id: int, plant: Callable[[], Plant],
                 port: int, scaling: Scaling, max_current_A: float,
                 eds: str | Path | None = None,
                 on_reset: Callable[[SimDriveNode], None] | None = None,
                 on_write: Callable[[SimDriveNode, int, Any], None] | None = None) -> None:
        self.id = node_id
        self.network = network
        self.plant = plant
        self.port = port
        self.scaling = scaling
        self.od = load_od(eds, node_id)
        self.node = canopen.LocalNode(node_id, self.od)
        self.node.add_write_callback(self._on_sdo_write)
        self.node.add_read_callback(self._on_sdo_read)
        network.add_node(self.node)
        # SDO requests pass through the NMT state first (no SDO while STOPPED).
        network.unsubscribe(self.node.sdo.rx_cobid, self.node.sdo.on_request)
        network.subscribe(self.node.sdo.rx_cobid, self._on_sdo_request)
        network.subscribe(NMT_COB_ID, self._on_nmt)
        self._on_reset = on_reset
        self._on_write = on_write
        self.max_current_A = max_current_A
        #: Speed error that counts as a following error (None: not checked), rad/s.
        self.following_window_rad_s: float | None = None
        self._following_s = 0.0
        # Its own heartbeat, not canopen's cyclic task (see bus.heartbeat_producer).
        self.heartbeat = HeartbeatProducer(network, node_id, lambda: self.nmt_state)
        self.node._write_callbacks.remove(self.node.nmt.on_write)
        self.pdo_drop_every = 0  # fault injection: drop every n-th TPDO (0 = none)
        self._tpdo_count = 0
        self.tpdos_discarded = 0  # SYNCs answered by no TPDO: outside the synchronous window
        self.syncs = 0  # SYNCs seen since power-on (stand time = syncs · period)
        self.quick_stop_at: tuple[float, int] | None = None  # (time.monotonic(), syncs)
        self._subscribed: list[int] = []
        self._power_on()

    # -- state -------------------------------------------------------------------------
    def _power_on(self) -> None:
        self.node.data_store.clear()
        self.sm = cia402.StateMachine()
        self.mode: str | None = None  # no mode of operation until one is written (0x6060 = 0)
        self.values: dict[int, int] = {cia402.CONTROLWORD: 0}
        self._pending: dict[int, int] = {}  # synchronous RPDO data, acting at the next SYNC
        self._tpdo_last: dict[int, bytes] = {}  # event-driven TPDOs: the data last sent
        self.syncs = 0
        self.quick_stop_at = None
        self.measurement = Measurement(0.0, 0.0, 0.0, 0.0)
        self._tpdos: list[tuple[int, Layout, int]] | None = None
        self._resubscribe({})
        self.node.data_store.setdefault(cia402.RATED_CURRENT, {})[0] = struct.pack(
            "<I", self.scaling.rated_current_mA)
        resolution = self.node.data_store.setdefault(cia402.POSITION_ENCODER_RESOLUTION, {})
        resolution[cia402.ENCODER_INCREMENTS] = struct.pack("<I", self.scaling.counts_per_rev)
        resolution[cia402.MOTOR_REVOLUTIONS] = struct.pack("<I", 1)
        self.node.data_store.setdefault(cia402.MAX_CURRENT, {})[0] = struct.pack(
            "<H", min(0xFFFF, int(self.max_current_A / self.scaling.amp_per_unit)))

    @property
    def nmt_state(self) -> int:
        return self.node.nmt._state

    def boot(self) -> None:
        """Send the boot-up message and enter PRE-OPERATIONAL (CiA 301 §7.2.8.3)."""
        nmt = self.node.nmt
        nmt._state = NMT_BOOT_UP
        self.network.send_message(HEARTBEAT_BASE + self.id, bytes([NMT_BOOT_UP]))
        nmt._state = NMT_PRE_OPERATIONAL
        period_ms = struct.unpack("<H", self.node.get_data(PRODUCER_HEARTBEAT_TIME, 0))[0]
        self._set_heartbeat(period_ms)

    def _set_heartbeat(self, period_ms: int) -> None:
        self.heartbeat.set_period(period_ms / 1000.0)

    def _refresh_heartbeat(self) -> None:
        self.heartbeat.refresh()

    def heartbeat_tick(self, now: float) -> float | None:
        """Send the heartbeat if due at ``now`` (see :meth:`HeartbeatProducer.tick`)."""
        return self.heartbeat.tick(now)

    def close(self) -> None:
        self.heartbeat.mute()
        self.network.unsubscribe(NMT_COB_ID, self._on_nmt)
        if self._on_sdo_request in self.network.subscribers.get(self.node.sdo.rx_cobid, []):
            self.network.unsubscribe(self.node.sdo.rx_cobid, self._on_sdo_request)
        self._resubscribe({})

    def mute_heartbeat(self) -> None:
        """Fault injection: stop producing heartbeats (the node otherwise keeps working)."""
        self.heartbeat.mute()

    # -- NMT ---------------------------------------------------------------------------
    def _on_nmt(self, can_id: int, data: bytearray, timestamp: float) -> None:
        command, target = data[0], data[1]
        if target not in (0, self.id):
            return
        if command in (NMT_RESET_NODE, NMT_RESET_COMMUNICATION):
            self.heartbeat.stop()  # the boot-up is the first frame after a reset
            self._power_on()
            if command == NMT_RESET_NODE and self._on_reset:
                self._on_reset(self)
            self.boot()
        elif self.nmt_state != NMT_OPERATIONAL and self.sm.enabled:
            self._disable()
        if self.nmt_state == NMT_OPERATIONAL:
            self._tpdos = None
            self._resubscribe(self._rpdo_layouts())
        self._refresh_heartbeat()

    # -- SDO callbacks -----------------------------------------------------------------
    def _on_sdo_request(self, can_id: int, data: bytearray, timestamp: float) -> None:
        if self.nmt_state != NMT_STOPPED:
            self.node.sdo.on_request(can_id, data, timestamp)

    def _on_sdo_read(self, index: int, subindex: int, od: Any) -> Any:
        m = self.measurement
        s = self.scaling
        if index == cia402.STATUSWORD:
            return self.sm.statusword
        if index == cia402.POSITION_ACTUAL:
            return int(round(m.position_rad / s.rad_per_count))
        if index == cia402.VELOCITY_ACTUAL:
            return int(round(m.velocity_rad_s / s.velocity_unit_rad_s))
        if index in (cia402.CURRENT_ACTUAL, cia402.TORQUE_ACTUAL):
            # Both per mille of their rated value; rated torque 0x6076 is the torque at
            # rated current 0x6075, so the two read the same.
            return int(round(m.current_A / s.amp_per_unit))
        if index == cia402.VOLTAGE_ACTUAL:
            return int(round(m.voltage_V / s.voltage_unit_V))
        if index == cia402.CURRENT_MEAN:
            return int(round(m.current_mean_A / s.amp_per_unit))
        if index == cia402.MODES_DISPLAY:
            return cia402.MODES[self.mode] if self.mode else cia402.MODE_NONE
        if index == cia402.ERROR_CODE:
            return self.values.get(cia402.ERROR_CODE, 0)
        return None

    def _on_sdo_write(self, index: int, subindex: int, od: Any, data: bytes) -> None:
        value = od.decode_raw(data)
        if index == cia402.CONTROLWORD:
            self._controlword(int(value))
        elif index == cia402.MODES_OF_OPERATION:
            self._mode_of_operation(int(value))
        elif index in TARGETS:
            self.values[index] = int(value)
        elif index == PRODUCER_HEARTBEAT_TIME:
            self._set_heartbeat(int(value))
        elif RPDO_COMMUNICATION <= index < TPDO_MAPPING + 0x200:
            if self.nmt_state == NMT_OPERATIONAL:
                raise SdoAbortedError(ABORT_GENERAL | 0x22)  # not in the present device state
            self._tpdos = None
        elif MANUFACTURER_FIRST <= index < MANUFACTURER_END and self._on_write:
            self._on_write(self, index, value)

    # -- CiA 402 -----------------------------------------------------------------------
    def _mode_of_operation(self, value: int) -> None:
        modes = {v: k for k, v in cia402.MODES.items()}
        if value not in modes and value != cia402.MODE_NONE:
            raise SdoAbortedError(0x0609_0030)  # value range exceeded
        self.mode = modes.get(value)

    def _controlword(self, word: int) -> None:
        before = self.sm.state
        self.values[cia402.CONTROLWORD] = word
        after = self.sm.on_controlword(word)
        if after is before:
            return
        if before is cia402.State.FAULT:  # fault reset: the error is gone (CiA 301 §7.2.7)
            self.values[cia402.ERROR_CODE] = EMCY_ERROR_RESET
            self._emcy(EMCY_ERROR_RESET, 0x00)
        if after is cia402.State.QUICK_STOP_ACTIVE:
            self.quick_stop_at = (time.monotonic(), self.syncs)
            self.plant().command("speed", 0.0, self.port)
        elif before in (cia402.State.OPERATION_ENABLED, cia402.State.QUICK_STOP_ACTIVE):
            self.plant().command("current", 0.0, self.port)

    def _disable(self) -> None:
        self.sm.state = cia402.State.SWITCH_ON_DISABLED
        self.plant().command("current", 0.0, self.port)

    def fault(self, code: int, register: int = 0x01) -> None:
        """Enter FAULT, remove torque and send EMCY ``code`` (CiA 301 §7.2.7)."""
        self.sm.fault()
        self.values[cia402.ERROR_CODE] = code
        self.plant().command("current", 0.0, self.port)
        self._emcy(code, register)
        log.warning("node %d: fault 0x%04X", self.id, code)

    def _emcy(self, code: int, register: int) -> None:
        """Send EMCY ``code`` with error register ``register`` (0x1001)."""
        self.network.send_message(EMCY_BASE + self.id, struct.pack("<HB5s", code, register, b""))

    # -- PDO ---------------------------------------------------------------------------
    def _layouts(self, comm: int, mapping: int) -> list[tuple[int, Layout, int]]:
        """(COB-ID, layout, transmission type) of every valid PDO of ``comm``/``mapping``."""
        out = []
        for n in range(PDO_COUNT):
            if comm + n not in self.od:
                break
            cob_id = struct.unpack("<I", self.node.get_data(comm + n, 1))[0]
            count = self.node.get_data(mapping + n, 0)[0]
            if cob_id & COB_ID_INVALID or count == 0:
                continue
            entries = [struct.unpack("<I", self.node.get_data(mapping + n, k))[0]
                       for k in range(1, count + 1)]
            kind = self.node.get_data(comm + n, 2)[0]
            out.append((cob_id & 0x7FF, Layout.from_entries(self.od, entries), kind))
        return out

    def _rpdo_layouts(self) -> dict[int, tuple[Layout, bool]]:
        return {cob_id: (layout, kind <= LAST_SYNCHRONOUS_TYPE)
                for cob_id, layout, kind in self._layouts(RPDO_COMMUNICATION, RPDO_MAPPING)}

    def _resubscribe(self, layouts: dict[int, tuple[Layout, bool]]) -> None:
        for cob_id in self._subscribed:
            self.network.unsubscribe(cob_id, self._on_rpdo)
        self._rpdo = layouts
        self._subscribed = list(layouts)
        for cob_id in self._subscribed:
            self.network.subscribe(cob_id, self._on_rpdo)

    def _on_rpdo(self, can_id: int, data: bytearray, timestamp: float) -> None:
        rpdo = self._rpdo.get(can_id)
        if rpdo is None or self.nmt_state != NMT_OPERATIONAL:
            return
        layout, synchronous = rpdo
        if len(data) < layout.packer.size:
            return  # too short for its mapping: not taken (CiA 301 §7.2.2.3)
        values = dict(zip(layout.indices, (int(v) for v in layout.unpack(data)), strict=True))
        if synchronous:
            self._pending.update(values)  # the last before the SYNC counts
        else:
            self._apply(values)

    def _apply(self, values: dict[int, int]) -> None:
        for index, value in values.items():
            if index == cia402.CONTROLWORD:
                if value != self.values.get(index):
                    self._controlword(value)
            elif index == cia402.MODES_OF_OPERATION:
                try:
                    self._mode_of_operation(value)
                except SdoAbortedError:
                    log.warning("node %d: mode of operation %d in an RPDO ignored", self.id, value)
            else:
                self.values[index] = value

    def apply_rpdos(self) -> None:
        """At SYNC, first: the synchronous RPDO data received since the last SYNC act now."""
        pending, self._pending = self._pending, {}
        if pending:
            self._apply(pending)

    def sample(self, dt_s: float, sync_stamp: float | None = None) -> None:
        """At SYNC: measure, check the limits, send the TPDOs when OPERATIONAL.

        ``sync_stamp`` is the SYNC's ``time.time()`` stamp; a TPDO that could not be sent
        within the synchronous window 0x1007 after it is discarded (CiA 301), so a late
        answer is never taken for the next SYNC's. The check is made right before each send.
        """
        m = self.plant().measure(dt_s, self.port)
        self.measurement = m
        self.syncs += 1
        if abs(m.current_A) > self.max_current_A * OVER_CURRENT_MARGIN and self.sm.enabled:
            self.fault(cia402.EMCY_OVER_CURRENT, register=0x03)
        self._check_following(m, dt_s)
        if self.nmt_state != NMT_OPERATIONAL:
            return
        window_s = (struct.unpack("<I", self.node.get_data(SYNCHRONOUS_WINDOW_LENGTH, 0))[0] * 1e-6
                    if SYNCHRONOUS_WINDOW_LENGTH in self.od else 0)
        if self._tpdos is None:
            self._tpdos = self._layouts(TPDO_COMMUNICATION, TPDO_MAPPING)
        for cob_id, layout, kind in self._tpdos:
            values = [self._read_value(index) for index in layout.indices]
            data = layout.pack(values)
            if 0 < kind <= LAST_SYNCHRONOUS_TYPE:
                if self.syncs % kind:
                    continue  # type n: every n-th SYNC
            elif self._tpdo_last.get(cob_id) == data:
                continue  # event-driven (or acyclic): only when the data changed
            self._tpdo_last[cob_id] = data
            self._tpdo_count += 1
            if self.pdo_drop_every and self._tpdo_count % self.pdo_drop_every == 0:
                continue
            if window_s and sync_stamp is not None and not 0 <= time.time() - sync_stamp <= window_s:
                self.tpdos_discarded += 1
                continue
            self.network.send_message(cob_id, data)

    def _check_following(self, m: Measurement, dt_s: float) -> None:
        """Speed mode: a speed error beyond the window for longer than the time is a fault."""
        if not (self.sm.enabled and self.mode == "speed" and self.following_window_rad_s):
            self._following_s = 0.0
            return
        target = self.values.get(0x60FF, 0) * self.scaling.velocity_unit_rad_s
        if abs(target - m.velocity_rad_s) > self.following_window_rad_s:
            self._following_s += dt_s
            if self._following_s > FOLLOWING_ERROR_TIME_S:
                self.fault(cia402.EMCY_FOLLOWING_ERROR, register=0x21)
        else:
            self._following_s = 0.0

    def _read_value(self, index: int) -> int:
        """The present value of a mappable object (the process data or the object dictionary)."""
        value = self._on_sdo_read(index, 0, None)
        if value is None:
            value = self.values.get(index)
        if value is None:
            var: Any = self.od[index]
            value = var.decode_raw(self.node.get_data(index, 0))
        return int(value)

    def actuate(self) -> None:
        """At SYNC, after sampling: apply the latest target when OPERATION ENABLED."""
        if not self.sm.enabled or self.mode is None:
            return
        index, _, _ = cia402.TARGET_OBJECT[self.mode]
        raw = self.values.get(index, 0)
        unit = {"speed": self.scaling.velocity_unit_rad_s, "current": self.scaling.amp_per_unit,
                "voltage": self.scaling.voltage_unit_V}[self.mode]
        target = raw * unit
        if not math.isfinite(target):
            target = 0.0
        self.plant().command(self.mode, target, self.port)
