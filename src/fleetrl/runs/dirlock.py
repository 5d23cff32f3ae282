"""One process per run directory: the exclusive ``fcntl.flock`` a role holds on ``DIR/.lock-chief`` or
``DIR/.lock-worker`` for its whole life, naming its holder (local disks only: flock may not hold over NFS)."""

from __future__ import annotations

import contextlib
import fcntl
import json
import os
import socket
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

LOCK_PREFIX = ".lock-"


class RoleConflict(OSError):
    """Another process holds what this role needs (its run directory, or its place in the run): the command
    did not start (exit 1)."""


@dataclass(frozen=True)
class Holder:
    """Who holds a run directory (or a place in a run), since when (ISO 8601, UTC)."""

    role: str
    pid: int | None
    host: str | None
    since: str | None

    def describe(self) -> str:
        """``pid 123 on host h since 2024-…`` (what is known of it)."""
        parts = []
        if self.pid is not None:
            parts.append(f"pid {self.pid}")
        if self.host:
            parts.append(f"on host {self.host}")
        if self.since:
            parts.append(f"since {self.since}")
        return " ".join(parts) or "a process that did not say who it is"


class DirectoryLock:
    """The exclusive lock of ``directory`` for ``role`` (``chief``, ``worker K``, ``unit host K``), from
    :meth:`acquire` (or ``with``) until :meth:`release` or the process's end."""

    def __init__(self, directory: Path, role: str) -> None:
        self.directory = Path(directory)
        self.role = role
        self._fd: int | None = None
        self._new_file = False
        self.created = False
        """whether :meth:`acquire` created the directory (a refused start removes what it created)"""

    @property
    def path(self) -> Path:
        return self.directory / (LOCK_PREFIX + ("chief" if self.role == "chief" else "worker"))

    def acquire(self) -> DirectoryLock:
        """Take the lock (creating the directory if needed); :class:`RoleConflict` naming the holder if
        another process has it."""
        self.created = not self.directory.exists()
        self.directory.mkdir(parents=True, exist_ok=True)
        self._new_file = not self.path.exists()
        fd = os.open(self.path, os.O_RDWR | os.O_CREAT | os.O_CLOEXEC, 0o644)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            holder = _read_holder(fd)
            os.close(fd)
            raise RoleConflict(
                f"{self.directory} is in use by the {holder.role} {holder.describe()} (it holds "
                f"{self.path}): only one process may use a run directory; stop that one first (it keeps "
                "the lock while it lives, even stopped), or choose another --out"
            ) from None
        except OSError:
            os.close(fd)
            raise
        since = datetime.now(UTC).isoformat(timespec="seconds")
        me = {"role": self.role, "pid": os.getpid(), "host": socket.gethostname(), "since": since}
        record = json.dumps(me) + "\n"
        os.ftruncate(fd, 0)
        os.pwrite(fd, record.encode(), 0)
        os.fsync(fd)
        self._fd = fd
        return self

    def release(self) -> None:
        """Let the lock go (the file stays: removing it could race a process taking it)."""
        if self._fd is not None:
            with contextlib.suppress(OSError):
                fcntl.flock(self._fd, fcntl.LOCK_UN)
            os.close(self._fd)
            self._fd = None

    def abandon(self) -> None:
        """Remove what :meth:`acquire` created (the lock file, and the directory if this lock made it and
        nothing else was put there) and release the lock, for a start refused after it."""
        if self._fd is not None and self._new_file:
            with contextlib.suppress(OSError):
                self.path.unlink()
        self.release()
        if self.created:
            with contextlib.suppress(OSError):
                self.directory.rmdir()

    def __enter__(self) -> DirectoryLock:
        return self if self._fd is not None else self.acquire()

    def __exit__(self, *exc: object) -> None:
        self.release()


def _read_holder(fd: int) -> Holder:
    try:
        data: Any = json.loads(os.pread(fd, 4096, 0).decode() or "{}")
    except (OSError, ValueError):
        data = {}
    if not isinstance(data, dict):
        data = {}
    pid = data.get("pid")
    return Holder(
        str(data.get("role") or "process"),
        pid if isinstance(pid, int) else None,
        str(data["host"]) if data.get("host") else None,
        str(data["since"]) if data.get("since") else None,
    )
