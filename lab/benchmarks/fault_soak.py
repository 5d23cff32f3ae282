"""Fault soak: many small federated CartPole runs (``fleetrl`` chief and worker processes over one mosquitto),
each with one random fault at a random moment, and the books checked after (exit codes, rounds lost or
duplicated, the chief's drops, with ``--one-policy`` one policy at every exchange). docs/benchmarks.md,
"Fault soak", has the rules and results.

    python lab/benchmarks/fault_soak.py --runs 50 --out /tmp/fault-soak
    python lab/benchmarks/fault_soak.py --runs 50 --workers 3 --uneven "--slow w1=4 --absent 0.2"
    python lab/benchmarks/fault_soak.py --runs 2 --one-policy --uneven "--slow w1=4" --mutate skip # fails
"""

from __future__ import annotations

import argparse
import csv
import json
import os
import random
import shlex
import signal
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

from one_policy import MUTATIONS, compare, load

from fleetrl.transport.broker import find_mosquitto, free_port, mqtt_ready

ONE_POLICY = Path(__file__).resolve().parent / "one_policy.py"

FAULTS = ("worker-resumed", "worker-gone", "chief-resumed", "broker-restarted", "worker-added")
GRACE = 15.0
"""the chief's --dropout-grace by default: it must be longer than a worker's restart for a resumed worker to
keep its place in W (a restart that takes longer loses the rounds played without it)"""
RUN_TIMEOUT = 180.0

ADDED_ROUNDS_LEFT = 5
"""rounds an added worker has at least, after the moment it is started"""


class Broker:
    """mosquitto as a child process on a fixed port (so it can be killed and restarted in place)."""

    def __init__(self, directory: Path) -> None:
        self.port = free_port()
        self.config = directory / "mosquitto.conf"
        self.config.write_text(
            f"listener {self.port} 127.0.0.1\nallow_anonymous true\nset_tcp_nodelay true\npersistence false\n"
        )
        self.proc: subprocess.Popen[bytes] | None = None

    @property
    def url(self) -> str:
        return f"mqtt://127.0.0.1:{self.port}"

    def start(self) -> None:
        binary = find_mosquitto()
        assert binary, "mosquitto not installed"
        self.proc = subprocess.Popen([binary, "-c", str(self.config)], stderr=subprocess.DEVNULL)
        deadline = time.monotonic() + 15
        while not mqtt_ready("127.0.0.1", self.port):
            assert time.monotonic() < deadline, "mosquitto did not start"
            time.sleep(0.01)

    def kill9(self) -> None:
        assert self.proc is not None
        self.proc.kill()
        self.proc.wait()

    def stop(self) -> None:
        if self.proc is not None and self.proc.poll() is None:
            self.proc.terminate()
            self.proc.wait(10)


@dataclass
class Outcome:
    """One run of the soak."""

    run: int
    fault: str
    victim: str
    after_round: int
    completed: bool = False
    lost: int = 0
    duplicated: int = 0
    chief_agrees: bool = True
    same_model: bool | None = None
    one_policy: bool | None = None
    """no worker off the fleet's policy at any exchange (None: not checked, or no catch-up to check)"""
    one_policy_summary: str = ""
    recovery_s: float | None = None
    wall_s: float = 0.0
    notes: list[str] = field(default_factory=list)


