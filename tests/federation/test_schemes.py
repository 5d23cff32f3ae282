"""Each scheme as a strategy object, on hand-computed arrays: no chief, no worker, no broker."""

from __future__ import annotations

import numpy as np
import pytest

from fleetrl.federation.aggregation import get_aggregator
from fleetrl.federation.chief import Chief
from fleetrl.federation.messages import Message, Reason, encode
from fleetrl.federation.schemes import COMPLETED, SCHEMES, Granularity, RoundContext, Scheme, get_scheme
from fleetrl.federation.schemes.paper import PaperScheme

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


def test_the_registry_builds_each_scheme_and_names_the_choices() -> None:
    assert {name: type(get_scheme(name)).name for name in SCHEMES} == {
        n: n for n in ("paper", "fedavg", "fedavgm", "fedadam")
    }
    choices = r"\(choose paper, fedavg, fedavgm or fedadam\)"
    with pytest.raises(ValueError, match=r"unknown federation scheme 'fedsgd' " + choices):
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


@pytest.mark.parametrize("name", sorted(SCHEMES))
def test_every_scheme_sends_what_its_layout_describes(name: str) -> None:
    scheme: Scheme = get_scheme(name)
    agent = FakeAgent()
    size = sum(int(np.prod(shape)) for _, shape in scheme.layout(agent))
    for completed in (False, True):
        kind, flat = scheme.outgoing(agent, completed=completed)
        assert flat.size == size and scheme.accepts(kind)


class PerStepScheme(PaperScheme):
    """A scheme that would send once per optimisation step (none is registered yet)."""

    name = "per-step"
    granularity = Granularity.STEP


def test_the_per_round_chief_and_worker_refuse_a_per_step_scheme() -> None:
    with pytest.raises(
        ValueError, match="'per-step' sends per step: this chief drives per-round schemes only"
    ):
        Chief(run_id=RUN, workers=("1",), layout=[("pi", (2,))], max_rounds=3, scheme=PerStepScheme())


def test_a_message_for_a_step_is_rejected_by_a_per_round_chief() -> None:
    chief = Chief(run_id=RUN, workers=("1", "2"), layout=[("pi", (2,))], max_rounds=3)
    message = Message("gradient", RUN, "1", 1, flat=np.ones(2, np.float32), step=2)
    step = chief.receive_bytes(encode(message, layout=[("pi", (2,))]), topic_worker="1", now=0.0)
    assert [(e.reason, e.detail) for e in step.events] == [(Reason.BAD_ROUND, "step 2 in a per-round scheme")]
    assert chief.answered == ()
