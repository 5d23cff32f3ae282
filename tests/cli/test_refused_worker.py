"""A ``fleetrl worker`` whose shared settings differ from its chief's is refused at join: it exits 2 (a bad
setting) with one line naming the setting, and the chief never averages anything of it."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest
from cli_helpers import Fleetrl, last_line

from fleetrl.transport.broker import EmbeddedBroker


@pytest.mark.slow
@pytest.mark.mqtt
@pytest.mark.mosquitto
def test_a_worker_with_another_preset_is_refused_and_exits_2(tmp_path: Path, fleetrl: Fleetrl) -> None:
    with EmbeddedBroker("mosquitto") as broker:
        common = ("--broker", broker.url, "--run-id", "mixed", "--env", "cartpole")
        chief = subprocess.Popen(
            [
                sys.executable, "-m", "fleetrl.cli.main", "chief", *common, "--workers", "1",
                "--preset", "standard", "--idle-timeout", "5", "--out", str(tmp_path / "chief"),
            ],
            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
        )  # fmt: skip
        try:
            done = fleetrl(
                "worker", *common, "--worker-id", "0", "--preset", "paper", "--reply-timeout", "30",
                "--out", str(tmp_path / "w0"),
            )  # fmt: skip
        finally:
            _, chief_err = chief.communicate(timeout=60)
    assert done.returncode == 2, done.stderr
    assert "Traceback" not in done.stderr
    assert last_line(done) == (
        "fleetrl worker: error: worker 0: refused by the chief of run 'mixed': setting 'preset' differs "
        "(chief 'standard', worker 'paper'); start it with the chief's settings"
    )
    assert "worker 0 refused: setting 'preset' differs" in chief_err
    assert chief.returncode == 1  # nobody it accepts came: its idle timeout
    summary = json.loads((tmp_path / "w0" / "summary.json").read_text())
    assert summary["rounds"] == 0 and summary["workers"]["0"]["events"] == [], summary
