"""``fleetrl control`` as a user runs it: each episode's score printed; no torch imported on its path (model
file or ONNX); Ctrl-C or SIGTERM leaves the unit with its motor off; bad input is one clear line, exit 2."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import onnx
import pytest
from onnx import TensorProto, helper

from fleetrl.cli.main import main
from fleetrl.control.export import export_policy
from fleetrl.runs.evaluate import evaluate_model

HERE = Path(__file__).resolve().parent
SRC = HERE.parents[1] / "src"
IMPORTS = """
import sys
from fleetrl.cli.main import main
code = main(sys.argv[1:])
print("exit", code, "torch", "torch" in sys.modules, "onnx", "onnx" in sys.modules, flush=True)
"""


def child_env(**extra: str) -> dict[str, str]:
    return {**os.environ, "PYTHONPATH": str(SRC), **extra}


def test_each_episode_s_score_is_printed(models: dict[str, Path], capsys: pytest.CaptureFixture[str]) -> None:
    want = evaluate_model(models["fresh"], "qube", 1, 0, 3, 5)  # fleetrl evaluate's scores, unit 1, seed 5
    assert main(["control", str(models["fresh"]), "--episodes", "3", "--unit", "1", "--seed", "5"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines[0].startswith("unit 1: ") and "on qube (sim, lockstep), 3 episodes" in lines[0]
    assert lines[1:4] == [f"episode {k + 1}: score {score:g}" for k, score in enumerate(want)]
    assert lines[4:] == [f"mean score {sum(want) / 3:g} over 3 episodes"] and len(set(want)) > 1


def test_a_units_own_policy_runs_exported_as_fleetrl_evaluate_plays_it(
    models: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A unit's model file (its own head offset holds the balance law): exported, ``fleetrl control`` plays
    the scores ``fleetrl evaluate`` gives the model file, and they are the unit's own policy's (it holds the
    pendulum to the cap), not the shared part's alone."""
    onnx_file = tmp_path / "unit.onnx"
    assert export_policy(models["balancing-own"], onnx_file, "qube").passed
    want = evaluate_model(models["balancing-own"], "qube", 0, 0, 2, 7)
    capsys.readouterr()
    assert main(["control", str(onnx_file), "--episodes", "2", "--seed", "7"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines[1:3] == [f"episode {k + 1}: score {score:g}" for k, score in enumerate(want)]
    assert want == [2500.0, 2500.0]


@pytest.mark.slow
@pytest.mark.parametrize("kind", ["model file", "onnx"])
def test_the_controller_s_path_imports_no_torch(models: dict[str, Path], tmp_path: Path, kind: str) -> None:
    model = models["balancing"]
    if kind == "onnx":
        model = tmp_path / "policy.onnx"
        assert export_policy(models["balancing"], model, "qube").passed
    done = subprocess.run(
        [sys.executable, "-c", IMPORTS, "control", str(model), "--episodes", "1"],
        capture_output=True,
        text=True,
        timeout=300,
        env=child_env(),
    )
    assert "episode 1: score 2500" in done.stdout, done.stderr
    assert done.stdout.splitlines()[-1] == "exit 0 torch False onnx False"


@pytest.mark.slow
@pytest.mark.parametrize("stop", [signal.SIGINT, signal.SIGTERM])
def test_an_interrupt_leaves_the_motor_off(
    models: dict[str, Path], tmp_path: Path, stop: signal.Signals
) -> None:
    log = tmp_path / "driver.log"
    argv = ["control", str(models["balancing"]), "--driver", "recording_driver:driver", "--realtime"]
    child = subprocess.Popen(
        [sys.executable, "-m", "fleetrl.cli.main", *argv, "--rt-priority", "0", "--episodes", "20"],
        cwd=HERE,  # the driver's module, as a user's from the current directory
        env=child_env(FLEETRL_TEST_DRIVER_LOG=str(log)),
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        deadline = time.monotonic() + 120
        while (not log.exists() or log.read_text().count("write") < 200) and time.monotonic() < deadline:
            time.sleep(0.05)  # the policy is holding the pendulum in real time
        assert child.poll() is None, child.communicate()
        child.send_signal(stop)
        _, err = child.communicate(timeout=60)
    finally:
        if child.poll() is None:
            child.kill()
    assert child.returncode == 130 and err.strip().splitlines()[-1] == "interrupted", err
    calls = log.read_text().splitlines()
    last_write = max(i for i, call in enumerate(calls) if call.startswith("write"))
    assert (
        "off" in calls[last_write:] and calls[-1] == "close"
    )  # motor off after the last command, then closed


def no_metadata_onnx(path: Path) -> Path:
    node = helper.make_node("Identity", ["observation"], ["action"])
    io = [helper.make_tensor_value_info(n, TensorProto.FLOAT, [1, 4]) for n in ("observation", "action")]
    graph = helper.make_graph([node], "plain", io[:1], io[1:])
    onnx.save(helper.make_model(graph, opset_imports=[helper.make_opsetid("", 17)], ir_version=8), str(path))
    return path


def bad_inputs(tmp_path: Path, models: dict[str, Path]) -> dict[str, tuple[list[str], str]]:
    (tmp_path / "policy.txt").write_text("weights")
    (tmp_path / "broken.onnx").write_bytes(np.arange(20, dtype=np.uint8).tobytes())
    plain = no_metadata_onnx(tmp_path / "plain.onnx")
    return {
        "missing": ([str(tmp_path / "none.onnx")], "no model file at"),
        "other suffix": ([str(tmp_path / "policy.txt")], "give a fleetrl model file"),
        "not onnx": ([str(tmp_path / "broken.onnx")], "is not an ONNX model onnxruntime can load"),
        "not exported": ([str(plain)], "not a policy fleetrl exported"),
        "other env": ([str(models["cartpole"]), "--env", "qube"], "env 'qube' has 4 and Discrete(3)"),
        "no episodes": ([str(models["fresh"]), "--episodes", "0"], "--episodes must be at least 1"),
        "bad driver": ([str(models["fresh"]), "--driver", "simulated"], "--driver 'simulated': choose sim"),
        "bad watchdog": ([str(models["fresh"]), "--watchdog-ms", "0"], "--watchdog-ms must be positive"),
    }


@pytest.mark.parametrize(
    "case",
    [
        "missing",
        "other suffix",
        "not onnx",
        "not exported",
        "other env",
        "no episodes",
        "bad driver",
        "bad watchdog",
    ],
)
def test_bad_input_is_one_clear_line_and_exit_2(
    models: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str], case: str
) -> None:
    argv, message = bad_inputs(tmp_path, models)[case]
    assert main(["control", *argv]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and err.startswith("fleetrl control: error: ") and message in err, err


def test_your_own_unit_type_runs_through_its_own_driver(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    """``--env package.module:factory --driver package.module:function`` (tests/link/slider_units.py, a
    continuous unit of 2 observations): the scores of ``fleetrl evaluate`` on the in-process unit."""
    from control_models import fresh_model

    monkeypatch.chdir(HERE.parents[1])  # the user's modules, from the current directory
    env, driver = "tests.link.slider_units:factory", "tests.link.slider_units:driver"
    model = fresh_model(tmp_path / "slider.safetensors", env, seed=2)
    want = evaluate_model(model, env, 0, 0, 3, 0)
    assert main(["control", str(model), "--env", env, "--driver", driver, "--episodes", "3"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines[1:4] == [f"episode {k + 1}: score {score:g}" for k, score in enumerate(want)]
