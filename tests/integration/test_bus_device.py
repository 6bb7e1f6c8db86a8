"""The device check before configuring (issue 20, item 4): the master reads 0x1000 and 0x1018,
compares them with the drive's EDS or DCF, refuses what does not fit before it writes
anything, and gives objects only the simulation has to a simulated drive only."""

from __future__ import annotations

import re
from collections.abc import Iterator
from dataclasses import replace
from pathlib import Path

import can
import numpy as np
import pytest

from bus.adapters import BusConfig, connect_network
from bus.cia301 import SDO_REQUEST_BASE
from bus.eds import DEFAULT_EDS
from bus.sim_device import SimIoDevice
from bus.simstand import SimStand
from bus.stand_bus import StandBus
from stand.cli import main
from stand.controller import ExperimentProfile, StandController, plan
from stand.errors import DeviceMismatch, InputError, ProfileError
from stand.profiles import resolve
from stand.runfile import CURRENT_MEAN_COLUMN, read_run

MOTOR = "crouzet_82800502"
#: Heartbeat period: long enough that a one-CPU User-Mode Linux on a loaded host never
#: starves a heartbeat into a false alarm, s.
CALM_HEARTBEAT_S = 0.5
IO_NODE = 5
#: Noise seed of the simulated drives, the same for every run compared.
SEED = 3
#: A vendor's identity for the "real" drive (any vendor id and product code but ours).
VENDOR_ID, PRODUCT_CODE = 0x000001AB, 0x00402001
#: SDO client command specifier (CiA 301 §7.2.4.3): bits 5-7 of the first byte; 1 starts a
#: download (a write), 2 an upload (a read).
CCS_SHIFT, CCS_DOWNLOAD = 5, 1
ADDED_INERTIA = ExperimentProfile(name="x", procedure="added_inertia", motor=MOTOR, repeats=1,
                                  duration_s=0.5, period_s=0.001)


def vendor_file(directory: Path, suffix: str) -> Path:
    """The simulated drive's EDS as a vendor would ship it for its own drive: another identity,
    the same objects (0x2100 stays, as a vendor parameter of the same index would)."""
    text = DEFAULT_EDS.read_text()
    text = re.sub(r"VendorNumber=\S+", f"VendorNumber=0x{VENDOR_ID:08X}", text)
    text = re.sub(r"ProductNumber=\S+", f"ProductNumber=0x{PRODUCT_CODE:08X}", text)
    for sub, value in ((1, VENDOR_ID), (2, PRODUCT_CODE)):
        text = re.sub(rf"(\[1018sub{sub}\][^\[]*?DefaultValue=)\S+", rf"\g<1>0x{value:08X}", text)
    text = text.replace("ParameterName=Simulated added inertia", "ParameterName=Vendor parameter")
    path = directory / f"vendor_drive{suffix}"
    path.write_text(text)
    return path


class SdoRequests(can.Listener):
    """Every SDO request frame to one node, as another participant on the bus sees it."""

    def __init__(self, node_id: int) -> None:
        self.cob_id = SDO_REQUEST_BASE + node_id
        self.commands: list[int] = []

    def on_message_received(self, msg: can.Message) -> None:
        if msg.arbitration_id == self.cob_id and msg.data:
            self.commands.append(msg.data[0] >> CCS_SHIFT)


@pytest.fixture
def probe(can_config: BusConfig) -> Iterator[SdoRequests]:
    listener = SdoRequests(IO_NODE)
    with can.Bus(interface=can_config.interface, channel=can_config.channel) as bus:
        notifier = can.Notifier(bus, [listener], timeout=0.05)
        try:
            yield listener
        finally:
            notifier.stop()


def test_a_non_drive_device_is_refused_before_anything_is_written(
        can_config: BusConfig, probe: SdoRequests) -> None:
    (_, drives), = plan(ADDED_INERTIA)
    at_io_node = [type(drives[0])(**{**drives[0].__dict__, "node_id": IO_NODE})]
    network = connect_network(can_config, role="drive")
    io = SimIoDevice(network, IO_NODE)
    try:
        with StandBus(None, can_config, simulate=False, heartbeat_period_s=CALM_HEARTBEAT_S) as bus, \
                pytest.raises(DeviceMismatch, match=r"node 5: device type 0x00030191 \(CiA 401 "
                              r"generic I/O\).*not a CiA 402 drive; nothing was written"):
            bus.setup(at_io_node, 0.001)
    finally:
        io.close()
        network.disconnect()
    assert probe.commands and CCS_DOWNLOAD not in probe.commands  # reads only
    assert io.node.data_store == {}


