"""A run's record: built from a run directory (with or without an ``episodes`` column), written compactly,
read back to the same numbers; anything else is not a record."""

import json
from pathlib import Path

import pytest
from experiment_fakes import record, write_record_of, write_run_dir

from fleetrl_lab.arms import Places, arm
from fleetrl_lab.records import build_record, read_record, unseen_units, write_record

ALONE = arm("cartpole", 2, "individual", "standard", 10, "alone")


@pytest.mark.parametrize("episodes", [False, True])
def test_a_record_built_from_a_run_directory_reads_back_the_same(tmp_path: Path, episodes: bool) -> None:
    run = ALONE.run(Places(tmp_path / "runs", tmp_path / "records"), 100)
    write_run_dir(run, {0: [9.0, 20.456, 500.0], 1: [8.0, 7.0, 6.0]}, {0: 3, 1: None}, episodes=episodes)
    data = build_record(run.out, run.command(), run.expected, "host A", unseen=0)
    write_record(run.record, data)
    kept = read_record(run.record)
    assert kept is not None and kept.data == json.loads(json.dumps(data))
    assert kept.result_settings == run.expected and kept.host == "host A" and kept.wall_seconds == 12.3
    assert kept.scores() == {0: [9, 20.46, 500], 1: [8, 7, 6]}
    completion = kept.completion()
    assert completion.per_worker == {"0": 3, "1": None} and completion.fleet == 10 and not completion.complete
    worker = kept.data["workers"]["0"]
    assert worker["events"] == {"3": "completed"}  # plain sharing rounds are not kept
    assert ("episodes" in worker) is episodes and worker.get("episodes", [2, 2, 2]) == [2, 2, 2]
    text = run.record.read_text()
    assert '"score":[9,20.46,500]' in text and len(text.splitlines()) < 50  # one line per worker


def test_round_records_carry_scores_and_events_for_the_plots(tmp_path: Path) -> None:
    run = ALONE.run(Places(tmp_path / "runs", tmp_path / "records"), 1)
    rows = (read_record(_written(run, record(run, fleet=3, units=2))) or pytest.fail()).round_records()
    assert [(r.worker, r.round, r.score) for r in rows if r.worker == 1] == [(1, 1, 1.0), (1, 2, 2.0)]


def _written(run, data) -> Path:  # type: ignore[no-untyped-def]
    write_record(run.record, data)
    return run.record


@pytest.mark.parametrize(
    "text", ["", "{not json", "[]", '{"format": 0, "result_settings": {}}', '{"format": 1}']
)
def test_anything_else_is_not_a_record(tmp_path: Path, text: str) -> None:
    path = tmp_path / "seed-1.json"
    path.write_text(text)
    assert read_record(path) is None
    assert read_record(tmp_path / "missing.json") is None


def test_unseen_units_follow_the_trained_ones() -> None:
    assert unseen_units(3, 2) == [10, 11]
    assert unseen_units(12, 3) == [12, 13, 14]


def test_episodes_to_completion_counts_a_units_episodes_until_its_criterion_held(tmp_path: Path) -> None:
    run = ALONE.run(Places(tmp_path / "runs", tmp_path / "records"), 100)
    write_run_dir(run, {0: [9.0, 20.0, 500.0], 1: [8.0, 7.0, 6.0]}, {0: 2, 1: None}, episodes=True)
    kept = read_record(
        write_record_of(run, build_record(run.out, run.command(), run.expected, "h", unseen=0))
    )
    assert kept is not None
    # two episodes per round: unit 0 held at round 2 (4 episodes), unit 1 never (all 6 it played)
    assert kept.episodes_to_completion() == {0: (4, True), 1: (6, False)}


def test_a_run_of_one_episode_per_round_has_no_episode_count(tmp_path: Path) -> None:
    run = ALONE.run(Places(tmp_path / "runs", tmp_path / "records"), 100)
    write_run_dir(run, {0: [9.0, 500.0]}, {0: 2}, episodes=False)
    kept = read_record(
        write_record_of(run, build_record(run.out, run.command(), run.expected, "h", unseen=0))
    )
    assert kept is not None and kept.episodes_to_completion() is None


def test_a_unit_that_missed_rounds_keeps_their_numbers_and_its_time_on_the_rigs(tmp_path: Path) -> None:
    fed = arm("cartpole", 2, "federated", "standard", 10, "fed", "pergrad")
    run = fed.run(Places(tmp_path / "runs", tmp_path / "records"), 100)
    write_run_dir(run, {0: [9.0, 20.0, 500.0], 1: [8.0, 7.0, 500.0]}, {0: 3, 1: 3})
    metrics = run.out / "metrics.csv"
    lines = metrics.read_text().splitlines()
    metrics.write_text("\n".join(line for line in lines if not line.startswith("2,1,")) + "\n")  # a straggler
    kept = read_record(
        write_record_of(run, build_record(run.out, run.command(), run.expected, "h", unseen=0))
    )
    assert kept is not None
    assert kept.data["workers"]["1"]["rounds"] == [1, 3] and "rounds" not in kept.data["workers"]["0"]
    rig = kept.rig_time()
    assert rig is not None and rig.complete  # round 3 is unit 1's second row, not a round it never played
    assert rig.per_unit == {"0": pytest.approx(3.0), "1": pytest.approx(3.0)}  # 3 rounds of 50 steps × 20 ms


def test_unseen_units_score_each_distinct_model_once_and_every_worker_its_own(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    from fleetrl.agent.config import PPOConfig
    from fleetrl.envs.catalog import describe_env
    from fleetrl.runs import evaluate
    from fleetrl.runs.factory import agent_for
    from fleetrl.runs.rundir import model_path
    from fleetrl_lab import records

    unit = describe_env("cartpole")
    shared, own = (agent_for(unit, PPOConfig(), seed=s) for s in (1, 2))
    for worker, agent in ((0, shared), (1, shared), (2, own)):  # workers 0 and 1: one policy's files
        model_path(tmp_path, worker).parent.mkdir(parents=True, exist_ok=True)
        agent.save(model_path(tmp_path, worker))
    calls: list[tuple[str, int]] = []
    real = evaluate.evaluate_model

    def counted(model: Path, env: str, unit: int, *args: object) -> list[float]:
        calls.append((model.name, unit))
        return real(model, env, unit, *args)  # type: ignore[arg-type]

    monkeypatch.setattr(records, "evaluate_model", counted)
    settings = {"units": 3, "env": "cartpole", "fleet_seed": 0, "fleet_profile": None}
    unseen = records.evaluate_unseen(tmp_path, settings, 2)
    assert sorted(calls) == [(f"worker-{w}.safetensors", u) for w in (0, 2) for u in (10, 11)]
    scores = unseen["scores"]
    assert scores["0"] == scores["1"] and len(scores["2"]) == 2
    for unit_index, u in enumerate((10, 11)):  # each score is the model's own evaluation on that unit
        alone = real(model_path(tmp_path, 1), "cartpole", u, 0, 1, 0, None)[0]
        assert scores["1"][unit_index] == pytest.approx(alone, abs=0.01)
