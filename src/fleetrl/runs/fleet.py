"""Following a fleet of workers (processes or threads) into a run directory and the live view."""

import logging
import queue
import threading
from collections.abc import Callable
from typing import Protocol

from fleetrl.runs.live import LiveView
from fleetrl.runs.processes import FleetEvent, WorkerExit
from fleetrl.runs.records import MetricsRow
from fleetrl.runs.rundir import RunDirectoryError, RunRecorder

log = logging.getLogger(__name__)


class Fleet(Protocol):
    """Workers that report through one event queue."""

    events: "queue.Queue[FleetEvent]"

    def size(self) -> int:
        """How many workers were started."""
        ...

    def interrupt(self) -> None:
        """Stop every worker (each saves its model), as soon as possible."""
        ...


class ThreadFleet:
    """Workers as threads of this process: worker id → a body reporting each round through its argument;
    ``units``: worker id → the units it reports for (default: its own)."""

    def __init__(
        self,
        bodies: dict[int, Callable[[Callable[[MetricsRow], None]], None]],
        units: dict[int, list[int]] | None = None,
    ) -> None:
        self.events: queue.Queue[FleetEvent] = queue.Queue()
        self.units = {worker: [worker] for worker in bodies} if units is None else units
        self.threads = {
            worker: threading.Thread(
                target=self._run, args=(worker, body), name=f"worker-{worker}", daemon=True
            )
            for worker, body in bodies.items()
        }
        for thread in self.threads.values():
            thread.start()

    def _run(self, worker: int, body: Callable[[Callable[[MetricsRow], None]], None]) -> None:
        code = 0
        try:
            body(self.events.put)
        except Exception:
            log.exception("worker %d failed", worker)
            code = 1
        for unit in self.units[worker]:
            self.events.put(WorkerExit(unit, code))

    def size(self) -> int:
        return sum(len(units) for units in self.units.values())

    def interrupt(self) -> None:
        """Threads cannot be stopped from outside; they are daemons and end with the process."""


def follow(fleet: Fleet, recorder: RunRecorder, view: LiveView) -> None:
    """Record every round until every worker has ended; on Ctrl-C stop them and keep what they reported."""
    ended: set[int] = set()
    try:
        while len(ended) < fleet.size():
            try:
                event = fleet.events.get(timeout=0.25)
            except queue.Empty:
                view.update(recorder.progress, recorder.elapsed(), ended=ended)
                continue
            apply_event(event, recorder, ended)
            view.update(recorder.progress, recorder.elapsed(), ended=ended)
    except KeyboardInterrupt:
        recorder.interrupted = True
        log.warning("interrupted: stopping the workers; the run directory stays valid")
        fleet.interrupt()
        while True:
            try:
                apply_event(fleet.events.get_nowait(), recorder, ended)
            except queue.Empty:
                break
    except OSError as err:  # the disk filled up (or went away): stop the run, keep what is on disk
        fleet.interrupt()
        raise RunDirectoryError(
            f"cannot write the run directory {recorder.out}: {err.strerror or err}; the run was stopped "
            f"and the rounds recorded so far are in {recorder.out / 'metrics.csv'}"
        ) from err
    view.update(recorder.progress, recorder.elapsed(), force=True, ended=ended)


def apply_event(event: FleetEvent, recorder: RunRecorder, ended: set[int]) -> None:
    """Write one event from the fleet into the run directory."""
    if isinstance(event, MetricsRow):
        recorder.add(event)
        return
    ended.add(event.worker)
    progress = recorder.progress[event.worker]
    if event.returncode not in (0, 130):
        recorder.set_state(event.worker, f"failed (exit {event.returncode}, see logs/)")
    elif progress.state not in ("completed",):
        recorder.set_state(event.worker, "stopped")
