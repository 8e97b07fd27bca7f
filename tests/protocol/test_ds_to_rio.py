"""DS -> roboRIO: the UDP control packet and the TCP 1740 frames."""

from __future__ import annotations

import datetime as dt

import pytest
from hypothesis import given
from hypothesis import strategies as st

from protocol import kinds
from protocol.ds_to_rio import (
    BARE_EMPTY_JOYSTICK, EMPTY_JOYSTICK, ControlPacket, Countdown, Date, GameData, Joystick, JoystickDescriptor,
    KeepAlive, MalformedTag, MatchInfo, Timezone, UnknownFrame, annotate_control, annotate_tcp, axis_to_int8,
    decode_control, decode_tcp, int8_to_axis, walk_control,
)
from protocol.enums import AllianceStation, AxisType, JoystickType, MatchType, Mode
from protocol.wire import Reader, UnknownTag

from .util import (assert_round_trip, assert_tiles, decode_or_protocol_error, framed, outcome, protocol_error,
                   where)

# -- golden vectors -------------------------------------------------------------------

# Header per the seed table (ds_to_rio.rst "UDP"): sequence 0x0001, comm version 0x01,
# control 0x04 (enabled, teleop), request 0x10 (PROTOCOL-NOTES: "Send 0x10 in normal
# operation"), station 0 (red 1).
HEADER_ENABLED_TELEOP = bytes.fromhex("0001 01 04 10 00")

# allwpilib simulation/halsim_ds_socket/src/test/native/cpp/DSCommPacketTest.cpp,
# MainJoystickTag: 4 axes (0x9c, 0xce, 0, 75), 12 buttons
# {0,1,0,0,1,1,0,1,0,1,0,1} (buttons 1-8 in the LAST byte = 0xb2, 9-12 in the first =
# 0x0a), 3 POVs (0x0032, 0x0064, 0x0f00).
WPILIB_JOYSTICK_TAG = bytes.fromhex("10 0c 04 9c ce 00 4b 0c 0a b2 03 0032 0064 0f00")

# An empty slot: seed joystick table with every count 0; the same 5 bytes as the
# BlankJoystickTag test of the file above ({4, tag, 0, 0, 0}).
EMPTY_JOYSTICK_TAG = bytes.fromhex("04 0c 00 00 00")

# PROTOCOL-NOTES "Corrections": WPILib's robot side accepts the 2-byte tag 01 0c as an empty
# slot (DSCommPacket.cpp ReadJoystickTag returns early on a 2-byte tag).
BARE_EMPTY_JOYSTICK_TAG = bytes.fromhex("01 0c")

# LibDS (QDriverStation's engine), src/protocols/frc_2015.c: header with request 0x80 (its
# "normal"), then one joystick (4 axes at 0, 12 buttons with button 1 down in two bytes, one
# hat centred) whose size byte get_joystick_size() makes 2 + 3 + (4 + 1) + (2 + 1) = 13, one
# more than the 12 bytes that follow (PROTOCOL-NOTES "Corrections": payload + 2).
LIBDS_2015_ENABLED = bytes.fromhex("0010 01 04 80 00" "0d 0c 04 00000000 0c 0001 01 ffff")

# allwpilib DSCommPacketTest.cpp, DescriptorTag (joystick 0, xbox, type 0, "Hello World",
# axis types 1-4, 12 buttons, 3 POVs), framed with the seed's TCP id 0x02.
WPILIB_DESCRIPTOR_FRAME = bytes.fromhex("0017 02 00 01 00 0b") + b"Hello World" + bytes.fromhex("04 01020304 0c 03")

# allwpilib DSCommPacketTest.cpp, MatchInfoTag ("WCBC", qualification, match 18, replay 1),
# framed with the seed's TCP id 0x07.
WPILIB_MATCH_INFO_FRAME = bytes.fromhex("000a 07 04") + b"WCBC" + bytes.fromhex("02 0012 01")

