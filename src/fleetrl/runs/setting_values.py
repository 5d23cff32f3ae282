"""Typed settings from a TOML file and the command line: one coercion, one error style, checked before
anything starts.

A settings class is a ``kw_only`` dataclass whose field names are the TOML keys and the flags' ``dest``
(``round_timeout`` and ``--round-timeout``). :func:`build` merges its defaults, a config file and the flags
given (flags win), checks every value against the field's type and calls the class's ``validate()``; a
:class:`SettingError` names the setting, the value and what is accepted. Nothing here creates a file, a
directory, a connection or a process.
"""

from __future__ import annotations

import dataclasses
import os
import resource
import shutil
import tomllib
import types
from collections.abc import Mapping
from pathlib import Path
from typing import Any, Literal, TypeVar, Union, get_args, get_origin, get_type_hints

MIN_FREE_BYTES = 64 * 2**20
"""free space an ``--out`` file system must have at start (a long QUBE run writes tens of MB)"""
MIN_FILE_SIZE_LIMIT = 64 * 2**20
"""the smallest file size limit (``ulimit -f``) a run accepts at start"""

S = TypeVar("S")


class SettingError(ValueError):
    """A setting with a value that cannot work: printed as one line, nothing was started (exit code 2)."""


NEGATED_FLAGS = {"live": "--no-live"}
"""settings whose flag switches them off (the key ``live = false``, the flag ``--no-live``)"""
TABLE_FLAGS = {"overrides": "--set", "scheme_params": "--scheme-param"}
"""table-valued settings whose repeatable ``KEY=VALUE`` flag has another name than the table"""


def flag(name: str) -> str:
    """The command-line flag of setting ``name`` (``round_timeout`` → ``--round-timeout``)."""
    return NEGATED_FLAGS.get(name) or TABLE_FLAGS.get(name) or "--" + name.replace("_", "-")


def label(name: str) -> str:
    """How an error names a setting: its flag (the config-file key is its name with ``_`` for ``-``), or for a
    setting whose flag switches it off, its key and that flag."""
    return f"{name} (flag {NEGATED_FLAGS[name]})" if name in NEGATED_FLAGS else flag(name)


def describe(kind: Any) -> str:
    """What a type accepts, in words."""
    origin, args = get_origin(kind), get_args(kind)
    if origin in (Union, types.UnionType):
        return " or ".join(describe(a) for a in args if a is not type(None)) + " (or unset)"
    if origin is Literal:
        return "one of " + ", ".join(repr(a) for a in args)
    if origin is tuple:
        return f"a list of {describe(args[0])}s"
    if origin is dict or kind is dict:
        return "a table of settings"
    names = {bool: "true or false", int: "an integer", float: "a number", str: "a string", Path: "a path"}
    return names.get(kind, getattr(kind, "__name__", str(kind)))


def coerce(name: str, value: Any, kind: Any) -> Any:
    """``value`` as the type ``kind`` (int to float, str to Path, list to tuple); else SettingError."""
    origin, args = get_origin(kind), get_args(kind)
    if kind is Any:
        return value
    if origin in (Union, types.UnionType):
        if value is None and type(None) in args:
            return None
        for option in (a for a in args if a is not type(None)):
            try:
                return coerce(name, value, option)
            except SettingError:
                continue
    elif origin is Literal:
        if value in args and not isinstance(value, bool):
            return value
    elif origin is tuple and isinstance(value, list | tuple):
        return tuple(coerce(name, item, args[0]) for item in value)
    elif (origin is dict or kind is dict) and isinstance(value, dict):
        return dict(value)
    elif (kind is bool and isinstance(value, bool)) or (
        kind is int and isinstance(value, int) and not isinstance(value, bool)
    ):
        return value
    elif kind is float and isinstance(value, int | float) and not isinstance(value, bool):
        return float(value)
    elif kind is str and isinstance(value, str):
        return value
    elif kind is Path and isinstance(value, str | Path) and str(value):
        return Path(value)
    raise SettingError(f"{name} = {value!r}: expected {describe(kind)}")


