"""One owner per data directory: an exclusive lock held for the life of a service.

Two services on one ``STAND_DATA_DIR`` would each believe they own the runs in it: the
second one's start-up recovery would mark the first one's live run ``aborted`` while its
drive keeps moving, and on hardware both would be CAN masters on one bus. The first
service takes ``fcntl.flock`` on ``<data_dir>/stand.lock`` and writes its PID there; a
second one finds the lock taken and refuses to start, naming that PID. The kernel drops
the lock when the owner's process ends, however it ends (SIGKILL included), so a stale
lock file never blocks a restart.
"""

from __future__ import annotations

import fcntl
import os
from pathlib import Path
from types import TracebackType
from typing import IO

from stand.errors import DataDirLocked, StorageError

#: Name of the lock file inside the data directory.
LOCK_NAME = "stand.lock"


class DataDirLock:
    """Exclusive ownership of ``data_dir`` by this process.

    Parameters
    ----------
    data_dir : path
        The service's data directory (created if missing).

    Examples
    --------
    >>> with DataDirLock(path) as lock:  # doctest: +SKIP
    ...     storage.recover(lock)
    """

    def __init__(self, data_dir: str | Path) -> None:
        self.data_dir = Path(data_dir)
        self.path = self.data_dir / LOCK_NAME
        self._file: IO[str] | None = None

    @property
    def held(self) -> bool:
        """Whether this object holds the lock now."""
        return self._file is not None

    def acquire(self) -> DataDirLock:
        """Take the lock or raise :class:`DataDirLocked` naming the owner's PID."""
        if self._file is not None:
            return self
        try:
            self.data_dir.mkdir(parents=True, exist_ok=True)
            # "a+" neither truncates nor moves the owner's PID before we hold the lock.
            file = open(self.path, "a+", encoding="ascii")  # noqa: SIM115 (held until release)
        except OSError as exc:
            raise StorageError(f"data directory {self.data_dir}: cannot open the lock file "
                               f"{self.path}: {exc}") from exc
        try:
            fcntl.flock(file.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError as exc:
            file.seek(0)
            owner = file.read(32).strip() or "unknown"
            file.close()
            raise DataDirLocked(
                f"data directory {self.data_dir} is in use by another stand service "
                f"(PID {owner}, lock file {self.path}); stop that service or set "
                "STAND_DATA_DIR to another directory") from exc
        file.seek(0)
        file.truncate()
        file.write(f"{os.getpid()}\n")
        file.flush()
        self._file = file
        return self

    def release(self) -> None:
        """Give the lock up (closing the file releases it)."""
        file, self._file = self._file, None
        if file is not None:
            file.close()

    def __enter__(self) -> DataDirLock:
        return self.acquire()

    def __exit__(self, kind: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        self.release()
