"""Helpers for tests of the real ``fleetrl`` command line (mostly in a child process)."""

from __future__ import annotations

import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

import pytest

Fleetrl = Callable[..., subprocess.CompletedProcess[str]]


def run_fleetrl(*argv: str, timeout: float = 120.0, **popen: object) -> subprocess.CompletedProcess[str]:
    """``python -m fleetrl.cli.main ARGV`` to its end; its output captured as text."""
    return subprocess.run(  # type: ignore[call-overload, no-any-return]
        [sys.executable, "-m", "fleetrl.cli.main", *argv],
        capture_output=True,
        text=True,
        timeout=timeout,
        **popen,
    )


def last_line(done: subprocess.CompletedProcess[str]) -> str:
    """The last line the command printed on stderr."""
    lines = done.stderr.strip().splitlines()
    return lines[-1] if lines else ""


def refused_in_process(tmp_path: Path, capsys: pytest.CaptureFixture[str], *argv: str) -> str:
    """The one line ``fleetrl train ARGV`` (run in this process) printed when it refused its settings (and
    created nothing)."""
    from fleetrl.cli.main import main

    out = tmp_path / "run"
    assert main(["train", "--out", str(out), "--no-live", "--transport", "local", *argv]) == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err and len(err.strip().splitlines()) == 1, err
    assert not out.exists()
    return err.strip()