def test_a_drive_its_eds_does_not_describe_is_refused(can_config: BusConfig, tmp_path: Path) -> None:
    (_, drives), = plan(ADDED_INERTIA)
    with SimStand(MOTOR, can_config, eds=vendor_file(tmp_path, ".eds")), \
            StandBus(None, can_config, simulate=False, heartbeat_period_s=CALM_HEARTBEAT_S) as bus, \
            pytest.raises(DeviceMismatch, match=r"node 1: the device is vendor id 0x000001AB, product "
                          r"code 0x00402001, but .*motorstand_cia402.eds describes .*--eds FILE"):
        bus.setup(drives, 0.001)


@pytest.mark.parametrize("suffix", [".eds", ".dcf"])
def test_a_real_drive_runs_with_its_vendor_file_and_gets_no_simulation_object(
        can_config: BusConfig, tmp_path: Path, suffix: str) -> None:
    (procedure, drives), = plan(ADDED_INERTIA)
    vendor = vendor_file(tmp_path, suffix)
    with SimStand(MOTOR, can_config, eds=vendor) as sim, \
            StandBus(None, can_config, simulate=False, eds=vendor,
                     heartbeat_period_s=CALM_HEARTBEAT_S) as bus:
        record = StandController(bus).run_procedure(procedure, drives, tmp_path)
        drive = bus.master.drives[0]
        assert drive.identity is not None and not drive.simulated
        assert (drive.identity.vendor_id, drive.identity.product_code) == (VENDOR_ID, PRODUCT_CODE)
        assert sim.added_inertia == 0.0  # 0x2100 is the vendor's object here: never written
        assert [layout.indices for _, layout in drive.tpdos][1] == (0x606C,)  # no 0x2001
    assert record.complete and record.samples == procedure.samples


def test_voltage_mode_is_refused_on_a_real_drive(can_config: BusConfig, tmp_path: Path) -> None:
    (_, drives), = plan(ADDED_INERTIA)
    vendor = vendor_file(tmp_path, ".eds")
    in_voltage = [type(drives[0])(**{**drives[0].__dict__, "mode": "voltage"})]
    with SimStand(MOTOR, can_config, eds=vendor), \
            StandBus(None, can_config, simulate=False, eds=vendor,
                     heartbeat_period_s=CALM_HEARTBEAT_S) as bus, \
            pytest.raises(InputError, match="node 1: voltage mode is the simulated drive's"):
        bus.setup(in_voltage, 0.001)


@pytest.mark.parametrize(("field", "wrong", "message"), [
    ("counts_per_rev", 4096, r"node 1: position encoder resolution 0x608F is 10000 increments per "
                             r"1 revolution\(s\), the motor profile's encoder gives 4096 counts"),
    ("rated_current_A", 2.0, r"node 1: motor rated current 0x6075 is 1000 mA, the motor profile "
                             r"says 2 A"),
])
def test_a_drive_whose_units_are_not_the_profiles_is_refused_before_anything_is_written(
        can_config: BusConfig, field: str, wrong: float, message: str) -> None:
    """Positions and currents travel in the drive's units (0x608F increments, per mille of
    0x6075): a profile that says otherwise would have every sample misread."""
    (_, drives), = plan(ADDED_INERTIA)
    assert (drives[0].counts_per_rev, drives[0].rated_current_A) == (10_000, 1.0)  # the profile's
    misdescribed = [type(drives[0])(**{**drives[0].__dict__, field: wrong})]
    requests = SdoRequests(1)
    with SimStand(MOTOR, can_config), \
            can.Bus(interface=can_config.interface, channel=can_config.channel) as witness:
        notifier = can.Notifier(witness, [requests], timeout=0.05)
        try:
            with StandBus(None, can_config, simulate=False,
                          heartbeat_period_s=CALM_HEARTBEAT_S) as bus, \
                    pytest.raises(DeviceMismatch, match=message + r".*nothing was written"):
                bus.setup(misdescribed, 0.001)
        finally:
            notifier.stop()
    assert requests.commands and CCS_DOWNLOAD not in requests.commands  # reads only


def _mean_currents(folder: Path) -> np.ndarray:
    (path,) = folder.glob("*.csv")
    return read_run(path, "single")[CURRENT_MEAN_COLUMN]


#: A run the simulated drive and the "vendor's" run alike (no added inertia, which only the
#: simulated drive is told of).
NO_LOAD = ExperimentProfile(name="x", procedure="no_load", motor=MOTOR, repeats=1,
                            duration_s=0.5, period_s=0.001)
