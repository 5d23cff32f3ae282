"""Running many ``fleetrl train`` runs (and SB3 peer runs), two at a time, each as its own process, with their
:class:`Progress`. A run is reused only if its record was made with the result settings the run has now."""

import json
import logging
import shlex
import shutil
import subprocess
import sys
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path
from typing import Any, TextIO

from fleetrl.portable import describe_host
from fleetrl.runs.setting_values import TABLE_FLAGS, build, flag
from fleetrl.runs.settings import RunSettings
from fleetrl_lab.peers import PeerRun
from fleetrl_lab.records import RunRecord, build_record, read_record, write_record

log = logging.getLogger(__name__)


def train_args(settings: Mapping[str, Any]) -> list[str]:
    """``fleetrl train`` arguments giving ``settings`` (RunSettings field → value; a table such as
    ``overrides`` → one ``--set KEY=VALUE`` per key)."""
    args: list[str] = []
    for name, value in settings.items():
        if name in TABLE_FLAGS:
            for key, item in value.items():
                text = item if isinstance(item, str) else json.dumps(item)
                args += [TABLE_FLAGS[name], f"{key}={text}"]
        elif isinstance(value, bool):
            raise ValueError(f"setting {name}: a switch cannot be an arm's setting")
        else:
            args += [flag(name), str(value)]
    return args


def result_settings(settings: Mapping[str, Any]) -> dict[str, Any]:
    """What :meth:`fleetrl.runs.settings.RunSettings.result_settings` gives for a run with ``settings``."""
    run = build(RunSettings, {}, {"out": ".", **settings}, resolve=False)
    return run.learning_resolved().result_settings()


@dataclass
class Run:
    """One training run of an experiment."""

    out: Path
    """its run directory"""
    settings: dict[str, Any]
    """its ``fleetrl train`` settings other than ``out`` (RunSettings field → value)"""
    record: Path
    """where its record goes"""
    labels: dict[str, str | int] = field(default_factory=dict)
    """what the experiment varies (e.g. arm, seed)"""
    unseen_units: int = 0
    """units of the generalisation row (0: none)"""

    @property
    def name(self) -> str:
        """How progress lines name it."""
        return f"{self.labels.get('arm', self.out.parent.name)} seed {self.settings.get('seed', '?')}"

    @property
    def log(self) -> Path:
        """Its process's output: beside its run directory."""
        return self.out.parent / f"{self.out.name}.log"

    def args(self) -> list[str]:
        """``fleetrl train`` arguments other than ``--out``."""
        return train_args(self.settings)

    def argv(self) -> list[str]:
        """The full command line."""
        return [
            sys.executable,
            "-m",
            "fleetrl.cli.main",
            "train",
            *self.args(),
            "--out",
            str(self.out),
            "--no-live",
        ]

    def command(self) -> str:
        """The command a person types to rerun it."""
        return shlex.join(["fleetrl", "train", *self.args(), "--out", str(self.out)])

    @cached_property
    def expected(self) -> dict[str, Any]:
        """The result settings this run has now."""
        return result_settings(self.settings)

    def result(self) -> RunRecord:
        """Its record (raises if the run is not done)."""
        record = read_record(self.record)
        if record is None:
            raise FileNotFoundError(f"no record at {self.record}: run the experiment")
        return record

    @property
    def done(self) -> bool:
        """Whether its record exists and was made with the settings the run has now."""
        record = read_record(self.record)
        return record is not None and record.result_settings == self.expected

    def reusable(self) -> bool:
        """Whether its run directory holds a finished, uninterrupted run with the same result settings."""
        try:
            summary = json.loads((self.out / "summary.json").read_text())
            config = json.loads((self.out / "config.json").read_text())
        except (OSError, ValueError):
            return False
        return summary.get("interrupted") is False and config.get("result_settings") == self.expected

    def finish(self) -> None:
        """Write its record from the finished run directory (and evaluate it on unseen units)."""
        record = build_record(self.out, self.command(), self.expected, describe_host(), self.unseen_units)
        write_record(self.record, record)


def duration(seconds: float) -> str:
    """``42 s``, ``12 min 05 s``, ``3 h 07 min``."""
    seconds = max(0, round(seconds))
    if seconds < 60:
        return f"{seconds} s"
    minutes, secs = divmod(seconds, 60)
    if minutes < 60:
        return f"{minutes} min {secs:02d} s"
    hours, minutes = divmod(minutes, 60)
    return f"{hours} h {minutes:02d} min"


