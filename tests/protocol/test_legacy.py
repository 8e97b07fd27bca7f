"""The cRIO-era 2010 protocol: control (UDP 1110), status (UDP 1150), dashboard (UDP 1165),
NetConsole (UDP 6666)."""

from __future__ import annotations

import struct
import zlib

import pytest
from hypothesis import given
from hypothesis import strategies as st

from protocol import kinds
from protocol.enums import AllianceStation
from protocol.errors import ProtocolError
from protocol.legacy import (
    CONTROL_NOT_ESTOP, NO_CODE_BATTERY, DynamicBlock, LegacyControlPacket, LegacyDashboardPacket,
    LegacyJoystick, LegacyStatusPacket, NetConsoleText, annotate_legacy_control,
    annotate_legacy_dashboard, annotate_legacy_status, annotate_netconsole, bcd_to_volts,
    decode_legacy_control, decode_legacy_dashboard, decode_legacy_status, decode_netconsole,
    legacy_crc, volts_to_bcd, walk_legacy_control,
)
from protocol.wire import Reader

from .util import assert_round_trip, assert_tiles, decode_or_protocol_error, protocol_error, where


# -- building golden packets from the seed's offsets ----------------------------------------
def _packet(size: int, pieces: dict[int, str | bytes]) -> bytearray:
    """``size`` zero bytes with each piece (hex text or bytes) written at its offset."""
    out = bytearray(size)
    for offset, piece in pieces.items():
        raw = bytes.fromhex(piece) if isinstance(piece, str) else piece
        out[offset:offset + len(raw)] = raw
    return out


def _zlib_crc(data: bytes | bytearray, crc_offset: int) -> int:
    """The CRC as PROTOCOL-NOTES words it, computed here independently of the module."""
    covered = bytearray(data[:crc_offset + 4])
    covered[crc_offset:crc_offset + 4] = bytes(4)
    return zlib.crc32(bytes(covered))


def _seal(data: bytearray, crc_offset: int) -> bytes:
    data[crc_offset:crc_offset + 4] = _zlib_crc(data, crc_offset).to_bytes(4, "big")
    return bytes(data)


# DS -> robot, laid out from frc_2010_protocol.txt "DS -> Robot" and the PROTOCOL-NOTES table
# "The 2010 legacy protocol" (FRCCommonControlData, 0x00-0x4f):
GOLDEN_CONTROL = _seal(_packet(1024, {
    0x00: "1234",  # packet index
    0x02: "60",  # control: 0x40 not-e-stop + 0x20 enabled (teleop, no FMS)
    0x03: "05",  # DS digital inputs 1 and 3
    0x04: "0126",  # team 294
    0x06: b"R1",  # alliance 'R', position '1'
    0x08: "7f 81 00 40 c0 01  0801",  # joystick 1: axes 127 -127 0 64 -64 1; buttons 1 and 12
    0x10: "00 00 00 00 00 00  0000",  # joystick 2: idle
    0x18: "01 02 03 04 05 06  0fff",  # joystick 3: buttons 1-12
    0x20: "ff fe fd fc fb fa  8000",  # joystick 4: bit 15 (unused by the DS, kept)
    0x28: "0000 0200 03ff 0001",  # analog inputs, 10-bit right-justified
    0x30: "0102030405060708",  # cRIO checksum
    0x38: "11111111 22222222 33333333 44444444",  # FPGA checksums 0-3
    0x48: b"10020800",  # DS version, 2010 DS 1.1
    # 0x50-0x72 unknown: zeros
    0x73: "04 11 aabbcc",  # dynamic block: 4 bytes follow, id 17 (DS Enhanced I/O input)
    0x78: "01 12",  # dynamic block: 1 byte follows, id 18, no data
    # 0x7a: size byte 0 ends the blocks; zeros to 0x3f7; 0x3f8-0x3fb zero
}), 0x3FC)
GOLDEN_CONTROL_CRC = "bcc339fe"  # zlib.crc32 of the 1024 bytes with 0x3fc-0x3ff zeroed

# Robot -> DS, from frc_2010_protocol.txt "Robot -> DS" (MAC is the seed's example):
_STATUS_PIECES: dict[int, str | bytes] = {
    0x00: "60",  # control byte echo
    0x01: "12 34",  # battery 12.34 V in BCD
    0x03: "81",  # DS digital outputs 1 and 8
    0x08: "0126",  # team 294
    0x0A: "00 80 2f 11 4d ac",  # cRIO MAC
    0x10: b"06300800",  # FPGA version
    0x1E: "1234",  # echoed packet index
    0x20: "07",  # user data update number
    0x21: "00000003",  # user string (userDataHigh) length ...
    0x25: "010203",  # ... and its bytes
    0x28: "00000004",  # error string length ...
    0x2C: b"oops",
    0x30: "00000002",  # user data (userDataLow) length ...
    0x34: "beef",
    # 0x36-0x3d7 zeros; 0x3d8-0x3f7 DSEIO status block:
    0x3D8: "de ad",
}
GOLDEN_STATUS = _seal(_packet(1024, _STATUS_PIECES), 0x3FC)
GOLDEN_STATUS_CRC = "475d32b2"
# With setUserDsLcdData(): 0x400 = 9f, 0x401 = ff, then 6 x 21 characters, space-padded.
LCD_TEXT = [b"Hello, 2010!", b"", b"line 3", b"", b"", b"123456789012345678901"]
GOLDEN_STATUS_LCD = GOLDEN_STATUS + b"\x9f\xff" + b"".join(line.ljust(21, b" ") for line in LCD_TEXT)

# DS -> dashboard, from frc_2010_protocol.txt "DS -> Dashboard":
GOLDEN_DASHBOARD = _seal(_packet(1018, {
    0x00: "0102",  # packet number, big endian
    0x02: "05",  # DS digital inputs
    0x03: "81",  # DS digital outputs
    0x04: "12 34",  # battery, BCD
    0x06: "60",  # control byte
    0x07: "00",  # error bit field
    0x08: "02 5e",  # team 294 as 2 and 94 (the seed's own example)
    0x0A: b"10020800",  # DS version
    0x18: "01 02",  # reply packets sent: 0x0201 = 513, LITTLE endian as the seed says
    0x1A: "07",  # user data update number
    0x1B: "00000001 ff",  # user string length 1, byte ff
    0x20: "00000003",  # error string length 3 ...
    0x24: b"err",
    0x27: "00000000",  # user data length 0
    # zeros to 0x3f1; 0x3f2-0x3f5 zero; CRC at 0x3f6-0x3f9
}), 0x3F6)
GOLDEN_DASHBOARD_CRC = "c544a596"


