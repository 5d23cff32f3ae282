"""Helpers for tests that run the real ``fleetrl`` command line in a child process."""

from __future__ import annotations

import subprocess
import sys
from collections.abc import Callable

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
