"""A scheme from the user's own code (``--scheme package.module:Class``), as ``--env package.module:factory``
names a unit type."""

from __future__ import annotations

import csv
import os
import subprocess
import sys
from pathlib import Path

import pytest

from fleetrl.federation.schemes import get_scheme, scheme_reference

USER_CODE = Path(__file__).parent / "user_code"


@pytest.fixture
def on_path(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.syspath_prepend(str(USER_CODE))


def test_a_user_scheme_is_loaded_by_reference_and_named_back_the_same_way(on_path: None) -> None:
    scheme = get_scheme("my_scheme:SampleWeightedAverage")
    assert scheme.name == "sample_weighted" and scheme.round_message == "weighted_model"
    assert scheme_reference(scheme) == "my_scheme:SampleWeightedAverage"
    assert scheme_reference(get_scheme("fedavg")) == "fedavg"


@pytest.mark.parametrize(
    ("reference", "error"),
    [
        ("my_scheme:Missing", "scheme 'my_scheme:Missing': module 'my_scheme' has no attribute 'Missing'"),
        ("no_such_module:X", "scheme 'no_such_module:X': cannot import module 'no_such_module'"),
        ("my_scheme:NotAScheme", "is not a subclass of fleetrl.federation.schemes.RoundScheme or StepScheme"),
        ("my scheme", "unknown federation scheme 'my scheme'"),
    ],
)
def test_a_bad_reference_is_one_line_saying_what_is_wrong(on_path: None, reference: str, error: str) -> None:
    with pytest.raises(ValueError) as info:
        get_scheme(reference)
    assert error in str(info.value) and "\n" not in str(info.value)


@pytest.mark.slow  # trains two CartPole units for a few rounds
def test_a_user_scheme_trains_two_cartpole_units_federated(tmp_path: Path) -> None:
    out = tmp_path / "run"
    argv = [sys.executable, "-m", "fleetrl.cli.main", "train", "--env", "cartpole", "--units", "2"]
    argv += ["--mode", "federated", "--transport", "local", "--scheme", "my_scheme:SampleWeightedAverage"]
    argv += ["--max-rounds", "4", "--seed", "1", "--no-live", "--out", str(out)]
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(USER_CODE), os.environ.get("PYTHONPATH", "")])}
    done = subprocess.run(argv, capture_output=True, text=True, env=env, timeout=600)
    assert done.returncode == 0, done.stderr[-2000:]
    with (out / "metrics.csv").open() as f:
        rows = list(csv.DictReader(f))
    assert sorted((int(r["round"]), r["worker"]) for r in rows) == [(k, w) for k in range(1, 5) for w in "01"]
    assert {r["event"] for r in rows if r["round"] != "4"} <= {"weighted_model", "completed"}
    wrong = [("my_scheme:Missing" if a == "my_scheme:SampleWeightedAverage" else a) for a in argv]
    bad = subprocess.run(wrong, capture_output=True, text=True, env=env, timeout=600)
    assert bad.returncode == 2 and "has no attribute 'Missing'" in bad.stderr.strip().splitlines()[-1]
