"""DS -> FMS: the UDP status packet (1160), the TCP 1750 frames and the challenge answer.

No seed document covers this direction: the vectors come from PROTOCOL-NOTES "Driver Station
-> FMS" and from what real peers read and write (Cheesy Arena, open-ds, LibDS).
"""

from __future__ import annotations

import datetime as dt

import pytest
from hypothesis import given
from hypothesis import strategies as st

from protocol import kinds
from protocol.ds_to_fms import (
    ROBOT_NAMES, ChallengeResponse, CommsMetrics, DeviceVersion, DsPing, DsStatusPacket, EmptyTag,
    DsHello, ErrorEvent, ErrorEventData, FieldRadioMetrics, KeepAlive, LaptopMetrics, LogData, LogRecord,
    PdInfo, RobotRadioMetrics, TeamNumber, UnknownFrame, UsageReport, VersionDevice,
    annotate_status, annotate_tcp, challenge_answer, check_challenge_answer, decode_status,
    decode_tcp, quantize_battery, quantize_half,
)
from protocol.enums import Mode
from protocol.framing import FrameDecoder
from protocol.wire import Reader, UnknownTag

from .util import (assert_round_trip, assert_tiles, check_mutated_frame, decode_or_protocol_error, feed_bytewise,
                   framed, mutate, protocol_error, where)

# -- golden vectors: the status packet ----------------------------------------------------

# PROTOCOL-NOTES "Driver Station -> FMS" table: sequence 42, comm version 0, status 0x3c
# (robot comms 0x20, radio ping 0x10, roboRIO ping 0x08, enabled 0x04, teleop), team 254,
# battery 12.5 V = 0x0c 0x80 (high byte volts, low byte /256).
STATUS_HEADER = bytes.fromhex("002a 00 3c 00fe 0c80")

# PROTOCOL-NOTES UDP tags, one of each: field radio (signal 50, bandwidth 256), comms (lost 3,
# sent 500, trip 5 ms: the size-6 tag Cheesy Arena reads), laptop (battery 90 %, CPU 15 %),
# robot radio (signal 40, bandwidth 128), PD info (empty).
FIELD_RADIO_TAG = bytes.fromhex("04 00 32 0100")
COMMS_TAG = bytes.fromhex("06 01 0003 01f4 05")
LAPTOP_TAG = bytes.fromhex("03 02 5a 0f")
ROBOT_RADIO_TAG = bytes.fromhex("04 03 28 0080")
PD_INFO_TAG = bytes.fromhex("01 04")
ALL_TAGS = FIELD_RADIO_TAG + COMMS_TAG + LAPTOP_TAG + ROBOT_RADIO_TAG + PD_INFO_TAG


def cheesy_arena_reads(data: bytes) -> dict:
    """What Cheesy Arena's listenForDsUdpPackets takes from a status packet (a restatement of
    its rules for the test, not its code): team from bytes 4-5, link bits 0x08/0x10/0x20 of
    byte 3, battery byte 6 + byte 7 / 256, and lost/ping from a tag 1 whose size byte is 6;
    a size byte of 0 is skipped."""
    seen = {"team": data[4] << 8 | data[5], "rio": bool(data[3] & 0x08),
            "radio": bool(data[3] & 0x10), "robot": bool(data[3] & 0x20),
            "battery": data[6] + data[7] / 256}
    i = 8
    while i < len(data):
        length = data[i]
        i += 1
        if length == 0:
            continue
        if i + length > len(data):
            break
        if data[i] == 1 and length == 6:
            seen["lost"] = data[i + 1] << 8 | data[i + 2]
            seen["ping"] = data[i + 5]
        i += length
    return seen


def test_status_packet_every_tag():
    data = STATUS_HEADER + ALL_TAGS
    p = decode_status(data)
    assert p == DsStatusPacket(
        sequence=42, estop=False, robot_comms=True, radio_ping=True, rio_ping=True, enabled=True,
        mode=Mode.TELEOP, team=254, battery=12.5,
        tags=(FieldRadioMetrics(50, 256), CommsMetrics(3, 500, 5), LaptopMetrics(90, 15),
              RobotRadioMetrics(40, 128), PdInfo()))
    assert p.encode() == data
    assert p.tag(CommsMetrics).average_trip_time_ms == 5 and p.tag(EmptyTag) is None


