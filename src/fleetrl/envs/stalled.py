"""A simulated unit that stalls whole at times (``--stall``, :mod:`fleetrl.runs.uneven`): before each step
and reset it waits out a pause under way, so no step of its device happens while it is paused. The wait
changes nothing the env computes (the same observations, later)."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, SupportsFloat

import gymnasium


class StalledEnv(gymnasium.Wrapper[Any, Any, Any, Any]):
    """``env`` whose steps and resets first call ``wait`` (a stalling unit's
    :meth:`~fleetrl.runs.uneven.Stall.wait`: returns when the unit is not paused).

    :param env: the unit's env (simulated, through a link, or paced; nothing of it changes)
    :param wait: waits out the pause under way, if any
    """

    def __init__(self, env: gymnasium.Env[Any, Any], wait: Callable[[], Any]) -> None:
        super().__init__(env)
        self._wait = wait

    def reset(self, **kwargs: Any) -> tuple[Any, dict[str, Any]]:
        """Reset the unit once it is not paused."""
        self._wait()
        return self.env.reset(**kwargs)

    def step(self, action: Any) -> tuple[Any, SupportsFloat, bool, bool, dict[str, Any]]:
        """Step the unit once it is not paused."""
        self._wait()
        return self.env.step(action)
