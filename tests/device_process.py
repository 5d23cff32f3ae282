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
    url: str, run_id: str, driver: str, unit: int, fleet_seed: int, cwd: Path
) -> Iterator[None]:
    """``fleetrl device --driver DRIVER`` serving ``unit`` of fleet ``fleet_seed`` on the broker at ``url``
    while the block runs; then SIGTERM, which must end it cleanly (motor off, offline announced, exit 0, no
    traceback)."""
    argv = [sys.executable, "-m", "fleetrl.cli.main", "device", "--driver", driver, "--unit", str(unit),
            "--fleet-seed", str(fleet_seed), "--broker", url, "--run-id", run_id]  # fmt: skip
    bridge = subprocess.Popen(argv, cwd=cwd, stderr=subprocess.PIPE, text=True)
    try:
        yield
    finally:
        bridge.send_signal(signal.SIGTERM)
        _, err = bridge.communicate(timeout=30)
    assert bridge.returncode == 0, err
    assert "Traceback" not in err
