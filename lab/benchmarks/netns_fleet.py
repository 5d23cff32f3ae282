"""A federated CartPole fleet across Linux network namespaces: broker, chief and workers on separate stacks.

Run as root: ``.venv/bin/python lab/benchmarks/netns_fleet.py`` (``--rounds 12 --workers 3 --delay-ms 20
--jitter-ms 5 --loss 1``; ``--keep`` keeps the run directories). Needs iproute2 and mosquitto. Each role's
namespace is joined to the broker's by a veth pair with netem on both ends where the kernel has it; prints
the round overhead from the roles' DEBUG logs (the last message of round r sent → the last answer applied).
Every namespace and process is removed at the end, on failure too.
"""

from __future__ import annotations

import argparse
import json
import logging
import os
import re
import shutil
import signal
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from datetime import datetime
from pathlib import Path

from fleetrl.transport.broker import find_mosquitto

log = logging.getLogger("netns_fleet")

SUBNET = "10.77.0"
PORT = 1883
STAMP = r"(\d{4}-\d\d-\d\d \d\d:\d\d:\d\d,\d{3})"
SENT = re.compile(
    STAMP + r" DEBUG fleetrl\.federation\.worker\.machine: worker (\d+): sending (?!join )\w+ of round (\d+)"
)
APPLIED = re.compile(STAMP + r" INFO fleetrl\.federation\.worker\.machine: worker (\d+) round (\d+): ")
FLEETRL = [sys.executable, "-m", "fleetrl.cli.main", "-v"]
"""a fleetrl role, its DEBUG log on (the measurements read it)"""


def sh(*argv: str, check: bool = True) -> subprocess.CompletedProcess[str]:
    """Run a command, its output captured; raise with its stderr if ``check`` and it fails."""
    done = subprocess.run(argv, capture_output=True, text=True, timeout=30)
    if check and done.returncode != 0:
        raise RuntimeError(f"{' '.join(argv)} failed: {done.stderr.strip()}")
    return done


@dataclass
class Fleet:
    """The namespaces, links and processes created, so that all of them can be removed."""

    tag: str
    namespaces: list[str] = field(default_factory=list)
    processes: list[subprocess.Popen[bytes]] = field(default_factory=list)

    def namespace(self, role: str) -> str:
        """Create (once) and return the namespace of ``role``, its loopback up."""
        name = f"{self.tag}-{role}"
        if name not in self.namespaces:
            sh("ip", "netns", "add", name)
            self.namespaces.append(name)
            sh("ip", "-n", name, "link", "set", "lo", "up")
        return name

    def link(self, index: int, broker_ns: str, node_ns: str) -> tuple[str, str, str, str]:
        """A veth pair broker ↔ node; returns (broker ifname, broker address, node ifname, node address)."""
        near, far = f"{self.tag}b{index}", f"{self.tag}n{index}"
        sh("ip", "link", "add", near, "type", "veth", "peer", "name", far)
        sh("ip", "link", "set", near, "netns", broker_ns)
        sh("ip", "link", "set", far, "netns", node_ns)
        near_ip, far_ip = f"{SUBNET}.{4 * index + 1}", f"{SUBNET}.{4 * index + 2}"
        for ns, ifname, ip in ((broker_ns, near, near_ip), (node_ns, far, far_ip)):
            sh("ip", "-n", ns, "addr", "add", f"{ip}/30", "dev", ifname)
            sh("ip", "-n", ns, "link", "set", ifname, "up")
        return near, near_ip, far, far_ip

    def start(self, ns: str, argv: list[str], logfile: Path) -> subprocess.Popen[bytes]:
        """Start ``argv`` inside namespace ``ns`` in its own process group, output to ``logfile``."""
        with logfile.open("ab") as out:
            proc = subprocess.Popen(
                ["ip", "netns", "exec", ns, *argv],
                stdout=out,
                stderr=subprocess.STDOUT,
                start_new_session=True,
            )
        self.processes.append(proc)
        return proc

    def stop(self) -> None:
        """Stop every process started that still runs (its group: TERM, then KILL after a grace)."""
        for proc in self.processes:
            if proc.poll() is None:
                os.killpg(proc.pid, signal.SIGTERM)
        grace = time.monotonic() + 5.0  # one grace for them all, not one each
        for proc in self.processes:
            try:
                proc.wait(max(0.1, grace - time.monotonic()))
            except subprocess.TimeoutExpired:
                os.killpg(proc.pid, signal.SIGKILL)
                proc.wait(5)

    def clean(self) -> None:
        """Stop every process started; delete every namespace and its veths."""
        self.stop()
        for name in reversed(self.namespaces):
            sh("ip", "netns", "del", name, check=False)
        left = [n for n in self.namespaces if n in sh("ip", "netns", "list").stdout]
        log.info(
            "cleaned up: %d processes, %d namespaces (%s left)",
            len(self.processes),
            len(self.namespaces),
            left or "none",
        )


