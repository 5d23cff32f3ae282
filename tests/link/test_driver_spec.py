"""The driver interface's command vectors: what a spec declares, clamping, and the simulated drivers."""

from __future__ import annotations

import numpy as np
import pytest

from fleetrl.link.driver import DeviceDriver, DriverSpec, qube_spec, simulated_driver


def test_the_qube_spec_declares_one_volt_command_clamped_to_ten_volts() -> None:
    spec = qube_spec(0.006)
    assert (spec.command_size, spec.command_low, spec.command_high, spec.command_dtype) == (
        1,
        (-10.0,),
        (10.0,),
        "float64",
    )
    assert [spec.command_of(a).tolist() for a in range(spec.n_actions)] == [[-1.44], [0.0], [1.44]]
    assert spec.clamp(np.array([12.5])).tolist() == [10.0]
    assert spec.clamp(np.array([-30.0])).tolist() == [-10.0]
    assert spec.clamp(np.array([3.25])).tolist() == [3.25]
    assert spec.off_command().tolist() == [0.0]


@pytest.mark.parametrize(
    ("command", "match"),
    [(np.array([1.0, 2.0]), "holds 1 values, got 2"), (np.array([np.nan]), "must be finite")],
)
def test_a_command_of_the_wrong_size_or_not_finite_is_refused(command: np.ndarray, match: str) -> None:
    with pytest.raises(ValueError, match=match):
        qube_spec(0.006).clamp(command)


def test_a_spec_refuses_a_discrete_command_outside_its_bounds() -> None:
    with pytest.raises(ValueError, match="not a command of size 1 in bounds"):
        DriverSpec("qube", (-1.0,), (1.0,), ((2.0,),), 0.006, 2, 1.5)


def test_simulated_drivers_hold_the_clamped_command_and_switch_off() -> None:
    qube = simulated_driver("qube", 0, 0)
    assert isinstance(qube, DeviceDriver)
    qube.home(1)
    qube.write_command(np.array([25.0]))
    assert qube.command.tolist() == [10.0]
    qube.wait_until(0.012)  # the held command acts one period late (the rig's actuation delay)
    assert qube.device.applied_volts == 10.0 - qube.device.params.deadband_volts
    qube.motor_off()
    assert qube.command.tolist() == [0.0]
    cart = simulated_driver("cartpole", 0, 0)
    assert (cart.spec.command_size, cart.spec.n_actions) == (1, 2)
    assert cart.spec.command_of(1).tolist() == [1.0]
