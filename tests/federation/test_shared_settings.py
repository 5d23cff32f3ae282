"""The settings all roles must share: carried in the welcome, checked at join; a worker whose settings differ
is refused with a reason naming the key (the chief's state machine, then a worker over the in-process bus)."""

from __future__ import annotations

import threading
from typing import Any

import numpy as np
import pytest
from conftest import worker_of

from fleetrl.federation.chief.machine import Chief
from fleetrl.federation.plan import ChiefPlan
from fleetrl.federation.runner import IdleTimeout, run_chief
from fleetrl.federation.shared_settings import (
    LearningSettings,
    SettingsRefused,
    settings_difference,
    shared_text,
)
from fleetrl.federation.wire.messages import Message, Reason, encode
from fleetrl.federation.wire.signing import status_payload
from fleetrl.runs.settings import resolve_learning
from fleetrl.transport.local import LocalBus

RUN = "shared"
LAYOUT = [("w", (2,))]
CHIEF_SETTINGS = shared_text(
    LearningSettings(
        env="qube",
        fleet_seed=0,
        fleet_profile="table2",
        preset="standard",
        overrides={},
        scheme="paper",
        scheme_params={},
        target_score=2450.0,
    )
)


def shared_settings(**values: Any) -> dict[str, str]:
    return shared_text(LearningSettings(**values))


def chief() -> Chief:
    return Chief(
        ChiefPlan(
            run_id=RUN,
            workers=("1", "2"),
            layout=LAYOUT,
            max_rounds=5,
            scheme="paper",
            settings=CHIEF_SETTINGS,
        )
    )


def join(worker: str, **changes: object) -> bytes:
    values = {
        "env": "qube",
        "fleet_seed": 0,
        "fleet_profile": "table2",
        "preset": "standard",
        "overrides": {},
        "scheme": "paper",
        "scheme_params": {},
        "target_score": 2450.0,
    } | changes
    settings = shared_settings(**values)
    return encode(Message("join", RUN, worker, 1, settings=settings), layout=LAYOUT)


def gradient(worker: str) -> bytes:
    return encode(Message("gradient", RUN, worker, 1, flat=np.ones(2, np.float32)), layout=LAYOUT)


def test_the_first_differing_key_is_named_with_both_values() -> None:
    ours = {"env": "qube", "preset": "standard", "scheme": "paper"}
    assert settings_difference(ours, dict(ours)) is None
    theirs = ours | {"preset": "paper", "scheme": "fedavg"}
    assert settings_difference(ours, theirs) == "setting 'preset' differs (chief 'standard', worker 'paper')"
    assert settings_difference(ours, {"env": "qube", "preset": "standard"}) == (
        "setting 'scheme' differs (chief 'paper', worker '<not set>')"
    )


def test_equal_settings_give_equal_text_whatever_the_order_of_the_overrides() -> None:
    a = shared_settings(
        env="qube",
        fleet_seed=3,
        fleet_profile=None,
        preset="paper",
        overrides={"lr": 0.1, "k": 2},
        scheme="paper",
        scheme_params={},
        target_score=2450.0,
    )
    b = shared_settings(
        env="qube",
        fleet_seed=3,
        fleet_profile=None,
        preset="paper",
        overrides={"k": 2, "lr": 0.1},
        scheme="paper",
        scheme_params={},
        target_score=2450.0,
    )
    assert a == b and a["overrides"] == '{"k":2,"lr":0.1}' and a["fleet_seed"] == "3"


def test_each_worker_keeps_its_own_learning_seed_and_the_join_does_not_compare_it() -> None:
    base = dict(CHIEF_SETTINGS_ARGS, scheme="pergrad", scheme_params={})
    assert shared_settings(**base, seed=40) == shared_settings(**base, seed=41)
    assert "seed" not in shared_settings(**base) and "max_rounds" not in shared_settings(**base)


def test_the_scheme_params_are_the_schemes_own_with_its_defaults_filled_in() -> None:
    def params(**given: object) -> str:
        learning = LearningSettings(env="cartpole", scheme="fedavgm", scheme_params=given)
        return shared_text(resolve_learning(learning))["scheme_params"]

    assert (
        params()
        == params(momentum=0, server_lr=1)
        == ('{"momentum":0.0,"optimizer":"momentum","server_lr":1.0}')
    )
    assert params(momentum=0.9) != params()


CHIEF_SETTINGS_ARGS: dict[str, object] = {
    "env": "qube",
    "fleet_seed": 0,
    "fleet_profile": "table2",
    "preset": "standard",
    "overrides": {},
    "target_score": 2450.0,
}


def test_the_welcome_carries_the_chiefs_settings() -> None:
    online = status_payload(b"online", run_id=RUN, node="1", incarnation=1)
    (welcome,) = chief().status("1", online, now=0.0).outgoing
    assert welcome.type == "welcome" and dict(welcome.settings) == CHIEF_SETTINGS


