"""``fleetrl aggregator``: its settings refused in one line before anything starts, and a site of two
``fleetrl worker`` processes on a site broker behind it finishing a run of ``fleetrl chief`` on the central
broker (two mosquitto brokers)."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from cli_helpers import Fleetrl, last_line
from safetensors.numpy import load_file

from fleetrl.transport.broker import EmbeddedBroker

SITE = ("--site-id", "0", "--site-run", "site-a", "--members", "2")


@pytest.mark.parametrize(
    ("extra", "line"),
    [
        (
            ("--aggregation", "median"),
            "aggregation 'median' does not decompose into sites' sums (a robust rule needs every member's "
            "vector at one place): use mean, or run the fleet flat",
        ),
        (("--scheme", "paper"), "cannot run behind edge aggregators (they sum their members' answers)"),
        (("--site-run", "root"), "must differ from the root's run id on the same broker"),
    ],
)
def test_settings_that_cannot_make_a_tree_are_refused_in_one_line(
    fleetrl: Fleetrl, extra: tuple[str, ...], line: str
) -> None:
    done = fleetrl(
        "aggregator", "--broker", "mqtt://127.0.0.1:9", "--run-id", "root", "--env", "cartpole", *SITE, *extra
    )  # fmt: skip
    assert done.returncode == 2 and "Traceback" not in done.stderr, done.stderr
    assert line in last_line(done)


@pytest.mark.slow
@pytest.mark.mqtt
@pytest.mark.mosquitto
def test_a_site_behind_an_aggregator_finishes_the_chief_s_run_over_two_brokers(tmp_path: Path) -> None:
    run = ["--env", "cartpole", "--preset", "standard", "--max-rounds", "2"]
    base = [sys.executable, "-m", "fleetrl.cli.main"]
    with EmbeddedBroker("mosquitto") as centre, EmbeddedBroker("mosquitto") as site:
        url = ["--broker", centre.url]
        roles = [[*base, "chief", *url, "--run-id", "root", *run, "--workers", "1", "--idle-timeout", "120"]]
        aggregator = [*base, "aggregator", *url, "--run-id", "root", *run, *SITE, "--site-broker", site.url]
        roles.append([*aggregator, "--idle-timeout", "120"])
        worker = [*base, "worker", "--broker", site.url, "--run-id", "site-a", *run]
        roles += [[*worker, "--worker-id", w, "--out", str(tmp_path / w)] for w in ("0", "1")]
        procs = [subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.PIPE) for argv in roles]
        codes = [p.wait(timeout=600) for p in procs]
        outs = [p.communicate() for p in procs]
    assert codes == [0, 0, 0, 0], [err[-800:] for _, err in outs]
    chief = json.loads(outs[0][0].decode().strip().splitlines()[-1])
    site = json.loads(outs[1][0].decode().strip().splitlines()[-1])
    assert chief["rounds"] == 2 and site["end_reason"] == "the root ended the run"
    models = [load_file(str(tmp_path / w / "models" / f"worker-{w}.safetensors")) for w in ("0", "1")]
    assert all(np.array_equal(models[0][name], models[1][name]) for name in models[0])
