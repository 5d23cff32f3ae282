"""Device wire messages: round trips, and every malformed or out-of-range message is a WireError."""

from __future__ import annotations

import contextlib

import msgpack
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from fleetrl.link.wire import (
    MAX_PAYLOAD,
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
        assert decode_command(encode_command(command), 3) == command
    assert decode_command(encode_command(Command(1, 2, "reset")), 3).seed is None
    assert len(encode_command(Command(123456, 99, "step", action=1))) < 40


def test_state_round_trip_is_exact() -> None:
    obs = np.array([0.1, -2.5, 1e-7, 3.0], dtype=np.float32)
    state = decode_state(encode_state(State(5, 9, 0.012, obs, flags=1)))
    assert (state.sid, state.seq, state.time, state.flags, state.error) == (5, 9, 0.012, 1, None)
    assert state.obs.dtype == np.float32 and np.array_equal(state.obs, obs)
    refusal = decode_state(encode_state(State(5, 10, 0.0, np.zeros(0, np.float32), error="no")))
    assert refusal.error == "no" and refusal.obs.size == 0


def _cmd(**fields: object) -> bytes:
    body: dict[str, object] = {"v": 1, "sid": 1, "seq": 1, "op": "step", "a": 0}
    body.update(fields)
    return bytes(msgpack.packb({k: v for k, v in body.items() if v is not ...}))


@pytest.mark.parametrize(
    ("payload", "reason"),
    [
        (b"\xc1garbage", "not msgpack"),
        (msgpack.packb([1, 2]), "expected a map"),
        (_cmd(v=2), "unsupported version"),
        (_cmd(v=True), "unsupported version"),
        (_cmd(op="fire"), "unknown op"),
        (_cmd(a=3), "out of range"),
        (_cmd(a=-1), "out of range"),
        (_cmd(a=1.0), "out of range"),
        (_cmd(a=True), "out of range"),
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
        decode_command(payload, 3)


def test_a_refusal_keeps_a_valid_header_so_it_can_be_answered() -> None:
    with pytest.raises(WireError) as info:
        decode_command(_cmd(sid=4, seq=8, a=9), 3)
    assert (info.value.sid, info.value.seq) == (4, 8)


@pytest.mark.parametrize(
    "obs",
    [b"\x00\x00\xc0\x7f" * 4, b"\x00" * 5, b"\x00" * 68, [1.0, 2.0], b""],  # NaN, ragged, long, list
)
def test_bad_states_are_refused(obs: object) -> None:
    payload = msgpack.packb({"v": 1, "sid": 1, "seq": 1, "t": 0.0, "obs": obs, "flags": 0})
    with pytest.raises(WireError):
        decode_state(payload)


def decodes_or_refuses(payload: bytes) -> None:
    """Both decoders either decode ``payload`` or raise WireError; anything else fails the test."""
    with contextlib.suppress(WireError):
        decode_command(payload, 3)
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
