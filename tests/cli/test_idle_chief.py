"""Issue 14 (1): a chief whose workers never come (or a worker whose chief never answers) waits quietly, then
gives up with one line and exit 1."""

from __future__ import annotations

from pathlib import Path

import pytest
from cli_helpers import Fleetrl, last_line

from fleetrl.transport.broker import EmbeddedBroker


@pytest.mark.mqtt
@pytest.mark.mosquitto
def test_a_chief_nobody_joins_gives_up_after_its_idle_timeout_with_one_line(
    tmp_path: Path, fleetrl: Fleetrl
) -> None:
    with EmbeddedBroker("mosquitto") as broker:
        done = fleetrl(
            "chief", "--broker", broker.url, "--run-id", "lonely", "--workers", "3", "--env", "cartpole",
            "--round-timeout", "0.5", "--idle-timeout", "3", "--out", str(tmp_path / "chief"),
        )  # fmt: skip
    assert done.returncode == 1, done.stderr
    assert "Traceback" not in done.stderr
    last = last_line(done)
    assert last.startswith("fleetrl chief: error: ") and "no worker message for 3 s" in last, last
    assert "waiting for ['0', '1', '2']" in last


@pytest.mark.mqtt
@pytest.mark.mosquitto
def test_a_worker_the_chief_never_answers_gives_up_after_its_reply_timeout_with_one_line(
    tmp_path: Path, fleetrl: Fleetrl
) -> None:
    with EmbeddedBroker("mosquitto") as broker:
        done = fleetrl(
            "worker", "--broker", broker.url, "--run-id", "nochief", "--worker-id", "0", "--env", "cartpole",
            "--reply-timeout", "2", "--out", str(tmp_path / "w0"),
        )  # fmt: skip
    assert done.returncode == 1, done.stderr
    assert "Traceback" not in done.stderr
    assert last_line(done) == (
        "fleetrl worker: error: worker 0: nothing from the chief of run 'nochief' for 2 s (--reply-timeout) "
        "while waiting for the chief's welcome"
    )