def add_netem(ends: Iterable[tuple[str, str]], delay_ms: float, jitter_ms: float, loss: float) -> str | None:
    """Put netem (delay ± jitter, loss %) on every (namespace, ifname) of ``ends`` in turn; None if done, else
    why not (the kernel's answer; the ends after a failure are left alone)."""
    netem = ["root", "netem", "delay", f"{delay_ms}ms", f"{jitter_ms}ms", "loss", f"{loss}%"]
    for ns, ifname in ends:
        done = sh("ip", "netns", "exec", ns, "tc", "qdisc", "add", "dev", ifname, *netem, check=False)
        if done.returncode != 0:
            return done.stderr.strip() or f"tc exited {done.returncode}"
    return None


def start_broker(fleet: Fleet, ns: str, work: Path, name: str = "broker") -> None:
    """mosquitto in namespace ``ns``, listening on every address at :data:`PORT` (its configuration and log
    in ``work``, named after ``name``)."""
    config = work / f"{name}.conf"
    config.write_text(
        f"listener {PORT} 0.0.0.0\nallow_anonymous true\nset_tcp_nodelay true\npersistence false\n"
    )
    mosquitto = find_mosquitto()
    assert mosquitto is not None
    fleet.start(ns, [mosquitto, "-c", str(config)], work / f"{name}.log")


def run_args(run_id: str, rounds: int) -> list[str]:
    """The settings every role of a run shares: CartPole, the standard preset, ``rounds`` rounds."""
    return ["--run-id", run_id, "--env", "cartpole", "--preset", "standard", "--max-rounds", str(rounds)]


def wait_all(roles: dict[str, subprocess.Popen[bytes]], deadline: float) -> dict[str, int | None]:
    """Each role's exit code (None: still running at ``deadline``, a ``time.monotonic()`` value)."""
    codes: dict[str, int | None] = {}
    for role, proc in roles.items():
        try:
            codes[role] = proc.wait(max(1.0, deadline - time.monotonic()))
        except subprocess.TimeoutExpired:
            codes[role] = None
    return codes


def spread(values: list[float]) -> str:
    """p50, p95 and max of ``values`` (ms), for a report line."""
    ordered = sorted(values)
    p95 = ordered[min(len(ordered) - 1, round(0.95 * (len(ordered) - 1)))]
    return f"p50 {statistics.median(ordered):.1f} ms, p95 {p95:.1f} ms, max {ordered[-1]:.1f} ms"


def timestamp(stamp: str) -> float:
    """A log line's time (``asctime``), in seconds."""
    return datetime.strptime(stamp, "%Y-%m-%d %H:%M:%S,%f").timestamp()


def wait_for_broker(fleet: Fleet, ns: str, host: str, deadline: float) -> None:
    """Until a TCP connect from namespace ``ns`` to the broker succeeds."""
    probe = f"import socket; socket.create_connection(('{host}', {PORT}), 1).close()"
    while sh("ip", "netns", "exec", ns, sys.executable, "-c", probe, check=False).returncode != 0:
        if time.monotonic() > deadline:
            raise TimeoutError(f"the broker at {host}:{PORT} is not reachable from {ns}")
        time.sleep(0.2)


def overheads(logs: list[Path]) -> dict[int, float]:
    """Round → overhead in ms from the workers' logs: the last worker's record of round r minus the last
    worker's send of r."""
    sent: dict[int, float] = {}
    applied: dict[int, float] = {}
    for path in logs:
        for line in path.read_text(errors="replace").splitlines():
            for pattern, table in ((SENT, sent), (APPLIED, applied)):
                if m := pattern.match(line):
                    rnd, t = int(m.group(3)), timestamp(m.group(1))
                    table[rnd] = max(table.get(rnd, 0.0), t)
    return {r: 1000.0 * (applied[r] - sent[r]) for r in sorted(sent) if r in applied}


