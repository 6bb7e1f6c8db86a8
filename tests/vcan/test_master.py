"""Our CANopen master against simulated CiA 402 drives in another process, on a real vcan0.

The drives run as ``python -m bus.simstand --interface socketcan --channel vcan0`` (their own
process, their own socket); the master runs here. candump, a third process, records what
crossed the bus, and tests/vcan/cia301.py reads it against CiA 301 independently of bus/.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterator

import canopen
import numpy as np
import pytest

from bus.adapters import BusConfig
from bus.drive import DriveConfig
from bus.eds import DEFAULT_EDS, load_od
from bus.master import PDO_TIMEOUT_S as PDO_TIMEOUT_DEFAULT_S
from bus.master import Master
from bus.sampler import Samples
from bus.simstand import scaling_for
from stand.profiles import load_motor
from tests.vcan import cia301
from tests.vcan.canutils import Candump, Cangen, Frame
from tests.vcan.conftest import CHANNEL, SimstandProcess

PROFILE = "crouzet_82800502"  # seed 000's motor: speed-mode drive, 2500-line encoder, 15 ms
NODE = 1
PERIOD_S = 0.015
TARGET_RAD_S = 50.0
RUN_SAMPLES = 200
#: Predefined connection set (CiA 301 §7.3.5) for node 1.
TPDO1, TPDO2, TPDO3, RPDO1 = 0x180 + NODE, 0x280 + NODE, 0x380 + NODE, 0x200 + NODE
CW_ENABLE_OPERATION = 0x000F
#: Producer heartbeat period the master asks for, s. Longer than the master's default: the
#: guest has one CPU shared by the master, the drives' process, candump and cangen (and the
#: host under it is shared too), so a 100 ms heartbeat with a 150 ms consumer time reports
#: false losses there; the protocol checks here are about frames, not about that margin.
HEARTBEAT_PERIOD_S = 0.5
#: Heartbeat intervals on the wire may differ from the period by this fraction (kernel BCM
#: timers in the drives' process; scheduling of a one-CPU guest).
HEARTBEAT_TOLERANCE = 0.2
#: Lockstep: time the TPDOs of one SYNC may take before they count as lost, s: the
#: master's default (bus.master.PDO_TIMEOUT_S), as on a stand. 0.5 s was exceeded in one of
#: three full runs here (two windows lost) while the host under the guest ran at load 11.
PDO_TIMEOUT_S = PDO_TIMEOUT_DEFAULT_S
#: SDO answer and boot-up timeouts, s: the master's defaults (0.3 s, 2 s) are tight for a
#: drive process that shares the guest's one CPU with candump and cangen.
SDO_TIMEOUT_S = 1.0
BOOT_TIMEOUT_S = 5.0
#: Gap of the 29-bit foreign load, ms (the 11-bit load has twice the gap): 250-300 frames/s
#: in all in lockstep, about 140 in realtime, where the guest's one CPU also runs the clock.
FOREIGN_GAP_MS = {"lockstep": 5.0, "realtime": 10.0}
#: Time the capture goes on after a realtime run, for answers of a late drive, s.
LATE_ANSWER_S = 1.0
#: Fewest SYNC windows a realtime run under load must record for its check to mean something.
MIN_WINDOWS = 50
#: Foreign 11-bit identifier used for load: in CiA 301's reserved range 0x780..0x7E3, so no
#: CANopen node may react to it.
FOREIGN_ID = "790"


@pytest.fixture
def drives(simstand: Callable[..., SimstandProcess]) -> SimstandProcess:
    proc = simstand(PROFILE, "--seed", "7")
    proc.wait_ready()
    return proc


@pytest.fixture
def master(drives: SimstandProcess) -> Iterator[Master]:
    m = Master(BusConfig("socketcan", CHANNEL), heartbeat_period_s=HEARTBEAT_PERIOD_S,
               pdo_timeout_s=PDO_TIMEOUT_S, sdo_timeout_s=SDO_TIMEOUT_S,
               boot_timeout_s=BOOT_TIMEOUT_S)
    try:
        yield m
    finally:
        m.close()


def _setup(master: Master) -> None:
    scaling = scaling_for(load_motor(PROFILE))
    master.setup([DriveConfig(NODE, "speed", scaling)], PERIOD_S)


def _windows(frames: list[Frame]) -> list[list[Frame]]:
    """The frames after each SYNC up to the next one (11-bit frames only)."""
    out: list[list[Frame]] = []
    for f in cia301.base_frames(frames):
        if f.arbitration_id == cia301.SYNC_ID:
            out.append([])
        elif out:
            out[-1].append(f)
    return out


def _values(tpdo1: Frame | None, tpdo2: Frame | None) -> dict[str, float]:
    """Raw values of a TPDO pair, decoded from the bytes by their CiA 402 types:
    TPDO1 = position actual (INTEGER32) + current actual (INTEGER16),
    TPDO2 = velocity actual (INTEGER32) + voltage actual (INTEGER16)."""
    out = {"position": np.nan, "current": np.nan, "velocity": np.nan}
    if tpdo1 is not None:
        out["position"] = int.from_bytes(tpdo1.data[0:4], "little", signed=True)
        out["current"] = int.from_bytes(tpdo1.data[4:6], "little", signed=True)
    if tpdo2 is not None:
        out["velocity"] = int.from_bytes(tpdo2.data[0:4], "little", signed=True)
    return out


Candidates = list[dict[str, set[float]]]


def _wire_answers(frames: list[Frame], count: int) -> Candidates | None:
    """For each of the first ``count`` SYNCs of the capture, the values that may have answered it.

    The simulated drive answers every SYNC it receives once and in order with one TPDO1 and
    one TPDO2, so when the capture holds as many answers as SYNCs the k-th answer after the
    first SYNC is the answer to SYNC k, however late it came: one candidate each.

    With fewer answers, the drive discarded late ones because the master set a synchronous
    window (0x1007, CiA 301 §7.5.2.7) shorter than the shortest SYNC interval; an answer then
    belongs to the SYNC right before it, one candidate, unless an answer sent just inside
    the window crossed the next SYNC on the wire (no or two answers in a neighbouring
    window): then the answers of windows k and k+1 are all candidates. Without a window
    and with fewer answers the frames cannot say it: None.
    """
    transfers = cia301.sdo_transfers(frames, NODE)
    frames = cia301.base_frames(frames)
    first_sync = next(i for i, f in enumerate(frames) if f.arbitration_id == cia301.SYNC_ID)
    after = frames[first_sync:]
    syncs = sum(1 for f in after if f.arbitration_id == cia301.SYNC_ID)
    tpdo1 = [f for f in after if f.arbitration_id == TPDO1]
    tpdo2 = [f for f in after if f.arbitration_id == TPDO2]
    if len(tpdo1) == len(tpdo2) == syncs:
        return [{name: {v} for name, v in _values(tpdo1[k], tpdo2[k]).items()} for k in range(count)]
    windows_us = [t.value for t in transfers if t.write and (t.index, t.subindex) == (0x1007, 0)]
    if not windows_us or not windows_us[-1]:
        return None
    answers = [[_values(f, None) if f.arbitration_id == TPDO1 else _values(None, f)
                for f in window if f.arbitration_id in (TPDO1, TPDO2)] for window in _windows(after)]
    answers += [[]] * (count + 1 - len(answers))
    out: Candidates = []
    for k in range(count):
        here, there = answers[k], answers[k + 1]
        clean = len(here) == 2 and len(there) in (0, 2) if k + 1 == count else len(here) == len(there) == 2
        pool = here if clean else here + there
        out.append({name: {v[name] for v in pool if np.isfinite(v[name])}
                    for name in ("position", "current", "velocity")})
    return out


def _assert_master_read_the_wire(samples: Samples, frames: list[Frame], realtime: bool = False) -> int:
    """Every value the master recorded is a value that answered that SYNC on the wire.

    A lockstep run must have every SYNC answered (one candidate per window). When a realtime
    run's answers cannot be attributed from the frames (see :func:`_wire_answers`) the test
    is skipped with the reason. Returns the number of windows with more than one candidate.
    """
    scaling = scaling_for(load_motor(PROFILE))
    candidates = _wire_answers(frames, samples.count)
    assert candidates is not None or realtime, "the drive did not answer every SYNC of a lockstep run"
    if candidates is None:
        pytest.skip("fewer answers than SYNCs on the wire and no synchronous window (0x1007) "
                    "written, so the frames cannot say which SYNC each answer is for")
    cols = samples.drives[0].columns
    got = {"position": np.round(cols["position_rad"] / scaling.rad_per_count),
           "current": np.round(cols["current_A"] / scaling.amp_per_unit),
           "velocity": np.round(cols["velocity_rad_s"] / scaling.velocity_unit_rad_s)}
    windows = _windows(frames)
    for name, values in got.items():
        wrong = [k for k, v in enumerate(values) if np.isfinite(v) and v not in candidates[k][name]]
        if wrong:  # the frames around the first wrong window, for whoever fixes it
            near = {j: [f"{f.arbitration_id:03X}#{f.data.hex()}" for f in windows[j]
                        if f.arbitration_id in (TPDO1, TPDO2)]
                    for j in range(max(0, wrong[0] - 2), min(len(windows), wrong[0] + 3))}
            recorded = {j: values[j] for j in near if j < len(values)}
        assert not wrong, (
            f"{name}: the master recorded {[values[k] for k in wrong[:5]]} in windows {wrong[:5]} but "
            f"the TPDOs answering those SYNCs on the wire carried "
            f"{[sorted(candidates[k][name]) for k in wrong[:5]]} (misattributed PDO); TPDOs after "
            f"each SYNC near the first: {near}; the master's {name} there: {recorded}")
    return sum(1 for c in candidates if len(c["position"]) > 1)


def test_setup_follows_cia301(master: Master) -> None:
    """Boot (NMT reset → boot-up), SDO configuration, PDO mapping and start, as on the wire."""
    with Candump(CHANNEL) as dump:
        _setup(master)
        time.sleep(3.5 * HEARTBEAT_PERIOD_S)  # three heartbeats in OPERATIONAL
        master.stop_drives()
    frames = dump.frames
    nmt = cia301.check_nmt(frames)
    assert nmt[0] == ("reset node", NODE)
    assert ("start", NODE) in nmt
    beats = cia301.heartbeats(frames, NODE)
    reset_at = next(f.timestamp_s for f in frames if f.arbitration_id == cia301.NMT_ID)
    first_sdo_at = next(f.timestamp_s for f in frames if f.arbitration_id == 0x600 + NODE)
    boot_ups = [b for b in beats if b.data[0] == 0 and reset_at < b.timestamp_s < first_sdo_at]
    assert len(boot_ups) == 1, "exactly one boot-up message between NMT reset and the first SDO"

    transfers = cia301.sdo_transfers(frames, NODE)
    aborted = [t for t in transfers if t.abort_code is not None]
    assert not aborted, f"SDO aborts: {[(hex(t.index), t.subindex, hex(t.abort_code or 0)) for t in aborted]}"
    writes = {(t.index, t.subindex): t.value for t in transfers if t.write}
    assert writes[(0x1006, 0)] == round(PERIOD_S * 1e6), "communication cycle period in µs"
    assert writes[(0x1017, 0)] == round(HEARTBEAT_PERIOD_S * 1000), "producer heartbeat time, ms"
    overflow = writes.get((0x1019, 0)) or 0
    assert overflow == 0 or 2 <= overflow <= 240, "synchronous counter overflow value range"

    pdos = cia301.pdo_configs(transfers)
    od = load_od(DEFAULT_EDS, NODE)
    for comm, cob_id in ((cia301.RPDO_COMM, RPDO1), (cia301.TPDO_COMM, TPDO1),
                         (cia301.TPDO_COMM + 1, TPDO2), (cia301.TPDO_COMM + 2, TPDO3)):
        assert comm in pdos, f"PDO 0x{comm:04X} not configured and enabled"
        pdo = pdos[comm]
        assert pdo.cob_id == cob_id, (
            f"0x{comm:04X}: COB-ID 0x{pdo.cob_id:03X}, the predefined connection set says 0x{cob_id:03X}")
        assert pdo.transmission_type == 1, "synchronous, every SYNC"
        assert 0 < pdo.length_bytes <= 8
        for index, _sub, bits in pdo.mapping:
            var = od[index]
            assert isinstance(var, canopen.objectdictionary.ODVariable), f"0x{index:04X} is not a variable"
            assert len(var) == bits, f"0x{index:04X} mapped with {bits} bits, the EDS says {len(var)}"
            assert var.pdo_mappable, f"0x{index:04X} is not PDO-mappable in the EDS"
    assert [m[0] for m in pdos[cia301.TPDO_COMM].mapping] == [0x6064, 0x6078]
    assert [m[0] for m in pdos[cia301.TPDO_COMM + 2].mapping] == [0x2002]  # the period mean

    # Heartbeat at the period written to 0x1017, reporting OPERATIONAL after NMT start.
    started_at = next(f.timestamp_s for f in frames if f.arbitration_id == cia301.NMT_ID
                      and f.data[0] == 0x01)
    operational = [b.timestamp_s for b in beats if b.data[0] == 0x05 and b.timestamp_s > started_at]
    assert len(operational) >= 3, f"{len(operational)} heartbeats reporting OPERATIONAL after NMT start"
    intervals = np.diff(operational)
    assert np.all(np.abs(intervals - HEARTBEAT_PERIOD_S) < HEARTBEAT_TOLERANCE * HEARTBEAT_PERIOD_S), (
        f"heartbeat intervals {intervals} s, period {HEARTBEAT_PERIOD_S} s")


def test_lockstep_run_on_the_wire(master: Master) -> None:
    """A short lockstep run: SYNC with counter, RPDO before each SYNC, both TPDOs after it,
    and the master's samples equal the TPDO bytes candump saw."""
    with Candump(CHANNEL) as dump:
        _setup(master)
        samples = master.run(np.full((1, RUN_SAMPLES), TARGET_RAD_S))
    master.stop_drives()  # its SYNCs: test_stop_syncs_carry_the_counter
    assert samples.complete, samples.aborted or samples.lost
    assert samples.drives[0].duplicates == 0 and samples.drives[0].late == 0
    frames = dump.frames
    overflow = _sync_overflow(frames)
    counters = cia301.check_sync(frames, overflow)
    assert len(counters) == RUN_SAMPLES
    if overflow:
        assert list(samples.sync_counter) == counters

    windows = _windows(frames)
    for k, window in enumerate(windows[:RUN_SAMPLES]):
        ids = [f.arbitration_id for f in window]
        assert ids.count(TPDO1) == 1 and ids.count(TPDO2) == 1, f"window {k}: frames {ids}"
        if k + 1 < RUN_SAMPLES:  # the next window's target goes out before its SYNC
            rpdos = [f for f in window if f.arbitration_id == RPDO1]
            assert len(rpdos) == 1, f"window {k}: {len(rpdos)} RPDOs before SYNC {k + 1}"
            cw = int.from_bytes(rpdos[0].data[0:2], "little")
            target = int.from_bytes(rpdos[0].data[2:6], "little", signed=True)
            assert (cw, target) == (CW_ENABLE_OPERATION, round(TARGET_RAD_S / 1e-3))
    _assert_master_read_the_wire(samples, frames)

    # The drive in its own process did follow the speed target: the last 50 samples
    # (0.75 s, after the PI loop settled) average within 0.5 rad/s (1 %) of it.
    velocity = samples.drives[0].columns["velocity_rad_s"]
    assert abs(np.mean(velocity[-50:]) - TARGET_RAD_S) < 0.5


