"""Size and tag-count bounds: what no real peer sends is refused before it is walked.

Issue 27: 65 KB datagrams of zeros took the fake roboRIO 210 ms each to decode (32,000
one-byte tags), long enough to freeze a whole field. Every packet kind now has a named size
bound next to its message (a real peer's largest, by the layout and the 2021 capture, with
room to spare), and a packet holds at most ``MAX_TAGS`` tags. These tests hold the promise
without timing anything (the figures are ``python benchmarks/codec.py``'s): over the bound
is a ProtocolError naming the message, ``size`` and the first byte over, and an annotation
still explains the header and covers every byte.
"""

from __future__ import annotations

import pytest
from hypothesis import given
from hypothesis import strategies as st

from protocol import ds_to_fms, ds_to_rio, fms_to_ds, kinds, legacy, rio_to_ds
from protocol.errors import ProtocolError
from protocol.frames import MAX_TAGS
from protocol.kinds import coverage_gaps
from protocol.wire import NOT_DECODED, UnknownTag

from .util import framed, outcome, protocol_error, where

BIGGEST_DATAGRAM = 65507  # the largest UDP payload over IPv4: what a flood sends

#: kind -> (its size bound, the bytes its header takes)
UDP_BOUNDS = {
    "ds-to-rio": (ds_to_rio.MAX_CONTROL_SIZE, 6),
    "rio-to-ds": (rio_to_ds.MAX_STATUS_SIZE, 8),
    "fms-to-ds": (fms_to_ds.MAX_CONTROL_SIZE, 22),
    "ds-to-fms": (ds_to_fms.MAX_STATUS_SIZE, 8),
}
TCP_BOUNDS = {
    "ds-to-rio-tcp": ds_to_rio.MAX_TCP_FRAME,
    "rio-to-ds-tcp": rio_to_ds.MAX_TCP_FRAME,
    "fms-to-ds-tcp": fms_to_ds.MAX_TCP_FRAME,
    "ds-to-fms-tcp": ds_to_fms.MAX_TCP_FRAME,
}


