"""CartPole units: CartPole-v1 physics exactly at nominal, per-unit deviations within ±10 %."""

from dataclasses import asdict

import gymnasium
import numpy as np
import pytest

from fleetrl.devices.cartpole import CARTPOLE_NOMINAL, CartPoleDevice, cartpole_unit_params
from fleetrl.devices.factory import make_device


def test_nominal_unit_reproduces_gymnasium_cartpole() -> None:
    reference = gymnasium.make("CartPole-v1").unwrapped
    reference.reset(seed=0)
    device = CartPoleDevice(CARTPOLE_NOMINAL)
    device.reset(seed=0)
    reference.state = device.state.copy()  # type: ignore[attr-defined]
    actions = [1, 1, 0, 1, 0, 0, 0, 1, 1, 1, 0, 1, 0, 1, 1, 0, 0, 0, 1, 0]
    for a in actions:
        expected, _, terminated, _, _ = reference.step(int(a))
        np.testing.assert_allclose(device.step(int(a)), expected, rtol=1e-6, atol=1e-7)
        if terminated:
            break


def test_units_deviate_within_ten_percent_and_deterministically() -> None:
    nominal = asdict(CARTPOLE_NOMINAL)
    units = [cartpole_unit_params(0, u) for u in range(20)]
    for p in units:
        for name in ("length", "masscart", "masspole", "force_mag"):
            assert abs(getattr(p, name) / nominal[name] - 1) <= 0.10
        assert p.gravity == nominal["gravity"] and p.tau == nominal["tau"]
    assert len({p.length for p in units}) == 20
    assert cartpole_unit_params(0, 4) == cartpole_unit_params(0, 4)


def test_unknown_unit_type_is_a_clear_error() -> None:
    with pytest.raises(ValueError, match=r"unknown unit type 'qbe' \(choose qube or cartpole\)"):
        make_device("qbe")
    with pytest.raises(ValueError, match="unit must be a non-negative integer"):
        make_device("cartpole", unit=-2)
    with pytest.raises(ValueError, match="unknown QUBE option"):
        make_device("qube", control_perod=0.01)
    assert isinstance(make_device("cartpole", unit=3), CartPoleDevice)