# -- golden vectors -----------------------------------------------------------------------
def test_golden_control_decodes_every_field():
    assert GOLDEN_CONTROL[0x3FC:].hex() == GOLDEN_CONTROL_CRC
    p = decode_legacy_control(GOLDEN_CONTROL)
    assert p.packet_index == 0x1234
    assert (p.reset, p.estop, p.enabled, p.autonomous, p.fms_attached, p.resync,
            p.crio_checksum_bit, p.fpga_checksum_bit) == (False, False, True, False, False, False, False, False)
    assert p.control_byte == 0x60
    assert p.ds_digital_in == 0x05
    assert p.team == 294
    assert p.station is AllianceStation.RED1
    assert p.joysticks == (
        LegacyJoystick((127, -127, 0, 64, -64, 1), 0x0801), LegacyJoystick(),
        LegacyJoystick((1, 2, 3, 4, 5, 6), 0x0FFF), LegacyJoystick((-1, -2, -3, -4, -5, -6), 0x8000))
    assert [b for b in range(1, 17) if p.joysticks[0].pressed(b)] == [1, 12]
    assert p.joysticks[0].axis(0) == 1.0 and p.joysticks[0].axis(1) == -127 / 128
    assert p.analog == (0, 512, 1023, 1)
    assert p.crio_checksum == bytes.fromhex("0102030405060708")
    assert p.fpga_checksums == tuple(bytes([k] * 4) for k in (0x11, 0x22, 0x33, 0x44))
    assert p.ds_version == "10020800"
    assert p.unknown_0x50 == bytes(35)
    assert p.dynamic_blocks == (DynamicBlock(17, b"\xaa\xbb\xcc"), DynamicBlock(18, b""))
    assert p.dynamic_blocks[0].name == "DS Enhanced I/O input"
    assert p.dynamic_padding == b""
    assert p.reserved == bytes(4)
    assert p.encode() == GOLDEN_CONTROL
    assert decode_legacy_control(GOLDEN_CONTROL, check_crc=False) == p


def test_golden_control_encodes_at_the_seed_offsets():
    p = LegacyControlPacket(
        packet_index=0x1234, enabled=True, ds_digital_in=5, team=294, station=AllianceStation.RED1,
        joysticks=(LegacyJoystick((127, -127, 0, 64, -64, 1), 0x0801), LegacyJoystick(),
                   LegacyJoystick((1, 2, 3, 4, 5, 6), 0x0FFF), LegacyJoystick((-1, -2, -3, -4, -5, -6), 0x8000)),
        analog=(0, 512, 1023, 1), crio_checksum=bytes.fromhex("0102030405060708"),
        fpga_checksums=(b"\x11" * 4, b"\x22" * 4, b"\x33" * 4, b"\x44" * 4),
        dynamic_blocks=(DynamicBlock(17, b"\xaa\xbb\xcc"), DynamicBlock(18)))
    data = p.encode()
    assert len(data) == 1024
    assert data[0x00:0x08] == bytes.fromhex("1234 60 05 0126 52 31")
    assert data[0x08:0x10] == bytes.fromhex("7f8100 40c001 0801")
    assert data[0x28:0x30] == bytes.fromhex("0000 0200 03ff 0001")
    assert data[0x48:0x50] == b"10020800"
    assert data[0x73:0x7B] == bytes.fromhex("04 11 aabbcc 01 12 00")
    assert data[0x3F8:0x3FC] == bytes(4)
    assert data[0x3FC:] == bytes.fromhex(GOLDEN_CONTROL_CRC)
    assert data == GOLDEN_CONTROL


def test_default_control_packet_is_not_estopped():
    # PROTOCOL-NOTES: 0x40 is "not e-stop", SET in normal operation.
    data = LegacyControlPacket().encode()
    assert data[2] == CONTROL_NOT_ESTOP
    assert data[0x48:0x50] == b"10020800"
    assert LegacyControlPacket(estop=True).encode()[2] == 0x00
    assert decode_legacy_control(LegacyControlPacket(estop=True).encode()).estop is True


@pytest.mark.parametrize("field,bit", [
    ("reset", 0x80), ("enabled", 0x20), ("autonomous", 0x10), ("fms_attached", 0x08),
    ("resync", 0x04), ("crio_checksum_bit", 0x02), ("fpga_checksum_bit", 0x01),
])
def test_each_control_bit(field, bit):
    # PROTOCOL-NOTES "The 2010 legacy protocol", control byte at 0x02.
    p = LegacyControlPacket(**{field: True})
    assert p.encode()[2] == CONTROL_NOT_ESTOP | bit
    assert decode_legacy_control(p.encode()) == p


@pytest.mark.parametrize("pair,station", [
    (b"R1", AllianceStation.RED1), (b"R3", AllianceStation.RED3), (b"B1", AllianceStation.BLUE1),
    (b"B2", AllianceStation.BLUE2), (b"B3", AllianceStation.BLUE3),
])
def test_alliance_and_position_bytes(pair, station):
    data = LegacyControlPacket(station=station).encode()
    assert data[6:8] == pair
    assert decode_legacy_control(data).station is station


@pytest.mark.parametrize("pair", [b"X1", b"R4", b"r1", b"\x00\x00", b"B0"])
def test_unknown_station_bytes_are_kept_raw(pair):
    data = bytearray(GOLDEN_CONTROL)
    data[6:8] = pair
    data = _seal(data, 0x3FC)
    p = decode_legacy_control(data)
    assert p.station == pair
    assert p.encode() == data
    spans = {s.field: s for s in annotate_legacy_control(data)}
    assert "kept raw" in spans["alliance"].meaning or "kept raw" in spans["position"].meaning


