"""Timing rules of the master: window reference stamps, heartbeat consumer, receive filters."""

from __future__ import annotations

import time
from collections.abc import Iterator

import can
import canopen
import pytest

from bus.adapters import BusConfig, connect_network, open_bus, receive_filters
from bus.eds import Scaling, load_od
from bus.heartbeat import SILENCE_CONFIRM_S, Supervisor
from bus.pdo import Layout, entry
from bus.sampler import Sampler
from stand.errors import HeartbeatLost, InputError

TPDO1 = 0x181
#: A synchronous window of a 15 ms realtime run, s.
WINDOW_S = 0.0075


def _sampler(window_s: float) -> Sampler:
    layout = Layout.from_entries(load_od(None, 1), [entry(0x6064, 0, 32)])
    return Sampler({TPDO1: (0, 0, layout)}, [1], [Scaling(counts_per_rev=10_000, rated_current_A=1.0)],
                   samples=4, period_s=0.015, window_s=window_s)


def test_realtime_tpdo_on_the_bus_before_the_sync_is_late_not_the_next_sample() -> None:
    """A late answer to SYNC k-1 that the reader hands on while SYNC k is being sent is
    judged against the time SYNC k was certainly out, so it never fills window k."""
    s = _sampler(WINDOW_S)
    s.open(0, 0.0, 1)
    before_sync = time.time()  # stamped while the SYNC was being sent: answers SYNC -1
    s.on_tpdo(TPDO1, bytearray((111).to_bytes(4, "little", signed=True)), before_sync)
    assert not s.received[0][0, 0], "held until the SYNC is known to be out"
    sent = time.time()
    s.sent(sent)
    s.on_tpdo(TPDO1, bytearray((222).to_bytes(4, "little", signed=True)), sent + 1e-3)
    assert s.late == [1]
    assert s.received[0][0, 0] and s.raw[0]["position_rad"][0] == 222


def test_a_late_echo_of_the_last_sync_does_not_open_the_next_window() -> None:
    """The reader may hand on SYNC k-1's echo after window k opened: matched by the SYNC
    counter, it must not become window k's reference (answers to k-1 would then count)."""
    s = _sampler(WINDOW_S)
    s.open(0, 0.0, 1)
    s.open(1, 0.015, 2)
    t_sync0 = time.time()
    s.sent(t_sync0, counter=1)
    s.on_tpdo(TPDO1, bytearray((7).to_bytes(4, "little", signed=True)), t_sync0 + 1e-3)
    assert not s.received[0][0, 1]
    s.sent(t_sync0 + 0.015, counter=2)  # SYNC 1's own echo: the held answer to SYNC 0 is late
    assert s.late == [1] and not s.received[0][0, 1]


def test_lockstep_answer_is_never_judged_late_by_the_send_time() -> None:
    """Lockstep: a drive may answer before the master's ``send`` returns (in-process bus);
    the reference is the time before the send, so such an answer counts."""
    s = _sampler(0.0)
    s.open(0, 0.0, 1)
    s.on_tpdo(TPDO1, bytearray((5).to_bytes(4, "little", signed=True)), time.time())
    s.sent(time.time() + 1.0)
    assert s.late == [0] and s.received[0][0, 0]


@pytest.fixture
def network() -> Iterator[canopen.Network]:
    net = connect_network(BusConfig("virtual", "test-bus-timing"), role="master")
    yield net
    net.disconnect()


def test_consumer_time_must_exceed_the_producer_period(network: canopen.Network) -> None:
    with pytest.raises(InputError, match="consumer"):
        Supervisor(network, consumer_factor=1.0)


def test_silent_bus_decides_only_after_the_reader_had_its_turn(network: canopen.Network) -> None:
    """After the whole process was held up, the first check must not call a heartbeat lost
    that the reader has not yet handed on; a silence that lasts is still a loss."""
    period_s = 0.1
    sup = Supervisor(network, consumer_factor=1.5)
    sup.watch(1)
    stalled_s = 1.0
    sup._on_heartbeat(0x701, bytearray([5]), time.time() - stalled_s)
    sup.heartbeats[1] = (time.monotonic() - stalled_s, 5, time.time() - stalled_s)
    sup.clock.last_frame_monotonic = time.monotonic() - stalled_s
    assert sup.check([1], period_s) is None
    time.sleep(SILENCE_CONFIRM_S * 1.2)
    assert isinstance(sup.check([1], period_s), HeartbeatLost)


def test_bus_time_judges_a_heartbeat_by_its_stamp(network: canopen.Network) -> None:
    """A heartbeat is late when frames stamped more than the consumer time after it came,
    however recently Python read it."""
    sup = Supervisor(network, consumer_factor=2.0)
    sup.watch(1)
    t0 = time.time()
    sup._on_heartbeat(0x701, bytearray([5]), t0)
    sup.clock.on_message_received(can.Message(arbitration_id=0x181, timestamp=t0 + 0.19))
    assert sup.check([1], 0.1) is None
    sup.clock.on_message_received(can.Message(arbitration_id=0x181, timestamp=t0 + 0.21))
    assert isinstance(sup.check([1], 0.1), HeartbeatLost)


def test_master_filters_drop_foreign_frames(can_config: BusConfig) -> None:
    """Only the frames a master needs reach it (in the kernel on SocketCAN): TPDOs, SDO
    answers, heartbeats, EMCY; not 29-bit aliases of COB-IDs, RPDOs or SDO requests."""
    filtered = BusConfig(can_config.interface, can_config.channel,
                         options={"can_filters": receive_filters("master")})
    with open_bus(filtered) as master, open_bus(can_config) as peer:
        sent = [(0x181, False), (0x181, True), (0x201, False), (0x601, False), (0x080, True),
                (0x581, False), (0x701, False), (0x081, False), (0x123, False)]
        for ident, extended in sent:
            peer.send(can.Message(arbitration_id=ident, is_extended_id=extended, data=b"\x01"))
        got = []
        while (msg := master.recv(0.5)) is not None:
            got.append((msg.arbitration_id, msg.is_extended_id))
    assert got == [(0x181, False), (0x581, False), (0x701, False), (0x081, False)]


def test_drive_role_filters() -> None:
    ids = {(f["can_id"], f["can_mask"]) for f in receive_filters("drive")}
    assert (0x000, 0x7FF) in ids and (0x080, 0x7FF) in ids and (0x600, 0x780) in ids
    with pytest.raises(InputError):
        receive_filters("sniffer")
