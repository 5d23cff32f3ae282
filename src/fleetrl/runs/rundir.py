"""A run directory: config.json, metrics.csv, TensorBoard events, models/, summary.json and the plot, written
as the run goes (an interrupted run leaves a valid, partial directory); a summarised run (a large fleet) gets
the fleet's scalars and plot instead of one per unit."""

import csv
import json
import math
import os
import time
from pathlib import Path
from typing import TYPE_CHECKING, Any

from fleetrl.envs.catalog import get_env_spec
from fleetrl.runs.fleet_summary import QUANTILES, snapshot
from fleetrl.runs.records import CSV_COLUMNS, MetricsRow, WorkerProgress, read_metrics
from fleetrl.runs.rig_time import rig_time, run_units, waits_of

if TYPE_CHECKING:
    from torch.utils.tensorboard import SummaryWriter


PLAIN_EVENTS = frozenset({"", "gradient", "model", "step_gradient"})
"""``event`` values of rounds that only shared (not listed among a worker's events)"""


class RunDirectoryError(OSError):
    """The run directory could not be written mid-run (e.g. a full disk); the run was stopped cleanly."""


def model_path(out: Path, worker: int) -> Path:
    return out / "models" / f"worker-{worker}.safetensors"


def write_json_atomic(path: Path, data: Any) -> None:
    """Write JSON through a temporary file and a rename, so a reader never sees half a file."""
    tmp = path.with_suffix(path.suffix + ".tmp")
    tmp.write_text(json.dumps(data, indent=2, sort_keys=True) + "\n")
    os.replace(tmp, path)


