"""The worked example of a user's own unit type, examples/dc-motor (``fleet_dc_motor``), imported from its
directory (nothing installed): its factory draws each unit from the seeds, its env passes Gymnasium's checks,
its physics holds the steady speed the motor equations give, and a federated fleet of it trains through
fleetrl, on the in-process bus and over an embedded MQTT broker. Its units behind device bridges
(``--device-driver fleet_dc_motor.units:driver``, and ``fleetrl device`` in a process of its own) give the
scores and observations they give in-process."""

from __future__ import annotations

import csv
import json
import math
import re
import threading
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from device_process import device_process
from gymnasium.utils.env_checker import check_env

from fleetrl.cli.main import main
from fleetrl.envs.catalog import get_env_spec
from fleetrl.envs.device_side import check_driver_fits
from fleetrl.link.driver import DriverSpec
from fleetrl.link.mqtt import open_mqtt_link
from fleetrl.transport.broker import EmbeddedBroker

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "dc-motor"
FACTORY = "fleet_dc_motor.units:factory"
DRIVER = "fleet_dc_motor.units:driver"
CLOSED = re.compile(r"bridge for unit (\d+) closed \(BridgeStats\(commands=(\d+), rejected=(\d+)")


@pytest.fixture(autouse=True)
def _in_the_example(monkeypatch: pytest.MonkeyPatch) -> Iterator[None]:
    """The example's directory is the current one (a factory's module is imported from there, in every
    worker process too) and on this process's path."""
    monkeypatch.chdir(EXAMPLE)
    monkeypatch.syspath_prepend(str(EXAMPLE))
    yield


def unit_env(unit: int, fleet_seed: int) -> Any:
    """Unit ``unit`` of fleet ``fleet_seed`` as fleetrl builds it (through the factory seam), unwrapped."""
    return get_env_spec(FACTORY).make(unit, fleet_seed).env.unwrapped


def test_the_example_is_imported_from_its_directory() -> None:
    import fleet_dc_motor

    assert Path(fleet_dc_motor.__file__).resolve().parent == EXAMPLE / "fleet_dc_motor"


def test_units_differ_by_unit_and_fleet_seed_and_are_equal_for_equal_seeds() -> None:
    params = {(u, s): unit_env(u, s).link.device.params for u in (0, 1, 2) for s in (0, 1)}
    assert len(set(params.values())) == 6  # every (unit, fleet seed) its own motor
    assert unit_env(1, 1).link.device.params == params[1, 1]
    from fleet_dc_motor.motor import NOMINAL, SPREAD

    for p in params.values():  # each varying constant within its spread of the nominal motor
        for name, spread in SPREAD.items():
            assert abs(getattr(p, name) / getattr(NOMINAL, name) - 1) <= spread


def test_the_unit_passes_gymnasiums_env_checker_and_fleetrls_seam() -> None:
    built = get_env_spec(FACTORY).make(2, 5)
    check_env(built.env.unwrapped, skip_render_check=True)
    assert built.description.action.kind == "box" and built.description.action.shape == (1,)
    assert built.description.obs_shape == (3,) and built.description.episode_cap == 200
    assert built.description.reward_threshold is not None


def test_a_reset_seed_replays_an_episode_and_a_bad_action_is_refused() -> None:
    def trajectory() -> list[float]:
        env = unit_env(0, 0)
        env.reset(seed=3)
        return [env.step(np.array([0.3 * math.sin(t / 7)], np.float32))[1] for t in range(150)]

    assert trajectory() == trajectory()
    env = unit_env(0, 0)
    env.reset(seed=0)
    with pytest.raises(ValueError, match="one finite duty cycle"):
        env.step(np.array([np.nan], np.float32))


def test_the_motor_settles_at_the_speed_its_equations_give() -> None:
    from fleet_dc_motor.motor import DCMotor, unit_params

    p = unit_params(4, 2)
    motor = DCMotor(p)
    motor.reset(seed=0)
    for _ in range(300):  # 3 s: dozens of time constants
        measured = motor.step(np.array([0.5], np.float32))
    k, r, volts = p.torque_constant, p.resistance, 0.5 * p.supply_volts
    # k·V/R = (k²/R + b)·ω + τc·tanh(ω): solved by bisection on [0, V/k]
    low, high = 0.0, volts / k
    for _ in range(60):
        mid = (low + high) / 2
        residual = (
            k * volts / r - (k * k / r + p.viscous_friction) * mid - p.coulomb_friction * math.tanh(mid)
        )
        low, high = (mid, high) if residual > 0 else (low, mid)
    assert motor.speed == pytest.approx(low, rel=1e-6)
    assert abs(measured[0] - motor.speed) <= 2 * motor.count_angle / motor.period  # encoder resolution
    assert measured[1] == pytest.approx((volts - k * motor.speed) / r)


def episode_score(policy: Callable[[np.ndarray], float]) -> float:
    env = unit_env(1, 0)
    obs, _ = env.reset(seed=0)
    score = 0.0
    for _ in range(200):
        obs, reward, *_ = env.step(np.array([policy(obs)], np.float32))
        score += reward
    return score


def test_the_reward_tells_a_speed_loop_from_an_idle_motor() -> None:
    """A hand-tuned proportional loop with feed-forward tracks far better than a motor left idle."""
    loop = episode_score(lambda obs: float(obs[1] * 0.85 + 3.0 * obs[2]))
    idle = episode_score(lambda obs: 0.0)
    assert loop > 0.2 * idle  # scores are negative: the loop's error is under a fifth of the idle one's