def test_status_packet_reads_as_cheesy_arena_reads_it():
    p = DsStatusPacket(sequence=1, robot_comms=True, radio_ping=True, rio_ping=True, team=1114,
                       battery=quantize_battery(12.34), tags=(LaptopMetrics(80, 5), CommsMetrics(7, 900, 12)))
    seen = cheesy_arena_reads(p.encode())
    assert seen == {"team": 1114, "rio": True, "radio": True, "robot": True,
                    "battery": p.battery, "lost": 7, "ping": 12}
    assert abs(p.battery - 12.34) <= 1 / 512


def test_status_bits_match_libds():
    # LibDS create_fms_packet / fms_control_code: comm version 0x00, robot comms sets both
    # 0x20 (comms) and 0x08 (robot ping), radio sets 0x10, auto 0x02, enabled 0x04, e-stop 0x80.
    p = DsStatusPacket(estop=True, robot_comms=True, rio_ping=True, radio_ping=True, enabled=True,
                       mode=Mode.AUTONOMOUS, team=0x1234)
    assert p.encode() == bytes.fromhex("0000 00 be 1234 0000")
    for st_byte in range(256):
        data = bytes((0, 1, 0, st_byte, 0, 1, 0, 0))
        q = decode_status(data)
        assert q.status_byte == st_byte and q.status_other == st_byte & 0x40
        assert q.encode() == data


def test_zero_size_tag_is_skipped_like_cheesy_arena():
    # PROTOCOL-NOTES tags always hold an id; Cheesy Arena skips a 0 size byte and reads on.
    data = STATUS_HEADER + b"\x00" + COMMS_TAG + b"\x00"
    p = decode_status(data)
    assert p.tags == (EmptyTag(), CommsMetrics(3, 500, 5), EmptyTag())
    assert p.encode() == data
    assert cheesy_arena_reads(data)["ping"] == 5
    assert "Cheesy Arena skips" in annotate_status(data)[5].meaning


def test_known_tag_with_the_wrong_size_is_kept_raw():
    # A comms tag of size 5: Cheesy Arena ignores it (it wants size 6); we keep it raw.
    data = STATUS_HEADER + bytes.fromhex("05 01 0003 01f4" "03 04 aa bb" "02 42 00")
    p = decode_status(data)
    assert p.tags == (UnknownTag(1, bytes.fromhex("0003 01f4")), UnknownTag(4, b"\xaa\xbb"),
                      UnknownTag(0x42, b"\x00"))
    assert p.encode() == data
    assert "ping" not in cheesy_arena_reads(data)
    spans = annotate_status(data)
    assert_tiles(spans, data)
    by_field = {s.field: s for s in spans}
    assert by_field["tags[0].id"].meaning == ("tag 0x01 (comms metrics) with 4 data byte(s), "
                                              "not the 5 its layout has: kept raw")


def test_status_annotation():
    data = STATUS_HEADER + ALL_TAGS
    spans = annotate_status(data)
    assert_tiles(spans, data)
    by_field = {s.field: s for s in spans}
    assert by_field["status"].meaning == ("status: no e-stop, robot comms, radio ping ok, roboRIO ping ok, "
                                          "enabled, teleop")
    assert by_field["battery"].value == 12.5
    assert by_field["battery"].meaning == "battery: 12.500 V (12 + 128/256)"
    assert by_field["tags[1].id"].value == "CommsMetrics"
    assert by_field["tags[1].average_trip_time_ms"].value == 5
    assert [s.field for s in spans if s.field.startswith("tags[4]")] == ["tags[4].size", "tags[4].id"]


@pytest.mark.parametrize("hexdata,field,offset", [
    ("", "sequence", 0),
    ("002a 00", "status", 3),
    ("002a 00 3c 00fe 0c", "battery", 6),
    ("002a 00 3c 00fe 0c80 06 01 00", "tags[0]", 9),
    ("002a 00 3c 00fe 0c80 04 00 32", "tags[0]", 9),
])
def test_bad_status_packets_name_field_and_offset(hexdata, field, offset):
    assert where(protocol_error(decode_status, bytes.fromhex(hexdata))) == ("DsStatusPacket", field, offset)


