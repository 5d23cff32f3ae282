"""fleetrl/QubeBalance-v0 passes a fleet profile through to the device layer."""

import gymnasium
import pytest

import fleetrl  # noqa: F401  (registers the envs)
from fleetrl.devices.qube import QubeDevice
from fleetrl.envs.qube_balance import QubeBalanceEnv
from fleetrl.envs.registration import QUBE_BALANCE_ID
from fleetrl.link.inprocess import InProcessLink


def test_fleet_profile_reaches_the_unit() -> None:
    env = gymnasium.make(QUBE_BALANCE_ID, unit=2, fleet_seed=1, fleet_profile="table2")
    device = env.unwrapped.link.device  # type: ignore[attr-defined]
    assert device.params == QubeDevice.from_fleet(2, 1, profile="table2").params
    default = QubeBalanceEnv(unit=2, fleet_seed=1).link.device  # type: ignore[attr-defined]
    assert default.params == QubeDevice.from_fleet(2, 1, profile="v1").params != device.params


def test_bad_fleet_profile_is_a_clear_error() -> None:
    with pytest.raises(ValueError, match=r"unknown fleet profile 'x' \(choose v1 or table2\)"):
        QubeBalanceEnv(fleet_profile="x")
    with pytest.raises(ValueError, match=r"\['fleet_profile'\] configure the in-process simulation"):
        QubeBalanceEnv(link=InProcessLink(QubeDevice.from_fleet(0, 0)), fleet_profile="table2")
