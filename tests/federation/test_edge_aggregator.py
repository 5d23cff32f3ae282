"""Edge aggregators (a two-level tree of federation): the mean as one float64 sum, a site's sum on the wire,
and the aggregator's state machine — an exchange closed up, the root's answer down, a member dropping."""

from __future__ import annotations

import threading

import numpy as np
import pytest
from conftest import StepAgent, chief_of

from fleetrl.federation.aggregation import mean, mean_of_parts, weighted_sum
from fleetrl.federation.chief.machine import Chief
from fleetrl.federation.chief.state import FleetModel
from fleetrl.federation.edge.aggregator import EdgeAggregator, EdgeStep, check_tree
from fleetrl.federation.edge.runner import run_edge
from fleetrl.federation.plan import ChiefPlan
from fleetrl.federation.runner import IdleTimeout, run_chief
from fleetrl.federation.schemes.pergrad import PerStepGradientScheme
from fleetrl.federation.shared_settings import SettingsRefused
from fleetrl.federation.wire.messages import Message, MessageRejected, Reason, decode, encode
from fleetrl.federation.wire.signing import status_payload
from fleetrl.transport.local import LocalBus

LAYOUT = [("w", (3,))]
WELCOME_LAYOUT = [("m", (2,))]
ROOT, SITE = "root", "site-a"
K = 2


def f32(*values: float) -> np.ndarray:
    return np.array(values, np.float32)


# ---- the sum path ----


def test_the_weighted_mean_is_the_hand_computed_sum_over_the_weights() -> None:
    xs = [f32(1.0, -2.0, 0.5), f32(4.0, 0.0, 0.25), f32(-1.0, 8.0, 1.0)]
    # (1·1 + 2·4 + 3·(-1)) / 6 = 1, (1·(-2) + 0 + 3·8) / 6 = 22/6, (0.5 + 0.5 + 3) / 6 = 4/6
    expected = np.array([1.0, 22 / 6, 4 / 6], np.float64).astype(np.float32)
    assert mean(xs, [1, 2, 3]).tobytes() == expected.tobytes()
    total, weight = weighted_sum(xs, [1, 2, 3])
    assert (total.tolist(), weight) == ([6.0, 22.0, 4.0], 6.0)


def test_equal_weights_give_np_mean_s_bits() -> None:
    rng = np.random.default_rng(5)
    for n in (1, 2, 3, 4, 7):
        xs = [(rng.normal(size=257) * 10.0 ** rng.integers(-9, 3, 257)).astype(np.float32) for _ in range(n)]
        flat = np.asarray(np.mean(np.stack(xs), axis=0, dtype=np.float64), dtype=np.float32)
        assert mean(xs).tobytes() == flat.tobytes()
        assert mean(xs, [1.0] * n).tobytes() == flat.tobytes()


def test_a_site_s_sum_and_a_plain_member_give_the_flat_mean() -> None:
    a, b, c = f32(0.1, 3.0, -7.5), f32(2.5, -1.25, 1e-3), f32(-0.3, 0.7, 9.0)
    site, units = weighted_sum([a, b], [1, 2])  # a site of two members, the second a host of 2 units
    tree = mean_of_parts([site, c], [units, 3.0], [True, False])
    assert tree.tobytes() == mean([a, b, c], [1, 2, 3]).tobytes()
    assert (
        mean_of_parts([site, c], [units, 1.0], [True, False]).tobytes()
        == mean([a, b, c], [1, 2, 1]).tobytes()
    )


def test_a_site_s_sum_travels_as_float64_and_only_a_chief_that_takes_sums_reads_it() -> None:
    total = np.array([0.1, 1e-30, 3.0]) + np.array([1e-17, 0.0, 0.0])  # not a float32 value
    message = Message("step_gradient", ROOT, SITE, 1, flat=total, units=2, summed=True)
    wire = encode(message, layout=LAYOUT)
    read = decode(
        wire, run_id=ROOT, known_senders={SITE}, layout=LAYOUT, scheme_types=("step_gradient",), sums=True
    )
    assert read.summed and read.flat is not None and read.flat.tobytes() == total.tobytes()
    with pytest.raises(MessageRejected) as refused:
        decode(wire, run_id=ROOT, known_senders={SITE}, layout=LAYOUT, scheme_types=("step_gradient",))
    assert refused.value.reason is Reason.LAYOUT_MISMATCH


