"""roboRIO -> DS: the UDP status packet and the TCP 1740 frames."""

from __future__ import annotations

import math
import struct

import pytest
from hypothesis import given
from hypothesis import strategies as st

from protocol import kinds
from protocol.enums import DeviceType, Mode
from protocol.rio_to_ds import (
    END_OF_VERSION_LIST, IDLE_JOYSTICK_OUTPUT, CanMetrics, CpuInfo, CpuLoad, DisableFaults, DiskInfo,
    ErrorMessage, JoystickOutput, KeepAlive, PdpLog, RadioEvents, RailFaults, RamInfo, StatusPacket,
    StdoutMessage, Unknown0d, Unknown09, UnknownFrame, UsageReport, VersionInfo, annotate_status,
    annotate_tcp, battery_to_raw, decode_status, decode_tcp, raw_to_battery, walk_status,
)
from protocol.rio_to_ds import _fast_status
from protocol.wire import Reader, UnknownTag

from .util import (assert_round_trip, assert_tiles, decode_or_protocol_error, framed, outcome, protocol_error,
                   where, with_size_repaired)

# -- golden vectors: real captures ------------------------------------------------------

# WPILib's simulator (robotpy 2026.2.2, halsim_ds_socket), captured by a teammate's probe:
# /work/interop/captures/probe_run.json, phase "enabled_teleop". The robot program had set
# outputs 0x12345678, LEFT rumble 0.25 and RIGHT rumble 0.75 (/work/interop/robot.py
# teleopInit). Status 0x04 (enabled teleop, echoed), trace 0x20 (robot code), battery 0x0c00
# (12.0 V), request 0x00, then six 9-byte joystick output tags: the simulator never sends the
# idle `01 01` form.
SIM_TELEOP = bytes.fromhex(
    "008a 01 04 20 0c00 00"
    "09 01 12345678 bfff 3fff"
    + "09 01 00000000 0000 0000" * 5)

# Same capture, phase "enabled_auto_matchtime15": outputs 0x00000001, left rumble 1.0, right
# 0.0 (robot.py autonomousInit). Status 0x06: enabled, autonomous.
SIM_AUTO = bytes.fromhex(
    "00ee 01 06 20 0c00 00"
    "09 01 00000001 0000 ffff"
    + "09 01 00000000 0000 0000" * 5)

# -- golden vectors: seed tables --------------------------------------------------------

# rio_to_ds.rst "Joystick Output": "if the 3rd joystick is outputting, it'll output
# `01 01 01 01 09 01 <below structure>`". Header: sequence 0x0102, comm version 1, status
# 0x80|0x10|0x08|0x04|2 (e-stop, brownout, code initializing, enabled, autonomous),
# trace 0x20|0x10|0x04 (robot code, roboRIO, auto), battery 12.5 V (0x0c80), request 0x01.
SEED_HEADER = bytes.fromhex("0102 01 9e 34 0c80 01")
SEED_THIRD_STICK = bytes.fromhex("01 01" "01 01" "09 01 80000003 1234 abcd")

# rio_to_ds.rst "Disk Info" (u32 free), "CPU Info" (f32 count 2.0, then four f32 per CPU:
# the seed's form, which no real roboRIO sends; see REAL_CPU below),
# "RAM Info" (u32 block, u32 free), "CAN Metrics" (f32 util, u32 bus off, u32 tx full, u8
# rx errors, u8 tx errors), "Unknown 0x09" (9 bytes).
SEED_DISK = bytes.fromhex("05 04 075bcd15")  # 123456789 bytes free
SEED_CPU = bytes.fromhex("25 05 40000000"
                         "3fc00000 40200000 41f00000 40800000"  # 1.5 2.5 30 4
                         "3f000000 3f800000 41a00000 40400000")  # 0.5 1 20 3
SEED_RAM = bytes.fromhex("09 06 00001000 0bebc200")  # block 4096, 200 000 000 free
SEED_CAN = bytes.fromhex("0f 0e 41480000 00000001 00000002 03 04")  # 12.5 %
SEED_UNKNOWN_09 = bytes.fromhex("0a 09 010203040506070809")

# rio_to_ds.rst "PDP Log": 1 unknown byte, 21 bytes of sixteen 10-bit currents, 3 unknown.
# Channel 0 = 8 (1.0 A), channel 6 = 1023, channel 15 = 1023, pad2 = 0xa, the rest 0:
#   u64 #1: 8 << 54 = 02 00 00 00 00 00 00 00
#   u64 #2: 1023 << 54 | 0xa = ff c0 00 00 00 00 00 0a
#   40-bit: 1023 = 00 00 00 03 ff
SEED_PDP = bytes.fromhex("1a 08 07" "0200000000000000" "ffc000000000000a" "00000003ff" "112233")