# allwpilib DSCommPacketTest.cpp, GameDataTag ("WCBC": length is the frame size - 1),
# framed with the seed's TCP id 0x0e.
WPILIB_GAME_DATA_FRAME = bytes.fromhex("0005 0e") + b"WCBC"


def test_header_only_packet():
    p = decode_control(HEADER_ENABLED_TELEOP)
    assert p == ControlPacket(sequence=1, enabled=True, mode=Mode.TELEOP, station=AllianceStation.RED1)
    assert p.encode() == HEADER_ENABLED_TELEOP


def test_wpilib_joystick_tag():
    p = decode_control(HEADER_ENABLED_TELEOP + WPILIB_JOYSTICK_TAG)
    (joy,) = p.tags
    assert joy.axes == (-100, -50, 0, 75)
    assert joy.button_count == 12
    assert [b for b in range(1, 13) if joy.pressed(b)] == [2, 5, 6, 8, 10, 12]
    assert joy.povs == (50, 100, 0x0F00)
    assert p.encode() == HEADER_ENABLED_TELEOP + WPILIB_JOYSTICK_TAG


def test_button_one_lives_in_the_last_byte():
    # PROTOCOL-NOTES: buttons read as one big-endian integer, bit 0 = button 1.
    tag = Joystick((), 0b1, 9, ())
    data = ControlPacket(tags=(tag,)).encode()
    assert data[6:] == bytes.fromhex("06 0c 00 09 00 01 00")


def test_empty_slots_keep_their_numbers():
    joys = (Joystick(), Joystick((5,), 0, 0, ()), Joystick())
    data = ControlPacket(tags=joys).encode()
    assert data[6:] == EMPTY_JOYSTICK_TAG + bytes.fromhex("05 0c 01 05 00 00") + EMPTY_JOYSTICK_TAG
    assert decode_control(data).joysticks == joys


def test_every_control_bit():
    # Seed "Control" table: e-stop 0x80, FMS 0x08, enabled 0x04, mode 0..2; "Request": reboot
    # 0x08, restart code 0x04. Station byte 5 is blue 3.
    p = ControlPacket(sequence=0xABCD, estop=True, fms_attached=True, enabled=True,
                      mode=Mode.AUTONOMOUS, reboot_roborio=True, restart_code=True,
                      station=AllianceStation.BLUE3)
    assert p.encode() == bytes.fromhex("abcd 01 8e 1c 05")
    assert decode_control(p.encode()) == p
    assert decode_control(bytes.fromhex("0000 01 01 00 03")).mode is Mode.TEST


def test_countdown_date_timezone_tags():
    when = dt.datetime(2026, 3, 14, 15, 9, 26, 535897, tzinfo=dt.timezone.utc)
    p = ControlPacket(tags=(Countdown(15.0), Date.from_datetime(when), Timezone("UTC")))
    data = p.encode()
    # Countdown: f32 15.0 = 41 70 00 00. Date: u32 microseconds, s, m, h, day, month
    # (0-based: March = 2), year - 1900 = 126 (seed "Date" table).
    assert data[6:] == bytes.fromhex("05 07 41700000" "0b 0f 00082d59 1a 09 0f 0e 02 7e" "04 10") + b"UTC"
    back = decode_control(data)
    assert back == p
    assert back.tags[1].to_datetime() == when


def test_unknown_tag_is_kept_raw():
    data = HEADER_ENABLED_TELEOP + bytes.fromhex("03 42 beef")
    p = decode_control(data)
    assert p.tags == (UnknownTag(0x42, b"\xbe\xef"),)
    assert p.encode() == data


@pytest.mark.parametrize("hexdata,field,offset", [
    ("", "sequence", 0),
    ("0001 01 04", "request", 4),
    ("0001 01 04 10", "station", 5),
    ("0001 01 04 10 06", "station", 5),
])
def test_bad_headers_name_field_and_offset(hexdata, field, offset):
    assert where(protocol_error(decode_control, bytes.fromhex(hexdata))) == ("ControlPacket", field, offset)


