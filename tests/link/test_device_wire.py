"""Device wire messages: round trips of indices and vectors, size caps, and every malformed or out-of-range
message is a WireError with its reason."""

from __future__ import annotations

import contextlib

import msgpack
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from fleetrl.link.wire import (
    MAX_ERROR,
    MAX_PAYLOAD,
    MAX_SEQ,
    MAX_SID,
    MAX_VECTOR,
    Command,
    State,
    WireError,
    decode_command,
    decode_state,
    device_topic,
    encode_command,
    encode_state,
)


def test_topics() -> None:
    assert device_topic("r1", 3, "cmd") == "fleetrl/r1/device/3/cmd"
    assert device_topic("r1", 0, "state") == "fleetrl/r1/device/0/state"
    for run_id, unit, leaf in [("a/b", 0, "cmd"), ("r", -1, "cmd"), ("r", True, "cmd"), ("r", 0, "x")]:
        with pytest.raises(ValueError):
            device_topic(run_id, unit, leaf)


def test_command_round_trip() -> None:
    for command in [Command(7, 1, "step", action=2), Command(2**32 - 1, 2**63 - 1, "reset", seed=2**64 - 1)]:
        assert decode_command(encode_command(command), 3, 1) == command
    assert decode_command(encode_command(Command(1, 2, "reset")), 3, 1).seed is None
    assert len(encode_command(Command(123456, 99, "step", action=1))) < 40


def test_a_command_vector_round_trips_as_float32() -> None:
    vector = np.array([1.5, -3.25, 1e-7], dtype=np.float32)
    command = Command.step(9, 4, vector)
    assert command.action is None and command.command == tuple(vector.tolist())
    decoded = decode_command(encode_command(command), 0, 3)  # a unit with no discrete commands
    assert decoded == command
    assert np.array_equal(np.array(decoded.command, dtype=np.float32), vector)
    # a unit with discrete commands takes a vector too (the continuous task on the same bridge)
    assert decode_command(encode_command(Command.step(9, 5, np.array([2.5]))), 3, 1).command == (2.5,)


@pytest.mark.parametrize(
    ("action", "expected"),
    [
        (2, Command(1, 1, "step", action=2)),
        (np.int64(1), Command(1, 1, "step", action=1)),
        (np.array([0.5], np.float32), Command(1, 1, "step", command=(0.5,))),
        (np.array([0.1, 2.0]), Command(1, 1, "step", command=(float(np.float32(0.1)), 2.0))),  # as float32
        ([1.25], Command(1, 1, "step", command=(1.25,))),
        (-0.5, Command(1, 1, "step", command=(-0.5,))),
    ],
)
def test_a_step_carries_an_index_or_a_float32_vector(action: object, expected: Command) -> None:
    assert Command.step(1, 1, action) == expected


@pytest.mark.parametrize("action", [True, np.array([1, 2]), [1, 2], "1.0", np.zeros((1, 1)), None])
def test_a_step_of_another_type_is_refused_before_it_is_sent(action: object) -> None:
    with pytest.raises(ValueError, match=r"an action index \(int\) or a 1-D vector of floats"):
        Command.step(1, 1, action)


def test_the_largest_messages_fit_the_payload_cap() -> None:
    full = np.full(MAX_VECTOR, -1.5e38, dtype=np.float32)
    state = State(MAX_SID, MAX_SEQ, -1.5e300, full, flags=255, error="\U0001f6d1" * MAX_ERROR)
    assert len(encode_state(state)) <= MAX_PAYLOAD
    assert decode_state(encode_state(state)).error == state.error
    command = Command.step(MAX_SID, MAX_SEQ, full)
    assert len(encode_command(command)) <= MAX_PAYLOAD
    assert decode_command(encode_command(command), 0, MAX_VECTOR) == command
    assert len(decode_state(encode_state(State(1, 1, 0.0, full))).obs) == MAX_VECTOR


def test_state_round_trip_is_exact() -> None:
    obs = np.array([0.1, -2.5, 1e-7, 3.0], dtype=np.float32)
    state = decode_state(encode_state(State(5, 9, 0.012, obs, flags=1)))
    assert (state.sid, state.seq, state.time, state.flags, state.error) == (5, 9, 0.012, 1, None)
    assert state.obs.dtype == np.float32 and np.array_equal(state.obs, obs)
    refusal = decode_state(encode_state(State(5, 10, 0.0, np.zeros(0, np.float32), error="no")))
    assert refusal.error == "no" and refusal.obs.size == 0


def _cmd(**fields: object) -> bytes:
    body: dict[str, object] = {"v": 2, "sid": 1, "seq": 1, "op": "step", "a": 0}
    body.update(fields)
    return bytes(msgpack.packb({k: v for k, v in body.items() if v is not ...}))


