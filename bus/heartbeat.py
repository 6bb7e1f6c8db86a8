"""Heartbeat and EMCY consumer of the master (CiA 301 §7.2.8.3.2 and §7.2.7).

Each drive produces a heartbeat every period (0x1017) carrying its NMT state; its
boot-up message is a heartbeat with state 0. A heartbeat is late when the bus has carried
frames stamped more than a consumer time (``consumer_factor`` periods, default
``HEARTBEAT_CONSUMER_FACTOR``; CiA 301 wants it longer than the producer time) after it
(bus time: the stamps the interface puts on frames as they arrive, ``msg.timestamp``), so a
reader thread that the OS holds up for a while raises no false alarm; when the bus falls
silent altogether (the reader has handed on no frame for a consumer time), wall time
decides, after ``SILENT_BUS_FACTOR`` consumer times, and only once the silence has lasted
``SILENCE_CONFIRM_S`` more of the caller's checks (right after the whole process was held
up, the reader has not yet handed on what the bus carried meanwhile).
An EMCY with a non-zero error code latches a fault; an EMCY error reset (0x0000) from the
same node clears it (the fault is over; the count in :meth:`Supervisor.node_status` stays).

During a run (:meth:`Supervisor.expect_operational`) every drive must stay OPERATIONAL: a
heartbeat stamped after the drives were started that carries another NMT state, or an NMT
command to one of them on the bus (the master sends none while it runs, so it came from
another master), is reported.
"""

from __future__ import annotations

import logging
import threading
import time

import can
import canopen

from bus.cia301 import (
    EMCY_BASE,
    EMCY_ERROR_RESET,
    HEARTBEAT_BASE,
    NMT_BOOT_UP,
    NMT_COB_ID,
    NMT_COMMAND_NAMES,
    NMT_OPERATIONAL,
    NMT_STATE_NAMES,
)
from stand.errors import BusError, DriveFault, HeartbeatLost, InputError, NodeNotOperational

log = logging.getLogger(__name__)

#: A heartbeat older than this many periods means the node is lost.
HEARTBEAT_CONSUMER_FACTOR = 1.5
#: On a silent bus, a heartbeat is lost after this many consumer times of wall time.
SILENT_BUS_FACTOR = 2.0
#: A silent bus must stay silent this long across checks before wall time decides, s
#: (longer than the bus reader needs to drain its queue once it runs again).
SILENCE_CONFIRM_S = 0.05


class BusClock(can.Listener):
    """The newest frame stamp the bus reader has handed on (bus time), s."""

    def __init__(self) -> None:
        self.newest = 0.0
        self.last_frame_monotonic = time.monotonic()

    def on_message_received(self, msg: can.Message) -> None:
        self.last_frame_monotonic = time.monotonic()
        if msg.timestamp > self.newest:
            self.newest = msg.timestamp