# -- golden vectors: a real roboRIO ------------------------------------------------------
# ../shared/captures/ni-ds-roborio-2021.pcapng (roboRIO image 2020_v10), roboRIO -> DS on
# UDP 1150. Frame 55: header, then the CPU tag with a u8 count of 2 and 2 x 16 bytes
# (PROTOCOL-NOTES "Corrections": the seed's f32 count is wrong).
REAL_CPU_STATUS = bytes.fromhex(
    "0b6b 01 00 31 0c3a 00"
    "22 05 02" "423600b4 00000000 00000000 410d2aed" "41e5c037 00000000 00000000 411d0e89")
# Frame 69: disk info in its 8-byte form (u32 block 0, u32 free 139 214 848).
REAL_DISK_STATUS = bytes.fromhex("0b70 01 00 31 0c36 00" "09 04 00000000 084c4000")
# Frame 12: CAN metrics, 15 bytes: utilisation 0.0, bus off 0, tx full 1, rx errors 0, tx
# errors 128.
REAL_CAN_STATUS = bytes.fromhex("0b56 01 00 31 0c35 00" "0f 0e 00000000 00000000 00000001 00 80")

# Seed "Version Info": the empty message marks the end of the list.
VERSION_END = bytes.fromhex("0007 0a 00 0000 00 00 00")
# Seed "Version Info": type 8 (PDP), 2 unknown bytes, id 0, name "PDP", version "1.40".
VERSION_PDP = bytes.fromhex("000e 0a 08 0000 00 03") + b"PDP" + b"\x04" + b"1.40"
# Seed "Unknown 0x0d": 00 00 04 04 04 04.
UNKNOWN_0D = bytes.fromhex("0007 0d 000004040404")
# Seed "Standard Output": f32 timestamp 10.0, u16 sequence 7, text.
STDOUT = bytes.fromhex("000c 0c 41200000 0007") + b"hello"
# PROTOCOL-NOTES "How a real roboRIO ... behaves": f32 timestamp 1.5, u16 sequence 8, u16
# occurrences 1, i32 error code 1234, flags 0x01 (error), details "bad", location "x.py",
# empty call stack. (WPILib's simulator sends no TCP frames: the probe's tcp_rx was empty.)
ERROR = bytes.fromhex("001b 0b 3fc00000 0008 0001 000004d2 01 0003") + b"bad" + b"\x00\x04x.py" + b"\x00\x00"
# The same layout, a LabVIEW warning with error code -44009 (0xffff5417).
WARNING_LV = bytes.fromhex("0014 0b 00000000 0009 0002 ffff5417 02 0000 0000 0000")
# Seed "Radio Events?" sample text.
RADIO = b"Warning <Code> 44008 <radioLostEvents> 16.008 <radioSeenEvents> 14.507\n"
RADIO_FRAME = (len(RADIO) + 1).to_bytes(2, "big") + b"\x00" + RADIO
# Seed "Usage Report": team 2 bytes, u8 unknown, entries (kept raw).
USAGE = bytes.fromhex("0009 01 0d05 00") + b"C3>I1"
# Seed "Disable Faults" (comms 3, 12 V 1) and "Rail Faults" (6 V 1, 5 V 2, 3.3 V 3).
DISABLE_FAULTS = bytes.fromhex("0005 04 0003 0001")
RAIL_FAULTS = bytes.fromhex("0007 05 0001 0002 0003")


def test_simulator_capture_teleop():
    p = decode_status(SIM_TELEOP)
    assert (p.sequence, p.comm_version, p.enabled, p.mode, p.estop) == (0x8A, 1, True, Mode.TELEOP, False)
    assert (p.robot_code, p.is_roborio, p.user_teleop, p.user_disabled) == (True, False, False, False)
    assert p.battery == 12.0 and p.battery_raw == 0x0C00 and not p.request_date
    outs = p.joystick_outputs
    assert len(outs) == 6 and len(p.tags) == 6
    # right 0.75 -> 0xbfff comes FIRST, left 0.25 -> 0x3fff second: the simulator's order.
    assert outs[0] == JoystickOutput(outputs=0x12345678, right_rumble=0xBFFF, left_rumble=0x3FFF)
    assert outs[0].output(4) and not outs[0].output(1)
    assert all(o == JoystickOutput() for o in outs[1:])
    assert p.encode() == SIM_TELEOP


