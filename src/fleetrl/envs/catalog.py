"""The unit types a fleet can train on, each an :class:`EnvSpec`: the built-ins by their short names and a
user's own ``package.module:factory``, every unit built and checked by :meth:`EnvSpec.make` and described
(:class:`UnitDescription`: its spaces, episode cap and target); their device side behind device bridges."""

from __future__ import annotations

import dataclasses
import functools
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Literal, NamedTuple

import gymnasium
import numpy as np

from fleetrl.devices.cartpole import DEFAULT_CARTPOLE_FLEET_PROFILE, cartpole_fleet_profile
from fleetrl.devices.qube.params import fleet_profile
from fleetrl.envs.registration import CARTPOLE_UNIT_ID, QUBE_BALANCE_CONTINUOUS_ID, QUBE_BALANCE_ID
from fleetrl.envs.unit_factory import (
    FACTORY_FORM,
    is_factory_reference,
    load_factory,
    takes_link,
)
from fleetrl.envs.wrappers import LastStep
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


UnitBuilder = Callable[..., Any]  # builder(unit, fleet_seed, **options) -> a unit's env


class BuiltUnit(NamedTuple):
    """One unit's env, checked, and its description."""

    env: gymnasium.Env[Any, Any]
    description: UnitDescription


@dataclass(frozen=True)
class EnvSpec:
    """One unit type: how to build its units and what a run of it needs to know."""

    name: str  # what ``--env`` names it by: a built-in's short name or ``package.module:factory``
    builder: UnitBuilder
    declared_target: float | None = None
    """the score that completes a worker's learning (None: the env spec's ``reward_threshold``)"""
    fleet_profile: Callable[[str | None], str | None] | None = None
    """the fleet profile a name chooses (None: the default); None if the unit type has a single fleet"""
    builtin: bool = False
    device: str | None = None  # a built-in's simulated device type a bridge serves; None: a user's type
    takes_link: bool = False  # whether the builder takes a ``link`` (units behind a device bridge)
    control_period: float | None = None  # seconds per step on the real unit (None: not known)
    large_fleet: LargeFleetUpdate | None = None  # the default preset's update for a large fleet of this type

    @property
    def title(self) -> str:
        """How errors name the unit type."""
        return f"env {self.name!r}" if self.builtin else f"unit factory {self.name!r}"

    def resolve_fleet_profile(self, name: str | None) -> str | None:
        """The fleet profile a run of this env draws its units with (``name``, or the type's default)."""
        if self.fleet_profile is not None:
            return self.fleet_profile(name)
        if name is not None:  # a user's unit type (every built-in has profiles)
            raise ValueError(
                f"{self.title} has no fleet profiles (got {name!r}): a factory draws each unit from "
                "(unit, fleet_seed) itself; vary the fleet with --fleet-seed"
            )
        return None

    def make_kwargs(self, fleet_profile: str | None) -> dict[str, Any]:
        """The builder's keyword arguments that pick the fleet profile (none for one fleet)."""
        resolved = self.resolve_fleet_profile(fleet_profile)
        return {} if resolved is None else {"fleet_profile": resolved}

    def make(
        self,
        unit: int,
        fleet_seed: int,
        *,
        fleet_profile: str | None = None,
        link: Any = None,
        last_step: bool = False,
    ) -> BuiltUnit:
        """Unit ``unit`` of fleet ``fleet_seed`` (simulated in-process, or reached through ``link``),
        checked (a ValueError names the unit and what is wrong); with ``last_step`` its observation holds its
        last step too (:class:`~fleetrl.envs.wrappers.LastStep`; the sensor size stays the unit's own)."""
        if link is not None:
            check_takes_link(self)
        options = self.make_kwargs(fleet_profile) if link is None else {"link": link}
        where = f"{self.title}: unit {unit}"
        try:
            env = self.builder(unit, fleet_seed, **options)
        except Exception as err:  # the builder's own failure, named by unit (a setting error, exit 2)
            raise ValueError(f"{where} could not be built: {type(err).__name__}: {err}") from None
        description = describe_unit(env, where)
        if not last_step:
            return BuiltUnit(env, description)
        try:
            wrapped = LastStep(env)
        except ValueError as err:
            env.close()
            raise ValueError(f"{where}: {err} (set last_step=false)") from None
        seen = describe_unit(wrapped, where)
        return BuiltUnit(wrapped, dataclasses.replace(seen, sensor_size=description.sensor_dim))

    def default_target(self, description: UnitDescription) -> float:
        """The target score when none is given: the declared one, else the env spec's ``reward_threshold``."""
        if self.declared_target is not None:
            return self.declared_target
        if description.reward_threshold is not None:
            return description.reward_threshold
        raise ValueError(
            f"{self.title} declares no target score and its env spec has no reward_threshold: "
            "give one with --target-score X (learning is complete when the weighted moving average of the "
            "last 10 scores reaches X)"
        )


