"""A master we did not write drives our simulated drive (issue 20, foreign-master suite).

canopen's own CiA 402 client, ``canopen.profiles.p402.BaseNode402``, takes the simulated
drive through boot, reading and mapping its PDOs, OPERATION ENABLED, cyclic synchronous
velocity and torque, quick stop and disable, with canopen's SYNC producer and cyclic
RPDOs. Nothing of ours runs on the master side.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Iterator

import pytest
from canopen.profiles.p402 import BaseNode402

from bus import cia402
from bus.adapters import BusConfig, connect_network
from bus.eds import DEFAULT_EDS
from bus.simstand import SimStand
from stand.profiles import load_motor

MOTOR = "crouzet_82800502"
NODE = 1
#: SYNC and RPDO period of the foreign master, s (canopen's producers are Python threads
#: on the virtual bus; the drive's physics step is set to it through 0x1006). 5 ms: at
#: 2 ms the foreign master and the drive, one process under User-Mode Linux, fell behind
#: the cycle, and an SDO answer took 0.4-0.7 s against the client's 0.5 s (fresh
#: machine, canopen 2.4.1, python-can 4.6.1; the mode switch was then silently dropped).
CYCLE_S = 0.005
BOOT_TIMEOUT_S = 2.0
#: Time the speed loop (tens of Hz) and the current loop get to settle, s.
SETTLE_S = 0.6
#: Speed command, rad/s (well inside the motor's limit), and its unit on the bus (0.001 rad/s).
SPEED_RAD_S = 50.0
VELOCITY_UNIT = 1e-3
#: Speed tolerance: a few encoder counts a sample of velocity noise plus the loop's ripple.
SPEED_RTOL = 0.05
#: Torque command in per mille of rated current (and of rated torque), and its tolerance:
#: the 10 mA current noise of the motor profile is 10 per mille at 1 A rated current.
TORQUE_PER_MILLE = 200
TORQUE_TOL_PER_MILLE = 40


def _reset(node: BaseNode402) -> None:
    """NMT reset node and wait for the boot-up (canopen's ``wait_for_bootup`` only sees a
    boot-up that comes after it was called: on SocketCAN the drive is quicker)."""
    booted = threading.Event()

    def on_heartbeat(state: int) -> None:
        if state == 0:
            booted.set()

    node.nmt.add_heartbeat_callback(on_heartbeat)
    node.nmt.state = "RESET"
    assert booted.wait(BOOT_TIMEOUT_S), "no boot-up message after NMT reset node"
    node.nmt._callbacks.remove(on_heartbeat)


def _wait_for(predicate: object, timeout_s: float = 2.0) -> bool:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if predicate():  # type: ignore[operator]
            return True
        time.sleep(CYCLE_S)
    return False


@pytest.fixture
def foreign(can_config: BusConfig) -> Iterator[tuple[SimStand, BaseNode402]]:
    """The simulated drive and canopen's CiA 402 node on a canopen network of its own."""
    with SimStand(MOTOR, can_config) as sim:
        network = connect_network(can_config)
        node = BaseNode402(NODE, str(DEFAULT_EDS))
        node.sdo.RESPONSE_TIMEOUT = 0.5
        network.add_node(node)
        try:
            yield sim, node
        finally:
            network.sync.stop()
            for pdo in (*node.rpdo.values(), *node.tpdo.values()):
                pdo.stop()
            network.disconnect()