def build(
    cls: type[S], file_values: Mapping[str, Any], flag_values: Mapping[str, Any], source: str = ""
) -> S:
    """An instance of the settings dataclass ``cls``: its defaults, then ``file_values`` (a config file's
    table; ``source`` names the file in errors), then ``flag_values`` (the flags given; None means not
    given). Table-valued settings (the PPO overrides) merge key by key. ``validate()`` is called."""
    hints = get_type_hints(cls)  # annotations may be strings
    fields = {f.name: f for f in dataclasses.fields(cls)}  # type: ignore[arg-type]
    unknown = sorted(set(file_values) - set(fields))
    if unknown:
        raise SettingError(
            f"{source or 'config'}: unknown setting(s) {', '.join(unknown)} "
            f"(known: {', '.join(sorted(fields))})"
        )
    values: dict[str, Any] = {}
    for layer, where in ((file_values, f" in {source}" if source else ""), (flag_values, "")):
        for name, raw in layer.items():
            if raw is None or name not in fields:
                continue
            try:
                value = coerce(label(name), raw, hints[name])
            except SettingError as err:
                raise SettingError(f"{err}{where}") from None
            if isinstance(value, dict) and isinstance(values.get(name), dict):
                value = {**values[name], **value}
            values[name] = value
    missing = [n for n, f in fields.items() if n not in values and _required(f)]
    if missing:
        raise SettingError(
            "missing setting(s): " + ", ".join(f"{flag(n)} (or {n} = … in a --config file)" for n in missing)
        )
    settings = cls(**values)
    validate = getattr(settings, "validate", None)
    if validate is not None:
        validate()
    return settings


def _required(field: dataclasses.Field[Any]) -> bool:
    return field.default is dataclasses.MISSING and field.default_factory is dataclasses.MISSING


def load_toml(path: Path) -> dict[str, Any]:
    """A config file's table; SettingError if it is missing, unreadable or not TOML."""
    try:
        with path.open("rb") as handle:
            return tomllib.load(handle)
    except OSError as err:
        raise SettingError(f"--config {path}: cannot read it ({err.strerror or err})") from None
    except tomllib.TOMLDecodeError as err:
        raise SettingError(f"--config {path}: not valid TOML ({err})") from None


def toml_values(settings: Any, *, leave_out: tuple[str, ...] = ()) -> dict[str, Any]:
    """The settings as a TOML-ready table (Paths as strings, unset values left out) that :func:`build`
    reads back to the same settings."""
    table: dict[str, Any] = {}
    for field in dataclasses.fields(settings):
        value = getattr(settings, field.name)
        if value is None or field.name in leave_out:
            continue
        if isinstance(value, Path):
            value = str(value)
        elif isinstance(value, dict):
            value = {k: list(v) if isinstance(v, tuple) else v for k, v in value.items()}
        table[field.name] = value
    return table


def dump_toml(table: Mapping[str, Any], header: str = "") -> str:
    """TOML text of ``table`` (scalars first, then sub-tables), with ``header`` as leading comment lines."""
    import tomli_w

    comment = "".join(f"# {line}\n" for line in header.splitlines())
    return comment + tomli_w.dumps(dict(table))


def check_readable_file(name: str, path: Path | None) -> None:
    """SettingError unless ``path`` (if set) is a file this process can read."""
    if path is None:
        return
    try:
        with path.open("rb") as handle:
            handle.read(1)
    except OSError as err:
        why = "it is a directory" if path.is_dir() else (err.strerror or str(err)).lower()
        raise SettingError(f"{label(name)} = {str(path)!r}: cannot read it ({why})") from None


def check_writable_dir(name: str, path: Path) -> None:
    """SettingError unless a run directory can be created (or written) at ``path``, on a file system with at
    least :data:`MIN_FREE_BYTES` free and a file size limit of at least :data:`MIN_FILE_SIZE_LIMIT`.
    Nothing is created."""
    if path.exists() and not path.is_dir():
        raise SettingError(f"{label(name)} = {str(path)!r}: it is a file, not a directory")
    existing = path.absolute()
    while not existing.exists():
        existing = existing.parent
    if not existing.is_dir() or not os.access(existing, os.W_OK | os.X_OK):
        why = "read-only file system" if _read_only(existing) else "no write permission"
        raise SettingError(f"{label(name)} = {str(path)!r}: {existing} is not writable ({why})")
    free = shutil.disk_usage(existing).free
    if free < MIN_FREE_BYTES:
        raise SettingError(
            f"{label(name)} = {str(path)!r}: only {free / 2**20:.1f} MB free on its file system "
            f"(a run needs at least {MIN_FREE_BYTES // 2**20} MB)"
        )
    limit = resource.getrlimit(resource.RLIMIT_FSIZE)[0]
    if limit != resource.RLIM_INFINITY and limit < MIN_FILE_SIZE_LIMIT:
        raise SettingError(
            f"{label(name)} = {str(path)!r}: the file size limit (ulimit -f) is {limit} bytes "
            f"(a run needs at least {MIN_FILE_SIZE_LIMIT // 2**20} MB)"
        )


def _read_only(path: Path) -> bool:
    try:
        return bool(os.statvfs(path).f_flag & os.ST_RDONLY)
    except OSError:
        return False