class Progress:
    """A sweep's progress, shown on ``stream`` (a bar in a terminal, one line per finished run otherwise)."""

    def __init__(
        self,
        total: int,
        parallel: int = 2,
        stream: TextIO | None = None,
        clock: Callable[[], float] = time.monotonic,
        terminal: bool | None = None,
    ) -> None:
        self.total = total
        self.parallel = parallel
        self.stream = sys.stderr if stream is None else stream
        self.clock = clock
        self.terminal = self.stream.isatty() if terminal is None else terminal
        self.started_at = clock()
        self.done = 0
        self.reused = 0
        self.walls: list[float] = []
        self.running: dict[str, float] = {}
        """name of each active run → when it started"""
        self._shown = ""

    def reuse(self, count: int = 1) -> None:
        """``count`` runs already had their result (done at once, outside the estimate)."""
        self.done += count
        self.reused += count

    def start(self, name: str) -> None:
        """Run ``name`` started."""
        self.running[name] = self.clock()
        self.tick()

    def finish(self, name: str, failed: bool = False) -> None:
        """Run ``name`` ended (its wall time enters the estimate unless it failed)."""
        wall = self.clock() - self.running.pop(name, self.clock())
        self.done += 1
        if not failed:
            self.walls.append(wall)
        what = "FAILED" if failed else "finished"
        if self.terminal:
            self._clear()
        self.stream.write(f"{what} {name} in {duration(wall)}; {self.status()}\n")
        self.tick()
        self.stream.flush()

    def left(self) -> float | None:
        """Seconds until every run is done, from the mean wall time of runs finished here (None: none yet)."""
        if not self.walls:
            return None
        mean = sum(self.walls) / len(self.walls)
        now = self.clock()
        waiting = self.total - self.done - len(self.running)
        work = waiting * mean + sum(max(mean - (now - t), 0.0) for t in self.running.values())
        return work / max(min(self.parallel, waiting + len(self.running)), 1)

    def status(self) -> str:
        """``3/20 runs done (2 reused), running: A, B; elapsed 4 min 10 s, about 12 min left``."""
        left = self.left()
        words = f"{self.done}/{self.total} runs done" + (f" ({self.reused} reused)" if self.reused else "")
        if self.running:
            words += f", running: {', '.join(self.running)}"
        words += f"; elapsed {duration(self.clock() - self.started_at)}"
        if self.done < self.total:
            words += ", estimate after the first run" if left is None else f", about {duration(left)} left"
        return words

    def tick(self) -> None:
        """Redraw the terminal bar (if the text changed); nothing outside a terminal."""
        if not self.terminal:
            return
        width = shutil.get_terminal_size((100, 20)).columns
        filled = round(20 * self.done / max(self.total, 1))
        text = f"[{'#' * filled}{'.' * (20 - filled)}] {self.status()}"[: width - 1]
        if text != self._shown:
            self.stream.write("\r" + text.ljust(len(self._shown)))
            self.stream.flush()
            self._shown = text

    def close(self) -> None:
        """End the bar's line (a terminal), so what follows starts on its own line."""
        if self.terminal and self._shown:
            self.stream.write("\n")
            self.stream.flush()
            self._shown = ""

    def _clear(self) -> None:
        if self._shown:
            self.stream.write("\r" + " " * len(self._shown) + "\r")
            self._shown = ""


def run_all(
    runs: "Sequence[Run | PeerRun]",
    parallel: int = 2,
    stream: TextIO | None = None,
    clock: Callable[[], float] = time.monotonic,
) -> None:
    """Run every run not yet done, ``parallel`` at a time, showing progress on ``stream`` (stderr); raise if
    one fails (its log says why)."""
    progress = Progress(len(runs), parallel, stream, clock)
    pending: list[Run | PeerRun] = []
    for run in runs:
        if not run.done and run.reusable():
            run.finish()
        if run.done:
            progress.reuse()
        else:
            pending.append(run)
    active: list[tuple[Run | PeerRun, subprocess.Popen[bytes]]] = []
    failures: list[str] = []
    try:
        while pending or active:
            while pending and len(active) < parallel:
                run = pending.pop(0)
                run.out.parent.mkdir(parents=True, exist_ok=True)
                if run.out.is_dir():  # an interrupted run or one made with other settings: start afresh
                    shutil.rmtree(run.out)
                run.log.parent.mkdir(parents=True, exist_ok=True)
                with run.log.open("wb") as log_file:
                    child = subprocess.Popen(run.argv(), stdout=log_file, stderr=subprocess.STDOUT)
                log.debug("started %s", run.command())
                progress.start(run.name)
                active.append((run, child))
            time.sleep(0.2)
            still = []
            for run, child in active:
                code = child.poll()
                if code is None:
                    still.append((run, child))
                elif code != 0:
                    failures.append(f"{run.command()} exited {code} (see {run.log})")
                    progress.finish(run.name, failed=True)
                else:
                    run.finish()
                    progress.finish(run.name)
            active = still
            progress.tick()
    finally:
        progress.close()
    if failures:
        raise RuntimeError("runs failed:\n" + "\n".join(failures))
