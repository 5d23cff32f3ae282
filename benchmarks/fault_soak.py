"""Fault soak: many small federated CartPole runs (real PPO learners; chief and workers are separate
``fleetrl`` processes over one mosquitto), each with one random fault at a random moment; the books are
checked after.

Faults, one per run, chosen at random: kill -9 of a random worker that is restarted with ``--resume``; kill -9
of a random worker that stays dead; kill -9 of the chief, restarted with ``--resume``; kill -9 of the broker,
restarted. The moment is after a random round (1 … M-2) of the killed role, plus a random 0-0.3 s.

Checked per run: every role that ran to the end exited 0; every surviving or restarted worker's metrics.csv
holds rounds 1 … n exactly once, n being the chief's last round (chief.json); a worker killed for good holds
every round it had finished, exactly once, and the chief dropped it in the round after (or the one after that,
if its last message had closed a round before it died). Recovery: seconds from the fault until the chief has
closed two more rounds (the one the fault hit and the next), or the run ended.

    python benchmarks/fault_soak.py --runs 50 --out /tmp/fault-soak      # see docs/benchmarks.md
"""

from __future__ import annotations

import argparse
import csv
import json
import os
import random
import signal
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from pathlib import Path

from fleetrl.transport.broker import find_mosquitto, free_port, mqtt_ready

FAULTS = ("worker-resumed", "worker-gone", "chief-resumed", "broker-restarted")
WORKERS = 2
GRACE = 15.0
"""the chief's --dropout-grace by default: it must be longer than a worker's restart for a resumed worker to
keep its place in W (a restart that takes longer loses the rounds played without it)"""
RUN_TIMEOUT = 180.0


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
    recovery_s: float | None = None
    wall_s: float = 0.0
    notes: list[str] = field(default_factory=list)


class Run:
    """The chief and the workers of one run, as ``fleetrl`` processes."""

    def __init__(self, index: int, broker: Broker, out: Path, rounds: int, grace: float) -> None:
        self.index, self.broker, self.out, self.rounds, self.grace = index, broker, out, rounds, grace
        self.run_id = f"soak-{index}"
        self.procs: dict[str, subprocess.Popen[bytes]] = {}
        self.common = ["--broker", broker.url, "--run-id", self.run_id, "--env", "cartpole"]
        self.common += ["--preset", "standard", "--max-rounds", str(rounds), "--connect-timeout", "60"]

    def start(self, role: str, *extra: str) -> None:
        if role == "chief":
            argv = ["chief", "--workers", str(WORKERS), "--dropout-grace", str(self.grace)]
            argv += ["--idle-timeout", "120"]
            argv += ["--out", str(self.out / "chief")]
        else:
            argv = [
                "worker",
                "--worker-id",
                role,
                "--seed",
                str(self.index),
                "--out",
                str(self.out / f"w{role}"),
            ]
        log = (self.out / f"{role}.log").open("ab")
        self.procs[role] = subprocess.Popen(
            [sys.executable, "-m", "fleetrl.cli.main", *argv, *self.common, *extra],
            stdout=log, stderr=subprocess.STDOUT, start_new_session=True,
        )  # fmt: skip
        log.close()

    def kill9(self, role: str) -> None:
        proc = self.procs[role]
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait()

    def closed_rounds(self) -> int:
        """The last round the chief closed, from its log."""
        path = self.out / "chief" / "chief.log"
        if not path.exists():
            return 0
        closed = [
            int(line.split()[1].rstrip(":"))
            for line in path.read_text().splitlines()
            if ": answered " in line
        ]
        return max(closed, default=0)

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


def soak_one(
    index: int, fault: str, rng: random.Random, broker: Broker, root: Path, rounds: int, grace: float
) -> Outcome:
    """One run with one fault; the books checked after."""
    out = root / f"run-{index:03d}"
    out.mkdir(parents=True)
    run = Run(index, broker, out, rounds, grace)
    victim = {"chief-resumed": "chief", "broker-restarted": "broker"}.get(fault) or str(
        rng.randrange(WORKERS)
    )
    outcome = Outcome(index, fault, victim, after_round=rng.randint(1, rounds - 2))
    started = time.monotonic()
    try:
        run.start("chief")
        for k in range(WORKERS):
            run.start(str(k))
        progress = (
            (lambda: len(run.worker_rounds(victim)) >= outcome.after_round)
            if victim.isdigit()
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
        check_books(run, outcome, finished_by_victim)
    finally:
        run.stop_all()
        outcome.wall_s = round(time.monotonic() - started, 1)
    return outcome


def check_books(run: Run, outcome: Outcome, finished_by_victim: int) -> None:
    """Rounds lost or duplicated, per worker, against the chief's record (chief.json)."""
    chief_json = run.out / "chief" / "chief.json"
    if not chief_json.exists():
        outcome.chief_agrees = False
        outcome.notes.append("no chief.json")
        return
    chief = json.loads(chief_json.read_text())
    last = int(chief["rounds"])
    dropped = {d["worker"]: int(d["round"]) for d in chief["dropouts"]}
    for k in range(WORKERS):
        worker = str(k)
        rounds = run.worker_rounds(worker)
        gone = outcome.fault == "worker-gone" and worker == outcome.victim
        expected = set(range(1, (finished_by_victim if gone else last) + 1))
        outcome.duplicated += len(rounds) - len(set(rounds))
        outcome.lost += len(expected - set(rounds))
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
        "| longest recovery |",
        "|---|---|---|---|---|---|---|",
    ]
    for fault in (*FAULTS, "all"):
        group = [o for o in outcomes if fault in ("all", o.fault)]
        recoveries = [o.recovery_s for o in group if o.recovery_s is not None]
        longest = f"{max(recoveries):.1f} s" if recoveries else "-"
        lines.append(
            f"| {fault} | {len(group)} | {sum(o.completed for o in group)} | {sum(o.lost for o in group)} | "
            f"{sum(o.duplicated for o in group)} | {sum(o.chief_agrees for o in group)} | {longest} |"
        )
    lines.append(f"\n{len(outcomes)} runs in {seconds / 60:.1f} min")
    return "\n".join(lines)


def main() -> int:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--runs", type=int, default=50)
    parser.add_argument("--rounds", type=int, default=8, help="M of every run (default 8)")
    parser.add_argument("--seed", type=int, default=0, help="seed of the faults and their moments")
    parser.add_argument(
        "--grace", type=float, default=GRACE, help=f"the chief's --dropout-grace ({GRACE:g} s)"
    )
    parser.add_argument("--out", type=Path, default=None, help="directory for the runs and soak.json")
    parser.add_argument(
        "--faults", default=",".join(FAULTS), help=f"the kinds to draw from ({','.join(FAULTS)})"
    )
    args = parser.parse_args()
    kinds = args.faults.split(",")
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
            outcome = soak_one(index, rng.choice(kinds), rng, broker, root, args.rounds, args.grace)
            outcomes.append(outcome)
            print(json.dumps(asdict(outcome)), flush=True)
            (root / "soak.json").write_text(json.dumps([asdict(o) for o in outcomes], indent=1))
    finally:
        broker.stop()
    print(report(outcomes, time.monotonic() - started))
    bad = [o for o in outcomes if not o.completed or o.lost or o.duplicated or not o.chief_agrees]
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