@pytest.mark.parametrize("tail,tag_id,reason", [
    ("00", None, "tags[0].size at byte 6: a size of 0"),
    ("05 0c 00", 0x0C, "tags[0].size at byte 6: 5 byte(s) said, 2 left"),
    ("04 0c 05 00 00", 0x0C, "tags[0].axes at byte 9: needs 5 bytes, 2 left"),
    ("05 0c 00 00 00 00", 0x0C, "tags[0].end at byte 11: 1 unexpected trailing byte(s)"),
    ("04 07 00 00 00", 0x07, "tags[0].seconds at byte 8: needs 4 bytes, 3 left"),
    ("0a 0f 00000000 01 02 03 04 05", 0x0F, "tags[0].year at byte 17: needs 1 byte, 0 left"),
])
def test_a_malformed_tag_keeps_the_header(tail, tag_id, reason):
    # PROTOCOL-NOTES "Corrections": a robot applies the header before it walks the tags, so
    # a malformed tag costs only its own data: the packet decodes, the tag is kept raw.
    data = HEADER_ENABLED_TELEOP + bytes.fromhex(tail)
    p = decode_control(data)
    assert p.enabled and p.mode is Mode.TELEOP and p.sequence == 1
    (tag,) = p.tags
    assert type(tag) is MalformedTag and tag.tag_id == tag_id and tag.raw == data[6:]
    assert tag.reason.startswith(reason)
    assert p.encode() == data and p.malformed_tags == (tag,)
    spans = annotate_control(data)
    assert_tiles(spans, data)
    assert spans[-1].field == "tags[0].malformed" and spans[-1].meaning.startswith("MALFORMED")


def test_good_tags_around_a_malformed_one_still_count():
    data = HEADER_ENABLED_TELEOP + WPILIB_JOYSTICK_TAG + bytes.fromhex("04 0c 05 00 00") + EMPTY_JOYSTICK_TAG
    p = decode_control(data)
    assert [type(t) for t in p.tags] == [Joystick, MalformedTag, Joystick]
    # the malformed joystick keeps its slot, read as empty: the third tag is still slot 2
    assert p.joysticks == (p.tags[0], EMPTY_JOYSTICK, EMPTY_JOYSTICK)
    assert [s.field for s in annotate_control(data) if s.field.endswith("malformed")] == ["tags[1].malformed"]


def test_libds_joystick_with_a_size_one_too_big():
    # LIBDS_2015_ENABLED: the header (enabled, teleop, R1) applies; the joystick runs past the
    # packet, so its slot reads neutral.
    p = decode_control(LIBDS_2015_ENABLED)
    assert p.enabled and p.mode is Mode.TELEOP and p.station is AllianceStation.RED1
    assert p.joysticks == (EMPTY_JOYSTICK,) and p.tags[0].tag_id == 0x0C
    assert "13 byte(s) said, 12 left" in p.tags[0].reason
    assert p.encode() == LIBDS_2015_ENABLED
    assert kinds.get("ds-to-rio").annotate_lenient(LIBDS_2015_ENABLED)[1] is None


def test_bare_empty_slot():
    # BARE_EMPTY_JOYSTICK_TAG: an empty slot, not a malformed tag; it re-encodes as it came.
    data = HEADER_ENABLED_TELEOP + BARE_EMPTY_JOYSTICK_TAG + WPILIB_JOYSTICK_TAG
    p = decode_control(data)
    assert p.tags[0] == BARE_EMPTY_JOYSTICK and p.tags[0].is_empty and not p.malformed_tags
    assert p.joysticks[0] == BARE_EMPTY_JOYSTICK and p.joysticks[1].button_count == 12
    assert p.encode() == data
    assert walk_control(Reader(data, "ControlPacket")) == p
    spans = annotate_control(data)
    assert_tiles(spans, data)
    assert "empty slot" in spans[6].meaning
    assert protocol_error(ControlPacket(tags=(Joystick((1,), bare=True),)).encode).field == "tags[0].bare"