def test_crc_is_zlib_crc32_over_all_1024_bytes_big_endian():
    assert legacy_crc(GOLDEN_CONTROL, 0x3FC) == int(GOLDEN_CONTROL_CRC, 16)
    assert legacy_crc(GOLDEN_CONTROL, 0x3FC) == zlib.crc32(GOLDEN_CONTROL[:0x3FC] + bytes(4))
    # The LCD extension lies after the CRC field and is not covered (seed: "CRC32 of 0-0x3ff").
    assert legacy_crc(GOLDEN_STATUS_LCD, 0x3FC) == legacy_crc(GOLDEN_STATUS, 0x3FC)
    assert legacy_crc(GOLDEN_DASHBOARD, 0x3F6) == int(GOLDEN_DASHBOARD_CRC, 16)


def test_flipping_any_byte_is_a_crc_error():
    for i in range(1024):
        data = bytearray(GOLDEN_CONTROL)
        data[i] ^= 0x01
        assert where(protocol_error(decode_legacy_control, bytes(data))) == ("LegacyControlPacket", "crc", 1020), i


def test_flipping_any_covered_byte_of_status_and_dashboard_is_a_crc_error():
    for golden, decode, crc_at in ((GOLDEN_STATUS_LCD, decode_legacy_status, 0x3FC),
                                   (GOLDEN_DASHBOARD, decode_legacy_dashboard, 0x3F6)):
        for i in range(crc_at + 4):
            data = bytearray(golden)
            data[i] ^= 0x80
            assert where(protocol_error(decode, bytes(data)))[1:] == ("crc", crc_at), i


def test_crc_error_message_names_expected_and_found():
    data = bytearray(GOLDEN_CONTROL)
    data[0x3FC:] = bytes(4)
    assert str(protocol_error(decode_legacy_control, bytes(data))) == (
        f"LegacyControlPacket.crc at byte 1020: expected 0x{GOLDEN_CONTROL_CRC}, found 0x00000000 "
        "(CRC-32 of bytes 0x000-0x3ff with this field zeroed)")


def test_inspector_decodes_and_explains_a_bad_crc():
    data = bytearray(GOLDEN_CONTROL)
    data[0x3FF] ^= 0xFF
    data = bytes(data)
    p = decode_legacy_control(data, check_crc=False)
    assert p.team == 294
    spans = annotate_legacy_control(data)
    assert_tiles(spans, data)
    crc = spans[-1]
    assert (crc.field, crc.offset, crc.length) == ("crc", 1020, 4)
    assert crc.meaning.endswith(f"BAD, expected 0x{GOLDEN_CONTROL_CRC}, found 0x{data[0x3FC:].hex()}")
    good = annotate_legacy_control(GOLDEN_CONTROL)[-1]
    assert good.meaning.endswith(": OK")
    # The Kind's lenient annotation (what the inspector calls) keeps every span too.
    lenient, error = kinds.get("legacy-ds-to-robot").annotate_lenient(data)
    assert error is None and lenient[-1].meaning == crc.meaning


# -- control packet: dynamic blocks and bad fields -------------------------------------------
def test_dynamic_padding_is_kept_raw():
    data = bytearray(GOLDEN_CONTROL)
    data[0x100] = 0x55  # a stray byte after the 0 size byte at 0x7a
    data = _seal(data, 0x3FC)
    p = decode_legacy_control(data)
    assert p.dynamic_blocks == (DynamicBlock(17, b"\xaa\xbb\xcc"), DynamicBlock(18, b""))
    assert p.dynamic_padding == bytes(0x100 - 0x7A) + b"\x55"
    assert p.encode() == data
    span = {s.field: s for s in annotate_legacy_control(data)}["dynamic_padding"]
    assert (span.offset, span.length) == (0x7A, 0x3F8 - 0x7A) and "NOT all zero" in span.meaning


def test_dynamic_blocks_may_fill_the_area_exactly():
    # 0x73..0x3f7 is 901 bytes: three blocks of 256 (size 255) and one of 133.
    blocks = (DynamicBlock(1, bytes(254)), DynamicBlock(2, b"\x01" * 254), DynamicBlock(3, bytes(254)),
              DynamicBlock(4, bytes(131)))
    data = LegacyControlPacket(dynamic_blocks=blocks).encode()
    assert data[0x73:0x75] == b"\xff\x01" and data[0x3F6:0x3F8] == bytes(2)
    p = decode_legacy_control(data)
    assert p.dynamic_blocks == blocks and p.dynamic_padding == b""
    assert protocol_error(LegacyControlPacket(dynamic_blocks=blocks + (DynamicBlock(5),)).encode).field == (
        "dynamic_blocks[4]")


# A chain of blocks that runs past 0x3f7: three blocks of 255 bytes (size 0xfe) from 0x73,
# then at 0x370 a size of 0xff with only 135 bytes left.
_BLOCK_CHAIN = {0x73: "fe 01", 0x172: "fe 02", 0x271: "fe 03", 0x370: "ff 04"}


def test_a_malformed_block_under_a_good_crc_keeps_the_control_data():
    # Issue 18: the CRC held, so the control data is the DS's; only the blocks from the one
    # whose size runs past 0x3f7 on are lost. GOLDEN_CONTROL's head (enabled, team 294) with
    # _BLOCK_CHAIN from 0x73.
    data = bytearray(GOLDEN_CONTROL[:0x73] + bytes(0x400 - 0x73))
    for at, text in _BLOCK_CHAIN.items():
        piece = bytes.fromhex(text)
        data[at:at + len(piece)] = piece
    data = _seal(data, 0x3FC)
    p = decode_legacy_control(data)
    assert p.enabled and not p.estop and p.team == 294 and p.joysticks[0].pressed(12)
    assert [b.block_id for b in p.dynamic_blocks] == [1, 2, 3]
    assert p.blocks_malformed and p.dynamic_padding == bytes.fromhex("ff 04")
    assert p.encode() == data
    spans = annotate_legacy_control(data)
    assert_tiles(spans, data)
    bad = {s.field: s for s in spans}["dynamic_blocks[3].malformed"]
    assert (bad.offset, bad.length) == (0x370, 0x3F8 - 0x370) and bad.meaning.startswith("MALFORMED")
    assert decode_legacy_control(p.encode()) == p
    # A bad CRC still drops the packet.
    data = bytearray(data)
    data[0x02] ^= 0x20
    assert where(protocol_error(decode_legacy_control, bytes(data)))[1] == "crc"
    # Padding that starts with a size that fits is a block, not padding: refused.
    with pytest.raises(ProtocolError, match="runs past"):
        LegacyControlPacket(dynamic_padding=b"\x05\x01").encode()


