"""The 2010 legacy protocol: what its packets share. The control-byte bits, the BCD battery,
the CRC-32 every packet but NetConsole ends in, the size check, the three u32-length user-data
fields of the status and dashboard packets, and the span helpers their walks have in common.

See :mod:`protocol.legacy` for the sources and the decisions; it re-exports the public names.
"""

from __future__ import annotations

import math
import zlib
from typing import Callable, TypeVar

from .errors import ProtocolError
from .wire import U32, Reader, check_int, encode_text

T = TypeVar("T")

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
NO_CODE_BATTERY = (0x37, 0x37)  # what the robot sends while no user code runs

ZERO4 = bytes(4)


# -- CRC and size ----------------------------------------------------------------------
def legacy_crc(data: bytes, crc_offset: int) -> int:
    """zlib's CRC-32 of ``data[0 : crc_offset + 4]`` with the four CRC bytes taken as zero.

    The CRC field is the last thing it covers: bytes after it (the status packet's LCD
    extension) are not part of the CRC, as the seed's "CRC32 of 0-0x3ff" says.
    """
    if crc_offset < 0 or crc_offset + 4 > len(data):
        raise ValueError(f"CRC field at {crc_offset} does not fit {len(data)} bytes")
    return zlib.crc32(ZERO4, zlib.crc32(memoryview(data)[:crc_offset]))


def with_crc(body: bytes) -> bytes:
    """``body`` and its CRC-32: the CRC field is the last 4 bytes, taken as zero (legacy_crc)."""
    return body + U32.pack(zlib.crc32(ZERO4, zlib.crc32(body)))


def _crc_verdict(data: bytes, crc_offset: int) -> tuple[int, int]:
    """(expected, found)."""
    return legacy_crc(data, crc_offset), int.from_bytes(data[crc_offset:crc_offset + 4], "big")


def verify_crc(message: str, data: bytes, crc_offset: int) -> None:
    expected, found = _crc_verdict(data, crc_offset)
    if expected != found:
        raise ProtocolError(message, "crc", crc_offset,
                            f"expected 0x{expected:08x}, found 0x{found:08x} (CRC-32 of bytes "
                            f"0x000-0x{crc_offset + 3:03x} with this field zeroed)")


def check_size(message: str, data: bytes, sizes: tuple[int, ...]) -> None:
    n = len(data)
    if n in sizes:
        return
    want = " or ".join(str(s) for s in sizes)
    smaller = [s for s in sizes if s < n]
    offset = n if n < sizes[0] else max(smaller)
    raise ProtocolError(message, "size", offset, f"{n} bytes; this packet is exactly {want} bytes")


def decode_checked(walk: Callable[[Reader], T], message: str, data: bytes, sizes: tuple[int, ...],
                   crc_offset: int, check: bool) -> T:
    """Check the size and (when ``check``) the CRC, then walk: what the ``decode_*`` do."""
    data = bytes(data)
    check_size(message, data, sizes)
    if check:
        verify_crc(message, data, crc_offset)
    return walk(Reader(data, message))


# -- BCD battery ------------------------------------------------------------------------
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


class BcdBattery:
    """``no_code`` and ``volts`` for a packet whose ``battery`` is the robot's two BCD bytes."""

    __slots__ = ()
    battery: tuple[int, int]

    @property
    def no_code(self) -> bool:
        """The battery bytes say no robot code is running (0x37 0x37)."""
        return tuple(self.battery) == NO_CODE_BATTERY

    @property
    def volts(self) -> float | None:
        """Battery volts, or None when no code runs or the bytes are not BCD."""
        battery = self.battery
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


# -- fields, checks and spans the packets share ------------------------------------------
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


def bits_text(b: int, what: str) -> str:
    on = [str(k + 1) for k in range(8) if b >> k & 1]
    return f"{what} 1-8 (bit 0 = #1): on {', '.join(on) or 'none'}"


def zero_run(r: Reader, value: bytes, what: str) -> None:
    """Make the last raw span of ``value`` read well: zero runs as one short value."""
    if value and not value.strip(b"\0"):
        r.explain(f"00 x {len(value)}", f"{what}: all zero")
    elif value:
        r.explain(None, f"{what}: NOT all zero, kept raw")