class RunRecorder:
    """Receives round records from every worker and keeps the run directory ``out`` up to date (an existing
    metrics.csv is refused). ``resume_from``: continue the run in ``out``, worker id → the first round it will
    play again (its rows from there on are dropped); ``summarise``: the fleet's scalars, once per round."""

    def __init__(
        self,
        out: Path,
        config: dict[str, Any],
        workers: list[int],
        resume_from: dict[int, int] | None = None,
        *,
        summarise: bool = False,
    ) -> None:
        self.out = Path(out)
        self.summarise = summarise
        kept: list[MetricsRow] = []
        if resume_from is not None and (self.out / "metrics.csv").exists():
            kept = [
                r
                for r in read_metrics(self.out / "metrics.csv")
                if r.round < resume_from.get(r.worker, r.round + 1)
            ]
        elif (self.out / "metrics.csv").exists():
            raise FileExistsError(f"{self.out} already holds a run (metrics.csv); choose another --out")
        (self.out / "models").mkdir(parents=True, exist_ok=True)
        self.config = config
        self.started = time.monotonic()
        self.progress = {w: WorkerProgress() for w in workers}
        self.records: list[MetricsRow] = []
        self.interrupted = False
        self.finished = False
        self.extra: dict[str, Any] = {}
        """more entries for summary.json"""
        write_json_atomic(self.out / "config.json", config)
        metrics = self.out / "metrics.csv"
        partial = metrics.with_name(".metrics.csv.partial")  # the kept rows replace the file in one rename
        with partial.open("w", newline="") as handle:
            csv.writer(handle).writerows([CSV_COLUMNS, *(r.csv_row() for r in kept)])
        os.replace(partial, metrics)
        for record in kept:  # a resumed run's earlier rounds (TensorBoard has them already)
            self.records.append(record)
            self._progress(record)
        self._csv_file = metrics.open("a", newline="")
        self._csv = csv.writer(self._csv_file)
        self._tb: SummaryWriter | None = None
        self._fleet_round = max((r.round for r in kept), default=0)  # its fleet scalars: when the next begins

    def _board(self) -> "SummaryWriter":
        """The TensorBoard writer, made on the first round (its imports stay out of the start-up)."""
        if self._tb is None:
            from torch.utils.tensorboard import SummaryWriter

            self._tb = SummaryWriter(log_dir=str(self.out / "tensorboard"))
        return self._tb

    def elapsed(self) -> float:
        return time.monotonic() - self.started

    def add(self, record: MetricsRow) -> None:
        """Append one record to metrics.csv and TensorBoard and update the worker's progress."""
        self.records.append(record)
        self._csv.writerow(record.csv_row())
        self._csv_file.flush()
        if self.summarise and record.round > self._fleet_round:  # the round before has begun to end
            self._board_fleet()
            self._fleet_round = record.round
        self._progress(record)
        if self.summarise:  # the fleet's scalars only
            return
        tag = f"worker_{record.worker}"
        board = self._board()
        if math.isfinite(record.score):
            board.add_scalar(f"rollout/score/{tag}", record.score, record.round)
            board.add_scalar(f"rollout/wma/{tag}", record.wma, record.round)
        for name in ("actor_loss", "critic_loss", "entropy", "approx_kl", "clip_fraction"):
            value = getattr(record, name)
            if math.isfinite(value):
                board.add_scalar(f"train/{name}/{tag}", value, record.round)

    def _board_fleet(self) -> None:
        if self._fleet_round < 1:
            return
        fleet = snapshot(self.progress)
        board = self._board()
        board.add_scalar("fleet/completed", fleet.completed, self._fleet_round)
        for q, value in zip(QUANTILES, fleet.wma, strict=True):
            name = "wma_median" if q == 50 else f"wma_p{q:g}"
            if math.isfinite(value):
                board.add_scalar(f"fleet/{name}", value, self._fleet_round)

    def _progress(self, record: MetricsRow) -> None:
        progress = self.progress.setdefault(record.worker, WorkerProgress())
        progress.round = record.round
        if math.isfinite(record.score):  # an interrupted round's row has no figures: the last ones stay
            progress.score, progress.wma = record.score, record.wma
        progress.episodes += record.episodes
        progress.state = "learning" if progress.completed_at_round is None else "completed"
        if record.event not in PLAIN_EVENTS:  # plain sharing rounds are in metrics.csv alone
            progress.events.append(f"{record.round}:{record.event}")
            if "completed" in record.event.split("+") and progress.completed_at_round is None:
                progress.completed_at_round = record.round
                progress.completed_at_episode = progress.episodes
                progress.state = "completed"

    def set_state(self, worker: int, state: str) -> None:
        """Mark a worker's state for the live view."""
        self.progress.setdefault(worker, WorkerProgress()).state = state

    def summary(self) -> dict[str, Any]:
        """The run's outcome in the shape of summary.json."""
        rounds = max((r.round for r in self.records), default=0)
        return {
            "mode": self.config.get("mode"),
            "env": self.config.get("env"),
            "preset": self.config.get("preset"),
            "seed": self.config.get("seed"),
            "criterion": self.criterion(),
            "rounds": rounds,
            "wall_seconds": round(self.elapsed(), 3),
            "interrupted": self.interrupted,
            "workers": {
                str(w): {
                    "completed_at_round": p.completed_at_round,
                    "completed_at_episode": p.completed_at_episode,
                    "episodes": p.episodes,
                    "final_wma": None if math.isnan(p.wma) else p.wma,
                    "state": p.state,
                    "events": p.events,
                }
                for w, p in sorted(self.progress.items())
            },
            "rig_seconds": self.rig_seconds(),
            **self.extra,
        }

    def criterion(self) -> dict[str, Any]:
        """What a unit's completion proves in this run: the criterion's kind and its target WMA."""
        ppo = self.config.get("ppo") or {}
        return {"kind": ppo.get("criterion", "sampled"), "target": self.config.get("completion_threshold")}

    def rig_seconds(self) -> dict[str, Any] | None:
        """The time the rounds played so far would take on real-time rigs (:mod:`fleetrl.runs.rig_time`);
        None before any round, or for a unit type whose control period is not known."""
        if not self.records:
            return None
        try:
            period = get_env_spec(str(self.config.get("env"))).control_period
        except ValueError:
            return None
        if period is None:
            return None
        steps: dict[str, dict[int, int]] = {}
        episodes: dict[str, dict[int, int]] = {}
        for record in sorted(self.records, key=lambda r: (r.worker, r.round)):
            steps.setdefault(str(record.worker), {})[record.round] = record.steps
            episodes.setdefault(str(record.worker), {})[record.round] = record.episodes
        completed = {w: self.progress[int(w)].completed_at_round for w in steps}
        waits = waits_of(self.config.get("mode"), self.config.get("scheme"), self.config.get("quorum"))
        units = run_units(steps, completed, self.config, episodes=episodes)
        return {"period": period, "rule": waits.rule, **rig_time(units, period, waits).to_dict()}

    def finish(self) -> dict[str, Any]:
        """Close the files, write summary.json and the plot; returns the summary."""
        self.finished = True
        self._csv_file.close()
        if self.summarise:
            self._board_fleet()
        self._board().close()  # a run without a round has its (empty) events file too
        summary = self.summary()
        write_json_atomic(self.out / "summary.json", summary)
        from fleetrl.runs.plots import plot_run  # matplotlib loads only when a run ends

        config = self.config
        title = (
            f"{config.get('env')} · {config.get('mode')} · preset {config.get('preset')} · "
            f"seed {config.get('seed')} · {config.get('units')} units"
        )
        if self.summarise:  # the fleet's panel, against rounds
            target = self.config.get("completion_threshold")
            plot_run(self.records, self.out / "scores.png", title=title, summarise=True, target=target)
            return summary
        plot_run(self.records, self.out / "scores.png", title=title)
        if any(r.episodes > 1 for r in self.records):  # rounds of several episodes: both x-axes
            plot_run(self.records, self.out / "scores-by-episode.png", title=title, x_axis="episodes")
        return summary