def test_simulator_capture_auto():
    p = decode_status(SIM_AUTO)
    assert p.mode is Mode.AUTONOMOUS and p.enabled and p.status_byte == 0x06
    assert p.joystick_outputs[0] == JoystickOutput(1, right_rumble=0, left_rumble=0xFFFF)
    assert p.joystick_outputs[0].output(1)
    assert p.encode() == SIM_AUTO


def test_seed_header_and_idle_slots():
    data = SEED_HEADER + SEED_THIRD_STICK
    p = decode_status(data)
    assert (p.sequence, p.estop, p.brownout, p.code_initializing, p.enabled, p.mode) == \
        (0x0102, True, True, True, True, Mode.AUTONOMOUS)
    assert (p.robot_code, p.is_roborio, p.user_test, p.user_auto, p.user_teleop, p.user_disabled) == \
        (True, True, False, True, False, False)
    assert p.battery == 12.5 and p.request_date
    assert p.tags == (IDLE_JOYSTICK_OUTPUT, IDLE_JOYSTICK_OUTPUT,
                      JoystickOutput(0x80000003, right_rumble=0x1234, left_rumble=0xABCD))
    assert p.tags[0].idle and not p.tags[2].idle
    assert p.tags[2].output(32) and p.tags[2].output(1) and p.tags[2].output(2) and not p.tags[2].output(3)
    assert p.encode() == data
    assert StatusPacket(tags=(IDLE_JOYSTICK_OUTPUT,)).encode()[8:] == b"\x01\x01"


def test_seed_metric_tags():
    data = SEED_HEADER + SEED_DISK + SEED_CPU + SEED_RAM + SEED_CAN + SEED_UNKNOWN_09
    p = decode_status(data)
    disk, cpu, ram, can, unk = p.tags
    assert disk == DiskInfo(123456789)
    assert cpu == CpuInfo((CpuLoad(1.5, 2.5, 30.0, 4.0), CpuLoad(0.5, 1.0, 20.0, 3.0)), f32_count=True)
    assert ram == RamInfo(4096, 200_000_000)
    assert can == CanMetrics(12.5, 1, 2, 3, 4)
    assert unk == Unknown09(bytes(range(1, 10)))
    assert p.encode() == data


def test_disk_info_in_its_8_byte_form():
    # open-ds and the jcreigh Wireshark dissector read disk info as u32 block + u32 free.
    data = SEED_HEADER + bytes.fromhex("09 04 00001000 075bcd15")
    p = decode_status(data)
    assert p.tags == (DiskInfo(free_bytes=123456789, block=4096),)
    assert p.encode() == data
    # ... and so does a real roboRIO send it (REAL_DISK_STATUS, the capture's frame 69)
    assert decode_status(REAL_DISK_STATUS).tags == (DiskInfo(free_bytes=0x084C4000, block=0),)


def test_real_roborio_cpu_tag_has_a_u8_count():
    # REAL_CPU_STATUS: a real roboRIO's CPU tag (capture frame 55), u8 count 2.
    p = decode_status(REAL_CPU_STATUS)
    (cpu,) = p.tags
    assert type(cpu) is CpuInfo and not cpu.f32_count and len(cpu.cpus) == 2
    assert cpu.cpus[0].time_critical == struct.unpack(">f", bytes.fromhex("423600b4"))[0]  # 45.5 %
    assert cpu.cpus[1].low == struct.unpack(">f", bytes.fromhex("411d0e89"))[0]
    assert p.encode() == REAL_CPU_STATUS
    assert _fast_status(REAL_CPU_STATUS) == walk_status(Reader(REAL_CPU_STATUS, "StatusPacket"))
    # encoding writes the real form unless asked for the seed's
    assert CpuInfo(cpu.cpus) == cpu
    assert StatusPacket(tags=(CpuInfo((CpuLoad(),) * 2),)).encode()[8:11] == bytes.fromhex("22 05 02")
    assert StatusPacket(tags=(CpuInfo((CpuLoad(),) * 2, f32_count=True),)).encode()[8:14] == \
        bytes.fromhex("25 05 40000000")
    spans = {s.field: s for s in annotate_status(REAL_CPU_STATUS)}
    assert spans["tags[0].cpu_count"].length == 1 and spans["tags[0].cpu_count"].value == 2


