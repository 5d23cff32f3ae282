"""Fleet profiles: the seam, today's fleet unchanged, and the calibrated fleet's Table 2 figures."""

import math
from dataclasses import fields

import numpy as np
import pytest

from fleetrl.devices.homogeneity import homogeneity_test, pooled_homogeneity
from fleetrl.devices.qube.device import QubeDevice
from fleetrl.devices.qube.params import (
    DEFAULT_FLEET_PROFILE,
    FLEET_PROFILES,
    NOMINAL,
    QubeVariation,
    fleet_profile,
    qube_unit_params,
)

# the paper's Table 2 (three real units): off-diagonal motor 0.75-0.86, pendulum 0.96-0.98
TABLE2_MOTOR = (0.75, 0.86)
TABLE2_PENDULUM = (0.96, 0.98)


def test_profiles_by_name_and_a_clear_error() -> None:
    assert set(FLEET_PROFILES) == {"v1", "table2", "wide"}
    assert DEFAULT_FLEET_PROFILE == "table2"
    assert fleet_profile() is fleet_profile("table2")
    for name, profile in FLEET_PROFILES.items():
        assert profile.name == name and profile.summary
    for bad in ("tabel2", "", "V1"):
        with pytest.raises(ValueError, match=rf"unknown fleet profile '{bad}' \(choose v1, table2 or wide\)"):
            fleet_profile(bad)
        with pytest.raises(ValueError, match="unknown fleet profile"):
            QubeDevice.from_fleet(0, 0, profile=bad)
        with pytest.raises(ValueError, match="unknown fleet profile"):
            homogeneity_test(profile=bad)
    with pytest.raises(ValueError, match="a fleet profile or a variation, not both"):
        QubeDevice.from_fleet(0, 0, variation=QubeVariation(), profile="v1")


def test_v1_is_the_variation_the_fleet_had_and_adds_no_new_physics() -> None:
    """``v1`` is ``QubeVariation()``'s defaults, and its units carry no cable torque and no dead zone."""
    assert fleet_profile("v1").variation == QubeVariation()
    for seed in range(3):
        for unit in range(10):
            p = qube_unit_params(seed, unit, fleet_profile("v1").variation)
            assert p == qube_unit_params(seed, unit)
            assert p.cable_stiffness == 0.0 and p.deadband_volts == 0.0


def _trajectory(device: QubeDevice, seed: int) -> np.ndarray:
    """Reset (swing-up), 400 random actions, the balance law: every observation and the true end state."""
    rows = [device.reset(seed=seed).astype(np.float64)]
    rows += [device.step(int(a)).astype(np.float64) for a in np.random.default_rng(seed).integers(0, 3, 400)]
    device.set_state(np.array([0.0, math.radians(3.0), 0.0, 0.0]))
    rows.append(np.array([device.balance(300), device.last_reset_seconds, 0.0, 0.0]))
    rows.append(device.state)
    return np.array(rows)


def test_the_default_fleet_is_table2_bit_for_bit() -> None:
    for unit in range(3):
        default = QubeDevice.from_fleet(unit, fleet_seed=4)
        named = QubeDevice.from_fleet(unit, fleet_seed=4, profile="table2")
        assert default.params == named.params
        np.testing.assert_array_equal(_trajectory(default, unit), _trajectory(named, unit))
    first = homogeneity_test(3, 1, 20, 2)
    again = homogeneity_test(3, 1, 20, 2, profile="table2")
    assert first.profile == again.profile == "table2"
    np.testing.assert_array_equal(first.motor_changes, again.motor_changes)
    np.testing.assert_array_equal(first.pendulum_changes, again.pendulum_changes)


def test_table2_units_differ_from_v1_where_the_profiles_differ() -> None:
    v1, table2 = (fleet_profile(name).variation for name in ("v1", "table2"))
    changed = {f.name for f in fields(QubeVariation) if getattr(v1, f.name) != getattr(table2, f.name)}
    assert "cable_stiffness_range" in changed
    a, b = qube_unit_params(0, 1, v1), qube_unit_params(0, 1, table2)
    assert a.cable_stiffness == 0.0 < b.cable_stiffness
    assert (a.Rm, a.km, a.mp, a.Lp) == (b.Rm, b.km, b.mp, b.Lp)  # same draws where the spreads agree


def test_wide_units_spread_as_a_fleet_of_mixed_revisions_does() -> None:
    table2, wide = (fleet_profile(name).variation for name in ("table2", "wide"))
    drawn = [(qube_unit_params(7, u, table2), qube_unit_params(7, u, wide)) for u in range(200)]
    for name, spread in (("Rm", 0.25), ("km", 0.25), ("mr", 0.20), ("Lr", 0.20), ("mp", 0.20), ("Lp", 0.20)):
        nominal = getattr(NOMINAL, name)
        deviations = np.array([getattr(w, name) / nominal - 1.0 for _, w in drawn])
        assert np.all(np.abs(deviations) <= spread + 1e-12), name
        assert np.abs(deviations).max() > 0.9 * spread, name  # the spread is used, not just allowed
    dead_zones = np.array([w.deadband_volts for _, w in drawn])
    assert np.all((dead_zones >= 0.0) & (dead_zones <= 0.2)) and dead_zones.max() > 0.18
    assert all(t.deadband_volts == 0.0 for t, _ in drawn)
    # the cable and the damping are table2's, drawn in the same order: the same value for the same unit
    assert all((t.Dr, t.Dp, t.cable_stiffness) == (w.Dr, w.Dp, w.cable_stiffness) for t, w in drawn)


@pytest.mark.slow
def test_the_default_fleet_gives_the_papers_homogeneity() -> None:
    table2 = pooled_homogeneity(range(3), range(5))
    assert table2.profile == "table2"
    assert table2.motor.shape == table2.pendulum.shape == (3 * 5 * 3,)  # 3 pairs per test
    motor, pendulum = table2.motor_median, table2.pendulum_median
    assert TABLE2_MOTOR[0] <= motor <= TABLE2_MOTOR[1], f"median motor correlation {motor:.3f}"
    assert TABLE2_PENDULUM[0] <= pendulum <= TABLE2_PENDULUM[1], f"median pendulum correlation {pendulum:.3f}"
    # the motors differ more than the pendulums, as on the rig; today's fleet shows the reverse
    v1 = pooled_homogeneity(range(3), range(5), profile="v1")
    assert v1.profile == "v1" and v1.motor_median > v1.pendulum_median
    assert motor < pendulum
