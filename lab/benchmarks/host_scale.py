"""Unit hosts at scale: a CartPole fleet of N units with and without hosts, in this process.

    python lab/benchmarks/host_scale.py [--units 8 64 256] [--rounds 3] [--per-host 0]
                                        [--part acting|train|all] [--kinds flat host]
                                        [--set KEY=VALUE ...] [--transport local|mqtt]
                                        [--policy MODEL]

acting: unit-steps per second (per wall and per CPU second) of the units' first ``--rounds`` episodes, N
learners of one unit each against hosts of ``--per-host`` units (0: one host of all N; fewer: that many host
processes playing at once), every unit on ``--policy``'s weights if given. train: ``fleetrl train --env
cartpole --mode federated --preset standard --seed 3`` per configuration in a fresh process: seconds per
round (rounds 2 … R), unit-steps per second including updates and exchanges, peak memory. The load average is
printed around each measurement (the machine is shared).
"""

from __future__ import annotations

import argparse
import csv
import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

SEED = 3


def load() -> str:
    """The 1-minute load average and the cores (the machine is shared)."""
    return f"load {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores"


def acting(
    units: int,
    rounds: int,
    hosted: bool,
    policy: str | None = None,
    first: int = 0,
    start_at: float | None = None,
) -> dict[str, float]:
    """Unit-steps per second of ``rounds`` episodes of every unit (ids ``first`` …), no update; every unit
    on the weights of the model file ``policy`` if given; the timed part starts at the wall-clock time
    ``start_at`` if given (after the warm-up)."""
    import gymnasium
    import torch

    from fleetrl.agent.checkpoint import read_checkpoint
    from fleetrl.agent.config import get_preset
    from fleetrl.agent.criterion import CompletionCriterion
    from fleetrl.agent.learner import Learner
    from fleetrl.agent.ppo import PPOAgent
    from fleetrl.envs.registration import CARTPOLE_UNIT_ID

    torch.set_num_threads(1)
    config = get_preset("standard")
    ids = range(first, first + units)
    envs = [gymnasium.make(CARTPOLE_UNIT_ID, unit=u, fleet_seed=0) for u in ids]
    seeds = [SEED * 100_000 + u for u in ids]
    weights = None if policy is None else read_checkpoint(policy)[0]  # read once, whatever the units
    if hosted:
        agent = PPOAgent(4, 2, config, seeds)
        if weights is not None:
            agent.load_weights(weights, str(policy))
        learners = [Learner(envs, agent, [CompletionCriterion(1e9) for _ in envs], seeds)]
    else:
        learners = [
            Learner(env, PPOAgent(4, 2, config, seed=s), CompletionCriterion(1e9), seed=s)
            for env, s in zip(envs, seeds, strict=True)
        ]
        for learner in learners if weights is not None else ():
            learner.agent.load_weights(weights, str(policy))
    learners[0].play_episodes()  # compile and warm up
    if hosted and start_at is not None:
        time.sleep(max(0.0, start_at - time.time()))
    began = time.time()
    started, cpu = time.perf_counter(), time.process_time()
    steps = 0
    for _ in range(rounds):
        steps += sum(sum(e.steps) for learner in learners for e in learner.play_episodes())
    seconds, cpu_seconds = time.perf_counter() - started, time.process_time() - cpu
    return {"unit_steps": steps, "seconds": seconds, "unit_steps_per_s": steps / seconds,
            "unit_steps_per_cpu_s": steps / cpu_seconds, "began": began, "ended": time.time()}  # fmt: skip


WARM_UP_S = 30.0
"""how long the host processes of :func:`acting_hosts` are given to start, build their units and warm up
before they play together"""


def acting_hosts(units: int, per_host: int, rounds: int, policy: str | None) -> dict[str, float]:
    """:func:`acting` in ``units / per_host`` processes of ``per_host`` units each, playing at the same
    time: every host's unit-steps over the wall time from the first one's start to the last one's end."""
    if units % per_host:
        raise SystemExit(f"--per-host {per_host} must divide --units {units}")
    start_at = time.time() + WARM_UP_S
    hosts = [
        in_child(f"acting({per_host}, {rounds}, True, {policy!r}, {first}, {start_at!r})")
        for first in range(0, units, per_host)
    ]
    results = [child_result(host, "a host process") for host in hosts]
    late = max(r["began"] for r in results) - start_at
    if late > 0.5:
        print(f"  (a host started {late:.1f} s late: its warm-up outlasted {WARM_UP_S:.0f} s)")
    steps = sum(r["unit_steps"] for r in results)
    seconds = max(r["ended"] for r in results) - min(r["began"] for r in results)
    cpu_seconds = sum(r["unit_steps"] / r["unit_steps_per_cpu_s"] for r in results)
    return {"unit_steps": steps, "seconds": seconds, "unit_steps_per_s": steps / seconds,
            "unit_steps_per_cpu_s": steps / cpu_seconds}  # fmt: skip


