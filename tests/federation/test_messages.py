"""The wire format: round trips, every rejection reason, and property tests on the decoder."""

from __future__ import annotations

from typing import Any

import msgpack
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from fleetrl.federation.wire.messages import (
    VERSION,
    Message,
    MessageRejected,
    Reason,
    check_scheme_type,
    decode,
    default_max_bytes,
    encode,
    envelope,
)

LAYOUT = [("w", (2, 3)), ("b", (3,))]
SENDERS = ("1", "2", "3")
FLAT = np.arange(9, dtype=np.float32) / 7


def gradient(**changes: Any) -> Message:
    fields: dict[str, Any] = dict(
        type="gradient", run_id="r1", sender="2", round=5, flat=FLAT, metrics={"score": 3}
    )
    fields.update(changes)
    return Message(**fields)


def dec(payload: bytes, **kw: Any) -> Message:
    args: dict[str, Any] = dict(run_id="r1", known_senders=SENDERS, layout=LAYOUT, scheme_types=("gradient",))
    args.update(kw)
    return decode(payload, **args)


def packed(**changes: Any) -> bytes:
    env = envelope(gradient(), layout=LAYOUT)
    env.update(changes)
    return bytes(msgpack.packb(env, use_bin_type=True))


def reason_of(payload: bytes, **kw: Any) -> Reason:
    with pytest.raises(MessageRejected) as info:
        dec(payload, **kw)
    return info.value.reason


def test_round_trip_keeps_every_field_and_tensor() -> None:
    msg = dec(encode(gradient(), layout=LAYOUT))
    assert (msg.type, msg.run_id, msg.sender, msg.round, msg.version) == ("gradient", "r1", "2", 5, VERSION)
    assert msg.metrics == {"score": 3.0}
    assert msg.flat is not None and msg.flat.dtype == np.float32
    np.testing.assert_array_equal(msg.flat, FLAT)
    tensors = msg.tensors(LAYOUT)
    assert tensors["w"].shape == (2, 3) and tensors["b"].tolist() == FLAT[6:].tolist()


def test_tensor_bytes_are_raw_little_endian_float32() -> None:
    env = msgpack.unpackb(encode(gradient(), layout=LAYOUT), raw=False)
    assert env["data"] == FLAT.astype("<f4").tobytes()
    assert env["tensors"] == [["w", [2, 3]], ["b", [3]]]


def test_chief_messages_round_trip() -> None:
    transfer = Message("transfer", "r1", "chief", 4, flat=FLAT, origin="2", finished=("2", "3"))
    msg = decode(encode(transfer, layout=LAYOUT), run_id="r1", known_senders=("chief",), layout=LAYOUT)
    assert (msg.origin, msg.finished) == ("2", ("2", "3"))
    done = decode(
        encode(Message("done", "r1", "chief", 9), layout=LAYOUT),
        run_id="r1",
        known_senders=("chief",),
        layout=LAYOUT,
    )
    assert done.type == "done" and done.flat is None


@pytest.mark.parametrize(
    ("payload", "reason"),
    [
        (b"\xc1", Reason.NOT_MSGPACK),
        (b"hello world", Reason.NOT_MSGPACK),
        (msgpack.packb([1, 2, 3]), Reason.MALFORMED),
        (packed(version=VERSION + 1), Reason.WRONG_VERSION),
        (packed(version=str(VERSION)), Reason.WRONG_VERSION),
        (packed(type="gradients"), Reason.UNKNOWN_TYPE),
        (packed(run_id="r2"), Reason.WRONG_RUN_ID),
        (packed(sender="9"), Reason.UNKNOWN_SENDER),
        (packed(sender="chief"), Reason.UNKNOWN_SENDER),
        (packed(round=0), Reason.BAD_ROUND),
        (packed(round=-3), Reason.BAD_ROUND),
        (packed(round="5"), Reason.BAD_ROUND),
        (packed(round=True), Reason.BAD_ROUND),
        (packed(round=1.0), Reason.BAD_ROUND),
        (packed(metrics={"score": float("nan")}), Reason.BAD_METRICS),
        (packed(metrics=[1]), Reason.BAD_METRICS),
        (packed(tensors=[["w", [3, 2]], ["b", [3]]]), Reason.LAYOUT_MISMATCH),
        (packed(tensors=[["W", [2, 3]], ["b", [3]]]), Reason.LAYOUT_MISMATCH),
        (packed(tensors=[["w", [2, 3]]]), Reason.LAYOUT_MISMATCH),
        (packed(data=b"\x00" * 32), Reason.LAYOUT_MISMATCH),
        (packed(data="text"), Reason.LAYOUT_MISMATCH),
        (packed(data=np.array([np.nan] + [0] * 8, "<f4").tobytes()), Reason.NOT_FINITE),
        (packed(data=np.array([0] * 8 + [np.inf], "<f4").tobytes()), Reason.NOT_FINITE),
        (packed(data=np.array([-np.inf] * 9, "<f4").tobytes()), Reason.NOT_FINITE),
        (packed(origin=3), Reason.MALFORMED),
        (packed(finished="1"), Reason.MALFORMED),
        (packed(extra=1), Reason.MALFORMED),
    ],
)
def test_each_defect_is_rejected_with_its_reason(payload: bytes, reason: Reason) -> None:
    assert reason_of(payload) == reason


def test_missing_key_is_malformed() -> None:
    env = envelope(gradient(), layout=LAYOUT)
    del env["metrics"]
    assert reason_of(msgpack.packb(env)) == Reason.MALFORMED


def test_oversized_is_rejected_before_parsing() -> None:
    payload = encode(gradient(), layout=LAYOUT)
    assert reason_of(payload, max_bytes=len(payload) - 1) == Reason.OVERSIZED
    assert reason_of(b"\x00" * (default_max_bytes(LAYOUT) + 1)) == Reason.OVERSIZED


