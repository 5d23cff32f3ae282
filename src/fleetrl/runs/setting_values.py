"""Typed settings from a TOML file and the command line: a settings class is a frozen dataclass whose field
names are the TOML keys and the flags' ``dest`` (a field holding a settings dataclass is a group of settings
under their own names); :func:`build` merges defaults, file and flags and returns the ``resolved()`` value."""

from __future__ import annotations

import ast
import dataclasses
import functools
import inspect
import linecache
import os
import re
import resource
import shutil
import textwrap
import tomllib
from collections.abc import Mapping
from pathlib import Path
from typing import Any, TypeVar, get_type_hints

import tomli_w

from fleetrl.coercion import CoercionError
from fleetrl.coercion import coerce as typed

MIN_FREE_BYTES = 64 * 2**20
"""free space an ``--out`` file system must have at start"""
MIN_FILE_SIZE_LIMIT = 64 * 2**20
"""the smallest file size limit (``ulimit -f``) a run accepts at start"""

S = TypeVar("S")


class SettingError(ValueError):
    """A setting with a value that cannot work: printed as one line, nothing was started (exit code 2)."""


NEGATED_FLAGS = {"live": "--no-live"}
"""settings whose flag switches them off"""
TABLE_FLAGS = {
    "overrides": "--set",
    "scheme_params": "--scheme-param",
    "slow": "--slow",
    "link_delay": "--link-delay",
    "stall": "--stall",
}
"""table-valued settings and their repeatable ``KEY=VALUE`` flag"""
TABLE_METAVARS = {"slow": "UNIT=FACTOR", "link_delay": "UNIT=SECONDS", "stall": "UNIT=SHARE"}
"""how a table flag's help shows its entries (default ``KEY=VALUE``)"""


def flag(name: str) -> str:
    """The command-line flag of setting ``name`` (``round_timeout`` → ``--round-timeout``)."""
    return NEGATED_FLAGS.get(name) or TABLE_FLAGS.get(name) or "--" + name.replace("_", "-")


def label(name: str) -> str:
    """How an error names a setting: its flag (with its key, for a flag that switches it off)."""
    return f"{name} (flag {NEGATED_FLAGS[name]})" if name in NEGATED_FLAGS else flag(name)


def coerce(name: str, value: Any, kind: Any) -> Any:
    """``value`` as the type ``kind`` (:func:`fleetrl.coercion.coerce`); else SettingError."""
    try:
        return typed(name, value, kind)
    except CoercionError as err:
        raise SettingError(str(err)) from None


def group_type(kind: Any) -> type | None:
    """The settings dataclass a field of type ``kind`` holds (a group), or None for one setting."""
    return kind if isinstance(kind, type) and dataclasses.is_dataclass(kind) else None


def setting_fields(cls: type) -> dict[str, tuple[dataclasses.Field[Any], Any]]:
    """Every setting of ``cls`` by name (a group's too), with its field and type."""
    return dict(_setting_fields(cls))


@functools.cache
def _setting_fields(cls: type) -> dict[str, tuple[dataclasses.Field[Any], Any]]:
    # once per class: resolving the string annotations is most of the parser's start-up time
    hints = get_type_hints(cls)  # annotations may be strings
    found: dict[str, tuple[dataclasses.Field[Any], Any]] = {}
    for f in dataclasses.fields(cls):
        group = group_type(hints[f.name])
        found |= _setting_fields(group) if group is not None else {f.name: (f, hints[f.name])}
    return found


def construct(cls: type[S], values: Mapping[str, Any]) -> S:
    """``cls`` from flat setting values; a value not given takes its field's default."""
    hints = get_type_hints(cls)
    kwargs: dict[str, Any] = {}
    for f in dataclasses.fields(cls):  # type: ignore[arg-type]
        group = group_type(hints[f.name])
        if group is not None:
            kwargs[f.name] = construct(group, values)
        elif f.name in values:
            kwargs[f.name] = values[f.name]
    return cls(**kwargs)


def flat_values(settings: Any) -> dict[str, Any]:
    """The settings' values by setting name (a group's at the top, as in a config file)."""
    values: dict[str, Any] = {}
    for f in dataclasses.fields(settings):
        value = getattr(settings, f.name)
        values |= flat_values(value) if dataclasses.is_dataclass(value) else {f.name: value}
    return values


