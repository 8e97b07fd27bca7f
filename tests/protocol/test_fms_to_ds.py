"""FMS -> DS: the UDP control packet (1121) and the TCP 1750 frames."""

from __future__ import annotations

import datetime as dt

import pytest
from hypothesis import given
from hypothesis import strategies as st

from protocol import kinds
from protocol.enums import AllianceStation, Mode, StationStatus, TournamentLevel
from protocol.fms_to_ds import (
    ChallengeQuestion, DeviceVersion, EventCode, FmsControlPacket, FmsDate, GameData, GameDataTag, HelloReply,
    KeepAlive, StationInfo, UnknownFrame, VersionDevice, annotate_control, annotate_tcp, decode_control,
    decode_tcp,
)
from protocol.framing import FrameDecoder
from protocol.wire import UnknownTag

from .util import (assert_round_trip, assert_tiles, check_mutated_frame, decode_or_protocol_error, feed_bytewise,
                   framed, mutate, protocol_error, where)

# -- golden vectors: the control packet ---------------------------------------------------

# Built byte by byte the way Cheesy Arena's encodeControlPacket writes it
# (field/driver_station_connection.go): packet count 0x0102, protocol 0, status 0x06 (auto
# 0x02 + enabled 0x04), byte 4 = 0, station B2 = 4, match type qualification = 2, match
# number (TypeOrder) 28, repeat number 1, time.Now() = 2025-06-14 13:02:03.000500 local:
# microseconds 500, second, minute, hour, day 14, Month() = 6 (June, 1-BASED), year - 1900 =
# 125; remaining seconds 15 (auto period).
CHEESY_CONTROL = bytes.fromhex("0102 00 06 00 04 02 001c 01 000001f4 03 02 0d 0e 06 7d 000f")

# Cheesy Arena for the 2027 FIRST DS (field/driver_station_connection.go, commit 1612d071,
# and before it 2025): the same 22 bytes, then game data as UDP tag 32 (0x20): size =
# len + 1, "LRL". Its test file as stored here predates the new DS and gives no vector for
# it, so this is built from its encoder's layout (docs/protocol.md#cheesy-2027).
CHEESY_GAME_DATA_TAG = bytes.fromhex("04 20") + b"LRL"

# Seed table (fms_to_ds.rst "UDP" and "Date"): sequence 7, comm version 0, control 0x80
# (e-stop) | 0x40 (a-stop, PROTOCOL-NOTES) | 0x04 enabled | 0x01 test, request 0, station
# R1, level playoff (3), match 300, play 2, 2026-03-14 15:09:26.535897 UTC with the month
# 0-BASED (March = 2) and year 126, remaining 140 s.
SEED_CONTROL = bytes.fromhex("0007 00 c5 00 00 03 012c 02 00082d59 1a 09 0f 0e 02 7e 008c")


def test_cheesy_arena_control_packet():
    p = decode_control(CHEESY_CONTROL)
    assert p.sequence == 0x0102 and p.comm_version == 0
    assert (p.estop, p.astop, p.enabled, p.mode) == (False, False, True, Mode.AUTONOMOUS)
    assert p.request == 0 and p.station is AllianceStation.BLUE2
    assert p.tournament_level is TournamentLevel.QUALIFICATION
    assert (p.match_number, p.play_number, p.remaining_seconds) == (28, 1, 15)
    assert p.date == FmsDate(500, 3, 2, 13, 14, 6, 125)
    assert p.tags == () and p.control_other == 0
    assert p.encode() == CHEESY_CONTROL


def test_cheesy_month_is_one_based_and_local():
    date = decode_control(CHEESY_CONTROL).date
    # Read as the seed says (0-based, UTC) the date is a month late ...
    assert date.to_datetime() == dt.datetime(2025, 7, 14, 13, 2, 3, 500, tzinfo=dt.timezone.utc)
    # ... read as Cheesy Arena means it, it is June, local time.
    assert date.to_datetime(one_based_month=True, tz=None) == dt.datetime(2025, 6, 14, 13, 2, 3, 500)
    # December from Cheesy Arena is month 12: no such month 0-based, and no crash.
    december = FmsDate(0, 0, 0, 12, 24, 12, 125)
    assert december.to_datetime() is None
    assert december.to_datetime(one_based_month=True) == dt.datetime(2025, 12, 24, 12, tzinfo=dt.timezone.utc)