#: A per count of the "vendor's" period-mean current in the second case: twice the per
#: mille of the 1 A rated current that the simulated drive's 0x2002 counts in.
DOUBLE_UNIT_A = 0.002


@pytest.mark.parametrize(("unit", "scale"), [(None, 1.0), (DOUBLE_UNIT_A, 2.0)])
def test_a_real_drive_maps_the_period_mean_current_its_motor_profile_names(
        can_config: BusConfig, tmp_path: Path, unit: float | None, scale: float) -> None:
    """A real drive gets no object of the simulation's (0x2002 is the vendor's own here),
    unless the motor profile names it as the drive's current averaged over each SYNC
    period (``drive.current_mean_object``, in ``current_mean_unit_A``): then TPDO3
    carries it into the run's ``current_mean_A``, as the simulated drive's own does."""
    (procedure, drives), = plan(NO_LOAD)
    vendor = vendor_file(tmp_path, ".eds")
    named = [replace(drives[0], current_mean=(0x2002, 0), current_mean_unit_A=unit)]
    runs = {}
    for name, setup, eds in (("plain", drives, vendor), ("named", named, vendor),
                             ("simulated", drives, None)):
        folder = tmp_path / name
        with SimStand(MOTOR, can_config, seed=SEED, eds=eds), \
                StandBus(None, can_config, simulate=False, eds=eds,
                         heartbeat_period_s=CALM_HEARTBEAT_S) as bus:
            record = StandController(bus).run_procedure(procedure, setup, folder)
            assert record.complete
            runs[name] = [layout.indices for _, layout in bus.master.drives[0].tpdos]
        if name != "plain":
            runs[name + " column"] = _mean_currents(folder)
    # its trace reads back with the motor profile that names the object (and its unit)
    profile = tmp_path / "vendor_motor.yaml"
    profile.write_text(resolve(MOTOR, "motors").read_text().replace(
        "drive:\n", "drive:\n  current_mean_object: 0x2002\n"
        + (f"  current_mean_unit_A: {unit}\n" if unit else ""), 1))
    back = tmp_path / "back.csv"
    assert main(["import", str(tmp_path / "named" / "no_load_1.log"), "-o", str(back),
                 "--motor", str(profile), "--eds", str(vendor)]) == 0
    assert np.array_equal(read_run(back)[CURRENT_MEAN_COLUMN], runs["named column"])
    # without the profile, 0x2002 of this drive's EDS is the vendor's own object: not read
    assert main(["import", str(tmp_path / "named" / "no_load_1.log"), "-o", str(back),
                 "--eds", str(vendor)]) == 0
    assert CURRENT_MEAN_COLUMN not in read_run(back)
    assert runs["plain"] == [(0x6064, 0x6078), (0x606C,)]  # no TPDO3 on a real drive
    assert runs["named"] == [(0x6064, 0x6078), (0x606C,), (0x2002,)]
    assert runs["simulated"] == [(0x6064, 0x6078), (0x606C, 0x2001), (0x2002,)]
    assert np.array_equal(runs["named column"], scale * runs["simulated column"])
    assert np.ptp(runs["simulated column"]) > 0


@pytest.mark.parametrize(("address", "message"), [
    ((0x2345, 0), r"0x2345:00 is not in the drive's EDS .*vendor_drive.eds"),
    ((0x6075, 0), r"0x6075:00 \(Motor rated current\) is not PDO-mappable"),
])
def test_a_period_mean_object_the_drive_cannot_send_is_refused_before_anything_is_written(
        can_config: BusConfig, tmp_path: Path, address: tuple[int, int], message: str) -> None:
    (_, drives), = plan(ADDED_INERTIA)
    vendor = vendor_file(tmp_path, ".eds")
    requests = SdoRequests(1)
    with SimStand(MOTOR, can_config, eds=vendor), \
            can.Bus(interface=can_config.interface, channel=can_config.channel) as witness:
        notifier = can.Notifier(witness, [requests], timeout=0.05)
        try:
            with StandBus(None, can_config, simulate=False, eds=vendor,
                          heartbeat_period_s=CALM_HEARTBEAT_S) as bus, \
                    pytest.raises(ProfileError, match=r"node 1: the motor profile's "
                                  r"drive.current_mean_object " + message):
                bus.setup([replace(drives[0], current_mean=address)], 0.001)
        finally:
            notifier.stop()
    assert CCS_DOWNLOAD not in requests.commands  # nothing was written