def build(
    cls: type[S],
    file_values: Mapping[str, Any],
    flag_values: Mapping[str, Any],
    source: str = "",
    *,
    resolve: bool = True,
) -> S:
    """``cls`` from its defaults, then ``file_values`` (``source`` names the file in errors), then
    ``flag_values`` (None: not given); tables merge key by key. With ``resolve``: its ``resolved()``."""
    fields = setting_fields(cls)
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
                value = coerce(label(name), raw, fields[name][1])
            except SettingError as err:
                raise SettingError(f"{err}{where}") from None
            if isinstance(value, dict) and isinstance(values.get(name), dict):
                value = {**values[name], **value}
            values[name] = value
    missing = [n for n, (f, _) in fields.items() if n not in values and required(f)]
    if missing:
        raise SettingError(
            "missing setting(s): " + ", ".join(f"{flag(n)} (or {n} = … in a --config file)" for n in missing)
        )
    settings = construct(cls, values)
    resolved: S = settings.resolved() if resolve else settings  # type: ignore[attr-defined]
    return resolved


def required(field: dataclasses.Field[Any]) -> bool:
    return field.default is dataclasses.MISSING and field.default_factory is dataclasses.MISSING


def field_default(field: dataclasses.Field[Any]) -> Any:
    """A setting's default (None when it has none)."""
    if field.default is not dataclasses.MISSING:
        return field.default
    if field.default_factory is not dataclasses.MISSING:
        return field.default_factory()
    return None


@functools.cache
def field_docs(cls: type) -> dict[str, str]:
    """The docstring under each field of ``cls``, its bases and groups, as one line of plain text."""
    docs: dict[str, str] = {}
    for klass in reversed(cls.__mro__):
        if not dataclasses.is_dataclass(klass):
            continue
        body = _class_definition(klass)
        for node, after in zip(body.body, body.body[1:], strict=False):
            if (
                isinstance(node, ast.AnnAssign)
                and isinstance(node.target, ast.Name)
                and isinstance(after, ast.Expr)
                and isinstance(after.value, ast.Constant)
                and isinstance(after.value.value, str)
            ):
                docs[node.target.id] = _plain(after.value.value)
    hints = get_type_hints(cls)
    for f in dataclasses.fields(cls):
        group = group_type(hints[f.name])
        if group is not None:
            docs |= field_docs(group)
    return docs


def _class_definition(klass: type) -> ast.ClassDef:
    """The syntax tree of ``klass``'s definition: in its module's tree, else (defined in a function) alone."""
    filename = inspect.getsourcefile(klass)
    nodes = _module_tree(filename).body if filename else []
    found: ast.ClassDef | None = None
    for part in klass.__qualname__.split("."):
        found = next(
            (n for n in reversed(nodes) if isinstance(n, ast.ClassDef) and n.name == part), None
        )  # the last definition of a name is the one the module holds
        if found is None:
            break
        nodes = found.body
    if found is not None:
        return found
    body = ast.parse(textwrap.dedent(inspect.getsource(klass))).body[0]
    assert isinstance(body, ast.ClassDef)
    return body


@functools.cache
def _module_tree(filename: str) -> ast.Module:
    return ast.parse("".join(linecache.getlines(filename)))


def _plain(doc: str) -> str:
    text = re.sub(r":[a-z]+:`~?(?:[\w.]+\.)?([\w]+)`", r"\1", doc)
    return " ".join(text.replace("``", "").split())


def load_toml(path: Path) -> dict[str, Any]:
    """A config file's table; SettingError if it is missing, unreadable or not TOML."""
    try:
        with path.open("rb") as handle:
            return tomllib.load(handle)
    except OSError as err:
        raise SettingError(f"--config {path}: cannot read it ({err.strerror or err})") from None
    except tomllib.TOMLDecodeError as err:
        raise SettingError(f"--config {path}: not valid TOML ({err})") from None


def toml_text(settings: Any, header: str) -> str:
    """The settings as a flat TOML table :func:`build` reads (unset values and empty tables left out; scalars
    first, then sub-tables), under ``header`` as comment lines."""
    table: dict[str, Any] = {}
    for name, value in flat_values(settings).items():
        if value is None or value == {}:
            continue
        if isinstance(value, Path):
            value = str(value)
        elif isinstance(value, dict):
            value = {k: list(v) if isinstance(v, tuple) else v for k, v in value.items()}
        table[name] = value
    comment = "".join(f"# {line}\n" for line in header.splitlines())
    return comment + tomli_w.dumps(table)


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
    """SettingError unless a run directory can be written at ``path``, with room (:data:`MIN_FREE_BYTES`,
    :data:`MIN_FILE_SIZE_LIMIT`); nothing is created."""
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