def test_status_error_messages_read_well():
    assert (str(protocol_error(decode_status, bytes.fromhex("002a 00 3c 00fe 0c")))
            == "DsStatusPacket.battery at byte 6: needs 2 bytes, 1 left")
    assert (str(protocol_error(DsStatusPacket(battery=12.3).encode))
            == "DsStatusPacket.battery: 12.3 is not a multiple of 1/256")
    assert (str(protocol_error(DsStatusPacket(tags=(CommsMetrics(lost_packets=70000),)).encode))
            == "DsStatusPacket.tags[0].lost_packets: 70000 is outside 0..65535")


@pytest.mark.parametrize("packet,field", [
    (DsStatusPacket(sequence=-1), "sequence"),
    (DsStatusPacket(comm_version=256), "comm_version"),
    (DsStatusPacket(mode=4), "mode"),
    (DsStatusPacket(status_other=0x80), "status_other"),
    (DsStatusPacket(status_other=0x01), "status_other"),
    (DsStatusPacket(team=65536), "team"),
    (DsStatusPacket(battery=12.3), "battery"),
    (DsStatusPacket(battery=-1 / 256), "battery"),
    (DsStatusPacket(battery=256.0), "battery"),
    (DsStatusPacket(battery=float("nan")), "battery"),
    (DsStatusPacket(battery=float("inf")), "battery"),
    (DsStatusPacket(battery=1e308), "battery"),
    (DsStatusPacket(battery="12.5"), "battery"),
    (DsStatusPacket(battery=True), "battery"),
    (DsStatusPacket(tags=(FieldRadioMetrics(256, 0),)), "tags[0].signal_strength"),
    (DsStatusPacket(tags=(FieldRadioMetrics(0, 65536),)), "tags[0].bandwidth_utilization"),
    (DsStatusPacket(tags=(LaptopMetrics(0, 0), LaptopMetrics(0, -1))), "tags[1].cpu_percent"),
    (DsStatusPacket(tags=(CommsMetrics(0, 0, 256),)), "tags[0].average_trip_time_ms"),
    (DsStatusPacket(tags=(RobotRadioMetrics(1.5, 0),)), "tags[0].signal_strength"),
    (DsStatusPacket(tags=(UnknownTag(5, b"x" * 255),)), "tags[0].data"),
    (DsStatusPacket(tags=(UnknownTag(-1, b""),)), "tags[0].tag_id"),
    (DsStatusPacket(tags=("PdInfo",)), "tags[0]"),
    (DsStatusPacket(tags=(LogRecord(),)), "tags[0]"),
])
def test_status_encoding_refuses_bad_values(packet, field):
    assert where(protocol_error(packet.encode)) == ("DsStatusPacket", field, None)


def test_quantizers():
    assert quantize_battery(12.34) == 3159 / 256
    assert quantize_battery(-3) == 0.0 and quantize_battery(300) == 0xFFFF / 256
    assert quantize_battery(float("nan")) == 0.0
    assert quantize_half(20.3) == 20.5 and quantize_half(-1) == 0.0 and quantize_half(1000) == 127.5
    DsStatusPacket(battery=quantize_battery(7.777)).encode()


# -- golden vectors: TCP frames -----------------------------------------------------------

# PROTOCOL-NOTES: the login, "00 03 18 hi lo", team 254. Cheesy Arena tests exactly
# packet[0] == 0, packet[1] == 3, packet[2] == 24.
LOGIN_254 = bytes.fromhex("0003 18 00fe")

# DS ping: the FMS documents name 0x1c; Cheesy Arena (since 2024-07) and open-ds take 0x1d,
# and Cheesy Arena logs 0x1c as "unknown packet type 28" (PROTOCOL-NOTES DS -> FMS table).
DS_PING = bytes.fromhex("0001 1c")
CHEESY_PING = bytes.fromhex("0001 1d")

# PROTOCOL-NOTES log data: trip byte 0x0a (a 10 ms round trip: "Corrections", log data
# 0x16), lost 2, battery 12.25 V (0c 40), status 0x24 (DS teleop 0x20 + robot teleop 0x04),
# CAN 0x29 (20.5 %), signal 0x50 (40 dB), bandwidth 0x0180 (1.5).
LOG_DATA = bytes.fromhex("000a 16 0a 02 0c40 24 29 50 0180")

