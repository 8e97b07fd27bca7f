"""The cRIO-era ("2010 legacy") protocol: DS -> robot control (UDP 1110), robot -> DS status
(UDP 1150), DS -> dashboard (UDP 1165) and the robot's NetConsole text (UDP 6666).

Source: ``shared/seeds/frc_2010_protocol.txt`` (Peter Johnson, team 294), settled by
``shared/PROTOCOL-NOTES.md`` "The 2010 legacy protocol". The 80-byte common control block
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

Decisions where the sources leave room:

* Undocumented bytes (0x50-0x72 of the control packet, the "?" rows of the others) and the
  seed's zero fields are kept raw so a decoded packet re-encodes byte-identical; they
  default to zeros.
* Padding after the dynamic blocks and after the user data is kept with its trailing zeros
  stripped (``b""`` = all zeros), so the defaults stay short and the wire stays identical.
* An alliance/position pair that names no station is kept as its two raw bytes.
* An analog input above 1023 is refused (a 10-bit value; encoding refuses it too).
* Battery BCD that is not BCD is kept raw, with ``volts`` None: never a wrong number.
* The LCD extension (bytes 0x400-0x47f of a 1152-byte status packet) is NOT covered by the
  CRC: the seed says "CRC32 of 0-0x3ff", and we do exactly that.
"""

from __future__ import annotations

import math
import struct
import zlib
from dataclasses import dataclass
from typing import Union

from .ds_to_rio import int8_to_axis
from .enums import AllianceStation
from .errors import ProtocolError
from .kinds import Kind
from .wire import (TEXT_ENCODING, TEXT_ERRORS, U32, Reader, Span, check_int, encode_text,
                   unchecked_constructor)

CONTROL = "LegacyControlPacket"
STATUS = "LegacyStatusPacket"
DASHBOARD = "LegacyDashboardPacket"
NETCONSOLE = "NetConsoleText"

PORT_ROBOT = 1110  # DS -> robot control
PORT_DS = 1150  # robot -> DS status
PORT_DASHBOARD = 1165  # DS -> dashboard
PORT_NETCONSOLE = 6666  # robot console text (a broadcast on a real field)

CONTROL_SIZE = 1024
STATUS_SIZE = 1024
STATUS_LCD_SIZE = 1152
DASHBOARD_SIZE = 1018
NETCONSOLE_MAX = 65507  # the largest UDP payload over IPv4

# Control byte (FRCCommonControlData.control, 2010 layout).
CONTROL_RESET = 0x80
CONTROL_NOT_ESTOP = 0x40  # SET in normal operation: a clear bit is an e-stop
CONTROL_ENABLED = 0x20
CONTROL_AUTONOMOUS = 0x10
CONTROL_FMS_ATTACHED = 0x08
CONTROL_RESYNC = 0x04
CONTROL_CRIO_CHECKSUM = 0x02
CONTROL_FPGA_CHECKSUM = 0x01

DEFAULT_DS_VERSION = "10020800"  # 2010 DS 1.1 (10.02.08.00)
DEFAULT_FPGA_VERSION = "06300800"
NO_CODE_BATTERY = (0x37, 0x37)  # what the robot sends while no user code runs
LCD_HEADER = b"\x9f\xff"
LCD_LINES = 6
LCD_WIDTH = 21

# Control packet layout.
_DYNAMIC_START = 0x73
_DYNAMIC_END = 0x3F8
_CONTROL_RESERVED = 0x3F8
_CONTROL_CRC = 0x3FC
_UNKNOWN_0X50_LEN = _DYNAMIC_START - 0x50  # 35
MAX_BLOCK_DATA = 0xFE  # the size byte counts the id byte too
# Status packet layout.
_STATUS_USER_START = 0x21
_STATUS_USER_END = 0x3D8
_STATUS_CRC = 0x3FC
_DSEIO_LEN = 0x3F8 - 0x3D8  # 32
# Dashboard packet layout.
_DASH_USER_START = 0x1B
_DASH_USER_END = 0x3F2
_DASH_CRC = 0x3F6

# Dynamic block ids named in NI's FRCComm.h (kFRC_NetworkCommunication_DynamicType_*).
DYNAMIC_BLOCK_NAMES = {
    17: "DS Enhanced I/O input", 18: "DS Enhanced I/O output", 19: "Kinect header",
    20: "Kinect extra 1", 21: "Kinect vertices 1", 22: "Kinect extra 2",
    23: "Kinect vertices 2", 24: "Kinect joystick", 25: "Kinect custom",
}

_ZERO4 = bytes(4)


class _Irregular(Exception):
    """The fast path met something only the reference walk can name: fall back to it."""


# -- helpers ------------------------------------------------------------------------------
def legacy_crc(data: bytes, crc_offset: int) -> int:
    """zlib's CRC-32 of ``data[0 : crc_offset + 4]`` with the four CRC bytes taken as zero.

    The CRC field is the last thing it covers: bytes after it (the status packet's LCD
    extension) are not part of the CRC, as the seed's "CRC32 of 0-0x3ff" says.
    """
    if crc_offset < 0 or crc_offset + 4 > len(data):
        raise ValueError(f"CRC field at {crc_offset} does not fit {len(data)} bytes")
    return zlib.crc32(_ZERO4, zlib.crc32(memoryview(data)[:crc_offset]))


