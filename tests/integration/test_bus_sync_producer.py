"""Real-time SYNC from the kernel's broadcast manager where the bus has one (issue 20, item 6).

On SocketCAN a real-time run's SYNCs come from one cyclic broadcast-manager task over the
frames of the whole counter sequence; elsewhere (python-can ``virtual``) from the master's
Python clock. Timing figures are the bus benchmark's (tests/bench/bench_bus.py), not
asserted here: a loaded machine would make them flake.
"""

from __future__ import annotations

import numpy as np
import pytest

from bus.adapters import BusConfig
from bus.master import Master
from bus.stand_bus import StandBus
from bus.sync import SyncWatch
from stand.controller import ExperimentProfile, plan
from stand.errors import InputError

STAND = "cycloidal_two_motor"
#: Heartbeat period: long enough that a one-CPU User-Mode Linux on a loaded host never
#: starves a heartbeat into a false alarm, s.
CALM_HEARTBEAT_S = 0.5
PERIOD_S = 0.005
SAMPLES = 200
OVERFLOW = 240


def test_realtime_syncs_come_from_the_kernel_where_the_bus_has_one(can_config: BusConfig) -> None:
    kernel = can_config.interface == "socketcan"
    experiment = ExperimentProfile(name="x", procedure="efficiency", stand=STAND,
                                   duration_s=SAMPLES * PERIOD_S, period_s=PERIOD_S)
    (procedure, drives), = plan(experiment)
    tasks: list[list[bytes]] = []
    with StandBus(STAND, can_config, simulate=True, seed=1, heartbeat_period_s=CALM_HEARTBEAT_S) as bus:
        assert bus.master.kernel_sync is kernel
        bus.setup(drives, PERIOD_S)
        network_bus = bus.master.network.bus

        def progress(k: int, n: int) -> None:
            if k == SAMPLES // 2:  # the broadcast manager's tasks while the run goes on
                tasks.extend([bytes(m.data) for m in task.messages]  # type: ignore[attr-defined]
                             for task in network_bus._periodic_tasks)  # type: ignore[union-attr]

        samples = bus.run(np.zeros((2, SAMPLES)), time_mode="realtime", progress=progress)
        after = list(network_bus._periodic_tasks)  # type: ignore[union-attr]
    if kernel:  # one task: the whole counter sequence, one frame a SYNC; stopped at the end
        (frames,) = tasks
        assert len(frames) == OVERFLOW and sorted(f[0] for f in frames) == list(range(1, OVERFLOW + 1))
        assert all(b[0] == a[0] % OVERFLOW + 1 for a, b in zip(frames, frames[1:], strict=False))
        assert not after
    else:
        assert tasks == []
    # Whoever sent them, the windows carry the counter sequence, one SYNC each.
    counters = samples.sync_counter[:samples.count]
    assert samples.count == SAMPLES and counters[0] == 1
    assert np.all(counters[1:] == counters[:-1] % OVERFLOW + 1)
    # Heard stamps rise. How many windows have one is timing: on a loaded machine the
    # kernel's SYNC k may be heard before the master opens window k (a late target), and
    # the master's own clock may open window k + 1 before the echo of SYNC k is handed on.
    # The first window's is certain only from the kernel: the master opens window 1 once it
    # heard SYNC 1.
    stamps = samples.sync_stamp_s
    heard = stamps[np.isfinite(stamps)]
    assert heard.size and np.all(np.diff(heard) > 0)
    assert np.isfinite(stamps[0]) or not kernel


def test_the_kernel_producer_is_refused_where_the_bus_has_none() -> None:
    with pytest.raises(InputError, match="sync_producer 'kernel' needs SocketCAN's broadcast manager"):
        Master(BusConfig("virtual", "no-bcm"), sync_producer="kernel")
    with pytest.raises(InputError, match="sync_producer must be one of auto, kernel, python"):
        Master(BusConfig("virtual", "no-bcm"), sync_producer="bcm")


def _watch_hears(watch: SyncWatch, frames: list[tuple[bytes, float]]) -> int:
    for data, stamp in frames:
        watch.on_sync(0x080, bytearray(data), stamp)
    return watch.foreign


def test_a_sync_of_ours_the_socket_lost_is_not_taken_for_another_producer() -> None:
    watch = SyncWatch(echo=True, first=1, overflow=OVERFLOW)
    for _ in range(4):
        watch.sent()
    # SYNC 2 never reached the master's socket (a full receive queue): 3 and 4 are ours.
    assert _watch_hears(watch, [(b"\x01", 0.0), (b"\x03", 0.002), (b"\x04", 0.003)]) == 0
    assert watch.unheard == 1
    # A fifth SYNC heard when four were sent, and a SYNC without counter: another producer's.
    assert _watch_hears(watch, [(b"\x05", 0.004), (b"", 0.004)]) == 2


def test_kernel_syncs_may_skip_only_as_many_as_periods_passed() -> None:
    period = 0.001
    watch = SyncWatch(echo=True, first=1, overflow=OVERFLOW, period_s=period)
    # 1, then 3 two periods later (2 unheard): ours; then 9 half a period later: foreign.
    assert _watch_hears(watch, [(b"\x01", 10.0), (b"\x03", 10.002), (b"\x09", 10.0025)]) == 1
    assert watch.unheard == 1 and watch.expected == 4
