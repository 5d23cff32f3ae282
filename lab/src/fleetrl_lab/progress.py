"""Where a sweep is: runs done of the total, what runs now, elapsed time and an estimate of what is left.

In a terminal one line is rewritten in place (``\\r``); otherwise (a log file, CI) one line per finished run
says the same. The estimate comes from the wall times of runs finished in this sweep: reused runs count as
done at once and do not enter it.
"""

import shutil
import sys
import time
from collections.abc import Callable
from typing import TextIO


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
        line = f"{what} {name} in {duration(wall)}; {self.status()}"
        if self.terminal:
            self._clear()
            self.stream.write(line + "\n")
            self.tick()
        else:
            self.stream.write(line + "\n")
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
