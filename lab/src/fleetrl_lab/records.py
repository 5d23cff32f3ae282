"""A run's record: the small JSON file a sweep keeps of each finished run, from which every number of a report
is computed (committed in ``lab/records``). ``<records>/<arm key>/seed-<n>.json``::

    {
     "format": 2,
     "command": "fleetrl train --env qube ... --seed 100 --out runs/experiments/runs/.../seed-100",
     "result_settings": {"env": "qube", "fleet_profile": "table2", "fleet_seed": 0, ...},
     "host": "AMD EPYC ...; torch 2.5.1 (AVX2 kernels); mode default",
     "wall_seconds": 412.3,
     "max_rounds": 1000,
     "workers": {"0": {"completed_at_round": 91, "score": [9,14,...], "wma": [9.0,11.8,...],
                       "steps": [10,15,...], "events": {"91": "completed"}}, ...},
     "generalisation": {"units": [10,...,19], "cap": 2500, "scores": {"0": [2500,1830,...]}}
    }
"""

import hashlib
import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from fleetrl.agent.checkpoint import read_checkpoint
from fleetrl.envs.catalog import describe_env, get_env_spec
from fleetrl.runs.evaluate import evaluate_model
from fleetrl.runs.records import MetricsRow, read_metrics
from fleetrl.runs.rig_time import RigTime, rig_time, run_units, waits_of
from fleetrl.runs.rundir import PLAIN_EVENTS, model_path
from fleetrl_lab.stats import Completion

FORMAT = 2
"""the records' schema (:mod:`fleetrl_lab.migrate` brought format 1 to it)"""
FIRST_UNSEEN_UNIT = 10
"""the generalisation row's first unit (or the fleet's first untrained unit, if later)"""


@dataclass(frozen=True)
class RunRecord:
    """A record read back: what one run measured."""

    data: dict[str, Any]

    @property
    def result_settings(self) -> dict[str, Any]:
        settings: dict[str, Any] = self.data["result_settings"]
        return settings

    @property
    def wall_seconds(self) -> float:
        return float(self.data["wall_seconds"])

    @property
    def host(self) -> str:
        return str(self.data.get("host", "?"))

    def completion(self) -> Completion:
        """Rounds to completion, per worker and for the fleet."""
        workers = self.data["workers"]
        per_worker = {k: workers[k]["completed_at_round"] for k in sorted(workers, key=int)}
        return Completion(per_worker, int(self.data["max_rounds"]))

    def episodes_to_completion(self) -> dict[int, tuple[int, bool]] | None:
        """Per worker, the episodes it played until its criterion held (or in all) and whether it held;
        None if every round was one episode."""
        workers = self.data["workers"]
        if not any("episodes" in w for w in workers.values()):
            return None
        result = {}
        for key, worker in workers.items():
            played = worker.get("episodes") or [1] * len(worker["score"])
            done = worker["completed_at_round"]
            result[int(key)] = (sum(played if done is None else played[:done]), done is not None)
        return result

    def rig_time(self) -> RigTime | None:
        """The time the run would take on real-time rigs (:mod:`fleetrl.runs.rig_time`); None for a unit type
        without a known control period, or a record that kept no steps."""
        settings = self.result_settings
        try:
            period = get_env_spec(str(settings["env"])).control_period
        except ValueError:
            return None
        workers = self.data["workers"]
        if period is None or any("steps" not in w for w in workers.values()):
            return None
        steps: dict[str, Any] = {k: w["steps"] for k, w in workers.items()}
        episodes: dict[str, Any] = {k: w.get("episodes") or [1] * len(steps[k]) for k, w in workers.items()}
        for k, w in workers.items():  # a unit that missed rounds keeps their numbers
            if "rounds" in w:
                steps[k] = dict(zip(w["rounds"], steps[k], strict=True))
                episodes[k] = dict(zip(w["rounds"], episodes[k], strict=True))
        completed = {k: w["completed_at_round"] for k, w in workers.items()}
        units = run_units(steps, completed, settings, episodes=episodes)
        return rig_time(
            units, period, waits_of(settings.get("mode"), settings.get("scheme"), settings.get("quorum"))
        )

    def scores(self) -> dict[int, list[float]]:
        """Each worker's score per round."""
        return {int(k): list(v["score"]) for k, v in sorted(self.data["workers"].items())}

    def round_records(self) -> list[MetricsRow]:
        """The per-round rows the record keeps (score, WMA, events; no losses), for the per-worker plots."""
        rows = []
        for key, worker in self.data["workers"].items():
            events = worker.get("events", {})
            for i, (score, wma) in enumerate(zip(worker["score"], worker["wma"], strict=True)):
                event = events.get(str(i + 1), "")
                rows.append(MetricsRow(i + 1, int(key), _number(score), _number(wma), steps=0, event=event))
        return rows

    def unseen_scores(self) -> list[float]:
        """Every greedy episode of the final policies on units no worker trained on."""
        scores = (self.data.get("generalisation") or {}).get("scores", {})
        return [float(s) for per_worker in scores.values() for s in per_worker]

    @property
    def episode_cap(self) -> int:
        """The episode cap of the unseen units' evaluation."""
        return int((self.data.get("generalisation") or {}).get("cap", 0))


def _number(value: float | None) -> float:
    return math.nan if value is None else float(value)