# open-ds's LOG_DATA for team 254, teleop, enabled, as it writes it: trip 0x01, lost 0x00,
# then the TEAM NUMBER where the battery belongs (00 fe), status 0x20 + 0x04, CAN 1, signal
# 1, bandwidth 0x0001. It decodes: the battery just reads 254/256 V.
OPEN_DS_LOG_DATA = bytes.fromhex("000a 16 01 00 00fe 24 01 01 0001")

# open-ds's USAGE_REPORT: team, 0x00, then (here two) entry bytes.
USAGE_REPORT = bytes.fromhex("0006 15 00fe 00 abcd")

# PROTOCOL-NOTES error and event data with count 1: timestamp 2025-01-01 00:00:00.5 UTC
# (3818534400 s after 1904-01-01; the next 8 bytes hold 0.5 s as 2**63 / 2**64), then a
# u32-length string.
ERROR_EVENT = (bytes.fromhex("002b 17 00000001 00000000e39a3600 8000000000000000 00000012")
               + b"Joystick unplugged")

# open-ds's CHALLENGE_RESPONSE: the answer's bytes, no length prefix. Team 254 and random
# value 1000: (254 * 1000) % 23 = 11, R2-D2.
CHALLENGE_RESPONSE = bytes.fromhex("0006 1b") + b"R2-D2"

# Cheesy Arena (field/driver_station_connection.go, commit 1612d071) reads the 2027 FIRST
# DS's hello, tag 30: {0, size, 30, port hi, port lo, flags, team length, team text}: UDP
# port 1121, flags 0, team "254". Its test file as stored here predates the new DS, so the
# bytes follow its reader's layout (docs/protocol.md#cheesy-2027).
CHEESY_NEW_DS_LOGIN = bytes.fromhex("0008 1e 0461 00 03") + b"254"


def test_login_and_pings():
    assert decode_tcp(LOGIN_254) == TeamNumber(254)
    assert TeamNumber(254).encode() == LOGIN_254
    assert decode_tcp(DS_PING) == DsPing(0x1C) and DsPing(0x1C).encode() == DS_PING
    assert decode_tcp(CHEESY_PING) == DsPing(0x1D) and DsPing(0x1D).encode() == CHEESY_PING
    assert DsPing().encode() == CHEESY_PING  # what a DS sends
    assert decode_tcp(b"\x00\x00") == KeepAlive()
    assert annotate_tcp(LOGIN_254)[1].meaning == "frame 0x18: team number, the login (first frame)"


def test_log_data():
    frame = decode_tcp(LOG_DATA)
    (rec,) = frame.records
    assert rec == LogRecord(trip_time_ms=10, lost_packets=2, battery=12.25, ds_teleop=True,
                            robot_teleop=True, can_utilization=20.5, signal_db=40.0, bandwidth=1.5)
    assert rec.status_byte == 0x24
    assert frame.encode() == LOG_DATA
    # Cheesy Arena's parseDsLogPacket reads the status byte at frame offset 7; the trip byte
    # at offset 3 is the round trip itself.
    assert LOG_DATA[7] == 0x24 and LOG_DATA[3] == rec.trip_time_ms
    spans = annotate_tcp(LOG_DATA)
    assert_tiles(spans, LOG_DATA)
    by_field = {s.field: s for s in spans}
    assert by_field["records[0].status"].meaning == "robot status: ds teleop, robot teleop"
    assert by_field["records[0].battery"].meaning == "battery: 12.250 V (12 + 64/256)"
    assert by_field["records[0].trip_time_ms"].value == 10
    assert "round trip" in by_field["records[0].trip_time_ms"].meaning


def test_open_ds_log_data_and_batched_records():
    (rec,) = decode_tcp(OPEN_DS_LOG_DATA).records
    assert rec.battery == 254 / 256 and rec.ds_teleop and rec.robot_teleop and not rec.ds_disabled
    assert decode_tcp(OPEN_DS_LOG_DATA).encode() == OPEN_DS_LOG_DATA
    every_bit = LogRecord(brownout=True, watchdog=True, ds_teleop=True, ds_auto=True, ds_disabled=True,
                          robot_teleop=True, robot_auto=True, robot_disabled=True)
    assert every_bit.status_byte == 0xFF
    two = LogData((rec, every_bit)).encode()
    assert two[:3] == bytes.fromhex("0013 16") and len(two) == 3 + 18
    assert decode_tcp(two) == LogData((rec, every_bit))
    assert decode_tcp(bytes.fromhex("0001 16")) == LogData(())


