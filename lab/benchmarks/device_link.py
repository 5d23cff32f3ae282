"""Device link: control-step round trip over MQTT, real-time period jitter, env episodes/s over MQTT links.

Run: ``.venv/bin/python lab/benchmarks/device_link.py`` (``--quick`` for a smoke run). The bridge runs in its
own process (the Raspberry Pi's role), the worker's side in this one, on an embedded broker on loopback
(mosquitto and amqtt): lockstep round trip p50/p99 (action index and command vector), the 6 ms real-time
bridge's tick jitter, and episodes/s of both envs over an MQTT link vs in-process.
"""

from __future__ import annotations

import argparse
import multiprocessing as mp
import time
from typing import Any

import numpy as np

from fleetrl.envs.cartpole_unit import CartPoleUnitEnv
from fleetrl.envs.qube_balance import QubeBalanceEnv
from fleetrl.link.bridge import DeviceBridge
from fleetrl.link.driver import simulated_driver
from fleetrl.link.mqtt import open_mqtt_link
from fleetrl.link.realtime import request_realtime_priority
from fleetrl.transport.broker import EmbeddedBroker, find_mosquitto
from fleetrl.transport.mqtt import MqttTransport

RUN_ID = "bench"


def serve_bridge(url: str, env: str, realtime: bool, stop: Any, ticks: Any, rt_all: bool) -> None:
    """Child process: serve unit 0 until ``stop`` is set; report real-time tick times on ``ticks``.

    A real-time bridge always asks for SCHED_FIFO (as ``fleetrl device --realtime`` does); a lockstep one
    only with ``rt_all``."""
    if realtime or rt_all:
        request_realtime_priority()
    bridge = DeviceBridge(
        MqttTransport(url), simulated_driver(env, 0, 0, realtime=realtime), RUN_ID, 0, realtime=realtime
    )
    bridge.start()
    stop.wait()
    bridge.close()
    ticks.put(list(bridge.tick_times))


class BridgeProcess:
    """A bridge in a child process, as a context manager."""

    rt_all = False
    """also give lockstep bridges real-time priority (``--rt``)"""

    def __init__(self, url: str, env: str = "qube", realtime: bool = False) -> None:
        ctx = mp.get_context("spawn")
        self._stop = ctx.Event()
        self._ticks: Any = ctx.Queue()
        self._proc = ctx.Process(
            target=serve_bridge, args=(url, env, realtime, self._stop, self._ticks, self.rt_all)
        )
        self.ticks: list[float] = []

    def __enter__(self) -> BridgeProcess:
        self._proc.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self._stop.set()
        self.ticks = self._ticks.get(timeout=30)
        self._proc.join(timeout=30)


def step_round_trips(url: str, n: int, vector: bool = False) -> np.ndarray:
    """Seconds per step over a link to unit 0; full power back towards the centre keeps the arm inside its
    limit (``vector``: sent as the command vector ``[±1.44 V]`` instead of the action index 0 or 2)."""
    link = open_mqtt_link(url, RUN_ID, 0)
    obs = link.reset(0)
    times = np.empty(n + 200)
    volts = [np.array([-1.44], dtype=np.float32), np.array([1.44], dtype=np.float32)]
    for i in range(n + 200):  # the first 200 are a warm-up
        back = obs[2] > 0.0
        action = volts[0 if back else 1] if vector else (0 if back else 2)
        start = time.perf_counter()
        obs, _ = link.step(action)
        times[i] = time.perf_counter() - start
    link.close()
    return times[200:]


def round_trip(url: str, n: int, vector: bool = False) -> dict[str, float]:
    """p50/p99 of a lockstep control step over MQTT (µs)."""
    with BridgeProcess(url):
        times = step_round_trips(url, n, vector)
    return {"p50_us": 1e6 * np.percentile(times, 50), "p99_us": 1e6 * np.percentile(times, 99)}


