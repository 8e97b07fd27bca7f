"""Checks shared by the protocol tests."""

from __future__ import annotations

import pytest
from hypothesis import strategies as st

from protocol.errors import ProtocolError
from protocol.kinds import coverage_gaps, get


def assert_tiles(spans, data: bytes) -> None:
    """Spans cover every byte exactly once, and each span is well formed."""
    assert not coverage_gaps(spans, len(data)), coverage_gaps(spans, len(data))
    for s in spans:
        assert s.length > 0, s
        assert s.field, s
        assert isinstance(s.meaning, str), s


def decode_or_protocol_error(kind: str, data: bytes):
    """The fuzz invariant: a message (whose annotation tiles the bytes) or a ProtocolError."""
    k = get(kind)
    try:
        message = k.decode(data)
    except ProtocolError as exc:
        assert exc.field and exc.message, exc
        assert exc.offset is None or 0 <= exc.offset <= len(data), exc
        return None
    assert_tiles(k.annotate(data), data)
    return message


def feed_bytewise(decoder, data: bytes) -> list[bytes]:
    frames = []
    for i in range(len(data)):
        frames.extend(decoder.feed(data[i:i + 1]))
    return frames


# -- errors -------------------------------------------------------------------------------
def protocol_error(fn, *args, **kwargs) -> ProtocolError:
    """The ProtocolError ``fn(*args, **kwargs)`` must raise."""
    with pytest.raises(ProtocolError) as info:
        fn(*args, **kwargs)
    return info.value


def where(exc: ProtocolError) -> tuple[str, str, int | None]:
    """``(message, field, offset)``: what a test of a bad packet or value pins down."""
    return exc.message, exc.field, exc.offset


def outcome(fn, raw: bytes) -> str:
    """``repr`` of what ``fn(raw)`` gives, or the text of its ProtocolError: compares a fast
    path with its reference walk (repr, so NaN floats from random bytes compare equal)."""
    try:
        return repr(fn(raw))
    except ProtocolError as exc:
        return str(exc)


# -- round trips --------------------------------------------------------------------------
def assert_round_trip(message, decode, annotate) -> bytes:
    """``message`` encodes to bytes that decode back to it, re-encode identically and whose
    annotation tiles them; returns the bytes."""
    data = message.encode()
    back = decode(data)
    assert back == message
    assert back.encode() == data
    assert_tiles(annotate(data), data)
    return data


# -- TCP frames and mutations ---------------------------------------------------------------
def framed(tag_id: int, payload: bytes) -> bytes:
    """A TCP frame whose u16 size is right: ``[size][id][payload]``."""
    return (len(payload) + 1).to_bytes(2, "big") + bytes((tag_id,)) + payload


def with_size_repaired(raw) -> bytes:
    """``raw`` with its u16 size field set to what follows, so the payload decoder sees it."""
    return (len(raw) - 2).to_bytes(2, "big") + bytes(raw[2:])


def mutate(data: bytes, draw) -> bytes:
    """One hypothesis-drawn damage to ``data``: flip a bit, set a byte, truncate or extend."""
    raw = bytearray(data)
    choice = draw(st.sampled_from(["flip", "truncate", "extend", "set"]))
    if choice == "flip" and raw:
        raw[draw(st.integers(0, len(raw) - 1))] ^= 1 << draw(st.integers(0, 7))
    elif choice == "set" and raw:
        raw[draw(st.integers(0, len(raw) - 1))] = draw(st.integers(0, 0xFF))
    elif choice == "truncate":
        raw = raw[: draw(st.integers(0, len(raw)))]
    else:
        raw += draw(st.binary(min_size=1, max_size=20))
    return bytes(raw)


def check_mutated_frame(kind: str, frame, draw) -> None:
    """Damage an encoded frame, sometimes repairing its size so the payload decoder sees the
    damage, and hold the fuzz invariant."""
    raw = mutate(frame.encode(), draw)
    if draw(st.booleans()) and len(raw) >= 2:
        raw = with_size_repaired(raw)
    decode_or_protocol_error(kind, raw)
