"""The lab's history wrapper: each observation carries the one before it and the action between them."""

import numpy as np

from fleetrl_lab.history_env import qube_wide


def test_an_observation_holds_the_last_observation_and_the_action_that_followed_it():
    env = qube_wide(0, 0)
    try:
        first, _ = env.reset(seed=0)
        assert env.observation_space.shape == (11,)
        np.testing.assert_array_equal(first[:4], first[4:8])  # at a reset the last observation is the first
        np.testing.assert_array_equal(first[8:], 0.0)
        second, *_ = env.step(2)
        np.testing.assert_array_equal(second[4:8], first[:4])
        np.testing.assert_array_equal(second[8:], [0.0, 0.0, 1.0])
        third, *_ = env.step(0)
        np.testing.assert_array_equal(third[4:8], second[:4])
        np.testing.assert_array_equal(third[8:], [1.0, 0.0, 0.0])
    finally:
        env.close()
