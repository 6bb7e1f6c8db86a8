"""can-utils as an independent peer on vcan0: a candump capture and a cangen load generator.

`candump` and `cangen` (the SocketCAN project's own tools, written in C, not sharing a line of
code with python-can or canopen) see and make the frames on the wire, so a check against them
is a check of what really crossed the bus, not of what our Python believes it sent.
"""

from __future__ import annotations

import contextlib
import re
import signal
import subprocess
import threading
import time
from dataclasses import dataclass
from typing import Any

import can

CANDUMP_READY_TIMEOUT_S = 5.0
CANDUMP_STOP_TIMEOUT_S = 5.0
MARKER_PERIOD_S = 0.02
# An extended (29-bit) identifier: CANopen (CiA 301) uses 11-bit identifiers only, so the
# markers that frame a capture can never be confused with the traffic under test.
MARKER_ID = 0x1FFFFFFE
MARKER_START = b"START"
MARKER_STOP = b"STOP"

_LINE = re.compile(r"^\((?P<t>[0-9.]+)\)\s+(?P<ch>\S+)\s+(?P<id>[0-9A-Fa-f]+)#(?P<rest>\S*)$")


@dataclass(frozen=True)
class Frame:
    """One classic CAN frame as candump logged it.

    Attributes
    ----------
    timestamp_s : float
        Kernel receive time of candump's socket (s, epoch).
    arbitration_id : int
        11- or 29-bit identifier.
    is_extended_id : bool
        True for a 29-bit identifier (candump prints 8 hex digits).
    is_remote_frame : bool
        True for an RTR frame.
    data : bytes
        Payload, 0..8 bytes.
    """

    timestamp_s: float
    arbitration_id: int
    is_extended_id: bool
    is_remote_frame: bool
    data: bytes


#: candump's socket receive buffer (``-r``; root sets it past ``rmem_max``), bytes.
CANDUMP_RCVBUF_BYTES = 8 * 1024 * 1024


def interrupt(proc: subprocess.Popen[Any]) -> None:
    """Stop a can-utils tool as a user would (SIGINT), killing it if it does not end."""
    if proc.poll() is None:
        proc.send_signal(signal.SIGINT)
        try:
            proc.wait(CANDUMP_STOP_TIMEOUT_S)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()


def parse_candump_line(line: str) -> Frame | None:
    """Parse one line of ``candump -L`` output (``(1.000000) vcan0 123#11223344``).

    Returns None for a line that is not a classic CAN frame (blank, CAN FD ``##``).
    """
    match = _LINE.match(line.strip())
    if match is None or match["rest"].startswith("#"):
        return None
    ident = match["id"]
    rest = match["rest"]
    remote = rest.upper().startswith("R")
    data = b"" if remote else bytes.fromhex(rest)
    return Frame(float(match["t"]), int(ident, 16), len(ident) == 8, remote, data)