def test_real_can_metrics():
    # REAL_CAN_STATUS: the capture's frame 12.
    assert decode_status(REAL_CAN_STATUS).tags == (CanMetrics(0.0, 0, 1, 0, 128),)
    assert decode_status(REAL_CAN_STATUS).encode() == REAL_CAN_STATUS


def _pdp_bits(currents, pad1, pad2):
    """An independent packing: channels as 10-bit MSB-first strings, pads after 6 and 12."""
    bits = "".join(f"{c:010b}" for c in currents[:6]) + f"{pad1:04b}"
    bits += "".join(f"{c:010b}" for c in currents[6:12]) + f"{pad2:04b}"
    bits += "".join(f"{c:010b}" for c in currents[12:])
    assert len(bits) == 168
    return int(bits, 2).to_bytes(21, "big")


def test_pdp_log_unpacks_sixteen_currents():
    p = decode_status(SEED_HEADER + SEED_PDP)
    (pdp,) = p.tags
    expected = [0] * 16
    expected[0], expected[6], expected[15] = 8, 1023, 1023
    assert pdp == PdpLog(tuple(expected), 7, bytes.fromhex("112233"), 0, 0xA)
    assert pdp.amps[0] == 1.0 and pdp.amps[15] == 1023 / 8
    assert _pdp_bits(expected, 0, 0xA) == SEED_PDP[3:24]
    assert p.encode() == SEED_HEADER + SEED_PDP


@given(st.lists(st.integers(0, 1023), min_size=16, max_size=16), st.integers(0, 15), st.integers(0, 15))
def test_pdp_packing_matches_an_independent_bit_string(currents, pad1, pad2):
    tag = PdpLog(tuple(currents), 0, b"\0\0\0", pad1, pad2)
    data = StatusPacket(tags=(tag,)).encode()
    assert data[8:11] == b"\x1a\x08\x00" and data[11:32] == _pdp_bits(currents, pad1, pad2)
    assert decode_status(data).tags == (tag,)


def test_battery_helpers():
    assert battery_to_raw(12.0) == 0x0C00 and battery_to_raw(12.5) == 0x0C80
    assert battery_to_raw(12.34) == 3159 and raw_to_battery(3159) == 3159 / 256
    assert battery_to_raw(255.999) == 0xFFFF and battery_to_raw(0) == 0
    for raw in (0, 1, 0x0C80, 0xFFFF):
        assert battery_to_raw(raw_to_battery(raw)) == raw
    for bad in (-0.01, 256.0, float("nan"), float("inf"), "12", True, None):
        assert protocol_error(battery_to_raw, bad).field == "battery"
    protocol_error(raw_to_battery, 0x10000)
    # Encoding rounds to the nearest 1/256 V; decoding gives it back exactly.
    assert decode_status(StatusPacket(battery=12.34).encode()).battery == 3159 / 256


def test_undocumented_bits_are_kept():
    data = bytes.fromhex("0000 01 60 c0 0000 fe")
    p = decode_status(data)
    assert (p.status_other, p.trace_other, p.request_other, p.request_date) == (0x60, 0xC0, 0xFE, False)
    assert p.encode() == data


def test_unknown_tag_is_kept_raw():
    data = SEED_HEADER + bytes.fromhex("03 42 beef") + bytes.fromhex("01 77")
    p = decode_status(data)
    assert p.tags == (UnknownTag(0x42, b"\xbe\xef"), UnknownTag(0x77, b""))
    assert p.encode() == data


@pytest.mark.parametrize("hexdata,field,offset", [
    ("", "sequence", 0),
    ("0001 01 04 20", "battery", 5),
    ("0001 01 04 20 0c00", "request_date", 7),
    ("0001 01 04 20 0c00 00 00", "tags[0].size", 8),
    ("0001 01 04 20 0c00 00 05 01", "tags[0]", 9),
    ("0001 01 04 20 0c00 00 05 01 00000000 06", "tags[1]", 15),
])
def test_bad_packets_name_field_and_offset(hexdata, field, offset):
    assert where(protocol_error(decode_status, bytes.fromhex(hexdata))) == ("StatusPacket", field, offset)


