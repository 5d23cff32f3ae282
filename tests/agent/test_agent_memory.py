"""Trajectory memory (ring buffer, chronological order) and the contiguous window sampler."""

import numpy as np
import pytest

from fleetrl.agent.memory import TrajectoryMemory, sample_window


def fill(memory: TrajectoryMemory, n: int) -> None:
    for i in range(n):
        obs = np.full(2, i, dtype=np.float32)
        memory.add(obs, i % 3, float(i), obs + 1, terminated=(i % 7 == 6), truncated=(i % 11 == 10))


def test_memory_keeps_last_capacity_in_order() -> None:
    memory = TrajectoryMemory(5, obs_dim=2)
    fill(memory, 12)
    data = memory.transitions()
    assert len(memory) == 5 and len(data) == 5
    assert data.rewards.tolist() == [7.0, 8.0, 9.0, 10.0, 11.0]
    assert data.obs[:, 0].tolist() == [7.0, 8.0, 9.0, 10.0, 11.0]
    assert data.next_obs[:, 0].tolist() == [8.0, 9.0, 10.0, 11.0, 12.0]
    assert data.actions.tolist() == [1, 2, 0, 1, 2]
    assert data.terminated.tolist() == [0.0, 0.0, 0.0, 0.0, 0.0]
    assert data.episode_end.tolist() == [0.0, 0.0, 0.0, 1.0, 0.0]  # 10: truncated


def test_memory_partial_fill_and_terminal_flags() -> None:
    memory = TrajectoryMemory(200, obs_dim=2)
    fill(memory, 8)
    data = memory.transitions()
    assert data.rewards.tolist() == list(map(float, range(8)))
    assert data.terminated[6] == 1.0 and data.episode_end[6] == 1.0


def test_unscored_slots_follow_new_transitions() -> None:
    memory = TrajectoryMemory(4, obs_dim=2)
    fill(memory, 3)
    slots = memory.unscored()
    assert slots.tolist() == [0, 1, 2]
    memory.score(slots, np.array([-0.1, -0.2, -0.3], dtype=np.float32))
    assert memory.unscored().size == 0
    fill(memory, 2)  # wraps: slot 3 and then slot 0 are overwritten
    assert memory.unscored().tolist() == [0, 3]
    assert np.allclose(memory.transitions().behaviour_log_probs[:2], [-0.2, -0.3])


def test_window_is_contiguous_full_length_and_covers_all_starts() -> None:
    rng = np.random.default_rng(0)
    starts = set()
    for _ in range(3000):
        start, stop = sample_window(200, 64, rng)
        assert stop - start == 64 and start >= 0 and stop <= 200
        starts.add(start)
    assert starts == set(range(0, 200 - 64 + 1))


def test_window_smaller_memory_takes_everything() -> None:
    rng = np.random.default_rng(0)
    assert sample_window(20, 64, rng) == (0, 20)
    assert sample_window(64, 64, rng) == (0, 64)
    with pytest.raises(ValueError, match="empty"):
        sample_window(0, 64, rng)


def test_window_starts_are_seeded() -> None:
    a = [sample_window(200, 64, np.random.default_rng(3)) for _ in range(5)]
    b = [sample_window(200, 64, np.random.default_rng(3)) for _ in range(5)]
    assert a == b


def test_a_growing_memory_keeps_every_transition_until_cleared() -> None:
    memory = TrajectoryMemory(3, obs_dim=2, grows=True)
    for i in range(7):
        assert len(memory) == i
        memory.add(np.full(2, i, np.float32), i % 2, float(i), np.full(2, i + 1, np.float32), False, i == 6)
    data = memory.transitions()
    assert len(memory) == 7
    assert data.rewards.tolist() == [0, 1, 2, 3, 4, 5, 6]  # nothing overwritten, in order
    assert data.next_obs[:, 0].tolist() == [1, 2, 3, 4, 5, 6, 7] and data.episode_end.tolist()[-1] == 1.0
    assert memory.unscored().tolist() == list(range(7))
    memory.clear()
    assert len(memory) == 0 and memory.unscored().size == 0


def test_a_grown_memory_state_loads_into_a_fresh_one() -> None:
    memory = TrajectoryMemory(2, obs_dim=1, grows=True)
    for i in range(5):
        memory.add(np.array([i], np.float32), 0, float(i), np.array([i], np.float32), False, False)
    fresh = TrajectoryMemory(2, obs_dim=1, grows=True)
    fresh.load_state_arrays(memory.state_arrays())
    assert fresh.transitions().rewards.tolist() == [0, 1, 2, 3, 4]
    fresh.add(np.array([5], np.float32), 0, 5.0, np.array([5], np.float32), False, False)
    assert fresh.transitions().rewards.tolist() == [0, 1, 2, 3, 4, 5]


@pytest.mark.parametrize(("grows", "action_dim"), [(False, 0), (True, 0), (False, 2), (True, 2)])
def test_extend_stores_what_one_add_per_transition_stores(grows: bool, action_dim: int) -> None:
    rng = np.random.default_rng(4)
    one_by_one = TrajectoryMemory(5, obs_dim=3, grows=grows, action_dim=action_dim)
    at_once = TrajectoryMemory(5, obs_dim=3, grows=grows, action_dim=action_dim)
    for n in (0, 2, 4, 1, 12, 3, 5, 0, 7):  # wraps a ring, runs longer than it, doubles a growing one twice
        obs, next_obs = rng.normal(size=(2, n, 3)).astype(np.float32)
        if action_dim == 0:
            actions = rng.integers(0, 3, size=n)
        else:
            actions = rng.normal(size=(n, 2)).astype(np.float32)
        rewards = rng.normal(size=n)  # float64: stored as float32 either way
        terminated, truncated = rng.random((2, n)) < 0.3
        for i in range(n):
            one_by_one.add(obs[i], actions[i], float(rewards[i]), next_obs[i], terminated[i], truncated[i])
        at_once.extend(obs, actions, rewards, next_obs, terminated, truncated)
        if n == 3:
            one_by_one.score(one_by_one.unscored()[:2], np.ones(2, dtype=np.float32))
            at_once.score(at_once.unscored()[:2], np.ones(2, dtype=np.float32))
        mine, theirs = at_once.state_arrays(), one_by_one.state_arrays()
        assert mine.keys() == theirs.keys()
        for name in mine:
            assert np.array_equal(mine[name], theirs[name]), name
    if grows:
        assert len(at_once) == 34 and at_once.state_arrays()["actions"].shape[0] == 40