def test_invalid_dates_decode_and_give_none():
    for date in (FmsDate(), FmsDate(0, 60, 0, 0, 1, 0, 100), FmsDate(0, 0, 0, 25, 1, 0, 100),
                 FmsDate(0, 0, 0, 0, 31, 1, 100), FmsDate(2**32 - 1, 255, 255, 255, 255, 255, 255)):
        data = FmsControlPacket(date=date).encode()
        assert decode_control(data).date == date
        assert date.to_datetime() is None
    # An early Cheesy Arena fork put nanoseconds in the microseconds field: clamped.
    assert FmsDate(999_999_999, 0, 0, 0, 1, 0, 100).to_datetime().microsecond == 999_999


def test_seed_control_packet_and_from_datetime():
    when = dt.datetime(2026, 3, 14, 15, 9, 26, 535897, tzinfo=dt.timezone.utc)
    p = FmsControlPacket(sequence=7, estop=True, astop=True, enabled=True, mode=Mode.TEST,
                         station=AllianceStation.RED1, tournament_level=TournamentLevel.PLAYOFF,
                         match_number=300, play_number=2, date=FmsDate.from_datetime(when),
                         remaining_seconds=140)
    assert p.encode() == SEED_CONTROL
    assert decode_control(SEED_CONTROL) == p
    assert p.date.month == 2 and p.date.year == 126
    assert p.date.to_datetime() == when
    # An aware time elsewhere is converted to UTC first (the seed: hour "In UTC?").
    pacific = dt.timezone(dt.timedelta(hours=-7))
    assert FmsDate.from_datetime(when.astimezone(pacific)) == p.date


def test_control_bits_and_undocumented_bits_survive():
    # Every combination of the control byte decodes and re-encodes identically.
    for ctl in range(256):
        data = bytearray(CHEESY_CONTROL)
        data[3] = ctl
        p = decode_control(bytes(data))
        assert p.estop == bool(ctl & 0x80) and p.astop == bool(ctl & 0x40)
        assert p.enabled == bool(ctl & 0x04) and p.mode == ctl & 3
        assert p.control_other == ctl & 0x38
        assert p.control_byte == ctl and p.encode() == bytes(data)


def test_undocumented_tournament_level_and_request_are_kept():
    data = bytearray(CHEESY_CONTROL)
    data[4], data[6] = 0x5A, 9
    p = decode_control(bytes(data))
    assert p.request == 0x5A and p.tournament_level == 9 and not isinstance(p.tournament_level, TournamentLevel)
    assert p.encode() == bytes(data)


def test_game_data_tag_32_for_the_2027_ds_and_unknown_tags_kept_raw():
    data = CHEESY_CONTROL + CHEESY_GAME_DATA_TAG + bytes.fromhex("01 7f")
    p = decode_control(data)
    assert p.tags == (GameDataTag("LRL"), UnknownTag(0x7F, b""))
    assert p.game_data == "LRL" and decode_control(CHEESY_CONTROL).game_data is None
    assert p.encode() == data
    assert FmsControlPacket(**{**{f: getattr(p, f) for f in ("sequence", "enabled", "mode", "station",
                                                              "tournament_level", "match_number", "play_number",
                                                              "date", "remaining_seconds")},
                               "tags": (GameDataTag("LRL"),)}).encode() == CHEESY_CONTROL + CHEESY_GAME_DATA_TAG
    spans = annotate_control(data)
    assert_tiles(spans, data)
    by_field = {s.field: s for s in spans}
    assert by_field["tags[0].id"].value == "game_data" and "2027" in by_field["tags[0].id"].meaning
    assert (by_field["tags[0].text"].offset, by_field["tags[0].text"].value) == (24, "LRL")
    assert "not documented" in by_field["tags[1].id"].meaning


