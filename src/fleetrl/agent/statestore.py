"""A crash-safe state directory: one JSON commit record naming an immutable safetensors blob, each written to
a temp file and renamed, so a process killed at any instant leaves the previous state or the new one."""

from __future__ import annotations

import hashlib
import itertools
import json
import logging
import os
from pathlib import Path
from typing import Any

import numpy as np
from safetensors import SafetensorError
from safetensors.numpy import load_file, save_file

log = logging.getLogger(__name__)

FORMAT = "fleetrl.state/1"  # ``format`` of every state record
_TEMP_NAMES = itertools.count()


class StateError(ValueError):
    """A state directory that cannot be used: missing, corrupt, or written for something else."""


class StateWriteError(OSError):
    """A state could not be committed (a one-line message naming the file); the last committed one stays."""


class StateStore:
    """Save and load one named state (``chief``, ``worker``...; its record ``<name>.json``) in ``directory``,
    created on the first save; one writer per directory."""

    def __init__(self, directory: str | Path, name: str) -> None:
        self.directory = Path(directory)
        self.name = name
        self._blob: str | None = None  # the blob the last save or load used
        self._blob_digest: str | None = None
        self._tensor_digest: str | None = None
        self._serial = 0

    @property
    def record(self) -> Path:
        """The JSON commit record."""
        return self.directory / f"{self.name}.json"

    def exists(self) -> bool:
        """True if a state was committed here."""
        return self.record.is_file()

    def save(self, fields: dict[str, Any], tensors: dict[str, np.ndarray]) -> None:
        """Commit ``fields`` and ``tensors`` atomically (unchanged tensors reuse the current blob);
        StateWriteError if the write failed."""
        try:
            self._save(fields, tensors)
        except (OSError, _WriteFailed) as exc:
            target, why = _what_failed(exc, self.record)
            raise StateWriteError(
                f"cannot write the {self.name} checkpoint {target}: {why}; the last committed state in "
                f"{self.directory} stays loadable"
            ) from exc

    def _save(self, fields: dict[str, Any], tensors: dict[str, np.ndarray]) -> None:
        self.directory.mkdir(parents=True, exist_ok=True)
        contiguous = {k: np.ascontiguousarray(v) for k, v in sorted(tensors.items())}
        digest = _tensor_digest(contiguous)
        previous = self._blob
        if previous is None:  # never number a new blob like one a committed record may name
            existing = (_serial_of(b.name) for b in self.directory.glob(f"{self.name}-*.safetensors"))
            self._serial = max(self._serial, *existing, 0)
        if digest != self._tensor_digest or self._blob is None:
            self._serial += 1
            blob = f"{self.name}-{self._serial}.safetensors"
            partial = _temp_name(self.directory / blob)
            try:
                save_file(contiguous, str(partial))
                _fsync(partial)
            except (OSError, SafetensorError) as exc:  # safetensors reports a failed write as its own error
                partial.unlink(missing_ok=True)
                raise _WriteFailed(partial, exc) from exc
            _replace(partial, self.directory / blob)
            self._blob, self._tensor_digest = blob, digest
            self._blob_digest = _file_digest(self.directory / blob)
        record = {
            "format": FORMAT,
            "name": self.name,
            "tensors": self._blob,
            "sha256": self._blob_digest,
            "fields": fields,
        }
        _write_atomic(self.record, json.dumps(record, indent=1, sort_keys=True) + "\n")
        if previous is not None and previous != self._blob:
            (self.directory / previous).unlink(missing_ok=True)

    def load(self) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
        """The committed (fields, tensors); FileNotFoundError if none, StateError if unreadable or corrupt."""
        if not self.exists():
            raise FileNotFoundError(f"no {self.name} state in {self.directory} ({self.record.name} missing)")
        try:
            record = json.loads(self.record.read_text())
        except (OSError, ValueError) as exc:
            raise StateError(f"{self.record} is not a readable state record ({exc})") from exc
        if not isinstance(record, dict) or record.get("format") != FORMAT or record.get("name") != self.name:
            raise StateError(f"{self.record} is not a fleetrl {self.name} state ({FORMAT})")
        blob = self.directory / str(record.get("tensors"))
        if not blob.is_file() or _file_digest(blob) != record.get("sha256"):
            raise StateError(f"{self.record}: its tensor file {blob.name} is missing or does not match")
        try:
            tensors = load_file(str(blob))
        except (SafetensorError, OSError) as exc:
            raise StateError(f"{blob} is not a readable safetensors file ({exc})") from exc
        self._blob, self._blob_digest = blob.name, record["sha256"]
        self._tensor_digest = _tensor_digest({k: tensors[k] for k in sorted(tensors)})
        self._serial = max(self._serial, _serial_of(blob.name))
        for stale in self.directory.glob(f"{self.name}-*.safetensors"):
            if stale.name != blob.name:  # a blob written by a save that crashed before its commit
                stale.unlink(missing_ok=True)
        for partial in self.directory.glob(f".{self.name}*.partial"):  # a save's temp file, cut short
            partial.unlink(missing_ok=True)
        return dict(record["fields"]), tensors


def _serial_of(blob: str) -> int:
    try:
        return int(blob.rsplit("-", 1)[1].split(".")[0])
    except (IndexError, ValueError):
        return 0


def _tensor_digest(tensors: dict[str, np.ndarray]) -> str:
    h = hashlib.sha256()
    for name, array in tensors.items():
        h.update(f"{name}|{array.dtype.str}|{array.shape}|".encode())
        h.update(array.tobytes())
    return h.hexdigest()


def _file_digest(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


class _WriteFailed(Exception):
    def __init__(self, path: Path, cause: BaseException) -> None:
        super().__init__(str(path))
        self.path, self.cause = path, cause


def _what_failed(exc: BaseException, record: Path) -> tuple[str, str]:
    """(the file, why) of a failed write, in words for one line."""
    if isinstance(exc, _WriteFailed):
        path, exc = str(exc.path), exc.cause
    else:
        # os.replace names its source first and its target second: the target is the file that failed
        path = str(getattr(exc, "filename2", None) or getattr(exc, "filename", None) or record)
    why = exc.strerror if isinstance(exc, OSError) and exc.strerror else str(exc)
    return path, (why.splitlines() or [type(exc).__name__])[0]


def _temp_name(path: Path) -> Path:
    """A temporary name beside ``path`` that no other write (of this process or another) uses."""
    return path.with_name(f".{path.name}.{os.getpid()}.{next(_TEMP_NAMES)}.partial")


def _replace(partial: Path, path: Path) -> None:
    """Rename ``partial`` onto ``path``; if that fails, remove ``partial`` and raise."""
    try:
        os.replace(partial, path)
    except OSError:
        partial.unlink(missing_ok=True)
        raise


def _write_atomic(path: Path, text: str) -> None:
    partial = _temp_name(path)
    try:
        with open(partial, "w") as handle:
            handle.write(text)
            handle.flush()
            os.fsync(handle.fileno())
    except OSError:
        partial.unlink(missing_ok=True)
        raise
    _replace(partial, path)
    _fsync_dir(path.parent)


def _fsync(path: Path) -> None:
    with open(path, "rb") as handle:
        os.fsync(handle.fileno())


def _fsync_dir(directory: Path) -> None:
    try:
        fd = os.open(directory, os.O_RDONLY)
    except OSError:  # some filesystems do not open directories; the rename is still atomic
        return
    try:
        os.fsync(fd)
    finally:
        os.close(fd)
