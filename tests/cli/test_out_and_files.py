"""Issue 14 (5): an --out that cannot be written and a fleet key that cannot be read are refused at start,
with one line and nothing created; a disk that fills up mid-run stops the run cleanly, keeping its rounds."""

from __future__ import annotations

import contextlib
import csv
import os
import resource
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import pytest
from cli_helpers import Fleetrl, last_line

pytestmark = pytest.mark.slow  # `fleetrl` processes, tmpfs mounts

SMALL = ["--env", "cartpole", "--preset", "standard", "--units", "1", "--mode", "individual", "--no-live"]


@contextlib.contextmanager
def tmpfs(where: Path, size: str, *options: str) -> Iterator[Path]:
    """A small tmpfs mounted at ``where`` (root only; the test is skipped where mounting is not allowed)."""
    where.mkdir()
    done = subprocess.run(
        ["mount", "-t", "tmpfs", "-o", ",".join([f"size={size}", *options]), "tmpfs", str(where)],
        capture_output=True,
    )
    if done.returncode != 0:
        pytest.skip(f"cannot mount a tmpfs here: {done.stderr.decode().strip()}")
    try:
        yield where
    finally:
        subprocess.run(["umount", "-l", str(where)], check=False)


def test_an_out_on_a_read_only_file_system_is_refused_before_anything_starts(
    tmp_path: Path, fleetrl: Fleetrl
) -> None:
    with tmpfs(tmp_path / "ro", "1m", "ro") as ro:
        done = fleetrl("train", *SMALL, "--out", str(ro / "run"))
    assert done.returncode == 2, done.stderr
    assert "Traceback" not in done.stderr
    assert last_line(done) == (
        f"fleetrl train: error: --out = '{ro / 'run'}': {ro} is not writable (read-only file system)"
    )


def test_an_out_on_a_full_file_system_is_refused_before_anything_starts(
    tmp_path: Path, fleetrl: Fleetrl
) -> None:
    with tmpfs(tmp_path / "small", "1m") as small:
        done = fleetrl("train", *SMALL, "--out", str(small / "run"))
        assert not (small / "run").exists()
    assert done.returncode == 2, done.stderr
    assert "MB free on its file system (a run needs at least 64 MB)" in last_line(done)


def _limit_file_size() -> None:
    signal.signal(signal.SIGXFSZ, signal.SIG_IGN)  # a write past the limit then fails with EFBIG
    resource.setrlimit(resource.RLIMIT_FSIZE, (2**20, 2**20))


def test_a_file_size_limit_too_small_for_a_run_is_refused_at_start(tmp_path: Path, fleetrl: Fleetrl) -> None:
    done = fleetrl("train", *SMALL, "--out", str(tmp_path / "run"), preexec_fn=_limit_file_size)
    assert done.returncode == 2, done.stderr
    assert "the file size limit (ulimit -f) is 1048576 bytes" in last_line(done)
    assert not (tmp_path / "run").exists()


def test_an_out_that_is_a_file_is_refused(tmp_path: Path, fleetrl: Fleetrl) -> None:
    (tmp_path / "f").write_text("x")
    done = fleetrl("train", *SMALL, "--out", str(tmp_path / "f"))
    assert done.returncode == 2 and "it is a file, not a directory" in last_line(done)


@pytest.mark.parametrize("role", ["chief", "worker"])
@pytest.mark.parametrize("key", ["missing", "directory", "unreadable"])
def test_a_fleet_key_that_cannot_be_read_is_refused_before_connecting(
    tmp_path: Path, fleetrl: Fleetrl, role: str, key: str
) -> None:
    path = tmp_path / "fleet.key"
    if key == "directory":
        path.mkdir()
    elif key == "unreadable":
        if os.geteuid() == 0:
            pytest.skip("root reads any file")
        path.write_text("k" * 64)
        path.chmod(0)
    out = tmp_path / "out"
    argv = ["--workers", "2"] if role == "chief" else ["--worker-id", "0"]
    done = fleetrl(
        role, *argv, "--run-id", "r", "--broker", "mqtt://127.0.0.1:1", "--connect-timeout", "30",
        "--fleet-key-file", str(path), "--out", str(out),
    )  # fmt: skip
    assert done.returncode == 2, done.stderr
    why = {
        "missing": "no such file or directory",
        "directory": "it is a directory",
        "unreadable": "permission",
    }
    line = last_line(done)
    assert line.startswith(f"fleetrl {role}: error: --fleet-key-file = '{path}': cannot read it"), line
    assert why[key] in line
    assert not out.exists()


@pytest.mark.slow
@pytest.mark.timeout(240)
def test_a_disk_that_fills_up_mid_run_stops_the_run_with_one_line_and_keeps_its_rounds(
    tmp_path: Path,
) -> None:
    with tmpfs(tmp_path / "disk", "80m") as disk:
        out = disk / "run"
        child = subprocess.Popen(
            [sys.executable, "-m", "fleetrl.cli.main", "train", *SMALL, "--max-rounds", "100000",
             "--out", str(out)],
            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
        )  # fmt: skip
        try:
            deadline = time.monotonic() + 120
            while len(rows(out)) < 5:
                assert child.poll() is None, child.communicate()
                assert time.monotonic() < deadline, "the run did not start"
                time.sleep(0.2)
            filler = disk / "filler"
            with contextlib.suppress(OSError), filler.open("wb") as f:
                while True:
                    f.write(b"\0" * 2**20)
            _, stderr = child.communicate(timeout=120)
        finally:
            if child.poll() is None:
                child.kill()
        played = rows(out)
        filler.unlink()
    assert child.returncode == 1, stderr
    assert "Traceback" not in stderr, stderr
    last = stderr.strip().splitlines()[-1]
    assert last.startswith(f"fleetrl train: error: cannot write the run directory {out}: No space left"), last
    assert [int(r["round"]) for r in played] == list(range(1, len(played) + 1)) and len(played) >= 5


def rows(out: Path) -> list[dict[str, str]]:
    path = out / "metrics.csv"
    if not path.exists():
        return []
    with path.open(newline="") as f:
        return [
            r for r in csv.DictReader(f) if None not in r.values()
        ]  # a row cut by the full disk: left out