# Whole tags (their size fits the packet) whose inside is not laid out as documented: kept
# raw, so a real roboRIO's variant of a tag never costs the DS its status packet. The
# annotation says why the bytes were kept raw.
@pytest.mark.parametrize("hexdata,reason", [
    ("0001 01 04 20 0c00 00 05 01 00000000", "right_rumble"),
    ("0001 01 04 20 0c00 00 06 04 0000000000", "unexpected trailing byte"),
    ("0001 01 04 20 0c00 00 05 05 40400000", "3.0 is not the 0 CPU(s) this tag holds"),
    ("0001 01 04 20 0c00 00 05 05 3fc00000", "is not the 0 CPU(s)"),
    ("0001 01 04 20 0c00 00 05 05 80000000", "is not the 0 CPU(s)"),
    ("0001 01 04 20 0c00 00 05 08 00 000000", "needs"),
    ("0001 01 04 20 0c00 00 0e 0e 00000000 00000000 00000000 00", "needs"),
])
def test_malformed_known_tags_are_kept_raw(hexdata, reason):
    data = bytes.fromhex(hexdata)
    p = decode_status(data)
    (tag,) = p.tags
    assert type(tag) is UnknownTag and tag.tag_id == data[9]
    assert p.encode() == data
    spans = annotate_status(data)
    assert_tiles(spans, data)
    assert reason in spans[-1].meaning and "kept raw" in spans[-1].meaning


def test_error_text_names_message_field_and_offset():
    assert (str(protocol_error(decode_status, bytes.fromhex("0001 01 04 20 0c00 00 05 01")))
            == "StatusPacket.tags[0] at byte 9: needs 5 bytes, 1 left")
    assert (str(protocol_error(decode_tcp, bytes.fromhex("0007 0b 3fc00000 0008")))
            == "RioToDsFrame.occurrences at byte 9: needs 2 bytes, 0 left")


@pytest.mark.parametrize("packet,field", [
    (StatusPacket(sequence=65536), "sequence"),
    (StatusPacket(comm_version=-1), "comm_version"),
    (StatusPacket(mode=4), "mode"),
    (StatusPacket(status_other=0x80), "status_other"),
    (StatusPacket(trace_other=0x01), "trace_other"),
    (StatusPacket(request_other=0x01), "request_other"),
    (StatusPacket(battery=256.0), "battery"),
    (StatusPacket(battery=-1.0), "battery"),
    (StatusPacket(tags=(JoystickOutput(outputs=1 << 32),)), "tags[0].outputs"),
    (StatusPacket(tags=(JoystickOutput(right_rumble=65536),)), "tags[0].right_rumble"),
    (StatusPacket(tags=(JoystickOutput(left_rumble=-1),)), "tags[0].left_rumble"),
    (StatusPacket(tags=(JoystickOutput(outputs=1, idle=True),)), "tags[0].idle"),
    (StatusPacket(tags=(DiskInfo(-1),)), "tags[0].free_bytes"),
    (StatusPacket(tags=(DiskInfo(0, 1 << 32),)), "tags[0].block"),
    (StatusPacket(tags=(CpuInfo((CpuLoad(),) * 16),)), "tags[0].cpus"),
    (StatusPacket(tags=(CpuInfo((CpuLoad(low=1e39),)),)), "tags[0].cpus[0].low"),
    (StatusPacket(tags=(RamInfo(free_bytes=1 << 32),)), "tags[0].free_bytes"),
    (StatusPacket(tags=(PdpLog(currents=(0,) * 15),)), "tags[0].currents"),
    (StatusPacket(tags=(PdpLog(currents=(0,) * 15 + (1024,)),)), "tags[0].currents[15]"),
    (StatusPacket(tags=(PdpLog(unknown_tail=b"\0\0"),)), "tags[0].unknown_tail"),
    (StatusPacket(tags=(PdpLog(pad1=16),)), "tags[0].pad1"),
    (StatusPacket(tags=(Unknown09(bytes(255)),)), "tags[0].data"),
    (StatusPacket(tags=(CanMetrics(rx_errors=256),)), "tags[0].rx_errors"),
    (StatusPacket(tags=(CanMetrics(utilization="x"),)), "tags[0].utilization"),
    (StatusPacket(tags=(UnknownTag(0x42, bytes(255)),)), "tags[0].data"),
    (StatusPacket(tags=(UnknownTag(0x42, 7),)), "tags[0].data"),
    (StatusPacket(tags=(IDLE_JOYSTICK_OUTPUT, "not a tag")), "tags[1]"),
])
def test_encoding_refuses_out_of_range(packet, field):
    assert where(protocol_error(packet.encode)) == ("StatusPacket", field, None)


