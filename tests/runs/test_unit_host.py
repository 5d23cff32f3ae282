"""Unit hosts in a run (``--units-per-host``): 2 hosts x 3 units train CartPole in-process end to end, each
unit with its own rows, completion and model; every preset and uneven fleet runs in hosts; the setting is
checked once before anything starts."""

import csv
import json
from pathlib import Path

import pytest

from fleetrl.agent.criterion import CompletionCriterion
from fleetrl.cli.main import main
from fleetrl.runs.host_settings import host_groups

TARGET = 40.0


def train(out: Path, *extra: str) -> int:
    argv = ["train", "--env", "cartpole", "--units", "6", "--preset", "standard", "--seed", "3", "--mode",
            "federated", "--transport", "local", "--out", str(out), "--no-live", *extra]  # fmt: skip
    return main(argv)


def rows(out: Path) -> list[dict[str, str]]:
    return list(csv.DictReader((out / "metrics.csv").open()))


@pytest.mark.slow
def test_two_hosts_of_three_units_train_cartpole_end_to_end(tmp_path: Path) -> None:
    hosts, flat = tmp_path / "hosts", tmp_path / "flat"
    assert train(hosts, "--units-per-host", "3", "--max-rounds", "25", "--target-score", str(TARGET)) == 0
    summary = json.loads((hosts / "summary.json").read_text())
    config = json.loads((hosts / "config.json").read_text())
    assert config["units_per_host"] == 3 and config["result_settings"]["units_per_host"] == 3
    assert sorted(summary["chief"]["completed"]) == ["host-0", "host-3"]  # two members of the federation
    recorded = rows(hosts)
    rounds = max(int(r["round"]) for r in recorded)
    for unit in range(6):  # every unit: one row per round under its own id, its own completion
        mine = sorted((r for r in recorded if r["worker"] == str(unit)), key=lambda r: int(r["round"]))
        assert [int(r["round"]) for r in mine] == list(range(1, rounds + 1))
        criterion = CompletionCriterion(TARGET)
        for row in mine:
            criterion.add(float(row["score"]))
            assert (row["event"] == "completed") == criterion.done
        assert summary["workers"][str(unit)]["state"] == "completed"
        assert (hosts / "models" / f"worker-{unit}.safetensors").exists()
    # the first round is played before any update: the same fleet start and seeds as 6 workers of one unit
    assert train(flat, "--max-rounds", "1") == 0
    first = {r["worker"]: r["score"] for r in recorded if r["round"] == "1"}
    assert first == {r["worker"]: r["score"] for r in rows(flat)}


@pytest.mark.slow
@pytest.mark.mqtt
def test_hosts_as_processes_on_the_embedded_broker_play_as_hosts_in_process(tmp_path: Path) -> None:
    processes, threads = tmp_path / "processes", tmp_path / "threads"
    same = ("--units-per-host", "3", "--max-rounds", "3", "--quorum", "1")  # every exchange waits for both
    assert train(processes, *same, "--transport", "mqtt") == 0
    assert train(threads, *same) == 0
    played = {(r["worker"], r["round"], r["score"], r["event"]) for r in rows(processes)}
    assert played == {(r["worker"], r["round"], r["score"], r["event"]) for r in rows(threads)}
    assert {(w, r) for w, r, _, _ in played} == {(str(u), str(r)) for u in range(6) for r in (1, 2, 3)}
    summary = json.loads((processes / "summary.json").read_text())
    assert summary["chief"]["rounds"] == 3 and not summary["chief"]["rejections"]
    assert "answered host-0,host-3" in (processes / "logs" / "chief.log").read_text()  # two members
    assert "learner ready" in (processes / "logs" / "host-3.log").read_text()  # one process per host
    assert all((processes / "models" / f"worker-{unit}.safetensors").exists() for unit in range(6))


@pytest.mark.slow
@pytest.mark.mqtt
def test_units_of_a_host_behind_device_bridges_play_as_in_process(tmp_path: Path) -> None:
    bridged, local = tmp_path / "bridged", tmp_path / "local"
    assert train(bridged, "--units-per-host", "3", "--device-link", "mqtt", "--max-rounds", "1") == 0
    assert train(local, "--max-rounds", "1") == 0
    assert {(r["worker"], r["score"]) for r in rows(bridged)} == {
        (r["worker"], r["score"]) for r in rows(local)
    }


@pytest.mark.parametrize(
    ("extra", "words"),
    [
        (("--units-per-host", "0"), "at least 1"),
        (("--units-per-host", "2", "--scheme", "fedavg"), "pergrad"),
        (("--units-per-host", "2", "--mode", "individual"), "--mode federated"),
    ],
)
def test_a_run_refuses_hosts_it_cannot_have_before_anything_starts(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], extra: tuple[str, ...], words: str
) -> None:
    assert train(tmp_path / "run", *extra) == 2
    error = capsys.readouterr().err.strip().splitlines()
    assert any("--units-per-host" in line and words in line for line in error), error
    assert not (tmp_path / "run").exists()


@pytest.mark.parametrize(
    "extra",
    [
        ("--preset", "paper"),
        ("--pace", "0.05", "--slow", "w1=1.5", "--link-delay", "w4=0.01"),
        ("--absent", "0.3", "--absent-rounds", "1", "--stall", "w2=0.3"),
    ],
)
def test_every_preset_and_uneven_fleet_runs_in_hosts(tmp_path: Path, extra: tuple[str, ...]) -> None:
    out = tmp_path / "run"
    assert train(out, "--units-per-host", "3", "--max-rounds", "3", "--target-score", "1e9", *extra) == 0
    played = {(r["worker"], r["round"]) for r in rows(out)}
    assert played == {(str(unit), str(r)) for unit in range(6) for r in (1, 2, 3)}
    assert json.loads((out / "config.json").read_text())["units_per_host"] == 3


def test_hosts_carry_the_units_in_order_the_last_what_is_left() -> None:
    assert host_groups(7, 3) == [[0, 1, 2], [3, 4, 5], [6]]
    assert host_groups(3, 1) == [[0], [1], [2]]