class Supervisor:
    """Watches the heartbeats, boot-ups and EMCYs of a set of nodes on ``network``."""

    def __init__(self, network: canopen.Network,
                 consumer_factor: float = HEARTBEAT_CONSUMER_FACTOR) -> None:
        if not consumer_factor > 1.0:
            raise InputError(f"heartbeat consumer time must exceed the producer period "
                             f"(CiA 301): consumer_factor {consumer_factor} <= 1")
        self.consumer_factor = consumer_factor
        self._silence_seen: float | None = None
        self._last_check = 0.0
        self.network = network
        self.clock = BusClock()
        assert network.notifier is not None, "connect the network first"
        network.notifier.add_listener(self.clock)
        self.heartbeats: dict[int, tuple[float, int, float]] = {}  # monotonic, state, stamp
        self.emcy: dict[int, list[tuple[float, int]]] = {}
        #: The EMCY code each node's fault is latched on (cleared by an error reset).
        self.latched: dict[int, int] = {}
        self.booted: dict[int, threading.Event] = {}
        #: When each node was told its producer heartbeat time: (monotonic, bus stamp).
        self._producing_since: dict[int, tuple[float, float]] = {}
        #: While a run goes on: its drives, and the newest bus stamp when it began.
        self._operational: tuple[frozenset[int], float] | None = None
        self._foreign_nmt: tuple[int, int] | None = None  # (command, target) first seen

    def watch(self, node_id: int) -> None:
        """Start watching ``node_id`` afresh (before resetting it)."""
        self.booted[node_id] = threading.Event()
        self.heartbeats.pop(node_id, None)
        self._producing_since.pop(node_id, None)
        self.emcy[node_id] = []
        self.latched.pop(node_id, None)
        self.network.subscribe(HEARTBEAT_BASE + node_id, self._on_heartbeat)
        self.network.subscribe(EMCY_BASE + node_id, self._on_emcy)

    def producing(self, node_id: int) -> None:
        """``node_id`` was just told its producer heartbeat time (0x1017): its first beat is
        due a period from now, so its silence counts from now, not from its boot-up."""
        self._producing_since[node_id] = (time.monotonic(), self.clock.newest)

    def forget(self, node_id: int) -> None:
        for cob_id, callback in ((HEARTBEAT_BASE + node_id, self._on_heartbeat),
                                 (EMCY_BASE + node_id, self._on_emcy)):
            if callback in self.network.subscribers.get(cob_id, []):
                self.network.unsubscribe(cob_id, callback)

    def expect_operational(self, node_ids: list[int]) -> None:
        """From now on, ``node_ids`` must stay OPERATIONAL (a run begins; they were started)."""
        self._foreign_nmt = None
        self._operational = (frozenset(node_ids), self.clock.newest)
        self.network.subscribe(NMT_COB_ID, self._on_nmt)

    def release(self) -> None:
        """The run is over: the master may change the drives' NMT states again."""
        self._operational = None
        if self._on_nmt in self.network.subscribers.get(NMT_COB_ID, []):
            self.network.unsubscribe(NMT_COB_ID, self._on_nmt)

    def _on_nmt(self, can_id: int, data: bytearray, timestamp: float) -> None:
        watched = self._operational
        if watched is None or len(data) < 2 or self._foreign_nmt is not None:
            return
        command, target = data[0], data[1]
        if target == 0 or target in watched[0]:
            self._foreign_nmt = (command, target)

    def _on_heartbeat(self, can_id: int, data: bytearray, timestamp: float) -> None:
        node_id = can_id - HEARTBEAT_BASE
        state = data[0] & 0x7F if data else NMT_BOOT_UP
        self.heartbeats[node_id] = (time.monotonic(), state, timestamp)
        if state == NMT_BOOT_UP and node_id in self.booted:
            self.booted[node_id].set()

    def _on_emcy(self, can_id: int, data: bytearray, timestamp: float) -> None:
        node_id = can_id - EMCY_BASE
        code = int.from_bytes(bytes(data[:2]), "little") if len(data) >= 2 else EMCY_ERROR_RESET
        if code == EMCY_ERROR_RESET:
            if self.latched.pop(node_id, None) is not None:
                log.info("node %d: EMCY error reset", node_id)
            return
        self.emcy.setdefault(node_id, []).append((time.monotonic(), code))
        self.latched[node_id] = code
        log.warning("node %d: EMCY 0x%04X", node_id, code)

    def age_s(self, node_id: int) -> float | None:
        """Wall time since the last heartbeat of ``node_id`` arrived, s (None: none yet)."""
        beat = self.heartbeats.get(node_id)
        return None if beat is None else time.monotonic() - beat[0]

    def check(self, node_ids: list[int], period_s: float) -> BusError | None:
        """A heartbeat loss, a latched EMCY fault or (during a run) a drive that left
        OPERATIONAL among ``node_ids``, or None."""
        limit = self.consumer_factor * period_s
        newest = self.clock.newest
        now = time.monotonic()
        silent = now - self.clock.last_frame_monotonic > limit
        if not silent or now - self._last_check > limit:
            self._silence_seen = None  # heard the bus, or not looked for a long while
        if silent and self._silence_seen is None:
            self._silence_seen = now
        self._last_check = now
        confirmed = self._silence_seen is not None and now - self._silence_seen >= SILENCE_CONFIRM_S
        for node_id in node_ids:
            beat = self.heartbeats.get(node_id)
            if beat is None:
                continue
            received, _, stamp = beat
            since = self._producing_since.get(node_id)
            if since is not None:  # the boot-up came before the drive was told to beat
                received, stamp = max(received, since[0]), max(stamp, since[1])
            bus_age, wall_age = newest - stamp, now - received
            if bus_age > limit or (confirmed and wall_age > SILENT_BUS_FACTOR * limit):
                return HeartbeatLost(f"node {node_id}: no heartbeat for {max(bus_age, wall_age):.3f} s "
                                     f"(period {period_s} s); every drive was quick-stopped")
        for node_id in node_ids:
            if node_id in self.latched:
                code = self.latched[node_id]
                return DriveFault(f"node {node_id}: EMCY 0x{code:04X}; every drive was quick-stopped")
        return self._check_operational(node_ids)

    def _check_operational(self, node_ids: list[int]) -> BusError | None:
        watched = self._operational
        if watched is None:
            return None
        if self._foreign_nmt is not None:
            command, target = self._foreign_nmt
            name = NMT_COMMAND_NAMES.get(command, f"0x{command:02X}")
            to = "every node" if target == 0 else f"node {target}"
            return NodeNotOperational(f"{to}: NMT command '{name}' from another master left "
                                      "OPERATIONAL; every drive was quick-stopped")
        _, since = watched
        for node_id in node_ids:
            beat = self.heartbeats.get(node_id)
            # A heartbeat stamped before the run began may predate the NMT start.
            if beat is not None and beat[2] > since and beat[1] != NMT_OPERATIONAL:
                state = NMT_STATE_NAMES.get(beat[1], str(beat[1]))
                return NodeNotOperational(f"node {node_id}: heartbeat says {state}, expected "
                                          "OPERATIONAL during the run; every drive was quick-stopped")
        return None

    def node_status(self, node_id: int) -> dict[str, object]:
        beat = self.heartbeats.get(node_id)
        emcy = self.emcy.get(node_id, [])
        return {"fault_latched": node_id in self.latched,
                "nmt_state": NMT_STATE_NAMES.get(beat[1], str(beat[1])) if beat else "UNKNOWN",
                "heartbeat_age_s": self.age_s(node_id),
                "emcy_count": len(emcy),
                "last_emcy": f"0x{emcy[-1][1]:04X}" if emcy else None}
