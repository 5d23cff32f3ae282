"""CartPole fleet profiles: the seam, the default fleet unchanged, and the wide fleet's spread."""

from dataclasses import astuple, fields

import numpy as np
import pytest

from fleetrl.devices.cartpole import (
    CARTPOLE_FLEET_PROFILES,
    CARTPOLE_NOMINAL,
    DEFAULT_CARTPOLE_FLEET_PROFILE,
    CartPoleDevice,
    CartPoleParams,
    CartPoleVariation,
    cartpole_fleet_profile,
    cartpole_unit_params,
)
from fleetrl.devices.factory import make_device
from fleetrl.devices.variation import CARTPOLE_FAMILY, unit_generator

DRAWN = ("masscart", "masspole", "length", "force_mag")
"""the parameters a unit draws, in the order it draws them"""


def drawn_at_ten_percent(fleet_seed: int, unit: int) -> CartPoleParams:
    """The unit as it was drawn before the fleet had profiles: each drawn parameter times a factor from
    U(0.9, 1.1), in the order cart mass, pole mass, length, force."""
    rng = unit_generator(fleet_seed, unit, CARTPOLE_FAMILY)
    nominal = CARTPOLE_NOMINAL
    factors = {name: float(getattr(nominal, name) * rng.uniform(1.0 - 0.10, 1.0 + 0.10)) for name in DRAWN}
    return CartPoleParams(gravity=nominal.gravity, tau=nominal.tau, **factors)


def deviations(params: list[CartPoleParams], name: str) -> np.ndarray:
    return np.array([getattr(p, name) / getattr(CARTPOLE_NOMINAL, name) - 1.0 for p in params])


def test_profiles_by_name_and_a_clear_error() -> None:
    assert set(CARTPOLE_FLEET_PROFILES) == {"standard", "wide"}
    assert DEFAULT_CARTPOLE_FLEET_PROFILE == "standard"
    assert cartpole_fleet_profile() is cartpole_fleet_profile("standard")
    for name, profile in CARTPOLE_FLEET_PROFILES.items():
        assert profile.name == name and profile.summary
    for bad in ("Standard", "table2", ""):
        choices = r"\(choose standard or wide\)"
        with pytest.raises(ValueError, match=rf"unknown cartpole fleet profile '{bad}' {choices}"):
            cartpole_fleet_profile(bad)
        with pytest.raises(ValueError, match="unknown cartpole fleet profile"):
            CartPoleDevice.from_fleet(0, 0, profile=bad)
        with pytest.raises(ValueError, match="unknown cartpole fleet profile"):
            make_device("cartpole", 0, 0, fleet_profile=bad)
    with pytest.raises(ValueError, match=r"a cartpole unit takes no options, got \['control_period'\]"):
        make_device("cartpole", 0, 0, fleet_profile="wide", control_period=0.01)


def test_a_spread_that_would_make_a_unit_unphysical_is_refused() -> None:
    with pytest.raises(ValueError, match=r"length spread must be in \[0, 1\)"):
        CartPoleVariation(length=1.0)
    with pytest.raises(ValueError, match=r"masspole spread must be in \[0, 1\)"):
        CartPoleVariation(masspole=-0.1)


def test_the_default_fleet_draws_every_unit_as_before_bit_for_bit() -> None:
    for fleet_seed in (0, 1, 7, 2**31 + 5):
        for unit in range(40):
            before = drawn_at_ten_percent(fleet_seed, unit)
            assert cartpole_unit_params(fleet_seed, unit) == before
            assert CartPoleDevice.from_fleet(unit, fleet_seed).params == before
            assert CartPoleDevice.from_fleet(unit, fleet_seed, profile="standard").params == before
            assert make_device("cartpole", unit, fleet_seed).params == before
            assert make_device("cartpole", unit, fleet_seed, fleet_profile="standard").params == before


def test_wide_units_spread_four_times_as_far_and_stay_physical() -> None:
    units = range(500)
    standard = [CartPoleDevice.from_fleet(u, 3, profile="standard").params for u in units]
    wide = [CartPoleDevice.from_fleet(u, 3, profile="wide").params for u in units]
    assert all(w.gravity == CARTPOLE_NOMINAL.gravity and w.tau == CARTPOLE_NOMINAL.tau for w in wide)
    for name in DRAWN:
        narrow, far = deviations(standard, name), deviations(wide, name)
        assert np.all(np.abs(far) <= 0.40 + 1e-12) and np.abs(far).max() > 0.38, name  # the spread is used
        assert np.all(np.abs(narrow) <= 0.10 + 1e-12), name
        assert 3.5 < far.std() / narrow.std() < 4.5, name  # uniform on ±40 % against ±10 %
        # the same draws, stretched: each unit deviates the same way, four times as far
        np.testing.assert_allclose(far, 4.0 * narrow, atol=1e-12)
    for p in wide:  # positive masses, length and force: the pole's equation has a positive denominator
        assert min(astuple(p)) > 0.0
        assert p.length * (4.0 / 3.0 - p.masspole / (p.masspole + p.masscart)) > 0.0


def test_a_wide_unit_still_steps_as_cartpole_does() -> None:
    """A wide unit steps without a numerical fault, and from the same start the same pushes move a wide
    fleet's poles further apart than the standard fleet's."""
    ends = {}
    for profile in ("standard", "wide"):
        poles = []
        for unit in range(20):
            device = CartPoleDevice.from_fleet(unit, 0, profile=profile)
            device.set_state(np.array([0.0, 0.0, 0.02, 0.0]))
            for action in [1, 0] * 5:
                obs = device.step(action)
            assert np.all(np.isfinite(obs))
            poles.append(float(device.state[2]))
        ends[profile] = np.std(poles)
    assert ends["wide"] > 2.0 * ends["standard"]


def test_only_the_drawn_parameters_vary() -> None:
    assert [f.name for f in fields(CartPoleVariation)] == list(DRAWN)
    assert all(getattr(cartpole_fleet_profile("wide").variation, name) == 0.40 for name in DRAWN)
