"""A 10-unit QUBE fleet: the reference controller, the device-side reset, per-unit determinism."""

import math
from dataclasses import asdict

import numpy as np
import pytest

from fleetrl.devices.qube import NOMINAL, QubeConfig, QubeDevice
from fleetrl.devices.qube.units import QubeVariation, qube_unit_params

FLEET = range(10)
SWING_UP_BOUND_S = 5.0  # measured: at most 1.85 s over 200 units (10 fleet seeds x 20 units)
ARM_TRAVEL_BOUND = math.radians(150)


@pytest.mark.parametrize(
    "config",
    [
        QubeConfig(control_period=0.002, velocity_estimate="filter"),  # the reference's 500 Hz + 50 rad/s
        QubeConfig(),  # the agent's default: 6 ms, finite-difference velocities
    ],
    ids=["500Hz-filter", "166Hz-difference"],
)
def test_reference_controller_holds_every_unit(config: QubeConfig) -> None:
    assert config.quantise and config.actuation_delay
    for unit in FLEET:
        device = QubeDevice.from_fleet(unit, fleet_seed=0, config=config)
        device.set_state(np.array([0.0, math.radians(3.0), 0.0, 0.0]))
        worst = device.balance(2500)
        assert worst < math.radians(7.5), f"unit {unit}: |alpha| reached {math.degrees(worst):.1f} deg"
        assert abs(device.state[0]) < math.radians(30), f"unit {unit}: arm drifted"


def test_swing_up_and_settle_hands_over_on_every_unit() -> None:
    for unit in FLEET:
        device = QubeDevice.from_fleet(unit, fleet_seed=0)
        obs = device.reset(seed=unit)
        assert device.last_reset_seconds <= SWING_UP_BOUND_S, f"unit {unit}: {device.last_reset_seconds} s"
        assert device.last_reset_arm_travel < ARM_TRAVEL_BOUND
        alpha, alpha_dot, theta, theta_dot = obs
        assert abs(alpha) <= math.radians(3.0) and abs(alpha_dot) <= 1.5
        assert abs(theta) <= math.radians(20.0) and abs(theta_dot) <= 1.5
        true_alpha = (device.state[1] + math.pi) % (2 * math.pi) - math.pi
        assert abs(true_alpha) < math.radians(5.0)


def test_same_unit_same_trajectory_other_unit_other_dynamics() -> None:
    actions = np.random.default_rng(7).integers(0, 3, size=300)

    def trajectory(unit: int) -> np.ndarray:
        device = QubeDevice.from_fleet(unit, fleet_seed=5)
        device.set_state(np.array([0.0, math.pi - 0.2, 0.0, 0.0]))
        return np.array([device.step(int(a)).copy() for a in actions])

    first, again, other = trajectory(3), trajectory(3), trajectory(4)
    np.testing.assert_array_equal(first, again)
    assert np.max(np.abs(first - other)) > 0.05  # rad: clearly different dynamics
    assert qube_unit_params(5, 3) == qube_unit_params(5, 3)
    assert qube_unit_params(5, 3) != qube_unit_params(6, 3)


def test_seeded_reset_is_reproducible() -> None:
    a = QubeDevice.from_fleet(2, fleet_seed=1).reset(seed=11).copy()
    b = QubeDevice.from_fleet(2, fleet_seed=1).reset(seed=11).copy()
    c = QubeDevice.from_fleet(2, fleet_seed=1).reset(seed=12).copy()
    np.testing.assert_array_equal(a, b)
    assert not np.array_equal(a, c)


def test_deviations_stay_in_their_documented_ranges() -> None:
    v = QubeVariation()
    nominal = asdict(NOMINAL)
    draws = [qube_unit_params(seed, unit) for seed in range(5) for unit in range(20)]
    for p in draws:
        for name in ("mr", "Lr", "mp", "Lp"):
            assert abs(getattr(p, name) / nominal[name] - 1) <= v.mass_length
        for name in ("Rm", "km"):
            assert abs(getattr(p, name) / nominal[name] - 1) <= v.motor
        assert v.Dr_range[0] <= p.Dr <= v.Dr_range[1] and v.Dp_range[0] <= p.Dp <= v.Dp_range[1]
        assert abs(p.theta_offset_counts) <= 2 and abs(p.alpha_offset_counts) <= 2
    assert len({p.km for p in draws}) == len(draws)  # every unit is its own


@pytest.mark.parametrize("bad", [-1, 1.5, "0", True])
def test_bad_unit_is_a_clear_error(bad: object) -> None:
    with pytest.raises(ValueError, match="unit must be a non-negative integer"):
        QubeDevice.from_fleet(bad, fleet_seed=0)  # type: ignore[arg-type]


def test_bad_action_is_a_clear_error() -> None:
    device = QubeDevice(NOMINAL)
    with pytest.raises(ValueError, match=r"out of range \(choose 0, 1 or 2"):
        device.step(3)