def _crc_verdict(data: bytes, crc_offset: int) -> tuple[int, int]:
    """(expected, found)."""
    return legacy_crc(data, crc_offset), int.from_bytes(data[crc_offset:crc_offset + 4], "big")


def _check_crc(message: str, data: bytes, crc_offset: int) -> None:
    expected, found = _crc_verdict(data, crc_offset)
    if expected != found:
        raise ProtocolError(message, "crc", crc_offset,
                            f"expected 0x{expected:08x}, found 0x{found:08x} (CRC-32 of bytes "
                            f"0x000-0x{crc_offset + 3:03x} with this field zeroed)")


def _check_size(message: str, data: bytes, sizes: tuple[int, ...]) -> None:
    n = len(data)
    if n in sizes:
        return
    want = " or ".join(str(s) for s in sizes)
    smaller = [s for s in sizes if s < n]
    offset = n if n < sizes[0] else max(smaller)
    raise ProtocolError(message, "size", offset, f"{n} bytes; this packet is exactly {want} bytes")


def bcd_to_volts(int_byte: int, frac_byte: int) -> float:
    """Two BCD bytes to volts: ``0x12, 0x34`` is 12.34 V. A nibble above 9 is a ProtocolError.

    (Another implementation read the first byte as ``b * 12 / 0x12``: that is not BCD.)
    """
    for field, b in (("battery.int", int_byte), ("battery.frac", frac_byte)):
        check_int("Battery", field, b, 0, 0xFF)
        if b >> 4 > 9 or b & 0xF > 9:
            raise ProtocolError("Battery", field, None, f"0x{b:02x} is not BCD (a digit above 9)")
    centi = ((int_byte >> 4) * 10 + (int_byte & 0xF)) * 100 + (frac_byte >> 4) * 10 + (frac_byte & 0xF)
    return centi / 100


