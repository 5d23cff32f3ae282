"""Worker processes (:mod:`fleetrl.runs.worker_main`) that print their rounds as JSON lines on stdout, read
on threads into one queue. Where the OS has ``fork`` a child is forked with fleetrl already imported (so the
fleet starts before this process starts threads or a multi-threaded torch operation);
``FLEETRL_WORKER_START=spawn`` starts new interpreters instead."""

import logging
import os
import queue
import signal
import subprocess
import sys
import threading
import time
import traceback
from collections.abc import Mapping, Sequence
from contextlib import suppress
from dataclasses import dataclass
from pathlib import Path
from typing import IO, NoReturn

from fleetrl.runs.records import MetricsRow

log = logging.getLogger(__name__)

WORKER_MODULE = "fleetrl.runs.worker_main"
START_ENV = "FLEETRL_WORKER_START"
CHILD_ENV = {"PYTHONUNBUFFERED": "1", "OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}


@dataclass
class WorkerExit:
    """A worker (process or thread) ended (``returncode`` 0: a clean end)."""

    worker: int
    returncode: int


FleetEvent = MetricsRow | WorkerExit


class ForkedChild:
    """A child forked from this process, with the part of ``subprocess.Popen``'s interface the fleet uses."""

    def __init__(self, pid: int) -> None:
        self.pid = pid
        self.returncode: int | None = None
        self._lock = threading.Lock()

    def poll(self) -> int | None:
        with self._lock:
            if self.returncode is None:
                pid, status = os.waitpid(self.pid, os.WNOHANG)
                if pid:
                    self.returncode = os.waitstatus_to_exitcode(status)
            return self.returncode

    def wait(self, timeout: float | None = None) -> int:
        deadline = None if timeout is None else time.monotonic() + timeout
        while (code := self.poll()) is None:
            if deadline is not None and time.monotonic() >= deadline:
                raise subprocess.TimeoutExpired(str(self.pid), timeout or 0.0)
            time.sleep(0.02)
        return code

    def send_signal(self, sig: int) -> None:
        if self.poll() is None:
            os.kill(self.pid, sig)

    def kill(self) -> None:
        self.send_signal(signal.SIGKILL)


Child = ForkedChild | subprocess.Popen[str]


def fork_available() -> bool:
    """Whether worker processes are forked."""
    how = os.environ.get(START_ENV, "fork").strip().lower()
    if how not in ("fork", "spawn"):
        raise ValueError(f"{START_ENV}={how!r}: use fork or spawn")
    return how == "fork" and hasattr(os, "fork")


def _run_forked_worker(args: Sequence[str], stdout_fd: int, log_path: Path) -> NoReturn:
    """The forked child: a new session, stdout to the parent's pipe, stderr to its log; run the worker and
    exit without returning into the parent's code."""
    code = 1
    try:
        os.setsid()
        os.dup2(stdout_fd, 1)
        os.close(stdout_fd)
        log_fd = os.open(log_path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o644)
        os.dup2(log_fd, 2)
        os.close(log_fd)
        # new streams over fds 1 and 2: the inherited ones may write elsewhere (a test's capture)
        sys.stdout = open(1, "w", encoding="utf-8", buffering=1, closefd=False)  # noqa: SIM115
        sys.stderr = open(2, "w", encoding="utf-8", buffering=1, closefd=False)  # noqa: SIM115
        os.environ.update(CHILD_ENV)
        root = logging.getLogger()
        for handler in list(root.handlers):  # the parent's console and run.log: worker_main sets its own
            root.removeHandler(handler)
        from fleetrl.runs import worker_main

        code = worker_main.main(list(args))
    except KeyboardInterrupt:
        code = 130
    except SystemExit as stop:
        code = stop.code if isinstance(stop.code, int) else 1
    except BaseException:
        traceback.print_exc()
    finally:
        for stream in (sys.stdout, sys.stderr):
            with suppress(OSError, ValueError):
                stream.flush()
        os._exit(code)


class ProcessFleet:
    """Starts one child per worker (its :mod:`fleetrl.runs.worker_main` arguments) and streams their records;
    ``units``: worker id → the units it reports for (default: its own); stderr to ``log_dir``."""

    def __init__(
        self,
        commands: Mapping[int, Sequence[str]],
        log_dir: Path,
        units: Mapping[int, list[int]] | None = None,
    ) -> None:
        log_dir.mkdir(parents=True, exist_ok=True)
        self.events: queue.Queue[FleetEvent] = queue.Queue()
        self.children: dict[int, Child] = {}
        self.units = {worker: [worker] for worker in commands} if units is None else dict(units)
        self._threads: list[threading.Thread] = []
        fork = fork_available()
        for worker, args in commands.items():
            role = "worker" if self.units[worker] == [worker] else "host"
            log_path = log_dir / f"{role}-{worker}.log"
            child, stdout = self._fork(args, log_path) if fork else self._spawn(args, log_path)
            self.children[worker] = child
            log.debug("worker %d: process %d %s", worker, child.pid, "forked" if fork else "started")
            thread = threading.Thread(target=self._read, args=(worker, child, stdout), daemon=True)
            thread.start()
            self._threads.append(thread)

    @staticmethod
    def _spawn(args: Sequence[str], log_path: Path) -> tuple[Child, IO[str]]:
        env = dict(os.environ, **CHILD_ENV)
        with log_path.open("w") as stderr:
            child = subprocess.Popen(
                [sys.executable, "-m", WORKER_MODULE, *args],
                stdout=subprocess.PIPE,
                stderr=stderr,
                text=True,
                env=env,
                start_new_session=True,
            )
        assert child.stdout is not None
        return child, child.stdout

    @staticmethod
    def _fork(args: Sequence[str], log_path: Path) -> tuple[Child, IO[str]]:
        read_fd, write_fd = os.pipe()
        for stream in (sys.stdout, sys.stderr):  # nothing buffered here is printed twice
            stream.flush()
        pid = os.fork()
        if pid == 0:
            os.close(read_fd)
            _run_forked_worker(args, write_fd, log_path)
        os.close(write_fd)
        return ForkedChild(pid), open(read_fd, encoding="utf-8")  # closed by _read

    def _read(self, worker: int, child: Child, stdout: IO[str]) -> None:
        with stdout:
            for line in stdout:
                line = line.strip()
                if not line:
                    continue
                try:
                    self.events.put(MetricsRow.from_json(line))
                except (ValueError, TypeError) as err:
                    log.warning(
                        "worker %d printed a line that is not a round record (%s): %.200s", worker, err, line
                    )
        code = child.wait()
        for unit in self.units[worker]:
            self.events.put(WorkerExit(unit, code))

    def size(self) -> int:
        return sum(len(self.units[worker]) for worker in self.children)

    def interrupt(self, grace_seconds: float = 15.0) -> None:
        """Ask every child to stop (SIGINT: they save their model and exit), then kill what remains."""
        for child in self.children.values():
            if child.poll() is None:
                child.send_signal(signal.SIGINT)
        self.wait(grace_seconds)

    def wait(self, timeout: float) -> None:
        """Wait for the children up to ``timeout`` seconds in all, then kill the rest."""
        for child in self.children.values():
            try:
                child.wait(timeout=timeout)
            except subprocess.TimeoutExpired:
                log.warning("worker process %d did not stop; killing it", child.pid)
                child.kill()
                child.wait()
        for thread in self._threads:
            thread.join(timeout=5)
