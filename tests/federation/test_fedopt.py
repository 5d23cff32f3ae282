"""The server-optimiser schemes (``fedavgm``, ``fedadam``) on hand-computed arrays: no chief, no broker."""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

import numpy as np
import pytest

from fleetrl.federation.aggregation import get_aggregator
from fleetrl.federation.chief.checkpoint import chief_to_state
from fleetrl.federation.chief.machine import Chief
from fleetrl.federation.plan import ChiefPlan
from fleetrl.federation.schemes import RoundAnswer, RoundContext, Scheme, get_scheme
from fleetrl.federation.schemes.fedavg import FedAvgScheme
from fleetrl.federation.wire.messages import Message, encode
from fleetrl.runs.checkpoints import ChiefCheckpoint

RUN = "opt"
MEMBERS = ("1", "2")


def models(*vectors: list[float], kind: str = "model") -> dict[str, Message]:
    return {
        w: Message(kind, RUN, w, 1, flat=np.array(v, np.float32))
        for w, v in zip(MEMBERS, vectors, strict=True)
    }


def combine(scheme: Scheme, *vectors: list[float], completed: Mapping[str, int] | None = None) -> RoundAnswer:
    return scheme.combine(models(*vectors), RoundContext(get_aggregator("mean"), MEMBERS, completed or {}))


def test_the_first_round_is_fedavgs_and_sets_x_and_zero_moments() -> None:
    scheme = get_scheme("fedavgm", momentum=0.9)
    answer = combine(scheme, [1.0, 2.0], [3.0, 6.0])
    assert answer.kind == "average" and answer.fleet_model and answer.contributors == MEMBERS
    np.testing.assert_array_equal(answer.flat, [2.0, 4.0])
    fields, tensors = scheme.state()
    assert fields == {} and set(tensors) == {"x", "v"}
    np.testing.assert_array_equal(tensors["v"], [0.0, 0.0])


def test_momentum_over_three_rounds_by_hand() -> None:
    scheme = get_scheme("fedavgm", server_lr=0.5, momentum=0.5)
    combine(scheme, [0.0, 0.0], [2.0, 4.0])  # x = [1, 2], v = 0
    # round 2: mean [3, 2]; Δ = [2, 0]; v = [2, 0]; x = [1, 2] + 0.5·[2, 0] = [2, 2]
    np.testing.assert_array_equal(combine(scheme, [2.0, 2.0], [4.0, 2.0]).flat, [2.0, 2.0])
    # round 3: mean [2, 4]; Δ = [0, 2]; v = 0.5·[2, 0] + [0, 2] = [1, 2]; x = [2, 2] + 0.5·[1, 2] = [2.5, 3]
    np.testing.assert_array_equal(combine(scheme, [2.0, 4.0], [2.0, 4.0]).flat, [2.5, 3.0])
    # round 4: mean [2.5, 3]; Δ = 0; v = [0.5, 1]; x = [2.75, 3.5]
    np.testing.assert_array_equal(combine(scheme, [2.5, 3.0], [2.5, 3.0]).flat, [2.75, 3.5])
    np.testing.assert_array_equal(scheme.state()[1]["v"], [0.5, 1.0])


def test_adams_first_steps_by_hand() -> None:
    scheme = get_scheme("fedadam", server_lr=0.1, beta1=0.5, beta2=0.75, tau=0.5)
    combine(scheme, [1.0, 1.0], [1.0, 1.0])  # x = [1, 1]
    # Δ = [2, -1]; m = 0.5·Δ = [1, -0.5]; v = 0.25·Δ² = [1, 0.25]; x += 0.1·m / (√v + 0.5)
    step = combine(scheme, [3.0, 0.0], [3.0, 0.0]).flat
    np.testing.assert_allclose(step, [1 + 0.1 * 1 / 1.5, 1 - 0.1 * 0.5 / 1.0], rtol=1e-6)
    x = step.astype(np.float64)
    # Δ = [3, 0] − x; m = 0.5·m + 0.5·Δ; v = 0.75·v + 0.25·Δ²
    delta = np.array([3.0, 0.0]) - x
    m = 0.5 * np.array([1.0, -0.5]) + 0.5 * delta
    v = 0.75 * np.array([1.0, 0.25]) + 0.25 * delta**2
    expected = x + 0.1 * m / (np.sqrt(v) + 0.5)
    np.testing.assert_allclose(combine(scheme, [3.0, 0.0], [3.0, 0.0]).flat, expected, rtol=1e-6)


