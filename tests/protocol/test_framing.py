"""The TCP stream framer: any chunking in, whole frames out, bounded."""

from __future__ import annotations

import pytest
from hypothesis import given
from hypothesis import strategies as st

from protocol.errors import ProtocolError
from protocol.framing import FrameDecoder, split_frames

from .util import feed_bytewise

# Frames as the seeds describe them: u16 size counting the id byte, then the id.
GAME_DATA = bytes.fromhex("0005 0e") + b"WCBC"  # ds_to_rio.rst "Game Data"
KEEPALIVE = b"\x00\x00"  # size 0: no id (seed: "ID only if Size > 0")
STDOUT = bytes.fromhex("000a 0c 3f800000 0001") + b"hi!"  # rio_to_ds.rst "Standard Output"


def test_frames_in_any_chunking():
    stream = GAME_DATA + KEEPALIVE + STDOUT
    assert FrameDecoder().feed(stream) == [GAME_DATA, KEEPALIVE, STDOUT]
    assert feed_bytewise(FrameDecoder(), stream) == [GAME_DATA, KEEPALIVE, STDOUT]
    d = FrameDecoder()
    assert d.feed(stream[:5]) == []
    assert d.buffered == 5
    assert d.feed(stream[5:]) == [GAME_DATA, KEEPALIVE, STDOUT]
    assert d.buffered == 0


def test_oversized_frame_is_refused_and_stays_refused():
    d = FrameDecoder("RioToDsStream", max_frame=64)
    assert d.feed(GAME_DATA) == [GAME_DATA]
    with pytest.raises(ProtocolError) as info:
        d.feed(b"\x01\x00")
    assert (info.value.message, info.value.field, info.value.offset) == ("RioToDsStream", "size", 7)
    with pytest.raises(ProtocolError):
        d.feed(GAME_DATA)


def test_split_frames_refuses_a_cut_frame():
    with pytest.raises(ProtocolError) as info:
        split_frames(GAME_DATA + GAME_DATA[:3])
    assert info.value.offset == len(GAME_DATA)


@given(st.lists(st.binary(max_size=300), max_size=10), st.lists(st.integers(1, 50), min_size=1))
def test_any_chunking_gives_the_same_frames(payloads, cuts):
    frames = [(len(p).to_bytes(2, "big") + p) for p in payloads]
    stream = b"".join(frames)
    d = FrameDecoder()
    out, pos, i = [], 0, 0
    while pos < len(stream):
        step = cuts[i % len(cuts)]
        out.extend(d.feed(stream[pos:pos + step]))
        pos += step
        i += 1
    assert out == frames
    assert d.buffered == 0


@given(st.binary(max_size=400), st.integers(2, 600))
def test_random_bytes_one_at_a_time(data, bound):
    d = FrameDecoder(max_frame=bound)
    frames = []
    try:
        for i in range(len(data)):
            frames.extend(d.feed(data[i:i + 1]))
            assert d.buffered < max(bound, 2)
    except ProtocolError as exc:
        assert exc.field == "size"
        return
    assert b"".join(frames) + data[len(data) - d.buffered:] == data
    assert all(len(f) <= bound for f in frames)


def test_frames_before_a_bad_header_come_first():
    # Found by hypothesis on the FMS's fresh connection: two empty frames, then a size of
    # 0x4000 (over the bound). The frames that arrived before it are handed over with the
    # error, so a core judges them first (the FMS: "not a team number") and then closes.
    decoder = FrameDecoder("t", max_frame=16384)  # the FMS's bound (roles/cores/fms.py)
    frames, error = decoder.feed_until_error(b"\x00\x00\x00\x00\x40\x00")
    assert frames == [b"\x00\x00", b"\x00\x00"]
    assert error is not None and error.field == "size" and error.offset == 4
    assert decoder.feed_until_error(b"\x00\x01x") == ([], error)  # unusable from now on
    with pytest.raises(ProtocolError):
        decoder.feed(b"")


def test_a_size_over_the_bound_is_refused_before_the_body_is_buffered():
    # Issue 27: a peer announcing a frame over the bound must cost nothing more: the chunk
    # that carries the header is not kept, whatever follows it in that chunk.
    d = FrameDecoder("t", max_frame=64)
    frames, error = d.feed_until_error(GAME_DATA + b"\x10\x00" + bytes(60_000))
    assert frames == [GAME_DATA] and error is not None and error.offset == len(GAME_DATA)
    assert d.buffered == 0
    # the same with the header split across chunks: refused once its second byte is in
    d = FrameDecoder("t", max_frame=64)
    assert d.feed(b"\x10") == [] and d.buffered == 1
    frames, error = d.feed_until_error(b"\x00" + bytes(60_000))
    assert frames == [] and error is not None and error.offset == 0 and d.buffered == 2


def test_a_frame_dripped_a_byte_at_a_time_is_held_once():
    frame = (60_000).to_bytes(2, "big") + bytes(range(256)) * 234 + bytes(96)
    d = FrameDecoder()
    out = []
    for i in range(len(frame)):
        out += d.feed(frame[i:i + 1])
        assert d.buffered == (i + 1) % len(frame)
    assert out == [frame]