def test_game_data_tag_bounds():
    # Eight characters is the most an FMS sends (Cheesy Arena cuts game data there) ...
    eight = CHEESY_CONTROL + bytes.fromhex("09 20") + b"ABCDEFGH"
    assert decode_control(eight).tags == (GameDataTag("ABCDEFGH"),)
    assert decode_control(CHEESY_CONTROL + bytes.fromhex("01 20")).tags == (GameDataTag(""),)
    # ... nine is no FMS's: kept raw (so it still re-encodes byte for byte), and said so.
    nine = CHEESY_CONTROL + bytes.fromhex("0a 20") + b"ABCDEFGHI"
    assert decode_control(nine).tags == (UnknownTag(0x20, b"ABCDEFGHI"),)
    assert decode_control(nine).encode() == nine
    assert "over the 8" in {s.field: s for s in annotate_control(nine)}["tags[0].id"].meaning
    # Encoding refuses what no DS would take, naming the field.
    assert where(protocol_error(FmsControlPacket(tags=(GameDataTag("ABCDEFGHI"),)).encode)) == (
        "FmsControlPacket", "tags[0].text", None)
    assert where(protocol_error(FmsControlPacket(tags=(GameDataTag(b"LRL"),)).encode)) == (
        "FmsControlPacket", "tags[0].text", None)
    # A size byte running past the packet names the tag and its offset.
    assert where(protocol_error(decode_control, CHEESY_CONTROL + bytes.fromhex("05 20") + b"LR")) == (
        "FmsControlPacket", "tags[0]", 23)


def test_annotation_explains_the_control_packet():
    spans = annotate_control(CHEESY_CONTROL)
    assert_tiles(spans, CHEESY_CONTROL)
    by_field = {s.field: s for s in spans}
    assert [s.field for s in spans] == [
        "sequence", "comm_version", "control", "request", "station", "tournament_level",
        "match_number", "play_number", "date.microseconds", "date.second", "date.minute",
        "date.hour", "date.day", "date.month", "date.year", "remaining_seconds"]
    assert by_field["control"].meaning == "control: no e-stop, no a-stop, enabled, autonomous"
    assert by_field["station"].value == "B2"
    assert by_field["tournament_level"].value == "QUALIFICATION"
    assert by_field["date.month"].meaning == "month 6: July if 0-based (seed), June if 1-based (Cheesy Arena)"
    assert "2025-06-14 13:02:03" in by_field["date.year"].meaning
    assert by_field["remaining_seconds"].meaning == "15 s (0:15) left in the current period"


@pytest.mark.parametrize("hexdata,field,offset", [
    ("", "sequence", 0),
    ("0102 00", "control", 3),
    ("0102 00 06 00 06", "station", 5),
    ("0102 00 06 00 ff", "station", 5),
    ("0102 00 06 00 04 02 001c 01 000001", "date.microseconds", 10),
    ("0102 00 06 00 04 02 001c 01 000001f4 03 02 0d 0e 06 7d 00", "remaining_seconds", 20),
    ("0102 00 06 00 04 02 001c 01 000001f4 03 02 0d 0e 06 7d 000f 00", "tags[0].size", 22),
    ("0102 00 06 00 04 02 001c 01 000001f4 03 02 0d 0e 06 7d 000f 04 20 4c", "tags[0]", 23),
])
def test_bad_control_packets_name_field_and_offset(hexdata, field, offset):
    assert where(protocol_error(decode_control, bytes.fromhex(hexdata))) == ("FmsControlPacket", field, offset)


def test_control_error_messages_read_well():
    assert (str(protocol_error(decode_control, bytes.fromhex("0102 00 06 00 06")))
            == "FmsControlPacket.station at byte 5: 6 is not an alliance station (0-5)")
    assert (str(protocol_error(decode_control, CHEESY_CONTROL[:21]))
            == "FmsControlPacket.remaining_seconds at byte 20: needs 2 bytes, 1 left")
    assert (str(protocol_error(FmsControlPacket(match_number=70000).encode))
            == "FmsControlPacket.match_number: 70000 is outside 0..65535")


