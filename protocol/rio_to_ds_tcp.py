"""roboRIO -> Driver Station, TCP 1740: console output, errors and warnings, versions, fault
counts, radio events and the usage report.

Source: docs/protocol.md#rio-to-ds-tcp (the seed rio_to_ds.rst), settled by
docs/protocol.md#rio-behaviour (how a real roboRIO and WPILib's simulator behave). Where a
real peer or a real decoder differs from the seed, the code follows the peer and a comment
names both. The UDP status packet is in :mod:`protocol.rio_to_ds`, which also re-exports
everything here.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass
from typing import ClassVar, Union

from .enums import DeviceType, enum_or_int
from .errors import ProtocolError
from .frames import (KeepAlive, RawFrame, UsageReportFrame, decode_frame, keep_raw, walk_frame_header,
                     walk_usage_report)
from .wire import (F32, U16, Reader, Span, annotate_with, check_bytes, check_f32, check_int, encode_text,
                   tcp_frame, text8, text16)

TCP = "RioToDsFrame"
#: The largest roboRIO -> DS frame decoded (and what the DS's framer takes). The big ones are
#: an error message with its call stack and a console line, a few KiB from a real robot (the
#: 2021 capture's largest: 1,071 bytes); the wire would allow 65,537.
MAX_TCP_FRAME = 0x8000
_TCP_WHAT = "a roboRIO -> DS frame (a real robot's are a few KiB at most)"
FRAME_RADIO_EVENTS = 0x00
FRAME_USAGE_REPORT = 0x01
FRAME_DISABLE_FAULTS = 0x04
FRAME_RAIL_FAULTS = 0x05
FRAME_VERSION_INFO = 0x0A
FRAME_ERROR_MESSAGE = 0x0B
FRAME_STDOUT = 0x0C
FRAME_UNKNOWN_0D = 0x0D

ERROR_FLAG_IS_ERROR = 0x01
ERROR_FLAG_LV_CODE = 0x02


@dataclass(frozen=True, slots=True)
class RadioEvents:
    """Frame 0x00: radio event text (the seed shows ``Warning <Code> 44008 ...``)."""

    text: str = ""

    def encode(self) -> bytes:
        return tcp_frame(TCP, FRAME_RADIO_EVENTS, encode_text(TCP, "text", self.text, 0xFFFE))


@dataclass(frozen=True, slots=True)
class UsageReport(UsageReportFrame):
    """Frame 0x01: team number, one unknown byte, then usage entries (kept raw). The seed types
    the team's 2 bytes "string"; they are read as a u16, like DS -> FMS frame 0x15."""

    MESSAGE: ClassVar[str] = TCP
    FRAME_ID: ClassVar[int] = FRAME_USAGE_REPORT


@dataclass(frozen=True, slots=True)
class DisableFaults:
    """Frame 0x04: counts of disables from lost comms and from the 12 V rail."""

    comms: int = 0
    rail_12v: int = 0

    def encode(self) -> bytes:
        check_int(TCP, "comms", self.comms, 0, 0xFFFF)
        check_int(TCP, "rail_12v", self.rail_12v, 0, 0xFFFF)
        return tcp_frame(TCP, FRAME_DISABLE_FAULTS, U16.pack(self.comms) + U16.pack(self.rail_12v))


@dataclass(frozen=True, slots=True)
class RailFaults:
    """Frame 0x05: fault counts of the 6 V, 5 V and 3.3 V rails."""

    rail_6v: int = 0
    rail_5v: int = 0
    rail_3v3: int = 0

    def encode(self) -> bytes:
        for name in ("rail_6v", "rail_5v", "rail_3v3"):
            check_int(TCP, name, getattr(self, name), 0, 0xFFFF)
        return tcp_frame(TCP, FRAME_RAIL_FAULTS, _RAILS.pack(self.rail_6v, self.rail_5v, self.rail_3v3))


_RAILS = struct.Struct(">HHH")


@dataclass(frozen=True, slots=True)
class VersionInfo:
    """Frame 0x0a: one device's name and version. All fields zero/empty (payload
    ``00 00 00 00 00 00``) marks the end of the list: see :data:`END_OF_VERSION_LIST`."""

    device_type: DeviceType | int = DeviceType.SOFTWARE
    unknown: int = 0  # 2 bytes no document explains
    device_id: int = 0  # CAN id?
    name: str = ""
    version: str = ""

    @property
    def is_end_of_list(self) -> bool:
        return self == END_OF_VERSION_LIST

    def encode(self) -> bytes:
        check_int(TCP, "device_type", self.device_type, 0, 0xFF)
        check_int(TCP, "unknown", self.unknown, 0, 0xFFFF)
        check_int(TCP, "device_id", self.device_id, 0, 0xFF)
        payload = (bytes((int(self.device_type),)) + U16.pack(self.unknown) + bytes((self.device_id,))
                   + text8(TCP, "name", self.name) + text8(TCP, "version", self.version))
        return tcp_frame(TCP, FRAME_VERSION_INFO, payload)