@pytest.mark.parametrize("pieces,field,offset,reason", [
    ({0x2A: "0400"}, "analog[1]", 0x2A, "1024 is not a 10-bit value (0..1023)"),
    ({0x2E: "ffff"}, "analog[3]", 0x2E, "65535 is not a 10-bit value (0..1023)"),
    ({0x3F0: "ff"}, "dynamic_blocks[0].size", 0x73, None),
])
def test_bad_control_fields_name_field_and_offset(pieces, field, offset, reason):
    if reason is None:  # a zero at 0x73 ends the blocks at once: the stray 0xff is padding
        p = decode_legacy_control(_seal(_packet(1024, pieces), 0x3FC))
        assert p.dynamic_blocks == () and p.dynamic_padding == bytes(0x3F0 - 0x73) + b"\xff"
        return
    exc = protocol_error(decode_legacy_control, _seal(_packet(1024, pieces), 0x3FC))
    assert (*where(exc), exc.reason) == ("LegacyControlPacket", field, offset, reason)


@pytest.mark.parametrize("size,offset", [(0, 0), (1000, 1000), (1023, 1023), (1025, 1024), (2048, 1024)])
def test_control_size_must_be_1024(size, offset):
    exc = protocol_error(decode_legacy_control, (GOLDEN_CONTROL * 2)[:size])
    assert (exc.field, exc.offset) == ("size", offset)
    assert exc.reason == f"{size} bytes; this packet is exactly 1024 bytes"


# -- BCD battery ------------------------------------------------------------------------------
@pytest.mark.parametrize("volts,pair", [
    (12.34, (0x12, 0x34)), (0.0, (0x00, 0x00)), (9.05, (0x09, 0x05)), (13.5, (0x13, 0x50)),
    (99.99, (0x99, 0x99)), (7.999, (0x08, 0x00)), (12, (0x12, 0x00)),
])
def test_volts_to_bcd(volts, pair):
    assert volts_to_bcd(volts) == pair


@pytest.mark.parametrize("pair,volts", [((0x12, 0x34), 12.34), ((0x13, 0x50), 13.5), ((0x09, 0x99), 9.99),
                                        ((0x00, 0x01), 0.01), ((0x37, 0x37), 37.37)])
def test_bcd_to_volts(pair, volts):
    # BCD, not the trap b * 12 / 0x12 (which reads 0x13 as 12.67 and 0x09 as 6).
    assert bcd_to_volts(*pair) == volts


@pytest.mark.parametrize("volts", [-0.01, 100, 99.996, float("nan"), float("inf"), "12", None, True])
def test_volts_to_bcd_refuses(volts):
    assert protocol_error(volts_to_bcd, volts).field == "volts"


@pytest.mark.parametrize("pair,field", [((0x1A, 0x00), "battery.int"), ((0x12, 0x3F), "battery.frac"),
                                        ((0xA0, 0x00), "battery.int"), ((256, 0), "battery.int")])
def test_bcd_to_volts_refuses_non_bcd(pair, field):
    assert protocol_error(bcd_to_volts, *pair).field == field


@given(st.integers(0, 9999))
def test_bcd_round_trip(centi):
    assert volts_to_bcd(bcd_to_volts(*volts_to_bcd(centi / 100))) == volts_to_bcd(centi / 100)
    assert round(bcd_to_volts(*volts_to_bcd(centi / 100)) * 100) == centi


# -- robot -> DS status -----------------------------------------------------------------------
def test_golden_status_decodes_every_field():
    assert GOLDEN_STATUS[0x3FC:].hex() == GOLDEN_STATUS_CRC
    p = decode_legacy_status(GOLDEN_STATUS)
    assert p == LegacyStatusPacket(
        control=0x60, battery=(0x12, 0x34), ds_digital_out=0x81, team=294,
        mac=bytes.fromhex("00802f114dac"), fpga_version="06300800", packet_index=0x1234,
        update_number=7, user_data_high=b"\x01\x02\x03", error_text="oops", user_data_low=b"\xbe\xef",
        dseio_status=b"\xde\xad" + bytes(30))
    assert p.volts == 12.34 and not p.no_code
    assert p.enabled and not p.estop and not p.autonomous
    assert p.lcd is None
    assert p.encode() == GOLDEN_STATUS


def test_golden_status_with_lcd():
    p = decode_legacy_status(GOLDEN_STATUS_LCD)
    assert p.lcd == ("Hello, 2010!", "", "line 3", "", "", "123456789012345678901")
    assert p.encode() == GOLDEN_STATUS_LCD
    data = p.encode()
    assert len(data) == 1152 and data[0x400:0x402] == b"\x9f\xff"
    assert data[0x402:0x402 + 21] == b"Hello, 2010!         "
    # Fewer lines are padded with blank ones.
    short = LegacyStatusPacket(lcd=("a",)).encode()
    assert short[0x402:] == b"a" + b" " * 125
    # The LCD text is not covered by the CRC: changing it still decodes.
    changed = bytearray(GOLDEN_STATUS_LCD)
    changed[0x402] = ord("J")
    assert decode_legacy_status(bytes(changed)).lcd[0] == "Jello, 2010!"
    spans = annotate_legacy_status(GOLDEN_STATUS_LCD)
    assert_tiles(spans, GOLDEN_STATUS_LCD)
    assert [s.field for s in spans[-7:]] == ["lcd.header"] + [f"lcd[{i}]" for i in range(6)]