def _registered(gym_id: str) -> UnitBuilder:
    """A built-in's builder: ``gymnasium.make`` of its registered id."""

    def build(unit: int, fleet_seed: int, **options: Any) -> Any:
        return gymnasium.make(gym_id, unit=unit, fleet_seed=fleet_seed, **options)

    return build


def _qube_fleet_profile(name: str | None) -> str:
    return fleet_profile(name).name


def _cartpole_fleet_profile(name: str | None) -> str | None:
    """CartPole's profile by name; its default, ``standard``, resolves to None, as before profiles."""
    chosen = cartpole_fleet_profile(name).name
    return None if chosen == DEFAULT_CARTPOLE_FLEET_PROFILE else chosen


@dataclass(frozen=True)
class LargeFleetUpdate:
    """PPO settings a federated fleet of at least ``from_units`` units of one type learns with by default."""

    from_units: int
    settings: tuple[tuple[str, float | int], ...]


CARTPOLE_LARGE_FLEET = LargeFleetUpdate(
    1000, (("batch_size", 16), ("n_optimisations", 40), ("actor_lr", 2e-3), ("critic_lr", 2e-3))
)
"""measured at 1,000 CartPole units; QUBE has none (docs/results.md, "A fleet of any size")"""

QUBE_CONTROL_PERIOD = 0.006  # the QUBE-Servo 2 rig's control period (``QubeConfig.control_period``: 6 ms)
CARTPOLE_CONTROL_PERIOD = 0.02  # CartPole's step (``CartPoleParams.tau``: 20 ms)
_QUBE = (_qube_fleet_profile, "qube", QUBE_CONTROL_PERIOD)  # both QUBE tasks' profiles, device and period

ENV_SPECS: dict[str, EnvSpec] = {
    name: EnvSpec(
        name,
        _registered(gym_id),
        target,
        profiles,
        builtin=True,
        device=device,
        takes_link=True,
        control_period=period,
        large_fleet=CARTPOLE_LARGE_FLEET if name == "cartpole" else None,
    )
    for name, gym_id, target, profiles, device, period in [
        ("qube", QUBE_BALANCE_ID, 2450.0, *_QUBE),
        ("qube-continuous", QUBE_BALANCE_CONTINUOUS_ID, 2450.0, *_QUBE),
        ("cartpole", CARTPOLE_UNIT_ID, 475.0, _cartpole_fleet_profile, "cartpole", CARTPOLE_CONTROL_PERIOD),
    ]
}


def get_env_spec(name: str) -> EnvSpec:
    """A built-in by short name, or a user's unit type by ``package.module:factory``."""
    if name in ENV_SPECS:
        return ENV_SPECS[name]
    if is_factory_reference(name):
        factory = load_factory(name)
        return EnvSpec(name, factory, takes_link=takes_link(factory))
    *others, last = sorted(ENV_SPECS)
    choices = f"{', '.join(others)} or {last}"
    module, dot, attr = name.rpartition(".")
    hint = f"; did you mean {module + ':' + attr!r}?" if dot and module and attr else ""
    raise ValueError(
        f"unknown env {name!r} (choose {choices}, or your own unit type as {FACTORY_FORM}){hint}"
    )


@functools.lru_cache(maxsize=16)
def describe_env(name: str, last_step: bool = False) -> UnitDescription:
    """The description of unit 0 of fleet 0 of env ``name`` (built once per process and closed)."""
    built = get_env_spec(name).make(0, 0, last_step=last_step)
    built.env.close()
    return built.description


def check_takes_link(env: EnvSpec) -> None:
    """A ValueError saying how to fix it unless ``env``'s units can be built over a device link."""
    if not env.takes_link:
        raise ValueError(
            f"{env.title} takes no link keyword: to put its units behind device bridges, define it as "
            "factory(unit, fleet_seed, link=None) and build the env over the link it is given"
        )
