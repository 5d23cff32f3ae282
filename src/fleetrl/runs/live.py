"""The live terminal view: one row per worker, or for a large fleet its summary
(:mod:`fleetrl.runs.fleet_summary`); a ``rich`` table redrawn in place on a terminal, elsewhere a plain
progress line every few seconds."""

from __future__ import annotations

import math
import time
from collections.abc import Collection, Sequence
from types import TracebackType
from typing import TYPE_CHECKING

from fleetrl.runs.fleet_summary import FleetSnapshot, snapshot
from fleetrl.runs.records import WorkerProgress

if TYPE_CHECKING:
    from rich.console import Console, Group
    from rich.live import Live
    from rich.table import Table


def _fmt(value: float) -> str:
    return "-" if math.isnan(value) else f"{value:.1f}"


def _progress_table(title: str, who: str, wma: str, rows: Sequence[tuple[int, WorkerProgress]]) -> Table:
    """A table of one row per worker (or unit): its round, score, WMA, state and last event."""
    from rich.table import Table

    table = Table(title=title, title_justify="left")
    for column in (who, "round", "score", wma, "state", "last event"):
        table.add_column(column, justify="right" if column != "state" else "left")
    for worker, p in rows:
        last = p.events[-1] if p.events else ""
        table.add_row(str(worker), str(p.round), _fmt(p.score), _fmt(p.wma), p.state, last)
    return table


class LiveView:
    """Shows a run's progress; call :meth:`update` whenever something changed (it rate-limits itself).
    ``summarise``: the fleet's summary, ``members`` the units each member carries (default: one each)."""

    def __init__(
        self,
        title: str,
        threshold: float,
        enabled: bool = True,
        *,
        summarise: bool = False,
        members: Sequence[Sequence[int]] | None = None,
    ) -> None:
        self.title = title
        self.threshold = threshold
        self.enabled = enabled
        self.summarise = summarise
        self.members = members
        self.console: Console | None = None
        if enabled:
            from rich.console import Console

            self.console = Console(stderr=True)
            if not self.console.is_terminal:
                self.console.width = 200  # one progress line per update in logs, not wrapped at 80
        self._live: Live | None = None
        self._last_plain = 0.0
        self._plain_every = 5.0
        self._fleet_every = 0.25  # a summary redrawn on a terminal: its quantiles at most this often

    def __enter__(self) -> LiveView:
        if self.console is not None and self.console.is_terminal:
            from rich.live import Live

            self._live = Live(console=self.console, refresh_per_second=4, transient=False)
            self._live.__enter__()
        return self

    def __exit__(
        self, exc_type: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None
    ) -> None:
        if self._live is not None:
            self._live.__exit__(exc_type, exc, tb)
            self._live = None

    def table(self, progress: dict[int, WorkerProgress], elapsed: float) -> Table:
        """The table as it stands."""
        title = f"{self.title}  ·  {elapsed:.0f} s"
        return _progress_table(title, "worker", f"WMA (→ {self.threshold:g})", sorted(progress.items()))

    def fleet_tables(self, fleet: FleetSnapshot, elapsed: float) -> Group:
        """The summary as it stands: one table of the fleet's figures, one of its slowest units."""
        from rich.console import Group
        from rich.table import Table

        figures = Table(title=f"{self.title}  ·  {elapsed:.0f} s", title_justify="left")
        for column in ("units completed", f"WMA p10 / median / p90 (→ {self.threshold:g})", "members online"):
            figures.add_column(column, justify="right")
        figures.add_row(
            f"{fleet.completed} of {fleet.units}",
            " / ".join(_fmt(q) for q in fleet.wma),
            f"{fleet.members_online} of {fleet.members}",
        )
        slowest = _progress_table("slowest units (not completed, lowest WMA)", "unit", "WMA", fleet.slowest)
        return Group(figures, slowest)

    def fleet_line(self, fleet: FleetSnapshot) -> str:
        p10, median, p90 = (_fmt(q) for q in fleet.wma)
        slow = ", ".join(f"u{u} r{p.round} wma {_fmt(p.wma)}" for u, p in fleet.slowest) or "none"
        return (
            f"completed {fleet.completed}/{fleet.units} | WMA p10 {p10} median {median} p90 {p90} "
            f"(→ {self.threshold:g}) | slowest: {slow} | "
            f"members online {fleet.members_online}/{fleet.members}"
        )

    def update(
        self,
        progress: dict[int, WorkerProgress],
        elapsed: float,
        force: bool = False,
        ended: Collection[int] = (),
    ) -> None:
        """Redraw (terminal) or print a progress line at most every few seconds (elsewhere); ``ended``: the
        units whose worker has ended."""
        if self.console is None:
            return
        now = time.monotonic()
        every = self._plain_every if self._live is None else self._fleet_every if self.summarise else 0.0
        if not (force or now - self._last_plain >= every):
            return
        self._last_plain = now
        fleet = snapshot(progress, ended, self.members) if self.summarise else None
        if self._live is not None:
            shown = self.table(progress, elapsed) if fleet is None else self.fleet_tables(fleet, elapsed)
            self._live.update(shown)
            return
        if fleet is not None:
            line = self.fleet_line(fleet)
        else:
            units = sorted(progress.items())
            line = " | ".join(f"w{w} r{p.round} wma {_fmt(p.wma)} {p.state}" for w, p in units)
        self.console.print(f"[{elapsed:6.1f}s] {line}", highlight=False)
