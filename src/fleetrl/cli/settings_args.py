"""Settings from a ``--config`` TOML file and the flags given (flags win): ``train``, ``chief``, ``worker``.

Every flag of those commands has ``default=None`` (not given) and a ``dest`` that is a field of the command's
settings class (:mod:`fleetrl.runs.settings`, :mod:`fleetrl.runs.role_settings`): the defaults live in one
place, the dataclass, and every flag has a config-file key of the same name.
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any, TypeVar

from fleetrl.cli.parsing import parse_overrides

S = TypeVar("S")

CONNECT_TIMEOUT = 60.0  # fleetrl.runs.role_settings.CONNECT_TIMEOUT, without importing torch for --help

NOT_SETTINGS = frozenset({"command", "handler", "verbose", "config"})
"""parsed names that are not settings"""


def add_config_argument(p: argparse.ArgumentParser) -> None:
    """``--config FILE``: settings from a TOML file; flags given on the command line override it."""
    p.add_argument(
        "--config",
        type=Path,
        default=None,
        metavar="FILE",
        help="read settings from this TOML file (keys: the flags' names with _ for -); flags override it",
    )


def add_learning_arguments(p: argparse.ArgumentParser) -> None:
    """The learning options of ``train``, ``chief`` and ``worker`` (defaults: fleetrl.runs.settings)."""
    add_env_argument(p, default=None)
    add_target_score_argument(p)
    add_fleet_profile_argument(p)
    p.add_argument(
        "--preset",
        default=None,
        help="PPO preset: standard (default; learns on every unit type measured), paper (Table 1 as "
        "written, to reproduce the paper) or paper-code (what the authors' code ran)",
    )
    p.add_argument(
        "--max-rounds", type=int, default=None, help="the paper's M: most rounds per worker (1000)"
    )
    p.add_argument(
        "--scheme",
        default=None,
        help="federated: pergrad (default; gradients averaged at every optimisation step), paper (the "
        "paper's: gradient sharing + model transfer), fedavg (model averaging), fedavgm or fedadam (fedavg "
        "with a server optimiser)",
    )
    p.add_argument(
        "--scheme-param",
        dest="scheme_params",
        action="append",
        default=None,
        metavar="KEY=VALUE",
        help="one parameter of the scheme, e.g. --scheme-param momentum=0.9 (repeatable; all roles agree)",
    )
    p.add_argument(
        "--set",
        dest="overrides",
        action="append",
        default=None,
        metavar="KEY=VALUE",
        help="override one PPO setting of the preset, e.g. --set clip_eps=0.2 (repeatable; all roles agree)",
    )


def add_env_argument(p: argparse.ArgumentParser, default: str | None) -> None:
    """``--env``: a built-in unit type, or the user's own as ``package.module:factory``."""
    p.add_argument(
        "--env",
        default=default,
        metavar="ENV",
        help="the unit type: qube (QUBE-Servo 2 balance; default), cartpole, or your own as "
        "package.module:factory, where factory(unit: int, fleet_seed: int) -> gymnasium.Env builds unit "
        "`unit` of your fleet (imported from the current directory or the installed packages)",
    )


def add_target_score_argument(p: argparse.ArgumentParser) -> None:
    """``--target-score``: the completion criterion's target."""
    p.add_argument(
        "--target-score",
        type=float,
        default=None,
        metavar="X",
        help="learning is complete when the weighted moving average of the last 10 scores reaches X "
        "(default: qube 2450, cartpole 475, a factory's env spec reward_threshold; all roles agree)",
    )


def add_fleet_profile_argument(p: argparse.ArgumentParser) -> None:
    """``--fleet-profile``: which per-unit variation the simulated QUBE fleet is drawn with."""
    p.add_argument(
        "--fleet-profile",
        default=None,
        metavar="NAME",
        help="QUBE fleet profile: table2 (default; fitted to the paper's Table 2) or v1 (the first fleet); "
        "other unit types have one fleet",
    )


def add_round_arguments(p: argparse.ArgumentParser) -> None:
    """How the chief closes a round (``train`` and ``chief``)."""
    p.add_argument(
        "--aggregation",
        default=None,
        help="mean (default, the paper's), median, trimmed_mean[:β], clipped_mean[:C]",
    )
    p.add_argument(
        "--quorum",
        type=float,
        default=None,
        help="at the round deadline, close the round if this fraction of W answered (default 1.0)",
    )
    p.add_argument(
        "--round-timeout",
        type=float,
        default=None,
        help="round deadline in seconds (default: none, the paper's fully synchronous rule)",
    )


def add_broker_arguments(p: argparse.ArgumentParser, default: str) -> None:
    """``--broker`` and the password file (never the password itself on a command line)."""
    p.add_argument("--broker", default=None, help=f"mqtt://[user@]host:port or mqtts://…; {default}")
    p.add_argument(
        "--broker-password-file",
        type=Path,
        default=None,
        metavar="FILE",
        help="the broker password's file (else $FLEETRL_BROKER_PASSWORD; never put it in the URL)",
    )


def add_connect_timeout(p: argparse.ArgumentParser, default: float | None = CONNECT_TIMEOUT) -> None:
    """``--connect-timeout``: how long a standalone role retries an unreachable broker (start order does not
    matter) before it exits 1."""
    p.add_argument(
        "--connect-timeout",
        type=float,
        default=default,
        help=f"seconds to keep retrying an unreachable broker, with backoff (default {CONNECT_TIMEOUT:g})",
    )


def settings_from_args(cls: type[S], args: argparse.Namespace) -> S:
    """The command's validated settings object from ``--config`` and the flags given."""
    from fleetrl.runs.setting_values import build, load_toml

    file_values: dict[str, Any] = {} if args.config is None else load_toml(args.config)
    flags = {k: v for k, v in vars(args).items() if k not in NOT_SETTINGS}
    for table, flag in (("overrides", "--set"), ("scheme_params", "--scheme-param")):
        if flags.get(table) is not None:
            flags[table] = parse_overrides(flags[table], flag)
    return build(cls, file_values, flags, source=str(args.config or ""))
