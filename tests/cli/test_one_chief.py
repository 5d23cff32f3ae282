"""One chief per run, one process per worker id (issue 42): real ``fleetrl chief/worker`` processes on
mosquitto, CartPole, a keep-alive of 2 s (a lease of 3 s).

* a second chief on the same run directory is refused (the first one live, and the first one stopped with
  SIGSTOP past its lease: only the directory lock stands then);
* a second chief with the same run id and another directory is refused while the first is live;
* a chief cut off from the broker (stopped with SIGSTOP) is replaced after its lease by ``--resume`` on a copy
  of its checkpoint; woken up, the old one exits 1 on the newer epoch without writing anything, and the run
  completes with each worker's rounds once;
* a second worker process with a live worker id is refused;
* kill -9 of the chief followed at once by ``--resume`` on its directory works.
"""

from __future__ import annotations

import csv
import os
import shutil
import signal
import subprocess
import sys
import time
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest

from fleetrl.federation.wire.signing import parse_status
from fleetrl.transport.broker import EmbeddedBroker
from fleetrl.transport.mqtt import read_retained

pytestmark = [pytest.mark.mqtt, pytest.mark.mosquitto, pytest.mark.slow]

ROUNDS = 4
RUN = ["--env", "cartpole", "--preset", "standard", "--max-rounds", str(ROUNDS), "--keepalive", "2"]
QUICK = ["--resend-interval", "1"]


@pytest.fixture(scope="module")
def url() -> Iterator[str]:
    with EmbeddedBroker("mosquitto") as broker:
        yield broker.url


@pytest.fixture
def procs() -> Iterator[list[subprocess.Popen[str]]]:
    started: list[subprocess.Popen[str]] = []
    yield started
    for p in started:
        if p.poll() is None:
            os.kill(p.pid, signal.SIGCONT)
            p.kill()
            p.wait(10)


def start(
    procs: list[subprocess.Popen[str]], role: str, url: str, run: str, out: Path, *extra: str
) -> subprocess.Popen[str]:
    argv = [sys.executable, "-m", "fleetrl.cli.main", role, "--broker", url, "--run-id", run, *RUN]
    out.parent.mkdir(parents=True, exist_ok=True)
    log = (out.parent / f"{out.name}.{role}.{len(procs)}.log").open("a")
    proc = subprocess.Popen(
        [*argv, "--out", str(out), *extra],
        stdout=log,
        stderr=subprocess.STDOUT,
        text=True,
        start_new_session=True,
    )
    procs.append(proc)
    return proc


def chief(
    procs: list[subprocess.Popen[str]], url: str, run: str, out: Path, *extra: str
) -> subprocess.Popen[str]:
    return start(procs, "chief", url, run, out, "--workers", "2", "--idle-timeout", "120", *extra)


def worker(
    procs: list[subprocess.Popen[str]], url: str, run: str, out: Path, k: int, *extra: str
) -> subprocess.Popen[str]:
    return start(procs, "worker", url, run, out / f"w{k}", "--worker-id", str(k), *QUICK, *extra)


def refused(url: str, run: str, out: Path, role: str, *extra: str) -> subprocess.CompletedProcess[str]:
    """A second role process run to its end (it must be refused at once)."""
    argv = [sys.executable, "-m", "fleetrl.cli.main", role, "--broker", url, "--run-id", run, *RUN]
    return subprocess.run([*argv, "--out", str(out), *extra], capture_output=True, text=True, timeout=60)


def status(url: str, run: str, node: str) -> str | None:
    payload = read_retained(
        url, f"fleetrl/{run}/status/{node}", client_id=f"t-{time.monotonic_ns()}", timeout=10
    )
    return None if payload is None else parse_status(payload, run_id=run, node=node).state


def wait_until(done: Callable[[], bool], what: str, timeout: float = 120.0) -> None:
    deadline = time.monotonic() + timeout
    while not done():
        assert time.monotonic() < deadline, f"timed out waiting for {what}"
        time.sleep(0.1)


