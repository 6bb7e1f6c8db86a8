"""The SYNC-driven sampler: TPDOs of all drives aligned by SYNC, in preallocated arrays.

Each SYNC opens a window; the TPDOs a drive sends in reply fill its slot of that window.
A TPDO that does not come is counted as lost (its values stay NaN, never filled in); a
second copy of the same TPDO in one window is counted as a duplicate and ignored — and if
the window before lacked that TPDO, the first copy may have been its late answer, so the
sample is dropped as well (counted late); a TPDO that arrives while no window is open
(after the run's last window closed) or that is stamped before the SYNC of the open window
was sent (it answers an earlier SYNC; bus stamps, as python-can gives them) is counted as
late. Raw values are converted to SI units with each drive's :class:`~bus.eds.Scaling`.

A window also keeps the target each drive was commanded for it (:meth:`Sampler.command`),
where the target is one a run file has a column for (:data:`TARGET_FIELDS`): the master
records what it sends, the trace reader what the RPDOs before the SYNC carried.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from bus import cia402
from bus.eds import Scaling
from bus.pdo import Layout
from stand.errors import BusTimeout

#: Process data objects the sampler understands, and the field each fills.
FIELDS = {cia402.POSITION_ACTUAL: "position_rad", cia402.CURRENT_ACTUAL: "current_A",
          cia402.VELOCITY_ACTUAL: "velocity_rad_s", cia402.VOLTAGE_ACTUAL: "voltage_V",
          cia402.CURRENT_MEAN: "current_mean_A",
          cia402.STATUSWORD: "statusword"}
#: Of those, the objects only the simulated drive has: on another drive the same index is
#: the vendor's own object and is not read (unless named, ``current_means``).
SIMULATION_OBJECTS = (cia402.VOLTAGE_ACTUAL, cia402.CURRENT_MEAN)
#: RPDO target objects whose value a window keeps, and the field each fills: the target
#: velocity of cyclic synchronous velocity mode, held from its SYNC to the next.
TARGET_FIELDS = {cia402.TARGET_VELOCITY: "speed_target_rad_s"}
INT32_SPAN = 1 << 32
#: Frame stamps within this much of ``time.time()`` share its epoch (interfaces whose
#: stamps count from elsewhere are not compared), s.
SAME_EPOCH_S = 60.0


@dataclass
class DriveSamples:
    """Samples of one drive, SI units; NaN where a TPDO was lost."""

    node_id: int
    columns: dict[str, np.ndarray]
    received: np.ndarray  # (pdos, samples) bool
    lost: int = 0
    duplicates: int = 0
    late: int = 0
    #: TPDOs shorter than their mapping (dropped: their samples count as lost).
    short: int = 0

    @property
    def valid(self) -> np.ndarray:
        """True for the samples whose every TPDO arrived."""
        return np.all(self.received, axis=0)


@dataclass
class Samples:
    """What a run recorded: SYNC-aligned samples of every drive.

    Attributes
    ----------
    period_s : float
        SYNC period, s (stand time of sample k is ``k·period_s``).
    count : int
        Number of SYNC windows recorded (the run's length when it ran to its end).
    wall_s : ndarray
        ``time.monotonic()`` when each SYNC was sent, s.
    sync_counter : ndarray
        SYNC counter value (0x1019) each SYNC carried (0 when the counter is off).
    drives : list of DriveSamples
    aborted : str or None
        Why the run stopped early, or None.
    sync_stamp_s : ndarray
        Bus stamp of each window's SYNC as the master heard it in real time (where the
        interface does not echo it, when ``send`` returned; NaN in lockstep),
        ``time.time()`` epoch, s.
    late_targets : int
        Windows whose RPDOs (targets) left after their SYNC (only when the kernel sends the
        SYNCs): they acted a SYNC late.
    """

    period_s: float
    count: int
    wall_s: np.ndarray
    sync_counter: np.ndarray
    drives: list[DriveSamples]
    aborted: str | None = None
    meta: dict[str, object] = field(default_factory=dict)
    sync_stamp_s: np.ndarray = field(default_factory=lambda: np.zeros(0))
    late_targets: int = 0

    @property
    def lost(self) -> dict[int, int]:
        return {d.node_id: d.lost for d in self.drives}

    @property
    def error(self) -> Exception | None:
        """The error that ended the run early (``meta["error"]``), or None."""
        error = self.meta.get("error")
        return error if isinstance(error, Exception) else None

    @property
    def complete(self) -> bool:
        """True when the run ended normally, every target acted at its own SYNC, and every
        window of every drive got each of its TPDOs once, in time: no TPDO lost, duplicated
        or late."""
        return (self.aborted is None and self.late_targets == 0
                and all(d.lost == d.duplicates == d.late == 0 for d in self.drives))

    def time_s(self) -> np.ndarray:
        return np.arange(self.count) * self.period_s


class Sampler:
    """Collects TPDOs into preallocated buffers.

    Parameters
    ----------
    tpdos : dict
        COB-ID → (drive number, PDO number within the drive, layout) of every TPDO expected.
    node_ids : sequence of int
        The drives, in drive-number order.
    scalings : sequence of Scaling
        Their units.
    samples : int
        Number of SYNC windows to hold.
    period_s : float
        SYNC period, s.
    window_s : float
        Synchronous window length, s: a TPDO stamped later after its SYNC is late (0: none).
    targets : sequence of int or None
        Each drive's RPDO target object (0x60FF, 0x6071, ...), or None; the windows keep
        the commanded value of those in :data:`TARGET_FIELDS`.
    current_means : sequence of (int, int) or None
        Each drive's object (index, subindex) holding its current averaged over each
        period, named by its motor profile, or None (the simulated drive's
        :data:`~bus.cia402.CURRENT_MEAN` is known anyway): it fills ``current_mean_A``.
    simulated : sequence of bool
        Whether each drive is the simulated one (default: all are): only then are its
        :data:`SIMULATION_OBJECTS` read.
    """

    def __init__(self, tpdos: dict[int, tuple[int, int, Layout]], node_ids: Sequence[int],
                 scalings: Sequence[Scaling], samples: int, period_s: float,
                 window_s: float = 0.0, targets: Sequence[int | None] = (),
                 current_means: Sequence[tuple[int, int] | None] = (),
                 simulated: Sequence[bool] = ()) -> None:
        self.window_s = window_s
        self.tpdos = tpdos
        self.scalings = list(scalings)
        self.samples = samples
        self.period_s = period_s
        pdos = [sum(1 for d, _, _ in tpdos.values() if d == n) for n in range(len(node_ids))]
        #: Object (index, subindex) → field, per drive.
        self.fields = [{(index, 0): name for index, name in FIELDS.items()} for _ in node_ids]
        for n, ours in enumerate(simulated):
            if not ours:
                for own in SIMULATION_OBJECTS:
                    del self.fields[n][(own, 0)]
        for n, named in enumerate(current_means):
            if named is not None:
                self.fields[n][named] = "current_mean_A"
        self.raw: list[dict[str, np.ndarray]] = []
        for n, fields in enumerate(self.fields):
            names = {fields[o] for c in tpdos.values() if c[0] == n for o in c[2].objects if o in fields}
            self.raw.append({name: np.full(samples, np.nan) for name in sorted(names)})
        #: Drive number → the field its commanded target fills.
        self.target_fields = {n: TARGET_FIELDS[index] for n, index in enumerate(targets)
                              if index in TARGET_FIELDS}
        for n, name in self.target_fields.items():
            self.raw[n][name] = np.full(samples, np.nan)
        self.received = [np.zeros((p, samples), dtype=bool) for p in pdos]
        self.duplicates = [0] * len(node_ids)
        self.late = [0] * len(node_ids)
        self.short = [0] * len(node_ids)
        self.node_ids = list(node_ids)
        self.expected = sum(pdos)
        self.wall_s = np.zeros(samples)
        self.sync_counter = np.zeros(samples, dtype=np.int16)
        self.sync_stamp = np.full(samples, np.nan)
        self.window = -1
        self._opened_stamp: float | None = 0.0
        self._parked: list[tuple[int, bytearray, float]] = []
        self._arrived = 0
        self.complete = threading.Event()
        self._lock = threading.Lock()
        self._plan = {cob: (d, p, layout, [self.fields[d].get(o) for o in layout.objects])
                      for cob, (d, p, layout) in tpdos.items()}

    def open(self, k: int, wall_s: float, counter: int) -> None:
        """Open window ``k`` (just before SYNC ``k`` is sent).

        Lockstep (no synchronous window): the drives answer only after the SYNC, so the
        window's reference stamp is taken now. Real time: the reference is the SYNC's own bus
        stamp (or the time ``send`` returned), given by :meth:`sent`; TPDOs that arrive
        before that are held and judged then (a late answer to SYNC ``k - 1`` that reached
        the bus while SYNC ``k`` was being sent is stamped before SYNC ``k``).
        """
        with self._lock:
            self._drop_parked()
            self._opened_stamp = None if self.window_s else time.time()
            self.window = k
            self._arrived = 0
            self.complete.clear()
            self.wall_s[k] = wall_s
            self.sync_counter[k] = counter

    def sent(self, stamp: float, counter: int = 0) -> None:
        """SYNC of the open window is on the bus, stamped ``stamp`` (its own bus stamp as the
        interface echoed it, or ``time.time()`` after ``send`` returned, which is never
        before that). ``counter`` is the echoed SYNC's counter byte: an echo of an earlier
        window's SYNC that the reader hands on late is ignored (0: no counter, not checked).
        """
        with self._lock:
            if self.window < 0 or (counter and counter != self.sync_counter[self.window]):
                return
            if self._opened_stamp is None:
                self._opened_stamp = stamp
                self.sync_stamp[self.window] = stamp
                parked, self._parked = self._parked, []
                for args in parked:
                    self._take(*args)

    def command(self, d: int, k: int, raw: int) -> None:
        """Drive ``d`` was commanded the raw target ``raw`` for window ``k`` (it acts from
        SYNC ``k`` to the next); kept when it is one of :data:`TARGET_FIELDS`."""
        name = self.target_fields.get(d)
        if name is not None:
            self.raw[d][name][k] = raw

    def missing(self, k: int) -> list[int]:
        """The drives (numbers) that lack a TPDO of window ``k``."""
        with self._lock:
            return [n for n, received in enumerate(self.received) if not received[:, k].all()]

    def close(self) -> None:
        """No window is open any more; TPDOs arriving now are late."""
        with self._lock:
            self.window = -1
            self._drop_parked()

    def _drop_parked(self) -> None:
        """TPDOs held for a window whose SYNC was never confirmed are late (lock held)."""
        for can_id, _, _ in self._parked:
            self.late[self._plan[can_id][0]] += 1
        self._parked = []

    def on_tpdo(self, can_id: int, data: bytearray, timestamp: float) -> None:
        """Subscriber of every expected TPDO COB-ID (called from the bus reader thread)."""
        with self._lock:
            if self.window >= 0 and self._opened_stamp is None:
                self._parked.append((can_id, data, timestamp))  # judged once the SYNC is out
                return
            self._take(can_id, data, timestamp)

    def _take(self, can_id: int, data: bytearray, timestamp: float) -> None:
        """Record one TPDO in the open window (the lock is held)."""
        d, p, layout, names = self._plan[can_id]
        if len(data) < layout.packer.size:
            self.short[d] += 1  # a foreign or broken frame: its sample is lost, not misread
            return
        k = self.window
        after = timestamp - (self._opened_stamp or 0.0)
        if k < 0 or -SAME_EPOCH_S < after < 0 or (self.window_s and SAME_EPOCH_S > after > self.window_s):
            # No window open, or the frame is stamped before this window's SYNC was
            # sent (it answers an earlier SYNC) or after the synchronous window.
            self.late[d] += 1
            return
        received = self.received[d]
        if received[p, k]:
            self.duplicates[d] += 1
            if k > 0 and not received[p, k - 1]:
                # The first frame of this window may have been the late answer to the
                # last SYNC: neither can be told apart, so this sample is not trusted.
                received[p, k] = False
                self.late[d] += 1
            return
        received[p, k] = True
        raw = self.raw[d]
        for name, value in zip(names, layout.unpack(data), strict=True):
            if name is not None:
                raw[name][k] = value
        self._arrived += 1
        if self._arrived == self.expected:
            self.complete.set()

    def result(self, count: int, aborted: str | None = None) -> Samples:
        """The first ``count`` windows in SI units."""
        drives = []
        for n, node_id in enumerate(self.node_ids):
            s = self.scalings[n]
            raw = {name: values[:count] for name, values in self.raw[n].items()}
            columns: dict[str, np.ndarray] = {}
            for name, values in raw.items():
                if name == "position_rad":
                    columns[name] = _unwrap_int32(values) * s.rad_per_count
                elif name == "current_A":
                    columns[name] = values * s.amp_per_unit
                elif name == "current_mean_A":
                    columns[name] = values * s.mean_amp_per_unit
                elif name in ("velocity_rad_s", "speed_target_rad_s"):
                    columns[name] = values * s.velocity_unit_rad_s
                elif name == "voltage_V":
                    columns[name] = values * s.voltage_unit_V
                else:
                    columns[name] = values.copy()
            received = self.received[n][:, :count].copy()
            drives.append(DriveSamples(node_id, columns, received,
                                       lost=int(np.sum(~received)),
                                       duplicates=self.duplicates[n], late=self.late[n],
                                       short=self.short[n]))
        return Samples(self.period_s, count, self.wall_s[:count].copy(),
                       self.sync_counter[:count].copy(), drives, aborted,
                       sync_stamp_s=self.sync_stamp[:count].copy())


class MissingPdos:
    """Counts, per drive, the SYNC windows in a row that lacked one of its TPDOs.

    Parameters
    ----------
    node_ids : sequence of int
        The drives, in drive-number order.
    limit : int
        Windows in a row after which the drive is reported.
    """

    def __init__(self, node_ids: Sequence[int], limit: int) -> None:
        self.node_ids = list(node_ids)
        self.limit = limit
        self.in_a_row = [0] * len(self.node_ids)

    def check(self, k: int, lacking: Sequence[int]) -> BusTimeout | None:
        """Window ``k`` lacked TPDOs of the drives ``lacking``; an error once one reaches the limit."""
        for n, node_id in enumerate(self.node_ids):
            self.in_a_row[n] = self.in_a_row[n] + 1 if n in lacking else 0
            if self.in_a_row[n] >= self.limit:
                return BusTimeout(f"node {node_id}: TPDOs missing for {self.limit} SYNCs in a row "
                                  f"(windows {k - self.limit + 1}-{k}); is it still OPERATIONAL? "
                                  "every drive was quick-stopped")
        return None


def _unwrap_int32(values: np.ndarray) -> np.ndarray:
    """Undo int32 wrap-around of a position counter (NaN entries stay NaN)."""
    out = values.copy()
    ok = np.isfinite(values)
    if ok.sum() > 1:
        v = values[ok]
        steps = np.diff(v)
        steps = (steps + INT32_SPAN // 2) % INT32_SPAN - INT32_SPAN // 2
        out[ok] = v[0] + np.concatenate(([0.0], np.cumsum(steps)))
    return out