@pytest.mark.parametrize("packet,field", [
    (FmsControlPacket(sequence=-1), "sequence"),
    (FmsControlPacket(sequence=0x10000), "sequence"),
    (FmsControlPacket(comm_version=256), "comm_version"),
    (FmsControlPacket(mode=4), "mode"),
    (FmsControlPacket(control_other=0x80), "control_other"),
    (FmsControlPacket(control_other=0x04), "control_other"),
    (FmsControlPacket(request=256), "request"),
    (FmsControlPacket(station=6), "station"),
    (FmsControlPacket(station="R1"), "station"),
    (FmsControlPacket(tournament_level=-1), "tournament_level"),
    (FmsControlPacket(match_number=0x10000), "match_number"),
    (FmsControlPacket(play_number=256), "play_number"),
    (FmsControlPacket(date=FmsDate(microseconds=2**32)), "date.microseconds"),
    (FmsControlPacket(date=FmsDate(month=256)), "date.month"),
    (FmsControlPacket(date=FmsDate(year=-1)), "date.year"),
    (FmsControlPacket(date=dt.datetime(2025, 1, 1)), "date"),
    (FmsControlPacket(remaining_seconds=-5), "remaining_seconds"),
    (FmsControlPacket(remaining_seconds=1.5), "remaining_seconds"),
    (FmsControlPacket(tags=(UnknownTag(0x20, b"x" * 255),)), "tags[0].data"),
    (FmsControlPacket(tags=(UnknownTag(256, b""),)), "tags[0].tag_id"),
    (FmsControlPacket(tags=(b"\x01\x20",)), "tags[0]"),
])
def test_control_encoding_refuses_bad_values(packet, field):
    assert where(protocol_error(packet.encode)) == ("FmsControlPacket", field, None)


# -- golden vectors: TCP frames -----------------------------------------------------------

# PROTOCOL-NOTES "How a real FMS behaves", and Cheesy Arena's assignment packet
# {0, 3, 25, station, status}: a team not in the match (station 0, waiting), a team in B2
# (good), a team in the wrong station (R2, bad).
STATION_WAITING = bytes.fromhex("0003 19 00 02")
STATION_B2_GOOD = bytes.fromhex("0003 19 04 00")
STATION_R2_BAD = bytes.fromhex("0003 19 01 01")

# Cheesy Arena's event name packet {0, len + 2, 20, len, name...}: TBA code "2025casj" with
# its leading digits stripped.
CHEESY_EVENT_CODE = bytes.fromhex("0006 14 04") + b"casj"

# Cheesy Arena's sendGameDataPacketTcp {0, size + 2, 28, size, data...} for "LRL".
CHEESY_GAME_DATA = bytes.fromhex("0005 1c 03") + b"LRL"

# An early Cheesy Arena-based FMS (DsIpConfig): inquiry {0, 4 + len, 0x1a, len, text,
# value / 256, value % 256}, with its first inquiry value 1000 = 0x03e8.
EARLY_CHALLENGE = bytes.fromhex("001a 1a 16") + b"Coolest robot EVER!!??" + bytes.fromhex("03e8")

# The same early FMS's version frames {0, 2 + len, id, len, text}: the version alone.
EARLY_FMS_VERSION = bytes.fromhex("0015 00 13") + b"2015 Update 6.1.6.8"
EARLY_RIO_VERSION = bytes.fromhex("0016 01 14") + b"FRC_roboRIO_2015_v18"

# Seed "Version": status then version, each (our reading, see DeviceVersion) with a u8
# length: the preferred DS version.
DS_VERSION_PREFERRED = bytes.fromhex("0016 02 0b") + b"<preferred>" + bytes.fromhex("08") + b"09121400"

# Cheesy Arena (commit 1612d071) answers the 2027 DS's hello with tag 31: {0, 6, 31,
# station, status, flags, team hi, team lo}: B1, good, full FMS, team 254. Its test file as
# stored here predates the new DS, so the bytes follow its encoder's layout.
CHEESY_NEW_DS_ASSIGNMENT = bytes.fromhex("0006 1f 03 00 00 00fe")
# The same from an FMS in FMS Lite mode (flags bit 0), team 1503 waiting at R1.
CHEESY_NEW_DS_LITE_WAITING = bytes.fromhex("0006 1f 00 02 01 05df")


def test_station_info_frames():
    assert decode_tcp(STATION_WAITING) == StationInfo(AllianceStation.RED1, StationStatus.WAITING)
    assert decode_tcp(STATION_B2_GOOD) == StationInfo(AllianceStation.BLUE2, StationStatus.GOOD)
    assert decode_tcp(STATION_R2_BAD) == StationInfo(AllianceStation.RED2, StationStatus.BAD)
    for frame in (STATION_WAITING, STATION_B2_GOOD, STATION_R2_BAD):
        assert decode_tcp(frame).encode() == frame
    odd = decode_tcp(bytes.fromhex("0003 19 05 07"))
    assert odd.status == 7 and odd.encode() == bytes.fromhex("0003 19 05 07")
    spans = {s.field: s for s in annotate_tcp(STATION_WAITING)}
    assert spans["status"].value == "WAITING" and "not in the current match" in spans["status"].meaning