END_OF_VERSION_LIST = VersionInfo()


@dataclass(frozen=True, slots=True)
class ErrorMessage:
    """Frame 0x0b: an error or warning for the DS's diagnostics box and log.

    Layout as real robots send it (docs/protocol.md#rio-to-ds-tcp; WPILib's ``HAL_SendError(isError,
    errorCode, isLVCode, details, location, callStack, printMsg)`` supplies the values, an
    i32 error code included): f32 timestamp, u16 sequence (shared with stdout), u16
    occurrence count, i32 error code, flags (0x01 error vs warning, 0x02 LabVIEW code), then
    details, location and call stack, each a u16-length string. The seed's table differs
    (a u8 "PrintMsg", a u16 error code, a bool is-error: 10 bytes before the strings, not
    13). open-ds reads the same bits: its ``hasPlacedBit(flags, 7)`` counts from the left, so
    bit 7 is 0x01 (error) and bit 6 is 0x02 (LabVIEW). We decode what real robots send.
    """

    timestamp: float = 0.0  # seconds since the robot's log started
    sequence: int = 0
    occurrences: int = 1
    error_code: int = 0
    is_error: bool = True  # False: a warning
    is_lv_code: bool = False
    details: str = ""
    location: str = ""
    call_stack: str = ""
    flags_other: int = 0  # flag bits besides 0x01/0x02, kept for byte identity

    @property
    def flags(self) -> int:
        return ((ERROR_FLAG_IS_ERROR if self.is_error else 0) | (ERROR_FLAG_LV_CODE if self.is_lv_code else 0)
                | self.flags_other)

    def encode(self) -> bytes:
        check_f32(TCP, "timestamp", self.timestamp)
        check_int(TCP, "sequence", self.sequence, 0, 0xFFFF)
        check_int(TCP, "occurrences", self.occurrences, 0, 0xFFFF)
        check_int(TCP, "error_code", self.error_code, -0x80000000, 0x7FFFFFFF)
        if check_int(TCP, "flags_other", self.flags_other, 0, 0xFF) & 0x03:
            raise ProtocolError(TCP, "flags_other", None, "may not hold the error/LabVIEW bits 0x03")
        payload = (_ERROR_HEAD.pack(self.timestamp, self.sequence, self.occurrences, self.error_code, self.flags)
                   + text16(TCP, "details", self.details) + text16(TCP, "location", self.location)
                   + text16(TCP, "call_stack", self.call_stack))
        return tcp_frame(TCP, FRAME_ERROR_MESSAGE, payload)


_ERROR_HEAD = struct.Struct(">fHHiB")


@dataclass(frozen=True, slots=True)
class StdoutMessage:
    """Frame 0x0c: one console line: f32 timestamp, u16 sequence, text to the end of the frame."""

    timestamp: float = 0.0
    sequence: int = 0
    text: str = ""

    def encode(self) -> bytes:
        check_f32(TCP, "timestamp", self.timestamp)
        check_int(TCP, "sequence", self.sequence, 0, 0xFFFF)
        return tcp_frame(TCP, FRAME_STDOUT, F32.pack(self.timestamp) + U16.pack(self.sequence)
                         + encode_text(TCP, "text", self.text, 0xFFFE - 6))


@dataclass(frozen=True, slots=True)
class Unknown0d:
    """Frame 0x0d: not documented; the seed shows ``00 00 04 04 04 04``. Kept raw."""

    data: bytes = b""

    def encode(self) -> bytes:
        return tcp_frame(TCP, FRAME_UNKNOWN_0D, check_bytes(TCP, "data", self.data))


@dataclass(frozen=True, slots=True)
class UnknownFrame(RawFrame):
    """A roboRIO -> DS frame with an id this library does not know: kept raw."""

    MESSAGE: ClassVar[str] = TCP


RioToDsFrame = Union[KeepAlive, RadioEvents, UsageReport, DisableFaults, RailFaults, VersionInfo,
                     ErrorMessage, StdoutMessage, Unknown0d, UnknownFrame]


