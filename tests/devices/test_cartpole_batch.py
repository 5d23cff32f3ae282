"""CartPole units stepped in a batch: each unit's state and observation equal, bit for bit, to the same unit
stepped alone (CartPoleDevice.step), on random states, parameters and actions."""

import numpy as np
import pytest
from batch_checks import steps_match_alone

from fleetrl.devices.cartpole import CartPoleDevice, CartPoleParams, cartpole_unit_params
from fleetrl.devices.cartpole_batch import CartPoleBatch


def random_units(rng: np.random.Generator, n: int) -> list[CartPoleParams]:
    """Parameters far wider than a fleet's ±10 % (masses, length, force, step and gravity all drawn)."""
    return [
        CartPoleParams(
            gravity=rng.uniform(1.0, 20.0),
            masscart=rng.uniform(0.2, 3.0),
            masspole=rng.uniform(0.01, 1.0),
            length=rng.uniform(0.1, 2.0),
            force_mag=rng.uniform(1.0, 30.0),
            tau=rng.uniform(0.001, 0.05),
        )
        for _ in range(n)
    ]


def test_a_batch_steps_each_unit_as_it_steps_alone_bit_for_bit() -> None:
    rng = np.random.default_rng(20)
    params = random_units(rng, 300) + [cartpole_unit_params(0, u) for u in range(50)]
    alone = [CartPoleDevice(p) for p in params]
    batch = CartPoleBatch([CartPoleDevice(p) for p in params])
    for row, device in enumerate(alone):
        start = rng.uniform(-3.0, 3.0, size=4) * rng.choice([1e-6, 1e-2, 1.0, 10.0])
        device.set_state(start)
        batch.devices[row].set_state(start)
        batch.load(row)
    for _ in steps_match_alone(batch, alone, rng, n_actions=2, steps=60):
        pass
    for row in range(len(params)):  # handed back, the devices hold the states the units reached alone
        batch.store(row)
        assert np.array_equal(batch.devices[row].state, alone[row].state)
    assert len({tuple(batch.state(r)) for r in range(len(params))}) == len(params)  # 350 distinct paths


def test_a_batch_refuses_an_action_a_unit_refuses() -> None:
    batch = CartPoleBatch([CartPoleDevice(), CartPoleDevice()])
    with pytest.raises(
        ValueError, match=r"action 2 is out of range \(choose 0: push left, or 1: push right\)"
    ):
        batch.step(np.array([0, 1]), np.array([1, 2]))