def test_a_tree_refuses_robust_rules_and_schemes_that_do_not_sum() -> None:
    check_tree("pergrad", "mean")
    check_tree("fedavg", "mean")
    with pytest.raises(ValueError, match="does not decompose"):
        check_tree("pergrad", "trimmed_mean:0.1")
    with pytest.raises(ValueError, match="cannot run behind edge aggregators"):
        check_tree("paper", "mean")


# ---- the state machine ----


def edge(**options: object) -> EdgeAggregator:
    return chief_of(  # type: ignore[no-any-return]
        EdgeAggregator, site_id=SITE, root_run=ROOT, run_id="site-a-run", members=("1", "2"), layout=LAYOUT,
        welcome_layout=WELCOME_LAYOUT, scheme="pergrad", max_rounds=3, steps_per_round=K, quorum=1.0,
        **options,  # type: ignore[arg-type]
    )  # fmt: skip


def online(worker: str) -> bytes:
    return status_payload(b"online", run_id="site-a-run", node=worker, incarnation=1)


def offline(worker: str) -> bytes:
    return status_payload(b"offline", run_id="site-a-run", node=worker, incarnation=1)


def step_grad(worker: str, rnd: int, step: int, *values: float, kind: str = "step_gradient") -> bytes:
    message = Message(kind, "site-a-run", worker, rnd, step=step, flat=f32(*values))
    return encode(message, layout=LAYOUT)


def root_welcome() -> Message:
    return Message("welcome", ROOT, "chief", 1, flat=f32(7.0, 8.0), origin="chief")


def started(e: EdgeAggregator) -> EdgeStep:
    e.start(now=0.0)
    held = e.status("1", online("1"), now=0.0) + e.status("2", online("2"), now=0.0)
    assert held.down == ()  # the site has no model yet: its members wait for the root's welcome
    return e.from_root(root_welcome(), now=0.1)


def test_the_root_s_welcome_releases_the_members_welcome_with_the_fleet_s_model() -> None:
    e = edge()
    (join,) = e.start(now=0.0).up
    assert (join.type, join.run_id, join.sender) == ("join", ROOT, SITE)
    (welcome,) = started(e).down
    assert welcome.type == "welcome" and welcome.flat is not None and welcome.flat.tolist() == [7.0, 8.0]
    assert (welcome.run_id, welcome.round, welcome.step) == ("site-a-run", 1, 0)


def test_an_exchange_closes_up_as_one_sum_and_the_root_s_answer_comes_down() -> None:
    e = edge()
    started(e)
    first = e.receive_bytes(step_grad("2", 1, 0, 1.0, 2.0, 3.0), topic_worker="2", now=1.0)
    assert first.up == () and first.down == ()
    (up,) = e.receive_bytes(step_grad("1", 1, 0, 0.5, 0.5, 0.5), topic_worker="1", now=1.0).up
    assert (up.type, up.run_id, up.sender, up.round, up.step, up.units, up.summed) == (
        "step_gradient", ROOT, SITE, 1, 0, 2, True,
    )  # fmt: skip
    assert up.flat is not None and up.flat.tolist() == [1.5, 2.5, 3.5]
    # the root (two sites of 2 units) answers; the members get it with member ids
    answer = Message(
        "average", ROOT, "chief", 1, step=0, flat=f32(0.25, 0.5, 1.0), contributors=(SITE, "site-b")
    )
    (down,) = e.from_root(answer, now=2.0).down
    assert (down.type, down.run_id, down.round, down.step, down.contributors) == (
        "average", "site-a-run", 1, 0, ("1", "2"),
    )  # fmt: skip
    assert down.flat is not None and down.flat.tolist() == [0.25, 0.5, 1.0]
    assert e.from_root(answer, now=2.5).down == ()  # a copy of an answer passed on changes nothing
    assert (e.site.round, e.site.state.step) == (1, 1)