def walk_tcp(r: Reader) -> RioToDsFrame:
    tag_id = walk_frame_header(r)
    if tag_id is None:
        return KeepAlive()
    r.refuse_over(MAX_TCP_FRAME, _TCP_WHAT)
    if tag_id == FRAME_STDOUT:
        r.explain("stdout", "frame 0x0c: a line of the robot program's console output")
        ts = r.f32("timestamp")
        r.explain(None, f"{ts:.3f} s since the robot's log started")
        seq = r.u16("sequence", "message sequence number (shared with error messages)")
        return StdoutMessage(ts, seq, r.rest_text("text", "console text, to the end of the frame"))
    if tag_id == FRAME_ERROR_MESSAGE:
        r.explain("error_message", "frame 0x0b: error or warning (layout real robots send, not the seed's)")
        ts = r.f32("timestamp")
        r.explain(None, f"{ts:.3f} s since the robot's log started")
        seq = r.u16("sequence", "message sequence number (shared with stdout)")
        count = r.u16("occurrences", "how many times this message has occurred")
        code = r.i32("error_code", "error code (i32; negative codes are NI/HAL errors)")
        flags = r.u8("flags")
        words = ["ERROR" if flags & ERROR_FLAG_IS_ERROR else "warning"]
        if flags & ERROR_FLAG_LV_CODE:
            words.append("LabVIEW error code")
        if flags & ~0x03:
            words.append(f"other bits 0x{flags & ~0x03:02x} (named by no document)")
        r.explain(f"0x{flags:02x}", "flags: " + ", ".join(words) + " (0x01 error, 0x02 LabVIEW code)")
        details = r.text16("details", "what happened")
        location = r.text16("location", "where it happened")
        stack = r.text16("call_stack", "call stack")
        r.expect_end()
        return ErrorMessage(ts, seq, count, code, bool(flags & ERROR_FLAG_IS_ERROR),
                            bool(flags & ERROR_FLAG_LV_CODE), details, location, stack, flags & ~0x03 & 0xFF)
    if tag_id == FRAME_VERSION_INFO:
        r.explain("version_info", "frame 0x0a: device version (all zero: end of the list)")
        dt = r.u8("device_type")
        device = enum_or_int(DeviceType, dt)
        r.explain(getattr(device, "name", dt), "device type: 0 software, 2 CAN Talon, 8 PDP, 9 PCM")
        unknown = r.u16("unknown", "2 bytes no document explains")
        dev_id = r.u8("device_id", "device id (CAN id?)")
        name = r.text8("name", "device or software name")
        version = r.text8("version", "version string")
        r.expect_end()
        return VersionInfo(device, unknown, dev_id, name, version)
    if tag_id == FRAME_RADIO_EVENTS:
        r.explain("radio_events", "frame 0x00: radio events")
        return RadioEvents(r.rest_text("text", "radio event text, to the end of the frame"))
    if tag_id == FRAME_USAGE_REPORT:
        return walk_usage_report(r, UsageReport, "team number (u16; the seed's table types it 2-byte string)",
                                 "1 byte no document explains")
    if tag_id == FRAME_DISABLE_FAULTS:
        r.explain("disable_faults", "frame 0x04: disable fault counts")
        comms = r.u16("comms", "disables from lost comms")
        v12 = r.u16("rail_12v", "disables from the 12 V rail (brownout)")
        r.expect_end()
        return DisableFaults(comms, v12)
    if tag_id == FRAME_RAIL_FAULTS:
        r.explain("rail_faults", "frame 0x05: rail fault counts")
        v6 = r.u16("rail_6v", "6 V rail faults")
        v5 = r.u16("rail_5v", "5 V rail faults")
        v33 = r.u16("rail_3v3", "3.3 V rail faults")
        r.expect_end()
        return RailFaults(v6, v5, v33)
    if tag_id == FRAME_UNKNOWN_0D:
        r.explain("unknown_0d", "frame 0x0d: not documented (the seed shows 00 00 04 04 04 04), kept raw")
        return Unknown0d(r.rest("data", "undocumented frame 0x0d data"))
    return keep_raw(r, UnknownFrame, "frame", tag_id, "undocumented frame data")


def decode_tcp(frame: bytes) -> RioToDsFrame:
    """Decode one whole roboRIO -> DS TCP frame (its u16 size included)."""
    return decode_frame(walk_tcp, TCP, frame, MAX_TCP_FRAME, _TCP_WHAT)


def annotate_tcp(frame: bytes) -> list[Span]:
    return annotate_with(walk_tcp, TCP, frame)


__all__ = [
    "DisableFaults", "END_OF_VERSION_LIST", "ERROR_FLAG_IS_ERROR", "ERROR_FLAG_LV_CODE", "ErrorMessage",
    "FRAME_DISABLE_FAULTS", "FRAME_ERROR_MESSAGE", "FRAME_RADIO_EVENTS", "FRAME_RAIL_FAULTS", "FRAME_STDOUT",
    "FRAME_UNKNOWN_0D", "FRAME_USAGE_REPORT", "FRAME_VERSION_INFO", "KeepAlive", "MAX_TCP_FRAME", "RadioEvents",
    "RailFaults", "RioToDsFrame", "StdoutMessage", "TCP", "Unknown0d", "UnknownFrame", "UsageReport",
    "VersionInfo", "annotate_tcp", "decode_tcp", "walk_tcp",
]
