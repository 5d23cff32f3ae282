"""``fleetrl device --driver``: the simulated default, the QUBE SPI driver's options, and clear errors (no
traceback, non-zero exit) where the hardware or its package is missing or the options do not fit."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

from fleetrl.cli.main import build_parser, main

BROKER = ["--broker", "mqtt://127.0.0.1:1"]  # never reached: each case fails before connecting


def test_the_driver_options_parse() -> None:
    args = build_parser().parse_args(["device", "--unit", "0"])
    assert (args.driver, args.spi_bus, args.spi_device, args.spi_device_id) == ("sim", 0, 0, None)
    args = build_parser().parse_args(
        ["device", "--unit", "0", "--driver", "qube-spi", "--spi-bus", "1", "--spi-device", "1"]
    )
    assert (args.driver, args.spi_bus, args.spi_device) == ("qube-spi", 1, 1)


def test_without_spidev_the_error_names_the_extra(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    monkeypatch.setitem(sys.modules, "spidev", None)  # as on a machine without the [pi] extra
    assert main(["device", "--unit", "0", "--driver", "qube-spi", *BROKER]) == 1
    err = capsys.readouterr().err
    assert "pip install 'fleetrl[pi]'" in err and "Traceback" not in err


@pytest.mark.parametrize(
    ("options", "message"),
    [
        (["--env", "cartpole"], "drives a qube unit, not 'cartpole'"),
        (["--spi-bus", "-1"], "--spi-bus and --spi-device must be >= 0"),
        (["--spi-device-id", "qube"], "--spi-device-id 'qube' is not a number"),
        (["--spi-device-id", "0x10000"], "is not a 16-bit id"),
        (["--period-ms", "0"], "--period-ms must be positive"),
    ],
)
def test_bad_qube_spi_options_are_one_clear_line(
    options: list[str], message: str, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["device", "--unit", "0", "--driver", "qube-spi", *options, *BROKER]) == 2
    err = capsys.readouterr().err
    assert message in err and "Traceback" not in err


@pytest.mark.parametrize(
    ("options", "message"),
    [
        (["--driver", "tests.link.no_such_module:driver"], "device driver "
         "'tests.link.no_such_module:driver': cannot import module 'tests.link.no_such_module'"),
        (["--driver", "tests.link.slider_units:NOT_CALLABLE"], "'NOT_CALLABLE' is a int, not callable"),
        (["--driver", "tests.link.slider_units:not_a_driver"], "returned a dict for unit 0, "
         "not a DeviceDriver"),
        (["--driver", "simulated"], "--driver 'simulated': choose sim, qube-spi or your own as "
         "package.module:function"),
        (["--driver", "tests.link.slider_units:driver", "--env", "qube", "--period-ms", "5"],
         "--env, --period-ms configure built-in simulated units; driver 'tests.link.slider_units:driver' "
         "builds its own unit"),
    ],
)  # fmt: skip
def test_a_bad_user_driver_is_one_clear_line(
    options: list[str], message: str, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.chdir(Path(__file__).resolve().parents[2])  # the driver's module from the current directory
    assert main(["device", "--unit", "0", *options, *BROKER]) == 2
    err = capsys.readouterr().err
    assert message in err and "Traceback" not in err and len(err.strip().splitlines()) == 1
