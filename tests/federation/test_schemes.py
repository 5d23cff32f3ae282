"""Each scheme as a strategy object, on hand-computed arrays: no chief, no worker, no broker."""

from __future__ import annotations

import numpy as np
import pytest

from fleetrl.federation.aggregation import get_aggregator
from fleetrl.federation.chief.machine import Chief
from fleetrl.federation.plan import ChiefPlan
from fleetrl.federation.schemes import (
    COMPLETED,
    SCHEMES,
    AsyncScheme,
    RoundAnswer,
    RoundContext,
    RoundScheme,
    Scheme,
    StepScheme,
    get_scheme,
)
from fleetrl.federation.schemes.base import aggregate
from fleetrl.federation.wire.messages import Message, Reason, encode
from fleetrl.federation.wire.signing import status_payload

RUN = "r1"


class FakeAgent:
    """An agent whose actor is two numbers and whose critic is one more; records what was applied."""

    def __init__(self) -> None:
        self.actor = np.array([1.0, 2.0], np.float32)
        self.critic = np.array([3.0], np.float32)
        self.gradient = np.array([0.5, -0.5], np.float32)
        self.applied: list[np.ndarray] = []

    def actor_layout(self) -> list[tuple[str, tuple[int, ...]]]:
        return [("pi", (2,))]

    def model_layout(self) -> list[tuple[str, tuple[int, ...]]]:
        return [("pi", (2,)), ("v", (1,))]

    def actor_gradient(self) -> np.ndarray:
        return self.gradient.copy()

    def apply_actor_gradient(self, flat: np.ndarray) -> None:
        self.applied.append(flat)
        self.actor = self.actor - flat  # plain SGD with rate 1 stands in for the optimiser

    def actor_parameters(self) -> np.ndarray:
        return self.actor.copy()

    def set_actor_parameters(self, flat: np.ndarray) -> None:
        self.actor = np.array(flat, np.float32)

    def model_parameters(self) -> np.ndarray:
        return np.concatenate([self.actor, self.critic])

    def set_model_parameters(self, flat: np.ndarray) -> None:
        self.actor, self.critic = np.array(flat[:2], np.float32), np.array(flat[2:], np.float32)


def answers(*items: tuple[str, str, list[float]]) -> dict[str, Message]:
    return {w: Message(kind, RUN, w, 1, flat=np.array(v, np.float32)) for w, kind, v in items}


def context(
    members: tuple[str, ...], completed: dict[str, int] | None = None, rule: str = "mean"
) -> RoundContext:
    return RoundContext(get_aggregator(rule), members, completed or {})


def test_the_registry_finds_each_scheme_module_and_names_the_choices() -> None:
    assert {name: type(get_scheme(name)).name for name in SCHEMES} == {n: n for n in SCHEMES}
    assert set(SCHEMES) >= {"paper", "fedavg", "fedavgm", "fedadam", "pergrad"}
    with pytest.raises(
        ValueError, match=r"unknown federation scheme 'fedsgd' \(choose fedasync, fedavg, .* or pergrad, or"
    ):
        get_scheme("fedsgd")
    with pytest.raises(
        ValueError, match=r"scheme 'paper' has no parameter\(s\) momentum \(its parameters: none\)"
    ):
        get_scheme("paper", momentum=0.9)


def test_paper_shares_the_actor_and_sends_its_gradient_then_its_parameters() -> None:
    scheme, agent = get_scheme("paper"), FakeAgent()
    assert scheme.layout(agent) == [("pi", (2,))]
    kind, flat = scheme.outgoing(agent, completed=False)
    assert kind == "gradient" and flat.tolist() == [0.5, -0.5]
    kind, flat = scheme.outgoing(agent, completed=True)
    assert kind == COMPLETED and flat.tolist() == [1.0, 2.0]
    assert scheme.accepts("gradient") and scheme.accepts(COMPLETED) and not scheme.accepts("model")