class Run:
    """The chief and the workers of one run, as ``fleetrl`` processes."""

    def __init__(self, index: int, broker: Broker, out: Path, args: Any, recorder: list[str] | None) -> None:
        self.index, self.broker, self.out, self.rounds = index, broker, out, args.rounds
        self.grace, self.workers, self.uneven = args.grace, args.workers, shlex.split(args.uneven)
        self.recorder = recorder
        """one_policy.py's flags before a worker's: record its holdings (None: run fleetrl plainly)"""
        self.run_id = f"soak-{index}"
        self.procs: dict[str, subprocess.Popen[bytes]] = {}
        self.common = ["--broker", broker.url, "--run-id", self.run_id, "--env", "cartpole"]
        self.common += ["--preset", "standard", "--max-rounds", str(self.rounds), "--connect-timeout", "60"]

    def start(self, role: str, *extra: str) -> None:
        if role == "chief":
            argv = ["chief", "--workers", str(self.workers), "--dropout-grace", str(self.grace)]
            argv += ["--idle-timeout", "120", "--out", str(self.out / "chief")]
        else:
            argv = ["worker", "--worker-id", role, "--seed", str(self.index)]
            argv += ["--out", str(self.out / f"w{role}"), *self.uneven]
        log = (self.out / f"{role}.log").open("ab")
        command = [sys.executable, "-m", "fleetrl.cli.main"]
        if role != "chief" and self.recorder is not None:
            digests = str(self.out / f"w{role}.digests.jsonl")
            command = [sys.executable, str(ONE_POLICY), "--digests", digests, *self.recorder, "--"]
        self.procs[role] = subprocess.Popen(
            [*command, *argv, *self.common, *extra],
            stdout=log, stderr=subprocess.STDOUT, start_new_session=True,
        )  # fmt: skip
        log.close()

    def kill9(self, role: str) -> None:
        proc = self.procs[role]
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait()

    def closed_rounds(self) -> int:
        """The last round the chief closed, from its log."""
        return max((r for rounds in self.answered().values() for r in rounds), default=0)

    def answered(self) -> dict[str, set[int]]:
        """Per worker, the rounds in which the chief's log lists it as answering an exchange."""
        path = self.out / "chief" / "chief.log"
        out: dict[str, set[int]] = {}
        for line in path.read_text().splitlines() if path.exists() else ():
            if ": answered " in line:
                rnd = int(line.split()[1].rstrip(":"))
                for worker in line.split(": answered ")[1].split(";")[0].split(","):
                    out.setdefault(worker.strip(), set()).add(rnd)
        return out

    def worker_rounds(self, worker: str) -> list[int]:
        path = self.out / f"w{worker}" / "metrics.csv"
        if not path.exists():
            return []
        with path.open(newline="") as handle:
            return [int(r["round"]) for r in csv.DictReader(handle) if r.get("round")]

    def wait(self, done: Callable[[], bool], timeout: float) -> bool:
        deadline = time.monotonic() + timeout
        while not done():
            if time.monotonic() > deadline:
                return False
            time.sleep(0.05)
        return True

    def stop_all(self) -> None:
        for proc in self.procs.values():
            if proc.poll() is None:
                proc.kill()
                proc.wait()


def soak_one(index: int, fault: str, rng: random.Random, broker: Broker, root: Path, args: Any) -> Outcome:
    """One run with one fault; the books checked after."""
    out = root / f"run-{index:03d}"
    out.mkdir(parents=True)
    rounds, workers = args.rounds, args.workers
    recorder = (["--mutate", args.mutate] if args.mutate else []) if args.one_policy else None
    run = Run(index, broker, out, args, recorder)
    victim = {"chief-resumed": "chief", "broker-restarted": "broker"}.get(fault) or str(
        workers if fault == "worker-added" else rng.randrange(workers)
    )
    # an added unit needs rounds left to join (a process starts in seconds, a CartPole round may take one)
    last = max(1, rounds - (ADDED_ROUNDS_LEFT if fault == "worker-added" else 2))
    outcome = Outcome(index, fault, victim, after_round=rng.randint(1, last))
    started = time.monotonic()
    try:
        run.start("chief")
        for k in range(workers):
            run.start(str(k))
        progress = (  # a straggler's own rounds may lag far behind: an uneven fleet goes by the chief's
            (lambda: len(run.worker_rounds(victim)) >= outcome.after_round)
            if victim.isdigit() and fault != "worker-added" and not args.uneven
            else (lambda: run.closed_rounds() >= outcome.after_round)
        )
        if not run.wait(progress, RUN_TIMEOUT):
            outcome.notes.append("the fault's moment never came")
            return outcome
        time.sleep(rng.uniform(0.0, 0.3))
        before = run.closed_rounds()
        finished_by_victim = len(run.worker_rounds(victim)) if victim.isdigit() else 0
        struck = time.monotonic()
        if fault == "broker-restarted":
            broker.kill9()
            time.sleep(rng.uniform(0.5, 2.0))
            broker.start()
        elif fault == "worker-added":
            run.start(victim)
        else:
            run.kill9(victim)
            if fault != "worker-gone":
                run.start(victim, "--resume")
        recovered = min(before + 2, rounds)  # two more rounds closed: the one the fault hit, and the next
        if run.wait(lambda: run.closed_rounds() >= recovered, RUN_TIMEOUT):
            outcome.recovery_s = round(time.monotonic() - struck, 2)
        alive = [r for r in run.procs if not (fault == "worker-gone" and r == victim)]
        ended = run.wait(lambda: all(run.procs[r].poll() is not None for r in alive), RUN_TIMEOUT)
        codes = {r: run.procs[r].poll() for r in alive}
        outcome.completed = ended and all(code == 0 for code in codes.values())
        if not outcome.completed:
            outcome.notes.append(f"exit codes {codes}")
        check_books(run, outcome, finished_by_victim, synchronous=not args.uneven and workers <= 2)
        if args.one_policy:
            outcome.same_model = holds_fleet_model(
                out / "chief", {w: out / f"w{w}" for w in alive if w.isdigit()}
            )
            held = compare(load(out.glob("w*.digests.jsonl")))
            outcome.one_policy = False if held.mismatches else (True if held.after_catch_up else None)
            outcome.one_policy_summary = held.summary()
    finally:
        run.stop_all()
        outcome.wall_s = round(time.monotonic() - started, 1)
    return outcome


