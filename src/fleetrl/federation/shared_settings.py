"""The settings every role of a run must share, and the rule that compares a worker's with the chief's.

The chief's ``welcome`` carries its shared settings; a worker's ``join`` carries its own. They are a map of
setting name → value text (what :func:`fleetrl.runs.shared.shared_settings` builds: env, fleet seed, preset,
``--set`` overrides, scheme and its parameters). A worker whose map differs is refused at join, with a reason
that names the first differing key in sorted order.
"""

from __future__ import annotations

from collections.abc import Mapping

SharedSettings = Mapping[str, str]
"""setting name → its value as text (the same text for the same value on every machine)"""

MISSING = "<not set>"
"""How a setting one side lacks is shown."""


class SettingsRefused(ValueError):
    """The chief refused this worker at join: a shared setting differs (a setting error: exit code 2)."""


def settings_difference(chief: SharedSettings, worker: SharedSettings) -> str | None:
    """Why ``worker``'s settings cannot join ``chief``'s run (the first differing key); None if equal."""
    for key in sorted(set(chief) | set(worker)):
        ours, theirs = chief.get(key, MISSING), worker.get(key, MISSING)
        if ours != theirs:
            return f"setting {key!r} differs (chief {ours!r}, worker {theirs!r})"
    return None
