"""CAN bus adapters chosen by name (python-can's interface table).

``virtual`` (in-process, the embedded default), ``socketcan`` (``vcan0`` or a real
``can0``) and any other python-can interface, with its options passed through.
``udp_multicast`` is refused: its datagrams leave the machine.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Any

import can
import canopen

from bus.cia301 import (
    EMCY_BASE,
    HEARTBEAT_BASE,
    NMT_COB_ID,
    RPDO_BASES,
    SDO_REQUEST_BASE,
    SDO_RESPONSE_BASE,
    SYNC_COB_ID,
    TPDO_BASES,
)
from stand.errors import BusError, InputError

#: Interfaces that must never be used (traffic would leave the machine).
FORBIDDEN_INTERFACES = ("udp_multicast",)
#: Longest wait of a bus reader thread for one frame (bounds the time to close), s.
NOTIFIER_CYCLE_S = 0.1
#: The embedded default: python-can's in-process virtual bus.
DEFAULT_INTERFACE = "virtual"
DEFAULT_CHANNEL = "motorstand"
#: Mask of a CANopen function code: the 4 high bits of an 11-bit COB-ID select the object.
FUNCTION_MASK = 0x780
EXACT_MASK = 0x7FF
#: What a master must hear (CiA 301 predefined connection set, any node id): EMCY (and a
#: SYNC), TPDO1-4, SDO responses, heartbeats; and NMT commands (exact id), for another
#: master's. 11-bit frames only.
MASTER_RECEIVES = (EMCY_BASE, *TPDO_BASES, SDO_RESPONSE_BASE, HEARTBEAT_BASE)
MASTER_RECEIVES_EXACT = (NMT_COB_ID,)
#: What a drive must hear: NMT and SYNC (exact ids), RPDO1-4 and SDO requests (any node id).
DRIVE_RECEIVES_EXACT = (NMT_COB_ID, SYNC_COB_ID)
DRIVE_RECEIVES = (*RPDO_BASES, SDO_REQUEST_BASE)


def receive_filters(role: str) -> list[dict[str, Any]]:
    """python-can ``can_filters`` passing only the 11-bit frames ``role`` needs.

    ``role`` is ``"master"`` or ``"drive"``. On SocketCAN the kernel applies them, so
    foreign traffic (other ids, every 29-bit frame) never wakes a Python reader; other
    interfaces filter in python-can.
    """
    if role == "master":
        return ([{"can_id": cob, "can_mask": EXACT_MASK, "extended": False} for cob in MASTER_RECEIVES_EXACT]
                + [{"can_id": base, "can_mask": FUNCTION_MASK, "extended": False}
                   for base in MASTER_RECEIVES])
    if role == "drive":
        return ([{"can_id": cob, "can_mask": EXACT_MASK, "extended": False} for cob in DRIVE_RECEIVES_EXACT]
                + [{"can_id": base, "can_mask": FUNCTION_MASK, "extended": False} for base in DRIVE_RECEIVES])
    raise InputError(f"role must be 'master' or 'drive', not {role!r}")


def has_kernel_timers(bus: can.BusABC | None) -> bool:
    """True when ``bus`` sends periodic frames from kernel timers (SocketCAN's broadcast
    manager), which keep their period however busy the Python process is."""
    try:
        from can.interfaces.socketcan import SocketcanBus
    except ImportError:  # pragma: no cover - not Linux
        return False
    return isinstance(bus, SocketcanBus)


@dataclass(frozen=True)
class BusConfig:
    """Which CAN bus to open.

    Parameters
    ----------
    interface : str
        python-can interface name (``virtual``, ``socketcan``, ``pcan``, ...).
    channel : str
        Channel of that interface (``motorstand``, ``vcan0``, ``can0``, ...).
    bitrate : int
        Bit rate, bit/s (ignored by ``virtual`` and ``socketcan``).
    options : dict
        Further keyword arguments for :class:`can.Bus`.
    """

    interface: str = DEFAULT_INTERFACE
    channel: str = DEFAULT_CHANNEL
    bitrate: int = 1_000_000
    options: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if self.interface in FORBIDDEN_INTERFACES:
            raise InputError(
                f"bus interface {self.interface!r} is not allowed: its traffic leaves the machine; "
                "use 'virtual' or 'socketcan'"
            )
        if self.interface not in can.VALID_INTERFACES:
            known = ", ".join(sorted(set(can.VALID_INTERFACES) - set(FORBIDDEN_INTERFACES)))
            raise InputError(f"bus interface must be one of {known}, not {self.interface!r}")

    def with_default(self, option: str, value: Any) -> BusConfig:
        """This config, with ``options[option] = value`` unless ``option`` is set already."""
        if option in self.options:
            return self
        return replace(self, options={**self.options, option: value})

    @classmethod
    def from_settings(cls) -> BusConfig:
        """The bus named by the settings (``STAND_BUS_INTERFACE`` etc.)."""
        from stand.settings import get_settings

        s = get_settings()
        return cls(s.bus_interface, s.bus_channel, s.bus_bitrate)


def open_bus(config: BusConfig) -> can.BusABC:
    """Open ``config``'s bus; raise :class:`BusError` naming it when that fails."""
    kwargs: dict[str, Any] = dict(config.options)
    if config.interface not in ("virtual", "socketcan"):
        kwargs.setdefault("bitrate", config.bitrate)
    try:
        return can.Bus(interface=config.interface, channel=config.channel, **kwargs)
    except (can.CanError, OSError, ImportError) as exc:
        raise BusError(
            f"cannot open CAN bus {config.interface}:{config.channel}: {exc}; check that the "
            "interface exists (e.g. 'ip link show vcan0') or choose another with STAND_BUS_INTERFACE"
        ) from exc


class StandardFrameListener(canopen.network.MessageListener):
    """Hands only 11-bit data frames to the network: CANopen uses no 29-bit identifiers
    (CiA 301 §7.2.1), so an extended frame whose identifier equals a COB-ID is foreign."""

    def on_message_received(self, msg: can.Message) -> None:
        if not msg.is_extended_id:
            super().on_message_received(msg)


def connect_network(config: BusConfig, network: canopen.Network | None = None,
                    role: str | None = None) -> canopen.Network:
    """``network`` (default: a new one) on ``config``'s bus, its reader thread started.

    With ``role`` (``"master"`` or ``"drive"``) the bus receives only what that role needs
    (:func:`receive_filters`), unless ``config.options`` sets ``can_filters`` itself.
    """
    network = network if network is not None else canopen.Network()
    if role is not None:
        config = config.with_default("can_filters", receive_filters(role))
    network.bus = open_bus(config)
    network.listeners = [StandardFrameListener(network)]
    network.NOTIFIER_CYCLE = NOTIFIER_CYCLE_S
    network.connect()
    return network
