"""Simulated stand: CiA 402 drive nodes with stand physics, on a CAN bus.

One motor profile gives one node on a :class:`~stand.physics.plant.MotorPlant`; a stand
profile gives two nodes (input and output motor) sharing one
:class:`~stand.physics.reducer.ReducerPlant`, which advances once per SYNC. On SYNC every
node samples (and sends its TPDOs when OPERATIONAL), then applies its latest target, then
the plant advances one communication cycle period (0x1006, written by the master), so the
drives keep lockstep with the SYNCs. With a SYNC counter (0x1019 set), a SYNC whose
counter does not follow the last one came from another producer and moves nothing: the
stand's time is the master's SYNCs only. Run it in-process or in its own process::

    python -m bus.simstand --interface socketcan --channel vcan0 --profile crouzet_82800502
"""

from __future__ import annotations

import argparse
import logging
import signal
import struct
import sys
import threading
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from bus.adapters import BusConfig, connect_network
from bus.cia301 import COMMUNICATION_CYCLE_PERIOD, SYNC_COB_ID, SYNCHRONOUS_COUNTER_OVERFLOW
from bus.cia402 import ADDED_INERTIA
from bus.drive_node import Plant, SimDriveNode
from bus.eds import FINE_COUNTS_PER_REV, Scaling
from bus.sampler import SAME_EPOCH_S
from stand.errors import NotFoundError
from stand.physics.plant import MotorPlant
from stand.physics.reducer import ReducerPlant
from stand.profiles import MotorProfile, StandProfile, load_motor, load_stand, resolve

log = logging.getLogger(__name__)

#: The main thread of ``python -m bus.simstand`` looks for SIGTERM/SIGINT this often, s.
SIGNAL_POLL_S = 0.2
#: Longest sleep of the heartbeat thread while no node produces heartbeats, s.
HEARTBEAT_IDLE_S = 0.05
#: Following-error window of a speed-mode drive, as a fraction of the speed limit.
FOLLOWING_WINDOW_FRACTION = 0.5
#: Over-current threshold as a multiple of the drive's current limit.
OVER_CURRENT_FACTOR = 1.5


def scaling_for(profile: MotorProfile) -> Scaling:
    """Units of the raw process data of a drive running ``profile``'s motor."""
    return Scaling(counts_per_rev=profile.sensor_params().counts_per_rev or FINE_COUNTS_PER_REV,
                   rated_current_A=profile.drive.rated_current_A,
                   current_mean_unit_A=profile.drive.current_mean_unit_A)


