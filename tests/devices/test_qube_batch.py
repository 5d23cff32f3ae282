"""QUBE units stepped in a batch: each unit's state, sensor pipeline and observation equal, bit for bit, to
the same unit stepped alone (QubeDevice.step), over resets, random actions and units of several fleets."""

import numpy as np
import pytest
from batch_checks import steps_match_alone

from fleetrl.devices.qube.device import QubeBatch, QubeDevice
from fleetrl.devices.qube.params import qube_config


def fleet(n: int) -> list[QubeDevice]:
    """Units of two fleet seeds, one simulated with the quantised encoders and the actuation delay."""
    units = [QubeDevice.from_fleet(u, fleet_seed=u % 2) for u in range(n - 1)]
    return [*units, QubeDevice.from_fleet(7, 3, qube_config(quantise=True, actuation_delay=True))]


def test_a_batch_steps_each_unit_as_it_steps_alone_bit_for_bit() -> None:
    rng = np.random.default_rng(21)
    alone, batched = fleet(12), fleet(12)
    batch = QubeBatch(batched)
    for row, device in enumerate(alone):
        assert np.array_equal(device.reset(seed=row), batched[row].reset(seed=row))
        batch.load(row)
    ends = 0
    for row, obs in steps_match_alone(batch, alone, rng, n_actions=3, steps=600):
        assert np.array_equal(batch.sensor(row), alone[row]._sensor)
        if abs(float(obs[0])) > 0.3 or abs(float(obs[2])) > 1.5:  # fallen: reset both
            ends += 1
            batch.store(row)
            seed = 1000 + ends
            assert np.array_equal(alone[row].reset(seed=seed), batched[row].reset(seed=seed))
            batch.load(row)
    for row in range(len(alone)):  # handed back, the devices hold what the units reached alone
        batch.store(row)
        assert np.array_equal(batched[row].state, alone[row].state)
        assert batched[row].readings == alone[row].readings
    assert ends > 10  # episodes ended and started again in the batch


def test_a_batch_refuses_an_action_a_unit_refuses() -> None:
    batch = QubeBatch(fleet(2))
    refusal = r"action 3 is out of range \(choose 0, 1 or 2: power -60, 0, \+60\)"
    with pytest.raises(ValueError, match=refusal):
        batch.step(np.array([0, 1]), np.array([1, 3]))
    with pytest.raises(ValueError, match="at least one unit"):
        QubeBatch([])
