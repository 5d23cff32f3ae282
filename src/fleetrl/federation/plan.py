"""A run's plan, resolved once: what its chief (a site's too) and each worker are built from (by
:mod:`.kinds`), and what the chief's checkpoint keeps of the run's configuration."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass
from typing import Any

from fleetrl.federation.schemes import Scheme, get_scheme, resolve_scheme, scheme_reference
from fleetrl.federation.schemes.agent import FederatedAgent
from fleetrl.federation.wire.messages import Layout
from fleetrl.federation.wire.topics import validate_id, validate_worker_id

ENDED_GRACE = 30.0  # seconds an unwelcomed worker gives a new chief once the retained status says "ended"


@dataclass(frozen=True, kw_only=True)
class ChiefPlan:
    """The run as its chief sees it. ``scheme`` may be given by name (it is resolved once, here)."""

    run_id: str
    workers: Sequence[str]  # W at the start
    scheme: Scheme
    layout: Layout  # what a round message carries (what the scheme shares)
    max_rounds: int  # M, the last round
    steps_per_round: int = 1  # exchanges per round: 1, or a per-step scheme's K
    welcome_layout: Layout | None = None  # what a welcome carries (None: the fleet's start's, else layout)
    settings: Mapping[str, str] | None = None  # what every worker must share (:mod:`.shared_settings`)
    aggregator: str = "mean"  # the aggregation rule, ``name`` or ``name:value`` (:mod:`.aggregation`)
    quorum: float = 1.0
    round_timeout: float | None = None
    max_staleness: int | None = None
    """the waiting rules (:mod:`.chief.stragglers`): the quorum, the seconds a round may stay open and the
    rounds a per-step straggler's contribution may lag (None: no limit)"""
    dropout_grace: float = 3.0  # seconds an offline worker has to come back before it leaves W
    resend_holdoff: float = 1.0  # least seconds between two re-sends of one answer to one worker
    open_fleet: bool = True  # a worker with an id not in ``workers`` may join the run
    max_bytes: int | None = None  # message size cap; None: from the layout

    def __post_init__(self) -> None:
        validate_id(self.run_id, "run id")
        object.__setattr__(self, "scheme", resolve_scheme(self.scheme))
        object.__setattr__(self, "workers", tuple(self.workers))
        object.__setattr__(self, "layout", _layout(self.layout))
        if self.welcome_layout is not None:
            object.__setattr__(self, "welcome_layout", _layout(self.welcome_layout))

    def fields(self) -> dict[str, Any]:
        """The plan as JSON values (the checkpoint's ``config``)."""
        values = {k: v for k, v in asdict(self).items() if k != "scheme"}
        values["workers"] = list(self.workers)
        for name in ("layout", "welcome_layout"):
            values[name] = [[n, list(shape)] for n, shape in (getattr(self, name) or self.layout)]
        values["settings"] = None if self.settings is None else dict(self.settings)
        return values | {"scheme": scheme_reference(self.scheme), "scheme_params": self.scheme.params()}

    @classmethod
    def from_fields(cls, values: Mapping[str, Any]) -> ChiefPlan:
        """The plan :meth:`fields` wrote (its scheme made anew from its reference and parameters)."""
        values = dict(values)
        scheme = get_scheme(values.pop("scheme"), **values.pop("scheme_params", {}))
        return cls(scheme=scheme, **values)


@dataclass(frozen=True, kw_only=True)
class WorkerPlan:
    """The run as one worker sees it. ``scheme`` may be given by name (it is resolved once, here)."""

    run_id: str
    worker_id: str  # a topic level; not ``chief``
    scheme: Scheme
    layout: Layout  # what a round message carries (``scheme.layout(agent)``)
    max_rounds: int  # M, the last round
    steps_per_round: int = 1  # exchanges per round: 1, or a per-step scheme's K
    welcome_layout: Layout | None = None  # what a welcome or done carries (None: ``layout``)
    settings: Mapping[str, str] | None = None  # this worker's shared settings, sent in its join
    units: int = 1  # the units the worker carries (a unit host: U), said in every contribution
    start_round: int | None = None  # resuming: the first round the learner's state has not played
    restarted: bool = False  # resumed with no checkpoint: an earlier process went down in round 1
    reply_timeout: float | None = 600.0  # seconds to wait for the chief (None: forever)
    resend_interval: float | None = 5.0  # seconds without an answer before re-sending (None: never)
    ended_grace: float = ENDED_GRACE

    def __post_init__(self) -> None:
        validate_id(self.run_id, "run id")
        validate_worker_id(self.worker_id)
        if self.units < 1:
            raise ValueError(f"a worker carries at least one unit, got units={self.units}")
        object.__setattr__(self, "scheme", resolve_scheme(self.scheme))
        object.__setattr__(self, "layout", _layout(self.layout))
        if self.welcome_layout is not None:
            object.__setattr__(self, "welcome_layout", _layout(self.welcome_layout))

    @classmethod
    def for_agent(cls, agent: FederatedAgent, *, scheme: Scheme | str, **fields: Any) -> WorkerPlan:
        """The plan of a worker whose learner's agent is ``agent``: its scheme's layouts and K for it."""
        scheme = resolve_scheme(scheme)
        return cls(
            scheme=scheme, layout=scheme.layout(agent), welcome_layout=scheme.welcome_layout(agent),
            steps_per_round=scheme.exchanges_per_round(agent), **fields,
        )  # fmt: skip


def _layout(layout: Layout) -> tuple[tuple[str, tuple[int, ...]], ...]:
    return tuple((str(name), tuple(int(d) for d in shape)) for name, shape in layout)