def volts_to_bcd(volts: float) -> tuple[int, int]:
    """Volts (0 <= v < 100) to two BCD bytes, rounded to hundredths: 12.34 -> (0x12, 0x34)."""
    if isinstance(volts, bool) or not isinstance(volts, (int, float)) or not math.isfinite(volts):
        raise ProtocolError("Battery", "volts", None, f"{volts!r} is not a finite number")
    if not 0 <= volts < 100:
        raise ProtocolError("Battery", "volts", None, f"{volts} V is outside 0 <= v < 100")
    centi = round(volts * 100)
    if centi >= 10000:
        raise ProtocolError("Battery", "volts", None, f"{volts} V rounds to 100.00 V: no BCD for it")
    whole, frac = divmod(centi, 100)
    return (whole // 10) << 4 | whole % 10, (frac // 10) << 4 | frac % 10


def _is_bcd(b: int) -> bool:
    return b >> 4 <= 9 and b & 0xF <= 9


def _battery_volts(battery: tuple[int, int]) -> float | None:
    if tuple(battery) == NO_CODE_BATTERY or not (_is_bcd(battery[0]) and _is_bcd(battery[1])):
        return None
    return bcd_to_volts(battery[0], battery[1])


def _battery_text(b1: int, b2: int) -> str:
    raw = f"0x{b1:02x} 0x{b2:02x}"
    if (b1, b2) == NO_CODE_BATTERY:
        return f"battery: {raw} = no robot code running"
    if not (_is_bcd(b1) and _is_bcd(b2)):
        return f"battery: {raw} is not BCD (a digit above 9): kept raw, no voltage"
    return f"battery: {bcd_to_volts(b1, b2):.2f} V (BCD: integer volts {b1:02x}, hundredths {b2:02x})"


def control_byte_text(b: int) -> str:
    """The 2010 control byte in words."""
    words = ["not e-stopped" if b & CONTROL_NOT_ESTOP else "E-STOPPED (0x40 clear)",
             "enabled" if b & CONTROL_ENABLED else "disabled",
             "autonomous" if b & CONTROL_AUTONOMOUS else "teleop"]
    if b & CONTROL_RESET:
        words.insert(0, "RESET")
    if b & CONTROL_FMS_ATTACHED:
        words.append("FMS attached")
    if b & CONTROL_RESYNC:
        words.append("resync")
    if b & CONTROL_CRIO_CHECKSUM:
        words.append("cRIO checksum bit")
    if b & CONTROL_FPGA_CHECKSUM:
        words.append("FPGA checksum bit")
    return ", ".join(words)


def _bits_text(b: int, what: str) -> str:
    on = [str(k + 1) for k in range(8) if b >> k & 1]
    return f"{what} 1-8 (bit 0 = #1): on {', '.join(on) or 'none'}"


def _zero_run(r: Reader, value: bytes, what: str) -> None:
    """Make the last raw span of ``value`` read well: zero runs as one short value."""
    if value and not value.strip(b"\0"):
        r.explain(f"00 x {len(value)}", f"{what}: all zero")
    elif value:
        r.explain(None, f"{what}: NOT all zero, kept raw")


def _fixed_text(message: str, field: str, text: str, n: int) -> bytes:
    data = encode_text(message, field, text)
    if len(data) != n:
        raise ProtocolError(message, field, None, f"{len(data)} bytes; must be exactly {n}")
    return data


def _check_raw(message: str, field: str, value: object, n: int | None) -> bytes:
    if not isinstance(value, (bytes, bytearray)):
        raise ProtocolError(message, field, None, f"{type(value).__name__} is not bytes")
    if n is not None and len(value) != n:
        raise ProtocolError(message, field, None, f"{len(value)} bytes; must be exactly {n}")
    return bytes(value)


def _check_battery(message: str, battery: object) -> tuple[int, int]:
    if not isinstance(battery, tuple) or len(battery) != 2:
        raise ProtocolError(message, "battery", None, f"{battery!r} is not a pair of BCD bytes "
                                                      "(use volts_to_bcd)")
    check_int(message, "battery[0]", battery[0], 0, 0xFF)
    check_int(message, "battery[1]", battery[1], 0, 0xFF)
    return battery


def _bcd_span(r: Reader) -> tuple[int, int]:
    raw = r.raw(2, "battery")
    r.explain(f"{raw[0]:02x} {raw[1]:02x}", _battery_text(raw[0], raw[1]))
    return raw[0], raw[1]


def _crc_span(r: Reader, crc_offset: int) -> int:
    found = r.u32("crc")
    expected = legacy_crc(r.data, crc_offset)
    covers = f"CRC-32 (zlib) of bytes 0x000-0x{crc_offset + 3:03x} with this field zeroed"
    if expected == found:
        r.explain(f"0x{found:08x}", f"{covers}: OK")
    else:
        r.explain(f"0x{found:08x}", f"{covers}: BAD, expected 0x{expected:08x}, found 0x{found:08x}")
    return found


def _reserved_span(r: Reader, start: int) -> bytes:
    value = r.raw(4, "reserved")
    _zero_run(r, value, f"bytes 0x{start:03x}-0x{start + 3:03x}, zero per the seed")
    return value


# -- user data: three u32-length fields, bounded by the end of their area ----------------
_USER_FIELDS = (
    ("user_data_high", "user data (setStatusData userDataHigh), raw bytes"),
    ("error_text", "error text (setErrorData)"),
    ("user_data_low", "user data (setStatusData userDataLow), raw bytes"),
)


def _walk_user_area(r: Reader, end: int) -> tuple[bytes, str, bytes, bytes]:
    values = []
    for name, meaning in _USER_FIELDS:
        left = end - r.pos
        if left < 4:
            r.fail(f"{name}.length", f"needs 4 bytes, {max(left, 0)} left before 0x{end:03x}")
        n = r.u32(f"{name}.length", f"length of {name}, in bytes (32-bit big endian)")
        left = end - r.pos
        if n > left:
            r.fail(f"{name}.length", f"{n} bytes, only {left} left before 0x{end:03x}", r.pos - 4)
        if name == "error_text":
            values.append(r.text(n, name, meaning))
        else:
            values.append(r.raw(n, name, meaning))
    padding = r.raw(end - r.pos, "user_padding")
    _zero_run(r, padding, f"after the user data, up to 0x{end - 1:03x}")
    return values[0], values[1], values[2], padding.rstrip(b"\0")


def _encode_user_area(message: str, start: int, end: int, high: object, errors: object,
                      low: object, padding: object) -> bytes:
    parts = []
    pos = start
    for k, ((name, _), value) in enumerate(zip(_USER_FIELDS, (high, errors, low))):
        if name == "error_text":
            data = encode_text(message, name, value)  # type: ignore[arg-type]
        else:
            data = _check_raw(message, name, value, None)
        left = end - pos - 4 * (3 - k)  # its own length field and the ones after it
        if len(data) > left:
            raise ProtocolError(message, name, None,
                                f"{len(data)} bytes, only {max(left, 0)} fit before 0x{end:03x}")
        parts.append(U32.pack(len(data)))
        parts.append(data)
        pos += 4 + len(data)
    padding = _check_raw(message, "user_padding", padding, None)
    if len(padding) > end - pos:
        raise ProtocolError(message, "user_padding", None,
                            f"{len(padding)} bytes, only {end - pos} fit before 0x{end:03x}")
    parts.append(padding)
    parts.append(bytes(end - pos - len(padding)))
    return b"".join(parts)


# =========================================================================================
# DS -> robot: the control packet, UDP 1110
# =========================================================================================
@dataclass(frozen=True, slots=True)
class LegacyJoystick:
    """One of four joysticks: six int8 axes, a u16 button word (12 used, bit 0 = button 1)."""

    axes: tuple[int, ...] = (0, 0, 0, 0, 0, 0)
    buttons: int = 0

    def pressed(self, button: int) -> bool:
        """Whether button ``button`` (1-based) is down."""
        return 1 <= button <= 16 and bool(self.buttons >> (button - 1) & 1)

    def axis(self, k: int) -> float:
        """Axis ``k`` (0-based) as -1.0..1.0 (negative /128, positive /127)."""
        return int8_to_axis(self.axes[k])


EMPTY_LEGACY_JOYSTICK = LegacyJoystick()


@dataclass(frozen=True, slots=True)
class DynamicBlock:
    """A dynamic block after 0x73: ``[u8 size of what follows][u8 id][data]``, kept raw."""

    block_id: int
    data: bytes = b""

    @property
    def name(self) -> str:
        return DYNAMIC_BLOCK_NAMES.get(self.block_id, f"block 0x{self.block_id:02x}")


_STATION_BYTES = {s: (b"R" if s.value < 3 else b"B") + str(s.position).encode() for s in AllianceStation}
_STATION_FROM_BYTES = {v: k for k, v in _STATION_BYTES.items()}


@dataclass(frozen=True, slots=True)
class LegacyControlPacket:
    """DS -> robot, UDP 1110, 1024 bytes every 20 ms."""

    packet_index: int = 0
    reset: bool = False
    estop: bool = False  # the wire has the inverse: bit 0x40 "not e-stop", set normally
    enabled: bool = False
    autonomous: bool = False
    fms_attached: bool = False
    resync: bool = False
    crio_checksum_bit: bool = False
    fpga_checksum_bit: bool = False
    ds_digital_in: int = 0  # bit 0 = input 1
    team: int = 0
    # AllianceStation when the two ASCII bytes name one ('R'/'B', '1'-'3'), else the raw pair.
    station: Union[AllianceStation, bytes] = AllianceStation.RED1
    joysticks: tuple[LegacyJoystick, ...] = (EMPTY_LEGACY_JOYSTICK,) * 4
    analog: tuple[int, ...] = (0, 0, 0, 0)  # 10-bit, right-justified
    crio_checksum: bytes = bytes(8)
    fpga_checksums: tuple[bytes, ...] = (_ZERO4,) * 4
    ds_version: str = DEFAULT_DS_VERSION
    unknown_0x50: bytes = bytes(_UNKNOWN_0X50_LEN)
    dynamic_blocks: tuple[DynamicBlock, ...] = ()
    # What follows the blocks up to 0x3f7, trailing zeros stripped (b"" = all zero). When not
    # empty it starts with the 0 size byte that ends the blocks.
    dynamic_padding: bytes = b""
    reserved: bytes = _ZERO4  # 0x3f8-0x3fb, zero per the seed

    @property
    def control_byte(self) -> int:
        return ((CONTROL_RESET if self.reset else 0) | (0 if self.estop else CONTROL_NOT_ESTOP)
                | (CONTROL_ENABLED if self.enabled else 0)
                | (CONTROL_AUTONOMOUS if self.autonomous else 0)
                | (CONTROL_FMS_ATTACHED if self.fms_attached else 0)
                | (CONTROL_RESYNC if self.resync else 0)
                | (CONTROL_CRIO_CHECKSUM if self.crio_checksum_bit else 0)
                | (CONTROL_FPGA_CHECKSUM if self.fpga_checksum_bit else 0))

    def encode(self) -> bytes:
        """The 1024 bytes, CRC included. Raises ProtocolError naming the bad field."""
        try:
            return self._encode_fast()
        except (_Irregular, struct.error, TypeError, ValueError, OverflowError, AttributeError):
            self._validate()
            raise ProtocolError(CONTROL, "?", None, "cannot encode this packet") from None

    def _encode_fast(self) -> bytes:
        st = self.station
        st_bytes = _STATION_BYTES.get(st) if type(st) is AllianceStation else st
        if not isinstance(st_bytes, (bytes, bytearray)) or len(st_bytes) != 2:
            raise _Irregular
        sticks = self.joysticks
        if len(sticks) != 4:
            raise _Irregular
        args = [self.packet_index, self.control_byte, self.ds_digital_in, self.team, st_bytes]
        for stick in sticks:
            axes = stick.axes
            if type(stick) is not LegacyJoystick or len(axes) != 6:
                raise _Irregular
            args.extend(axes)
            args.append(stick.buttons)
        analog = self.analog
        if len(analog) != 4:
            raise _Irregular
        for a in analog:
            if not 0 <= a <= 1023:
                raise _Irregular
        args.extend(analog)
        fpga = self.fpga_checksums
        if len(self.crio_checksum) != 8 or len(fpga) != 4 or any(len(f) != 4 for f in fpga):
            raise _Irregular
        version = self.ds_version.encode(TEXT_ENCODING, TEXT_ERRORS)
        if len(version) != 8:
            raise _Irregular
        args.append(self.crio_checksum)
        args.append(b"".join(fpga))
        args.append(version)
        if len(self.unknown_0x50) != _UNKNOWN_0X50_LEN or len(self.reserved) != 4:
            raise _Irregular
        parts = [_CONTROL_HEAD.pack(*args), self.unknown_0x50]
        for block in self.dynamic_blocks:
            data = block.data
            if type(block) is not DynamicBlock or len(data) > MAX_BLOCK_DATA:
                raise _Irregular
            parts.append(bytes((len(data) + 1, block.block_id)))
            parts.append(data)
        padding = self.dynamic_padding
        if padding and padding[0]:
            raise _Irregular
        parts.append(padding)
        body = b"".join(parts)
        fill = _DYNAMIC_END - len(body)
        if fill < 0:
            raise _Irregular
        body = b"".join((body, bytes(fill), self.reserved))
        return body + U32.pack(zlib.crc32(_ZERO4, zlib.crc32(body)))

    def _validate(self) -> None:
        check_int(CONTROL, "packet_index", self.packet_index, 0, 0xFFFF)
        check_int(CONTROL, "ds_digital_in", self.ds_digital_in, 0, 0xFF)
        check_int(CONTROL, "team", self.team, 0, 0xFFFF)
        if not isinstance(self.station, AllianceStation):
            _check_raw(CONTROL, "station", self.station, 2)
        if not isinstance(self.joysticks, tuple) or len(self.joysticks) != 4:
            raise ProtocolError(CONTROL, "joysticks", None, "must be a tuple of exactly 4 LegacyJoystick")
        for i, stick in enumerate(self.joysticks):
            if not isinstance(stick, LegacyJoystick):
                raise ProtocolError(CONTROL, f"joysticks[{i}]", None,
                                    f"{type(stick).__name__} is not a LegacyJoystick")
            if not isinstance(stick.axes, tuple) or len(stick.axes) != 6:
                raise ProtocolError(CONTROL, f"joysticks[{i}].axes", None, "must be a tuple of exactly 6 axes")
            for k, a in enumerate(stick.axes):
                check_int(CONTROL, f"joysticks[{i}].axes[{k}]", a, -128, 127)
            check_int(CONTROL, f"joysticks[{i}].buttons", stick.buttons, 0, 0xFFFF)
        if not isinstance(self.analog, tuple) or len(self.analog) != 4:
            raise ProtocolError(CONTROL, "analog", None, "must be a tuple of exactly 4 inputs")
        for i, a in enumerate(self.analog):
            check_int(CONTROL, f"analog[{i}]", a, 0, 1023)
        _check_raw(CONTROL, "crio_checksum", self.crio_checksum, 8)
        if not isinstance(self.fpga_checksums, tuple) or len(self.fpga_checksums) != 4:
            raise ProtocolError(CONTROL, "fpga_checksums", None, "must be a tuple of exactly 4 x 4 bytes")
        for i, f in enumerate(self.fpga_checksums):
            _check_raw(CONTROL, f"fpga_checksums[{i}]", f, 4)
        _fixed_text(CONTROL, "ds_version", self.ds_version, 8)
        _check_raw(CONTROL, "unknown_0x50", self.unknown_0x50, _UNKNOWN_0X50_LEN)
        if not isinstance(self.dynamic_blocks, (tuple, list)):
            raise ProtocolError(CONTROL, "dynamic_blocks", None, "must be a tuple of DynamicBlock")
        pos = _DYNAMIC_START
        for i, block in enumerate(self.dynamic_blocks):
            if not isinstance(block, DynamicBlock):
                raise ProtocolError(CONTROL, f"dynamic_blocks[{i}]", None,
                                    f"{type(block).__name__} is not a DynamicBlock")
            check_int(CONTROL, f"dynamic_blocks[{i}].block_id", block.block_id, 0, 0xFF)
            data = _check_raw(CONTROL, f"dynamic_blocks[{i}].data", block.data, None)
            if len(data) > MAX_BLOCK_DATA:
                raise ProtocolError(CONTROL, f"dynamic_blocks[{i}].data", None,
                                    f"{len(data)} bytes, at most {MAX_BLOCK_DATA} (u8 size counts the id)")
            pos += 2 + len(data)
            if pos > _DYNAMIC_END:
                raise ProtocolError(CONTROL, f"dynamic_blocks[{i}]", None,
                                    f"ends at 0x{pos:03x}, past the dynamic area (0x073-0x3f7)")
        padding = _check_raw(CONTROL, "dynamic_padding", self.dynamic_padding, None)
        if len(padding) > _DYNAMIC_END - pos:
            raise ProtocolError(CONTROL, "dynamic_padding", None,
                                f"{len(padding)} bytes, only {_DYNAMIC_END - pos} left before 0x3f8")
        if padding and padding[0]:
            raise ProtocolError(CONTROL, "dynamic_padding", None,
                                "must start with the 0 size byte that ends the blocks")
        _check_raw(CONTROL, "reserved", self.reserved, 4)


# 0x00 index, control, digital in, team, alliance+position; 4 x (6 axes, buttons) from 0x08;
# 4 analog from 0x28; cRIO checksum 0x30; FPGA checksums 0x38; DS version 0x48-0x4f.
_CONTROL_HEAD = struct.Struct(">HBBH2s" + "6bH" * 4 + "4H8s16s8s")
assert _CONTROL_HEAD.size == 0x50


def _ascii_value(b: int) -> str:
    return repr(chr(b)) if 0x20 <= b < 0x7F else f"0x{b:02x}"


def walk_legacy_control(r: Reader) -> LegacyControlPacket:
    """The reference walk. Does not refuse a bad CRC: the ``crc`` span says expected/found."""
    index = r.u16("packet_index", "packet index, counts up every packet; the robot echoes it at 0x1e")
    ctl = r.u8("control")
    r.explain(f"0x{ctl:02x}", f"control: {control_byte_text(ctl)}")
    din = r.u8("ds_digital_in")
    r.explain(f"0x{din:02x}", _bits_text(din, "DS digital inputs"))
    team = r.u16("team", "team number")
    a = r.u8("alliance")
    r.explain(_ascii_value(a), {0x52: "alliance 'R': red", 0x42: "alliance 'B': blue"}.get(
        a, "alliance: not 'R' or 'B', kept raw"))
    p = r.u8("position")
    r.explain(_ascii_value(p), f"position {chr(p)} (ASCII '1'-'3')" if 0x31 <= p <= 0x33
              else "position: not ASCII '1'-'3', kept raw")
    pair = bytes((a, p))
    station = _STATION_FROM_BYTES.get(pair, pair)
    sticks = []
    for i in range(4):
        axes = []
        for k in range(6):
            v = r.i8(f"joysticks[{i}].axes[{k}]")
            r.explain(None, f"joystick {i + 1} axis {k + 1}: {int8_to_axis(v):+.3f} "
                            "(int8; negative /128, positive /127)")
            axes.append(v)
        buttons = r.u16(f"joysticks[{i}].buttons")
        down = [str(b + 1) for b in range(16) if buttons >> b & 1]
        extra = " (bits 12-15 are unused)" if buttons >> 12 else ""
        r.explain(f"0x{buttons:04x}", f"joystick {i + 1} buttons, bit 0 = button 1: down "
                                      f"{', '.join(down) or 'none'}{extra}")
        sticks.append(LegacyJoystick(tuple(axes), buttons))
    analog = []
    for i in range(4):
        v = r.u16(f"analog[{i}]")
        if v > 1023:
            r.fail(f"analog[{i}]", f"{v} is not a 10-bit value (0..1023)", r.pos - 2)
        r.explain(None, f"DS analog input {i + 1}: {v}/1023 (10-bit, right-justified)")
        analog.append(v)
    crio = r.raw(8, "crio_checksum", "cRIO checksum (kept raw)")
    fpga = tuple(r.raw(4, f"fpga_checksums[{i}]", f"FPGA checksum {i} (kept raw)") for i in range(4))
    version = r.text(8, "ds_version")
    r.explain(None, f"DS version {'.'.join(version[k:k + 2] for k in range(0, 8, 2))} "
                    "(ASCII; 10020800 is the 2010 DS 1.1)")
    unknown = r.raw(_UNKNOWN_0X50_LEN, "unknown_0x50")
    _zero_run(r, unknown, "bytes 0x050-0x072, not documented")
    r.need(_DYNAMIC_END - r.pos, "dynamic_blocks")
    blocks, padding = _walk_dynamic(r)
    reserved = _reserved_span(r, _CONTROL_RESERVED)
    _crc_span(r, _CONTROL_CRC)
    r.expect_end()
    return LegacyControlPacket(
        index, bool(ctl & CONTROL_RESET), not ctl & CONTROL_NOT_ESTOP, bool(ctl & CONTROL_ENABLED),
        bool(ctl & CONTROL_AUTONOMOUS), bool(ctl & CONTROL_FMS_ATTACHED), bool(ctl & CONTROL_RESYNC),
        bool(ctl & CONTROL_CRIO_CHECKSUM), bool(ctl & CONTROL_FPGA_CHECKSUM), din, team, station,
        tuple(sticks), tuple(analog), crio, fpga, version, unknown, blocks, padding, reserved)


def _walk_dynamic(r: Reader) -> tuple[tuple[DynamicBlock, ...], bytes]:
    blocks = []
    while r.pos < _DYNAMIC_END:
        where = f"dynamic_blocks[{len(blocks)}]"
        size = r.data[r.pos]
        if size == 0:
            break
        r.u8(f"{where}.size", f"block size: {size} byte(s) follow (id + {size - 1} data)")
        if r.pos + size > _DYNAMIC_END:
            r.fail(f"{where}.size", f"{size} bytes, only {_DYNAMIC_END - r.pos} left before 0x3f8", r.pos - 1)
        block_id = r.u8(f"{where}.id")
        name = DYNAMIC_BLOCK_NAMES.get(block_id)
        r.explain(None, f"block id {block_id}: {name}" if name else f"block id {block_id}: not documented")
        blocks.append(DynamicBlock(block_id, r.raw(size - 1, f"{where}.data", "block data, kept raw")))
    padding = r.raw(_DYNAMIC_END - r.pos, "dynamic_padding")
    if padding:
        if not padding.strip(b"\0"):
            r.explain(f"00 x {len(padding)}", "size byte 0: no more blocks; zeros up to 0x3f7")
        else:
            r.explain(None, "size byte 0: no more blocks; then bytes up to 0x3f7, NOT all zero, kept raw")
    return tuple(blocks), padding.rstrip(b"\0")


_new_joystick = unchecked_constructor(LegacyJoystick)
_new_control = unchecked_constructor(LegacyControlPacket)
_new_block = unchecked_constructor(DynamicBlock)


def decode_legacy_control(data: bytes, *, check_crc: bool = True) -> LegacyControlPacket:
    """Decode a 2010 DS -> robot packet. Raises only ProtocolError (size, crc, a field).

    ``check_crc=False`` is for the inspector: decode what is there even if the CRC is bad.
    """
    if type(data) is not bytes:
        data = bytes(data)
    _check_size(CONTROL, data, (CONTROL_SIZE,))
    if check_crc:
        _check_crc(CONTROL, data, _CONTROL_CRC)
    try:
        return _fast_control(data)
    except _Irregular:
        return walk_legacy_control(Reader(data, CONTROL))


def _fast_control(data: bytes) -> LegacyControlPacket:
    v = _CONTROL_HEAD.unpack_from(data, 0)
    ctl = v[1]
    pair = v[4]
    analog = v[33:37]
    if max(analog) > 1023:
        raise _Irregular
    f = v[38]
    blocks = []
    pos = _DYNAMIC_START
    while pos < _DYNAMIC_END:
        size = data[pos]
        if size == 0:
            break
        end = pos + 1 + size
        if end > _DYNAMIC_END:
            raise _Irregular
        blocks.append(_new_block(data[pos + 1], data[pos + 2:end]))
        pos = end
    return _new_control(
        v[0], ctl & 0x80 != 0, ctl & 0x40 == 0, ctl & 0x20 != 0, ctl & 0x10 != 0, ctl & 0x08 != 0,
        ctl & 0x04 != 0, ctl & 0x02 != 0, ctl & 0x01 != 0, v[2], v[3], _STATION_FROM_BYTES.get(pair, pair),
        (_new_joystick(v[5:11], v[11]), _new_joystick(v[12:18], v[18]),
         _new_joystick(v[19:25], v[25]), _new_joystick(v[26:32], v[32])),
        analog, v[37], (f[0:4], f[4:8], f[8:12], f[12:16]), v[39].decode(TEXT_ENCODING, TEXT_ERRORS),
        data[0x50:_DYNAMIC_START], tuple(blocks), data[pos:_DYNAMIC_END].rstrip(b"\0"),
        data[_CONTROL_RESERVED:_CONTROL_CRC])


def annotate_legacy_control(data: bytes) -> list[Span]:
    r = Reader(bytes(data), CONTROL, annotate=True)
    walk_legacy_control(r)
    return r.spans or []


# =========================================================================================
# robot -> DS: the status packet, UDP 1150
# =========================================================================================
@dataclass(frozen=True, slots=True)
class LegacyStatusPacket:
    """Robot -> DS, UDP 1150, in reply to every control packet: 1024 bytes, 1152 with LCD."""

    control: int = CONTROL_NOT_ESTOP  # echo of the DS's control byte
    battery: tuple[int, int] = NO_CODE_BATTERY  # BCD (volts_to_bcd); 0x37 0x37 = no code
    ds_digital_out: int = 0  # bit 0 = output 1
    unknown_0x04: bytes = _ZERO4
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
    reserved: bytes = _ZERO4  # 0x3f8-0x3fb
    # None = no LCD data (1024 bytes). Else up to 6 lines of at most 21 bytes, space-padded on
    # the wire; decoding gives 6 lines with the padding spaces stripped.
    lcd: tuple[str, ...] | None = None

    @property
    def no_code(self) -> bool:
        """The battery bytes say no robot code is running (0x37 0x37)."""
        return tuple(self.battery) == NO_CODE_BATTERY

    @property
    def volts(self) -> float | None:
        """Battery volts, or None when no code runs or the bytes are not BCD."""
        return _battery_volts(self.battery)

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
        b1, b2 = _check_battery(STATUS, self.battery)
        check_int(STATUS, "ds_digital_out", self.ds_digital_out, 0, 0xFF)
        check_int(STATUS, "team", self.team, 0, 0xFFFF)
        check_int(STATUS, "packet_index", self.packet_index, 0, 0xFFFF)
        check_int(STATUS, "update_number", self.update_number, 0, 0xFF)
        head = b"".join((
            bytes((self.control, b1, b2, self.ds_digital_out)),
            _check_raw(STATUS, "unknown_0x04", self.unknown_0x04, 4),
            self.team.to_bytes(2, "big"),
            _check_raw(STATUS, "mac", self.mac, 6),
            _fixed_text(STATUS, "fpga_version", self.fpga_version, 8),
            _check_raw(STATUS, "unknown_0x18", self.unknown_0x18, 6),
            self.packet_index.to_bytes(2, "big"),
            bytes((self.update_number,)),
        ))
        user = _encode_user_area(STATUS, _STATUS_USER_START, _STATUS_USER_END, self.user_data_high,
                                 self.error_text, self.user_data_low, self.user_padding)
        body = b"".join((head, user, _check_raw(STATUS, "dseio_status", self.dseio_status, _DSEIO_LEN),
                         _check_raw(STATUS, "reserved", self.reserved, 4)))
        packet = body + U32.pack(zlib.crc32(_ZERO4, zlib.crc32(body)))
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
    battery = _bcd_span(r)
    dout = r.u8("ds_digital_out")
    r.explain(f"0x{dout:02x}", _bits_text(dout, "DS digital outputs"))
    unknown4 = r.raw(4, "unknown_0x04")
    _zero_run(r, unknown4, "bytes 0x04-0x07, not documented")
    team = r.u16("team", "team number")
    mac = r.raw(6, "mac")
    r.explain(":".join(f"{b:02x}" for b in mac), "cRIO MAC address")
    fpga = r.text(8, "fpga_version", "FPGA version, ASCII (06300800 on a 2010 cRIO)")
    unknown18 = r.raw(6, "unknown_0x18")
    _zero_run(r, unknown18, "bytes 0x18-0x1d, not documented")
    index = r.u16("packet_index", "packet index echoed from the DS's control packet")
    update = r.u8("update_number", "user data update number (setStatusData)")
    high, errors, low, padding = _walk_user_area(r, _STATUS_USER_END)
    dseio = r.raw(_DSEIO_LEN, "dseio_status")
    if dseio.strip(b"\0"):
        r.explain(None, "DS Enhanced I/O status block (overrideIOConfig), kept raw")
    else:
        r.explain(f"00 x {_DSEIO_LEN}", "DS Enhanced I/O status block (overrideIOConfig): all zero")
    reserved = _reserved_span(r, 0x3F8)
    _crc_span(r, _STATUS_CRC)
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
    data = bytes(data)
    _check_size(STATUS, data, (STATUS_SIZE, STATUS_LCD_SIZE))
    if check_crc:
        _check_crc(STATUS, data, _STATUS_CRC)
    return walk_legacy_status(Reader(data, STATUS))


def annotate_legacy_status(data: bytes) -> list[Span]:
    r = Reader(bytes(data), STATUS, annotate=True)
    walk_legacy_status(r)
    return r.spans or []


# =========================================================================================
# DS -> dashboard, UDP 1165
# =========================================================================================
@dataclass(frozen=True, slots=True)
class LegacyDashboardPacket:
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
    reserved: bytes = _ZERO4  # 0x3f2-0x3f5

    @property
    def no_code(self) -> bool:
        return tuple(self.battery) == NO_CODE_BATTERY

    @property
    def volts(self) -> float | None:
        return _battery_volts(self.battery)

    def encode(self) -> bytes:
        check_int(DASHBOARD, "packet_number", self.packet_number, 0, 0xFFFF)
        check_int(DASHBOARD, "ds_digital_in", self.ds_digital_in, 0, 0xFF)
        check_int(DASHBOARD, "ds_digital_out", self.ds_digital_out, 0, 0xFF)
        b1, b2 = _check_battery(DASHBOARD, self.battery)
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
            _fixed_text(DASHBOARD, "ds_version", self.ds_version, 8),
            _check_raw(DASHBOARD, "unknown_0x12", self.unknown_0x12, 6),
            self.reply_packets.to_bytes(2, "little"),  # the seed: "Reply packets sent (little endian)"
            bytes((self.update_number,)),
        ))
        user = _encode_user_area(DASHBOARD, _DASH_USER_START, _DASH_USER_END, self.user_data_high,
                                 self.error_text, self.user_data_low, self.user_padding)
        body = head + user + _check_raw(DASHBOARD, "reserved", self.reserved, 4)
        return body + U32.pack(zlib.crc32(_ZERO4, zlib.crc32(body)))


