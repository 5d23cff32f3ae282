"""Where a worker's state machine is (:class:`Phase`) and what it waits for (:class:`Wait`): the vocabulary
shared by the machines of every scheme (:mod:`fleetrl.federation.worker.machine`,
:mod:`~fleetrl.federation.worker.per_step`, :mod:`~fleetrl.federation.worker.asynchronous`)."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from enum import Enum, auto

from fleetrl.federation.wire.messages import Message
from fleetrl.federation.worker import actions
from fleetrl.federation.worker.actions import WorkerStep

__all__ = ["NOTHING", "QUEUED", "Phase", "Wait"]

NOTHING = WorkerStep()


class Phase(Enum):
    """Where the worker is: waiting for the chief (``WELCOME``, ``ANSWER``, ``STEP_ANSWER``, a per-step
    straggler's ``WAIT_ROUND``), for the runner (``PLAYING`` a round, a per-step update's ``JOINING``,
    ``COMPUTING`` a step, ``STEPS_DONE``: finishing the round), or applying answers already queued
    (``CATCH_UP`` after a round, a per-step worker's ``DRAIN`` before its update)."""

    NEW = auto()
    WELCOME = auto()
    PLAYING = auto()
    DRAIN = auto()
    WAIT_ROUND = auto()
    JOINING = auto()
    COMPUTING = auto()
    STEP_ANSWER = auto()
    STEPS_DONE = auto()
    ANSWER = auto()
    CATCH_UP = auto()
    DONE = auto()


QUEUED = (Phase.CATCH_UP, Phase.DRAIN)
"""phases that read only what is already queued (due at once)"""


@dataclass
class Wait:
    """Waiting for a chief message: what is wanted, what is re-sent, the deadlines."""

    wanted: Callable[[Message], bool]
    what: str
    resend: actions.Publish
    """what was sent (retained: the join, re-sent with the ``online`` status)"""
    deadline: float | None
    next_send: float | None
