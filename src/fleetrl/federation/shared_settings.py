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


class JoinGate:
    """The chief's record of who joined with matching settings and who was refused (and why).

    :param settings: the chief's shared settings; None checks nothing (every join matches).
    """

    def __init__(self, settings: SharedSettings | None) -> None:
        """Nobody has joined yet."""
        self.settings: dict[str, str] | None = None if settings is None else dict(settings)
        self._refused: dict[str, str] = {}  # worker → why its last join was refused
        self._joined: set[str] = (
            set()
        )  # workers whose join matched, since their newest incarnation came online

    def join(self, worker: str, settings: SharedSettings) -> str:
        """Check a join: ``joined``, ``duplicate`` (a matching join already seen) or ``refused`` (then
        :meth:`refusal` says why)."""
        why = None if self.settings is None else settings_difference(self.settings, settings)
        if why is not None:
            self._refused[worker] = why
            return "refused"
        if worker in self._joined:
            return "duplicate"
        self._joined.add(worker)
        self._refused.pop(worker, None)
        return "joined"

    def refusal(self, worker: str) -> str | None:
        """Why ``worker`` is refused, or None."""
        return self._refused.get(worker)

    def new_incarnation(self, worker: str) -> None:
        """A new process of ``worker`` came online: it joins afresh."""
        self._joined.discard(worker)
        self._refused.pop(worker, None)
