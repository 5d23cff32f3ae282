"""Command-line values and errors."""

import pytest

from fleetrl.cli.main import main
from fleetrl.cli.parsing import parse_overrides


def test_overrides_are_json_typed() -> None:
    assert parse_overrides(
        ["clip_eps=0.2", "normalise_advantages=true", "activation=tanh", "hidden=[64,64]"]
    ) == {
        "clip_eps": 0.2,
        "normalise_advantages": True,
        "activation": "tanh",
        "hidden": (64, 64),
    }


def test_override_without_equals_is_refused() -> None:
    with pytest.raises(ValueError, match="KEY=VALUE"):
        parse_overrides(["clip_eps"])


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["--env", "qbe"], "unknown env 'qbe' (choose cartpole or qube)"),
        (["--preset", "fancy"], "fancy"),
        (["--mode", "solo"], "unknown mode 'solo'"),
        (["--units", "0"], "--units must be at least 1"),
        (["--set", "no_such_field=1"], "unknown PPO setting"),
    ],
)
def test_train_reports_bad_arguments_in_one_line(tmp_path, capsys, argv: list[str], message: str) -> None:
    code = main(["train", "--out", str(tmp_path / "run"), "--no-live", *argv])
    assert code == 2
    err = capsys.readouterr().err
    assert message in err and "Traceback" not in err
    assert not (tmp_path / "run" / "metrics.csv").exists()