def _sync_overflow(frames: list[Frame]) -> int:
    """The synchronous counter overflow value (0x1019) the master wrote to the drive."""
    writes = {(t.index, t.subindex): t.value for t in cia301.sdo_transfers(frames, NODE) if t.write}
    return writes.get((0x1019, 0)) or 0


def test_stop_syncs_carry_the_counter(master: Master) -> None:
    """After a run the master quick-stops the drives and keeps sending SYNCs so that they
    act; having set 0x1019 on the drives, every SYNC must carry the counter (CiA 301
    §7.2.5: a consumer with 0x1019 > 0 answers another data length with EMCY 0x8240)."""
    with Candump(CHANNEL) as dump:
        _setup(master)
        master.run(np.full((1, 20), TARGET_RAD_S))
        master.stop_drives()
    cia301.check_sync(dump.frames, _sync_overflow(dump.frames))


@pytest.mark.parametrize("time_mode", ["lockstep", "realtime"])
def test_foreign_load_while_sampling(master: Master, time_mode: str) -> None:
    """cangen sends foreign 29-bit frames (random ids, lengths and data) and a foreign 11-bit
    id while the master samples: no TPDO is attributed to the wrong SYNC, and in lockstep
    none is lost or duplicated.

    In realtime mode a TPDO that misses its 15 ms window on this one-CPU guest may be lost
    (NaN, counted), and the run may even end early on a heartbeat the starved master read
    too late; but no TPDO may ever be recorded as another window's value.
    """
    _setup(master)
    gap_ms = FOREIGN_GAP_MS[time_mode]
    with Candump(CHANNEL) as dump, \
            Cangen(CHANNEL, gap_ms=gap_ms, ident="r", extra=["-e", "-L", "r"]), \
            Cangen(CHANNEL, gap_ms=2 * gap_ms, ident=FOREIGN_ID, extra=["-L", "8"]):
        samples = master.run(np.full((1, RUN_SAMPLES), TARGET_RAD_S), time_mode=time_mode)
        time.sleep(LATE_ANSWER_S)  # let the capture hold a late drive's last answers
    master.stop_drives()
    frames = dump.frames
    sync_times = [f.timestamp_s for f in frames if f.arbitration_id == cia301.SYNC_ID
                  and not f.is_extended_id]
    during = [f for f in frames if sync_times[0] <= f.timestamp_s <= sync_times[-1]]
    foreign = [f for f in during if f.is_extended_id or f.arbitration_id == int(FOREIGN_ID, 16)]
    # cangen makes 100-400 frames/s each on this guest; at the least one foreign frame for
    # every four SYNC windows shows that the load ran and interleaved with the PDOs.
    assert len(foreign) >= RUN_SAMPLES / 4, f"only {len(foreign)} foreign frames: the load did not run"
    assert not dump.drop_reports, dump.drop_reports
    d = samples.drives[0]
    print(f"{time_mode}: {len(foreign)} foreign frames in {sync_times[-1] - sync_times[0]:.2f} s; "
          f"{samples.count} windows, TPDOs lost {d.lost}, duplicates {d.duplicates}, late {d.late}; "
          f"aborted: {samples.aborted}")
    assert samples.count >= MIN_WINDOWS, f"only {samples.count} windows recorded: {samples.aborted}"
    answers = sum(1 for f in cia301.base_frames(frames) if f.arbitration_id == TPDO1)
    print(f"{time_mode}: {len(sync_times)} SYNCs and {answers} TPDO1 answers on the wire")
    ambiguous = _assert_master_read_the_wire(samples, frames, realtime=time_mode == "realtime")
    print(f"{time_mode}: {ambiguous} windows with an answer that crossed the next SYNC")
    if time_mode == "lockstep":
        assert samples.aborted is None, samples.aborted
        assert (d.lost, d.duplicates, d.late) == (0, 0, 0), (
            f"lost {d.lost}, duplicates {d.duplicates}, late {d.late}")


