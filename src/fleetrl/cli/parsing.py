"""Small parsers for command-line values."""

import json
from typing import Any


def parse_overrides(items: list[str], flag: str = "--set") -> dict[str, Any]:
    """Turn ``["clip_eps=0.2", "normalise_advantages=true"]`` into a dict of JSON-typed values.

    A value that is not JSON (e.g. ``tanh``) is kept as a string; ``flag`` names the option in errors.
    """
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