def test_paper_averages_gradients_with_the_runs_rule() -> None:
    scheme = get_scheme("paper")
    got = answers(("1", "gradient", [1, 4]), ("2", "gradient", [3, 0]), ("3", "gradient", [50, 2]))
    answer = scheme.combine(got, context(("1", "2", "3")))
    assert (answer.kind, answer.contributors, answer.leave_w, answer.ends_run) == (
        "average", ("1", "2", "3"), (), False
    )  # fmt: skip
    np.testing.assert_allclose(answer.flat, [18.0, 2.0])
    assert not answer.fleet_model  # an average gradient is no model a joiner could start from
    median = scheme.combine(got, context(("1", "2", "3"), rule="median"))
    np.testing.assert_allclose(median.flat, [3.0, 2.0])


def test_paper_transfers_the_lowest_completed_worker_and_discards_the_gradients() -> None:
    scheme = get_scheme("paper")
    got = answers(("1", "gradient", [1, 1]), ("2", COMPLETED, [7, 8]), ("3", COMPLETED, [9, 9]))
    answer = scheme.combine(got, context(("1", "2", "3"), {"2": 1, "3": 1}))
    assert (answer.kind, answer.origin, answer.finished, answer.leave_w) == (
        "transfer",
        "2",
        ("2", "3"),
        ("2", "3"),
    )
    np.testing.assert_array_equal(answer.flat, [7, 8])
    assert answer.fleet_model and not answer.ends_run


def test_paper_applies_an_average_through_the_optimiser_unless_the_worker_is_mature() -> None:
    scheme, agent = get_scheme("paper"), FakeAgent()
    scheme.apply_average(agent, np.array([1.0, 1.0], np.float32), completed=False, contributed=True)
    assert agent.actor.tolist() == [0.0, 1.0] and agent.critic.tolist() == [3.0]
    scheme.apply_average(agent, np.array([1.0, 1.0], np.float32), completed=True, contributed=False)
    assert agent.actor.tolist() == [0.0, 1.0]  # late with its θ: it keeps its mature policy
    with pytest.raises(RuntimeError, match="parameters with an average"):
        scheme.apply_average(agent, np.array([1.0, 1.0], np.float32), completed=True, contributed=True)
    scheme.take_parameters(agent, np.array([5.0, 6.0], np.float32))
    assert agent.actor.tolist() == [5.0, 6.0] and agent.critic.tolist() == [3.0]


def test_fedavg_shares_the_whole_model() -> None:
    scheme, agent = get_scheme("fedavg"), FakeAgent()
    assert scheme.layout(agent) == [("pi", (2,)), ("v", (1,))]
    assert [(k, f.tolist()) for k, f in (scheme.outgoing(agent, completed=c) for c in (False, True))] == [
        ("model", [1.0, 2.0, 3.0]),
        (COMPLETED, [1.0, 2.0, 3.0]),
    ]
    scheme.apply_average(agent, np.array([4.0, 5.0, 6.0], np.float32), completed=True, contributed=False)
    assert agent.actor.tolist() == [4.0, 5.0] and agent.critic.tolist() == [6.0] and agent.applied == []


def test_fedavg_averages_models_and_a_mature_one_stays() -> None:
    scheme = get_scheme("fedavg")
    got = answers(("1", "model", [0, 0, 0]), ("2", COMPLETED, [6, 3, 3]), ("3", "model", [3, 0, 6]))
    answer = scheme.combine(got, context(("1", "2", "3"), {"2": 1}))
    assert (answer.kind, answer.leave_w, answer.finished, answer.ends_run) == ("average", (), (), False)
    np.testing.assert_allclose(answer.flat, [3.0, 1.0, 3.0])
    assert answer.fleet_model


def test_fedavg_ends_the_run_once_every_member_has_completed() -> None:
    scheme = get_scheme("fedavg")
    got = answers(("1", "model", [1, 1, 1]), ("3", COMPLETED, [3, 3, 3]))
    answer = scheme.combine(got, context(("1", "3"), {"1": 4, "2": 1, "3": 9}))
    assert answer.ends_run and answer.finished == ("1", "3")
    not_yet = scheme.combine(got, context(("1", "2", "3", "4"), {"1": 4, "2": 1, "3": 9}))
    assert not not_yet.ends_run and not_yet.finished == ()


