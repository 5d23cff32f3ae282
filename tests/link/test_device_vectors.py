"""Command vectors through a device bridge on the in-process bus: the continuous QUBE task and a user's
continuous unit type (slider_units.py) give their in-process trajectories; out-of-bound values are
clamped; a bad vector is refused with its reason and never acted on; the protective stop holds for vectors;
an observation of another size than the env declares is an error."""

from __future__ import annotations

import logging
import warnings
from collections.abc import Iterator

import gymnasium
import numpy as np
import pytest
from slider_units import SLIDER_ID, SliderDevice, SliderEnv, driver
from trajectory_helpers import assert_same, run_episodes

from fleetrl.envs.qube_balance import QubeBalanceContinuousEnv
from fleetrl.link.bridge import DeviceBridge
from fleetrl.link.driver import DeviceDriver, SimulatedDriver, driver_of, simulated_driver
from fleetrl.link.mqtt import DeviceLinkError, MqttLink
from fleetrl.transport.local import LocalBus

RUN = "v"


@pytest.fixture
def bus() -> LocalBus:
    return LocalBus()


def serve(bus: LocalBus, served: DeviceDriver, unit: int = 0) -> DeviceBridge:
    return DeviceBridge(bus.client(), served, RUN, unit).start()


@pytest.fixture
def slider(bus: LocalBus) -> Iterator[DeviceBridge]:
    running = serve(bus, driver_of(driver, 0, 2))
    yield running
    running.close()


def test_the_continuous_qube_task_over_a_bridge_gives_the_in_process_trajectory(bus: LocalBus) -> None:
    bridge = serve(bus, simulated_driver("qube", 1, 3), unit=1)
    try:
        over_link = QubeBalanceContinuousEnv(1, 3, link=MqttLink(bus.client(), RUN, 1, obs_size=4))
        expected = run_episodes(QubeBalanceContinuousEnv(1, 3), 2, 150, seed=5)
        assert_same(run_episodes(over_link, 2, 150, seed=5), expected)
        over_link.close()
    finally:
        bridge.close()
    assert bridge.stats.rejected == 0 and bridge.stats.commands > 20


def test_a_user_unit_type_over_a_bridge_gives_the_in_process_trajectory(
    bus: LocalBus, slider: DeviceBridge
) -> None:
    over_link = SliderEnv(0, 2, link=MqttLink(bus.client(), RUN, 0, obs_size=2))
    expected = run_episodes(SliderEnv(0, 2), 3, 80, seed=1)
    assert_same(run_episodes(over_link, 3, 80, seed=1), expected)
    assert slider.stats.rejected == 0 and slider.stats.commands > 20


def test_an_out_of_bound_command_is_clamped_to_the_spec(bus: LocalBus) -> None:
    qube = simulated_driver("qube", 0, 0)
    bridge = serve(bus, qube)
    try:
        link = MqttLink(bus.client(), RUN, 0)
        link.reset(1)
        link.step(np.array([25.0], dtype=np.float32))
        assert qube.command.tolist() == [10.0]  # the QUBE's ±10 V
        link.step(1)  # an index on the same bridge: the discrete task's 0 V
        assert qube.command.tolist() == [0.0]
        link.step(np.array([-1e30]))
        assert qube.command.tolist() == [-10.0]
    finally:
        bridge.close()


@pytest.mark.parametrize(
    ("action", "reason"),
    [
        (np.array([0.5, 0.5], dtype=np.float32), "command vector of 8 bytes: this unit takes 1"),
        (np.array([np.nan], dtype=np.float32), "not finite"),
        (np.array([np.inf]), "not finite"),
        (1, "this unit takes no action index, got 1"),
    ],
)
def test_a_bad_command_is_refused_with_its_reason_and_never_acted_on(
    bus: LocalBus, slider: DeviceBridge, caplog: pytest.LogCaptureFixture, action: object, reason: str
) -> None:
    link = MqttLink(bus.client(), RUN, 0)
    link.reset(3)
    link.step(np.array([1.0], dtype=np.float32))
    held = slider.driver
    assert isinstance(held, SimulatedDriver) and held.command.tolist() == [1.0]
    with (
        caplog.at_level(logging.WARNING, logger="fleetrl.link.bridge"),
        pytest.raises(DeviceLinkError) as info,
    ):
        link.step(action)
    assert reason in str(info.value) and reason in caplog.text
    assert held.command.tolist() == [1.0] and slider.stats.rejected == 1  # the refused command did nothing
    link.step(np.array([0.25]))  # the bridge carries on
    assert held.command.tolist() == [0.25]


def test_a_vector_of_another_dtype_is_refused_before_it_is_sent(bus: LocalBus, slider: DeviceBridge) -> None:
    link = MqttLink(bus.client(), RUN, 0)
    link.reset(3)
    with pytest.raises(ValueError, match=r"an action index \(int\) or a 1-D vector of floats"):
        link.step(np.array([1]))  # integers: neither an index nor a float vector
    assert slider.stats.commands == 1 and slider.stats.rejected == 0


def test_the_protective_stop_holds_for_command_vectors(bus: LocalBus, slider: DeviceBridge) -> None:
    link = MqttLink(bus.client(), RUN, 0)
    link.reset(4)
    extras: object = {}
    for _ in range(200):  # full force one way: the slider runs past |x| = 1.5
        obs, extras = link.step(np.array([2.0], dtype=np.float32))
        if extras:
            break
    assert extras == {"protective_stop": 1.0} and obs[0] > 1.5
    held = slider.driver
    assert isinstance(held, SimulatedDriver) and not held.command.any()
    with pytest.raises(DeviceLinkError, match="protective stop"):
        link.step(np.array([-2.0], dtype=np.float32))
    link.reset(5)
    assert link.step(np.array([0.0], dtype=np.float32))[1] == {}
    assert slider.stats.protective_stops == 1


def test_an_observation_of_another_size_than_the_env_declares_is_an_error(
    bus: LocalBus, slider: DeviceBridge
) -> None:
    link = MqttLink(bus.client(), RUN, 0, obs_size=4)  # a QUBE env's link to a slider's bridge
    with pytest.raises(DeviceLinkError, match="sent 2 observation values, the env declares 4"):
        link.reset(1)


def test_a_simulated_device_without_a_spec_is_refused() -> None:
    with pytest.raises(ValueError, match="a simulated SliderDevice needs its DriverSpec"):
        SimulatedDriver(SliderDevice(1.0))


class ShortSensors(SimulatedDriver):
    """A faulty driver: its spec declares 2 sensor values, it reads 1."""

    def read_sensors(self) -> np.ndarray:
        return super().read_sensors()[:1]


def test_a_driver_reading_another_sensor_size_than_declared_is_refused(bus: LocalBus) -> None:
    faulty = ShortSensors(SliderDevice.from_fleet(0, 0), driver_of(driver, 0, 0).spec)
    bridge = serve(bus, faulty)
    try:
        link = MqttLink(bus.client(), RUN, 0)
        link.reset(1)  # the reset's observation comes from home(), which is right
        with pytest.raises(DeviceLinkError, match="driver read 1 sensor values, its spec declares 2"):
            link.step(np.array([0.5], dtype=np.float32))
    finally:
        bridge.close()


def test_a_registered_env_over_a_link_reads_its_spec_without_copying_the_link(
    bus: LocalBus, slider: DeviceBridge
) -> None:
    link = MqttLink(bus.client(), RUN, 0)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # gymnasium warns when it cannot deep-copy the spec's kwargs
        env = gymnasium.make(SLIDER_ID, link=link)
        assert env.spec is not None and env.spec.kwargs["link"] is link
    env.close()
