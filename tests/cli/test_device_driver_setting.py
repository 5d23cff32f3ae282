"""``fleetrl train --device-link mqtt --device-driver package.module:function`` for a user's unit type: each
way the pair can be wrong is one line on stderr and exit code 2, before anything starts or is created
(tests/link/slider_units.py holds the unit type and its broken drivers)."""

from __future__ import annotations

from pathlib import Path

import pytest
from cli_helpers import refused_in_process as refused

from fleetrl.runs.settings import LearningSettings, RunSettings

REPO = Path(__file__).resolve().parents[2]
SLIDER = "tests.link.slider_units"
BRIDGES = ["--env", f"{SLIDER}:factory", "--device-link", "mqtt", "--target-score", "50"]


@pytest.fixture(autouse=True)
def _from_the_repository(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(REPO)  # the modules are imported from the current directory


@pytest.mark.parametrize(
    ("driver", "message"),
    [
        ("tests.link.no_such_module:driver", "--device-driver: device driver "
         "'tests.link.no_such_module:driver': cannot import module 'tests.link.no_such_module' "
         "(ModuleNotFoundError"),
        (f"{SLIDER}.driver", f"--device-driver: device driver '{SLIDER}.driver' is not in "
         "package.module:function form"),
        (f"{SLIDER}:no_such_driver", f"module '{SLIDER}' has no attribute 'no_such_driver'"),
        (f"{SLIDER}:NOT_CALLABLE", "'NOT_CALLABLE' is a int, not callable (it must be "
         "driver(unit: int, fleet_seed: int, *, realtime: bool) -> DeviceDriver)"),
        (f"{SLIDER}:not_a_driver", "--device-driver: driver function not_a_driver returned a dict for "
         "unit 0, not a DeviceDriver"),
        (f"{SLIDER}:qube_driver", "--device-driver: device driver 'qube' (unit 0) declares 4 sensor "
         "values; the env observes 2"),
        (f"{SLIDER}:wide_driver", "--device-driver: device driver 'wide' (unit 0) takes a command vector "
         "of 2; the env's actions are Box(1,)"),
    ],
)  # fmt: skip
def test_a_bad_device_driver_is_one_line_and_exit_2(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], driver: str, message: str
) -> None:
    line = refused(tmp_path, capsys, *BRIDGES, "--device-driver", driver)
    assert line.startswith("fleetrl train: error: --") and message in line


def test_a_factory_without_a_link_keyword_cannot_be_served(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    argv = ["--env", "tests.envs.fake_units:factory", "--device-link", "mqtt"]
    line = refused(tmp_path, capsys, *argv, "--device-driver", f"{SLIDER}:driver")
    assert (
        "--device-link: unit factory 'tests.envs.fake_units:factory' takes no link keyword: to put its "
        in line
    )
    assert "define it as factory(unit, fleet_seed, link=None)" in line


def test_a_factory_behind_bridges_needs_its_driver(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    line = refused(tmp_path, capsys, *BRIDGES)
    assert (
        f"--device-link: unit factory '{SLIDER}:factory' needs --device-driver package.module:function"
        in line
    )


def test_a_device_driver_needs_device_bridges(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    line = refused(tmp_path, capsys, "--env", f"{SLIDER}:factory", "--device-driver", f"{SLIDER}:driver")
    assert "--device-driver names what device bridges serve: it needs --device-link mqtt" in line


def test_a_fitting_driver_is_accepted_and_is_a_result_setting(tmp_path: Path) -> None:
    learning = LearningSettings(env=f"{SLIDER}:factory", target_score=50.0)
    settings = RunSettings(out=tmp_path / "a", learning=learning, device_link="mqtt",
                           device_driver=f"{SLIDER}:driver").resolved()  # fmt: skip
    assert settings.result_settings()["device_driver"] == f"{SLIDER}:driver"
    cartpole = RunSettings(out=tmp_path / "b", learning=LearningSettings(env="cartpole"))
    assert cartpole.learning_resolved().result_settings()["device_driver"] is None
