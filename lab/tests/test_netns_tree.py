"""lab/benchmarks/netns_tree.py, small: a chief, an edge aggregator and two workers in separate network
namespaces on two mosquitto brokers finish a run and pass every check; a run cut short by its timeout fails
and still leaves no namespace behind. Root only (network namespaces); skipped elsewhere with the reason."""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

LAB = Path(__file__).resolve().parents[1]
BENCHMARK = LAB / "benchmarks" / "netns_tree.py"

pytestmark = [pytest.mark.slow, pytest.mark.mqtt, pytest.mark.mosquitto]


def why_no_namespaces() -> str | None:
    """Why this machine cannot run the benchmark (None: it can)."""
    if os.geteuid() != 0:
        return "network namespaces need root"
    if shutil.which("ip") is None:
        return "`ip` not found (apt-get install iproute2)"
    probe = f"fltest{os.getpid()}"
    made = subprocess.run(["ip", "netns", "add", probe], capture_output=True, text=True)
    if made.returncode != 0:
        return f"cannot create a network namespace here: {made.stderr.strip()}"
    subprocess.run(["ip", "netns", "del", probe], capture_output=True)
    return None


@pytest.fixture(scope="module")
def namespaces() -> None:
    """Skip the module's tests where namespaces cannot be made."""
    if why := why_no_namespaces():
        pytest.skip(why)


def run_tree(*flags: str) -> tuple[subprocess.CompletedProcess[str], list[str]]:
    """The benchmark's output, and the namespaces of its tag still there after it ended."""
    proc = subprocess.Popen(
        [sys.executable, str(BENCHMARK), "--workers", "2", "--rounds", "3", *flags],
        cwd=LAB.parent, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
    )  # fmt: skip
    out, _ = proc.communicate(timeout=180)
    done = subprocess.CompletedProcess(proc.args, proc.returncode, out, "")
    if kept := re.search(r"kept in (\S+)", out):  # a failed run keeps its logs for a person to read
        shutil.rmtree(kept.group(1), ignore_errors=True)
    tag = f"ft{proc.pid % 100000}-"
    listed = subprocess.run(["ip", "netns", "list"], capture_output=True, text=True).stdout.split()
    return done, [name for name in listed if name.startswith(tag)]


def test_a_two_broker_tree_across_namespaces_passes_every_check(namespaces: None) -> None:
    done, left = run_tree("--timeout", "150")
    assert done.returncode == 0, done.stdout[-3000:]
    assert "FAILED" not in done.stdout
    for check in (
        "ok  every worker's metrics.csv: rounds 1 … 3 once each",
        "ok  every worker's final model is the chief's, bit for bit",
        "ok  the chief's one member is the site, its answer for 2 units",
        "ok  every worker held one policy at every exchange (",
    ):
        assert check in done.stdout, done.stdout[-3000:]
    assert "bytes per exchange at the root" in done.stdout
    assert left == []


def test_a_run_cut_short_fails_and_leaves_no_namespace(namespaces: None) -> None:
    done, left = run_tree("--rounds", "1000", "--timeout", "6")  # runs until its units complete
    assert done.returncode == 1, done.stdout[-3000:]
    assert "FAILED every role exited 0" in done.stdout
    assert left == []
