"""Running many ``fleetrl train`` runs (and SB3 peer runs), two at a time, each as its own process. A run is
reused only if its record was made with the result settings the run would have now."""

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
from fleetrl_lab.progress import Progress
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
