"""A chief's checkpoint: the chief and its run's configuration as data (JSON fields + named float32 tensors)
and back (docs/protocol.md, "Checkpoints and resume"); :mod:`fleetrl.runs.checkpoints` stores it."""

from __future__ import annotations

from typing import Any

import numpy as np

from fleetrl.federation.chief.machine import Chief
from fleetrl.federation.chief.state import SCHEME_TENSOR, STATE_VERSION, ChiefState, FleetModel
from fleetrl.federation.events import ChiefEvent, ChiefStep
from fleetrl.federation.kinds import new_chief
from fleetrl.federation.plan import ChiefPlan
from fleetrl.federation.wire.signing import FleetKey


def chief_config(chief: Chief) -> dict[str, Any]:
    """The settings that define the run (all JSON); a resumed chief must be given the same."""
    return chief.plan.fields() | {"workers": list(chief.all_workers), "signed": chief.key is not None}


def chief_fields(chief: Chief) -> dict[str, Any]:
    """The JSON part of the chief's state (cheap: the runner compares it after every input)."""
    return {
        "version": STATE_VERSION,
        "config": chief_config(chief),
        **chief.state.fields(),
        "scheme_state": chief.scheme.state()[0],
    }


def chief_tensors(chief: Chief) -> dict[str, np.ndarray]:
    """The tensors of the chief's state: the last answer's and the fleet model's, and the scheme's own."""
    scheme = {SCHEME_TENSOR + name: flat for name, flat in chief.scheme.state()[1].items()}
    return chief.state.tensors() | {name: np.asarray(flat, np.float32) for name, flat in scheme.items()}


def chief_to_state(chief: Chief) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
    """(fields, tensors): everything :func:`chief_from_state` needs."""
    return chief_fields(chief), chief_tensors(chief)


def chief_from_state(
    fields: dict[str, Any], tensors: dict[str, np.ndarray], *, key: FleetKey | None = None, now: float,
    fleet_model: FleetModel | None = None,
) -> Chief:  # fmt: skip
    """The chief as it was when ``fields``/``tensors`` were taken, its open round starting at ``now``.

    :param key: the fleet key; required if and only if the saved chief had one.
    :param fleet_model: a per-step scheme's fleet model, built as the saved chief's; set to the saved one.
    :raises ValueError: another state version, or a key where there was none (or the reverse).
    """
    if fields.get("version") != STATE_VERSION:
        raise ValueError(f"chief state version {fields.get('version')!r}, expected {STATE_VERSION}")
    config = dict(fields["config"])
    if bool(config.pop("signed")) != (key is not None):
        had = "with" if key is None else "without"
        raise ValueError(f"the checkpoint was written by a chief {had} a fleet key; resume it the same way")
    plan = ChiefPlan.from_fields(config)
    scheme_tensors = {
        n.removeprefix(SCHEME_TENSOR): t for n, t in tensors.items() if n.startswith(SCHEME_TENSOR)
    }
    plan.scheme.restore(fields.get("scheme_state", {}), scheme_tensors)
    state = ChiefState.from_data(
        fields, tensors, run_id=plan.run_id, holdoff=plan.resend_holdoff, grace=plan.dropout_grace, now=now
    )
    if fleet_model is not None and state.model is not None and state.model.flat is not None:
        fleet_model.load(state.model.flat)
    return new_chief(plan, key=key, state=state, now=now, fleet_model=fleet_model)


def replay_last_answer(chief: Chief) -> ChiefStep:
    """The chief's last answer again, published once when a restored chief comes online (it may have died
    after committing a round but before its answer left)."""
    last = chief.state.answers.last
    if not last:
        return ChiefStep()
    detail = f"answer of round {last[0].round} after resume"
    return ChiefStep(last, (ChiefEvent("resent", chief.round, sender="*", detail=detail),))