@pytest.mark.parametrize(
    "name",
    sorted(n for n, s in SCHEMES.items() if issubclass(s, RoundScheme) and not issubclass(s, AsyncScheme)),
)
def test_every_per_round_scheme_sends_what_its_layout_describes(name: str) -> None:
    scheme: Scheme = get_scheme(name)
    agent = FakeAgent()
    size = sum(int(np.prod(shape)) for _, shape in scheme.layout(agent))
    for completed in (False, True):
        kind, flat = scheme.outgoing(agent, completed=completed)
        assert flat.size == size and scheme.accepts(kind)


LAYOUT2 = [("g", (2,))]


class StepAgent(FakeAgent):
    """FakeAgent with an update of two steps, each moving the same two parameters."""

    def __init__(self) -> None:
        super().__init__()
        self.stepped: list[np.ndarray] = []
        self.moments = np.zeros(2, np.float32)
        """a stand-in for the optimisers' state"""

    def optimiser_layout(self) -> list[tuple[str, tuple[int, ...]]]:
        return [("optim.m", (2,))]

    def optimiser_parameters(self) -> np.ndarray:
        return self.moments.copy()

    def set_optimiser_parameters(self, flat: np.ndarray) -> None:
        self.moments = flat.copy()

    def update_step_count(self) -> int:
        return 2

    def step_layout(self, k: int) -> list[tuple[str, tuple[int, ...]]]:
        return LAYOUT2

    def apply_step(self, flat_grad: np.ndarray) -> None:
        self.stepped.append(flat_grad)


def test_pergrad_averages_each_steps_gradients_and_ends_at_the_last_step_once_all_completed() -> None:
    scheme, agent = get_scheme("pergrad"), StepAgent()
    assert isinstance(scheme, StepScheme) and scheme.shared_start and scheme.stays_after_completion
    assert scheme.layout(agent) == LAYOUT2 and scheme.exchanges_per_round(agent) == 2
    grads = answers(("1", "step_gradient", [1.0, 4.0]), ("2", COMPLETED, [3.0, -2.0]))
    middle = scheme.combine(
        grads, RoundContext(get_aggregator("mean"), ("1", "2"), {"1": 3, "2": 5}, 0, False)
    )
    np.testing.assert_array_equal(middle.flat, [2.0, 1.0])  # (1+3)/2, (4-2)/2
    assert middle.kind == "average" and middle.contributors == ("1", "2") and not middle.ends_run
    assert middle.finished == () and not middle.fleet_model  # no model travels: nobody rejoins from it
    last = scheme.combine(grads, RoundContext(get_aggregator("mean"), ("1", "2"), {"1": 3, "2": 5}, 1, True))
    assert last.ends_run and last.finished == ("1", "2")
    not_yet = scheme.combine(grads, RoundContext(get_aggregator("mean"), ("1", "2"), {"2": 5}, 1, True))
    assert not not_yet.ends_run and not_yet.finished == ()
    median = scheme.combine(
        answers(
            ("1", "step_gradient", [1, 1]), ("2", "step_gradient", [2, 9]), ("3", "step_gradient", [7, 2])
        ),
        RoundContext(get_aggregator("median"), ("1", "2", "3"), {}),
    )
    np.testing.assert_array_equal(median.flat, [2.0, 2.0])  # the run's robust rule applies per step
    scheme.apply_step_answer(agent, middle.flat)
    np.testing.assert_array_equal(agent.stepped[0], [2.0, 1.0])


def test_pergrad_refuses_an_update_whose_steps_move_different_parameters() -> None:
    class Sequential(StepAgent):
        def step_layout(self, k: int) -> list[tuple[str, tuple[int, ...]]]:
            return [("critic", (1,))] if k % 2 == 0 else [("actor", (2,))]

    with pytest.raises(ValueError, match="optimisers = 'per_model'"):
        get_scheme("pergrad").exchanges_per_round(Sequential())


