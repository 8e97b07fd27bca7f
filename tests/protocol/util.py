"""Checks shared by the protocol tests."""

from __future__ import annotations

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
