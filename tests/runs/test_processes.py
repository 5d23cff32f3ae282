"""Worker processes: forked from the launcher or started as new interpreters, the same rounds come back."""

import queue
from pathlib import Path

import pytest

from fleetrl.runs.processes import START_ENV, ProcessFleet, WorkerExit, fork_available
from fleetrl.runs.records import MetricsRow
from fleetrl.runs.settings import ALONE_SCHEME, LearningSettings, resolve_learning
from fleetrl.runs.spec import WorkerSpec

pytestmark = pytest.mark.slow  # worker processes that train


def spec(worker: int, rounds: int, out: Path) -> WorkerSpec:
    """Worker ``worker`` of a CartPole fleet alone, seed 3."""
    learning = LearningSettings(env="cartpole", preset="standard", seed=3, max_rounds=rounds)
    return WorkerSpec(
        worker=worker,
        unit=worker,
        learning=resolve_learning(learning, default_scheme=ALONE_SCHEME),
        out=str(out),
    )


Played = list[tuple[int, int, float, int]]


def play(out: Path, units: int = 2, rounds: int = 3) -> tuple[Played, dict[int, int]]:
    """Individual runs of ``units`` CartPole workers as a ProcessFleet: their (worker, round, score, steps)
    and exit codes."""
    commands = {k: [spec(k, rounds, out).to_json()] for k in range(units)}
    (out / "models").mkdir(parents=True)
    fleet = ProcessFleet(commands, out / "logs")
    records: Played = []
    codes: dict[int, int] = {}
    while len(codes) < units:
        event = fleet.events.get(timeout=120)
        if isinstance(event, MetricsRow):
            records.append((event.worker, event.round, event.score, event.steps))
        else:
            assert isinstance(event, WorkerExit)
            codes[event.worker] = event.returncode
    fleet.wait(10)
    with pytest.raises(queue.Empty):
        fleet.events.get_nowait()
    return sorted(records), codes


@pytest.mark.skipif(not hasattr(__import__("os"), "fork"), reason="no fork on this OS")
def test_forked_and_spawned_workers_play_the_same_rounds(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv(START_ENV, "fork")
    forked, forked_codes = play(tmp_path / "fork")
    monkeypatch.setenv(START_ENV, "spawn")
    spawned, spawned_codes = play(tmp_path / "spawn")
    assert forked_codes == spawned_codes == {0: 0, 1: 0}
    assert len(forked) == 6 and forked == spawned
    for k in (0, 1):  # each child logged to its own file and saved its model
        assert "learner ready" in (tmp_path / "fork" / "logs" / f"worker-{k}.log").read_text()
        assert (tmp_path / "fork" / "models" / f"worker-{k}.safetensors").stat().st_size > 1000


def test_the_start_method_is_checked(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv(START_ENV, "spawn")
    assert not fork_available()
    monkeypatch.setenv(START_ENV, "vfork")
    with pytest.raises(ValueError, match="use fork or spawn"):
        fork_available()