def holds_fleet_model(chief_out: Path, worker_outs: dict[str, Path]) -> bool:
    """Every worker's final network (worker id → its ``--out``) equals, bit for bit, the fleet model in the
    checkpoint of the chief whose ``--out`` is ``chief_out``."""
    import numpy as np

    from fleetrl.agent.ppo import PPOAgent
    from fleetrl.runs.checkpoints import ChiefCheckpoint, chief_checkpoint_dir
    from fleetrl.runs.rundir import model_path

    _, tensors = ChiefCheckpoint(chief_checkpoint_dir(chief_out)).store.load()
    chief = tensors.get("model")
    for worker, out in worker_outs.items():
        path = model_path(out, int(worker))
        if chief is None or not path.exists():
            return False
        mine = PPOAgent.load(path).model_parameters()
        if not np.array_equal(mine, chief[: mine.size]):
            return False
    return True


def check_books(run: Run, outcome: Outcome, finished_by_victim: int, synchronous: bool) -> None:
    """Rounds lost or duplicated, per worker, against the chief's record (chief.json, chief.log)."""
    chief_json = run.out / "chief" / "chief.json"
    if not chief_json.exists():
        outcome.chief_agrees = False
        outcome.notes.append("no chief.json")
        return
    chief = json.loads(chief_json.read_text())
    last = int(chief["rounds"])
    dropped = {d["worker"]: int(d["round"]) for d in chief["dropouts"]}
    answered = run.answered()
    for worker in (r for r in run.procs if r.isdigit()):  # the fleet's workers and an added one
        rounds = run.worker_rounds(worker)
        gone = outcome.fault == "worker-gone" and worker == outcome.victim
        outcome.duplicated += len(rounds) - len(set(rounds))
        took_part = {r for r in answered.get(worker, set()) if not gone or r <= finished_by_victim}
        outcome.lost += len(took_part - set(rounds))
        if not synchronous or (outcome.fault == "worker-added" and worker == outcome.victim):
            continue  # a unit added mid-run holds the rounds from its welcome on
        expected = set(range(1, (finished_by_victim if gone else last) + 1))
        outcome.lost += len(expected - set(rounds) - took_part)
        if gone:
            drop = dropped.get(worker)
            if drop is None or not finished_by_victim + 1 <= drop <= finished_by_victim + 2:
                outcome.chief_agrees = False
                outcome.notes.append(
                    f"worker {worker} finished {finished_by_victim} rounds, dropped at {drop}"
                )
        elif worker in dropped:
            outcome.chief_agrees = False
            outcome.notes.append(f"worker {worker} was dropped at round {dropped[worker]}")
        elif max(rounds, default=0) != last:
            outcome.chief_agrees = False
            outcome.notes.append(
                f"worker {worker} ended at round {max(rounds, default=0)}, the chief at {last}"
            )


