"""The chief's durable state as data (JSON fields + named float32 tensors), and the chief rebuilt from it.

No files here: :mod:`fleetrl.runs.checkpoints` stores what :func:`chief_to_state` returns. The state is what a
restarted chief needs to continue a run with no round lost or counted twice (docs/protocol.md, "Checkpoints
and resume"): its configuration, the open round, W, the workers that left, the last transfer θ*, the last
answer (re-sent to workers that ask again), the first completion of each worker, dropouts, rejoins,
rejections, suspects and the newest incarnation seen of each worker. Answers received for the open round are
not kept: the workers re-send them; nor are the earlier answers of the round that a running chief keeps for a
worker replaying it (docs/protocol.md says what a double failure in one round does).

Times are not kept either (they are seconds of a monotonic clock of a dead process): a restored chief opens
its round, re-arms the grace of suspected workers at the ``now`` it is given, and answers the first re-send of
every worker at once. This module reads the chief's private attributes; it is the chief's other half.
"""

from __future__ import annotations

from collections import Counter
from typing import Any

import numpy as np

from fleetrl.federation.chief import Chief
from fleetrl.federation.chief_answer import AnswerBook
from fleetrl.federation.events import ChiefEvent, ChiefStep
from fleetrl.federation.messages import Message, Reason
from fleetrl.federation.schemes import get_scheme
from fleetrl.federation.signing import FleetKey
from fleetrl.federation.topics import CHIEF_ID

STATE_VERSION = 1
"""Version of the state's fields; :func:`chief_from_state` refuses any other."""
SCHEME_TENSOR = "scheme."
"""Prefix of the scheme's own state tensors (a server optimiser's moments) in the tensor file."""


def chief_config(chief: Chief) -> dict[str, Any]:
    """The settings that define the run (all JSON); a resumed chief must be given the same."""
    return {
        "run_id": chief.run_id,
        "workers": list(chief.all_workers),
        "layout": [[name, list(shape)] for name, shape in chief.layout],
        "max_rounds": chief.max_rounds,
        "aggregator": chief.aggregator_name,
        "max_bytes": chief.max_bytes,
        "quorum": chief.quorum,
        "round_timeout": chief.round_timeout,
        "resend_holdoff": chief.resend_holdoff,
        "dropout_grace": chief.dropout_grace,
        "signed": chief.key is not None,
        "scheme": chief.scheme.name,
        "scheme_params": chief.scheme.params(),
        "settings": chief.settings,
        "steps_per_round": chief.steps_per_round,
    }


def chief_fields(chief: Chief) -> dict[str, Any]:
    """The JSON part of the chief's state (cheap: the runner compares it after every input)."""
    answers = [_message_fields(m, f"answer.{i}") for i, m in enumerate(chief._answers.last)]
    model = chief._model
    return {
        "version": STATE_VERSION,
        "config": chief_config(chief),
        "round": chief._round,
        "step": chief._step,
        "members": list(chief.members),
        "left": sorted(chief._left),
        "end_reason": chief._end_reason,
        "suspects": sorted(chief._suspects),
        "incarnations": dict(sorted(chief._incarnation.items())),
        "last_answer": answers,
        "model": None if model is None else _message_fields(model, "model"),
        "rejections": {reason.value: n for reason, n in sorted(chief.rejections.items())},
        "transfers": [[r, origin, list(to)] for r, origin, to in chief.transfers],
        "completed": dict(sorted(chief.completed.items())),
        "dropouts": [list(d) for d in chief.dropouts],
        "rejoins": [list(r) for r in chief.rejoins],
        "scheme_state": chief.scheme.state()[0],
    }


def chief_tensors(chief: Chief) -> dict[str, np.ndarray]:
    """The tensors of the chief's state: the last answer's and θ*'s flat vectors."""
    tensors = {f"answer.{i}": m.flat for i, m in enumerate(chief._answers.last) if m.flat is not None}
    if chief._model is not None and chief._model.flat is not None:
        tensors["model"] = chief._model.flat
    tensors |= {SCHEME_TENSOR + name: flat for name, flat in chief.scheme.state()[1].items()}
    return {name: np.asarray(flat, dtype=np.float32) for name, flat in tensors.items()}


def chief_to_state(chief: Chief) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
    """(fields, tensors): everything :func:`chief_from_state` needs."""
    return chief_fields(chief), chief_tensors(chief)


