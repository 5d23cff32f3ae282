"""``fleetrl experiment`` is the lab's: found through an entry point, and named as missing where it is."""

import importlib.metadata

import pytest

from fleetrl.cli.main import LAB_MISSING, main


def test_without_the_lab_experiment_says_how_to_get_it(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    monkeypatch.setattr(importlib.metadata, "entry_points", lambda **_: [])
    assert main(["experiment", "fig5", "--quick"]) == 2
    assert LAB_MISSING in capsys.readouterr().err


def test_every_argument_after_experiment_goes_to_the_lab(monkeypatch: pytest.MonkeyPatch) -> None:
    seen: list[list[str]] = []

    class Found:
        def load(self) -> object:
            return lambda argv: seen.append(list(argv)) or 0

    monkeypatch.setattr(importlib.metadata, "entry_points", lambda **_: [Found()])
    assert main(["experiment", "--help"]) == 0
    assert main(["experiment", "fig5", "--seeds", "3", "-v"]) == 0
    assert seen == [["--help"], ["fig5", "--seeds", "3", "-v"]]