def test_the_env_reads_two_sensor_values_and_a_driver_must_fit_them() -> None:
    """The observation (3 values) is composed from the motor's measurement (2) and the setpoint: the env
    declares its sensor_size, and a driver is checked against that."""
    from fleet_dc_motor.units import SPEC, driver

    description = get_env_spec(FACTORY).make(0, 0).description
    assert (description.obs_dim, description.sensor_dim) == (3, 2)
    served = driver(0, 0)
    check_driver_fits(served.spec, description, "the motor's driver")
    served.close()
    three = DriverSpec("three", (-1.0,), (1.0,), (), SPEC.control_period, 0, 1.0, sensor_size=3)
    with pytest.raises(ValueError, match="declares 3 sensor values; the env reads 2 \\(its sensor_size\\)"):
        check_driver_fits(three, description, "driver 'three'")


def train(out: Path, *argv: str) -> list[dict[str, str]]:
    run = ["train", "--env", FACTORY, "--units", "3", "--mode", "federated", "--preset", "standard"]
    assert main([*run, *argv, "--no-live", "--out", str(out)]) == 0
    assert json.loads((out / "config.json").read_text())["result_settings"]["env"] == FACTORY
    with (out / "metrics.csv").open(newline="") as f:
        return list(csv.DictReader(f))


@pytest.mark.slow
def test_a_federated_fleet_of_motors_trains_on_the_local_bus(tmp_path: Path) -> None:
    rows = train(tmp_path / "run", "--transport", "local", "--max-rounds", "3")
    assert sorted((int(r["worker"]), int(r["round"])) for r in rows) == [
        (w, r) for w in (0, 1, 2) for r in (1, 2, 3)
    ]
    assert all(-400 < float(r["score"]) < 0 for r in rows)  # 200 steps, each −|error| / rated speed


@pytest.mark.slow
@pytest.mark.mqtt
def test_a_federated_fleet_of_motors_trains_over_an_embedded_mqtt_broker(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Each worker process imports the example from the current directory, as a user's would."""
    out = tmp_path / "run"
    rows = train(out, "--max-rounds", "2")
    assert {int(r["worker"]) for r in rows} == {0, 1, 2} and len(rows) == 6
    capsys.readouterr()
    model = str(out / "models" / "worker-2.safetensors")
    assert main(["evaluate", model, "--env", FACTORY, "--unit", "7", "--episodes", "2"]) == 0
    assert len(json.loads(capsys.readouterr().out)["scores"]) == 2


def scores(rows: list[dict[str, str]]) -> list[tuple[int, int, float]]:
    return sorted((int(r["worker"]), int(r["round"]), float(r["score"])) for r in rows)


@pytest.mark.slow
@pytest.mark.mqtt
def test_a_federated_fleet_of_motors_behind_device_bridges_scores_as_in_process(tmp_path: Path) -> None:
    """One process: the chief and 3 workers on the local bus, a bridge thread per motor on an embedded broker
    serving ``driver``; every round of every worker recorded with the in-process run's score, and every
    bridge closed having refused nothing."""
    argv = ("--transport", "local", "--max-rounds", "3", "--quorum", "1")  # every round waits for all 3
    bridged = train(tmp_path / "run", *argv, "--device-link", "mqtt", "--device-driver", DRIVER)
    assert [(w, r) for w, r, _ in scores(bridged)] == [(w, r) for w in (0, 1, 2) for r in (1, 2, 3)]
    assert scores(bridged) == scores(train(tmp_path / "in-process", *argv))
    log = (tmp_path / "run" / "logs" / "run.log").read_text()
    closed = {int(unit): (int(n), int(rejected)) for unit, n, rejected in CLOSED.findall(log)}
    assert sorted(closed) == [0, 1, 2] and all(
        n > 3 * 200 and not rejected for n, rejected in closed.values()
    )
    assert not [t.name for t in threading.enumerate() if t.name.startswith("fleetrl-bridge")]
    config = json.loads((tmp_path / "run" / "config.json").read_text())
    assert config["device_link"] == "mqtt" and config["result_settings"]["device_driver"] == DRIVER


@pytest.mark.slow
@pytest.mark.mqtt
def test_fleetrl_device_serves_a_motor_to_an_env_in_another_process() -> None:
    """``fleetrl device --driver fleet_dc_motor.units:driver`` (a second machine's role) serves unit 2 of
    fleet 4; the env over an MQTT link to it sees what the in-process env sees, step for step."""
    from fleet_dc_motor.units import MotorSpeedEnv

    with EmbeddedBroker() as broker, device_process(broker.url, "motors", DRIVER, 2, 4, EXAMPLE):
        link = open_mqtt_link(broker.url, "motors", 2, obs_size=2, online_timeout=30.0)
        envs = (MotorSpeedEnv(2, 4, link=link), MotorSpeedEnv(2, 4))
        firsts = [env.reset(seed=3)[0] for env in envs]
        assert np.array_equal(*firsts)
        for t in range(120):  # past the setpoint's step at 100
            action = np.array([0.8 * math.sin(t / 9)], dtype=np.float32)
            (obs, reward, *_), (obs_in, reward_in, *_) = (env.step(action) for env in envs)
            assert np.array_equal(obs, obs_in) and reward == reward_in
        for env in envs:
            env.close()
