"""``fieldbox decode`` and the fast ``--help`` / ``--version``."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

# One whole packet per kind. Sources: the seed tables (ds_to_rio.rst, rio_to_ds.rst,
# fms_to_ds.rst), PROTOCOL-NOTES ("Driver Station -> FMS"), and for the 2010 kinds the
# packets our own encoder builds at the seed's offsets (checked byte by byte in
# tests/protocol/test_legacy.py).
VECTORS = {
    # control: enabled teleop, station R1, one joystick (allwpilib DSCommPacketTest MainJoystickTag)
    "ds-to-rio": "0001 01 04 10 00 10 0c 04 9c ce 00 4b 0c 0a b2 03 0032 0064 0f00",
    # status: echo, robot code + is roboRIO + teleop, 12.5 V, one idle joystick output tag
    "rio-to-ds": "0001 01 04 32 0c80 00 01 01",
    "ds-to-rio-tcp": "0005 0e 57434243",  # game data "WCBC"
    "rio-to-ds-tcp": "000a 0c 3f800000 0001 686921",  # stdout "hi!" at t=1.0 s, seq 1
    # FMS control: enabled auto, station B1, qualification 12, remaining 15 s
    "fms-to-ds": "0001 00 06 00 03 02 000c 01 00000000 00 00 00 01 00 7e 000f",
    "ds-to-fms": "0001 00 24 00fe 0c80",  # comms + enabled teleop, team 254, 12.5 V
    "fms-to-ds-tcp": "0003 19 00 00",  # station info: R1, good
    "ds-to-fms-tcp": "0003 18 00fe",  # team number 254: the login
}


# Issue 18's layouts. A real roboRIO's status with its CPU tag (u8 count 2), the 2021
# capture's frame 55 (../shared/captures/ni-ds-roborio-2021.pcapng); LibDS's control packet
# with a joystick size one too big (src/protocols/frc_2015.c get_joystick_size).
REAL_CPU = ("0b6b 01 00 31 0c3a 00 22 05 02 423600b4 00000000 00000000 410d2aed"
            " 41e5c037 00000000 00000000 411d0e89")
LIBDS_2015 = "0010 01 04 80 00 0d 0c 04 00000000 0c 0001 01 ffff"


def test_new_layouts_decode_with_every_byte_explained():
    out = json.loads(run("decode", "--as", "rio-to-ds", "--json", REAL_CPU).stdout)
    spans = {s["field"]: s for s in out["spans"]}
    assert spans["tags[0].cpu_count"]["length"] == 1 and spans["tags[0].cpu_count"]["value"] == 2
    assert sum(s["length"] for s in out["spans"]) == len(bytes.fromhex(REAL_CPU.replace(" ", "")))
    result = run("decode", "--as", "ds-to-rio", "--json", LIBDS_2015)
    assert result.returncode == 0, result.stderr  # the header holds: it decodes
    out = json.loads(result.stdout)
    assert out["fields"]["enabled"] and out["fields"]["tags"][0]["type"] == "MalformedTag"
    assert out["spans"][-1]["field"] == "tags[0].malformed" and "MALFORMED" in out["spans"][-1]["meaning"]


def run(*args, stdin: str | None = None) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "fieldbox", *args], cwd=ROOT, input=stdin,
                          capture_output=True, text=True, timeout=60)


@pytest.mark.parametrize("kind", sorted(VECTORS))
def test_every_kind_decodes_to_json_with_spans_covering_every_byte(kind):
    result = run("decode", "--as", kind, "--json", VECTORS[kind])
    assert result.returncode == 0, result.stderr
    obj = json.loads(result.stdout)
    assert obj["kind"] == kind
    data = bytes.fromhex(VECTORS[kind].replace(" ", ""))
    covered = sorted((s["offset"], s["length"]) for s in obj["spans"])
    pos = 0
    for offset, length in covered:
        assert offset == pos
        pos += length
    assert pos == len(data)
    assert all(set(s) == {"offset", "length", "field", "value", "meaning"} for s in obj["spans"])
    assert isinstance(obj["fields"], dict) and obj["fields"]["type"]


def test_fields_are_nested_and_named():
    obj = json.loads(run("decode", "--as", "ds-to-rio", "--json", VECTORS["ds-to-rio"]).stdout)
    f = obj["fields"]
    assert (f["sequence"], f["enabled"], f["mode"], f["station"]) == (1, True, "TELEOP", "RED1")
    assert f["tags"][0]["axes"] == [-100, -50, 0, 75]
    fms = json.loads(run("decode", "--as", "fms-to-ds", "--json", VECTORS["fms-to-ds"]).stdout)["fields"]
    assert (fms["mode"], fms["station"], fms["match_number"], fms["remaining_seconds"]) == ("AUTONOMOUS", "BLUE1", 12, 15)


def test_legacy_kinds_round_trip_through_the_command():
    from protocol.enums import AllianceStation
    from protocol.legacy import LegacyControlPacket, LegacyDashboardPacket, LegacyStatusPacket

    for kind, packet in (("legacy-ds-to-robot", LegacyControlPacket(packet_index=5, enabled=True, team=294,
                                                                     station=AllianceStation.RED1)),
                         ("legacy-robot-to-ds", LegacyStatusPacket(team=294, lcd=("hello",))),
                         ("legacy-dashboard", LegacyDashboardPacket(team=294))):
        result = run("decode", "--as", kind, "--json", packet.encode().hex())
        assert result.returncode == 0, result.stderr
        assert json.loads(result.stdout)["fields"]["team"] == 294


def test_table_output_and_stdin():
    result = run("decode", "--as", "ds-to-rio", "-", stdin=VECTORS["ds-to-rio"] + "\n")
    assert result.returncode == 0
    assert "tags[0].buttons" in result.stdout and "down: 2, 5, 6, 8, 10, 12" in result.stdout


@pytest.mark.parametrize("args,message", [
    (("--as", "ds-to-rio", "0001 01 04 10 07"), "ControlPacket.station at byte 5: 7 is not an alliance station"),
    (("--as", "ds-to-rio", "0001 01"), "ControlPacket.control at byte 3: needs 1 byte, 0 left"),
    (("--as", "ds-to-rio-tcp", "0009 0e 41"), "DsToRioFrame.size at byte 0"),
    (("--as", "ds-to-rio", "zz"), "not a hex digit: 'z' at character 0"),
    (("--as", "ds-to-rio", "abc"), "odd number of hex digits"),
])
def test_bad_input_is_one_line_naming_field_and_offset(args, message):
    result = run("decode", *args)
    assert result.returncode == 1
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and message in lines[0], result.stderr
    assert result.stdout == ""


def test_help_and_version_import_nothing_heavy():
    code = ("import sys\nfrom fieldbox.cli import build_parser\n"
            "try:\n    build_parser().parse_args(['--help'])\nexcept SystemExit:\n    pass\n"
            "print(sorted(m for m in ('textual', 'rich', 'pygame', 'roles', 'protocol') if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, timeout=30)
    assert out.stdout.strip().splitlines()[-1] == "[]"
    version = run("--version")
    assert version.returncode == 0 and version.stdout.startswith("fieldbox ")


def test_values_out_of_range_are_warnings_in_the_text_and_the_json():
    # issue 20: allwpilib's own test vector (MainJoystickTag, above) ends in POV 0x0f00 = 3840
    # degrees, which a real DS never sends; it decodes, with a warning
    result = run("decode", "--as", "ds-to-rio", VECTORS["ds-to-rio"])
    assert result.returncode == 0
    assert "warning: byte 21 (tags[0].povs[2]): 3840 is out of range (0..359 degrees" in result.stdout
    obj = json.loads(run("decode", "--as", "ds-to-rio", "--json", VECTORS["ds-to-rio"]).stdout)
    assert obj["warnings"] == [{"offset": 21, "field": "tags[0].povs[2]", "value": 3840,
                                "warning": "3840 is out of range (0..359 degrees, or -1 when centred)"}]
    # a status packet claiming 40.5 V (0x28 0x80): decoded, and flagged
    result = run("decode", "--as", "rio-to-ds", "0001 01 00 31 2880 00")
    assert "warning: byte 5 (battery): 40.5 is out of range (a robot battery reads 0..30 V)" in result.stdout
    assert json.loads(run("decode", "--as", "rio-to-ds", "--json", VECTORS["rio-to-ds"]).stdout)["warnings"] == []


def test_a_2010_battery_in_bcd_is_not_judged_as_volts_byte_by_byte():
    # the 2010 cRIO sends its battery as two BCD bytes (0x12 0x60 for 12.60 V; 0x37 0x37 with no
    # code): neither byte is a voltage, so neither is out of a battery's range
    from protocol.legacy import LegacyDashboardPacket, LegacyStatusPacket
    from protocol.legacy_common import NO_CODE_BATTERY, volts_to_bcd

    for kind, packet in (("legacy-robot-to-ds", LegacyStatusPacket(team=294, battery=volts_to_bcd(12.6))),
                         ("legacy-robot-to-ds", LegacyStatusPacket(team=294, battery=NO_CODE_BATTERY)),
                         ("legacy-dashboard", LegacyDashboardPacket(team=294, battery=volts_to_bcd(12.6)))):
        result = run("decode", "--as", kind, "--json", packet.encode().hex())
        assert result.returncode == 0, result.stderr
        assert json.loads(result.stdout)["warnings"] == [], kind


def test_floats_are_printed_as_a_person_reads_them_and_exact_in_json():
    packet = "0001 01 04 10 00 05 07 41c4a000"  # countdown tag: f32 0x41c4a000 = 24.578125 s
    table = run("decode", "--as", "ds-to-rio", packet).stdout
    assert "24.58" in table and "24.578125" not in table
    [span] = [s for s in json.loads(run("decode", "--as", "ds-to-rio", "--json", packet).stdout)["spans"]
              if s["field"] == "tags[0].seconds"]
    assert span["value"] == 24.578125


# -- issue 27: input bounded before it is read, big packets explained in linear time --------------
def test_input_longer_than_any_packet_is_refused_without_reading_the_rest():
    # 1 MB of hex took over two minutes and 1.9 GB. Now stdin is read only as far as a packet
    # can be spelled: the command answers while the writer is still writing, never at EOF.
    proc = subprocess.Popen([sys.executable, "-m", "fieldbox", "decode", "--as", "ds-to-rio", "-"], cwd=ROOT,
                            stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)

    def write() -> None:
        try:
            for _ in range(10_000):  # 10 MB, never closed while the command runs
                proc.stdin.write("00" * 512)
                proc.stdin.flush()
        except (BrokenPipeError, OSError, ValueError):
            pass

    import threading
    writer = threading.Thread(target=write, daemon=True)
    writer.start()
    try:
        assert proc.wait(60) == 1  # a hang guard, not a timing limit: it must not wait for EOF
    finally:
        proc.kill()
    err = proc.stderr.read()
    assert "more than 524,296 characters of input: no packet is longer than 65,537 bytes" in err
    assert proc.stdout.read() == ""


def test_more_bytes_than_any_packet_is_one_line():
    result = run("decode", "--as", "ds-to-rio-tcp", "-", stdin="00" * 65_538)
    assert result.returncode == 1 and result.stdout == ""
    assert result.stderr.strip() == "fieldbox decode: 65,538 bytes: no packet is longer than 65,537 bytes"


def test_a_maximum_size_datagram_is_refused_by_its_size():
    result = run("decode", "--as", "ds-to-rio", "-", stdin="00" * 65_507)
    assert result.returncode == 1 and result.stdout == ""
    assert result.stderr.strip() == ("fieldbox decode: ControlPacket.size at byte 1024: 65507 bytes is over the "
                                     "1024-byte bound of a control packet (a real DS's is at most 550 bytes): "
                                     "not decoded")


def test_a_big_legal_frame_prints_every_field_one_line_each():
    # A 16 KiB log-data frame (the FMS's bound) has 12,742 fields: as a drawn table it took
    # seven seconds, as plain columns a line each.
    records = bytes.fromhex("0a 02 0c80 24 10 50 0100") * 1820
    frame = (len(records) + 1).to_bytes(2, "big") + b"\x16" + records
    result = run("decode", "--as", "ds-to-fms-tcp", "-", stdin=frame.hex())
    assert result.returncode == 0, result.stderr
    lines = result.stdout.splitlines()
    assert lines[0] == ("DS -> FMS, TCP 1750: LogData, 16383 bytes (12,742 fields, as plain columns; "
                        "--json gives every value whole)")
    assert len(lines) == 2 + 12_742
    assert lines[-1].split() == ["16381", "01", "00", "records[1819].bandwidth", "1", "bandwidth:", "1.000",
                                 "Mbit/s", "(u16", "/", "256)"]
    # 500 error events whose text holds a newline: each stays on its row, escaped
    entry = bytes(16) + (3).to_bytes(4, "big") + b"a\nb"
    payload = (500).to_bytes(4, "big") + entry * 500
    frame = (len(payload) + 1).to_bytes(2, "big") + b"\x17" + payload
    result = run("decode", "--as", "ds-to-fms-tcp", "-", stdin=frame.hex())
    assert result.returncode == 0, result.stderr
    lines = result.stdout.splitlines()
    assert len(lines) == 2 + 3 + 500 * 4  # size, id, count; four fields an event
    assert lines[-1].split()[:4] == ["11504", "61", "0a", "62"] and "a\\nb" in lines[-1]


def test_several_lines_are_several_packets_never_one_joined():
    # Issue 30: two pasted lines were joined into one packet without a word
    first, second = "0001 01 04 10 00", "0002 01 00 10 03"
    result = run("decode", "--as", "ds-to-rio", "--json", "-", stdin=f"{first}\n\n{second}\n")
    assert result.returncode == 0, result.stderr
    objects = [json.loads(line) for line in result.stdout.splitlines()]
    assert [(o["line"], o["length"], o["fields"]["sequence"]) for o in objects] == [(1, 6, 1), (3, 6, 2)]
    table = run("decode", "--as", "ds-to-rio", "-", stdin=f"{first}\n{second}\n")
    assert table.returncode == 0 and "line 1:" in table.stdout and "line 2:" in table.stdout
    assert table.stdout.count("6 bytes") == 2
    # a packet wrapped over two lines is two packets that do not decode, and says so
    wrapped = run("decode", "--as", "ds-to-rio", "-", stdin="0001 01\n04 10 00\n")
    assert wrapped.returncode == 1
    assert "line 1: ControlPacket.control at byte 3" in wrapped.stderr
    assert "2 of 2 lines did not decode (one packet a line: join a packet wrapped over lines first)" in wrapped.stderr


# The 2027 FIRST DS hello (Cheesy Arena, field/driver_station_connection.go at commit
# 1612d071; docs/protocol.md#cheesy-2027): tag 30 from the DS, tag 31 from the FMS, and game
# data as control packet tag 32.
HELLO_2027 = {
    "ds-to-fms-tcp": ("0008 1e 0461 00 03 323534", "DsHello", "team_text", "254"),
    "fms-to-ds-tcp": ("0006 1f 03 00 01 00fe", "HelloReply", "flags", "0x01"),
    "fms-to-ds": ("0001 00 06 00 03 02 000c 01 00000000 00 00 00 01 00 7e 000f 04 20 4c524c",
                  "FmsControlPacket", "tags[0].text", "LRL"),
}


@pytest.mark.parametrize("kind", sorted(HELLO_2027))
def test_decode_knows_the_2027_hello_tags(kind):
    hexdata, message, field, value = HELLO_2027[kind]
    out = json.loads(run("decode", "--as", kind, "--json", hexdata).stdout)
    spans = {s["field"]: s for s in out["spans"]}
    assert out["fields"]["type"] == message and spans[field]["value"] == value
    assert sum(s["length"] for s in out["spans"]) == len(bytes.fromhex(hexdata.replace(" ", "")))
    text = run("decode", "--as", kind, hexdata).stdout
    assert message in text and "2027" in text