def step_message(worker: str, rnd: int, step: int, values: list[float], kind: str = "step_gradient") -> bytes:
    message = Message(kind, RUN, worker, rnd, step=step, flat=np.array(values, np.float32))
    return encode(message, layout=LAYOUT2)


def test_the_chief_closes_each_step_and_the_round_at_its_last_step() -> None:
    chief = Chief(
        ChiefPlan(
            run_id=RUN, workers=("1", "2"), layout=LAYOUT2, max_rounds=3, scheme="pergrad", steps_per_round=2
        )
    )
    chief.receive_bytes(step_message("1", 1, 0, [1, 2]), topic_worker="1", now=0.0)
    (answer,) = chief.receive_bytes(step_message("2", 1, 0, [3, 4]), topic_worker="2", now=0.0).outgoing
    assert (answer.type, answer.round, answer.step) == ("average", 1, 0)
    np.testing.assert_array_equal(answer.flat, [2.0, 3.0])
    assert chief.round == 1  # still round 1: its step 1 is open
    stale = chief.receive_bytes(step_message("1", 1, 0, [1, 2]), topic_worker="1", now=5.0)
    assert [e.reason for e in stale.events if e.kind == "rejected"] == [Reason.STALE_ROUND]
    early = chief.receive_bytes(step_message("1", 2, 0, [1, 2]), topic_worker="1", now=5.0)
    assert [e.reason for e in early.events] == [Reason.FUTURE_ROUND]
    beyond = chief.receive_bytes(step_message("1", 1, 2, [1, 2]), topic_worker="1", now=5.0)
    assert [(e.reason, e.detail) for e in beyond.events] == [(Reason.BAD_ROUND, "step 2 of 2 per round")]
    chief.receive_bytes(step_message("1", 1, 1, [0, 0], COMPLETED), topic_worker="1", now=6.0)
    (last,) = chief.receive_bytes(step_message("2", 1, 1, [2, 2]), topic_worker="2", now=6.0).outgoing
    assert (last.round, last.step) == (1, 1) and chief.round == 2 and chief.completed == {"1": 1}
    chief.receive_bytes(step_message("1", 2, 0, [0, 0], COMPLETED), topic_worker="1", now=7.0)
    chief.receive_bytes(step_message("2", 2, 0, [0, 0], COMPLETED), topic_worker="2", now=7.0)
    chief.receive_bytes(step_message("1", 2, 1, [0, 0], COMPLETED), topic_worker="1", now=7.0)
    end = chief.receive_bytes(step_message("2", 2, 1, [0, 0], COMPLETED), topic_worker="2", now=7.0)
    assert [m.type for m in end.outgoing] == [
        "average",
        "done",
    ] and chief.end_reason == "every unit completed"
    assert end.outgoing[0].finished == ("1", "2")


def test_a_per_round_chief_rejects_a_step_and_needs_a_deadline_for_a_quorum() -> None:
    chief = Chief(
        ChiefPlan(run_id=RUN, workers=("1", "2"), layout=[("pi", (2,))], max_rounds=3, scheme="paper")
    )
    message = Message("gradient", RUN, "1", 1, flat=np.ones(2, np.float32), step=2)
    step = chief.receive_bytes(encode(message, layout=[("pi", (2,))]), topic_worker="1", now=0.0)
    assert [(e.reason, e.detail) for e in step.events] == [(Reason.BAD_ROUND, "step 2 of 1 per round")]
    assert chief.answered == ()
    with pytest.raises(ValueError, match="scheme 'paper' sends once per round"):
        Chief(
            ChiefPlan(
                run_id=RUN, workers=("1",), layout=LAYOUT2, max_rounds=3, steps_per_round=2, scheme="paper"
            )
        )
    with pytest.raises(ValueError, match=r"scheme 'paper': a quorum below 1 needs a round timeout"):
        Chief(
            ChiefPlan(
                run_id=RUN,
                workers=("1", "2"),
                layout=[("pi", (2,))],
                max_rounds=3,
                scheme="paper",
                quorum=0.5,
            )
        )
    # a per-step scheme's quorum needs no deadline: the grace after it is one (docs/protocol.md "Stragglers")
    Chief(
        ChiefPlan(
            run_id=RUN,
            workers=("1", "2"),
            layout=LAYOUT2,
            max_rounds=3,
            scheme="pergrad",
            steps_per_round=2,
            quorum=0.5,
        )
    )