class Candump:
    """Capture vcan0 with ``candump -L`` between two marker frames.

    Used as a context manager: on entry candump is started and a START marker is sent until
    candump has logged it (so nothing sent afterwards can be missed); on exit a STOP marker is
    sent, candump is read up to it and ended. ``frames`` then holds every frame between the
    markers, in bus order, markers excluded, and ``drop_reports`` candump's reports of frames
    its socket dropped (``-d``; empty when it saw everything).

    Parameters
    ----------
    channel : str
        SocketCAN interface, e.g. ``"vcan0"``.
    """

    def __init__(self, channel: str) -> None:
        self.channel = channel
        self.frames: list[Frame] = []
        self.drop_reports: list[str] = []
        self._lines: list[str] = []
        self._cond = threading.Condition()
        self._proc: subprocess.Popen[str] | None = None
        self._reader: threading.Thread | None = None
        self._marker_bus: can.BusABC | None = None

    def __enter__(self) -> Candump:
        # stdbuf: candump's stdout is a pipe here, which C stdio would otherwise block-buffer.
        # -r: a socket buffer for seconds of traffic, so that candump, blocked on a pipe whose
        # Python reader the loaded one-CPU guest starves, drops nothing (the default ~200 kB
        # dropped frames at load 11 on the host).
        self._proc = subprocess.Popen(
            ["stdbuf", "-oL", "candump", "-L", "-d", "-r", str(CANDUMP_RCVBUF_BYTES), self.channel],
            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        self._reader = threading.Thread(target=self._read, name="candump-reader")
        self._reader.start()
        self._marker_bus = can.Bus(interface="socketcan", channel=self.channel)
        try:
            self._mark(MARKER_START, CANDUMP_READY_TIMEOUT_S)
        except BaseException:
            self._close()
            raise
        return self

    def __exit__(self, *exc: object) -> None:
        try:
            self._mark(MARKER_STOP, CANDUMP_STOP_TIMEOUT_S)
        finally:
            self._close()
        self.frames = self._between_markers()
        self.drop_reports = [line.strip() for line in self._lines if "DROPCOUNT" in line]

    def _read(self) -> None:
        assert self._proc is not None and self._proc.stdout is not None
        for line in self._proc.stdout:
            with self._cond:
                self._lines.append(line)
                self._cond.notify_all()

    def _seen(self, payload: bytes) -> bool:
        for line in reversed(self._lines):  # a marker just sent is near the end
            frame = parse_candump_line(line)
            if frame is not None and frame.arbitration_id == MARKER_ID and frame.data == payload:
                return True
        return False

    def _mark(self, payload: bytes, timeout_s: float) -> None:
        assert self._marker_bus is not None and self._proc is not None
        deadline = time.monotonic() + timeout_s
        msg = can.Message(arbitration_id=MARKER_ID, is_extended_id=True, data=payload)
        while True:
            self._marker_bus.send(msg)
            with self._cond:
                if self._cond.wait_for(lambda: self._seen(payload), MARKER_PERIOD_S):
                    return
            if self._proc.poll() is not None:
                err = self._proc.stderr.read() if self._proc.stderr else ""
                raise RuntimeError(f"candump exited with {self._proc.returncode}: {err.strip()}")
            if time.monotonic() > deadline:
                raise TimeoutError(f"candump did not log the {payload!r} marker within {timeout_s} s")

    def _close(self) -> None:
        if self._marker_bus is not None:
            self._marker_bus.shutdown()
            self._marker_bus = None
        if self._proc is not None:
            interrupt(self._proc)
            for stream in (self._proc.stdout, self._proc.stderr):
                if stream is not None:
                    stream.close()
        if self._reader is not None:
            self._reader.join(CANDUMP_STOP_TIMEOUT_S)
            self._reader = None

    def _between_markers(self) -> list[Frame]:
        frames = [f for f in map(parse_candump_line, self._lines) if f is not None]
        start = next(i for i, f in enumerate(frames)
                     if f.arbitration_id == MARKER_ID and f.data == MARKER_START)
        out: list[Frame] = []
        for frame in frames[start + 1:]:
            if frame.arbitration_id == MARKER_ID:
                if frame.data == MARKER_STOP:
                    break
                continue  # repeated START markers
            out.append(frame)
        return out


class Cangen:
    """Foreign traffic from ``cangen`` while the block runs (stopped with SIGINT on exit).

    Parameters
    ----------
    channel : str
        SocketCAN interface.
    gap_ms : float
        Gap between frames (ms); 0 = as fast as the kernel takes them.
    ident : str
        cangen's ``-I`` mode: a fixed hex identifier, ``r`` (random) or ``i`` (increment).
    extra : list of str
        Further cangen options, e.g. ``["-L", "8", "-D", "i"]``.
    count : int or None
        Frames to send (``-n``); the block's exit then waits for cangen to finish and
        ``returncode`` is cangen's own verdict. None: send until the block ends.
    """

    def __init__(self, channel: str, gap_ms: float = 1.0, ident: str = "r",
                 extra: list[str] | None = None, count: int | None = None) -> None:
        # -p: on a full transmit queue wait (poll) instead of failing or dropping.
        self.args = ["cangen", channel, "-g", f"{gap_ms:g}", "-I", ident, "-p", "10", *(extra or [])]
        if count is not None:
            self.args += ["-n", str(count)]
        self.count = count
        self._proc: subprocess.Popen[bytes] | None = None
        self.returncode: int | None = None
        self.stderr = ""

    def __enter__(self) -> Cangen:
        self._proc = subprocess.Popen(self.args, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
        time.sleep(0.05)
        if self._proc.poll() is not None:
            err = self._proc.stderr.read().decode() if self._proc.stderr else ""
            raise RuntimeError(f"{' '.join(self.args)} exited with {self._proc.returncode}: {err}")
        return self

    def __exit__(self, *exc: object) -> None:
        assert self._proc is not None
        if self.count is not None:
            # A counted run ends by itself; a signal would interrupt its poll() and make
            # it exit with an error status.
            with contextlib.suppress(subprocess.TimeoutExpired):
                self._proc.wait(CANDUMP_STOP_TIMEOUT_S)
        interrupt(self._proc)
        if self._proc.stderr is not None:
            self.stderr = self._proc.stderr.read().decode(errors="replace")
            self._proc.stderr.close()
        self.returncode = self._proc.returncode
