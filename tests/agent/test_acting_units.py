"""Acting and remembering for many units at once give each unit what its own agent would: its own draws,
the per-row kernel's actions, the transitions one ``add`` each would store."""

import dataclasses

import numpy as np
import pytest
import torch

from fleetrl.agent.config import get_preset
from fleetrl.agent.policy_numpy import NumpyPolicy
from fleetrl.agent.ppo import PPOAgent
from fleetrl.agent.row_acting import FEW_ROWS, MARGIN, RowActing, UniformDraws


def generators(seeds: range) -> list[np.random.Generator]:
    return [np.random.default_rng(np.random.SeedSequence(s).spawn(2)[0]) for s in seeds]


def test_each_units_draws_are_its_own_generators_in_order() -> None:
    mine, theirs = generators(range(40)), generators(range(40))
    draws = UniformDraws(mine)
    assert draws.compiled
    rng = np.random.default_rng(0)
    for _ in range(30):
        units = np.flatnonzero(rng.random(40) < 0.5)
        assert draws.draw(units).tolist() == [theirs[u].random() for u in units.tolist()]
    for g, twin in zip(mine, theirs, strict=True):  # each generator advanced as by its own random()
        assert g.bit_generator.state == twin.bit_generator.state
        assert g.random() == twin.random()


def test_generators_of_another_bit_generator_are_drawn_one_by_one() -> None:
    mine = [np.random.Generator(np.random.Philox(s)) for s in range(3)]
    theirs = [np.random.Generator(np.random.Philox(s)) for s in range(3)]
    draws = UniformDraws(mine)
    assert not draws.compiled
    assert draws.draw(np.array([2, 0])).tolist() == [theirs[2].random(), theirs[0].random()]


def policy(activation: str, scale: float, seed: int) -> NumpyPolicy:
    """The acting copy of a 3 x 128 actor with 3 actions, its weights scaled by ``scale`` (a trained policy's
    are far from the initial ones)."""
    config = dataclasses.replace(get_preset("standard"), activation=activation)  # type: ignore[arg-type]
    agent = PPOAgent(4, 3, config, [seed])
    with torch.no_grad():
        for p in agent.net.parameters():
            p.add_(torch.randn(p.shape, generator=torch.Generator().manual_seed(seed)) * scale * 0.1)
            p.mul_(scale)
    return NumpyPolicy(agent.net)


@pytest.mark.parametrize(
    ("activation", "scale"), [("tanh", 1.0), ("tanh", 6.0), ("relu", 1.0), ("relu", 4.0)]
)
def test_row_acting_takes_the_per_row_kernels_action_for_every_row(activation: str, scale: float) -> None:
    net = policy(activation, scale, seed=int(scale * 10))
    rows = RowActing(net)
    rng = np.random.default_rng(1)
    obs = rng.normal(size=(4000, 4)) * rng.choice([0.05, 1.0, 4.0], size=(4000, 1))
    draws = rng.random(4000)
    actions = rows.act(obs, draws)
    assert actions.tolist() == [net.act(o, u) for o, u in zip(obs, draws, strict=True)]
    assert len(set(actions.tolist())) >= 2  # not one action everywhere
    assert rows.kernel_rows < 10  # draws this close to a boundary are rare


def test_rows_whose_draw_lies_on_a_boundary_go_to_the_kernel() -> None:
    net = policy("tanh", 1.0, seed=3)
    rows = RowActing(net)
    rng = np.random.default_rng(2)
    obs = rng.normal(size=(600, 4))
    cumulative = np.array([np.cumsum(net.probabilities(o)) for o in obs])
    boundary = cumulative[np.arange(600), rng.integers(0, 2, size=600)]  # after action 0 or after action 1
    inside = (boundary > 0.01) & (boundary < 0.99)
    obs, boundary = obs[inside], boundary[inside]
    draws = boundary + rng.choice([-1, 0, 1], size=boundary.size) * rng.random(boundary.size) * MARGIN * 1e-3
    actions = rows.act(obs, draws)
    assert boundary.size > 300 and rows.kernel_rows == boundary.size
    assert actions.tolist() == [net.act(o, u) for o, u in zip(obs, draws, strict=True)]


def test_few_rows_or_nonfinite_logits_go_to_the_kernel() -> None:
    net = policy("tanh", 1.0, seed=4)
    rows = RowActing(net)
    obs = np.random.default_rng(3).normal(size=(FEW_ROWS - 1, 4))
    draws = np.linspace(0.0, 0.99, FEW_ROWS - 1)
    assert rows.act(obs, draws).tolist() == [net.act(o, u) for o, u in zip(obs, draws, strict=True)]
    assert rows.kernel_rows == FEW_ROWS - 1
    many = np.tile(obs, (3, 1))
    many[5] = np.nan
    rows.act(many, np.tile(draws, 3))
    assert rows.kernel_rows == FEW_ROWS - 1 + 1


def test_remembering_a_time_step_of_units_stores_what_one_call_per_unit_stores() -> None:
    config = dataclasses.replace(get_preset("standard"), hidden=(8,), memory_size=300)
    together, one_by_one = (PPOAgent(4, 2, config, [1, 2, 3, 4]) for _ in range(2))
    rng = np.random.default_rng(5)
    for _ in range(700):  # past the pending rows: drained on the way
        units = np.flatnonzero(rng.random(4) < 0.8)
        obs, next_obs = rng.normal(size=(2, units.size, 4)).astype(np.float32)
        actions, rewards = rng.integers(0, 2, size=units.size), rng.normal(size=units.size)
        terminated, truncated = rng.random((2, units.size)) < 0.05
        together.remember_units(units, obs, actions, rewards, next_obs, terminated, truncated)
        for j, u in enumerate(units.tolist()):
            one_by_one.memories[u].add(
                obs[j], int(actions[j]), float(rewards[j]), next_obs[j], terminated[j], truncated[j]
            )
        if rng.random() < 0.1:
            assert together.needs_more_episodes(0) == one_by_one.needs_more_episodes(0)
    for mine, theirs in zip(together.memories, one_by_one.memories, strict=True):
        for name, array in mine.state_arrays().items():
            assert np.array_equal(array, theirs.state_arrays()[name]), name
    assert not together.needs_more_episodes(0)
