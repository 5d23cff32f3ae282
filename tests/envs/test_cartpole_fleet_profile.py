"""fleetrl/CartPoleUnit-v0 draws its unit with a CartPole fleet profile; the env catalogue resolves CartPole's
profiles; a unit host steps each unit of a wide fleet in its batch as that unit's own env steps it."""

from typing import Any

import gymnasium
import numpy as np
import pytest

import fleetrl  # noqa: F401  (registers the envs)
from fleetrl.devices.cartpole import CARTPOLE_NOMINAL, CartPoleDevice, CartPoleParams
from fleetrl.envs.cartpole_unit import CartPoleUnitEnv
from fleetrl.envs.catalog import get_env_spec
from fleetrl.envs.host_envs import HostEnvs
from fleetrl.envs.registration import CARTPOLE_UNIT_ID
from fleetrl.link.inprocess import InProcessLink
from fleetrl.runs.factory import make_host_learner
from fleetrl.runs.settings import LearningSettings, resolve_learning
from fleetrl.runs.spec import WorkerSpec


def params_of(env: gymnasium.Env[Any, Any]) -> CartPoleParams:
    """The parameters of the in-process unit under ``env``."""
    device = env.unwrapped.link.device  # type: ignore[attr-defined]
    assert isinstance(device, CartPoleDevice)
    return device.params


def test_the_fleet_profile_reaches_the_unit() -> None:
    wide = gymnasium.make(CARTPOLE_UNIT_ID, unit=2, fleet_seed=1, fleet_profile="wide")
    assert params_of(wide) == CartPoleDevice.from_fleet(2, 1, profile="wide").params
    default = CartPoleUnitEnv(unit=2, fleet_seed=1)
    assert params_of(default) == CartPoleDevice.from_fleet(2, 1, profile="standard").params != params_of(wide)
    with pytest.raises(ValueError, match=r"unknown cartpole fleet profile 'v1' \(choose standard or wide\)"):
        CartPoleUnitEnv(fleet_profile="v1")
    with pytest.raises(ValueError, match=r"\['fleet_profile'\] configure the in-process simulation"):
        CartPoleUnitEnv(link=InProcessLink(CartPoleDevice.from_fleet(0, 0)), fleet_profile="wide")


def test_the_catalogue_resolves_cartpoles_profiles() -> None:
    cartpole = get_env_spec("cartpole")
    # the default is the fleet every CartPole run was made on, unset in a run's settings as it always was
    assert cartpole.resolve_fleet_profile(None) is None and cartpole.make_kwargs(None) == {}
    assert cartpole.resolve_fleet_profile("standard") is None and cartpole.make_kwargs("standard") == {}
    assert cartpole.resolve_fleet_profile("wide") == "wide"
    assert cartpole.make_kwargs("wide") == {"fleet_profile": "wide"}
    with pytest.raises(ValueError, match=r"cartpole fleet profile 'table2' \(choose standard or wide\)"):
        cartpole.resolve_fleet_profile("table2")
    built = cartpole.make(4, 2, fleet_profile="wide")
    assert params_of(built.env) == CartPoleDevice.from_fleet(4, 2, profile="wide").params


def test_a_unit_host_steps_each_wide_unit_in_its_batch_as_the_units_own_env_does() -> None:
    learning = resolve_learning(
        LearningSettings(env="cartpole", fleet_seed=3, fleet_profile="wide", preset="standard", max_rounds=5)
    )
    specs = [WorkerSpec(worker=u, unit=u, learning=learning, out="unused") for u in range(4)]
    host = make_host_learner([WorkerSpec.from_json(spec.to_json()) for spec in specs])  # as a host process
    batch = HostEnvs(host.envs)
    assert batch.batched.tolist() == [0, 1, 2, 3]
    alone = [gymnasium.make(CARTPOLE_UNIT_ID, unit=u, fleet_seed=3, fleet_profile="wide") for u in range(4)]
    for u, env in enumerate(alone):
        drawn = CartPoleDevice.from_fleet(u, 3, profile="wide").params
        assert params_of(host.envs[u]) == params_of(env) == drawn
        assert np.array_equal(batch.reset(u, 10 + u), env.reset(seed=10 + u)[0])
    for name in ("masscart", "masspole", "length", "force_mag"):  # every one beyond standard's ±10 % above
        assert max(getattr(params_of(env), name) / getattr(CARTPOLE_NOMINAL, name) for env in alone) > 1.3
    rng = np.random.default_rng(1)
    ends = 0
    for _ in range(300):
        units = np.flatnonzero(rng.random(len(alone)) < 0.8)
        actions = rng.integers(0, 2, size=units.size)
        step = batch.step(units, actions)
        for j, u in enumerate(units.tolist()):
            obs, reward, terminated, truncated, _ = alone[u].step(int(actions[j]))
            assert np.array_equal(step.obs[j], obs)
            assert (step.rewards[j], step.terminated[j], step.truncated[j]) == (reward, terminated, truncated)
            if terminated or truncated:
                ends += 1
                assert np.array_equal(batch.reset(u, None), alone[u].reset()[0])
    assert ends > 10
