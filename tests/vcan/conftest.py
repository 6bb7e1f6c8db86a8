"""Fixtures of the real-SocketCAN suite: skip outside a host with vcan0, fail inside UML without it.

The suite runs inside User-Mode Linux through ``tests/vcan/run.sh`` (the host kernel here has
no CAN). On a lab machine with ``vcan0`` (``ip link add dev vcan0 type vcan``) it runs as is:
``pytest tests/vcan``.
"""

from __future__ import annotations

import os
import selectors
import shutil
import signal
import subprocess
import sys
import time
from collections.abc import Callable, Iterator
from pathlib import Path

import can
import pytest

CHANNEL = "vcan0"
VCAN_SYSFS = Path("/sys/class/net") / CHANNEL
IN_UML = os.environ.get("VCAN_IN_UML") == "1"
CAN_UTILS = ("candump", "cangen", "cansend")


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """Mark every test here ``vcan``; skip them all where vcan0 or can-utils are missing."""
    here = Path(__file__).parent
    missing = [tool for tool in CAN_UTILS if shutil.which(tool) is None]
    reason = None
    if not VCAN_SYSFS.exists():
        reason = f"{VCAN_SYSFS} missing: run tests/vcan/run.sh (User-Mode Linux) or create vcan0"
    elif missing:
        reason = f"can-utils missing ({', '.join(missing)}): apt-get install can-utils"
    # A module with NEEDS_VCAN = False holds pure checks (frame decoding) that run anywhere.
    ours = [item for item in items if here in Path(str(item.fspath)).parents
            and getattr(getattr(item, "module", None), "NEEDS_VCAN", True)]
    if ours and reason is not None and IN_UML:
        # Inside the guest a missing vcan0 is a broken runner, not a reason to skip.
        raise pytest.UsageError(f"tests/vcan inside User-Mode Linux: {reason}")
    for item in ours:
        item.add_marker(pytest.mark.vcan)
        if reason is not None:
            item.add_marker(pytest.mark.skip(reason=reason))


@pytest.fixture
def vcan_bus() -> Iterator[can.BusABC]:
    """One SocketCAN bus on vcan0 that receives its own frames only if asked (default: not)."""
    bus = can.Bus(interface="socketcan", channel=CHANNEL)
    try:
        yield bus
    finally:
        bus.shutdown()


@pytest.fixture
def vcan_pair() -> Iterator[tuple[can.BusABC, can.BusABC]]:
    """Two independent SocketCAN sockets on vcan0 (two nodes on one wire)."""
    a = can.Bus(interface="socketcan", channel=CHANNEL)
    b = can.Bus(interface="socketcan", channel=CHANNEL)
    try:
        yield a, b
    finally:
        a.shutdown()
        b.shutdown()


SIMSTAND_READY_TIMEOUT_S = 60.0
SIMSTAND_STOP_TIMEOUT_S = 10.0
REPO = Path(__file__).resolve().parents[2]


class SimstandProcess:
    """``python -m bus.simstand`` on vcan0 in its own process (the drives), ended on close.

    Parameters
    ----------
    profile : str
        Motor or stand profile the drives simulate.
    log_path : Path
        File receiving the process's stderr (its log), shown when something fails.
    extra : list of str
        Further command-line options (``--seed``, ...).
    """

    def __init__(self, profile: str, log_path: Path, extra: list[str] | None = None) -> None:
        self.args = [sys.executable, "-m", "bus.simstand", "--interface", "socketcan",
                     "--channel", CHANNEL, "--profile", profile, *(extra or [])]
        self.log_path = log_path
        self._log = log_path.open("w")
        self.proc = subprocess.Popen(self.args, cwd=REPO, stdout=subprocess.PIPE,
                                     stderr=self._log, text=True)
        self.returncode: int | None = None

    def log(self) -> str:
        if not self._log.closed:
            self._log.flush()
        return self.log_path.read_text()

    def wait_ready(self, timeout_s: float = SIMSTAND_READY_TIMEOUT_S) -> None:
        """Block until the process prints ``ready`` (its nodes have booted); raise
        TimeoutError with the process's log otherwise."""
        assert self.proc.stdout is not None
        deadline = time.monotonic() + timeout_s
        with selectors.DefaultSelector() as sel:
            sel.register(self.proc.stdout, selectors.EVENT_READ)
            while time.monotonic() < deadline:
                if sel.select(max(0.0, deadline - time.monotonic())):
                    line = self.proc.stdout.readline()
                    if line.strip() == "ready":
                        return
                    if line == "":
                        break  # EOF: the process ended
        self.close()
        raise TimeoutError(f"{' '.join(self.args)} not ready within {timeout_s} s "
                           f"(exit {self.returncode}); its log:\n{self.log()}")

    def close(self) -> int:
        """SIGTERM, wait, and return the exit status (SIGKILL after a timeout)."""
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGTERM)
            try:
                self.proc.wait(SIMSTAND_STOP_TIMEOUT_S)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()
        if self.proc.stdout is not None:
            self.proc.stdout.close()
        self._log.close()
        self.returncode = self.proc.returncode
        return self.returncode


@pytest.fixture
def simstand(tmp_path: Path) -> Iterator[Callable[..., SimstandProcess]]:
    """Factory: ``simstand("crouzet_82800502")`` starts the drives' process (not waiting for
    ``ready``, so a capture can be started around the boot); all end with the test, and each
    must exit 0 on SIGTERM."""
    started: list[SimstandProcess] = []

    def start(profile: str, *extra: str) -> SimstandProcess:
        proc = SimstandProcess(profile, tmp_path / f"simstand{len(started)}.log", list(extra))
        started.append(proc)
        return proc

    yield start
    bad = [(p, p.close()) for p in started]
    bad = [(p, rc) for p, rc in bad if rc != 0]
    assert not bad, "; ".join(f"simstand exited {rc} on SIGTERM; log:\n{p.log()}" for p, rc in bad)