def test_annotation_explains_every_byte():
    data = SEED_HEADER + SEED_THIRD_STICK + SEED_DISK + SEED_CPU + SEED_RAM + SEED_PDP + SEED_CAN + SEED_UNKNOWN_09
    spans = annotate_status(data)
    assert_tiles(spans, data)
    by_field = {s.field: s for s in spans}
    assert by_field["battery"].meaning == "battery: 12.50 V (XX + YY/256 = 12 + 128/256)"
    assert "E-STOPPED" in by_field["status"].meaning and "autonomous" in by_field["status"].meaning
    assert "robot code" in by_field["trace"].meaning and "auto" in by_field["trace"].meaning
    assert by_field["tags[0].id"].value == "joystick_output (idle)"
    # the inspector shows both readings of the rumble order
    for name in ("tags[2].right_rumble", "tags[2].left_rumble"):
        assert "WPILib's simulator" in by_field[name].meaning and "seed" in by_field[name].meaning
    assert by_field["tags[4].cpu_count"].value == 2
    assert by_field["tags[6].channels_0_5"].meaning.endswith("0: 1.000 A, 1: 0.000 A, 2: 0.000 A, "
                                                             "3: 0.000 A, 4: 0.000 A, 5: 0.000 A")
    assert "15: 127.875 A" in by_field["tags[6].channels_12_15"].meaning
    assert "12.5 %" in by_field["tags[7].utilization"].meaning
    assert all(s.meaning for s in spans)


def test_kinds_are_registered():
    assert kinds.get("rio-to-ds").decode(SIM_TELEOP) == decode_status(SIM_TELEOP)
    assert kinds.get("rio-to-ds-tcp").tcp and kinds.get("rio-to-ds-tcp").decode(STDOUT) == decode_tcp(STDOUT)
    assert not kinds.get("rio-to-ds").tcp


# -- TCP frames -----------------------------------------------------------------------

def test_tcp_golden_frames():
    cases = [
        (STDOUT, StdoutMessage(10.0, 7, "hello")),
        (ERROR, ErrorMessage(1.5, 8, 1, 1234, True, False, "bad", "x.py", "")),
        (WARNING_LV, ErrorMessage(0.0, 9, 2, -44009, False, True, "", "", "")),
        (VERSION_END, END_OF_VERSION_LIST),
        (VERSION_PDP, VersionInfo(DeviceType.PDP, 0, 0, "PDP", "1.40")),
        (UNKNOWN_0D, Unknown0d(bytes.fromhex("000004040404"))),
        (RADIO_FRAME, RadioEvents(RADIO.decode())),
        (USAGE, UsageReport(0x0D05, 0, b"C3>I1")),
        (DISABLE_FAULTS, DisableFaults(3, 1)),
        (RAIL_FAULTS, RailFaults(1, 2, 3)),
        (b"\x00\x00", KeepAlive()),
        (bytes.fromhex("0003 55 0102"), UnknownFrame(0x55, b"\x01\x02")),
    ]
    for frame, message in cases:
        assert decode_tcp(frame) == message, frame.hex()
        assert message.encode() == frame, frame.hex()
        assert_tiles(annotate_tcp(frame), frame)
    assert decode_tcp(VERSION_END).is_end_of_list and not decode_tcp(VERSION_PDP).is_end_of_list
    assert decode_tcp(bytes.fromhex("0007 0a 63 0000 01 00 00")).device_type == 0x63  # no enum member


def test_error_flags_keep_other_bits():
    # 0x80 is named by no document (open-ds's hasPlacedBit(flags, 7) is 0x01, counted from
    # the left): kept as an undocumented bit.
    frame = bytes.fromhex("0014 0b 00000000 0001 0001 00000000 81 0000 0000 0000")
    msg = decode_tcp(frame)
    assert (msg.is_error, msg.is_lv_code, msg.flags_other, msg.flags) == (True, False, 0x80, 0x81)
    assert msg.encode() == frame
    spans = {s.field: s for s in annotate_tcp(frame)}
    assert "0x80" in spans["flags"].meaning and "ERROR" in spans["flags"].meaning


@pytest.mark.parametrize("frame,field,offset", [
    ("", "size", 0),
    ("0005 0c 00", "size", 0),
    ("0002 0c 00", "timestamp", 3),
    ("0003 04 0001", "rail_12v", 5),
    ("0006 04 0001 0002 ff", "end", 7),
    ("0011 0b 00000000 0001 0001 00000000 01 0005 61", "details", 18),
    ("0004 0a 00 0000", "device_id", 6),
    ("0008 0a 00 0000 00 03 6161", "name", 8),
])
def test_bad_tcp_frames_name_field_and_offset(frame, field, offset):
    assert where(protocol_error(decode_tcp, bytes.fromhex(frame))) == ("RioToDsFrame", field, offset)