class SimStand:
    """The drives of a motor or stand profile, simulated on ``config``'s bus.

    Parameters
    ----------
    profile : str
        Motor or stand profile (name or path).
    config : BusConfig
        The bus to attach to.
    seed : int or None
        Seed of the sensor noise; the plant is rebuilt with it on every NMT reset node.
    effects : dict or None
        Effects replacing the profile's (``Effects.from_mapping`` form); None keeps them.
    eds : path or None
        EDS of the nodes.
    """

    def __init__(self, profile: str, config: BusConfig | None = None, seed: int | None = None,
                 effects: dict[str, dict[str, float]] | None = None,
                 eds: str | Path | None = None) -> None:
        self.seed = seed
        self.added_inertia = 0.0
        self.stand: StandProfile | None
        try:
            resolve(profile, "stands")
            self.stand = load_stand(profile)
            self.motors = [load_motor(self.stand.motor_in), load_motor(self.stand.motor_out)]
            node_ids = [self.stand.node_in, self.stand.node_out]
            self.period_s = self.stand.sample_period_s
        except NotFoundError:
            self.stand = None
            self.motors = [load_motor(profile)]
            node_ids = [self.motors[0].drive.node_id]
            self.period_s = self.motors[0].sample_period_s
        self.effects = effects
        self.plant: Plant = self._build_plant()
        self.network = connect_network(config or BusConfig(), role="drive")
        self.nodes = [
            SimDriveNode(self.network, node_id, self._current_plant, port, scaling_for(motor),
                         OVER_CURRENT_FACTOR * motor.drive.current_limit_A, eds,
                         on_reset=self._on_reset, on_write=self._on_write)
            for port, (node_id, motor) in enumerate(zip(node_ids, self.motors, strict=True))
        ]
        for node, motor in zip(self.nodes, self.motors, strict=True):
            node.following_window_rad_s = FOLLOWING_WINDOW_FRACTION * motor.limits.speed_rad_s
        self.syncs = 0
        #: SYNCs ignored as another producer's (out of the counter sequence).
        self.foreign_syncs = 0
        self._last_counter: int | None = None
        self.network.subscribe(SYNC_COB_ID, self._on_sync)
        for node in self.nodes:
            node.boot()
        self._closing = threading.Event()
        self._heartbeats = threading.Thread(target=self._produce_heartbeats,
                                            name=f"simstand-heartbeat-{node_ids}", daemon=True)
        self._heartbeats.start()

    def _produce_heartbeats(self) -> None:
        while not self._closing.is_set():
            now = time.monotonic()
            due = [d for d in (node.heartbeat_tick(now) for node in self.nodes) if d is not None]
            self._closing.wait(max(0.0, min(due) - time.monotonic()) if due else HEARTBEAT_IDLE_S)

    def _current_plant(self) -> Plant:
        return self.plant

    def _build_plant(self) -> Plant:
        from stand.physics.effects import Effects

        def effects_of(motor: MotorProfile) -> Effects:
            if self.effects is None:
                return motor.effect_set()
            return Effects.from_mapping(self.effects, "simstand effects")

        if self.stand is None:
            m = self.motors[0]
            return MotorPlant(m.motor_params(), m.drive_params(), m.sensor_params(), effects_of(m),
                              added_inertia=self.added_inertia, seed=self.seed)
        m_in, m_out = self.motors
        return ReducerPlant(m_in.motor_params(), m_out.motor_params(), self.stand.reducer_params(),
                            m_in.drive_params("speed"), m_out.drive_params("current"),
                            m_in.sensor_params(), effects_of(m_in), m_out.effect_set(), seed=self.seed)

    def _on_reset(self, node: SimDriveNode) -> None:
        if node is self.nodes[0]:
            self.plant = self._build_plant()
            self._last_counter = None

    def _ours(self, data: bytearray) -> bool:
        """True unless the SYNC breaks the counter sequence of 0x1019 (another producer's)."""
        overflow = self.nodes[0].node.get_data(SYNCHRONOUS_COUNTER_OVERFLOW, 0)[0]
        if not overflow:
            return True  # no counter: producers cannot be told apart
        if len(data) != 1 or (self._last_counter is not None
                              and data[0] != self._last_counter % overflow + 1):
            self.foreign_syncs += 1
            if self.foreign_syncs == 1:
                log.warning("simulated stand: SYNC %s out of sequence after %s; ignored",
                            bytes(data).hex() or "without counter", self._last_counter)
            return False
        self._last_counter = data[0]
        return True

    def _on_write(self, node: SimDriveNode, index: int, value: Any) -> None:
        if index == ADDED_INERTIA and node is self.nodes[0]:
            self.added_inertia = float(value)
            self.plant = self._build_plant()
            log.info("simulated stand: added inertia %.4g kg·m², plant rebuilt", value)

    def _on_sync(self, can_id: int, data: bytearray, timestamp: float) -> None:
        if not self._ours(data):
            return
        cycle_us = struct.unpack("<I", self.nodes[0].node.get_data(COMMUNICATION_CYCLE_PERIOD, 0))[0]
        dt_s = cycle_us * 1e-6 if cycle_us else self.period_s
        stamp: float | None = timestamp
        if abs(time.time() - timestamp) > SAME_EPOCH_S:
            stamp = None  # the interface stamps frames on another clock
        now = time.monotonic()
        for node in self.nodes:  # a due heartbeat first: it is older than the TPDOs
            node.heartbeat_tick(now)
        for node in self.nodes:
            node.apply_rpdos()
        for node in self.nodes:
            node.sample(dt_s, stamp)
        for node in self.nodes:
            node.actuate()
        self.plant.advance(dt_s)
        self.syncs += 1
        now = time.monotonic()
        for node in self.nodes:
            node.heartbeat_tick(now)

    def node(self, node_id: int) -> SimDriveNode:
        for node in self.nodes:
            if node.id == node_id:
                return node
        raise NotFoundError(f"no simulated node {node_id}; nodes: {[n.id for n in self.nodes]}")

    def close(self) -> None:
        """Stop heartbeats and the notifier, and shut the bus down."""
        self._closing.set()
        self._heartbeats.join()
        for node in self.nodes:
            node.close()
        self.network.unsubscribe(SYNC_COB_ID, self._on_sync)
        self.network.disconnect()

    def __enter__(self) -> SimStand:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def main(argv: Sequence[str] | None = None) -> int:
    """``python -m bus.simstand``: serve the simulated drives until SIGINT/SIGTERM."""
    parser = argparse.ArgumentParser(prog="python -m bus.simstand", description=__doc__.split("\n")[0])
    parser.add_argument("--interface", default="virtual")
    parser.add_argument("--channel", default="motorstand")
    parser.add_argument("--profile", required=True, help="motor or stand profile")
    parser.add_argument("--seed", type=int, default=None)
    parser.add_argument("--eds", default=None)
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.INFO, stream=sys.stderr, format="%(message)s")
    done = threading.Event()
    signal.signal(signal.SIGTERM, lambda *_: done.set())
    signal.signal(signal.SIGINT, lambda *_: done.set())
    with SimStand(args.profile, BusConfig(args.interface, args.channel), args.seed, eds=args.eds) as sim:
        log.info("simulated drives %s on %s:%s", [n.id for n in sim.nodes], args.interface, args.channel)
        print("ready", flush=True)
        while not done.wait(SIGNAL_POLL_S):
            pass
    return 0


if __name__ == "__main__":
    sys.exit(main())