def test_extended_frames_aliasing_cob_ids_are_ignored(master: Master) -> None:
    """CANopen uses 11-bit identifiers only (CiA 301 §7.2.1), so a 29-bit frame whose
    identifier happens to equal a COB-ID (here 0x181 TPDO1 and 0x080 SYNC, as extended
    frames from another protocol on the same wire) is foreign traffic: the master must not
    take it for a TPDO and the drive must not take it for a SYNC."""
    _setup(master)
    with Candump(CHANNEL) as dump, \
            Cangen(CHANNEL, gap_ms=5, ident=f"{TPDO1:X}", extra=["-e", "-L", "6", "-D", "i"]), \
            Cangen(CHANNEL, gap_ms=5, ident=f"{cia301.SYNC_ID:X}", extra=["-e", "-L", "1"]):
        samples = master.run(np.full((1, RUN_SAMPLES), TARGET_RAD_S))
    master.stop_drives()
    frames = dump.frames
    aliases = [f for f in frames if f.is_extended_id and f.arbitration_id in (TPDO1, cia301.SYNC_ID)]
    assert len(aliases) >= RUN_SAMPLES / 4, f"only {len(aliases)} aliasing frames: the load did not run"
    windows = _windows(frames)
    for k, window in enumerate(windows[:RUN_SAMPLES]):
        ids = [f.arbitration_id for f in window]
        assert ids.count(TPDO1) == 1, f"window {k}: the drive answered {ids.count(TPDO1)} times"
    d = samples.drives[0]
    assert samples.aborted is None, samples.aborted
    _assert_master_read_the_wire(samples, frames)
    assert (d.lost, d.duplicates, d.late) == (0, 0, 0), (
        f"lost {d.lost}, duplicates {d.duplicates}, late {d.late}")
