"""A simulated CiA 301 device that is no drive: a CiA 401 digital I/O module.

It is what a stand's bus may also carry (or what answers at a mistyped node id): it boots,
answers SDO from its own EDS (``profiles/eds/motorstand_io401.eds``, device type
0x00030191), follows NMT and produces its heartbeat once 0x1017 is set (canopen's NMT
slave does both). The master must refuse it before it writes anything
(:meth:`bus.drive.Drive.check_device`).
"""

from __future__ import annotations

from pathlib import Path

import canopen

from bus.cia301 import (
    HEARTBEAT_BASE,
    NMT_BOOT_UP,
    NMT_COB_ID,
    NMT_PRE_OPERATIONAL,
    NMT_RESET_COMMUNICATION,
    NMT_RESET_NODE,
)
from bus.eds import load_od
from stand.profiles import PROFILES_DIR

#: The EDS of the simulated I/O module.
IO_EDS = PROFILES_DIR / "eds" / "motorstand_io401.eds"


class SimIoDevice:
    """A CiA 401 I/O module at ``node_id`` on ``network`` (connected).

    Parameters
    ----------
    network : canopen.Network
        The network it sits on.
    node_id : int
        Its node id, 1-127.
    eds : path or None
        Its EDS (default: :data:`IO_EDS`).
    """

    def __init__(self, network: canopen.Network, node_id: int, eds: str | Path | None = None) -> None:
        self.id = node_id
        self.network = network
        self.node = canopen.LocalNode(node_id, load_od(eds or IO_EDS, node_id))
        network.add_node(self.node)
        network.subscribe(NMT_COB_ID, self._on_nmt)  # after the NMT slave's own subscriber
        self.boot()

    def boot(self) -> None:
        """Send the boot-up message and enter PRE-OPERATIONAL (CiA 301 §7.2.8.3)."""
        self.node.nmt._state = NMT_PRE_OPERATIONAL
        self.network.send_message(HEARTBEAT_BASE + self.id, bytes([NMT_BOOT_UP]))

    def _on_nmt(self, can_id: int, data: bytearray, timestamp: float) -> None:
        if len(data) < 2 or data[1] not in (0, self.id):
            return
        if data[0] in (NMT_RESET_NODE, NMT_RESET_COMMUNICATION):
            self.node.nmt.stop_heartbeat()
            self.node.data_store.clear()
            self.boot()

    def close(self) -> None:
        self.node.nmt.stop_heartbeat()
        self.network.unsubscribe(NMT_COB_ID, self._on_nmt)
