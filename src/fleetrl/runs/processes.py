"""Worker processes that report their rounds as JSON lines on stdout.

Each child prints one :class:`RoundRecord` per line on stdout and logs to stderr (kept in
``<run>/logs/worker-K.log``). The parent reads every child's stdout on a thread and hands the parsed records
to one queue, so the main thread owns the run directory and the live view. Nothing crosses the process
boundary but text.
"""

import logging
import os
import queue
import signal
import subprocess
import threading
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import IO

from fleetrl.runs.records import RoundRecord

log = logging.getLogger(__name__)


@dataclass
class WorkerExit:
    """A worker (process or thread) ended; ``returncode`` 0 is a clean end."""

    worker: int
    returncode: int


FleetEvent = RoundRecord | WorkerExit


class ProcessFleet:
    """Starts one child per worker and streams their records.

    :param commands: worker id → argv of its process
    :param log_dir: where each child's stderr goes
    """

    def __init__(self, commands: Mapping[int, Sequence[str]], log_dir: Path) -> None:
        log_dir.mkdir(parents=True, exist_ok=True)
        self.events: queue.Queue[FleetEvent] = queue.Queue()
        self.children: dict[int, subprocess.Popen[str]] = {}
        self._threads: list[threading.Thread] = []
        env = dict(os.environ, PYTHONUNBUFFERED="1", OMP_NUM_THREADS="1", MKL_NUM_THREADS="1")
        for worker, argv in commands.items():
            stderr = (log_dir / f"worker-{worker}.log").open("w")
            child = subprocess.Popen(
                list(argv), stdout=subprocess.PIPE, stderr=stderr, text=True, env=env, start_new_session=True
            )
            stderr.close()
            self.children[worker] = child
            assert child.stdout is not None
            thread = threading.Thread(target=self._read, args=(worker, child, child.stdout), daemon=True)
            thread.start()
            self._threads.append(thread)

    def _read(self, worker: int, child: "subprocess.Popen[str]", stdout: IO[str]) -> None:
        for line in stdout:
            line = line.strip()
            if not line:
                continue
            try:
                self.events.put(RoundRecord.from_json(line))
            except (ValueError, TypeError) as err:
                log.warning(
                    "worker %d printed a line that is not a round record (%s): %.200s", worker, err, line
                )
        self.events.put(WorkerExit(worker, child.wait()))

    def size(self) -> int:
        """How many children were started."""
        return len(self.children)

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