def realtime_jitter(url: str, seconds: float) -> dict[str, float]:
    """Tick-interval error of a real-time bridge at 6 ms while a worker steps it (ms)."""
    with BridgeProcess(url, realtime=True) as bridge:
        steps = step_round_trips(url, int(seconds / 0.006))
    intervals = np.diff(np.asarray(bridge.ticks))
    error = np.abs(intervals - 0.006)
    return {
        "ticks": float(len(intervals)),
        "interval_mean_ms": 1e3 * float(intervals.mean()),
        "jitter_p50_ms": 1e3 * float(np.percentile(error, 50)),
        "jitter_p99_ms": 1e3 * float(np.percentile(error, 99)),
        "jitter_max_ms": 1e3 * float(error.max()),
        "worker_step_p50_ms": 1e3 * float(np.percentile(steps, 50)),
    }


def episodes_per_second(env: Any, seconds: float, seed: int = 0) -> dict[str, float]:
    """Random-action episodes (seeded) for about ``seconds``; episodes/s and steps/s."""
    rng = np.random.default_rng(seed)
    n_actions = int(env.action_space.n)
    env.reset(seed=seed)
    episodes = steps = 0
    start = time.perf_counter()
    while time.perf_counter() - start < seconds:
        env.reset()
        terminated = False
        while not terminated and steps < 10**7:
            terminated = env.step(int(rng.integers(n_actions)))[2]
            steps += 1
        episodes += 1
    elapsed = time.perf_counter() - start
    return {"episodes_per_s": episodes / elapsed, "steps_per_s": steps / elapsed}


def env_speed(url: str, seconds: float) -> dict[str, dict[str, float]]:
    """Episodes/s of both envs over an MQTT link vs in-process."""
    out: dict[str, dict[str, float]] = {}
    for name, env_cls in [("qube", QubeBalanceEnv), ("cartpole", CartPoleUnitEnv)]:
        out[f"{name} in-process"] = episodes_per_second(env_cls(0, 0), seconds)
        with BridgeProcess(url, name):
            env = env_cls(0, 0, link=open_mqtt_link(url, RUN_ID, 0))
            out[f"{name} mqtt"] = episodes_per_second(env, seconds)
            env.close()
    return out


def main() -> None:
    """Run every figure on each available broker and print them."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="tiny budgets (smoke run)")
    parser.add_argument(
        "--rt", action="store_true", help="SCHED_FIFO for this (worker) process and every bridge, as on a rig"
    )
    args = parser.parse_args()
    if args.rt:
        BridgeProcess.rt_all = request_realtime_priority()
    n, seconds = (300, 0.5) if args.quick else (3000, 2.0)
    brokers = (["mosquitto"] if find_mosquitto() else []) + ["amqtt"]
    for kind in brokers:
        with EmbeddedBroker(kind) as broker:
            for what, vector in [("action index", False), ("command vector", True)]:
                rt = round_trip(broker.url, n, vector)
                print(
                    f"[{kind}] control-step round trip over {n} steps, {what}: p50 {rt['p50_us']:.0f} µs, "
                    f"p99 {rt['p99_us']:.0f} µs"
                )
            jit = realtime_jitter(broker.url, seconds)
            print(
                f"[{kind}] real-time 6 ms: {jit['ticks']:.0f} ticks, mean interval "
                f"{jit['interval_mean_ms']:.3f} ms, |interval-6 ms| p50 {jit['jitter_p50_ms']:.3f} ms, "
                f"p99 {jit['jitter_p99_ms']:.3f} ms, max {jit['jitter_max_ms']:.3f} ms; worker step p50 "
                f"{jit['worker_step_p50_ms']:.2f} ms"
            )
            for label, figures in env_speed(broker.url, seconds).items():
                print(
                    f"[{kind}] {label}: {figures['episodes_per_s']:.0f} episodes/s "
                    f"({figures['steps_per_s']:.0f} steps/s, random actions)"
                )


if __name__ == "__main__":
    main()