def train_once(
    units: int, rounds: int, per_host: int, overrides: tuple[str, ...] = (), transport: str = "local"
) -> dict[str, float]:
    """One ``fleetrl train`` run in this process (1: flat); its figures and this process's peak memory (with
    ``transport='mqtt'`` the hosts are processes of their own, not counted in it)."""
    from fleetrl.cli.main import main
    from fleetrl.runs import plots

    plots.plot_run = lambda *args, **kwargs: None  # one panel per unit: minutes for 1000 units
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "run"
        argv = ["train", "--env", "cartpole", "--units", str(units), "--mode", "federated",
                "--transport", transport, "--preset", "standard", "--seed", str(SEED), "--max-rounds",
                str(rounds), "--no-live", "--target-score", "1e9", "--units-per-host", str(per_host),
                "--out", str(out)] + [a for o in overrides for a in ("--set", o)]  # fmt: skip
        started = time.perf_counter()
        code = main(argv)
        seconds = time.perf_counter() - started
        if code != 0:
            raise SystemExit(f"fleetrl train exited {code}")
        with (out / "metrics.csv").open() as f:
            rows = list(csv.DictReader(f))
    done = max(int(r["round"]) for r in rows)
    if done < 2:
        raise SystemExit("measure at least 2 rounds: the first one's end is where the timing starts")
    ends = {n: max(float(r["wall_time"]) for r in rows if int(r["round"]) == n) for n in (1, done)}
    timed = (ends[done] - ends[1]) / (done - 1)  # rounds 2 … R: no start-up, no first compile
    steps = sum(int(r["steps"]) for r in rows if int(r["round"]) > 1)
    peak_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    return {"rounds": done, "seconds_per_round": timed, "unit_steps": steps, "whole_run_s": seconds,
            "unit_steps_per_s": steps / (timed * (done - 1)), "peak_mb": peak_mb}  # fmt: skip


def train(
    units: int, rounds: int, per_host: int, overrides: tuple[str, ...] = (), transport: str = "local"
) -> dict[str, float]:
    """:func:`train_once` in a fresh process (its own peak memory, its own imports)."""
    call = f"train_once({units}, {rounds}, {per_host}, {overrides!r}, {transport!r})"
    return child_result(in_child(call, stderr=subprocess.PIPE), "fleetrl train's process")


def in_child(call: str, **popen: Any) -> subprocess.Popen[str]:
    """``host_scale.CALL`` in a fresh Python process, which prints its result as JSON."""
    code = f"import json, host_scale; print(json.dumps(host_scale.{call}))"
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(Path(__file__).parent), *sys.path])}
    return subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE, text=True, env=env, **popen)


def child_result(child: subprocess.Popen[str], what: str) -> dict[str, float]:
    """The result :func:`in_child`'s process printed last."""
    out, _ = child.communicate()
    if child.returncode != 0:
        raise SystemExit(f"{what} exited {child.returncode}")
    result: dict[str, float] = json.loads(out.strip().splitlines()[-1])
    return result


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--units", type=int, nargs="+", default=[8, 64, 256])
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--per-host", type=int, default=0, help="units per host (0: one host of all)")
    parser.add_argument("--part", choices=("acting", "train", "all"), default="all")
    parser.add_argument("--kinds", nargs="+", choices=("flat", "host"), default=["flat", "host"])
    parser.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                        help="a preset override for --part train (repeatable)")  # fmt: skip
    parser.add_argument("--transport", choices=("local", "mqtt"), default="local")
    parser.add_argument("--policy", help="--part acting: the model file every unit plays")
    args = parser.parse_args()
    for units in args.units:
        for name in args.kinds:
            hosted = name == "host"
            per_host = (args.per_host or units) if hosted else 1
            label = f"N={units:5d} {name:4s} (U={per_host})"
            if args.part in ("acting", "all"):
                before = load()
                if hosted and per_host < units:
                    r = acting_hosts(units, per_host, args.rounds, args.policy)
                else:
                    r = acting(units, args.rounds, hosted, args.policy)
                print(f"{label} acting: {r['unit_steps_per_s']:9.0f} unit-steps/s, "
                      f"{r['unit_steps_per_cpu_s']:9.0f} per CPU-second ({r['unit_steps']} in "
                      f"{r['seconds']:.2f} s)  [{before} -> {load()}]", flush=True)  # fmt: skip
            if args.part in ("train", "all"):
                before = load()
                t = train(units, args.rounds, per_host, tuple(args.overrides), args.transport)
                print(f"{label} train: {t['seconds_per_round']:7.2f} s/round, {t['unit_steps_per_s']:8.0f} "
                      f"unit-steps/s incl. updates, peak {t['peak_mb']:.0f} MB over {t['rounds']} rounds  "
                      f"[{before} -> {load()}]", flush=True)  # fmt: skip


if __name__ == "__main__":
    main()