def test_cheesy_string_frames():
    assert decode_tcp(CHEESY_EVENT_CODE) == EventCode("casj")
    assert EventCode("casj").encode() == CHEESY_EVENT_CODE
    assert decode_tcp(CHEESY_GAME_DATA) == GameData("LRL")
    assert GameData("LRL").encode() == CHEESY_GAME_DATA
    q = decode_tcp(EARLY_CHALLENGE)
    assert q == ChallengeQuestion("Coolest robot EVER!!??", 1000)
    assert ChallengeQuestion().encode() == EARLY_CHALLENGE


def test_version_frames_with_and_without_status():
    fms = decode_tcp(EARLY_FMS_VERSION)
    assert fms == DeviceVersion(VersionDevice.WPILIB, None, "2015 Update 6.1.6.8")
    assert fms.encode() == EARLY_FMS_VERSION
    rio = decode_tcp(EARLY_RIO_VERSION)
    assert rio == DeviceVersion(VersionDevice.ROBORIO, None, "FRC_roboRIO_2015_v18")
    ds = decode_tcp(DS_VERSION_PREFERRED)
    assert ds == DeviceVersion(VersionDevice.DS, "<preferred>", "09121400")
    assert ds.encode() == DS_VERSION_PREFERRED
    # Empty strings stay distinguishable: status "" is two length bytes, status None one.
    assert DeviceVersion(7, "", "").encode() == bytes.fromhex("0003 07 00 00")
    assert DeviceVersion(7, None, "").encode() == bytes.fromhex("0002 07 00")
    assert decode_tcp(bytes.fromhex("0003 07 00 00")) == DeviceVersion(7, "", "")
    assert decode_tcp(bytes.fromhex("0002 07 00")) == DeviceVersion(7, None, "")
    spans = annotate_tcp(DS_VERSION_PREFERRED)
    assert [s.field for s in spans] == ["size", "id", "status.length", "status", "version.length", "version"]
    assert spans[1].meaning == "frame 0x02: Driver Station version"


def test_keepalive_and_unknown_frames():
    assert decode_tcp(b"\x00\x00") == KeepAlive() and KeepAlive().encode() == b"\x00\x00"
    frame = decode_tcp(bytes.fromhex("0003 30 aa bb"))
    assert frame == UnknownFrame(0x30, b"\xaa\xbb") and frame.encode() == bytes.fromhex("0003 30 aa bb")
    assert "not documented" in annotate_tcp(bytes.fromhex("0003 30 aa bb"))[1].meaning


def test_hello_reply_tag_31_for_the_2027_ds():
    frame = decode_tcp(CHEESY_NEW_DS_ASSIGNMENT)
    assert frame == HelloReply(AllianceStation.BLUE1, StationStatus.GOOD, 0, 254) and not frame.fms_lite
    assert frame.encode() == CHEESY_NEW_DS_ASSIGNMENT and len(CHEESY_NEW_DS_ASSIGNMENT) == 8
    lite = decode_tcp(CHEESY_NEW_DS_LITE_WAITING)
    assert lite == HelloReply(AllianceStation.RED1, StationStatus.WAITING, 1, 1503) and lite.fms_lite
    spans = annotate_tcp(CHEESY_NEW_DS_LITE_WAITING)
    assert_tiles(spans, CHEESY_NEW_DS_LITE_WAITING)
    assert [s.field for s in spans] == ["size", "id", "station", "status", "flags", "team"]
    assert spans[1].value == "hello_reply" and "2027" in spans[1].meaning
    assert "FMS Lite" in spans[4].meaning and "waiting" in spans[3].meaning and spans[5].value == 1503
    # Flag bits no source names are kept, and said.
    odd = decode_tcp(bytes.fromhex("0006 1f 05 00 81 0001"))
    assert odd.flags == 0x81 and odd.encode() == bytes.fromhex("0006 1f 05 00 81 0001")
    assert "other bits 0x80" in annotate_tcp(bytes.fromhex("0006 1f 05 00 81 0001"))[4].meaning


