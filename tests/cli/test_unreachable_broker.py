"""Issue 14 (2): a broker nobody can reach ends every command with one line and a non-zero exit."""

from __future__ import annotations

from pathlib import Path

import pytest
from cli_helpers import Fleetrl, last_line

from fleetrl.cli.main import exit_code

pytestmark = pytest.mark.slow  # `fleetrl` processes that retry for up to 10 s

NOWHERE = "mqtt://127.0.0.1:1"  # nothing listens on port 1
SMALL = ["--env", "cartpole", "--max-rounds", "2"]


def test_train_on_an_unreachable_broker_fails_before_the_run_directory_exists(
    tmp_path: Path, fleetrl: Fleetrl
) -> None:
    out = tmp_path / "run"
    done = fleetrl("train", "--broker", NOWHERE, "--units", "2", "--no-live", "--out", str(out), *SMALL)
    assert done.returncode == 1, done.stderr
    assert "Traceback" not in done.stderr
    line = last_line(done)
    assert line.startswith(f"fleetrl train: error: cannot reach the broker {NOWHERE}"), line
    assert line.endswith("no answer within 10 s (fleetrl train retries its --broker for that long)"), line
    assert not out.exists()


@pytest.mark.parametrize(
    "role",
    [
        ["chief", "--workers", "2", "--run-id", "r"],
        ["worker", "--worker-id", "0", "--run-id", "r", "--out", "{tmp}/w0"],
        ["device", "--unit", "0", "--env", "cartpole"],
    ],
    ids=["chief", "worker", "device"],
)
def test_a_standalone_role_retries_up_to_its_connect_timeout_then_exits_1(
    tmp_path: Path, fleetrl: Fleetrl, role: list[str]
) -> None:
    argv = [a.replace("{tmp}", str(tmp_path)) for a in role]
    extra = [] if role[0] == "device" else SMALL
    done = fleetrl(*argv, *extra, "--broker", NOWHERE, "--connect-timeout", "2")
    assert done.returncode == 1, done.stderr
    assert "Traceback" not in done.stderr
    line = last_line(done)
    assert line.startswith(f"fleetrl {role[0]}: error: cannot reach the broker {NOWHERE}"), line
    assert line.endswith("no answer within 2 s"), line  # its --connect-timeout


def summary(**workers: str) -> dict[str, object]:
    return {"interrupted": False, "workers": {k: {"state": s} for k, s in workers.items()}, "chief": {}}


def test_a_run_in_which_a_worker_or_the_chief_failed_does_not_exit_0() -> None:
    assert exit_code(summary(w0="completed", w1="stopped")) == 0
    assert exit_code(summary(w0="completed", w1="failed (exit 1, see logs/)")) == 1
    assert exit_code({**summary(w0="completed"), "chief": {"error": "cannot reach"}}) == 1
    assert exit_code({**summary(w0="failed (exit 1, see logs/)"), "interrupted": True}) == 130