def answered(out: Path, rnd: int) -> bool:
    log = out / "chief.log"
    return log.exists() and f"round {rnd}: answered" in log.read_text()


def rounds(out: Path) -> list[int]:
    path = out / "metrics.csv"
    with path.open(newline="") as f:
        return [int(r["round"]) for r in csv.DictReader(f)]


def quiet(out: Path, seconds: float = 0.3) -> bool:
    """Nothing in ``out`` changed for ``seconds`` and no checkpoint write is under way."""
    before = snapshot(out)
    time.sleep(seconds)
    return snapshot(out) == before and not any(p.name.endswith(".partial") for p in out.rglob("*"))


def snapshot(directory: Path) -> dict[str, tuple[int, int]]:
    """Each file's change time and size (a file removed while listed, a rotated checkpoint: changed)."""
    files: dict[str, tuple[int, int]] = {}
    for p in directory.rglob("*"):
        try:
            stat = p.stat()
        except FileNotFoundError:
            stat = None
        files[str(p.relative_to(directory))] = (-1, -1) if stat is None else (stat.st_mtime_ns, stat.st_size)
    return files


def one_line(done: subprocess.CompletedProcess[str]) -> str:
    lines = done.stderr.strip().splitlines()
    assert "Traceback" not in done.stderr, done.stderr
    return lines[-1] if lines else ""


@pytest.mark.timeout(180)
def test_a_second_chief_on_the_same_directory_is_refused(
    url: str, procs: list[subprocess.Popen[str]], tmp_path: Path
) -> None:
    a = tmp_path / "a"
    first = chief(procs, url, "same-dir", a)
    wait_until(lambda: (a / "checkpoints" / "chief" / "chief.json").exists(), "the first chief's checkpoint")
    wait_until(lambda: status(url, "same-dir", "chief") == "online", "the first chief online")
    before = snapshot(a)
    for extra in (["--resume"], []):  # resuming or not
        done = refused(url, "same-dir", a, "chief", "--workers", "2", *extra)
        line = one_line(done)
        assert done.returncode == 1, done.stderr
        assert line.startswith("fleetrl chief: error: ") and f"in use by the chief pid {first.pid}" in line, (
            line
        )
    # stopped past its lease (its will fired: the broker says offline), the first chief still holds its
    # directory: only the lock stands between a second chief and its files
    os.kill(first.pid, signal.SIGSTOP)
    wait_until(
        lambda: status(url, "same-dir", "chief") == "offline", "the stopped chief's lease to run out", 30
    )
    done = refused(url, "same-dir", a, "chief", "--workers", "2", "--resume")
    assert done.returncode == 1, done.stderr
    assert f"in use by the chief pid {first.pid}" in one_line(done), done.stderr
    assert snapshot(a) == before  # nothing written
    os.kill(first.pid, signal.SIGCONT)


@pytest.mark.timeout(180)
def test_a_second_chief_of_a_live_run_id_is_refused(
    url: str, procs: list[subprocess.Popen[str]], tmp_path: Path
) -> None:
    a = tmp_path / "a"
    first = chief(procs, url, "same-run", a)
    wait_until(lambda: (a / "checkpoints" / "chief" / "chief.json").exists(), "the first chief's checkpoint")
    wait_until(lambda: status(url, "same-run", "chief") == "online", "the first chief online")
    b, c = tmp_path / "b", tmp_path / "c"
    shutil.copytree(a / "checkpoints", c / "checkpoints")  # as an operator resuming elsewhere would
    before = snapshot(c)
    for out, extra in ((b, []), (c, ["--resume"])):  # a new chief of the run id, and a resumed one
        done = refused(url, "same-run", out, "chief", "--workers", "2", *extra)
        line = one_line(done)
        assert done.returncode == 1, done.stderr
        assert f"run 'same-run' has a live chief (epoch 0): pid {first.pid} on host" in line, line
    assert not b.exists() and snapshot(c) == before  # nothing written
    assert first.poll() is None and status(url, "same-run", "chief") == "online"


