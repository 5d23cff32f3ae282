"""A simulated unit stepped in real time, as on the rig: a step returns no sooner than one control period
after the previous one returned, its computation hidden within the period; a reset no sooner than what it
took on the rig (the env's reset info ``reset_seconds``: a QUBE's swing-up, a hand reset's person) after it
began, both times the same scale. The deadlines are kept (a sleep's overshoot does not add up).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any, SupportsFloat

import gymnasium


class PacedEnv(gymnasium.Wrapper[Any, Any, Any, Any]):
    """``env`` whose steps each last ``period`` seconds of wall time (at least), and its resets their time on
    the rig × ``reset_scale``.

    :param env: the unit's env (simulated in-process or through a link; nothing of it changes)
    :param period: seconds a step lasts (the device's control period, optionally scaled); > 0
    :param reset_scale: a reset lasts its ``reset_seconds`` (reset info; none: 0) × this; ≥ 0 (0: as it comes)
    :param clock: the time source (seconds; monotonic)
    :param sleep: how to wait (seconds)
    """

    def __init__(
        self,
        env: gymnasium.Env[Any, Any],
        period: float,
        *,
        reset_scale: float = 0.0,
        clock: Callable[[], float] = time.monotonic,
        sleep: Callable[[float], None] = time.sleep,
    ) -> None:
        if not period > 0:
            raise ValueError(f"a paced env's period must be > 0 seconds, got {period!r}")
        if not reset_scale >= 0:
            raise ValueError(f"a paced env's reset scale must be >= 0, got {reset_scale!r}")
        super().__init__(env)
        self.period = period
        self.reset_scale = reset_scale
        self._clock = clock
        self._sleep = sleep
        self._due: float | None = None  # when the last step was due to return (None before the first reset)

    def reset(self, **kwargs: Any) -> tuple[Any, dict[str, Any]]:
        """Reset the unit and wait until its time on the rig, scaled, has passed since the reset began; the
        episode's clock starts when the reset returns."""
        began = self._clock()
        obs, info = self.env.reset(**kwargs)
        due = began + float(info.get("reset_seconds", 0.0)) * self.reset_scale
        now = self._clock()
        if due > now:
            self._sleep(due - now)
        self._due = max(now, due)
        return obs, info

    def step(self, action: Any) -> tuple[Any, SupportsFloat, bool, bool, dict[str, Any]]:
        """Step the unit, then wait until one period after the previous step was due (no wait if late)."""
        result = self.env.step(action)
        now = self._clock()
        due = now if self._due is None else max(now, self._due + self.period)
        if due > now:
            self._sleep(due - now)
        self._due = due
        return result
