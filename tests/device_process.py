"""A ``fleetrl device`` process (a second machine's role) for the tests that reach a bridge from outside."""

from __future__ import annotations

import signal
import subprocess
import sys
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path


@contextmanager
def device_process(
    url: str, run_id: str, driver: str, unit: int, fleet_seed: int, cwd: Path, env: str | None = None
) -> Iterator[list[str]]:
    """``fleetrl device --driver DRIVER`` (with ``env``: ``--env ENV``) serving ``unit`` of fleet
    ``fleet_seed`` on the broker at ``url`` while the block runs; then SIGTERM, which must end it cleanly
    (motor off, offline announced, exit 0, no traceback). Yields a list that holds the process's stderr
    once the block has run."""
    argv = [sys.executable, "-m", "fleetrl.cli.main", "device", "--driver", driver, "--unit", str(unit),
            "--fleet-seed", str(fleet_seed), "--broker", url, "--run-id", run_id]  # fmt: skip
    argv += [] if env is None else ["--env", env]
    bridge = subprocess.Popen(argv, cwd=cwd, stderr=subprocess.PIPE, text=True)
    log: list[str] = []
    try:
        yield log
    finally:
        bridge.send_signal(signal.SIGTERM)
        _, err = bridge.communicate(timeout=30)
        log.append(err)
    assert bridge.returncode == 0, err
    assert "Traceback" not in err