def fixed_text(message: str, field: str, text: str, n: int) -> bytes:
    data = encode_text(message, field, text)
    if len(data) != n:
        raise ProtocolError(message, field, None, f"{len(data)} bytes; must be exactly {n}")
    return data


def check_raw(message: str, field: str, value: object, n: int | None) -> bytes:
    if not isinstance(value, (bytes, bytearray)):
        raise ProtocolError(message, field, None, f"{type(value).__name__} is not bytes")
    if n is not None and len(value) != n:
        raise ProtocolError(message, field, None, f"{len(value)} bytes; must be exactly {n}")
    return bytes(value)


def check_battery(message: str, battery: object) -> tuple[int, int]:
    if not isinstance(battery, tuple) or len(battery) != 2:
        raise ProtocolError(message, "battery", None, f"{battery!r} is not a pair of BCD bytes "
                                                      "(use volts_to_bcd)")
    check_int(message, "battery[0]", battery[0], 0, 0xFF)
    check_int(message, "battery[1]", battery[1], 0, 0xFF)
    return battery


def bcd_span(r: Reader) -> tuple[int, int]:
    raw = r.raw(2, "battery")
    r.explain(f"{raw[0]:02x} {raw[1]:02x}", _battery_text(raw[0], raw[1]))
    return raw[0], raw[1]


def crc_span(r: Reader, crc_offset: int) -> int:
    found = r.u32("crc")
    expected = legacy_crc(r.data, crc_offset)
    covers = f"CRC-32 (zlib) of bytes 0x000-0x{crc_offset + 3:03x} with this field zeroed"
    if expected == found:
        r.explain(f"0x{found:08x}", f"{covers}: OK")
    else:
        r.explain(f"0x{found:08x}", f"{covers}: BAD, expected 0x{expected:08x}, found 0x{found:08x}")
    return found


def reserved_span(r: Reader, start: int) -> bytes:
    value = r.raw(4, "reserved")
    zero_run(r, value, f"bytes 0x{start:03x}-0x{start + 3:03x}, zero per the seed")
    return value


# -- user data: three u32-length fields, bounded by the end of their area ----------------
_USER_FIELDS = (
    ("user_data_high", "user data (setStatusData userDataHigh), raw bytes"),
    ("error_text", "error text (setErrorData)"),
    ("user_data_low", "user data (setStatusData userDataLow), raw bytes"),
)


def walk_user_area(r: Reader, end: int) -> tuple[bytes, str, bytes, bytes]:
    raw: list[bytes] = []
    text = ""
    for name, meaning in _USER_FIELDS:
        left = end - r.pos
        if left < 4:
            r.fail(f"{name}.length", f"needs 4 bytes, {max(left, 0)} left before 0x{end:03x}")
        n = r.u32(f"{name}.length", f"length of {name}, in bytes (32-bit big endian)")
        left = end - r.pos
        if n > left:
            r.fail(f"{name}.length", f"{n} bytes, only {left} left before 0x{end:03x}", r.pos - 4)
        if name == "error_text":
            text = r.text(n, name, meaning)
        else:
            raw.append(r.raw(n, name, meaning))
    padding = r.raw(end - r.pos, "user_padding")
    zero_run(r, padding, f"after the user data, up to 0x{end - 1:03x}")
    return raw[0], text, raw[1], padding.rstrip(b"\0")


def encode_user_area(message: str, start: int, end: int, high: object, errors: object,
                     low: object, padding: object) -> bytes:
    parts = []
    pos = start
    for k, ((name, _), value) in enumerate(zip(_USER_FIELDS, (high, errors, low))):
        if name == "error_text":
            data = encode_text(message, name, value)  # type: ignore[arg-type]
        else:
            data = check_raw(message, name, value, None)
        left = end - pos - 4 * (3 - k)  # its own length field and the ones after it
        if len(data) > left:
            raise ProtocolError(message, name, None,
                                f"{len(data)} bytes, only {max(left, 0)} fit before 0x{end:03x}")
        parts.append(U32.pack(len(data)))
        parts.append(data)
        pos += 4 + len(data)
    padding = check_raw(message, "user_padding", padding, None)
    if len(padding) > end - pos:
        raise ProtocolError(message, "user_padding", None,
                            f"{len(padding)} bytes, only {end - pos} fit before 0x{end:03x}")
    parts.append(padding)
    parts.append(bytes(end - pos - len(padding)))
    return b"".join(parts)