def test_usage_report_and_challenge_response():
    assert decode_tcp(USAGE_REPORT) == UsageReport(254, 0, b"\xab\xcd")
    assert UsageReport(254, 0, b"\xab\xcd").encode() == USAGE_REPORT
    assert decode_tcp(CHALLENGE_RESPONSE) == ChallengeResponse("R2-D2")
    assert ChallengeResponse(challenge_answer(254, 1000)).encode() == CHALLENGE_RESPONSE


def test_error_event_data():
    frame = decode_tcp(ERROR_EVENT)
    (entry,) = frame.entries
    assert entry == ErrorEvent(3818534400, 1 << 63, "Joystick unplugged")
    assert entry.to_datetime() == dt.datetime(2025, 1, 1, 0, 0, 0, 500000, tzinfo=dt.timezone.utc)
    assert ErrorEvent.at(dt.datetime(2025, 1, 1, 0, 0, 0, 500000), "Joystick unplugged") == entry
    assert frame.encode() == ERROR_EVENT
    spans = annotate_tcp(ERROR_EVENT)
    assert_tiles(spans, ERROR_EVENT)
    assert [s.field for s in spans] == ["size", "id", "count", "entries[0].seconds", "entries[0].fraction",
                                        "entries[0].text.length", "entries[0].text"]
    assert spans[3].meaning.endswith("2025-01-01 00:00:00+00:00")
    # Several entries (LabVIEW's array: count, then the elements) and none.
    many = ErrorEventData((entry, ErrorEvent(1, 0, ""), ErrorEvent(2, 3, "é")))
    assert decode_tcp(many.encode()) == many
    assert ErrorEventData().encode() == bytes.fromhex("0005 17 00000000")
    assert ErrorEvent(2**64 - 1, 0).to_datetime() is None


def test_versions_from_the_ds():
    frame = DeviceVersion(VersionDevice.DS, "", "21.0")
    data = frame.encode()
    assert data == bytes.fromhex("0007 02 00 04") + b"21.0"
    assert decode_tcp(data) == frame


def test_unknown_frames():
    frame = decode_tcp(bytes.fromhex("0002 40 01"))
    assert frame == UnknownFrame(0x40, b"\x01") and frame.encode() == bytes.fromhex("0002 40 01")
    assert "not documented" in annotate_tcp(bytes.fromhex("0002 40 01"))[1].meaning


def test_hello_tag_30_from_the_2027_ds():
    frame = decode_tcp(CHEESY_NEW_DS_LOGIN)
    assert frame == DsHello(1121, 0, "254") == DsHello.for_team(254)
    assert frame.team == 254 and frame.encode() == CHEESY_NEW_DS_LOGIN
    spans = annotate_tcp(CHEESY_NEW_DS_LOGIN)
    assert_tiles(spans, CHEESY_NEW_DS_LOGIN)
    assert [s.field for s in spans] == ["size", "id", "udp_port", "flags", "team_text.length", "team_text"]
    assert spans[1].value == "ds_hello" and "2027" in spans[1].meaning
    assert (spans[2].value, spans[5].value, spans[5].meaning) == (1121, "254", "team number in ASCII: 254")
    # A five-digit team and another reply port; the text is kept as it came ("0254" stays so).
    big = DsHello.for_team(25599, udp_port=5000, flags=0x80)
    assert big.encode() == bytes.fromhex("000a 1e 1388 80 05") + b"25599" and decode_tcp(big.encode()) == big
    padded = bytes.fromhex("0009 1e 0461 00 04") + b"0254"
    assert decode_tcp(padded).team == 254 and decode_tcp(padded).encode() == padded


def test_a_hello_that_names_no_team_decodes_and_says_so():
    for text in (b"", b"25a", b"123456", b"65536"):
        data = framed(0x1E, bytes.fromhex("0461 00") + bytes((len(text),)) + text)
        frame = decode_tcp(data)
        assert frame.team is None and frame.encode() == data
        assert "names no team" in annotate_tcp(data)[-1].meaning