def walk_legacy_dashboard(r: Reader) -> LegacyDashboardPacket:
    """The reference walk. Does not refuse a bad CRC: the ``crc`` span says expected/found."""
    number = r.u16("packet_number", "packet number (big endian)")
    din = r.u8("ds_digital_in")
    r.explain(f"0x{din:02x}", _bits_text(din, "DS digital inputs"))
    dout = r.u8("ds_digital_out")
    r.explain(f"0x{dout:02x}", _bits_text(dout, "DS digital outputs"))
    battery = _bcd_span(r)
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
    _zero_run(r, unknown, "bytes 0x12-0x17, not documented")
    raw = r.raw(2, "reply_packets")
    replies = int.from_bytes(raw, "little")
    # The seed says little endian here, unlike every other field: kept as the seed says.
    r.explain(replies, f"reply packets sent: {replies} (LITTLE endian, as the seed says)")
    update = r.u8("update_number", "user data update number (setStatusData)")
    high, errors, low, padding = _walk_user_area(r, _DASH_USER_END)
    reserved = _reserved_span(r, _DASH_USER_END)
    _crc_span(r, _DASH_CRC)
    r.expect_end()
    return LegacyDashboardPacket(number, din, dout, battery, ctl, errors_bits, hundreds * 100 + ones,
                                 version, unknown, replies, update, high, errors, low, padding, reserved)


def decode_legacy_dashboard(data: bytes, *, check_crc: bool = True) -> LegacyDashboardPacket:
    """Decode a 2010 DS -> dashboard packet (1018 bytes). Raises only ProtocolError."""
    data = bytes(data)
    _check_size(DASHBOARD, data, (DASHBOARD_SIZE,))
    if check_crc:
        _check_crc(DASHBOARD, data, _DASH_CRC)
    return walk_legacy_dashboard(Reader(data, DASHBOARD))


def annotate_legacy_dashboard(data: bytes) -> list[Span]:
    r = Reader(bytes(data), DASHBOARD, annotate=True)
    walk_legacy_dashboard(r)
    return r.spans or []


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
    r = Reader(bytes(data), NETCONSOLE, annotate=True)
    walk_netconsole(r)
    return r.spans or []


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