@pytest.mark.parametrize("packet,field", [
    (ControlPacket(sequence=65536), "sequence"),
    (ControlPacket(sequence=-1), "sequence"),
    (ControlPacket(tags=(Joystick((128,), 0, 0, ()),)), "tags[0].axes[0]"),
    (ControlPacket(tags=(Joystick((-129,), 0, 0, ()),)), "tags[0].axes[0]"),
    (ControlPacket(tags=(Joystick((), 0b100, 2, ()),)), "tags[0].buttons"),
    (ControlPacket(tags=(Joystick((), 0, 33, ()),)), "tags[0].button_count"),
    (ControlPacket(tags=(Joystick((0,) * 13, 0, 0, ()),)), "tags[0].axes"),
    (ControlPacket(tags=(Joystick((), 0, 0, (40000,)),)), "tags[0].povs[0]"),
    (ControlPacket(tags=(Timezone("x" * 255),)), "tags[0].name"),
    (ControlPacket(tags=(Countdown(1e39),)), "tags[0].seconds"),
])
def test_encoding_refuses_out_of_range(packet, field):
    assert where(protocol_error(packet.encode))[1:] == (field, None)


def test_axis_scaling_matches_wpilib():
    # PROTOCOL-NOTES: a peer scales negative values by /128 and positive by /127.
    assert axis_to_int8(-1.0) == -128 and axis_to_int8(1.0) == 127 and axis_to_int8(0.0) == 0
    assert axis_to_int8(5.0) == 127 and axis_to_int8(float("nan")) == 0
    assert int8_to_axis(-128) == -1.0 and int8_to_axis(127) == 1.0
    for raw in range(-128, 128):
        assert axis_to_int8(int8_to_axis(raw)) == raw


def test_annotation_explains_every_byte():
    data = HEADER_ENABLED_TELEOP + WPILIB_JOYSTICK_TAG + EMPTY_JOYSTICK_TAG
    spans = annotate_control(data)
    assert_tiles(spans, data)
    by_field = {s.field: s for s in spans}
    assert "enabled" in by_field["control"].meaning and "teleop" in by_field["control"].meaning
    assert by_field["tags[0].buttons"].meaning.endswith("down: 2, 5, 6, 8, 10, 12")
    assert by_field["tags[1].axis_count"].value == 0


# -- TCP frames -----------------------------------------------------------------------

def test_wpilib_tcp_frames():
    desc = decode_tcp(WPILIB_DESCRIPTOR_FRAME)
    assert desc == JoystickDescriptor(0, True, JoystickType.XINPUT_UNKNOWN, "Hello World",
                                      (AxisType.Y, AxisType.Z, AxisType.TWIST, AxisType.THROTTLE), 12, 3)
    assert desc.encode() == WPILIB_DESCRIPTOR_FRAME
    info = decode_tcp(WPILIB_MATCH_INFO_FRAME)
    assert info == MatchInfo("WCBC", MatchType.QUALIFICATION, 18, 1)
    assert info.encode() == WPILIB_MATCH_INFO_FRAME
    game = decode_tcp(WPILIB_GAME_DATA_FRAME)
    assert game == GameData("WCBC") and game.encode() == WPILIB_GAME_DATA_FRAME
    assert decode_tcp(b"\x00\x00") == KeepAlive() and KeepAlive().encode() == b"\x00\x00"
    assert decode_tcp(bytes.fromhex("0003 55 0102")) == UnknownFrame(0x55, b"\x01\x02")
    for frame in (WPILIB_DESCRIPTOR_FRAME, WPILIB_MATCH_INFO_FRAME, WPILIB_GAME_DATA_FRAME):
        assert_tiles(annotate_tcp(frame), frame)


