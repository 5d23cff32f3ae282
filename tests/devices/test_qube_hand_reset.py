"""The device-side reset's last resort: where the swing-up has not settled in time, the simulated pendulum
is put upright by hand (as at a rig) and settled by the balance law; a reset that settles in time is
untouched."""

import math

import numpy as np

from fleetrl.devices.qube.device import HAND_RESET_SECONDS, QubeDevice
from fleetrl.devices.qube.params import QubeConfig


def hand_off_window_holds(obs: np.ndarray) -> bool:
    alpha, alpha_dot, theta, theta_dot = obs
    return bool(abs(alpha) <= math.radians(3.0) and abs(alpha_dot) <= 1.5 and abs(theta) <= math.radians(20.0)
                and abs(theta_dot) <= 1.5)  # fmt: skip


def test_a_swing_up_out_of_time_ends_with_the_pendulum_put_upright_by_hand() -> None:
    device = QubeDevice.from_fleet(3, fleet_seed=0, config=QubeConfig(reset_timeout=0.05))  # no swing-up fits
    obs = device.reset(seed=7)
    assert device.last_reset_by_hand and device.hand_resets == 1
    assert hand_off_window_holds(obs)
    assert abs(device.state[0]) < math.radians(1.0) and abs(device.state[1]) < math.radians(1.0)
    assert device.last_reset_seconds >= 0.05  # the swing-up's time counts too
    assert device.last_reset_rig_seconds == device.last_reset_seconds + HAND_RESET_SECONDS  # and the person's


def test_a_reset_that_settles_in_time_is_the_swing_up_s_alone() -> None:
    quick, patient = (
        QubeDevice.from_fleet(3, fleet_seed=0, config=QubeConfig(reset_timeout=t)) for t in (20, 60)
    )
    for seed in range(5):
        first, second = quick.reset(seed=seed).copy(), patient.reset(seed=seed).copy()
        assert not quick.last_reset_by_hand and np.array_equal(first, second)
        assert quick.last_reset_rig_seconds == quick.last_reset_seconds > 0
    assert quick.hand_resets == 0


def test_every_unit_of_a_hundred_of_the_default_fleet_resets() -> None:
    """Units whose cable torque holds the balanced arm outside the hand-off window, or whose swings never
    slow to a catch, are in any fleet this size (the swing-up alone left some without a reset)."""
    for unit in range(100):
        device = QubeDevice.from_fleet(unit, fleet_seed=0)
        for seed in range(5):
            assert hand_off_window_holds(device.reset(seed=1000 * unit + seed))


def test_a_hand_reset_says_why_the_swing_up_did_not_settle() -> None:
    """Two ways a `wide` unit's swing-up runs out of time (lab/benchmarks/fleet_resets.py --modes): the
    balance law holds the pendulum up with the arm outside the settle window, or the swings are never
    caught. A reset that settles has no reason."""
    held = QubeDevice.from_fleet(0, fleet_seed=105, profile="wide")
    held.reset(seed=0)
    assert held.last_reset_by_hand and held.last_unsettled.startswith("held up, not settled: arm at ")
    swinging = QubeDevice.from_fleet(1, fleet_seed=108, profile="wide")
    swinging.reset(seed=0)
    assert swinging.last_reset_by_hand and swinging.last_unsettled == "never caught"
    fine = QubeDevice.from_fleet(3, fleet_seed=0)
    fine.reset(seed=0)
    assert not fine.last_reset_by_hand and fine.last_unsettled == ""