@pytest.mark.parametrize("hexdata,field,offset", [
    ("0002 1e 04", "udp_port", 3),
    ("0003 1e 04 61", "flags", 5),
    ("0004 1e 0461 00", "team_text.length", 6),
    ("0008 1e 0461 00 04 323534", "team_text", 7),  # length says 4, 3 follow
    ("0009 1e 0461 00 03 323534 00", "end", 10),
])
def test_bad_hellos_name_field_and_offset(hexdata, field, offset):
    assert where(protocol_error(decode_tcp, bytes.fromhex(hexdata))) == ("DsToFmsFrame", field, offset)


@pytest.mark.parametrize("frame,field", [
    (DsHello(-1), "udp_port"), (DsHello(flags=256), "flags"), (DsHello(team_text=254), "team_text"),
    (DsHello(team_text="9" * 256), "team_text"),
])
def test_hello_encoding_refuses_bad_values(frame, field):
    assert where(protocol_error(frame.encode)) == ("DsToFmsFrame", field, None)
    assert where(protocol_error(DsHello.for_team, 65536)) == ("DsToFmsFrame", "team", None)


def test_a_ds_session_through_the_stream_decoder():
    stream = (LOGIN_254 + DeviceVersion(VersionDevice.DS, "", "21.0").encode() + LOG_DATA + DS_PING
              + b"\x00\x00" + ERROR_EVENT + CHALLENGE_RESPONSE + USAGE_REPORT + CHEESY_PING)
    frames = feed_bytewise(FrameDecoder("DsToFmsFrame"), stream)
    assert [type(decode_tcp(f)).__name__ for f in frames] == [
        "TeamNumber", "DeviceVersion", "LogData", "DsPing", "KeepAlive", "ErrorEventData",
        "ChallengeResponse", "UsageReport", "DsPing"]
    assert b"".join(decode_tcp(f).encode() for f in frames) == stream


@pytest.mark.parametrize("hexdata,field,offset", [
    ("0004 18 00fe", "size", 0),
    ("0002 18 00", "team", 3),
    ("0004 18 00fe 00", "end", 5),
    ("0002 1c 00", "end", 3),
    ("0002 1d 00", "end", 3),
    ("000b 16" + "00" * 10, "records", 3),
    ("0005 16 01 02 0c 40", "records", 3),
    ("0005 17 00000002", "count", 3),
    ("0004 17 000000", "count", 3),
    ("0019 17 00000001" + "00" * 16 + "00000005", "entries[0].text", 27),
    ("001a 17 00000001" + "00" * 16 + "00000000 00", "end", 27),
    ("0003 15 00fe", "unknown", 5),
])
def test_bad_frames_name_field_and_offset(hexdata, field, offset):
    assert where(protocol_error(decode_tcp, bytes.fromhex(hexdata))) == ("DsToFmsFrame", field, offset)


def test_frame_error_messages_read_well():
    assert str(protocol_error(decode_tcp, bytes.fromhex("000b 16" + "00" * 10))) == (
        "DsToFmsFrame.records at byte 3: 10 byte(s) is not a whole number of 9-byte log records")
    assert str(protocol_error(decode_tcp, bytes.fromhex("0019 17 00000002" + "00" * 20))) == (
        "DsToFmsFrame.count at byte 3: 2 entries cannot fit the 20 byte(s) left (each takes at least 20)")
    assert (str(protocol_error(LogData((LogRecord(trip_time_ms=0.3),)).encode))
            == "DsToFmsFrame.records[0].trip_time_ms: 0.3 is not an integer")