def test_base_node_402_runs_the_simulated_drive(foreign: tuple[SimStand, BaseNode402]) -> None:
    sim, node = foreign
    # Boot: NMT reset node, wait for the boot-up message.
    _reset(node)
    assert node.nmt.state == "PRE-OPERATIONAL"

    # Read the PDO configuration: the CiA 402 predefined mapping.
    node.pdo.read()
    assert [v.index for v in node.rpdo[1]] == [cia402.CONTROLWORD]
    assert [v.index for v in node.tpdo[1]] == [cia402.STATUSWORD]

    # Map: RPDO1 controlword + target velocity + target torque; TPDO1 statusword + velocity
    # actual; TPDO2 modes of operation display + torque actual; all synchronous.
    node.rpdo[1].clear()
    for name in ("Controlword", "Target velocity", "Target torque"):
        node.rpdo[1].add_variable(name)
    node.tpdo[1].clear()
    for name in ("Statusword", "Velocity actual value"):
        node.tpdo[1].add_variable(name)
    node.tpdo[2].clear()
    for name in ("Modes of operation display", "Torque actual value"):
        node.tpdo[2].add_variable(name)
    for pdo in (node.rpdo[1], node.tpdo[1], node.tpdo[2]):
        pdo.trans_type = 1
        pdo.enabled = True
    node.rpdo[2].enabled = False
    node.tpdo[2].cob_id = node.tpdo[2].predefined_cob_id
    node.pdo.save()
    node.sdo[0x1006].raw = int(CYCLE_S * 1e6)  # communication cycle period, µs
    node.setup_402_state_machine(read_pdos=True)  # reads back what was written
    assert [v.index for v in node.rpdo[1]] == [cia402.CONTROLWORD, 0x60FF, 0x6071]
    assert [v.index for v in node.tpdo[2]] == [cia402.MODES_DISPLAY, cia402.TORQUE_ACTUAL]

    # Operational, with canopen's SYNC producer and its cyclic RPDO.
    node.rpdo[1]["Controlword"].raw = cia402.CW_DISABLE_VOLTAGE
    node.nmt.state = "OPERATIONAL"
    node.tpdo[1].wait_for_reception(1.0)
    node.network.sync.start(CYCLE_S)
    node.rpdo[1].start(CYCLE_S)
    assert node.tpdo[1].wait_for_reception(1.0) is not None

    # Cyclic synchronous velocity.
    node.op_mode = "CYCLIC SYNCHRONOUS VELOCITY"
    assert node.op_mode == "CYCLIC SYNCHRONOUS VELOCITY"
    node.state = "OPERATION ENABLED"
    assert node.state == "OPERATION ENABLED"
    node.rpdo[1]["Target velocity"].raw = int(SPEED_RAD_S / VELOCITY_UNIT)
    time.sleep(SETTLE_S)
    speed = node.tpdo[1]["Velocity actual value"].raw * VELOCITY_UNIT
    assert speed == pytest.approx(SPEED_RAD_S, rel=SPEED_RTOL)

    # Cyclic synchronous torque: the torque actual value follows the target.
    node.rpdo[1]["Target torque"].raw = TORQUE_PER_MILLE
    node.op_mode = "CYCLIC SYNCHRONOUS TORQUE"
    assert node.op_mode == "CYCLIC SYNCHRONOUS TORQUE"
    assert _wait_for(lambda: abs(node.tpdo[2]["Torque actual value"].raw - TORQUE_PER_MILLE)
                     <= TORQUE_TOL_PER_MILLE), node.tpdo[2]["Torque actual value"].raw

    # Quick stop: the drive brakes to standstill in speed control.
    node.state = "QUICK STOP ACTIVE"
    assert node.state == "QUICK STOP ACTIVE"
    assert sim.nodes[0].quick_stop_at is not None
    limit = load_motor(MOTOR).limits.speed_rad_s
    assert _wait_for(lambda: abs(node.tpdo[1]["Velocity actual value"].raw * VELOCITY_UNIT)
                     < 0.02 * limit)

    # Disable.
    node.state = "SWITCH ON DISABLED"
    assert node.state == "SWITCH ON DISABLED"
    assert not sim.nodes[0].sm.enabled


def test_base_node_402_boot_and_pdo_read_see_the_drive_pre_operational(
        foreign: tuple[SimStand, BaseNode402]) -> None:
    _, node = foreign
    _reset(node)
    node.setup_402_state_machine(read_pdos=True)
    assert node.rpdo_pointers[cia402.CONTROLWORD].index == cia402.CONTROLWORD
    assert cia402.STATUSWORD in node.tpdo_values
    assert node.is_op_mode_supported("CYCLIC SYNCHRONOUS VELOCITY")
    assert node.is_op_mode_supported("CYCLIC SYNCHRONOUS TORQUE")
    # No mode yet; and no TPDO before OPERATIONAL, so canopen reads it over SDO here.
    assert node.sdo[cia402.MODES_DISPLAY].raw == cia402.MODE_NONE
