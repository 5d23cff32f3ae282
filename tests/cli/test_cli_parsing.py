"""Command-line values and errors."""

import pytest

from fleetrl.cli.main import main
from fleetrl.cli.settings_args import parse_overrides


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
        (
            ["--env", "qbe"],
            "unknown env 'qbe' (choose cartpole, qube or qube-continuous, or your own unit type as",
        ),
        (["--preset", "fancy"], "fancy"),
        (["--mode", "solo"], "unknown mode 'solo'"),
        (["--units", "0"], "--units = 0: must be at least 1"),
        (["--set", "no_such_field=1"], "unknown PPO setting"),
        # issue 14: each of these ended in a traceback, or was refused only after the run directory existed
        (["--set", "clip_eps=abc"], "--set clip_eps = 'abc': expected a number"),
        (["--set", "clip_eps=-1"], "clip_eps must be > 0, got -1"),
        (["--set", 'hidden=[64,"x"]'], "--set hidden = 'x': expected an integer"),
        (["--set", "activation=sigmoid"], "expected one of 'tanh', 'relu'"),
        (["--aggregation", "medain"], "--aggregation: unknown aggregator 'medain' (choose"),
        (["--scheme", "fedavrg"], "--scheme: unknown federation scheme 'fedavrg'"),
        (
            ["--scheme", "fedavg", "--quorum", "0.5"],
            "scheme 'fedavg': a quorum below 1 needs a round timeout",
        ),
        (["--max-staleness", "-1"], "max_staleness must be >= 0 rounds, got -1"),
        (["--quorum", "1.5", "--round-timeout", "1"], "quorum must be in (0, 1], got 1.5"),
        (["--round-timeout", "-2"], "round_timeout must be > 0 seconds, got -2.0"),
        (["--broker", "http://x:1"], "--broker: bad broker URL 'http://x:1'"),
        (["--broker", "mqtt://h:1", "--broker-password-file", "/no/such/file"], "cannot read it"),
        (["--mode", "individual", "--scheme", "fedavg"], "needs --mode federated"),
    ],
)
def test_train_reports_bad_arguments_in_one_line(tmp_path, capsys, argv: list[str], message: str) -> None:
    code = main(["train", "--out", str(tmp_path / "run"), "--no-live", *argv])
    assert code == 2
    err = capsys.readouterr().err
    assert message in err and "Traceback" not in err
    assert not (tmp_path / "run").exists()  # nothing was created


def test_train_without_out_names_the_missing_setting(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["train", "--no-live"]) == 2
    assert "missing setting(s): --out" in capsys.readouterr().err