@pytest.mark.parametrize("rule", ["mean", "median", "trimmed_mean:0.2"])
def test_server_lr_one_without_momentum_is_fedavg_bit_for_bit(rule: str) -> None:
    rng = np.random.default_rng(0)
    members = tuple(str(k) for k in range(5))
    ours, theirs = get_scheme("fedavgm"), FedAvgScheme()
    for rnd in range(1, 6):
        answers = {
            w: Message("model", RUN, w, rnd, flat=rng.normal(size=64).astype(np.float32)) for w in members
        }
        completed = {w: 1 for w in members} if rnd == 5 else {}
        context = RoundContext(get_aggregator(rule), members, completed)
        a, b = ours.combine(answers, context), theirs.combine(answers, context)
        assert a.flat.dtype == b.flat.dtype == np.float32
        np.testing.assert_array_equal(a.flat, b.flat)
        assert (a.kind, a.contributors, a.finished, a.fleet_model, a.ends_run) == (
            b.kind, b.contributors, b.finished, b.fleet_model, b.ends_run,
        )  # fmt: skip
    assert a.ends_run and a.finished == members  # fedavg's end rule


@pytest.mark.parametrize("name", ["fedavgm", "fedadam"])
def test_a_chief_restored_from_its_checkpoint_continues_identically(name: str, tmp_path: Path) -> None:
    layout = [("w", (2,))]
    params = {"momentum": 0.9} if name == "fedavgm" else {"server_lr": 0.05}

    def chief(**changes: float) -> Chief:
        scheme = get_scheme(name, **(params | changes))
        return Chief(ChiefPlan(run_id=RUN, workers=MEMBERS, layout=layout, max_rounds=9, scheme=scheme))

    def play(boss: Chief, rnd: int) -> np.ndarray:
        out = None
        for k, w in enumerate(MEMBERS):
            flat = np.array([rnd * (k + 1), -rnd / (k + 2)], np.float32)
            out = boss.receive_bytes(
                encode(Message("model", RUN, w, rnd, flat=flat), layout=layout), topic_worker=w, now=0.0
            )
        assert out is not None
        (answer,) = [m for m in out.outgoing if m.type == "average"]
        assert answer.flat is not None
        return answer.flat

    straight = chief()
    for rnd in (1, 2, 3):
        play(straight, rnd)
    assert {"scheme.x", "scheme.v"} <= set(chief_to_state(straight)[1])
    store = ChiefCheckpoint(tmp_path)
    store.save(straight)
    with pytest.raises(ValueError, match="scheme_params: checkpoint"):
        store.load(now=0.0, expect=chief(server_lr=0.5))
    resumed = store.load(now=0.0, expect=chief())
    assert resumed.scheme.params() == straight.scheme.params()
    for rnd in (4, 5):
        np.testing.assert_array_equal(play(resumed, rnd), play(straight, rnd))


@pytest.mark.parametrize(
    ("name", "params", "message"),
    [
        ("fedavgm", {"momentum": 1.0}, r"momentum = 1.0: must be in \[0, 1\)"),
        ("fedavgm", {"server_lr": 0}, "server_lr = 0.0: must be > 0"),
        ("fedavgm", {"server_lr": "fast"}, "server_lr = 'fast': expected a number"),
        ("fedavgm", {"optimizer": "sgd"}, "optimizer 'sgd': choose momentum or adam"),
        ("fedavgm", {"beta1": 0.5}, "beta1: not a parameter of the momentum optimizer"),
        ("fedadam", {"momentum": 0.5}, "momentum: not a parameter of the adam optimizer"),
        ("fedadam", {"tau": -1}, "tau = -1.0: must be > 0"),
        ("fedadam", {"beta2": 1.5}, r"beta2 = 1.5: must be in \[0, 1\)"),
        ("fedadam", {"lr": 0.1}, r"scheme 'fedadam' has no parameter\(s\) lr \(its parameters: beta1"),
        ("fedavg", {"momentum": 0.9}, r"scheme 'fedavg' has no parameter\(s\) momentum"),
    ],
)
def test_bad_parameters_are_refused_naming_them(name: str, params: dict[str, object], message: str) -> None:
    with pytest.raises(ValueError, match=message):
        get_scheme(name, **params)


def test_restore_refuses_a_state_without_its_moments() -> None:
    scheme = get_scheme("fedadam")
    with pytest.raises(ValueError, match="lacks m, v"):
        scheme.restore({}, {"x": np.zeros(2, np.float32)})
    scheme.restore({}, {})
    assert scheme.state() == ({}, {})
