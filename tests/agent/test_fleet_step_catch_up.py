"""A straggler's catch-up on the real PPOAgent: an agent that missed a round's answers and applies them with
``apply_fleet_step`` holds, bit for bit, the network and Adam state of one that applied them live with
``apply_step`` — and the comparison fails on a catch-up broken on purpose (lab/benchmarks/one_policy.py)."""

from __future__ import annotations

import dataclasses
import sys
from pathlib import Path

import numpy as np
import pytest

from fleetrl.agent.config import get_preset
from fleetrl.agent.ppo import PPOAgent

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "lab" / "benchmarks"))  # one_policy

from one_policy import MUTATIONS, BrokenCatchUp

ROUNDS, MISSED = 4, (1, 2)
"""the fleet's rounds, and those the straggler plays too slowly to take part in"""


def cartpole_sized() -> PPOAgent:
    """A CartPole-sized agent of the ``standard`` preset (one Adam per model, as ``pergrad`` needs), small."""
    config = dataclasses.replace(get_preset("standard"), memory_size=96, batch_size=32, n_optimisations=3)
    return PPOAgent(4, 2, config, seed=5)


def play(agent: PPOAgent, rng: np.random.Generator, n: int = 40) -> None:
    """``n`` transitions of a made-up episode into the agent's memory."""
    obs = rng.normal(size=(n + 1, 4)).astype(np.float32)
    for t in range(n):
        agent.remember(obs[t], agent.act(obs[t]), 1.0, obs[t + 1], t == n - 1, False)


def assert_same_policy(a: PPOAgent, b: PPOAgent, where: str) -> None:
    """The network and the Adam states (moments and step counts) of ``a`` and ``b``, bit for bit."""
    for what, x, y in (
        ("network", a.model_parameters(), b.model_parameters()),
        ("Adam state", a.optimiser_parameters(), b.optimiser_parameters()),
    ):
        if x.tobytes() != y.tobytes():
            differ = np.flatnonzero(x != y)
            raise AssertionError(
                f"{where}: the {what} differs in {differ.size} of {x.size} values "
                f"(largest |Δ| {np.max(np.abs(x - y)):.3g})"
            )


def fleet_run(broken: BrokenCatchUp | None) -> tuple[int, list[str]]:
    """The fleet's answers (the mean of the live agent's step gradient and another worker's) to a live agent
    and to a straggler that misses rounds :data:`MISSED` and catches up after each; compared after each
    catch-up and at every exchange after it; how many comparisons, and the differences found (a line each)."""
    live, straggler = cartpole_sized(), cartpole_sized()
    assert_same_policy(live, straggler, "at the start")
    rng, other = np.random.default_rng(0), np.random.default_rng(1)
    found: list[str] = []
    checked = [0]
    behind_since: int | None = None

    def check(where: str) -> None:
        checked[0] += 1
        try:
            assert_same_policy(live, straggler, where)
        except AssertionError as err:
            found.append(str(err))

    for rnd in range(ROUNDS):
        play(live, rng)
        play(straggler, rng)
        behind = rnd in MISSED
        steps = live.begin_update()
        if not behind:
            assert straggler.begin_update() == steps
        missed: list[tuple[int, np.ndarray]] = []
        for k in range(steps):
            mine = live.step_gradients(k)
            answer = (0.5 * (mine + other.normal(scale=0.1, size=mine.size))).astype(np.float32)
            live.apply_step(answer)
            if behind:
                missed.append((k, answer))
                continue
            straggler.step_gradients(k)
            straggler.apply_step(answer)
            if behind_since is not None:
                check(f"round {rnd} step {k}, live after catching up")
        live.end_update()
        if not behind:
            straggler.end_update()
            continue
        for k, answer in missed:
            if broken is None:
                straggler.apply_fleet_step(k, answer)
            else:
                broken(straggler.apply_fleet_step, k, answer)
        behind_since = rnd if behind_since is None else behind_since
        check(f"round {rnd}, after catching up {len(missed)} answers")
    return checked[0], found


def test_a_straggler_that_caught_up_holds_what_a_live_agent_holds_at_every_exchange() -> None:
    checked, found = fleet_run(None)
    assert found == [] and checked == 5, checked  # after each of the 2 catch-ups, at the last round's 3 steps


@pytest.mark.parametrize("mutation", MUTATIONS)
def test_the_comparison_fails_on_a_broken_catch_up(mutation: str) -> None:
    """Skip one missed answer; apply two out of order; a catch-up step with one gradient term changed."""
    _, found = fleet_run(BrokenCatchUp(mutation))
    print(f"{mutation}: {len(found)} differences; first: {found[0] if found else None}")
    assert found and found[0].startswith(f"round {MISSED[0]}, after catching up"), found[:2]