def report(outcomes: list[Outcome], seconds: float) -> str:
    """The figures, as a Markdown table."""
    lines = [
        "| fault | runs | completed | rounds lost | rounds duplicated | chief's record agrees "
        "| final models = the chief's | one policy at every exchange, after catch-ups | longest recovery |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for fault in (*FAULTS, "all"):
        group = [o for o in outcomes if fault in ("all", o.fault)]
        recoveries = [o.recovery_s for o in group if o.recovery_s is not None]
        longest = f"{max(recoveries):.1f} s" if recoveries else "-"
        models = [o.same_model for o in group if o.same_model is not None]
        same = f"{sum(models)}/{len(models)}" if models else "-"
        checked = [o.one_policy for o in group if o.one_policy is not None]
        vacuous = sum(o.one_policy is None and bool(o.one_policy_summary) for o in group)
        policy = f"{sum(checked)}/{len(checked)}" if checked else "-"
        policy += f" ({vacuous} without a catch-up)" if vacuous else ""
        lines.append(
            f"| {fault} | {len(group)} | {sum(o.completed for o in group)} | {sum(o.lost for o in group)} | "
            f"{sum(o.duplicated for o in group)} | {sum(o.chief_agrees for o in group)} | {same} "
            f"| {policy} | {longest} |"
        )
    lines.append(f"\n{len(outcomes)} runs in {seconds / 60:.1f} min")
    return "\n".join(lines)


def main() -> int:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--runs", type=int, default=50)
    parser.add_argument("--workers", type=int, default=2, help="workers per run (default 2)")
    parser.add_argument("--uneven", default="", help="more flags for every worker, quoted")
    parser.add_argument(
        "--one-policy",
        action="store_true",
        help="check every worker's final model equals the chief's, and every worker holds the same policy "
        "at every exchange (pergrad)",
    )
    parser.add_argument(
        "--mutate",
        choices=MUTATIONS,
        default=None,
        help="break every worker's catch-up on purpose (implies --one-policy): the check must fail",
    )
    parser.add_argument("--rounds", type=int, default=8, help="M of every run (default 8)")
    parser.add_argument("--seed", type=int, default=0, help="seed of the faults and their moments")
    parser.add_argument(
        "--grace", type=float, default=GRACE, help=f"the chief's --dropout-grace ({GRACE:g}s)"
    )
    parser.add_argument("--out", type=Path, default=None, help="directory for the runs and soak.json")
    parser.add_argument("--faults", default=None, help=f"the kinds to draw from ({','.join(FAULTS)})")
    args = parser.parse_args()
    args.one_policy = args.one_policy or args.mutate is not None
    kinds = args.faults.split(",") if args.faults else list(FAULTS)
    if unknown := set(kinds) - set(FAULTS):
        parser.error(f"unknown fault(s) {sorted(unknown)} (choose from {', '.join(FAULTS)})")
    root = args.out or Path(tempfile.mkdtemp(prefix="fleetrl-soak-"))
    root.mkdir(parents=True, exist_ok=True)
    rng = random.Random(args.seed)
    broker = Broker(root)
    broker.start()
    outcomes: list[Outcome] = []
    started = time.monotonic()
    try:
        for index in range(args.runs):
            outcome = soak_one(index, rng.choice(kinds), rng, broker, root, args)
            outcomes.append(outcome)
            print(json.dumps(asdict(outcome)), flush=True)
            (root / "soak.json").write_text(json.dumps([asdict(o) for o in outcomes], indent=1))
    finally:
        broker.stop()
    print(report(outcomes, time.monotonic() - started))
    bad = [
        o for o in outcomes
        if not o.completed or o.lost or o.duplicated or not o.chief_agrees or o.same_model is False
        or o.one_policy is False
    ]  # fmt: skip
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
