"""The master's view of one CiA 402 drive: SDO access, PDO mapping, enabling.

Works with any CiA 402 drive whose EDS (or DCF) is given: :meth:`Drive.check_device` first
reads the device type and identity and refuses a device its EDS does not describe; then
the PDO layouts are written over SDO (CiA 301 §7.2.2: invalidate the PDO, clear the
mapping, write the entries, set the count, set the transmission type, make it valid
again). Objects only the simulated drive has are used only on a simulated drive.
"""

from __future__ import annotations

import contextlib
import time
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import canopen

from bus import cia402
from bus.cia301 import (
    DEVICE_TYPE,
    IDENTITY,
    PRODUCT_CODE,
    RPDO_COMMUNICATION,
    RPDO_MAPPING,
    TPDO_COMMUNICATION,
    TPDO_MAPPING,
    VENDOR_ID,
)
from bus.device import CIA402_PROFILE, DeviceIdentity, eds_identity, is_simulated
from bus.eds import DEFAULT_EDS, Scaling, load_od
from bus.pdo import COB_ID_INVALID, SYNCHRONOUS, Layout, Mapped, entries_for, mapped_variable
from stand.errors import BusError, BusTimeout, DeviceMismatch, DriveFault, InputError, ProfileError

#: Time an SDO answer may take, s.
SDO_TIMEOUT_S = 0.3
#: Time a drive may take to reach a CiA 402 state after a controlword, s.
STATE_TIMEOUT_S = 0.5
STATE_POLL_S = 0.005
DRIVE_MODES = tuple(cia402.MODES)
#: Short names of the PDO parameter bases (bus.tracereader reads them from here).
TPDO_COMM, TPDO_MAP = TPDO_COMMUNICATION, TPDO_MAPPING


@dataclass(frozen=True)
class DriveConfig:
    """One drive of a run.

    Parameters
    ----------
    node_id : int
        CANopen node id.
    mode : {'speed', 'current', 'voltage'}
        What the run commands.
    scaling : Scaling
        Units of its raw values.
    eds : path or None
        Its EDS (default: the simulated drive's).
    velocity : bool
        Also map velocity actual (and, on a simulated drive, voltage actual 0x2001) into TPDO2.
    current_mean : (int, int) or None
        The drive's object (index, subindex) holding its current averaged over each SYNC
        period, mapped into TPDO3 (the motor profile's ``drive.current_mean_object``; its
        unit is ``scaling.current_mean_unit_A``). None: the simulated drive's 0x2002 where
        the drive is the simulated one, else none.
    """

    node_id: int
    mode: str
    scaling: Scaling
    eds: str | Path | None = None
    velocity: bool = True
    current_mean: tuple[int, int] | None = None

    def __post_init__(self) -> None:
        if self.mode not in DRIVE_MODES:
            raise InputError(f"drive mode must be one of {', '.join(DRIVE_MODES)}, not {self.mode!r}")


def tpdo_objects(od: canopen.ObjectDictionary, simulated: bool = True,
                 current_mean: tuple[int, int] | None = None) -> list[list[Mapped]]:
    """The objects the master maps into the TPDOs of a drive with object dictionary
    ``od``: TPDO1 position and current actual; TPDO2 velocity actual (and voltage actual
    when the drive is the simulated one and ``od`` has 0x2001, an object only the
    simulation has); TPDO3 the current averaged over the communication cycle (column
    ``current_mean_A``): the object ``current_mean`` (index, subindex) names, else, on the
    simulated drive whose ``od`` offers it, 0x2002."""
    voltage = simulated and cia402.VOLTAGE_ACTUAL in od
    second: list[Mapped] = [cia402.VELOCITY_ACTUAL, *([cia402.VOLTAGE_ACTUAL] if voltage else [])]
    objects: list[list[Mapped]] = [[cia402.POSITION_ACTUAL, cia402.CURRENT_ACTUAL], second]
    if current_mean is not None:
        objects.append([current_mean])
    elif simulated and cia402.CURRENT_MEAN in od and TPDO_COMMUNICATION + 2 in od:
        objects.append([cia402.CURRENT_MEAN])
    return objects