@pytest.mark.parametrize("hexdata,field,offset", [
    ("0005 1f 03 00 00 00", "team", 6),  # one byte short
    ("0007 1f 03 00 00 00fe 00", "end", 8),  # one byte over
    ("0006 1f 06 00 00 00fe", "station", 3),  # no station 6
])
def test_bad_hello_replies_name_field_and_offset(hexdata, field, offset):
    assert where(protocol_error(decode_tcp, bytes.fromhex(hexdata))) == ("FmsToDsFrame", field, offset)


@pytest.mark.parametrize("frame,field", [
    (HelloReply(6), "station"), (HelloReply(status=256), "status"), (HelloReply(flags=-1), "flags"),
    (HelloReply(team=65536), "team"),
])
def test_hello_reply_encoding_refuses_bad_values(frame, field):
    assert where(protocol_error(frame.encode)) == ("FmsToDsFrame", field, None)


def test_frames_through_the_stream_decoder():
    stream = (STATION_B2_GOOD + CHEESY_EVENT_CODE + EARLY_FMS_VERSION + b"\x00\x00" + EARLY_CHALLENGE
              + CHEESY_GAME_DATA)
    frames = feed_bytewise(FrameDecoder("FmsToDsFrame"), stream)
    assert [type(decode_tcp(f)).__name__ for f in frames] == [
        "StationInfo", "EventCode", "DeviceVersion", "KeepAlive", "ChallengeQuestion", "GameData"]
    for f in frames:
        assert_tiles(annotate_tcp(f), f)


@pytest.mark.parametrize("hexdata,field,offset", [
    ("00", "size", 0),
    ("0004 19 00 02", "size", 0),
    ("0003 19 06 00", "station", 3),
    ("0002 19 00", "status", 4),
    ("0004 19 00 02 00", "end", 5),
    ("0003 14 05 41", "code", 4),
    ("0001 14", "code.length", 3),
    ("0004 1a 01 41 03", "random_value", 5),
    ("0001 02", "status.length", 3),
    ("0004 02 01 41 05", "version", 6),
    ("0006 02 00 00 41 42 43", "end", 5),
])
def test_bad_frames_name_field_and_offset(hexdata, field, offset):
    assert where(protocol_error(decode_tcp, bytes.fromhex(hexdata))) == ("FmsToDsFrame", field, offset)


def test_frame_error_messages_read_well():
    assert (str(protocol_error(decode_tcp, bytes.fromhex("0003 19 07 00")))
            == "FmsToDsFrame.station at byte 3: 7 is not an alliance station (0-5)")
    assert (str(protocol_error(EventCode("x" * 256).encode))
            == "FmsToDsFrame.code: 256 bytes is too long (at most 255)")
    assert str(protocol_error(DeviceVersion(8, "<good>", "1").encode)) == "DeviceVersion.device: 8 is outside 0..7"


@pytest.mark.parametrize("frame,message,field", [
    (EventCode("é" * 128), "FmsToDsFrame", "code"),
    (EventCode(5), "FmsToDsFrame", "code"),
    (StationInfo(6, StationStatus.GOOD), "FmsToDsFrame", "station"),
    (StationInfo(0, 256), "FmsToDsFrame", "status"),
    (ChallengeQuestion("?", 65536), "FmsToDsFrame", "random_value"),
    (ChallengeQuestion("?" * 256, 1000), "FmsToDsFrame", "question"),
    (GameData("x" * 256), "FmsToDsFrame", "text"),
    (GameData(b"LRL"), "FmsToDsFrame", "text"),
    (UnknownFrame(256, b""), "FmsToDsFrame", "tag_id"),
    (UnknownFrame(0x30, "text"), "FmsToDsFrame", "data"),
    (UnknownFrame(0x30, b"x" * 0xFFFF), "FmsToDsFrame", "size"),
    (DeviceVersion(-1, None, ""), "DeviceVersion", "device"),
    (DeviceVersion(0, 5, ""), "DeviceVersion", "status"),
    (DeviceVersion(0, "<good>", "v" * 256), "DeviceVersion", "version"),
])
def test_frame_encoding_refuses_bad_values(frame, message, field):
    assert where(protocol_error(frame.encode)) == (message, field, None)