def run(args: argparse.Namespace, fleet: Fleet, work: Path) -> int:
    """Build the namespaces, run the fleet, report; returns the exit code."""
    deadline = time.monotonic() + args.timeout
    broker_ns = fleet.namespace("broker")
    nodes = ["chief", *(f"w{k}" for k in range(args.workers))]
    hosts, ends = {}, []
    for i, node in enumerate(nodes):
        ns = fleet.namespace(node)
        near, hosts[node], far, _ = fleet.link(i, broker_ns, ns)
        ends += [(broker_ns, near), (ns, far)]
    netem = add_netem(ends, args.delay_ms, args.jitter_ms, args.loss)
    if netem is None:
        impairment = f"delay {args.delay_ms} ms ± {args.jitter_ms} ms, loss {args.loss} %"
        print(f"netem: {impairment} on both ends of every veth")
    else:
        print(f"netem: not available in this kernel ({netem}); running without added latency or loss")
    start_broker(fleet, broker_ns, work)
    wait_for_broker(fleet, fleet.namespace("chief"), hosts["chief"], deadline)
    common = run_args("netns", args.rounds)
    started = time.monotonic()
    roles = {
        "chief": fleet.start(
            fleet.namespace("chief"),
            [*FLEETRL, "chief", "--broker", f"mqtt://{hosts['chief']}:{PORT}", *common, "--workers",
             str(args.workers), "--out", str(work / "chief"), "--idle-timeout", str(args.timeout)],
            work / "chief.log",
        )
    }  # fmt: skip
    for k in range(args.workers):
        node = f"w{k}"
        roles[node] = fleet.start(
            fleet.namespace(node),
            [*FLEETRL, "worker", "--broker", f"mqtt://{hosts[node]}:{PORT}", *common, "--worker-id", str(k),
             "--out", str(work / node), "--resend-interval", "2", "--reply-timeout", str(args.timeout)],
            work / f"{node}.log",
        )  # fmt: skip
    codes = wait_all(roles, deadline)
    wall = time.monotonic() - started
    completed = all(code == 0 for code in codes.values())
    chief_json = work / "chief" / "chief.json"
    print(f"roles' exit codes: {codes}; wall time {wall:.1f} s (process start-up included)")
    if chief_json.exists():
        print(f"chief: {json.dumps(json.loads(chief_json.read_text()), sort_keys=True)}")
    per_round = overheads([work / f"w{k}.log" for k in range(args.workers)])
    per_round.pop(1, None)  # warm-up: first messages on fresh connections
    if per_round:
        print(
            f"round overhead, rounds 2-{max(per_round)} (last message sent → last answer applied): "
            f"{spread(list(per_round.values()))}"
        )
    print(f"completed: {'yes' if completed else 'NO'} ({args.workers} workers, {args.rounds} rounds)")
    if not completed or args.keep:
        print(f"logs and run directories kept in {work}")
    return 0 if completed else 1


def main() -> int:
    """Parse the options, check the machine, run, and always clean up."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--workers", type=int, default=3)
    parser.add_argument("--rounds", type=int, default=12)
    parser.add_argument("--delay-ms", type=float, default=20.0, help="netem delay per qdisc (ms)")
    parser.add_argument("--jitter-ms", type=float, default=5.0, help="netem jitter (ms)")
    parser.add_argument("--loss", type=float, default=1.0, help="netem packet loss per qdisc (%%)")
    parser.add_argument("--timeout", type=float, default=150.0, help="bound on the fleet's run (s)")
    parser.add_argument("--keep", action="store_true", help="keep the run directories and logs")
    args = parser.parse_args()
    check_machine(parser)
    if not 1 <= args.workers <= 60:
        parser.error("--workers must be 1 … 60 (one /30 of 10.77.0.0/24 each)")
    return run_and_clean(args, "fl", run)


def check_machine(parser: argparse.ArgumentParser) -> None:
    """Log to stderr with times; a usage error unless this runs as root with ``ip`` and mosquitto."""
    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(levelname)s %(message)s")
    if os.geteuid() != 0:
        parser.error("network namespaces need root: run it with sudo")
    if shutil.which("ip") is None:
        parser.error("`ip` not found: apt-get install iproute2")
    if find_mosquitto() is None:
        parser.error("mosquitto not found: apt-get install mosquitto")


def run_and_clean(
    args: argparse.Namespace, tag: str, run: Callable[[argparse.Namespace, Fleet, Path], int]
) -> int:
    """``run(args, fleet, work)`` with a fleet of namespaces named ``tag``… and a fresh work directory; every
    namespace and process removed after, on failure too; the work directory kept if the run failed or with
    ``--keep``. The run's exit code."""
    fleet = Fleet(tag=f"{tag}{os.getpid() % 100000}")
    work = Path(tempfile.mkdtemp(prefix=f"netns-{tag}-"))
    code = 1
    try:
        code = run(args, fleet, work)
    finally:
        fleet.clean()
        if code == 0 and not args.keep:
            shutil.rmtree(work, ignore_errors=True)
    return code


if __name__ == "__main__":
    sys.exit(main())