def test_each_scheme_is_one_protocol_and_has_no_method_of_the_other() -> None:
    for name, cls in SCHEMES.items():
        assert issubclass(cls, RoundScheme) != issubclass(cls, StepScheme), name
    pergrad, paper = get_scheme("pergrad"), get_scheme("paper")
    assert not any(hasattr(pergrad, m) for m in ("outgoing", "apply_average", "local_loss"))
    assert not any(hasattr(paper, m) for m in ("apply_step_answer",))
    assert paper.exchanges_per_round(StepAgent()) == 1


def test_pergrad_workers_take_the_fleet_s_model_with_its_optimisers_state() -> None:
    pergrad, agent = get_scheme("pergrad"), StepAgent()
    assert pergrad.welcome_layout(agent) == [*agent.model_layout(), ("optim.m", (2,))]
    pergrad.take_parameters(agent, np.array([7.0, 8.0, 9.0, 0.5, 0.25], np.float32))
    assert agent.model_parameters().tolist() == [7.0, 8.0, 9.0] and agent.moments.tolist() == [0.5, 0.25]
    assert pergrad.start_parameters(agent).tolist() == [7.0, 8.0, 9.0, 0.5, 0.25]
    paper = get_scheme("paper")
    assert paper.welcome_layout(agent) == agent.actor_layout()
    assert paper.start_parameters(agent).tolist() == [7.0, 8.0]


class Configured(RoundScheme):
    """fedavg-like, asking every worker for its round number (a stand-in for a learning-rate schedule)."""

    name = "configured"
    summary = "test scheme"
    round_message = "model"
    stays_after_completion = True

    def layout(self, agent: object) -> list[tuple[str, tuple[int, ...]]]:
        return [("pi", (2,))]

    def take_parameters(self, agent: object, flat: np.ndarray) -> None: ...

    def outgoing(self, agent: object, *, completed: bool) -> tuple[str, np.ndarray]:
        raise NotImplementedError

    def apply_average(
        self, agent: object, flat: np.ndarray, *, completed: bool, contributed: bool
    ) -> None: ...

    def configure(self, round: int, members: tuple[str, ...]) -> dict[str, float | str]:
        return {"round": float(round), "members": ",".join(members)}

    def combine(self, answers: dict[str, Message], context: RoundContext) -> RoundAnswer:  # type: ignore[override]
        return RoundAnswer("average", aggregate(answers, context), contributors=tuple(answers))


def test_the_chief_weighs_answers_by_their_units_and_configures_each_round() -> None:
    layout = [("pi", (2,))]
    chief = Chief(ChiefPlan(run_id=RUN, workers=("1", "2"), layout=layout, max_rounds=3, scheme=Configured()))
    (welcome,) = chief.status(
        "1", status_payload(b"online", run_id=RUN, node="1", incarnation=1), now=0.0
    ).outgoing
    assert welcome.config == {"round": 1.0, "members": "1,2"}

    def model(worker: str, values: list[float], units: int, samples: int) -> bytes:
        sent = Message(
            "model", RUN, worker, 1, flat=np.array(values, np.float32), units=units, samples=samples
        )
        return encode(sent, layout=layout)

    chief.receive_bytes(model("1", [1.0, 2.0], 1, 200), topic_worker="1", now=0.0)
    (answer,) = chief.receive_bytes(model("2", [4.0, 8.0], 2, 300), topic_worker="2", now=0.0).outgoing
    assert answer.flat is not None and answer.flat.tolist() == [3.0, 6.0]  # (1·[1,2] + 2·[4,8]) / 3
    assert (answer.units, answer.samples) == (3, 500)
    assert answer.config == {"round": 2.0, "members": "1,2"}  # it opens round 2