def record_path(records: Path, arm_key: str, seed: int) -> Path:
    return records / arm_key / f"seed-{seed}.json"


def read_record(path: Path) -> RunRecord | None:
    """The record at ``path``; None if there is none or it is not a record of this format."""
    try:
        data = json.loads(path.read_text())
    except (OSError, ValueError):
        return None
    if not isinstance(data, dict) or data.get("format") != FORMAT or "result_settings" not in data:
        return None
    return RunRecord(data)


def _compact(value: float) -> float | int | None:
    """A score or WMA for the record: 2 decimals, integers without a point, NaN as null."""
    if not math.isfinite(value):
        return None
    rounded = round(value, 2)
    return int(rounded) if rounded == int(rounded) else rounded


def read_worker_rows(run_dir: Path) -> dict[str, dict[str, Any]]:
    """Per worker, from metrics.csv: score, WMA, steps, events other than plain sharing, and where they are
    not implied the episodes of each round and the rounds it played."""
    workers: dict[str, dict[str, Any]] = {}
    for row in sorted(read_metrics(run_dir / "metrics.csv"), key=lambda r: (r.worker, r.round)):
        worker = workers.setdefault(str(row.worker), {"score": [], "wma": [], "events": {}, "steps": []})
        worker.setdefault("rounds", []).append(row.round)
        worker["score"].append(_compact(row.score))
        worker["steps"].append(row.steps)
        worker["wma"].append(_compact(row.wma))
        if row.event not in PLAIN_EVENTS:  # rounds that only shared are not kept
            worker["events"][str(row.round)] = row.event
        worker.setdefault("episodes", []).append(row.episodes)
    for worker in workers.values():
        if all(n == 1 for n in worker["episodes"]):  # one episode per round: nothing worth keeping
            del worker["episodes"]
        if worker["rounds"] == list(range(1, len(worker["rounds"]) + 1)):  # rounds 1 … n: implied
            del worker["rounds"]
    return workers


def unseen_units(trained: int, count: int) -> list[int]:
    """The units of the generalisation row: ``count`` units of the fleet no worker trained on."""
    first = max(FIRST_UNSEEN_UNIT, trained)
    return list(range(first, first + count))


def weights_digest(model: Path) -> str:
    """A digest of what a model file's greedy policy depends on (weights and metadata but its seed)."""
    tensors, metadata = read_checkpoint(model)
    policy = {k: v for k, v in metadata.items() if k != "seed"}
    digest = hashlib.sha256(json.dumps(policy, sort_keys=True).encode())
    for name in sorted(tensors):
        digest.update(name.encode())
        digest.update(tensors[name].tobytes())
    return digest.hexdigest()


def evaluate_unseen(run_dir: Path, settings: dict[str, Any], count: int) -> dict[str, Any]:
    """Each worker's final policy, greedily, one episode on each of ``count`` unseen units of its fleet."""
    units = unseen_units(int(settings["units"]), count)
    scores = {}
    by_content: dict[str, list[float | int | None]] = {}
    for worker in range(int(settings["units"])):
        model = model_path(run_dir, worker)
        if model.is_file():
            digest = weights_digest(model)
            if digest not in by_content:
                env, fleet_seed, profile = settings["env"], settings["fleet_seed"], settings["fleet_profile"]
                by_content[digest] = [
                    _compact(evaluate_model(model, env, unit, fleet_seed, 1, 0, profile)[0]) for unit in units
                ]
            scores[str(worker)] = list(by_content[digest])
    return {"units": units, "cap": describe_env(settings["env"]).episode_cap, "scores": scores}


def build_record(
    run_dir: Path, command: str, result_settings: dict[str, Any], host: str, unseen: int
) -> dict[str, Any]:
    """The record of the finished run in ``run_dir`` (``unseen``: units of the generalisation row)."""
    summary = json.loads((run_dir / "summary.json").read_text())
    workers = read_worker_rows(run_dir)
    for key, info in summary["workers"].items():
        workers.setdefault(key, {"score": [], "wma": [], "events": {}})["completed_at_round"] = info[
            "completed_at_round"
        ]
    return {
        "format": FORMAT,
        "command": command,
        "result_settings": result_settings,
        "host": host,
        "wall_seconds": round(float(summary["wall_seconds"]), 1),
        "max_rounds": int(result_settings["max_rounds"]),
        "workers": {k: workers[k] for k in sorted(workers, key=int)},
        "generalisation": evaluate_unseen(run_dir, result_settings, unseen) if unseen else None,
    }


def write_record(path: Path, record: dict[str, Any]) -> None:
    """Write ``record`` atomically: one line per top-level key and per worker, lists on one line."""
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(".tmp")
    tmp.write_text(_dumps(record) + "\n")
    tmp.replace(path)


def _dumps(value: Any, depth: int = 0) -> str:
    """JSON with dicts indented down to workers and lists kept on one line (short, diff-friendly)."""
    if not isinstance(value, dict) or not value or depth >= 2:
        return json.dumps(value, separators=(",", ":"), ensure_ascii=False)
    pad = " " * (depth + 1)
    items = [f"{pad}{json.dumps(k)}: {_dumps(v, depth + 1)}" for k, v in value.items()]
    return "{\n" + ",\n".join(items) + "\n" + " " * depth + "}"
