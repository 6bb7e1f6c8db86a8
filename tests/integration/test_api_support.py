"""A real ``stand serve`` (uvicorn) in a subprocess on a free loopback port, for the API tests.

Not a test module of its own: the API tests import :func:`serve` from here. Each server
leads its own process group, so the processes it starts (the upload parser's forkserver
and worker, a batch's Dask cluster) can be found, and :func:`stop` ends whatever of them
outlives it.
"""

from __future__ import annotations

import contextlib
import os
import resource
import signal
import socket
import subprocess
import sys
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import TypeVar

import httpx

T = TypeVar("T")

#: How long the server may take to answer /health after start, s.
START_TIMEOUT_S = 30.0
ROOT = Path(__file__).resolve().parents[2]
#: How long the processes a stopped server left behind may take to end once killed, s.
HELPERS_END_S = 5.0


@dataclass
class Server:
    """A running service: its URL, key, data directory and process."""

    base_url: str
    api_key: str | None
    data_dir: Path
    process: subprocess.Popen[bytes]
    log_path: Path

    def client(self, auth: bool = True, timeout: float = 60.0) -> httpx.Client:
        headers = {"Authorization": f"Bearer {self.api_key}"} if auth and self.api_key else {}
        return httpx.Client(base_url=self.base_url, headers=headers, timeout=timeout)

    def kill(self) -> None:
        """SIGKILL: no shutdown, no cleanup, as a crash."""
        self.process.send_signal(signal.SIGKILL)
        self.process.wait(10)

    def helpers(self) -> list[int]:
        """The processes the server started that are still there (its process group)."""
        return [pid for pid in _process_group(self.process.pid) if pid != self.process.pid]


def _process_group(pgid: int) -> list[int]:
    """The live processes (not zombies) of process group ``pgid``."""
    members = []
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            fields = (entry / "stat").read_text().rsplit(")", 1)[1].split()
        except OSError:  # ended meanwhile
            continue
        if int(fields[2]) == pgid and fields[0] != "Z":
            members.append(int(entry.name))
    return members

    def log(self) -> str:
        return self.log_path.read_text(errors="replace")


def wait_for(condition: Callable[[], T], timeout_s: float, what: str = "condition") -> T:
    """``condition()`` once it is truthy, polled every 50 ms; AssertionError after
    ``timeout_s`` seconds."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        value = condition()
        if value:
            return value
        time.sleep(0.05)
    raise AssertionError(f"{what}: not within {timeout_s} s")


def free_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return int(sock.getsockname()[1])


def start(data_dir: Path, api_key: str | None = "test-key", extra_env: dict[str, str] | None = None,
          file_size_limit: int | None = None) -> Server:
    """Start ``python -m stand serve`` and wait until /health answers.

    ``file_size_limit``: largest file the server may write, bytes (``RLIMIT_FSIZE``): a
    disk that fills up, without a privileged mount. Python ignores SIGXFSZ, so a write
    past the limit fails with EFBIG as on a full disk instead of killing the process.
    """

    def limit_files() -> None:
        if file_size_limit is not None:
            resource.setrlimit(resource.RLIMIT_FSIZE, (file_size_limit, file_size_limit))

    port = free_port()
    env = {k: v for k, v in os.environ.items() if not k.startswith("STAND_")}
    env.update(STAND_DATA_DIR=str(data_dir), PYTHONPATH=str(ROOT), **(extra_env or {}))
    if api_key:
        env["STAND_API_KEY"] = api_key
    data_dir.mkdir(parents=True, exist_ok=True)
    log_path = data_dir / f"server-{port}.log"
    with open(log_path, "ab") as log:
        process = subprocess.Popen(
            [sys.executable, "-m", "stand", "serve", "--host", "127.0.0.1", "--port", str(port),
             "--log-level", "warning"], cwd=ROOT, env=env, stdout=log, stderr=subprocess.STDOUT,
            preexec_fn=limit_files if file_size_limit is not None else None, start_new_session=True)
    server = Server(f"http://127.0.0.1:{port}", api_key, data_dir, process, log_path)
    deadline = time.monotonic() + START_TIMEOUT_S
    while time.monotonic() < deadline:
        if process.poll() is not None:
            raise RuntimeError(f"server exited with {process.returncode}:\n{server.log()}")
        try:
            if httpx.get(f"{server.base_url}/health", timeout=1.0).status_code == 200:
                return server
        except httpx.TransportError:
            pass
        time.sleep(0.1)
    server.kill()
    raise RuntimeError(f"server did not answer /health in {START_TIMEOUT_S} s:\n{server.log()}")


def stop(server: Server) -> None:
    """SIGTERM and wait (graceful shutdown); SIGKILL if it hangs. Then SIGKILL whatever the
    server started and left behind, so that no test leaves a process after pytest."""
    if server.process.poll() is None:
        server.process.terminate()
        try:
            server.process.wait(15)
        except subprocess.TimeoutExpired:
            server.kill()
    for pid in server.helpers():
        with contextlib.suppress(ProcessLookupError):
            os.kill(pid, signal.SIGKILL)
    deadline = time.monotonic() + HELPERS_END_S
    while server.helpers() and time.monotonic() < deadline:  # gone, not just told
        time.sleep(0.05)


@contextmanager
def serve(data_dir: Path, api_key: str | None = "test-key",
          extra_env: dict[str, str] | None = None, file_size_limit: int | None = None,
          ) -> Iterator[Server]:
    """A running server for the ``with`` block."""
    server = start(data_dir, api_key, extra_env, file_size_limit)
    try:
        yield server
    finally:
        stop(server)
