"""Device bridges through real brokers: lockstep trajectories equal in-process ones (mosquitto and amqtt),
the watchdog stops the motor when the worker process is killed, and the ``fleetrl device`` command line."""

from __future__ import annotations

import argparse
import os
import signal
import subprocess
import sys
import textwrap
import time

import pytest
from trajectory_helpers import assert_same, run_episodes

from fleetrl.cli.device_command import register
from fleetrl.envs.cartpole_unit import CartPoleUnitEnv
from fleetrl.envs.qube_balance import QubeBalanceEnv
from fleetrl.link.bridge import DeviceBridge
from fleetrl.link.driver import SimulatedDriver, simulated_driver
from fleetrl.link.fleet import start_bridges
from fleetrl.link.mqtt import open_mqtt_link
from fleetrl.transport.broker import EmbeddedBroker
from fleetrl.transport.mqtt import MqttTransport

pytestmark = pytest.mark.mqtt


def test_lockstep_over_mqtt_gives_the_in_process_trajectory(broker: EmbeddedBroker) -> None:
    run_id = f"same-{broker.kind}"
    with (
        start_bridges(broker.url, run_id, "qube", [0, 1], fleet_seed=4),
        start_bridges(broker.url, run_id, "cartpole", [5], fleet_seed=4),
    ):
        for unit, env_cls in [(0, QubeBalanceEnv), (1, QubeBalanceEnv), (5, CartPoleUnitEnv)]:
            # the trajectory is under test, not the latency: a loaded machine gets 10 s per step
            link = open_mqtt_link(broker.url, run_id, unit, step_timeout=10.0)
            over_mqtt = env_cls(unit, 4, link=link)
            in_process = env_cls(unit, 4)
            expected = run_episodes(in_process, 2, 200, seed=unit)
            assert_same(run_episodes(over_mqtt, 2, 200, seed=unit), expected)
            over_mqtt.close()


WORKER = textwrap.dedent(
    """
    import sys
    from fleetrl.link.mqtt import open_mqtt_link
    link = open_mqtt_link(sys.argv[1], "kill", 0)
    link.reset(1)
    print("stepping", flush=True)
    while True:
        link.step(1)  # 0 V: a worker stalled with full power held would drive the arm to its limit
    """
)


@pytest.mark.mosquitto
def test_watchdog_stops_the_motor_when_the_worker_process_is_killed() -> None:
    # a worker process stalled for longer than the watchdog on a loaded machine trips it before the kill as
    # well (harmless: the next command switches the motor on again), so trips are counted from the kill on
    watchdog = 0.2
    with EmbeddedBroker("mosquitto") as broker:
        driver = simulated_driver("qube", 0, 0, realtime=True)
        bridge = DeviceBridge(MqttTransport(broker.url), driver, "kill", 0, realtime=True, watchdog=watchdog)
        bridge.start()
        worker = subprocess.Popen(
            [sys.executable, "-c", WORKER, broker.url], stdout=subprocess.PIPE, text=True
        )
        try:
            assert worker.stdout is not None and worker.stdout.readline() == "stepping\n"
            deadline = time.monotonic() + 5
            while bridge.stats.commands < 20 and time.monotonic() < deadline:
                time.sleep(0.01)
            assert bridge.motor_on
            trips_before = bridge.stats.watchdog_trips
            os.kill(worker.pid, signal.SIGKILL)  # no MQTT DISCONNECT: the commands just stop
            killed = time.perf_counter()
            while bridge.motor_on and time.perf_counter() - killed < 2.0:
                time.sleep(0.001)
            stopped_after = time.perf_counter() - killed
        finally:
            worker.kill()
            worker.wait()
            bridge.close()
    assert isinstance(driver, SimulatedDriver) and not driver.command.any()
    assert bridge.stats.watchdog_trips == trips_before + 1 and bridge.stats.protective_stops == 0
    assert stopped_after < watchdog + 0.5  # the watchdog's doing, not the 2 s give-up


def test_device_command_line_parses() -> None:
    parser = argparse.ArgumentParser(prog="fleetrl")
    register(parser.add_subparsers(dest="command"))
    args = parser.parse_args(
        [
            "device",
            "--broker",
            "mqtt://127.0.0.1:1",
            "--run-id",
            "r",
            "--unit",
            "2",
            "--realtime",
            "--period-ms",
            "6",
        ]
    )
    assert (args.broker, args.run_id, args.unit, args.env, args.realtime, args.period_ms) == (
        "mqtt://127.0.0.1:1",
        "r",
        2,
        None,  # the simulated driver's default, qube
        True,
        6.0,
    )
    assert callable(args.handler)
