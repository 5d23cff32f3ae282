"""The garbage collector is paused while a command starts, and runs again whatever happened there."""

from __future__ import annotations

import gc
from collections.abc import Iterator
from pathlib import Path

import pytest

from fleetrl.cli.main import main
from fleetrl.cli.startup import collector_paused


@pytest.fixture(autouse=True)
def collector_as_it_was() -> Iterator[None]:
    """Each test starts with the collector on and leaves it on, nothing frozen by it."""
    gc.enable()
    yield
    gc.unfreeze()
    gc.enable()


def test_the_collector_is_off_inside_and_on_after_with_what_exists_frozen() -> None:
    frozen = gc.get_freeze_count()
    with collector_paused():
        assert not gc.isenabled()
        kept = [[n] for n in range(1000)]
    assert gc.isenabled()
    assert gc.get_freeze_count() >= frozen + len(kept)


def test_an_error_inside_still_turns_the_collector_on_and_is_raised() -> None:
    with pytest.raises(ImportError, match="no_such_module"), collector_paused():
        import no_such_module  # type: ignore[import-not-found]  # noqa: F401
    assert gc.isenabled()


def test_a_collector_already_off_stays_off_and_nothing_is_frozen() -> None:
    gc.disable()
    frozen = gc.get_freeze_count()
    with collector_paused():
        assert not gc.isenabled()
    assert not gc.isenabled() and gc.get_freeze_count() == frozen


def test_a_refused_setting_is_the_same_one_line_error_and_the_collector_runs_after(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["train", "--env", "qbe", "--out", str(tmp_path / "run")]) == 2
    assert "fleetrl train: error: --env: unknown env 'qbe'" in capsys.readouterr().err
    assert gc.isenabled() and not (tmp_path / "run").exists()


def test_without_freeze_nothing_is_frozen() -> None:
    frozen = gc.get_freeze_count()
    with collector_paused(freeze=False):
        assert not gc.isenabled()
    assert gc.isenabled() and gc.get_freeze_count() == frozen


def test_a_command_called_again_freezes_nothing_new(tmp_path: Path) -> None:
    """The parser (garbage once it has parsed) is not frozen: a process that calls main() many times, like a
    test run, does not keep every call's parser."""
    refused = ["train", "--env", "qbe", "--out", str(tmp_path / "run")]
    assert main(refused) == 2
    frozen = gc.get_freeze_count()
    for _ in range(3):
        assert main(refused) == 2
    assert gc.get_freeze_count() == frozen
