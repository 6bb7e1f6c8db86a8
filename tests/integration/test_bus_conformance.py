"""The simulated drive as CiA 301 and CiA 402 describe a drive (issue 20, item 5).

Each test talks to the simulated drive the way any CANopen master would, through canopen's
own client (``RemoteNode``) on another bus object, not through our master.
"""

from __future__ import annotations

import time
from collections.abc import Iterator

import canopen
import pytest

from bus import cia402
from bus.adapters import BusConfig, connect_network
from bus.cia301 import SYNC_COB_ID
from bus.eds import DEFAULT_EDS
from bus.simstand import SimStand

MOTOR = "crouzet_82800502"
NODE = 1
#: SDO answer time of the client: the simulated drive answers in well under a millisecond
#: on the virtual bus; a one-CPU User-Mode Linux guest may hold it up far longer, s.
SDO_TIMEOUT_S = 0.5
#: Time the tests wait for a frame's effect to be visible over SDO, s.
SETTLE_S = 0.05
#: 0x6502 bits (CiA 402 §6.2.13): 8 cyclic synchronous velocity, 9 cyclic synchronous
#: torque; bits 16-31 manufacturer modes, 16 being mode -1 (the simulation's voltage mode).
CSV_BIT, CST_BIT, MANUFACTURER_MINUS_1_BIT = 1 << 8, 1 << 9, 1 << 16
#: CiA 402 predefined mapping (a 32-bit entry: index, sub-index, length in bits).
PREDEFINED = {0x1600: [0x60400010], 0x1601: [0x60400010, 0x60600008],
              0x1A00: [0x60410010], 0x1A01: [0x60410010, 0x60610008]}


@pytest.fixture
def drive(can_config: BusConfig) -> Iterator[tuple[SimStand, canopen.RemoteNode]]:
    """The simulated drive (just powered on) and a client of another master on the bus."""
    with SimStand(MOTOR, can_config) as sim:
        network = connect_network(can_config)
        try:
            node = canopen.RemoteNode(NODE, str(DEFAULT_EDS))
            node.sdo.RESPONSE_TIMEOUT = SDO_TIMEOUT_S
            network.add_node(node)
            yield sim, node
        finally:
            network.disconnect()


def _state(node: canopen.RemoteNode) -> cia402.State:
    return cia402.state_of(node.sdo[cia402.STATUSWORD].raw)


def test_modes_of_operation_agree_at_power_on(drive: tuple[SimStand, canopen.RemoteNode]) -> None:
    _, node = drive
    assert node.sdo[cia402.MODES_OF_OPERATION].raw == cia402.MODE_NONE
    assert node.sdo[cia402.MODES_DISPLAY].raw == cia402.MODE_NONE
    node.sdo[cia402.MODES_OF_OPERATION].raw = cia402.MODE_CST
    assert node.sdo[cia402.MODES_DISPLAY].raw == cia402.MODE_CST


def test_power_on_pdo_mapping_is_cia402_predefined(drive: tuple[SimStand, canopen.RemoteNode]) -> None:
    _, node = drive
    for index, entries in PREDEFINED.items():
        assert node.sdo[index][0].raw == len(entries), hex(index)
        assert [node.sdo[index][k].raw for k in range(1, len(entries) + 1)] == entries, hex(index)


def test_supported_drive_modes_include_the_manufacturer_mode(
        drive: tuple[SimStand, canopen.RemoteNode]) -> None:
    _, node = drive
    supported = node.sdo[0x6502].raw
    assert supported & CSV_BIT and supported & CST_BIT and supported & MANUFACTURER_MINUS_1_BIT
    node.sdo[cia402.MODES_OF_OPERATION].raw = cia402.MODE_VOLTAGE  # the mode it advertises
    assert node.sdo[cia402.MODES_DISPLAY].raw == cia402.MODE_VOLTAGE


def test_no_sdo_answer_while_stopped(drive: tuple[SimStand, canopen.RemoteNode]) -> None:
    _, node = drive
    node.nmt.send_command(0x02)  # stop
    time.sleep(SETTLE_S)
    node.sdo.RESPONSE_TIMEOUT = 0.1
    with pytest.raises(canopen.SdoCommunicationError):
        node.sdo[cia402.STATUSWORD].raw  # noqa: B018 - the read is the test
    node.nmt.send_command(0x80)  # pre-operational: SDO again
    time.sleep(SETTLE_S)
    assert _state(node) is cia402.State.SWITCH_ON_DISABLED


@pytest.mark.parametrize("shutdown", [0x0006, 0x000E, 0x0046])
def test_shutdown_is_any_controlword_xxxx_x110(drive: tuple[SimStand, canopen.RemoteNode],
                                               shutdown: int) -> None:
    _, node = drive
    node.sdo[cia402.CONTROLWORD].raw = shutdown
    assert _state(node) is cia402.State.READY_TO_SWITCH_ON
    node.sdo[cia402.CONTROLWORD].raw = 0x0007 | (shutdown & 0x0070)  # switch on, same high bits
    assert _state(node) is cia402.State.SWITCHED_ON
    node.sdo[cia402.CONTROLWORD].raw = 0x000F | (shutdown & 0x0070)
    assert _state(node) is cia402.State.OPERATION_ENABLED


def test_a_synchronous_rpdo_controlword_acts_at_the_next_sync(
        drive: tuple[SimStand, canopen.RemoteNode]) -> None:
    sim, node = drive
    node.rpdo.read()
    rpdo1 = node.rpdo[1]
    assert [var.index for var in rpdo1] == [cia402.CONTROLWORD]  # the predefined mapping
    assert rpdo1.trans_type <= 240  # synchronous
    node.nmt.send_command(0x01)  # start
    time.sleep(SETTLE_S)
    rpdo1[0].raw = cia402.CW_SHUTDOWN
    rpdo1.transmit()
    time.sleep(SETTLE_S)
    assert _state(node) is cia402.State.SWITCH_ON_DISABLED  # not yet: no SYNC since
    node.network.send_message(SYNC_COB_ID, b"")
    time.sleep(SETTLE_S)
    assert _state(node) is cia402.State.READY_TO_SWITCH_ON
    assert sim.nodes[0].syncs == 1


def test_torque_actual_value_reads_the_torque(drive: tuple[SimStand, canopen.RemoteNode]) -> None:
    sim, node = drive
    node.sdo[cia402.MODES_OF_OPERATION].raw = cia402.MODE_CST
    for word in (cia402.CW_SHUTDOWN, cia402.CW_SWITCH_ON, cia402.CW_ENABLE_OPERATION):
        node.sdo[cia402.CONTROLWORD].raw = word
    target = 300  # per mille of rated current: 0.3 A on the 1 A rated drive
    node.sdo[0x6071].raw = target
    node.sdo[0x1006].raw = 1000  # 1 ms communication cycle
    for _ in range(20):  # SYNCs move the stand (the drive is PRE-OPERATIONAL: no PDO)
        node.network.send_message(SYNC_COB_ID, b"")
    time.sleep(SETTLE_S)
    torque, current = node.sdo[cia402.TORQUE_ACTUAL].raw, node.sdo[cia402.CURRENT_ACTUAL].raw
    # Rated torque 0x6076 is the torque at rated current 0x6075: both per mille read the
    # same; the current loop holds the target within the sensor's noise (σ 10 mA = 10 ‰;
    # 5 σ: 3 σ failed here once in some hundred runs, as a normal tail does).
    assert torque == current
    assert abs(torque - target) <= 50
    assert sim.nodes[0].syncs == 20
