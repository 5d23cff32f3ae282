"""The live terminal view: one row per worker with its round, score, WMA and state.

On a terminal it is a ``rich`` table redrawn in place; elsewhere (CI, a pipe) it prints one plain progress
line every few seconds, so logs stay readable. A disabled view (``--no-live``) does not import ``rich``.
"""

from __future__ import annotations

import math
import time
from types import TracebackType
from typing import TYPE_CHECKING

from fleetrl.runs.rundir import WorkerProgress

if TYPE_CHECKING:
    from rich.console import Console
    from rich.live import Live
    from rich.table import Table


def _fmt(value: float) -> str:
    return "-" if math.isnan(value) else f"{value:.1f}"


class LiveView:
    """Shows a run's progress; call :meth:`update` whenever something changed (it rate-limits itself).

    :param title: shown above the table
    :param threshold: the completion threshold, shown next to the WMA
    :param enabled: ``False`` silences the view entirely
    """

    def __init__(self, title: str, threshold: float, enabled: bool = True) -> None:
        self.title = title
        self.threshold = threshold
        self.enabled = enabled
        self.console: Console | None = None
        if enabled:
            from rich.console import Console

            self.console = Console(stderr=True)
            if not self.console.is_terminal:
                self.console.width = 200  # one progress line per update in logs, not wrapped at 80
        self._live: Live | None = None
        self._last_plain = 0.0
        self._plain_every = 5.0

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
        from rich.table import Table

        table = Table(title=f"{self.title}  ·  {elapsed:.0f} s", title_justify="left")
        for column in ("worker", "round", "score", f"WMA (→ {self.threshold:g})", "state", "last event"):
            table.add_column(column, justify="right" if column != "state" else "left")
        for worker, p in sorted(progress.items()):
            table.add_row(
                str(worker),
                str(p.round),
                _fmt(p.score),
                _fmt(p.wma),
                p.state,
                p.events[-1] if p.events else "",
            )
        return table

    def update(self, progress: dict[int, WorkerProgress], elapsed: float, force: bool = False) -> None:
        """Redraw (terminal) or print a progress line at most every few seconds (elsewhere)."""
        if self.console is None:
            return
        if self._live is not None:
            self._live.update(self.table(progress, elapsed))
            return
        now = time.monotonic()
        if force or now - self._last_plain >= self._plain_every:
            self._last_plain = now
            parts = [f"w{w} r{p.round} wma {_fmt(p.wma)} {p.state}" for w, p in sorted(progress.items())]
            self.console.print(f"[{elapsed:6.1f}s] " + " | ".join(parts), highlight=False)
