"""The installed lab is what ``fleetrl experiment`` finds."""

from importlib.metadata import entry_points

from fleetrl_lab.command import main


def test_the_lab_registers_fleetrl_experiment() -> None:
    (found,) = entry_points(group="fleetrl.commands", name="experiment")
    assert found.load() is main
