"""CAN bus adapters chosen by name (python-can's interface table).

``virtual`` (in-process, the embedded default), ``socketcan`` (``vcan0`` or a real
``can0``) and any other python-can interface, with its options passed through.
``udp_multicast`` is refused: its datagrams leave the machine.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import can
import canopen

from stand.errors import BusError, InputError

#: Interfaces that must never be used (traffic would leave the machine).
FORBIDDEN_INTERFACES = ("udp_multicast",)
#: Longest wait of a bus reader thread for one frame (bounds the time to close), s.
NOTIFIER_CYCLE_S = 0.1
#: The embedded default: python-can's in-process virtual bus.
DEFAULT_INTERFACE = "virtual"
DEFAULT_CHANNEL = "motorstand"


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


def connect_network(config: BusConfig, network: canopen.Network | None = None) -> canopen.Network:
    """``network`` (default: a new one) on ``config``'s bus, its reader thread started."""
    network = network if network is not None else canopen.Network()
    network.bus = open_bus(config)
    network.listeners = [StandardFrameListener(network)]
    network.NOTIFIER_CYCLE = NOTIFIER_CYCLE_S
    network.connect()
    return network
