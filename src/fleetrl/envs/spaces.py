"""What a run needs to know about one unit's env, read from a built env: its spaces (described generally,
so a layer that cannot handle one kind says so in its own words), episode cap and target."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Literal

import gymnasium
import numpy as np

from fleetrl.link.wire import MAX_VECTOR

SUPPORTED_OBSERVATIONS = "a 1-D Box of floats"
SUPPORTED_ACTIONS = "Discrete (at least 2 actions) or a 1-D Box of floats"


@dataclass(frozen=True)
class ActionSpec:
    """A unit's action space, in the terms the layers above use."""

    kind: Literal["discrete", "box"]  # one of ``n`` actions, or a float vector of ``shape`` within low/high
    n: int = 0
    shape: tuple[int, ...] = ()
    low: tuple[float, ...] = ()
    high: tuple[float, ...] = ()

    def __str__(self) -> str:
        return f"Discrete({self.n})" if self.kind == "discrete" else f"Box{self.shape}"


@dataclass(frozen=True)
class UnitDescription:
    """The facts of one built unit env that a run needs before any worker exists."""

    obs_shape: tuple[int, ...]  # 1-D: ``(obs_dim,)``
    action: ActionSpec
    episode_cap: int | None  # ``env.spec.max_episode_steps`` (None: the env ends its episodes itself)
    reward_threshold: float | None  # ``env.spec.reward_threshold``
    env_id: str | None  # ``env.spec.id`` (None: the env was not made from a registered id)
    sensor_size: int | None = None
    """``env.unwrapped.sensor_size``: the device's sensor vector's length (None: the observation's)"""

    @property
    def obs_dim(self) -> int:
        """Length of the observation vector."""
        return self.obs_shape[0]

    @property
    def sensor_dim(self) -> int:
        """Length of the sensor vector the env reads from its device link."""
        return self.obs_dim if self.sensor_size is None else self.sensor_size


def describe_unit(env: object, where: str) -> UnitDescription:
    """``env``'s description, or a ValueError naming ``where`` it came from and what is supported."""
    if not isinstance(env, gymnasium.Env):
        raise ValueError(f"{where} is a {type(env).__name__}, not a gymnasium.Env")
    obs = env.observation_space
    if not (_float_box(obs) and len(obs.shape or ()) == 1 and (obs.shape or (0,))[0] >= 1):
        raise ValueError(
            f"{where} has observation space {obs}: not supported (supported: {SUPPORTED_OBSERVATIONS})"
        )
    sensor_size = getattr(env.unwrapped, "sensor_size", None)
    if sensor_size is not None and (type(sensor_size) is not int or not 1 <= sensor_size <= MAX_VECTOR):
        raise ValueError(
            f"{where} declares sensor_size {sensor_size!r}: give the length of the sensor vector its device "
            f"link returns, an int 1 to {MAX_VECTOR} (or no sensor_size when the observation is that vector)"
        )
    spec = env.spec
    threshold = None if spec is None or spec.reward_threshold is None else float(spec.reward_threshold)
    return UnitDescription(
        obs_shape=tuple(int(n) for n in obs.shape or ()),
        action=action_spec(env.action_space, where),
        episode_cap=None if spec is None else spec.max_episode_steps,
        reward_threshold=threshold,
        env_id=None if spec is None else spec.id,
        sensor_size=sensor_size,
    )


def action_spec(space: gymnasium.Space[Any], where: str) -> ActionSpec:
    """``space`` as an :class:`ActionSpec`, or a ValueError saying which action spaces are supported."""
    if isinstance(space, gymnasium.spaces.Discrete) and int(space.n) >= 2 and int(space.start) == 0:
        return ActionSpec("discrete", n=int(space.n))
    if _float_box(space) and len(space.shape or ()) == 1:
        box: Any = space
        return ActionSpec(
            "box",
            shape=tuple(int(n) for n in box.shape),
            low=tuple(float(x) for x in box.low),
            high=tuple(float(x) for x in box.high),
        )
    raise ValueError(f"{where} has action space {space}: not supported (supported: {SUPPORTED_ACTIONS})")


def _float_box(space: gymnasium.Space[Any]) -> bool:
    return isinstance(space, gymnasium.spaces.Box) and np.issubdtype(space.dtype, np.floating)