def test_done_carries_the_whole_layout_or_no_tensors() -> None:
    env = envelope(Message("done", "r1", "2", 3), layout=LAYOUT)
    env["tensors"], env["data"] = [["w", [3, 3]]], FLAT.tobytes()
    assert reason_of(msgpack.packb(env)) == Reason.LAYOUT_MISMATCH
    env["tensors"] = [["w", [2, 3]], ["b", [3]]]  # the fleet's final model, from a chief that keeps it
    back = decode(msgpack.packb(env), run_id="r1", known_senders=("2",), layout=LAYOUT)
    assert back.flat is not None and back.flat.tolist() == FLAT.tolist()
    plain = decode(encode(Message("done", "r1", "2", 3), layout=LAYOUT), run_id="r1", known_senders=("2",),
                   layout=LAYOUT)  # fmt: skip
    assert plain.flat is None


def test_encode_refuses_what_receivers_reject() -> None:
    with pytest.raises(ValueError, match="NaN"):
        encode(gradient(flat=np.full(9, np.nan, np.float32)), layout=LAYOUT)
    with pytest.raises(ValueError, match="layout"):
        encode(gradient(flat=np.zeros(4, np.float32)), layout=LAYOUT)
    with pytest.raises(ValueError, match="unknown message type"):
        encode(gradient(type="Hello World"), layout=LAYOUT)
    with pytest.raises(ValueError, match="config entry 'mu'"):
        encode(gradient(config={"mu": float("inf")}), layout=LAYOUT)


def test_a_scheme_s_own_type_is_taken_only_by_a_receiver_that_expects_it() -> None:
    payload = encode(gradient(type="model_delta"), layout=LAYOUT)
    assert reason_of(payload) == Reason.UNKNOWN_TYPE  # the receiver expects "gradient" only
    assert dec(payload, scheme_types=("model_delta",)).type == "model_delta"
    with pytest.raises(ValueError, match="not one of the protocol's types"):
        check_scheme_type("average")
    assert check_scheme_type("model_delta") == "model_delta"


def test_what_a_message_stands_for_and_the_round_s_config_travel() -> None:
    sent = gradient(samples=812, units=3, config={"mu": 0.01, "phase": "warm-up"})
    back = dec(encode(sent, layout=LAYOUT))
    assert (back.samples, back.units, back.config) == (812, 3, {"mu": 0.01, "phase": "warm-up"})
    assert reason_of(packed(samples=-1)) == Reason.MALFORMED
    assert reason_of(packed(units=True)) == Reason.MALFORMED
    assert reason_of(packed(config={"mu": [1]})) == Reason.MALFORMED
    assert reason_of(packed(config={"mu": float("nan")})) == Reason.MALFORMED


def test_a_welcome_carries_the_tensors_of_its_own_layout() -> None:
    start = [("theta", (4,))]
    welcome = Message("welcome", "r1", "chief", 1, flat=np.ones(4, np.float32))
    payload = encode(welcome, layout=start)
    back = decode(payload, run_id="r1", known_senders=("chief",), layout=LAYOUT, layouts={"welcome": start})
    assert back.flat is not None and back.flat.tolist() == [1.0] * 4
    with pytest.raises(MessageRejected):
        decode(payload, run_id="r1", known_senders=("chief",), layout=LAYOUT)


def _only_rejections(payload: bytes) -> None:
    try:
        dec(payload)
    except MessageRejected as exc:
        assert isinstance(exc.reason, Reason)


@settings(max_examples=400, deadline=None)
@given(st.binary(max_size=400))
def test_random_bytes_only_ever_raise_message_rejected(payload: bytes) -> None:
    _only_rejections(payload)


VALID = encode(gradient(), layout=LAYOUT)


@settings(max_examples=400, deadline=None)
@given(
    st.lists(st.tuples(st.integers(0, len(VALID) - 1), st.integers(0, 255)), min_size=1, max_size=8),
    st.integers(0, len(VALID)),
)
def test_mutated_valid_bytes_only_ever_raise_message_rejected(flips: list[tuple[int, int]], cut: int) -> None:
    data = bytearray(VALID)
    for pos, value in flips:
        data[pos] = value
    _only_rejections(bytes(data[:cut]) if cut % 3 == 0 else bytes(data))


msgpack_values = st.recursive(
    st.none() | st.booleans() | st.integers(-(2**63), 2**64 - 1) | st.floats() | st.text(max_size=20)
    | st.binary(max_size=40),
    lambda inner: st.lists(inner, max_size=4) | st.dictionaries(st.text(max_size=8), inner, max_size=4),
    max_leaves=12,
)  # fmt: skip


@settings(max_examples=400, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.sampled_from(sorted(envelope(gradient(), layout=LAYOUT))), msgpack_values)
def test_mutated_envelope_fields_only_ever_raise_message_rejected(key: str, value: object) -> None:
    env = envelope(gradient(), layout=LAYOUT)
    env[key] = value
    _only_rejections(msgpack.packb(env, use_bin_type=True))


def test_deeply_nested_payload_is_rejected_not_crashing() -> None:
    nested: object = 1
    for _ in range(3000):
        nested = [nested]
    payload = b"\x91" * 3000 + b"\x01"
    assert reason_of(payload) in (Reason.NOT_MSGPACK, Reason.MALFORMED)
    assert nested is not None


def test_only_a_join_may_name_round_0_the_round_its_worker_resumes_at_when_none() -> None:
    join = encode(Message("join", "r1", "1", 0, settings={}), layout=LAYOUT)
    assert dec(join).round == 0
    assert reason_of(packed(round=0)) is Reason.BAD_ROUND