@pytest.mark.parametrize(
    ("change", "reason"),
    [
        ({"preset": "paper"}, "setting 'preset' differs (chief 'standard', worker 'paper')"),
        ({"scheme": "fedavg"}, "setting 'scheme' differs (chief 'paper', worker 'fedavg')"),
        ({"fleet_seed": 7}, "setting 'fleet_seed' differs (chief '0', worker '7')"),
        ({"fleet_profile": "v1"}, "setting 'fleet_profile' differs (chief 'table2', worker 'v1')"),
        ({"target_score": 50}, "setting 'target_score' differs (chief '2450.0', worker '50.0')"),
        (
            {"overrides": {"clip_eps": 0.3}},
            "setting 'overrides' differs (chief '{}', worker '{\"clip_eps\":0.3}')",
        ),
    ],
)
def test_a_worker_whose_settings_differ_is_refused_at_join_and_its_messages_rejected(
    change: dict[str, object], reason: str
) -> None:
    c = chief()
    step = c.receive_bytes(join("2", **change), topic_worker="2", now=0.0)
    (refusal,) = step.outgoing
    assert (refusal.type, refusal.finished, refusal.detail) == ("refused", ("2",), reason)
    assert [(e.kind, e.sender, e.detail) for e in step.events] == [("refused", "2", reason)]
    c.receive_bytes(gradient("1"), topic_worker="1", now=0.0)
    late = c.receive_bytes(gradient("2"), topic_worker="2", now=0.0)
    assert [e.reason for e in late.events] == [Reason.REFUSED] and late.outgoing == ()
    assert c.round == 1 and c.answered == ("1",)  # the refused worker's gradient entered nothing


def test_a_worker_whose_scheme_params_differ_is_refused_naming_them() -> None:
    ours = shared_settings(**CHIEF_SETTINGS_ARGS, scheme="fedavgm", scheme_params={"momentum": 0.9})
    c = Chief(
        ChiefPlan(
            run_id=RUN, workers=("1", "2"), layout=LAYOUT, max_rounds=5, scheme="fedavgm", settings=ours
        )
    )
    theirs = shared_settings(**CHIEF_SETTINGS_ARGS, scheme="fedavgm", scheme_params={"momentum": 0.5})
    step = c.receive_bytes(
        encode(Message("join", RUN, "2", 1, settings=theirs), layout=LAYOUT), topic_worker="2", now=0.0
    )
    (refusal,) = step.outgoing
    assert refusal.type == "refused" and refusal.detail.startswith("setting 'scheme_params' differs")
    assert '"momentum":0.9' in refusal.detail and '"momentum":0.5' in refusal.detail


def test_a_matching_join_is_accepted_once_and_lifts_a_refusal() -> None:
    c = chief()
    c.receive_bytes(join("2", preset="paper"), topic_worker="2", now=0.0)
    step = c.receive_bytes(join("2"), topic_worker="2", now=0.0)
    assert [e.kind for e in step.events] == ["joined"] and step.outgoing == ()
    again = c.receive_bytes(join("2"), topic_worker="2", now=0.0)  # a re-send (or a replay) changes nothing
    assert [e.reason for e in again.events] == [Reason.DUPLICATE]
    c.receive_bytes(gradient("1"), topic_worker="1", now=0.0)
    closed = c.receive_bytes(gradient("2"), topic_worker="2", now=0.0)
    assert [m.type for m in closed.outgoing] == ["average"] and c.round == 2


def test_a_chief_without_settings_checks_nothing() -> None:
    c = Chief(ChiefPlan(run_id=RUN, workers=("1",), layout=LAYOUT, max_rounds=5, scheme="paper"))
    step = c.receive_bytes(join("1", preset="paper"), topic_worker="1", now=0.0)
    assert [e.kind for e in step.events] == ["joined"]


@pytest.mark.parametrize("change", [{"scheme": "fedavg"}, {"preset": "paper"}])
def test_a_worker_with_another_scheme_or_preset_stops_with_the_chiefs_reason(
    change: dict[str, str], fake_learner: Any
) -> None:
    bus = LocalBus()
    learner = fake_learner(1)
    layout = learner.agent.actor_layout()
    boss = Chief(
        ChiefPlan(
            run_id=RUN, workers=("1",), layout=layout, max_rounds=5, scheme="paper", settings=CHIEF_SETTINGS
        )
    )
    failures: list[BaseException] = []

    def serve() -> None:
        try:
            run_chief(boss, bus.client(), idle_timeout=1.5)
        except IdleTimeout:
            pass  # nobody it accepts ever answers
        except BaseException as err:
            failures.append(err)

    thread = threading.Thread(target=serve)
    thread.start()
    values = {
        "env": "qube",
        "fleet_seed": 0,
        "fleet_profile": "table2",
        "preset": "standard",
        "overrides": {},
        "scheme": "paper",
        "scheme_params": {},
        "target_score": 2450.0,
    } | change
    worker = worker_of(
        learner, bus.client(), run_id=RUN, worker_id="1", max_rounds=5, reply_timeout=10,
        scheme="paper", settings=shared_settings(**values),
    )  # fmt: skip
    key = next(iter(change))
    with pytest.raises(
        SettingsRefused, match=f"worker 1: refused by the chief of run 'shared': setting '{key}'"
    ):
        worker.run()
    thread.join(10)
    assert not failures and learner.rounds == 0
    assert boss.round == 1 and boss.answered == ()


def test_a_refused_worker_coming_online_is_refused_again_until_a_new_process_comes() -> None:
    c = chief()
    c.status("2", status_payload(b"online", run_id=RUN, node="2", incarnation=5), now=0.0)
    c.receive_bytes(join("2", scheme="fedavg"), topic_worker="2", now=0.0)
    again = c.status("2", status_payload(b"online", run_id=RUN, node="2", incarnation=5), now=0.0)
    assert [m.type for m in again.outgoing] == ["refused"]
    restarted = c.status("2", status_payload(b"online", run_id=RUN, node="2", incarnation=6), now=0.0)
    assert [m.type for m in restarted.outgoing] == ["welcome"]  # its own join is checked when it comes