def floods() -> list[tuple[str, bytes]]:
    """What a flood may carry, each 65,507 bytes: zeros, 0xff, and runs of short tags."""
    out = [("zeros", bytes(BIGGEST_DATAGRAM)), ("ff", b"\xff" * BIGGEST_DATAGRAM)]
    for unit in ("01 07", "01 0c", "01 01", "01 00", "00", "02 0c 00", "05 08 00 00 00 00"):
        raw = bytes.fromhex(unit)
        out.append((unit, (raw * (BIGGEST_DATAGRAM // len(raw) + 1))[:BIGGEST_DATAGRAM]))
        out.append((f"header+{unit}", (bytes(22) + raw * (BIGGEST_DATAGRAM // len(raw) + 1))[:BIGGEST_DATAGRAM]))
    return out


# -- every decoder, on what a flood carries ----------------------------------------------------
@pytest.mark.parametrize("kind", list(kinds.kinds()))
@pytest.mark.parametrize("name,data", floods(), ids=[name for name, _ in floods()])
def test_every_decoder_on_a_maximum_size_datagram_refuses_it_or_decodes_it(kind, name, data):
    k = kinds.get(kind)
    try:
        k.decode(data)
    except ProtocolError as exc:
        assert exc.message and exc.field
        assert exc.offset is None or 0 <= exc.offset <= len(data)
    spans, error = k.annotate_lenient(data)
    assert not coverage_gaps(spans, len(data))  # every byte explained, even of a refused packet


@pytest.mark.parametrize("kind", list(UDP_BOUNDS))
@pytest.mark.parametrize("fill", [0x00, 0xFF, 0x01])
def test_a_udp_packet_over_its_bound_is_refused_at_the_first_byte_over(kind, fill):
    bound, header = UDP_BOUNDS[kind]
    k = kinds.get(kind)
    data = bytes([fill]) * BIGGEST_DATAGRAM
    exc = protocol_error(k.decode, data)
    assert where(exc) == (k.message, "size", bound)
    assert f"{BIGGEST_DATAGRAM} bytes is over the {bound}-byte bound" in exc.reason
    # One byte over is enough; at the bound it is walked (and may be bad for other reasons).
    assert where(protocol_error(k.decode, bytes(bound + 1))) == (k.message, "size", bound)
    try:
        k.decode(bytes(bound))
    except ProtocolError as exc2:
        assert exc2.field != "size" or exc2.offset != bound


@pytest.mark.parametrize("kind", list(UDP_BOUNDS))
def test_the_inspector_explains_the_header_of_an_oversize_packet_and_marks_the_rest(kind):
    bound, header = UDP_BOUNDS[kind]
    k = kinds.get(kind)
    data = bytes(header) + bytes(BIGGEST_DATAGRAM - header)
    if kind == "ds-to-rio":  # a header that decodes (station 0 is red 1): only the size is wrong
        data = bytes.fromhex("0001 01 04 10 00") + data[6:]
    spans, error = k.annotate_lenient(data)
    assert error is not None and where(error) == (k.message, "size", bound)
    assert not coverage_gaps(spans, len(data))
    rest = spans[-1]
    assert (rest.offset, rest.length) == (header, len(data) - header)
    assert rest.field == NOT_DECODED and f"over the {bound}-byte bound" in rest.meaning
    assert all(s.offset < header for s in spans[:-1])  # the header, field by field
    with pytest.raises(ProtocolError):  # the strict annotation refuses it, as decode does
        k.annotate(data)


@pytest.mark.parametrize("kind", list(TCP_BOUNDS))
def test_a_tcp_frame_over_its_bound_is_refused_before_its_payload_is_walked(kind):
    bound = TCP_BOUNDS[kind]
    k = kinds.get(kind)
    frame = framed(0x0C, bytes(min(0xFFFE, bound + 100)))
    assert where(protocol_error(k.decode, frame)) == (k.message, "size", bound)
    spans, error = k.annotate_lenient(frame)
    assert error is not None and not coverage_gaps(spans, len(frame))
    assert [s.field for s in spans][-1] == NOT_DECODED and spans[-1].offset == 3  # after size and id


def test_the_2010_packets_have_exact_sizes_and_refuse_anything_longer_at_once():
    for kind, size in (("legacy-ds-to-robot", legacy.CONTROL_SIZE), ("legacy-robot-to-ds", legacy.STATUS_LCD_SIZE),
                       ("legacy-dashboard", legacy.DASHBOARD_SIZE)):
        k = kinds.get(kind)
        data = bytes(BIGGEST_DATAGRAM)
        exc = protocol_error(k.decode, data)
        assert exc.field == "size"
        spans, error = k.annotate_lenient(data)
        assert error is not None and not coverage_gaps(spans, len(data))
        assert spans[-1].field == NOT_DECODED and spans[-1].offset < 8 and f"{size}" in spans[-1].meaning


# -- the tag-count bound -----------------------------------------------------------------------
def _control_with(tags: int) -> bytes:
    return bytes.fromhex("0001 01 04 10 00") + bytes.fromhex("01 0c") * tags


def test_a_control_packet_holds_up_to_max_tags_and_no_more():
    assert len(ds_to_rio.decode_control(_control_with(MAX_TAGS)).joysticks) == MAX_TAGS
    exc = protocol_error(ds_to_rio.decode_control, _control_with(MAX_TAGS + 1))
    assert where(exc) == ("ControlPacket", f"tags[{MAX_TAGS}]", 6 + 2 * MAX_TAGS)
    # the fast path and the reference walk agree on both sides of the bound
    for n in (MAX_TAGS, MAX_TAGS + 1):
        raw = _control_with(n)
        walk = outcome(lambda b: ds_to_rio.walk_control(ds_to_rio.Reader(b, "ControlPacket")), raw)
        assert outcome(ds_to_rio.decode_control, raw) == walk


def test_malformed_tags_count_towards_the_bound():
    # 33 zero-size tags: each alone would be a malformed tag the robot drops, header applied
    data = bytes.fromhex("0001 01 04 10 00") + bytes(MAX_TAGS + 1)
    assert where(protocol_error(ds_to_rio.decode_control, data))[1] == f"tags[{MAX_TAGS}]"
    assert len(ds_to_rio.decode_control(data[:-1]).malformed_tags) == MAX_TAGS


def test_status_packets_hold_up_to_max_tags_and_no_more():
    head = bytes.fromhex("0001 01 00 30 0c00 00")
    assert len(rio_to_ds.decode_status(head + bytes.fromhex("01 01") * MAX_TAGS).tags) == MAX_TAGS
    assert where(protocol_error(rio_to_ds.decode_status, head + bytes.fromhex("01 01") * (MAX_TAGS + 1)))[1] \
        == f"tags[{MAX_TAGS}]"
    fms_head = fms_to_ds.FmsControlPacket().encode()
    assert where(protocol_error(fms_to_ds.decode_control, fms_head + bytes.fromhex("01 20") * (MAX_TAGS + 1)))[1] \
        == f"tags[{MAX_TAGS}]"
    ds_head = ds_to_fms.DsStatusPacket(team=254).encode()
    assert where(protocol_error(ds_to_fms.decode_status, ds_head + bytes(MAX_TAGS + 1)))[1] == f"tags[{MAX_TAGS}]"


def test_nothing_encodes_what_its_peer_would_refuse():
    tags = tuple(UnknownTag(0x42, bytes(200)) for _ in range(6))  # 1,212 bytes
    assert where(protocol_error(ds_to_rio.ControlPacket(tags=tags).encode)) == ("ControlPacket", "size", None)
    assert where(protocol_error(rio_to_ds.StatusPacket(tags=tags).encode)) == ("StatusPacket", "size", None)
    assert where(protocol_error(fms_to_ds.FmsControlPacket(tags=tags).encode)) == ("FmsControlPacket", "size", None)
    assert where(protocol_error(ds_to_fms.DsStatusPacket(tags=tags).encode)) == ("DsStatusPacket", "size", None)
    many = tuple(UnknownTag(0x42) for _ in range(MAX_TAGS + 1))
    assert where(protocol_error(ds_to_rio.ControlPacket(tags=many).encode)) == ("ControlPacket", "tags", None)
    assert len(ds_to_rio.ControlPacket(tags=many[:MAX_TAGS]).encode()) == 6 + 2 * MAX_TAGS


# -- fuzz: any bytes near and past the bounds --------------------------------------------------
@given(st.sampled_from(sorted(UDP_BOUNDS)), st.integers(-40, 200), st.binary(min_size=1, max_size=4))
def test_bytes_around_the_bound_decode_or_raise_only_protocol_error(kind, past, unit):
    bound, _ = UDP_BOUNDS[kind]
    n = bound + past
    data = (unit * (n // len(unit) + 1))[:n]
    k = kinds.get(kind)
    try:
        k.decode(data)
        assert len(data) <= bound
    except ProtocolError as exc:
        assert len(data) <= bound or where(exc) == (k.message, "size", bound)
    spans, _ = k.annotate_lenient(data)
    assert not coverage_gaps(spans, len(data))
