"""The settings of ``fleetrl aggregator``, a site's edge aggregator (docs/deploy.md): the run's settings and
round rules as the chief has them, its id at the root, and where its members are."""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any

from fleetrl.federation.edge.aggregator import check_tree
from fleetrl.federation.wire.topics import validate_id, validate_worker_id
from fleetrl.runs.learning_resolution import as_setting_error, positive
from fleetrl.runs.role_settings import RoleSettings
from fleetrl.runs.setting_values import SettingError, label
from fleetrl.runs.settings import RoundRules


@dataclass(frozen=True, kw_only=True)
class AggregatorSettings(RoleSettings, RoundRules):
    """``fleetrl aggregator``: one member of the root chief (``--run-id`` on ``--broker``) that stands for a
    site's workers (``--site-run`` on ``--site-broker``)."""

    site_id: str
    """this aggregator's worker id at the root (under ``fleetrl chief --workers M`` whose members are all
    sites: 0 … M-1; the site's members' ids live in the site's run and may be the same numbers)"""
    site_run: str
    """the site's run id: its members run ``fleetrl worker --run-id SITE_RUN``"""
    members: int
    """N: the site's members are worker ids ``first_member`` … ``first_member`` + N - 1"""
    first_member: int = 0
    """the first member's worker id"""
    site_broker: str | None = None
    """the site's broker (``mqtt://host:port``; the same login); unset: the central broker, where the site's
    run id keeps its topics apart"""
    idle_timeout: float = 600.0
    """give up (exit 1) after this many seconds without any message"""
    dropout_grace: float = 3.0
    """seconds a member that went offline has to come back before it leaves the site"""
    resend_interval: float = 5.0
    """re-send an exchange's sum (or the join) after this many seconds without the root's answer"""
    closed_fleet: bool = False
    """take only the members named (by default a worker with another id joins the site: a new unit)"""

    def resolved(self) -> AggregatorSettings:
        """A new value with every default filled in; SettingError naming the first that cannot work."""
        learning, shape = self.resolved_learning()
        quorum = self.resolved_quorum(learning, shape)
        as_setting_error("scheme", check_tree, learning.federation_scheme(), self.aggregation)
        as_setting_error("site_id", validate_worker_id, self.site_id)
        as_setting_error("site_run", validate_id, self.site_run, "site run id")
        if self.site_run == self.run_id and self.site_broker in (None, self.broker):
            raise SettingError(f"{label('site_run')}: must differ from the root's run id on the same broker")
        if self.members < 1 or self.first_member < 0:
            raise SettingError(f"{label('members')} must be >= 1 and {label('first_member')} >= 0")
        for name in ("idle_timeout", "resend_interval"):
            positive(name, getattr(self, name))
        positive("dropout_grace", self.dropout_grace, allow_zero=True)
        replace(self, broker=self.site_broker).validate_broker()
        return replace(self, learning=learning, quorum=quorum)

    @property
    def member_ids(self) -> list[str]:
        return [str(k) for k in range(self.first_member, self.first_member + self.members)]

    def site_transport(self) -> Any:
        """An unconnected transport to the site's broker (the central one if none is set)."""
        if self.site_broker is None:
            return self.transport()
        return replace(self, broker=self.site_broker).transport()
