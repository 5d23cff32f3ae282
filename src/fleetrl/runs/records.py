"""One row of a run's metrics: what one worker did in one round."""

import csv
import json
import math
from dataclasses import asdict, dataclass, fields
from pathlib import Path
from typing import Any

CSV_COLUMNS = (
    "round",
    "worker",
    "score",
    "wma",
    "actor_loss",
    "critic_loss",
    "entropy",
    "steps",
    "wall_time",
    "event",
    "episodes",
    "approx_kl",
    "clip_fraction",
)
"""metrics.csv's columns (later ones were added at the end, so older files keep their columns' positions)"""


@dataclass
class RoundRecord:
    """A worker's round: the episode's score, the learning statistics, and what federation did.

    ``event`` is empty for a plain round, ``gradient`` for a gradient-sharing round, ``completed`` when the
    worker's criterion holds, ``transfer_out`` / ``transfer_in:<from>`` for model transfers. A round is one
    episode, or with the ``paper-code`` preset the episodes that fill the memory: ``score`` is then their
    mean return, ``steps`` their total and ``episodes`` their number.
    """

    round: int
    worker: int
    score: float
    wma: float
    actor_loss: float
    critic_loss: float
    entropy: float
    steps: int
    wall_time: float
    event: str = ""
    episodes: int = 1
    approx_kl: float = math.nan
    """the update's estimate of KL(π_θold ‖ π_θ) (NaN: no update, or a row written before the column)"""
    clip_fraction: float = math.nan
    """the update's share of clipped probability ratios (NaN: no update, or an older row)"""

    def to_json(self) -> str:
        """One line of JSON (non-finite floats become null)."""
        return json.dumps({k: _finite_or_none(v) for k, v in asdict(self).items()})

    @classmethod
    def from_json(cls, line: str) -> "RoundRecord":
        """Parse a line written by :meth:`to_json`; raises ValueError on anything else."""
        data = json.loads(line)
        if not isinstance(data, dict):
            raise ValueError("a round record must be a JSON object")
        names = {f.name for f in fields(cls)}
        data.setdefault("episodes", 1)  # written before rounds of several episodes
        data.setdefault("approx_kl", None)  # written before the update's diagnostics were kept
        data.setdefault("clip_fraction", None)
        if set(data) != names:
            raise ValueError(f"round record fields {sorted(data)} != {sorted(names)}")
        values: dict[str, Any] = {k: (math.nan if v is None else v) for k, v in data.items()}
        return cls(**values)

    @classmethod
    def from_csv_row(cls, row: dict[str, str]) -> "RoundRecord":
        """Parse one row of metrics.csv (as ``csv.DictReader`` gives it); empty losses become NaN."""

        def number(name: str) -> float:
            return float(row[name]) if row.get(name) else math.nan  # a column older files lack: NaN

        return cls(
            round=int(row["round"]),
            worker=int(row["worker"]),
            score=number("score"),
            wma=number("wma"),
            actor_loss=number("actor_loss"),
            critic_loss=number("critic_loss"),
            entropy=number("entropy"),
            steps=int(row["steps"]),
            wall_time=number("wall_time"),
            event=row["event"],
            episodes=int(row.get("episodes") or 1),  # older files have no such column
            approx_kl=number("approx_kl"),
            clip_fraction=number("clip_fraction"),
        )

    def csv_row(self) -> list[object]:
        """Values in :data:`CSV_COLUMNS` order."""
        return [getattr(self, name) for name in CSV_COLUMNS]


def _finite_or_none(value: object) -> object:
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


def read_metrics(path: Path) -> list[RoundRecord]:
    """Every record of a run's metrics.csv."""
    with path.open(newline="") as f:
        return [RoundRecord.from_csv_row(row) for row in csv.DictReader(f)]