@pytest.mark.timeout(420)
def test_a_cut_off_chief_is_replaced_after_its_lease_and_exits_on_the_newer_epoch(
    url: str, procs: list[subprocess.Popen[str]], tmp_path: Path
) -> None:
    a, b, run = tmp_path / "a", tmp_path / "b", "takeover"
    # units stepped in real time (CartPole: 20 ms a step) and twice the rounds: the chief waits for their
    # episodes, so it has quiet moments before its run ends (unpaced, 4 rounds end within 2 s of round 1)
    longer = ["--max-rounds", str(2 * ROUNDS)]
    old = chief(procs, url, run, a, *longer)
    workers = [worker(procs, url, run, tmp_path, k, *longer, "--pace", "1") for k in (0, 1)]
    wait_until(lambda: answered(a, 1), "round 1")
    # cut off while it waits (a step under way when stopped is finished when it wakes: docs/protocol.md,
    # "One chief per run", Limits): no keep-alive reaches the broker any more
    wait_until(lambda: quiet(a), "a moment the old chief waits")
    os.kill(old.pid, signal.SIGSTOP)
    assert old.poll() is None, "the old chief ended its run before it could be cut off"
    wait_until(lambda: status(url, run, "chief") == "offline", "the old chief's lease to run out", 30)
    shutil.copytree(a / "checkpoints", b / "checkpoints")  # the operator moves the run to another machine
    new = chief(procs, url, run, b, "--resume", *longer)
    wait_until(
        lambda: (b / "chief.log").exists() and "after resume" in (b / "chief.log").read_text(),
        "the new chief",
    )
    kept = snapshot(a)
    os.kill(old.pid, signal.SIGCONT)  # it comes back
    assert old.wait(60) == 1
    assert snapshot(a) == kept  # no checkpoint (nor anything else) written after it learned of epoch 1
    log = (tmp_path / "a.chief.0.log").read_text()
    assert "was replaced by a newer chief" in log.strip().splitlines()[-1], log[-2000:]
    assert new.wait(300) == 0
    assert [w.wait(60) for w in workers] == [0, 0]
    for k in (0, 1):
        assert rounds(tmp_path / f"w{k}") == list(range(1, 2 * ROUNDS + 1)), f"worker {k}"
    assert status(url, run, "chief") == "ended"


@pytest.mark.timeout(300)
def test_a_second_process_with_a_live_worker_id_is_refused(
    url: str, procs: list[subprocess.Popen[str]], tmp_path: Path
) -> None:
    run = "dup-worker"
    chief(procs, url, run, tmp_path / "c")
    first = worker(procs, url, run, tmp_path, 0)
    wait_until(lambda: status(url, run, "0") == "online", "worker 0 online")
    done = refused(url, run, tmp_path / "other", "worker", "--worker-id", "0")
    line = one_line(done)
    assert done.returncode == 1, done.stderr
    assert f"worker id 0 of run 'dup-worker' is live: pid {first.pid} on host" in line, line
    assert not (tmp_path / "other").exists()
    assert first.poll() is None and status(url, run, "0") == "online"  # the first one is untouched


@pytest.mark.timeout(420)
def test_kill_9_of_the_chief_then_resume_at_once(
    url: str, procs: list[subprocess.Popen[str]], tmp_path: Path
) -> None:
    a, run = tmp_path / "a", "kill-resume"
    old = chief(procs, url, run, a)
    workers = [worker(procs, url, run, tmp_path, k) for k in (0, 1)]
    wait_until(lambda: answered(a, 1), "round 1")
    os.kill(old.pid, signal.SIGKILL)
    assert old.wait(30) == -signal.SIGKILL
    new = chief(procs, url, run, a, "--resume")  # at once: the lock died with the process, the will fired
    assert new.wait(300) == 0, (tmp_path / "a.chief.3.log").read_text()[-2000:]
    assert [w.wait(60) for w in workers] == [0, 0]
    for k in (0, 1):
        assert rounds(tmp_path / f"w{k}") == list(range(1, ROUNDS + 1)), f"worker {k}"