def test_no_code_battery_and_invalid_bcd():
    p = LegacyStatusPacket()
    assert p.battery == NO_CODE_BATTERY and p.no_code and p.volts is None
    data = p.encode()
    assert data[1:3] == b"\x37\x37"
    spans = {s.field: s for s in annotate_legacy_status(data)}
    assert spans["battery"].meaning == "battery: 0x37 0x37 = no robot code running"
    bad = bytearray(GOLDEN_STATUS)
    bad[1:3] = b"\x1a\x34"
    bad = _seal(bad, 0x3FC)
    q = decode_legacy_status(bad)
    assert q.battery == (0x1A, 0x34) and q.volts is None and not q.no_code
    assert q.encode() == bad
    assert "not BCD" in {s.field: s for s in annotate_legacy_status(bad)}["battery"].meaning
    good = {s.field: s for s in annotate_legacy_status(GOLDEN_STATUS)}["battery"]
    assert good.meaning.startswith("battery: 12.34 V")


@pytest.mark.parametrize("pieces,field,offset,reason", [
    ({0x21: "00001388"}, "user_data_high.length", 0x21, "5000 bytes, only 947 left before 0x3d8"),
    ({0x21: "000003b3"}, "error_text.length", 0x3D8, "needs 4 bytes, 0 left before 0x3d8"),
    ({0x21: "00000000", 0x25: "000003af"}, "user_data_low.length", 0x3D8, "needs 4 bytes, 0 left before 0x3d8"),
    ({0x29: "ffffffff"}, "user_data_low.length", 0x29, "4294967295 bytes, only 939 left before 0x3d8"),
])
def test_status_lengths_are_bounded(pieces, field, offset, reason):
    exc = protocol_error(decode_legacy_status, _seal(_packet(1024, pieces), 0x3FC))
    assert (*where(exc), exc.reason) == ("LegacyStatusPacket", field, offset, reason)


def test_status_user_data_may_fill_to_0x3d7():
    # 0x3d8 - 0x21 = 951 bytes: 3 length fields and 939 data bytes.
    p = LegacyStatusPacket(user_data_high=b"\x01" * 900, error_text="e" * 39)
    assert decode_legacy_status(p.encode()) == p
    too_long = LegacyStatusPacket(user_data_high=b"\x01" * 900, error_text="e" * 39, user_data_low=b"x")
    assert (str(protocol_error(too_long.encode))
            == "LegacyStatusPacket.user_data_low: 1 bytes, only 0 fit before 0x3d8")


@pytest.mark.parametrize("tail,field,offset", [
    (b"\x9f\xfe" + bytes(126), "lcd.header", 1024),
    (b"\x00" * 128, "lcd.header", 1024),
])
def test_bad_lcd_header(tail, field, offset):
    assert where(protocol_error(decode_legacy_status, GOLDEN_STATUS + tail))[1:] == (field, offset)


@pytest.mark.parametrize("size,offset", [(0, 0), (1023, 1023), (1025, 1024), (1151, 1024), (1153, 1152)])
def test_status_size_must_be_1024_or_1152(size, offset):
    data = (GOLDEN_STATUS_LCD + bytes(100))[:size]
    assert where(protocol_error(decode_legacy_status, data))[1:] == ("size", offset)


# -- DS -> dashboard --------------------------------------------------------------------------
def test_golden_dashboard():
    assert GOLDEN_DASHBOARD[0x3F6:].hex() == GOLDEN_DASHBOARD_CRC
    p = decode_legacy_dashboard(GOLDEN_DASHBOARD)
    assert p == LegacyDashboardPacket(
        packet_number=0x0102, ds_digital_in=5, ds_digital_out=0x81, battery=(0x12, 0x34), control=0x60,
        error_bits=0, team=294, ds_version="10020800", reply_packets=0x0201, update_number=7,
        user_data_high=b"\xff", error_text="err", user_data_low=b"")
    assert p.volts == 12.34
    assert p.encode() == GOLDEN_DASHBOARD
    data = LegacyDashboardPacket(team=294, reply_packets=513).encode()
    assert len(data) == 1018
    assert data[8:10] == bytes((2, 94))  # the seed: 2 and 94 for 294
    assert data[0x18:0x1A] == b"\x01\x02"  # little endian, as the seed says
    spans = {s.field: s for s in annotate_legacy_dashboard(GOLDEN_DASHBOARD)}
    assert spans["reply_packets"].value == 513
    assert spans["team_ones"].meaning.endswith("team 294")


def test_dashboard_team_digits_must_be_two_digits():
    data = bytearray(GOLDEN_DASHBOARD)
    data[9] = 100
    assert str(protocol_error(decode_legacy_dashboard, _seal(data, 0x3F6))) == (
        "LegacyDashboardPacket.team_ones at byte 9: 100 is not the last two digits of a team number (0-99)")


@pytest.mark.parametrize("size,offset", [(1017, 1017), (1019, 1018), (1024, 1018)])
def test_dashboard_size_must_be_1018(size, offset):
    data = (GOLDEN_DASHBOARD + bytes(10))[:size]
    assert where(protocol_error(decode_legacy_dashboard, data))[1:] == ("size", offset)


# -- NetConsole -------------------------------------------------------------------------------
def test_netconsole_text():
    assert decode_netconsole(b"Robot code starting\n") == NetConsoleText("Robot code starting\n")
    raw = b"bad \xff\xfe bytes"
    assert decode_netconsole(raw).encode() == raw
    assert NetConsoleText("x" * 65507).encode() == b"x" * 65507
    assert (str(protocol_error(NetConsoleText("x" * 65508).encode))
            == "NetConsoleText.text: 65508 bytes is too long (at most 65507)")
    assert_tiles(annotate_netconsole(raw), raw)
    assert annotate_netconsole(b"") == [] and decode_netconsole(b"") == NetConsoleText("")


