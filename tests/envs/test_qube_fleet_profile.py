"""fleetrl/QubeBalance-v0 passes a fleet profile through to the device layer; the env catalogue names each
unit type's profiles."""

import gymnasium
import pytest

import fleetrl  # noqa: F401  (registers the envs)
from fleetrl.devices.factory import make_device
from fleetrl.devices.qube.device import QubeDevice
from fleetrl.envs.catalog import get_env_spec
from fleetrl.envs.qube_balance import QubeBalanceEnv
from fleetrl.envs.registration import QUBE_BALANCE_ID
from fleetrl.link.inprocess import InProcessLink


def test_fleet_profile_reaches_the_unit() -> None:
    env = gymnasium.make(QUBE_BALANCE_ID, unit=2, fleet_seed=1, fleet_profile="v1")
    device = env.unwrapped.link.device  # type: ignore[attr-defined]
    assert device.params == QubeDevice.from_fleet(2, 1, profile="v1").params
    default = QubeBalanceEnv(unit=2, fleet_seed=1).link.device  # type: ignore[attr-defined]
    assert default.params == QubeDevice.from_fleet(2, 1, profile="table2").params != device.params


def test_the_catalogue_resolves_each_unit_types_profiles() -> None:
    qube, cartpole = get_env_spec("qube"), get_env_spec("cartpole")
    assert qube.resolve_fleet_profile(None) == "table2"
    assert qube.resolve_fleet_profile("v1") == "v1"
    assert qube.make_kwargs(None) == {"fleet_profile": "table2"}
    with pytest.raises(ValueError, match="unknown fleet profile 'V1'"):
        qube.make_kwargs("V1")
    with pytest.raises(ValueError, match="unknown cartpole fleet profile 'v1'"):  # a QUBE's name
        cartpole.resolve_fleet_profile("v1")
    with pytest.raises(ValueError, match="unknown cartpole fleet profile 'v1'"):
        make_device("cartpole", 0, 0, fleet_profile="v1")
    v1_unit = QubeDevice.from_fleet(1, 2, profile="v1")
    assert make_device("qube", 1, 2, fleet_profile="v1").params == v1_unit.params


def test_bad_fleet_profile_is_a_clear_error() -> None:
    with pytest.raises(ValueError, match=r"unknown fleet profile 'x' \(choose v1, table2 or wide\)"):
        QubeBalanceEnv(fleet_profile="x")
    with pytest.raises(ValueError, match=r"\['fleet_profile'\] configure the in-process simulation"):
        QubeBalanceEnv(link=InProcessLink(QubeDevice.from_fleet(0, 0)), fleet_profile="table2")