@pytest.mark.parametrize("frame,field", [
    (TeamNumber(65536), "team"),
    (TeamNumber(-1), "team"),
    (UsageReport(team=65536), "team"),
    (UsageReport(unknown=256), "unknown"),
    (UsageReport(entries="ab"), "entries"),
    (UsageReport(entries=b"x" * 0xFFFC), "size"),
    (LogData((LogRecord(trip_time_ms=0.3),)), "records[0].trip_time_ms"),
    (LogData((LogRecord(trip_time_ms=256),)), "records[0].trip_time_ms"),
    (LogData((LogRecord(), LogRecord(lost_packets=256))), "records[1].lost_packets"),
    (LogData((LogRecord(battery=300.0),)), "records[0].battery"),
    (LogData((LogRecord(can_utilization=-0.5),)), "records[0].can_utilization"),
    (LogData((LogRecord(signal_db=float("nan")),)), "records[0].signal_db"),
    (LogData((LogRecord(bandwidth=1 / 512),)), "records[0].bandwidth"),
    (LogData(("record",)), "records[0]"),
    (LogData((LogRecord(),) * 7282), "records"),
    (ErrorEventData((ErrorEvent(-1, 0, ""),)), "entries[0].seconds"),
    (ErrorEventData((ErrorEvent(0, 2**64, ""),)), "entries[0].fraction"),
    (ErrorEventData((ErrorEvent(0, 0, b"text"),)), "entries[0].text"),
    (ErrorEventData(("entry",)), "entries[0]"),
    (ErrorEventData((ErrorEvent(0, 0, "x" * 0xFFF0),)), "size"),
    (ChallengeResponse(5), "answer"),
    (ChallengeResponse("x" * 0xFFFF), "answer"),
    (DsPing(0x1E), "tag_id"),
    (UnknownFrame(256, b""), "tag_id"),
    (UnknownFrame(0x40, "data"), "data"),
])
def test_frame_encoding_refuses_bad_values(frame, field):
    assert where(protocol_error(frame.encode)) == ("DsToFmsFrame", field, None)


def test_kinds_are_registered():
    udp, tcp = kinds.get("ds-to-fms"), kinds.get("ds-to-fms-tcp")
    assert (udp.message, udp.tcp, tcp.message, tcp.tcp) == ("DsStatusPacket", False, "DsToFmsFrame", True)
    assert kinds.decode("ds-to-fms-tcp", LOGIN_254) == TeamNumber(254)
    assert kinds.annotate("ds-to-fms", STATUS_HEADER) == annotate_status(STATUS_HEADER)


# -- the challenge ------------------------------------------------------------------------------

def test_robot_names_are_the_notes_list():
    # PROTOCOL-NOTES "Challenge response", by index.
    assert len(ROBOT_NAMES) == 23
    assert ROBOT_NAMES[0] == "Johnny Five" and ROBOT_NAMES[8] == "The Terminator"
    assert ROBOT_NAMES[11] == "R2-D2" and ROBOT_NAMES[12] == "C-3PO" and ROBOT_NAMES[22] == "ASIMO"
    assert len(set(ROBOT_NAMES)) == 23


@pytest.mark.parametrize("team,random_value,answer", [
    (254, 1000, "R2-D2"),        # 254000 % 23 = 11
    (1114, 1234, "C-3PO"),       # 1374676 % 23 = 12
    (23, 1777, "Johnny Five"),   # a multiple of 23 is always index 0
    (1, 1011, "ASIMO"),          # 1011 = 43 * 23 + 22
])
def test_challenge_answer(team, random_value, answer):
    assert challenge_answer(team, random_value) == answer


def test_challenge_answer_reaches_every_name():
    answers = {challenge_answer(254, value) for value in range(1000, 2001)}
    assert answers == set(ROBOT_NAMES)


def test_check_challenge_answer():
    assert check_challenge_answer(254, 1000, "R2-D2")
    assert not check_challenge_answer(254, 1000, "r2-d2")
    assert not check_challenge_answer(254, 1000, "C-3PO")
    assert not check_challenge_answer(254, 1000, None)
    assert where(protocol_error(challenge_answer, -1, 1000))[:2] == ("ChallengeResponse", "team")


# -- properties -----------------------------------------------------------------------------