def test_tcp_frame_size_must_match():
    assert where(protocol_error(decode_tcp, WPILIB_GAME_DATA_FRAME + b"x"))[1:] == ("size", 0)


def test_descriptor_name_too_long_is_refused():
    assert protocol_error(JoystickDescriptor(0, name="n" * 256).encode).field == "name"


# -- properties -----------------------------------------------------------------------

int8 = st.integers(-128, 127)


@st.composite
def joysticks(draw):
    count = draw(st.integers(0, 32))
    return Joystick(tuple(draw(st.lists(int8, max_size=12))), draw(st.integers(0, (1 << count) - 1)),
                    count, tuple(draw(st.lists(st.integers(-1, 359), max_size=12))))


tags = st.one_of(
    joysticks(),
    st.builds(Countdown, st.floats(width=32, allow_nan=False)),
    st.builds(Date, st.integers(0, 2**32 - 1), *[st.integers(0, 255)] * 6),
    # 30 characters (120 bytes at most): eight such tags stay under the 1,024-byte bound
    st.builds(Timezone, st.text(max_size=30)),
    st.builds(UnknownTag, st.integers(0, 255).filter(lambda i: i not in (0x07, 0x0C, 0x0F, 0x10)),
              st.binary(max_size=30)),
    st.just(BARE_EMPTY_JOYSTICK),
)

packets = st.builds(
    ControlPacket, st.integers(0, 0xFFFF), st.integers(0, 255), st.booleans(), st.booleans(),
    st.booleans(), st.sampled_from(Mode), st.booleans(), st.booleans(), st.sampled_from(AllianceStation),
    st.lists(tags, max_size=8).map(tuple), st.sampled_from([0, 0x10, 0x20, 0x70]),
    st.sampled_from([0, 0x10, 0x80, 0xF3]),
)


@given(packets)
def test_round_trip(packet):
    assert_round_trip(packet, decode_control, annotate_control)


@given(st.binary(max_size=120))
def test_random_bytes_give_a_packet_or_protocol_error(data):
    decode_or_protocol_error("ds-to-rio", data)


@given(packets, st.data())
def test_fast_path_agrees_with_reference_walk(packet, data):
    raw = bytearray(packet.encode())
    if raw and data.draw(st.booleans()):
        i = data.draw(st.integers(0, len(raw) - 1))
        raw[i] = data.draw(st.integers(0, 255))
    if data.draw(st.booleans()):
        raw = raw[: data.draw(st.integers(0, len(raw)))]
    raw = bytes(raw)
    assert outcome(decode_control, raw) == outcome(lambda b: walk_control(Reader(b, "ControlPacket")), raw)


descriptors = st.builds(
    JoystickDescriptor, st.integers(0, 255), st.booleans(),
    st.sampled_from(list(JoystickType)), st.text(max_size=40),
    st.lists(st.sampled_from(list(AxisType)), max_size=12).map(tuple), st.integers(0, 255), st.integers(0, 255),
)
frames = st.one_of(
    descriptors,
    st.builds(MatchInfo, st.text(max_size=60), st.sampled_from(list(MatchType)), st.integers(0, 0xFFFF),
              st.integers(0, 255)),
    st.builds(GameData, st.text(max_size=100)),
    st.builds(UnknownFrame, st.integers(0, 255).filter(lambda i: i not in (2, 7, 14)), st.binary(max_size=50)),
    st.just(KeepAlive()),
)


@given(frames)
def test_tcp_round_trip(frame):
    assert_round_trip(frame, decode_tcp, annotate_tcp)


@given(st.integers(0, 255), st.binary(max_size=80))
def test_random_tcp_payloads(tag_id, payload):
    decode_or_protocol_error("ds-to-rio-tcp", framed(tag_id, payload))


@given(st.binary(max_size=80))
def test_random_tcp_bytes(data):
    decode_or_protocol_error("ds-to-rio-tcp", data)
