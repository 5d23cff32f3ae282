"""Settings from a ``--config`` TOML file and the flags given (flags win). A settings field's name is its flag
and config-file key, its type the flag's type, its docstring the help; every flag defaults to None (not
given), so a config file can set what no flag gives."""

from __future__ import annotations

import argparse
import functools
import json
import types
from pathlib import Path
from typing import Any, TypeVar, Union, get_args, get_origin

from fleetrl.federation.schemes import DEFAULT_SCHEME
from fleetrl.federation.shared_settings import LearningSettings
from fleetrl.runs.role_settings import RoleSettings
from fleetrl.runs.setting_values import (
    NEGATED_FLAGS,
    TABLE_FLAGS,
    TABLE_METAVARS,
    build,
    field_default,
    field_docs,
    flag,
    load_toml,
    required,
    setting_fields,
)
from fleetrl.runs.settings import BrokerLogin

S = TypeVar("S")

NOT_SETTINGS = frozenset({"command", "handler", "verbose", "config"})  # parsed names that are not settings


def add_settings_arguments(
    p: argparse.ArgumentParser, cls: type, *, notes: dict[str, str] | None = None
) -> None:
    """``--config FILE`` and one flag per setting of the settings class ``cls`` (its groups' too), each with
    its help from the field's docstring and ``notes`` (setting → what this command adds)."""
    p.add_argument(
        "--config",
        type=Path,
        default=None,
        metavar="FILE",
        help="read settings from this TOML file (keys: the flags' names with _ for -); flags override it",
    )
    notes = {"scheme": f"unset: {DEFAULT_SCHEME}"} | (notes or {})
    for name in setting_fields(cls):
        add_setting_argument(p, cls, name, note=notes.get(name))


def add_setting_argument(
    p: argparse.ArgumentParser, cls: type, name: str, *, defaulted: bool = False, note: str | None = None
) -> None:
    """The flag of setting ``name`` of the settings class ``cls``; with ``defaulted`` it gives the setting's
    default when not given (else None: the settings class's default applies)."""
    field, kind = setting_fields(cls)[name]
    default = field_default(field) if defaulted else None
    help_text = field_docs(cls).get(name, "")
    if note:
        help_text += f"; {note}"
    if name in TABLE_FLAGS:
        p.add_argument(
            flag(name), dest=name, action="append", default=None,
            metavar=TABLE_METAVARS.get(name, "KEY=VALUE"),
            help=f"{help_text} (repeatable)",
        )  # fmt: skip
        return
    if name in NEGATED_FLAGS:
        p.add_argument(flag(name), dest=name, action="store_false", default=None, help=f"not: {help_text}")
        return
    if kind is bool:
        p.add_argument(flag(name), dest=name, action="store_true", default=None, help=help_text)
        return
    if required(field):
        help_text += " (required)"
    else:
        shown = field_default(field)
        if shown is not None:
            help_text += f" (default: {shown})"
    p.add_argument(flag(name), dest=name, type=_parse_type(kind), default=default, help=help_text)


def _parse_type(kind: Any) -> Any:
    """The argparse ``type`` of a setting's type (for a choice such as a number or ``auto``: the first of
    them that reads the text)."""
    if get_origin(kind) in (Union, types.UnionType):
        options = [a for a in get_args(kind) if a is not type(None)]
        if len(options) > 1:
            return functools.partial(_first_that_reads, [_parse_type(option) for option in options])
        kind = options[0]
    return kind if kind in (int, float, Path) else str


def _first_that_reads(parsers: list[Any], text: str) -> Any:
    """``text`` as the first of ``parsers`` reads it (as text if none does)."""
    for parse in parsers:
        try:
            return parse(text)
        except ValueError:
            continue
    return text


def add_learning_argument(p: argparse.ArgumentParser, name: str, *, defaulted: bool = True) -> None:
    """The flag of learning setting ``name`` for a command that is not a role; with ``defaulted`` it gives
    the setting's default when not given."""
    add_setting_argument(p, LearningSettings, name, defaulted=defaulted)


def add_target_score_argument(p: argparse.ArgumentParser) -> None:
    """``--target-score``: the completion criterion's target."""
    add_learning_argument(p, "target_score")


def add_fleet_profile_argument(p: argparse.ArgumentParser) -> None:
    """``--fleet-profile``: which per-unit variation the simulated fleet (QUBE or CartPole) is drawn with."""
    add_learning_argument(p, "fleet_profile")


def add_broker_arguments(p: argparse.ArgumentParser, note: str) -> None:
    """``--broker`` and the password file (never the password itself on a command line)."""
    add_setting_argument(p, BrokerLogin, "broker", note=note)
    add_setting_argument(p, BrokerLogin, "broker_password_file")


def add_connect_timeout(p: argparse.ArgumentParser) -> None:
    """``--connect-timeout``, its default the roles' setting's."""
    add_setting_argument(p, RoleSettings, "connect_timeout", defaulted=True)


def parse_overrides(items: list[str], flag: str = "--set") -> dict[str, Any]:
    """``["clip_eps=0.2", "activation=tanh"]`` as a dict of JSON-typed values (text if not JSON); ``flag``
    names the option in errors."""
    result: dict[str, Any] = {}
    for item in items:
        key, sep, raw = item.partition("=")
        if not sep or not key.strip():
            raise ValueError(f"{flag} takes KEY=VALUE, got {item!r}")
        try:
            value: Any = json.loads(raw)
        except json.JSONDecodeError:
            value = raw
        if isinstance(value, list):
            value = tuple(value)
        result[key.strip()] = value
    return result


def settings_from_args(cls: type[S], args: argparse.Namespace) -> S:
    """The command's resolved settings value from ``--config`` and the flags given."""
    file_values: dict[str, Any] = {} if args.config is None else load_toml(args.config)
    flags = {k: v for k, v in vars(args).items() if k not in NOT_SETTINGS}
    for table, table_flag in TABLE_FLAGS.items():
        if flags.get(table) is not None:
            flags[table] = parse_overrides(flags[table], table_flag)
    return build(cls, file_values, flags, source=str(args.config or ""))