class Drive:
    """A remote CiA 402 drive on the master's network."""

    def __init__(self, network: canopen.Network, config: DriveConfig,
                 sdo_timeout_s: float = SDO_TIMEOUT_S) -> None:
        self.config = config
        self.id = config.node_id
        self.od = load_od(config.eds, config.node_id)
        if config.current_mean is not None:
            self._check_current_mean(config.current_mean)
        self.node = canopen.RemoteNode(config.node_id, self.od)
        self.node.sdo.RESPONSE_TIMEOUT = sdo_timeout_s
        self.node.sdo.MAX_RETRIES = 1  # canopen counts the first try: one try, no retry
        network.add_node(self.node)
        self.network = network
        #: What the device said it is (:meth:`check_device`), and whether it is simulated.
        self.identity: DeviceIdentity | None = None
        self.simulated = False
        self.rpdo_cob_id = 0
        self.rpdo: Layout | None = None
        self.tpdos: list[tuple[int, Layout]] = []
        self.controlword = cia402.CW_DISABLE_VOLTAGE

    def _check_current_mean(self, address: tuple[int, int]) -> None:
        """Refuse, before anything is written, a period-mean current object that the EDS
        lacks or that no free TPDO can carry (TPDO3 holds it)."""
        index, sub = address
        where = (f"node {self.id}: the motor profile's drive.current_mean_object "
                 f"0x{index:04X}:{sub:02X}")
        eds = self.config.eds or DEFAULT_EDS
        try:
            var = mapped_variable(self.od, index, sub)
        except ProfileError as exc:
            raise ProfileError(f"{where} is not in the drive's EDS {eds}; name an object the "
                               "drive has, or leave the field out") from exc
        if not var.pdo_mappable:
            raise ProfileError(f"{where} ({var.name}) is not PDO-mappable in {eds}")
        if TPDO_COMMUNICATION + 2 not in self.od:
            raise ProfileError(f"{where}: {eds} offers no TPDO3 (0x{TPDO_COMMUNICATION + 2:04X}) "
                               "to carry it")

    # -- SDO ---------------------------------------------------------------------------
    def _variable(self, index: int, subindex: int) -> Any:
        try:
            obj = self.node.sdo[index]
            return obj[subindex] if not isinstance(obj, canopen.sdo.base.Variable) else obj
        except KeyError as exc:
            raise BusError(f"node {self.id}: object 0x{index:04X}:{subindex} is not in its EDS") from exc

    @contextlib.contextmanager
    def _sdo(self, index: int, subindex: int, var: Any, reading: str,
             aborted: str) -> Iterator[None]:
        """Name the node and the object in SDO errors (``reading``/``aborted`` say what)."""
        try:
            yield
        except canopen.SdoCommunicationError as exc:
            raise BusTimeout(f"node {self.id}: no SDO answer {reading} 0x{index:04X}:{subindex} "
                             f"({var.name}): {exc}; is the drive powered and on the bus?") from exc
        except canopen.SdoAbortedError as exc:
            raise BusError(f"node {self.id}: SDO {aborted} 0x{index:04X}:{subindex} ({var.name}) "
                           f"aborted: {exc}") from exc

    def read(self, index: int, subindex: int = 0) -> Any:
        """SDO upload of ``index:subindex``; errors name the node and the object."""
        var = self._variable(index, subindex)
        with self._sdo(index, subindex, var, "reading", "read of"):
            return var.raw

    def write(self, index: int, subindex: int, value: Any) -> None:
        """SDO download of ``value`` to ``index:subindex``."""
        var = self._variable(index, subindex)
        with self._sdo(index, subindex, var, "writing", f"write of {value!r} to"):
            var.raw = value

    def has(self, index: int) -> bool:
        """True when the drive's EDS has object ``index``."""
        return index in self.od

    def check_device(self) -> DeviceIdentity:
        """Read 0x1000 and 0x1018 and compare them with the EDS; writes nothing.

        Raises
        ------
        DeviceMismatch
            The device is no CiA 402 drive, or its vendor id and product code are not the
            EDS's.
        InputError
            Voltage mode (the simulation's manufacturer mode) asked of a real drive.
        """
        found = DeviceIdentity(int(self.read(DEVICE_TYPE)), int(self.read(IDENTITY, VENDOR_ID)),
                               int(self.read(IDENTITY, PRODUCT_CODE)))
        eds = self.config.eds or DEFAULT_EDS
        if found.profile != CIA402_PROFILE:
            raise DeviceMismatch(f"node {self.id}: {found.describe()}, not a CiA 402 drive; "
                                 "nothing was written to it; is the node id right?")
        expected = eds_identity(self.od)
        if expected is not None and (found.vendor_id, found.product_code) != (
                expected.vendor_id, expected.product_code):
            raise DeviceMismatch(
                f"node {self.id}: the device is vendor id 0x{found.vendor_id:08X}, product code "
                f"0x{found.product_code:08X}, but {eds} describes vendor id 0x{expected.vendor_id:08X}, "
                f"product code 0x{expected.product_code:08X}; nothing was written to it; give the "
                "drive's own EDS or DCF (stand run --eds FILE)")
        self.identity, self.simulated = found, is_simulated(found)
        if self.config.mode == "voltage" and not self.simulated:
            raise InputError(f"node {self.id}: voltage mode is the simulated drive's manufacturer "
                             f"mode (target 0x{cia402.TARGET_OBJECT['voltage'][0]:04X}); this is a "
                             f"real drive ({found.describe()}): run it in speed or current mode")
        return found

    def check_units(self) -> None:
        """Read the motor rated current 0x6075 and the position encoder resolution 0x608F,
        where the EDS has them, and compare them with the units of :attr:`config`; writes
        nothing. The reads also put the drive's units into a trace of the setup.

        Raises
        ------
        DeviceMismatch
            The drive's rated current or encoder resolution is not the one its scaling (the
            motor profile) says: currents or positions would be read in the wrong unit.
        """
        scaling = self.config.scaling
        if self.has(cia402.RATED_CURRENT):
            rated_mA = int(self.read(cia402.RATED_CURRENT))
            if rated_mA != scaling.rated_current_mA:
                raise DeviceMismatch(
                    f"node {self.id}: motor rated current 0x6075 is {rated_mA} mA, the motor profile "
                    f"says {scaling.rated_current_A:g} A; currents (per mille of 0x6075) would be "
                    "misread; set the profile's drive.rated_current_A or the drive's 0x6075; "
                    "nothing was written to it")
        if self.has(cia402.POSITION_ENCODER_RESOLUTION):
            increments = int(self.read(cia402.POSITION_ENCODER_RESOLUTION, cia402.ENCODER_INCREMENTS))
            revolutions = int(self.read(cia402.POSITION_ENCODER_RESOLUTION, cia402.MOTOR_REVOLUTIONS))
            if increments != scaling.counts_per_rev * revolutions:
                raise DeviceMismatch(
                    f"node {self.id}: position encoder resolution 0x608F is {increments} increments "
                    f"per {revolutions} revolution(s), the motor profile's encoder gives "
                    f"{scaling.counts_per_rev} counts per revolution; positions (0x6064, read as "
                    "encoder increments) would be misread; fix the profile's encoder or the drive; "
                    "nothing was written to it")

    # -- PDO mapping -------------------------------------------------------------------
    def _map(self, comm: int, mapping: int, indices: list[Mapped]) -> tuple[int, Layout]:
        cob_id = int(self.read(comm, 1)) & 0x7FF
        self.write(comm, 1, cob_id | COB_ID_INVALID)
        self.write(mapping, 0, 0)
        entries = entries_for(self.od, indices)
        for k, value in enumerate(entries, start=1):
            self.write(mapping, k, value)
        self.write(mapping, 0, len(entries))
        self.write(comm, 2, SYNCHRONOUS)
        self.write(comm, 1, cob_id)
        return cob_id, Layout.from_entries(self.od, entries)

    def _unmap(self, comm: int) -> None:
        if comm in self.od:
            cob_id = int(self.read(comm, 1))
            self.write(comm, 1, cob_id | COB_ID_INVALID)

    def configure_pdos(self) -> None:
        """Map RPDO1 (controlword + target) and the TPDOs of :func:`tpdo_objects` (actual
        values) over SDO."""
        target = cia402.TARGET_OBJECT[self.config.mode][0]
        self.rpdo_cob_id, self.rpdo = self._map(RPDO_COMMUNICATION, RPDO_MAPPING,
                                                [cia402.CONTROLWORD, target])
        self._unmap(RPDO_COMMUNICATION + 1)
        first, second, *rest = tpdo_objects(self.od, self.simulated, self.config.current_mean)
        self.tpdos = [self._map(TPDO_COMMUNICATION, TPDO_MAPPING, first)]
        if self.config.velocity:
            self.tpdos.append(self._map(TPDO_COMMUNICATION + 1, TPDO_MAPPING + 1, second))
        else:
            self._unmap(TPDO_COMMUNICATION + 1)
        for n, objects in enumerate(rest, start=2):
            self.tpdos.append(self._map(TPDO_COMMUNICATION + n, TPDO_MAPPING + n, objects))

    def rpdo_data(self, controlword: int, target_SI: float) -> bytes:
        """RPDO1 data for ``controlword`` and a target in SI units (rad/s, A or V)."""
        assert self.rpdo is not None, "configure_pdos() first"
        raw = self.config.scaling.target_raw(self.config.mode, target_SI)
        return self.rpdo.pack([controlword, raw])

    # -- CiA 402 -----------------------------------------------------------------------
    def state(self) -> cia402.State:
        return cia402.state_of(int(self.read(cia402.STATUSWORD)))

    def command(self, controlword: int, expect: cia402.State | None = None,
                timeout_s: float = STATE_TIMEOUT_S) -> cia402.State:
        """Write a controlword over SDO and wait for the state ``expect``."""
        self.write(cia402.CONTROLWORD, 0, controlword)
        self.controlword = controlword
        state = self.state()
        deadline = time.monotonic() + timeout_s
        while expect is not None and state is not expect:
            if state is cia402.State.FAULT:
                code = self.read(cia402.ERROR_CODE) if self.has(cia402.ERROR_CODE) else 0
                raise DriveFault(f"node {self.id}: drive in FAULT (error code 0x{code:04X}) while "
                                 f"waiting for {expect.name}; clear the fault and retry")
            if time.monotonic() > deadline:
                raise BusTimeout(f"node {self.id}: drive stayed in {state.name}, expected "
                                 f"{expect.name} within {timeout_s} s after controlword 0x{controlword:04X}")
            time.sleep(STATE_POLL_S)
            state = self.state()
        return state

    def enable(self) -> None:
        """Fault reset if needed, then shutdown → switch on → enable operation."""
        S = cia402.State
        if self.state() is S.FAULT:
            self.command(cia402.CW_FAULT_RESET, S.SWITCH_ON_DISABLED)
        self.command(cia402.CW_DISABLE_VOLTAGE, S.SWITCH_ON_DISABLED)
        self.command(cia402.CW_SHUTDOWN, S.READY_TO_SWITCH_ON)
        self.command(cia402.CW_SWITCH_ON, S.SWITCHED_ON)
        self.command(cia402.CW_ENABLE_OPERATION, S.OPERATION_ENABLED)

    def disable(self) -> None:
        self.command(cia402.CW_DISABLE_VOLTAGE, cia402.State.SWITCH_ON_DISABLED)