u8, u16 = st.integers(0, 0xFF), st.integers(0, 0xFFFF)
batteries = u16.map(lambda raw: raw / 256)
halves = u8.map(lambda raw: raw / 2)
_TAG_SIZES = {0: 3, 1: 5, 2: 2, 3: 3, 4: 0}
status_tags = st.one_of(
    st.builds(FieldRadioMetrics, u8, u16),
    st.builds(CommsMetrics, u16, u16, u8),
    st.builds(LaptopMetrics, u8, u8),
    st.builds(RobotRadioMetrics, u8, u16),
    st.just(PdInfo()),
    st.just(EmptyTag()),
    st.builds(UnknownTag, st.integers(5, 255), st.binary(max_size=30)),
    # a known id with the wrong payload size stays an UnknownTag
    st.tuples(st.integers(0, 4), st.binary(max_size=8)).filter(lambda t: len(t[1]) != _TAG_SIZES[t[0]])
      .map(lambda t: UnknownTag(*t)),
)
status_packets = st.builds(
    DsStatusPacket, u16, u8, st.booleans(), st.booleans(), st.booleans(), st.booleans(), st.booleans(),
    st.sampled_from(Mode), u16, batteries, st.lists(status_tags, max_size=8).map(tuple),
    st.sampled_from([0, 0x40]),
)


@given(status_packets)
def test_status_round_trip(packet):
    assert_round_trip(packet, decode_status, annotate_status)


@given(st.binary(max_size=120))
def test_random_bytes_give_a_packet_or_protocol_error(data):
    decode_or_protocol_error("ds-to-fms", data)


@given(status_packets, st.data())
def test_mutated_status_packets(packet, data):
    decode_or_protocol_error("ds-to-fms", mutate(packet.encode(), data.draw))


log_records = st.builds(LogRecord, u8, u8, batteries, *[st.booleans()] * 8, halves, halves, batteries)
text = st.text(max_size=40)
frames = st.one_of(
    st.just(KeepAlive()),
    st.builds(DeviceVersion, st.sampled_from(VersionDevice), st.one_of(st.none(), text), text),
    st.builds(UsageReport, u16, u8, st.binary(max_size=40)),
    st.builds(LogData, st.lists(log_records, max_size=6).map(tuple)),
    st.builds(ErrorEventData, st.lists(st.builds(ErrorEvent, st.integers(0, 2**64 - 1),
                                                 st.integers(0, 2**64 - 1), text), max_size=4).map(tuple)),
    st.builds(TeamNumber, u16),
    st.builds(ChallengeResponse, text),
    st.builds(DsPing, st.sampled_from([0x1C, 0x1D])),
    st.builds(DsHello, u16, u8, st.one_of(st.integers(0, 0xFFFF).map(str), text)),
    st.builds(UnknownFrame, u8.filter(lambda i: i > 7 and i not in (0x15, 0x16, 0x17, 0x18, 0x1B, 0x1C, 0x1D, 0x1E)),
              st.binary(max_size=60)),
)


@given(frames)
def test_tcp_round_trip(frame):
    assert_round_trip(frame, decode_tcp, annotate_tcp)


@given(st.datetimes(min_value=dt.datetime(1904, 1, 1), max_value=dt.datetime(9998, 12, 31),
                    timezones=st.just(dt.timezone.utc)), text)
def test_error_event_timestamps_round_trip(when, message):
    entry = ErrorEvent.at(when, message)
    assert entry.to_datetime() == when
    assert decode_tcp(ErrorEventData((entry,)).encode()).entries == (entry,)


FRAME_IDS = st.one_of(st.sampled_from([0, 2, 7, 0x15, 0x16, 0x17, 0x18, 0x1B, 0x1C, 0x1D, 0x1E]), u8)


@given(FRAME_IDS, st.binary(max_size=80))
def test_random_tcp_payloads(tag_id, payload):
    decode_or_protocol_error("ds-to-fms-tcp", framed(tag_id, payload))


@given(st.binary(max_size=80))
def test_random_tcp_bytes(data):
    decode_or_protocol_error("ds-to-fms-tcp", data)


@given(frames, st.data())
def test_mutated_tcp_frames(frame, data):
    check_mutated_frame("ds-to-fms-tcp", frame, data.draw)


@given(st.lists(st.binary(min_size=9, max_size=9), max_size=40))
def test_log_records_decode_alike_with_and_without_the_inspectors_spans(records):
    # Decoding alone reads each 9-byte record with one struct (a 16 KiB frame holds 1,800);
    # the inspector's walk names every field. Both must say the same.
    frame = framed(0x16, b"".join(records))
    assert decode_tcp(frame) == kinds.get("ds-to-fms-tcp").walk(Reader(frame, "DsToFmsFrame", annotate=True))