def test_kinds_are_registered():
    udp, tcp = kinds.get("fms-to-ds"), kinds.get("fms-to-ds-tcp")
    assert (udp.message, udp.tcp, tcp.message, tcp.tcp) == ("FmsControlPacket", False, "FmsToDsFrame", True)
    assert kinds.decode("fms-to-ds", CHEESY_CONTROL) == decode_control(CHEESY_CONTROL)
    assert kinds.annotate("fms-to-ds-tcp", STATION_WAITING) == annotate_tcp(STATION_WAITING)


# -- properties -----------------------------------------------------------------------------

u8, u16 = st.integers(0, 0xFF), st.integers(0, 0xFFFF)
dates = st.builds(FmsDate, st.integers(0, 2**32 - 1), u8, u8, u8, u8, u8, u8)
unknown_tags = st.one_of(
    st.builds(UnknownTag, u8.filter(lambda i: i != 0x20), st.binary(max_size=40)),
    st.builds(UnknownTag, st.just(0x20), st.binary(min_size=9, max_size=40)),  # over 8: kept raw
    st.builds(GameDataTag, st.text(max_size=8).filter(lambda t: len(t.encode("utf-8", "surrogateescape")) <= 8)),
)
control_packets = st.builds(
    FmsControlPacket, u16, u8, st.booleans(), st.booleans(), st.booleans(), st.sampled_from(Mode), u8,
    st.sampled_from(AllianceStation), st.one_of(st.sampled_from(TournamentLevel), st.integers(4, 255)),
    u16, u8, dates, u16, st.lists(unknown_tags, max_size=6).map(tuple),
    st.sampled_from([0, 0x08, 0x10, 0x20, 0x38]),
)


@given(control_packets)
def test_control_round_trip(packet):
    assert_round_trip(packet, decode_control, annotate_control)


@given(st.datetimes(min_value=dt.datetime(1900, 1, 1), max_value=dt.datetime(2155, 12, 31),
                    timezones=st.just(dt.timezone.utc)))
def test_dates_round_trip_through_the_seed_encoding(when):
    date = FmsDate.from_datetime(when)
    back = decode_control(FmsControlPacket(date=date).encode()).date
    assert back == date and back.to_datetime() == when


@given(st.binary(max_size=120))
def test_random_bytes_give_a_packet_or_protocol_error(data):
    decode_or_protocol_error("fms-to-ds", data)


@given(control_packets, st.data())
def test_mutated_packets_give_a_packet_or_protocol_error(packet, data):
    decode_or_protocol_error("fms-to-ds", mutate(packet.encode(), data.draw))


text = st.text(max_size=40)
frames = st.one_of(
    st.just(KeepAlive()),
    st.builds(DeviceVersion, st.sampled_from(VersionDevice), st.one_of(st.none(), text), text),
    st.builds(EventCode, text),
    st.builds(StationInfo, st.sampled_from(AllianceStation),
              st.one_of(st.sampled_from(StationStatus), st.integers(3, 255))),
    st.builds(ChallengeQuestion, text, u16),
    st.builds(GameData, text),
    st.builds(HelloReply, st.sampled_from(AllianceStation),
              st.one_of(st.sampled_from(StationStatus), st.integers(3, 255)), u8, u16),
    st.builds(UnknownFrame, u8.filter(lambda i: i > 7 and i not in (0x14, 0x19, 0x1A, 0x1C, 0x1F)),
              st.binary(max_size=60)),
)


@given(frames)
def test_tcp_round_trip(frame):
    assert_round_trip(frame, decode_tcp, annotate_tcp)


FRAME_IDS = st.one_of(st.sampled_from([0, 1, 2, 7, 0x14, 0x19, 0x1A, 0x1C, 0x1F]), u8)


@given(FRAME_IDS, st.binary(max_size=80))
def test_random_tcp_payloads(tag_id, payload):
    decode_or_protocol_error("fms-to-ds-tcp", framed(tag_id, payload))


@given(st.binary(max_size=80))
def test_random_tcp_bytes(data):
    decode_or_protocol_error("fms-to-ds-tcp", data)


@given(frames, st.data())
def test_mutated_tcp_frames(frame, data):
    check_mutated_frame("fms-to-ds-tcp", frame, data.draw)