# -- encoding validation ----------------------------------------------------------------------
@pytest.mark.parametrize("packet,field", [
    (LegacyControlPacket(packet_index=65536), "packet_index"),
    (LegacyControlPacket(team=-1), "team"),
    (LegacyControlPacket(ds_digital_in=256), "ds_digital_in"),
    (LegacyControlPacket(station=b"R"), "station"),
    (LegacyControlPacket(station="R1"), "station"),
    (LegacyControlPacket(joysticks=(LegacyJoystick(),) * 3), "joysticks"),
    (LegacyControlPacket(joysticks=(LegacyJoystick(),) * 3 + (None,)), "joysticks[3]"),
    (LegacyControlPacket(joysticks=(LegacyJoystick((0,) * 5),) + (LegacyJoystick((0,) * 7),) * 3),
     "joysticks[0].axes"),
    (LegacyControlPacket(joysticks=(LegacyJoystick((0, 128, 0, 0, 0, 0)),) * 4), "joysticks[0].axes[1]"),
    (LegacyControlPacket(joysticks=(LegacyJoystick(),) * 3 + (LegacyJoystick(buttons=0x10000),)),
     "joysticks[3].buttons"),
    (LegacyControlPacket(analog=(0, 0, 1024, 0)), "analog[2]"),
    (LegacyControlPacket(analog=(0, 0, 0, -1)), "analog[3]"),
    (LegacyControlPacket(analog=(0, 0, 0)), "analog"),
    (LegacyControlPacket(crio_checksum=bytes(7)), "crio_checksum"),
    (LegacyControlPacket(fpga_checksums=(bytes(4),) * 3), "fpga_checksums"),
    (LegacyControlPacket(fpga_checksums=(bytes(4),) * 3 + (bytes(5),)), "fpga_checksums[3]"),
    (LegacyControlPacket(ds_version="1002080"), "ds_version"),
    (LegacyControlPacket(ds_version="100208000"), "ds_version"),
    (LegacyControlPacket(ds_version="\ud800" * 8), "ds_version"),
    (LegacyControlPacket(unknown_0x50=bytes(34)), "unknown_0x50"),
    (LegacyControlPacket(dynamic_blocks=(DynamicBlock(1, bytes(255)),)), "dynamic_blocks[0].data"),
    (LegacyControlPacket(dynamic_blocks=(DynamicBlock(256),)), "dynamic_blocks[0].block_id"),
    (LegacyControlPacket(dynamic_blocks=(DynamicBlock(-1),)), "dynamic_blocks[0].block_id"),
    (LegacyControlPacket(dynamic_blocks=((1, b""),)), "dynamic_blocks[0]"),
    (LegacyControlPacket(dynamic_padding=b"\x01"), "dynamic_padding"),
    (LegacyControlPacket(dynamic_padding=bytes(902)), "dynamic_padding"),
    (LegacyControlPacket(reserved=bytes(3)), "reserved"),
    (LegacyStatusPacket(control=256), "control"),
    (LegacyStatusPacket(battery=12.34), "battery"),
    (LegacyStatusPacket(battery=(0x12, 0x100)), "battery[1]"),
    (LegacyStatusPacket(team=70000), "team"),
    (LegacyStatusPacket(mac=bytes(5)), "mac"),
    (LegacyStatusPacket(fpga_version="063008"), "fpga_version"),
    (LegacyStatusPacket(update_number=-1), "update_number"),
    (LegacyStatusPacket(user_data_high=bytes(948)), "user_data_high"),
    (LegacyStatusPacket(error_text=3), "error_text"),
    (LegacyStatusPacket(user_data_low="text"), "user_data_low"),
    (LegacyStatusPacket(user_padding=bytes(940)), "user_padding"),
    (LegacyStatusPacket(dseio_status=bytes(33)), "dseio_status"),
    (LegacyStatusPacket(lcd=("x" * 22,)), "lcd[0]"),
    (LegacyStatusPacket(lcd=("",) * 7), "lcd"),
    (LegacyStatusPacket(lcd=(None,)), "lcd[0]"),
    (LegacyDashboardPacket(team=25600), "team"),
    (LegacyDashboardPacket(reply_packets=65536), "reply_packets"),
    (LegacyDashboardPacket(error_bits=256), "error_bits"),
    (LegacyDashboardPacket(ds_version="v"), "ds_version"),
    (LegacyDashboardPacket(user_data_high=bytes(972)), "user_data_high"),
    (LegacyDashboardPacket(unknown_0x12=bytes(7)), "unknown_0x12"),
])
def test_encoding_refuses_bad_values(packet, field):
    assert where(protocol_error(packet.encode))[1:] == (field, None)


def test_encode_error_messages():
    assert (str(protocol_error(LegacyControlPacket(analog=(1024, 0, 0, 0)).encode))
            == "LegacyControlPacket.analog[0]: 1024 is outside 0..1023")
    assert (str(protocol_error(LegacyStatusPacket(lcd=("x" * 22,)).encode))
            == "LegacyStatusPacket.lcd[0]: 22 bytes is too long (at most 21)")


# -- annotation -------------------------------------------------------------------------------
def test_control_annotation_tiles_with_few_spans():
    spans = annotate_legacy_control(GOLDEN_CONTROL)
    assert_tiles(spans, GOLDEN_CONTROL)
    # 6 header + 4 x 7 joystick + 4 analog + 1 + 4 checksums + version + unknown + 2 blocks
    # (size, id, data / size, id) + padding + reserved + crc: no span per zero byte.
    assert len(spans) == 53
    by = {s.field: s for s in spans}
    assert by["control"].meaning == "control: not e-stopped, enabled, teleop"
    assert by["ds_digital_in"].meaning.endswith("on 1, 3")
    assert by["team"].value == 294
    assert by["alliance"].value == "'R'" and by["position"].meaning.startswith("position 1")
    assert by["joysticks[0].buttons"].meaning.endswith("down 1, 12")
    assert by["joysticks[0].axes[0]"].meaning.startswith("joystick 1 axis 1: +1.000")
    assert by["joysticks[3].buttons"].meaning.endswith("(bits 12-15 are unused)")
    assert by["analog[2]"].meaning == "DS analog input 3: 1023/1023 (10-bit, right-justified)"
    assert by["ds_version"].meaning.startswith("DS version 10.02.08.00")
    assert (by["unknown_0x50"].offset, by["unknown_0x50"].length, by["unknown_0x50"].value) == (0x50, 35, "00 x 35")
    assert by["dynamic_blocks[0].id"].meaning == "block id 17: DS Enhanced I/O input"
    assert (by["dynamic_padding"].offset, by["dynamic_padding"].length) == (0x7A, 0x3F8 - 0x7A)
    assert (by["reserved"].offset, by["reserved"].length) == (0x3F8, 4)
    assert by["crc"].meaning.endswith(": OK")