@pytest.mark.parametrize("message,field", [
    (ErrorMessage(error_code=1 << 31), "error_code"),
    (ErrorMessage(occurrences=-1), "occurrences"),
    (ErrorMessage(flags_other=0x01), "flags_other"),
    (ErrorMessage(timestamp=1e39), "timestamp"),
    (ErrorMessage(details="d" * 0x10000), "details"),
    (ErrorMessage(details="d" * 0xFFFF, location="l" * 10), "size"),
    (StdoutMessage(sequence=70000), "sequence"),
    (StdoutMessage(text="t" * 0xFFF9), "text"),
    (VersionInfo(name="n" * 256), "name"),
    (VersionInfo(device_type=256), "device_type"),
    (UsageReport(team=-1), "team"),
    (UsageReport(entries="abc"), "entries"),
    (DisableFaults(comms=65536), "comms"),
    (RailFaults(rail_3v3=65536), "rail_3v3"),
    (RadioEvents("r" * 0xFFFF), "text"),
    (Unknown0d("nope"), "data"),
    (UnknownFrame(256), "tag_id"),
])
def test_tcp_encoding_refuses_out_of_range(message, field):
    assert where(protocol_error(message.encode)) == ("RioToDsFrame", field, None)


# -- properties -----------------------------------------------------------------------

f32 = st.floats(width=32, allow_nan=False)
u8, u16, u32 = st.integers(0, 0xFF), st.integers(0, 0xFFFF), st.integers(0, 0xFFFFFFFF)

joystick_outputs = st.one_of(st.just(IDLE_JOYSTICK_OUTPUT), st.builds(JoystickOutput, u32, u16, u16))
status_tags = st.one_of(
    joystick_outputs,
    st.builds(DiskInfo, u32, st.one_of(st.none(), u32)),
    st.builds(CpuInfo, st.lists(st.builds(CpuLoad, f32, f32, f32, f32), max_size=4).map(tuple), st.booleans()),
    st.builds(RamInfo, u32, u32),
    st.builds(PdpLog, st.lists(st.integers(0, 1023), min_size=16, max_size=16).map(tuple), u8,
              st.binary(min_size=3, max_size=3), st.integers(0, 15), st.integers(0, 15)),
    st.builds(Unknown09, st.binary(max_size=20)),
    st.builds(CanMetrics, f32, u32, u32, u8, u8),
    st.builds(UnknownTag, u8.filter(lambda i: i not in (0x01, 0x04, 0x05, 0x06, 0x08, 0x09, 0x0E)),
              st.binary(max_size=30)),
)
packets = st.builds(
    StatusPacket, u16, u8, st.booleans(), st.booleans(), st.booleans(), st.booleans(), st.sampled_from(Mode),
    st.booleans(), st.booleans(), st.booleans(), st.booleans(), st.booleans(), st.booleans(),
    st.integers(0, 0xFFFF).map(lambda raw: raw / 256), st.booleans(), st.lists(status_tags, max_size=12).map(tuple),
    st.sampled_from([0, 0x20, 0x40, 0x60]), st.sampled_from([0, 0x40, 0x80, 0xC0]),
    st.sampled_from([0, 0x02, 0x80, 0xFE]),
)


@given(packets)
def test_round_trip(packet):
    data = assert_round_trip(packet, decode_status, annotate_status)
    assert walk_status(Reader(data, "StatusPacket")) == packet


@given(packets)
def test_valid_packets_take_the_fast_path(packet):
    # The fast path must not quietly fall back to the walk for anything a peer sends.
    assert _fast_status(packet.encode()) == packet


@given(packets, st.data())
def test_fast_path_agrees_with_reference_walk(packet, data):
    raw = bytearray(packet.encode())
    for _ in range(data.draw(st.integers(0, 3))):
        if raw:
            raw[data.draw(st.integers(0, len(raw) - 1))] = data.draw(u8)
    if data.draw(st.booleans()):
        raw = raw[: data.draw(st.integers(0, len(raw)))]
    if data.draw(st.booleans()):
        raw += data.draw(st.binary(max_size=20))
    raw = bytes(raw)
    assert outcome(decode_status, raw) == outcome(lambda b: walk_status(Reader(b, "StatusPacket")), raw)


@given(st.binary(max_size=160))
def test_fast_path_agrees_on_random_bytes(raw):
    assert outcome(decode_status, raw) == outcome(lambda b: walk_status(Reader(b, "StatusPacket")), raw)