def test_a_site_whose_members_all_completed_is_complete_at_the_root() -> None:
    e = edge()
    started(e)
    e.receive_bytes(step_grad("1", 1, 0, 1, 1, 1, kind="parameters"), topic_worker="1", now=1.0)
    (up,) = e.receive_bytes(step_grad("2", 1, 0, 1, 1, 1), topic_worker="2", now=1.0).up
    assert up.type == "step_gradient"  # member 2 has not completed
    e.from_root(
        Message("average", ROOT, "chief", 1, step=0, flat=f32(1, 1, 1), contributors=(SITE,)), now=2.0
    )
    e.receive_bytes(step_grad("1", 1, 1, 1, 1, 1, kind="parameters"), topic_worker="1", now=3.0)
    (up,) = e.receive_bytes(step_grad("2", 1, 1, 1, 1, 1, kind="parameters"), topic_worker="2", now=3.0).up
    assert up.type == "parameters"


def test_an_unanswered_exchange_is_sent_up_again_and_done_ends_the_members_run() -> None:
    e = edge(dropout_grace=1.0)
    started(e)
    e.receive_bytes(step_grad("1", 1, 0, 1, 1, 1), topic_worker="1", now=1.0)
    (up,) = e.receive_bytes(step_grad("2", 1, 0, 1, 1, 1), topic_worker="2", now=1.0).up
    assert e.tick(2.0).up == ()
    assert e.tick(6.5).up == (up,)  # resend_interval 5 s
    (done,) = e.from_root(Message("done", ROOT, "chief", 1), now=7.0).down
    assert done.type == "done" and e.finished


def test_a_member_dropping_out_leaves_the_site_and_the_next_exchange_closes_without_it() -> None:
    e = edge(dropout_grace=1.0)
    started(e)
    e.receive_bytes(step_grad("1", 1, 0, 1, 1, 1), topic_worker="1", now=1.0)
    e.receive_bytes(step_grad("2", 1, 0, 3, 3, 3), topic_worker="2", now=1.0)
    e.from_root(
        Message("average", ROOT, "chief", 1, step=0, flat=f32(2, 2, 2), contributors=(SITE,)), now=2.0
    )
    e.status("2", offline("2"), now=2.0)
    dropped = e.tick(3.5)
    assert [ev.kind for ev in dropped.events] == ["dropped"] and e.site.members == ("1",)
    (up,) = e.receive_bytes(step_grad("1", 1, 1, 4, 4, 4), topic_worker="1", now=4.0).up
    assert (up.units, up.step) == (1, 1) and up.flat is not None and up.flat.tolist() == [4.0, 4.0, 4.0]


def test_the_root_takes_a_site_s_sum_as_its_members_and_answers_with_the_flat_mean() -> None:
    root = Chief(
        ChiefPlan(
            run_id=ROOT,
            workers=(SITE, "9"),
            layout=LAYOUT,
            max_rounds=3,
            scheme="pergrad",
            steps_per_round=K,
            quorum=1.0,
        )
    )
    e = edge()
    started(e)
    e.receive_bytes(step_grad("1", 1, 0, 1.0, 2.0, 0.1), topic_worker="1", now=1.0)
    (up,) = e.receive_bytes(step_grad("2", 1, 0, 3.0, 5.0, 0.2), topic_worker="2", now=1.0).up
    root.receive_bytes(encode(up, layout=LAYOUT), topic_worker=SITE, now=1.0)
    plain = Message("step_gradient", ROOT, "9", 1, step=0, flat=f32(-1.0, 0.5, 0.3))
    (answer,) = root.receive_bytes(encode(plain, layout=LAYOUT), topic_worker="9", now=1.0).outgoing
    flat = mean([f32(1.0, 2.0, 0.1), f32(3.0, 5.0, 0.2), f32(-1.0, 0.5, 0.3)])
    assert answer.flat is not None and answer.flat.tobytes() == flat.tobytes()
    assert (answer.units, answer.contributors) == (3, ("9", SITE))  # numeric ids sort first
    robust = Chief(
        ChiefPlan(
            run_id=ROOT,
            workers=(SITE,),
            layout=LAYOUT,
            max_rounds=3,
            scheme="pergrad",
            steps_per_round=K,
            aggregator="median",
        )
    )
    step = robust.receive_bytes(encode(up, layout=LAYOUT), topic_worker=SITE, now=1.0)
    assert [ev.reason for ev in step.events] == [Reason.LAYOUT_MISMATCH]