def test_status_and_dashboard_annotation_tile():
    # Status: 10 header spans, 3 x (length, data), padding, DSEIO, reserved, crc. Dashboard: 12
    # header spans, 3 lengths and 2 data (user data is empty), padding, reserved, crc.
    for data, annotate, n in ((GOLDEN_STATUS, annotate_legacy_status, 20),
                              (GOLDEN_DASHBOARD, annotate_legacy_dashboard, 20)):
        spans = annotate(data)
        assert_tiles(spans, data)
        assert len(spans) == n
    by = {s.field: s for s in annotate_legacy_status(GOLDEN_STATUS)}
    assert by["mac"].value == "00:80:2f:11:4d:ac"
    assert by["error_text"].value == "oops"
    assert (by["user_padding"].offset, by["user_padding"].length) == (0x36, 0x3D8 - 0x36)
    assert by["control"].meaning.startswith("control byte echoed from the DS: not e-stopped, enabled")


def test_kinds_are_registered():
    for name in ("legacy-ds-to-robot", "legacy-robot-to-ds", "legacy-dashboard", "legacy-netconsole"):
        assert kinds.get(name).name == name
    assert kinds.decode("legacy-ds-to-robot", GOLDEN_CONTROL).team == 294
    assert_tiles(kinds.annotate("legacy-robot-to-ds", GOLDEN_STATUS_LCD), GOLDEN_STATUS_LCD)


# -- properties -------------------------------------------------------------------------------
# Hypothesis pays per draw, not per byte (about 0.1 ms a draw here), and CI runs 3000
# examples: so each message is built from one blob of random bytes for its fixed fields plus a
# few draws for the variable parts, rather than one draw per field.
_STATION_PAIRS = {b"R1", b"R2", b"R3", b"B1", b"B2", b"B3"}
_STICKS = struct.Struct(">" + "6bH" * 4)


def _blob(n: int):
    return st.binary(min_size=n, max_size=n)


def _text(b: bytes) -> str:
    return b.decode("utf-8", "surrogateescape")


class _Cursor:
    """Hands out consecutive slices of one random blob."""

    def __init__(self, blob: bytes) -> None:
        self.blob, self.pos = blob, 0

    def take(self, n: int) -> bytes:
        self.pos += n
        return self.blob[self.pos - n:self.pos]

    def u8(self) -> int:
        return self.take(1)[0]

    def u16(self) -> int:
        return int.from_bytes(self.take(2), "big")


def _battery(c: _Cursor) -> tuple[int, int]:
    pick, raw = c.u8() % 3, c.take(2)
    if pick == 0:
        return NO_CODE_BATTERY
    if pick == 1:
        return volts_to_bcd(int.from_bytes(raw, "big") % 10000 / 100)
    return raw[0], raw[1]


@st.composite
def control_packets(draw):
    c = _Cursor(draw(_blob(120)))
    pick, pair = c.u8(), c.take(2)
    station = AllianceStation(pick % 6) if pick < 192 or pair in _STATION_PAIRS else pair
    v = _STICKS.unpack(c.take(32))
    sticks = tuple(LegacyJoystick(v[k * 7:k * 7 + 6], v[k * 7 + 6]) for k in range(4))
    bits = c.u8()
    fixed = dict(
        packet_index=c.u16(), ds_digital_in=c.u8(), team=c.u16(), station=station, joysticks=sticks,
        analog=tuple(c.u16() & 0x3FF for _ in range(4)), crio_checksum=c.take(8),
        fpga_checksums=tuple(c.take(4) for _ in range(4)), ds_version=_text(c.take(8)),
        unknown_0x50=c.take(35), reserved=c.take(4))
    flags = {name: bool(bits >> k & 1) for k, name in enumerate(
        ("reset", "estop", "enabled", "autonomous", "fms_attached", "resync", "crio_checksum_bit",
         "fpga_checksum_bit"))}
    blocks, used = [], 0
    for block_id, data in draw(st.lists(st.tuples(st.integers(0, 255), st.binary(max_size=254)), max_size=4)):
        if used + 2 + len(data) <= 901:
            blocks.append(DynamicBlock(block_id, data))
            used += 2 + len(data)
    padding = draw(st.binary(max_size=min(40, 900 - used))) if used < 901 else b""
    padding = (b"\x00" + padding).rstrip(b"\x00") if padding else b""
    return LegacyControlPacket(**fixed, **flags, dynamic_blocks=tuple(blocks), dynamic_padding=padding)


@st.composite
def user_area(draw, room):
    high = draw(st.binary(max_size=300))
    errors = _text(draw(st.binary(max_size=300)))
    low = draw(st.binary(max_size=300))
    left = room - 12 - len(high) - len(errors.encode("utf-8", "surrogateescape")) - len(low)
    padding = draw(st.binary(max_size=min(left, 30))).rstrip(b"\x00")
    return dict(user_data_high=high, error_text=errors, user_data_low=low, user_padding=padding)


@st.composite
def status_packets(draw):
    c = _Cursor(draw(_blob(70)))
    fixed = dict(
        control=c.u8(), battery=_battery(c), ds_digital_out=c.u8(), unknown_0x04=c.take(4), team=c.u16(),
        mac=c.take(6), fpga_version=_text(c.take(8)), unknown_0x18=c.take(6), packet_index=c.u16(),
        update_number=c.u8(), dseio_status=c.take(32), reserved=c.take(4))
    lcd = None
    if draw(st.booleans()):
        text = draw(_blob(126 + 6))
        # Line i has text[126 + i] % 22 bytes; trailing spaces are padding, so none are generated.
        lcd = tuple(_text(text[21 * i:21 * i + text[126 + i] % 22].rstrip(b" ")) for i in range(6))
    return LegacyStatusPacket(**fixed, **draw(user_area(0x3D8 - 0x21)), lcd=lcd)


@st.composite
def dashboard_packets(draw):
    c = _Cursor(draw(_blob(32)))
    fixed = dict(
        packet_number=c.u16(), ds_digital_in=c.u8(), ds_digital_out=c.u8(), battery=_battery(c),
        control=c.u8(), error_bits=c.u8(), team=c.u16() % 25600, ds_version=_text(c.take(8)),
        unknown_0x12=c.take(6), reply_packets=c.u16(), update_number=c.u8(), reserved=c.take(4))
    return LegacyDashboardPacket(**fixed, **draw(user_area(0x3F2 - 0x1B)))