@given(st.binary(max_size=160))
def test_random_bytes_give_a_packet_or_protocol_error(data):
    decode_or_protocol_error("rio-to-ds", data)


@given(st.binary(min_size=8, max_size=8), st.lists(st.tuples(u8, st.binary(max_size=40)), max_size=8))
def test_random_well_framed_tags(header, tags):
    # Tags whose sizes are right, so every tag decoder sees arbitrary payloads.
    data = header + b"".join(bytes((len(p) + 1, tid)) + p for tid, p in tags)
    message = decode_or_protocol_error("rio-to-ds", data)
    if message is not None:
        assert message.encode() == data


strings = st.text(max_size=40)
frames = st.one_of(
    st.just(KeepAlive()),
    st.builds(RadioEvents, strings),
    st.builds(UsageReport, u16, u8, st.binary(max_size=40)),
    st.builds(DisableFaults, u16, u16),
    st.builds(RailFaults, u16, u16, u16),
    st.builds(VersionInfo, st.one_of(st.sampled_from(list(DeviceType)), u8), u16, u8, strings, strings),
    st.builds(ErrorMessage, f32, u16, u16, st.integers(-(1 << 31), (1 << 31) - 1), st.booleans(), st.booleans(),
              strings, strings, strings, st.sampled_from([0, 0x04, 0x80, 0xFC])),
    st.builds(StdoutMessage, f32, u16, st.text(max_size=100)),
    st.builds(Unknown0d, st.binary(max_size=20)),
    st.builds(UnknownFrame, u8.filter(lambda i: i not in (0x00, 0x01, 0x04, 0x05, 0x0A, 0x0B, 0x0C, 0x0D)),
              st.binary(max_size=40)),
)


@given(frames)
def test_tcp_round_trip(frame):
    assert_round_trip(frame, decode_tcp, annotate_tcp)


@given(st.integers(0, 255), st.binary(max_size=80))
def test_random_tcp_payloads(tag_id, payload):
    frame = framed(tag_id, payload)
    message = decode_or_protocol_error("rio-to-ds-tcp", frame)
    if message is not None:
        assert message.encode() == frame


@given(st.sampled_from([STDOUT, ERROR, WARNING_LV, VERSION_PDP, USAGE, RAIL_FAULTS]), st.data())
def test_mutated_tcp_frames(frame, data):
    raw = bytearray(frame)
    raw[data.draw(st.integers(2, len(raw) - 1))] = data.draw(u8)
    raw = raw[: data.draw(st.integers(0, len(raw)))] + data.draw(st.binary(max_size=6))
    decode_or_protocol_error("rio-to-ds-tcp", bytes(raw))
    # and with the size field repaired, so the payload decoder sees the damage
    if len(raw) >= 3:
        decode_or_protocol_error("rio-to-ds-tcp", with_size_repaired(raw))


@given(st.binary(max_size=80))
def test_random_tcp_bytes(data):
    decode_or_protocol_error("rio-to-ds-tcp", data)


def test_cpu_count_is_bounded_in_either_form():
    # The seed's f32 count: NaN, infinities, fractions, -0.0 and a count the tag does not hold
    # do not make a CPU tag: the tag is kept raw and the annotation names the field.
    for count in (float("nan"), float("inf"), 1.5, -1.0, -0.0, 1.0):
        tag = bytes((5, 0x05)) + struct.pack(">f", count)
        assert decode_status(SEED_HEADER + tag).tags == (UnknownTag(0x05, tag[2:]),)
        assert "tags[0].cpu_count" in annotate_status(SEED_HEADER + tag)[-1].meaning
    assert decode_status(SEED_HEADER + bytes.fromhex("05 05 00000000")).tags == (CpuInfo((), f32_count=True),)
    # The u8 count must be the number of CPUs the tag holds; a size that fits neither form is
    # kept raw too.
    for tag in (bytes.fromhex("02 05 01"), bytes.fromhex("12 05 02") + bytes(16), bytes.fromhex("04 05 00 00 00")):
        assert decode_status(SEED_HEADER + tag).tags == (UnknownTag(0x05, tag[2:]),)
        assert "tags[0].cpu_count" in annotate_status(SEED_HEADER + tag)[-1].meaning
    assert decode_status(SEED_HEADER + bytes.fromhex("02 05 00")).tags == (CpuInfo(()),)
    assert math.isclose(CpuLoad(normal=30.0).normal, 30.0)