@pytest.mark.parametrize(
    ("payload", "reason"),
    [
        (b"\xc1garbage", "not msgpack"),
        (msgpack.packb([1, 2]), "expected a map"),
        (_cmd(v=1), "unsupported version"),
        (_cmd(v=True), "unsupported version"),
        (_cmd(op="fire"), "unknown op"),
        (_cmd(a=3), "out of range"),
        (_cmd(a=-1), "out of range"),
        (_cmd(a=1.0), "neither an action index"),
        (_cmd(a=True), "neither an action index"),
        (_cmd(a=...), "missing"),
        (_cmd(extra=1), "unexpected"),
        (_cmd(seq=-1), "seq"),
        (_cmd(seq="1"), "seq"),
        (_cmd(sid=2**32), "sid"),
        (_cmd(op="reset", a=..., seed=-5), "seed"),
        (b"\x00" * (MAX_PAYLOAD + 1), "exceeds"),
    ],
)
def test_bad_commands_are_refused_with_a_reason(payload: bytes, reason: str) -> None:
    with pytest.raises(WireError, match=reason):
        decode_command(payload, 3, 1)


F32 = np.array([0.5], dtype="<f4").tobytes()
NAN = np.array([np.nan], dtype="<f4").tobytes()
INF = np.array([np.inf], dtype="<f4").tobytes()


@pytest.mark.parametrize(
    ("payload", "n_actions", "size", "reason"),
    [
        (_cmd(a=F32 * 2), 0, 1, "command vector of 8 bytes: this unit takes 1 little-endian float32 values"),
        (_cmd(a=F32), 0, 2, "command vector of 4 bytes: this unit takes 2 little-endian float32"),
        (_cmd(a=b""), 3, 1, "command vector of 0 bytes"),
        (_cmd(a=NAN), 3, 1, "not finite"),
        (_cmd(a=F32 + INF), 0, 2, "not finite"),
        (_cmd(a=np.array([0.5]).tobytes()), 0, 1, "8 bytes: this unit takes 1 little-endian float32"),  # f8
        (_cmd(a=[0.5]), 0, 1, "neither an action index .* nor a command vector of 1 float32 values as bytes"),
        (_cmd(a=0), 0, 1, "this unit takes no action index, got 0 .send a command vector of 1 float32"),
        (_cmd(a=F32 * (MAX_PAYLOAD // 4)), 0, 1, "exceeds"),
    ],
)
def test_bad_command_vectors_are_refused_with_a_reason(
    payload: bytes, n_actions: int, size: int, reason: str
) -> None:
    with pytest.raises(WireError, match=reason) as info:
        decode_command(payload, n_actions, size)
    if "exceeds" not in reason:
        assert (info.value.sid, info.value.seq) == (1, 1)  # answerable


def test_a_refusal_keeps_a_valid_header_so_it_can_be_answered() -> None:
    with pytest.raises(WireError) as info:
        decode_command(_cmd(sid=4, seq=8, a=9), 3, 1)
    assert (info.value.sid, info.value.seq) == (4, 8)


@pytest.mark.parametrize(
    "obs",
    # NaN, ragged, one value past the cap, list, empty
    [b"\x00\x00\xc0\x7f" * 4, b"\x00" * 5, b"\x00" * 4 * (MAX_VECTOR + 1), [1.0, 2.0], b""],
)
def test_bad_states_are_refused(obs: object) -> None:
    payload = msgpack.packb({"v": 2, "sid": 1, "seq": 1, "t": 0.0, "obs": obs, "flags": 0})
    with pytest.raises(WireError):
        decode_state(payload)


def decodes_or_refuses(payload: bytes) -> None:
    """Both decoders either decode ``payload`` or raise WireError; anything else fails the test."""
    with contextlib.suppress(WireError):
        decode_command(payload, 3, 1)
    with contextlib.suppress(WireError):
        decode_command(payload, 0, 2)
    with contextlib.suppress(WireError):
        decode_state(payload)


@settings(max_examples=300, deadline=None)
@given(st.binary(max_size=80))
def test_random_bytes_never_raise_anything_but_wire_error(payload: bytes) -> None:
    decodes_or_refuses(payload)


@settings(max_examples=200, deadline=None)
@given(
    st.dictionaries(
        st.sampled_from(["v", "sid", "seq", "op", "a", "seed", "t", "obs", "flags", "err"]),
        st.one_of(
            st.none(),
            st.booleans(),
            st.integers(-(2**63), 2**64 - 1),
            st.floats(),
            st.text(max_size=5),
            st.binary(),
        ),
    )
)
def test_random_maps_never_raise_anything_but_wire_error(body: dict[str, object]) -> None:
    decodes_or_refuses(msgpack.packb(body))