def chief_from_state(
    fields: dict[str, Any], tensors: dict[str, np.ndarray], *, key: FleetKey | None = None, now: float
) -> Chief:
    """The chief as it was when ``fields``/``tensors`` were taken, its open round starting at ``now``.

    :param key: the fleet key; required if and only if the saved chief had one.
    :param now: the current time of the clock the restored chief will be driven with.
    :raises ValueError: another state version, or a key where there was none (or the reverse).
    """
    if fields.get("version") != STATE_VERSION:
        raise ValueError(f"chief state version {fields.get('version')!r}, expected {STATE_VERSION}")
    config = dict(fields["config"])
    if bool(config.pop("signed")) != (key is not None):
        had = "with" if key is None else "without"
        raise ValueError(f"the checkpoint was written by a chief {had} a fleet key; resume it the same way")
    config["layout"] = [(str(name), tuple(int(d) for d in shape)) for name, shape in config["layout"]]
    scheme = get_scheme(config.pop("scheme"), **config.pop("scheme_params", {}))
    chief = Chief(**config, scheme=scheme, key=key)
    scheme_tensors = {
        n.removeprefix(SCHEME_TENSOR): t for n, t in tensors.items() if n.startswith(SCHEME_TENSOR)
    }
    scheme.restore(fields.get("scheme_state", {}), scheme_tensors)
    chief._round = int(fields["round"])
    chief._step = int(fields.get("step", 0))
    chief._members = set(fields["members"])
    chief._left = set(fields["left"])
    chief._end_reason = fields["end_reason"]
    chief._opened_at = now
    chief._suspects = {w: now + chief.dropout_grace for w in fields["suspects"]}
    chief._incarnation = {w: int(i) for w, i in fields["incarnations"].items()}
    # only the last answer: each worker's first re-send gets it at once (docs/protocol.md, "Checkpoints and
    # resume", on a worker replaying a round the restarted chief had half answered)
    last = tuple(_message(chief.run_id, m, tensors) for m in fields["last_answer"])
    chief._answers = AnswerBook(chief.resend_holdoff, last)
    chief._model = None if fields["model"] is None else _message(chief.run_id, fields["model"], tensors)
    chief.rejections = Counter({Reason(r): int(n) for r, n in fields["rejections"].items()})
    chief.transfers = [(int(r), str(o), tuple(to)) for r, o, to in fields["transfers"]]
    chief.completed = {str(w): int(r) for w, r in fields.get("completed", {}).items()}
    chief.dropouts = [(int(r), str(w), str(why)) for r, w, why in fields["dropouts"]]
    chief.rejoins = [(int(r), str(w)) for r, w in fields["rejoins"]]
    return chief


def replay_last_answer(chief: Chief) -> ChiefStep:
    """The chief's last answer again, to publish once when a restored chief comes online.

    A chief may die after committing a round but before its answer left; workers that got the answer ignore
    the copy (they are past that round), those that did not take it.
    """
    if not chief._answers.last:
        return ChiefStep()
    detail = f"answer of round {chief._answers.last[0].round} after resume"
    return ChiefStep(chief._answers.last, (ChiefEvent("resent", chief.round, sender="*", detail=detail),))


def _message_fields(message: Message, tensor: str) -> dict[str, Any]:
    return {
        "type": message.type,
        "round": message.round,
        "step": message.step,
        "origin": message.origin,
        "finished": list(message.finished),
        "contributors": list(message.contributors),
        "metrics": dict(message.metrics),
        "tensor": None if message.flat is None else tensor,
    }


def _message(run_id: str, fields: dict[str, Any], tensors: dict[str, np.ndarray]) -> Message:
    name = fields["tensor"]
    if name is not None and name not in tensors:
        raise ValueError(f"chief state names tensor {name!r}, which is not in its tensor file")
    return Message(
        fields["type"], run_id, CHIEF_ID, int(fields["round"]),
        flat=None if name is None else np.asarray(tensors[name], dtype=np.float32),
        metrics={str(k): float(v) for k, v in fields["metrics"].items()}, origin=fields["origin"],
        finished=tuple(fields["finished"]), contributors=tuple(fields["contributors"]),
        step=int(fields.get("step", 0)),
    )  # fmt: skip