def _mutate(raw: bytearray, edits: bytes) -> None:
    """Each 3 bytes of ``edits``: a u16 position (mod the length) and the byte to put there."""
    for k in range(0, len(edits) - 2, 3):
        raw[int.from_bytes(edits[k:k + 2], "big") % len(raw)] = edits[k + 2]


@given(control_packets())
def test_control_round_trip(packet):
    assert len(assert_round_trip(packet, decode_legacy_control, annotate_legacy_control)) == 1024


@given(status_packets())
def test_status_round_trip(packet):
    data = assert_round_trip(packet, decode_legacy_status, annotate_legacy_status)
    assert len(data) == (1024 if packet.lcd is None else 1152)


@given(dashboard_packets())
def test_dashboard_round_trip(packet):
    assert len(assert_round_trip(packet, decode_legacy_dashboard, annotate_legacy_dashboard)) == 1018


@given(st.binary(max_size=2000))
def test_netconsole_round_trip(raw):
    text = decode_netconsole(raw)
    assert text.encode() == raw
    assert NetConsoleText(text.text) == text


KIND_GOLDENS = [
    ("legacy-ds-to-robot", GOLDEN_CONTROL, 0x3FC),
    ("legacy-robot-to-ds", GOLDEN_STATUS, 0x3FC),
    ("legacy-robot-to-ds", GOLDEN_STATUS_LCD, 0x3FC),
    ("legacy-dashboard", GOLDEN_DASHBOARD, 0x3F6),
]


@pytest.mark.parametrize("kind", ["legacy-ds-to-robot", "legacy-robot-to-ds", "legacy-dashboard",
                                  "legacy-netconsole"])
@given(data=st.binary(max_size=1200))
def test_random_bytes_give_a_packet_or_protocol_error(kind, data):
    decode_or_protocol_error(kind, data)


@pytest.mark.parametrize("kind,golden,crc_at", KIND_GOLDENS, ids=["control", "status", "status-lcd", "dashboard"])
@given(data=st.data())
def test_mutated_packets_with_a_good_crc(kind, golden, crc_at, data):
    """Flip, truncate and extend valid packets, then fix the CRC so the fields are exercised."""
    raw = bytearray(golden)
    _mutate(raw, data.draw(st.binary(min_size=3, max_size=24)))
    how = data.draw(st.sampled_from(["keep", "truncate", "extend"]))
    if how == "truncate":
        raw = raw[:data.draw(st.integers(0, len(raw)))]
    elif how == "extend":
        raw += data.draw(st.binary(min_size=1, max_size=200))
    if len(raw) >= crc_at + 4:
        _seal(raw, crc_at)
    raw = bytes(raw)
    decode_or_protocol_error(kind, raw)
    k = kinds.get(kind)
    spans, error = k.annotate_lenient(raw)
    assert_tiles(spans, raw)


@pytest.mark.parametrize("size,crc_at,decode", [(1024, 0x3FC, decode_legacy_control),
                                                (1024, 0x3FC, decode_legacy_status),
                                                (1152, 0x3FC, decode_legacy_status),
                                                (1018, 0x3F6, decode_legacy_dashboard)],
                         ids=["control", "status", "status-lcd", "dashboard"])
@given(data=st.data())
def test_random_right_sized_packets_with_a_good_crc(size, crc_at, decode, data):
    raw = bytearray(data.draw(st.binary(min_size=size, max_size=size)))
    if size == 1152 and data.draw(st.booleans()):
        raw[0x400:0x402] = b"\x9f\xff"
    if data.draw(st.booleans()):  # plausible values, so later fields are reached more often
        for at in (0x21, 0x1B) if decode is not decode_legacy_control else ():
            raw[at:at + 4] = data.draw(st.integers(0, 40)).to_bytes(4, "big")
        if decode is decode_legacy_control:
            for at in range(0x28, 0x30, 2):
                raw[at] &= 0x03  # 10-bit analog inputs
            raw[0x73] = data.draw(st.sampled_from([0, 1, 5, raw[0x73]]))
    raw = _seal(raw, crc_at)
    try:
        message = decode(raw)
    except ProtocolError as exc:
        assert exc.field and 0 <= exc.offset <= len(raw)
        return
    assert message.encode() == raw
    assert decode(raw, check_crc=False) == message


@given(st.data())
def test_fast_path_agrees_with_reference_walk(data):
    raw = bytearray(GOLDEN_CONTROL)
    # Mostly in the parsed part (header, analog, dynamic blocks: 0x00-0xff), sometimes anywhere.
    edits = bytearray(data.draw(st.binary(max_size=18)))
    if data.draw(st.booleans()):
        edits[0::3] = bytes(len(edits[0::3]))
    _mutate(raw, bytes(edits))
    raw = bytes(raw)
    try:
        fast = decode_legacy_control(raw, check_crc=False)
    except ProtocolError as exc:
        fast = str(exc)
    try:
        slow = walk_legacy_control(Reader(raw, "LegacyControlPacket"))
    except ProtocolError as exc:
        slow = str(exc)
    assert fast == slow


junk = st.one_of(st.none(), st.integers(-300, 70000), st.text(max_size=3), st.binary(max_size=3),
                 st.tuples(st.integers(-1, 2)), st.floats(allow_nan=True))


@given(st.sampled_from(["packet_index", "team", "ds_digital_in", "station", "joysticks", "analog",
                        "crio_checksum", "fpga_checksums", "ds_version", "unknown_0x50", "dynamic_blocks",
                        "dynamic_padding", "reserved"]), junk)
def test_encode_of_junk_names_a_field(field, value):
    """Whatever a caller puts in a field, encode gives bytes or a ProtocolError naming a field."""
    packet = LegacyControlPacket(**{field: value})
    try:
        data = packet.encode()
    except ProtocolError as exc:
        assert exc.field != "?" and exc.field.split("[")[0].split(".")[0] == field, exc
        return
    assert len(data) == 1024