def test_a_site_refused_by_the_root_ends_its_members_run() -> None:
    e = edge(settings={"preset": "paper"})
    started_at = e.start(now=0.0)
    assert started_at.up[0].settings == {"preset": "paper"}
    refusal = Message("refused", ROOT, "chief", 1, finished=(SITE,), detail="setting 'preset' differs")
    (done,) = e.from_root(refusal, now=1.0).down
    assert done.type == "done" and e.finished and e.site.refused
    assert e.site.end_reason == "refused by the chief of run 'root': setting 'preset' differs"
    other = edge(settings={"preset": "paper"})
    other.start(now=0.0)
    elsewhere = Message("refused", ROOT, "chief", 1, finished=("9",), detail="not us")
    assert other.from_root(elsewhere, now=1.0) == EdgeStep() and not other.finished


def test_the_aggregator_s_loop_joins_the_root_and_raises_when_refused() -> None:
    bus = LocalBus()
    root = Chief(
        ChiefPlan(
            run_id=ROOT,
            workers=(SITE,),
            layout=LAYOUT,
            max_rounds=3,
            scheme="pergrad",
            steps_per_round=K,
            settings={"preset": "standard"},
        )
    )
    chief_end: list[BaseException] = []

    def serve() -> None:
        try:
            run_chief(root, bus.client(), idle_timeout=1.0)
        except IdleTimeout as exc:
            chief_end.append(exc)

    thread = threading.Thread(target=serve)
    thread.start()
    with pytest.raises(
        SettingsRefused, match="site site-a: refused by the chief of run 'root': setting 'preset'"
    ):
        run_edge(
            edge(settings={"preset": "paper"}),
            upstream=bus.client(),
            downstream=bus.client(),
            idle_timeout=5.0,
        )
    thread.join(10.0)
    assert chief_end and root.rejections[Reason.REFUSED] == 0  # refused at join, before anything was sent


def test_a_member_joining_late_is_welcomed_with_the_fleet_s_model_as_the_site_holds_it() -> None:
    model = FleetModel(PerStepGradientScheme(), StepAgent())  # type: ignore[arg-type]
    e = EdgeAggregator(
        ChiefPlan(
            run_id="site-a-run",
            workers=("1",),
            layout=LAYOUT,
            welcome_layout=model.layout,
            scheme="pergrad",
            max_rounds=3,
            steps_per_round=K,
            quorum=1.0,
        ),
        site_id=SITE,
        root_run=ROOT,
        fleet_model=model,
    )
    e.start(now=0.0)
    e.from_root(Message("welcome", ROOT, "chief", 1, flat=f32(5.0, 6.0, 2.0), origin="chief"), now=0.0)
    assert len(e.receive_bytes(step_grad("1", 1, 0, 1, 1, 1), topic_worker="1", now=1.0).up) == 1
    e.from_root(Message("average", ROOT, "chief", 1, flat=f32(1.0, 2.0, 0.0), contributors=(SITE,)), now=2.0)
    join = encode(Message("join", "site-a-run", "7", 1), layout=LAYOUT)
    step = e.receive_bytes(join, topic_worker="7", now=3.0)
    (welcome,) = step.down
    assert [ev.kind for ev in step.events] == ["admitted", "welcome"]
    assert (welcome.round, welcome.step) == (1, 1)  # the open exchange: after the root's first answer
    assert welcome.flat is not None and welcome.flat.tolist() == [4.0, 4.0, 3.0]  # start, one fleet step
