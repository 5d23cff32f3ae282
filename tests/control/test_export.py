"""``fleetrl export``: the ONNX graph picks fleetrl's greedy actions (discrete and continuous QUBE) on 1,000
observations of the unit's episodes and around them; a failed check leaves no file; bad input is one line."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import onnx
import onnxruntime
import pytest
from onnx import numpy_helper

from fleetrl.agent.policy_file import read_policy_file
from fleetrl.agent.ppo import PPOAgent
from fleetrl.cli.main import main
from fleetrl.control import export
from fleetrl.control.export import draw_observations, export_policy
from fleetrl.envs.catalog import get_env_spec

CASES = [
    ("fresh", "qube"),
    ("balancing", "qube"),
    ("balancing-own", "qube"),
    ("fresh-continuous", "qube-continuous"),
    ("balancing-continuous", "qube-continuous"),
]


@pytest.mark.parametrize(("name", "env"), CASES)
def test_the_graph_acts_as_the_agent_on_1000_observations(
    models: dict[str, Path], tmp_path: Path, name: str, env: str
) -> None:
    out = tmp_path / "policy.onnx"
    check = export_policy(models[name], out, env)
    assert check.passed and check.observations == check.agreeing == 1000
    # independently of the command's own check: the file on a bare onnxruntime session against the agent
    # as fleetrl loads it (torch network, PPOAgent.act_greedy)
    agent = PPOAgent.load(models[name])
    observations = draw_observations(env, read_policy_file(models[name]), 1000, seed=1)
    session = onnxruntime.InferenceSession(str(out), providers=["CPUExecutionProvider"])
    got = session.run(["action"], {"observation": observations})[0]
    want = np.stack([np.asarray(agent.act_greedy(obs)) for obs in observations])
    if agent.action_space.is_discrete:
        assert got.dtype == np.int64 and got.shape == (1000,)
        assert np.array_equal(got, want)
        assert len(set(want.tolist())) >= 2  # the actions vary: equality says something
    else:
        low, high = agent.action_space.low[0], agent.action_space.high[0]
        assert got.dtype == np.float32 and got.shape == (1000, 1)
        assert np.abs(got - want).max() <= 1e-5 * (high - low) / 2
        assert got.min() >= low and got.max() <= high
        inside = (got > low) & (got < high)
        assert inside.any() and (~inside).any() == name.startswith("balancing")  # the law saturates: clipped
    meta = json.loads(onnx.load(str(out)).metadata_props[0].value)
    assert meta["env"] == env and meta["obs_dim"] == 4


def test_the_check_observations_come_from_the_unit_and_around_it(models: dict[str, Path]) -> None:
    policy = read_policy_file(models["fresh"])
    drawn = draw_observations("qube", policy, 1000, seed=2)
    assert drawn.shape == (1000, 4) and drawn.dtype == np.float32 and np.isfinite(drawn).all()
    assert np.array_equal(drawn, draw_observations("qube", policy, 1000, seed=2))  # seeded
    space = get_env_spec("qube").make(0, 0).env.observation_space
    assert all(space.contains(obs) for obs in drawn)
    assert len(np.unique(drawn, axis=0)) > 900  # not a few states repeated


def test_the_command_prints_the_check_and_writes_the_file(
    models: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "policy.onnx"
    assert main(["export", str(models["balancing"]), "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "check passed: onnxruntime's actions equal fleetrl's on 1000 of 1000 observations" in printed
    assert out.is_file() and not out.with_name("policy.onnx.partial").exists()


def test_the_env_comes_from_the_run_directory(
    models: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    run = tmp_path / "run"
    (run / "models").mkdir(parents=True)
    (run / "config.json").write_text(json.dumps({"env": "cartpole"}))
    model = run / "models" / "worker-0.safetensors"
    model.write_bytes(models["cartpole"].read_bytes())
    out = tmp_path / "cartpole.onnx"
    assert main(["export", str(model), "--out", str(out), "--check", "200"]) == 0
    assert "on 200 of 200 observations" in capsys.readouterr().out
    assert json.loads(onnx.load(str(out)).metadata_props[0].value)["env"] == "cartpole"


def test_a_graph_that_disagrees_fails_the_check_and_is_not_written(
    models: dict[str, Path],
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    original = export.policy_graph

    def flipped(*args: object, **kwargs: object) -> onnx.ModelProto:  # the policy head's weights negated
        model = original(*args, **kwargs)  # type: ignore[arg-type]
        for i, tensor in enumerate(model.graph.initializer):
            if tensor.name == "policy.weight":
                negated = -numpy_helper.to_array(tensor)
                model.graph.initializer[i].CopyFrom(numpy_helper.from_array(negated, tensor.name))
        return model

    monkeypatch.setattr(export, "policy_graph", flipped)
    out = tmp_path / "policy.onnx"
    assert main(["export", str(models["balancing"]), "--out", str(out)]) == 1
    printed = capsys.readouterr().out
    assert "check FAILED" in printed and "of 1000 observations" in printed
    assert not out.exists() and not list(tmp_path.iterdir())


def bad_files(tmp_path: Path, models: dict[str, Path]) -> dict[str, tuple[list[str], str]]:
    text = tmp_path / "notes.safetensors"
    text.write_text("not a model")
    from safetensors.numpy import save_file

    foreign = tmp_path / "foreign.safetensors"
    save_file({"w": np.zeros(3, dtype=np.float32)}, str(foreign))
    out = str(tmp_path / "p.onnx")
    return {
        "missing": ([str(tmp_path / "none.safetensors"), "--out", out], "no model file at"),
        "not safetensors": ([str(text), "--out", out], "is not a readable safetensors model file"),
        "not fleetrl": ([str(foreign), "--out", out], "is a safetensors file but not a fleetrl agent model"),
        "other env": (
            [str(models["cartpole"]), "--out", out, "--env", "qube"],
            "env 'qube' has 4 and Discrete(3)",
        ),
        "not .onnx": ([str(models["fresh"]), "--out", str(tmp_path / "p.txt")], "name the file .onnx"),
        "no dir": ([str(models["fresh"]), "--out", str(tmp_path / "no" / "p.onnx")], "no directory"),
        "no check": ([str(models["fresh"]), "--out", out, "--check", "0"], "--check must be at least 1"),
    }


@pytest.mark.parametrize(
    "case", ["missing", "not safetensors", "not fleetrl", "other env", "not .onnx", "no dir", "no check"]
)
def test_bad_input_is_one_clear_line_and_exit_2(
    models: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str], case: str
) -> None:
    argv, message = bad_files(tmp_path, models)[case]
    assert main(["export", *argv]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and err.startswith("fleetrl export: error: ") and message in err, err
    assert not (tmp_path / "p.onnx").exists()
