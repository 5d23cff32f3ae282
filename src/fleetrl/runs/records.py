"""A run's metrics row (one worker's round: metrics.csv's columns) and :class:`WorkerProgress`, what a run
knows of each worker so far."""

import csv
import json
import math
from dataclasses import asdict, dataclass, field, fields
from pathlib import Path
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:  # reading metrics back (plots, experiments) needs no learner
    from fleetrl.agent.criterion import RoundResult

nan = math.nan


@dataclass(frozen=True)
class MetricsRow:
    """A worker's round: its score, the learning statistics (the figures of its ``RoundResult``), and what
    federation did (``event``: empty, ``gradient``, ``completed``, ``transfer_out``, ``transfer_in:<from>``).
    The fields are metrics.csv's columns, in order."""

    round: int
    worker: int
    score: float
    wma: float
    actor_loss: float = nan
    critic_loss: float = nan
    entropy: float = nan
    steps: int = 0
    wall_time: float = nan
    """seconds from the worker's start to the end of the round"""
    event: str = ""
    episodes: int = 1
    approx_kl: float = nan
    """the update's estimate of KL(π_θold ‖ π_θ) (NaN: no update)"""
    clip_fraction: float = nan
    """the update's share of clipped probability ratios (NaN: no update)"""

    @classmethod
    def of(
        cls, worker: int, round_: int, result: "RoundResult", wall_time: float, event: str
    ) -> "MetricsRow":
        """The row of the learner's ``result``, played by ``worker`` as round ``round_``."""
        figures: dict[str, Any] = {k: (int if k in COUNTS else float)(getattr(result, k)) for k in FIGURES}
        return cls(round=round_, worker=worker, wall_time=wall_time, event=event, **figures)

    def to_json(self) -> str:
        """One line of JSON (non-finite floats become null)."""
        values = asdict(self)
        for name, value in values.items():
            if isinstance(value, float) and not math.isfinite(value):
                values[name] = None
        return json.dumps(values)

    @classmethod
    def from_json(cls, line: str) -> "MetricsRow":
        """Parse a line written by :meth:`to_json`; raises ValueError on anything else."""
        data = json.loads(line)
        if not isinstance(data, dict):
            raise ValueError("a round record must be a JSON object")
        if set(data) != set(CSV_COLUMNS):
            raise ValueError(f"round record fields {sorted(data)} != {sorted(CSV_COLUMNS)}")
        values: dict[str, Any] = {k: (nan if v is None else v) for k, v in data.items()}
        return cls(**values)

    @classmethod
    def from_csv_row(cls, row: dict[str, str]) -> "MetricsRow":
        """Parse one row of metrics.csv (as ``csv.DictReader`` gives it); empty numbers become NaN."""
        values: dict[str, Any] = {}
        for f in fields(cls):
            if f.type is str:
                values[f.name] = row[f.name]
            elif f.name in COUNTS:
                values[f.name] = int(row[f.name])
            else:
                values[f.name] = float(row[f.name]) if row.get(f.name) else nan  # empty losses: NaN
        return cls(**values)

    def csv_row(self) -> list[object]:
        """Values in :data:`CSV_COLUMNS` order."""
        return [getattr(self, name) for name in CSV_COLUMNS]


CSV_COLUMNS = tuple(f.name for f in fields(MetricsRow))
"""metrics.csv's columns: :class:`MetricsRow`'s fields, in order"""
IDENTITY = frozenset({"round", "worker", "wall_time", "event"})
FIGURES = frozenset(CSV_COLUMNS) - IDENTITY
COUNTS = frozenset(f.name for f in fields(MetricsRow) if f.type is int)


def read_metrics(path: Path) -> list[MetricsRow]:
    with path.open(newline="") as f:
        return [MetricsRow.from_csv_row(row) for row in csv.DictReader(f)]


@dataclass
class WorkerProgress:
    """What the run knows of one worker so far (the live view and summary.json)."""

    round: int = 0
    score: float = math.nan
    wma: float = math.nan
    completed_at_round: int | None = None
    episodes: int = 0
    """episodes played so far (a round of the paper-code preset plays several)"""
    completed_at_episode: int | None = None
    state: str = "starting"
    events: list[str] = field(default_factory=list)
