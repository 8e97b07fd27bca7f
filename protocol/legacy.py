"""The cRIO-era ("2010 legacy") protocol: DS -> robot control (UDP 1110), robot -> DS status
(UDP 1150), DS -> dashboard (UDP 1165) and the robot's NetConsole text (UDP 6666).

Source: docs/protocol.md#legacy-2010 (the seed frc_2010_protocol.txt, Peter Johnson, team 294,
settled by fieldbox's protocol notes). The 80-byte common control block
(the seed's "0x0-0x49" is a typo for 0x00-0x4f) matches ``FRCCommonControlData`` in National
Instruments' ``FRCComm.h`` of 2008-2010 (NetworkCommunication, "FRC Spec for Comm Protocol
Revision 4.5"): a big-endian PowerPC bit field whose first member ``reset`` is bit 0x80.
In later versions of that header bits 0x02/0x01 became ``test``/``checkVersions``; in 2010
they are the cRIO and FPGA checksum bits, as the seed says.

Every packet but the NetConsole text ends in a CRC-32 (``zlib.crc32``) stored big-endian,
computed with the CRC field zeroed (:func:`legacy_crc`). ``decode_*`` CHECK it and raise a
:class:`ProtocolError` naming ``crc`` and its offset so a role can count and drop the packet;
``decode_*(data, check_crc=False)`` and the walks (``annotate_*``) do not refuse a bad CRC:
the ``crc`` span's meaning says which CRC was expected and which was found.

The control packet lives in :mod:`protocol.legacy_control`, what the packets share (control
bits, BCD battery, CRC, user-data area) in :mod:`protocol.legacy_common`; this module holds
the status, dashboard and NetConsole packets, re-exports the rest and registers the kinds.

Decisions where the sources leave room:

* Undocumented bytes (0x50-0x72 of the control packet, the "?" rows of the others) and the
  seed's zero fields are kept raw so a decoded packet re-encodes byte-identical; they
  default to zeros.
* Padding after the dynamic blocks and after the user data is kept with its trailing zeros
  stripped (``b""`` = all zeros), so the defaults stay short and the wire stays identical.
* An alliance/position pair that names no station is kept as its two raw bytes.
* An analog input above 1023 is refused (a 10-bit value; encoding refuses it too).
* A dynamic block whose size runs past 0x3f7 does not make the control packet bad: the CRC
  held, so the control data is what the DS sent. That block and the rest of the area are
  kept raw in ``dynamic_padding`` (``blocks_malformed``), marked ``MALFORMED`` in the
  annotation, and a robot drops them, as the 2015+ robot drops a malformed tag. A bad CRC
  still drops the whole packet.
* Battery BCD that is not BCD is kept raw, with ``volts`` None: never a wrong number.
* The LCD extension (bytes 0x400-0x47f of a 1152-byte status packet) is NOT covered by the
  CRC: the seed says "CRC32 of 0-0x3ff", and we do exactly that.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Union

from .errors import ProtocolError
from .kinds import Kind
# Shared pieces; the public ones (bcd_to_volts, legacy_crc, CONTROL_* ...) are re-exported.
from .legacy_common import (CONTROL_AUTONOMOUS, CONTROL_CRIO_CHECKSUM, CONTROL_ENABLED, CONTROL_FMS_ATTACHED,
                            CONTROL_FPGA_CHECKSUM, CONTROL_NOT_ESTOP, CONTROL_RESET, CONTROL_RESYNC,
                            DEFAULT_DS_VERSION, NO_CODE_BATTERY, ZERO4, BcdBattery, bcd_span, bcd_to_volts,
                            bits_text, check_battery, check_raw, control_byte_text, crc_span, decode_checked,
                            encode_user_area, fixed_text, legacy_crc, reserved_span, volts_to_bcd,
                            walk_user_area, with_crc, zero_run)
# The control packet, re-exported: ``from protocol.legacy import LegacyControlPacket`` keeps working.
from .legacy_control import (CONTROL, CONTROL_SIZE, DYNAMIC_BLOCK_NAMES, EMPTY_LEGACY_JOYSTICK, MAX_BLOCK_DATA,
                             DynamicBlock, LegacyControlPacket, LegacyJoystick, annotate_legacy_control,
                             decode_legacy_control, walk_legacy_control)
from .wire import Reader, Span, annotate_with, check_int, encode_text

STATUS = "LegacyStatusPacket"
DASHBOARD = "LegacyDashboardPacket"
NETCONSOLE = "NetConsoleText"

PORT_ROBOT = 1110  # DS -> robot control
PORT_DS = 1150  # robot -> DS status
PORT_DASHBOARD = 1165  # DS -> dashboard
PORT_NETCONSOLE = 6666  # robot console text (a broadcast on a real field)

STATUS_SIZE = 1024
STATUS_LCD_SIZE = 1152
DASHBOARD_SIZE = 1018
NETCONSOLE_MAX = 65507  # the largest UDP payload over IPv4

DEFAULT_FPGA_VERSION = "06300800"
LCD_HEADER = b"\x9f\xff"
LCD_LINES = 6
LCD_WIDTH = 21

# Status packet layout.
_STATUS_USER_START = 0x21
_STATUS_USER_END = 0x3D8
_STATUS_CRC = 0x3FC
_DSEIO_LEN = 0x3F8 - 0x3D8  # 32
# Dashboard packet layout.
_DASH_USER_START = 0x1B
_DASH_USER_END = 0x3F2
_DASH_CRC = 0x3F6


# =========================================================================================
# robot -> DS: the status packet, UDP 1150
# =========================================================================================
@dataclass(frozen=True, slots=True)
class LegacyStatusPacket(BcdBattery):
    """Robot -> DS, UDP 1150, in reply to every control packet: 1024 bytes, 1152 with LCD."""

    control: int = CONTROL_NOT_ESTOP  # echo of the DS's control byte
    battery: tuple[int, int] = NO_CODE_BATTERY  # BCD (volts_to_bcd); 0x37 0x37 = no code
    ds_digital_out: int = 0  # bit 0 = output 1
    unknown_0x04: bytes = ZERO4
    team: int = 0
    mac: bytes = bytes(6)
    fpga_version: str = DEFAULT_FPGA_VERSION
    unknown_0x18: bytes = bytes(6)
    packet_index: int = 0  # echo of the control packet's index
    update_number: int = 0
    user_data_high: bytes = b""
    error_text: str = ""
    user_data_low: bytes = b""
    user_padding: bytes = b""  # after the user data up to 0x3d7, trailing zeros stripped
    dseio_status: bytes = bytes(_DSEIO_LEN)  # 0x3d8-0x3f7, overrideIOConfig() data
    reserved: bytes = ZERO4  # 0x3f8-0x3fb
    # None = no LCD data (1024 bytes). Else up to 6 lines of at most 21 bytes, space-padded on
    # the wire; decoding gives 6 lines with the padding spaces stripped.
    lcd: tuple[str, ...] | None = None

    @property
    def estop(self) -> bool:
        return not self.control & CONTROL_NOT_ESTOP

    @property
    def enabled(self) -> bool:
        return bool(self.control & CONTROL_ENABLED)

    @property
    def autonomous(self) -> bool:
        return bool(self.control & CONTROL_AUTONOMOUS)

    def encode(self) -> bytes:
        check_int(STATUS, "control", self.control, 0, 0xFF)
        b1, b2 = check_battery(STATUS, self.battery)
        check_int(STATUS, "ds_digital_out", self.ds_digital_out, 0, 0xFF)
        check_int(STATUS, "team", self.team, 0, 0xFFFF)
        check_int(STATUS, "packet_index", self.packet_index, 0, 0xFFFF)
        check_int(STATUS, "update_number", self.update_number, 0, 0xFF)
        head = b"".join((
            bytes((self.control, b1, b2, self.ds_digital_out)),
            check_raw(STATUS, "unknown_0x04", self.unknown_0x04, 4),
            self.team.to_bytes(2, "big"),
            check_raw(STATUS, "mac", self.mac, 6),
            fixed_text(STATUS, "fpga_version", self.fpga_version, 8),
            check_raw(STATUS, "unknown_0x18", self.unknown_0x18, 6),
            self.packet_index.to_bytes(2, "big"),
            bytes((self.update_number,)),
        ))
        user = encode_user_area(STATUS, _STATUS_USER_START, _STATUS_USER_END, self.user_data_high,
                                 self.error_text, self.user_data_low, self.user_padding)
        body = b"".join((head, user, check_raw(STATUS, "dseio_status", self.dseio_status, _DSEIO_LEN),
                         check_raw(STATUS, "reserved", self.reserved, 4)))
        packet = with_crc(body)
        if self.lcd is None:
            return packet
        return packet + LCD_HEADER + _encode_lcd(self.lcd)


def _encode_lcd(lines: object) -> bytes:
    if not isinstance(lines, (tuple, list)) or len(lines) > LCD_LINES:
        raise ProtocolError(STATUS, "lcd", None, f"must be a tuple of at most {LCD_LINES} lines")
    out = []
    for i in range(LCD_LINES):
        text = encode_text(STATUS, f"lcd[{i}]", lines[i], LCD_WIDTH) if i < len(lines) else b""
        out.append(text.ljust(LCD_WIDTH, b" "))
    return b"".join(out)


def walk_legacy_status(r: Reader) -> LegacyStatusPacket:
    """The reference walk. Does not refuse a bad CRC: the ``crc`` span says expected/found."""
    ctl = r.u8("control")
    r.explain(f"0x{ctl:02x}", f"control byte echoed from the DS: {control_byte_text(ctl)}")
    r.refuse_over(STATUS_LCD_SIZE, f"a 2010 status packet ({STATUS_SIZE} bytes, {STATUS_LCD_SIZE} with LCD text)")
    battery = bcd_span(r)
    dout = r.u8("ds_digital_out")
    r.explain(f"0x{dout:02x}", bits_text(dout, "DS digital outputs"))
    unknown4 = r.raw(4, "unknown_0x04")
    zero_run(r, unknown4, "bytes 0x04-0x07, not documented")
    team = r.u16("team", "team number")
    mac = r.raw(6, "mac")
    r.explain(":".join(f"{b:02x}" for b in mac), "cRIO MAC address")
    fpga = r.text(8, "fpga_version", "FPGA version, ASCII (06300800 on a 2010 cRIO)")
    unknown18 = r.raw(6, "unknown_0x18")
    zero_run(r, unknown18, "bytes 0x18-0x1d, not documented")
    index = r.u16("packet_index", "packet index echoed from the DS's control packet")
    update = r.u8("update_number", "user data update number (setStatusData)")
    high, errors, low, padding = walk_user_area(r, _STATUS_USER_END)
    dseio = r.raw(_DSEIO_LEN, "dseio_status")
    if dseio.strip(b"\0"):
        r.explain(None, "DS Enhanced I/O status block (overrideIOConfig), kept raw")
    else:
        r.explain(f"00 x {_DSEIO_LEN}", "DS Enhanced I/O status block (overrideIOConfig): all zero")
    reserved = reserved_span(r, 0x3F8)
    crc_span(r, _STATUS_CRC)
    lcd = None
    if not r.at_end():
        header = r.raw(2, "lcd.header")
        if header != LCD_HEADER:
            r.fail("lcd.header", f"{header.hex(' ')} is not the LCD marker 9f ff", r.pos - 2)
        r.explain(None, "9f ff: LCD text follows (not covered by the CRC)")
        lines = []
        for i in range(LCD_LINES):
            line = r.text(LCD_WIDTH, f"lcd[{i}]")
            r.explain(None, f"DS LCD line {i + 1} of 6, 21 characters, space-padded")
            lines.append(line.rstrip(" "))
        lcd = tuple(lines)
        r.expect_end()
    return LegacyStatusPacket(ctl, battery, dout, unknown4, team, mac, fpga, unknown18, index, update,
                              high, errors, low, padding, dseio, reserved, lcd)


def decode_legacy_status(data: bytes, *, check_crc: bool = True) -> LegacyStatusPacket:
    """Decode a 2010 robot -> DS packet (1024 bytes, 1152 with LCD). Raises only ProtocolError."""
    return decode_checked(walk_legacy_status, STATUS, data, (STATUS_SIZE, STATUS_LCD_SIZE), _STATUS_CRC, check_crc)


def annotate_legacy_status(data: bytes) -> list[Span]:
    return annotate_with(walk_legacy_status, STATUS, bytes(data))


# =========================================================================================
# DS -> dashboard, UDP 1165
# =========================================================================================
@dataclass(frozen=True, slots=True)
class LegacyDashboardPacket(BcdBattery):
    """DS -> dashboard, UDP 1165, 1018 bytes. Only partly known: unknown bytes stay zero."""

    packet_number: int = 0
    ds_digital_in: int = 0
    ds_digital_out: int = 0
    battery: tuple[int, int] = NO_CODE_BATTERY  # BCD, as the robot sent it
    control: int = CONTROL_NOT_ESTOP
    error_bits: int = 0
    team: int = 0  # sent as two bytes: team // 100 and team % 100 (294 -> 2, 94)
    ds_version: str = DEFAULT_DS_VERSION
    unknown_0x12: bytes = bytes(6)
    reply_packets: int = 0  # LITTLE-endian on the wire, as the seed says
    update_number: int = 0
    user_data_high: bytes = b""
    error_text: str = ""
    user_data_low: bytes = b""
    user_padding: bytes = b""  # after the user data up to 0x3f1, trailing zeros stripped
    reserved: bytes = ZERO4  # 0x3f2-0x3f5

    def encode(self) -> bytes:
        check_int(DASHBOARD, "packet_number", self.packet_number, 0, 0xFFFF)
        check_int(DASHBOARD, "ds_digital_in", self.ds_digital_in, 0, 0xFF)
        check_int(DASHBOARD, "ds_digital_out", self.ds_digital_out, 0, 0xFF)
        b1, b2 = check_battery(DASHBOARD, self.battery)
        check_int(DASHBOARD, "control", self.control, 0, 0xFF)
        check_int(DASHBOARD, "error_bits", self.error_bits, 0, 0xFF)
        check_int(DASHBOARD, "team", self.team, 0, 255 * 100 + 99)
        check_int(DASHBOARD, "reply_packets", self.reply_packets, 0, 0xFFFF)
        check_int(DASHBOARD, "update_number", self.update_number, 0, 0xFF)
        hundreds, ones = divmod(self.team, 100)
        head = b"".join((
            self.packet_number.to_bytes(2, "big"),
            bytes((self.ds_digital_in, self.ds_digital_out, b1, b2, self.control, self.error_bits,
                   hundreds, ones)),
            fixed_text(DASHBOARD, "ds_version", self.ds_version, 8),
            check_raw(DASHBOARD, "unknown_0x12", self.unknown_0x12, 6),
            self.reply_packets.to_bytes(2, "little"),  # the seed: "Reply packets sent (little endian)"
            bytes((self.update_number,)),
        ))
        user = encode_user_area(DASHBOARD, _DASH_USER_START, _DASH_USER_END, self.user_data_high,
                                 self.error_text, self.user_data_low, self.user_padding)
        body = head + user + check_raw(DASHBOARD, "reserved", self.reserved, 4)
        return with_crc(body)


def walk_legacy_dashboard(r: Reader) -> LegacyDashboardPacket:
    """The reference walk. Does not refuse a bad CRC: the ``crc`` span says expected/found."""
    number = r.u16("packet_number", "packet number (big endian)")
    r.refuse_over(DASHBOARD_SIZE, f"a 2010 dashboard packet (exactly {DASHBOARD_SIZE} bytes)")
    din = r.u8("ds_digital_in")
    r.explain(f"0x{din:02x}", bits_text(din, "DS digital inputs"))
    dout = r.u8("ds_digital_out")
    r.explain(f"0x{dout:02x}", bits_text(dout, "DS digital outputs"))
    battery = bcd_span(r)
    ctl = r.u8("control")
    r.explain(f"0x{ctl:02x}", f"control byte sent to the robot: {control_byte_text(ctl)}")
    errors_bits = r.u8("error_bits")
    r.explain(f"0x{errors_bits:02x}", "error bit field (meaning not documented)")
    hundreds = r.u8("team_hundreds", "team number // 100, as an integer (2 for 294)")
    ones = r.u8("team_ones")
    if ones > 99:
        r.fail("team_ones", f"{ones} is not the last two digits of a team number (0-99)", r.pos - 1)
    r.explain(None, f"team number % 100, as an integer: team {hundreds * 100 + ones}")
    version = r.text(8, "ds_version", "DS version, ASCII (10020800 is the 2010 DS 1.1)")
    unknown = r.raw(6, "unknown_0x12")
    zero_run(r, unknown, "bytes 0x12-0x17, not documented")
    raw = r.raw(2, "reply_packets")
    replies = int.from_bytes(raw, "little")
    # The seed says little endian here, unlike every other field: kept as the seed says.
    r.explain(replies, f"reply packets sent: {replies} (LITTLE endian, as the seed says)")
    update = r.u8("update_number", "user data update number (setStatusData)")
    high, errors, low, padding = walk_user_area(r, _DASH_USER_END)
    reserved = reserved_span(r, _DASH_USER_END)
    crc_span(r, _DASH_CRC)
    r.expect_end()
    return LegacyDashboardPacket(number, din, dout, battery, ctl, errors_bits, hundreds * 100 + ones,
                                 version, unknown, replies, update, high, errors, low, padding, reserved)


def decode_legacy_dashboard(data: bytes, *, check_crc: bool = True) -> LegacyDashboardPacket:
    """Decode a 2010 DS -> dashboard packet (1018 bytes). Raises only ProtocolError."""
    return decode_checked(walk_legacy_dashboard, DASHBOARD, data, (DASHBOARD_SIZE,), _DASH_CRC, check_crc)


def annotate_legacy_dashboard(data: bytes) -> list[Span]:
    return annotate_with(walk_legacy_dashboard, DASHBOARD, bytes(data))


# =========================================================================================
# robot -> NetConsole, UDP 6666
# =========================================================================================
@dataclass(frozen=True, slots=True)
class NetConsoleText:
    """Console output, the whole datagram as text (UTF-8, surrogateescape: any bytes)."""

    text: str = ""

    def encode(self) -> bytes:
        return encode_text(NETCONSOLE, "text", self.text, NETCONSOLE_MAX)


def walk_netconsole(r: Reader) -> NetConsoleText:
    if r.remaining() > NETCONSOLE_MAX:
        r.fail("text", f"{r.remaining()} bytes, a UDP datagram holds at most {NETCONSOLE_MAX}")
    return NetConsoleText(r.rest_text("text", "console output, plain text"))


def decode_netconsole(data: bytes) -> NetConsoleText:
    return walk_netconsole(Reader(bytes(data), NETCONSOLE))


def annotate_netconsole(data: bytes) -> list[Span]:
    return annotate_with(walk_netconsole, NETCONSOLE, bytes(data))


LegacyMessage = Union[LegacyControlPacket, LegacyStatusPacket, LegacyDashboardPacket, NetConsoleText]

__all__ = [
    "CONTROL_AUTONOMOUS", "CONTROL_CRIO_CHECKSUM", "CONTROL_ENABLED", "CONTROL_FMS_ATTACHED",
    "CONTROL_FPGA_CHECKSUM", "CONTROL_NOT_ESTOP", "CONTROL_RESET", "CONTROL_RESYNC",
    "DEFAULT_DS_VERSION", "DEFAULT_FPGA_VERSION", "DYNAMIC_BLOCK_NAMES", "DynamicBlock",
    "EMPTY_LEGACY_JOYSTICK", "KINDS", "LCD_HEADER", "LegacyControlPacket", "LegacyDashboardPacket",
    "LegacyJoystick", "LegacyStatusPacket", "NO_CODE_BATTERY", "NetConsoleText", "PORT_DASHBOARD",
    "PORT_DS", "PORT_NETCONSOLE", "PORT_ROBOT", "annotate_legacy_control", "annotate_legacy_dashboard",
    "annotate_legacy_status", "annotate_netconsole", "bcd_to_volts", "control_byte_text",
    "decode_legacy_control", "decode_legacy_dashboard", "decode_legacy_status", "decode_netconsole",
    "legacy_crc", "volts_to_bcd", "walk_legacy_control", "walk_legacy_dashboard",
    "walk_legacy_status", "walk_netconsole",
]

KINDS = (
    Kind("legacy-ds-to-robot", "2010 DS -> cRIO, UDP 1110", CONTROL, walk_legacy_control,
         decode_legacy_control),
    Kind("legacy-robot-to-ds", "2010 cRIO -> DS, UDP 1150", STATUS, walk_legacy_status,
         decode_legacy_status),
    Kind("legacy-dashboard", "2010 DS -> dashboard, UDP 1165", DASHBOARD, walk_legacy_dashboard,
         decode_legacy_dashboard),
    Kind("legacy-netconsole", "cRIO NetConsole text, UDP 6666", NETCONSOLE, walk_netconsole,
         decode_netconsole),
)
