"""Driver Station -> FMS: the UDP status packet (port 1160) and the TCP 1750 frames
(team number login, versions, usage report, log data, error/event data, challenge response,
DS ping), plus the challenge answer.

No seed document covers this direction. Source: docs/protocol.md#ds-to-fms (fieldbox's
protocol notes), checked against Cheesy Arena (``Team254/cheesy-arena``,
``field/driver_station_connection.go``), a real FMS that reads these packets, and open-ds
(``Boomaa23/open-ds``, ``data/send/SendTag.java``), an open DS that writes them. Where they
differ from the notes, a comment beside the code names both.

The status packet goes out at least every 500 ms, far below the 50 Hz control rate, so
there is no fast path: ``decode_status`` is the reference walk.
"""

from __future__ import annotations

import datetime as _dt
import math
import struct
from dataclasses import dataclass
from typing import Any, ClassVar, Union

from .enums import MODE_TEXT, Mode
from .errors import ProtocolError
from .fms_to_ds import DeviceVersion, VersionDevice, walk_frame_start
from .frames import (KeepAlive, RawFrame, UsageReportFrame, check_packet, decode_frame, keep_raw, validate_unknown_tag,
                     walk_tags, walk_usage_report)
from .kinds import Kind
from .wire import (U16, U32, U64, Reader, Span, UnknownTag, annotate_with, check_int, encode_text, over_bound,
                   tcp_frame, udp_tag, unchecked_constructor)

STATUS = "DsStatusPacket"
TCP = "DsToFmsFrame"

#: The largest DS status packet decoded; a longer one is refused by its length alone, before
#: anything is walked. By the layout a real DS's is at most 31 bytes (the 8-byte header and the
#: five tags of docs/protocol.md#ds-to-fms-status); the bound leaves room for tags no document names yet. UDP
#: would carry 65,507.
MAX_STATUS_SIZE = 1024
_STATUS_WHAT = "a DS status packet (a real DS's is at most 31 bytes)"
#: The largest DS -> FMS frame decoded (and what the FMS's framer takes, roles/cores/fms.py's
#: MAX_FRAME). A DS sends a few hundred bytes at most (an error event with its text is the
#: big one); Cheesy Arena reads 4 KiB at a time.
MAX_TCP_FRAME = 16 * 1024
_TCP_WHAT = "a DS -> FMS frame (a real DS's are a few hundred bytes)"

# Status byte (docs/protocol.md#ds-to-fms-status). Cheesy Arena reads 0x08 roboRIO, 0x10 radio and 0x20
# robot link from it; 0x40 is reserved and kept in status_other.
STATUS_ESTOP = 0x80
STATUS_RESERVED = 0x40
STATUS_ROBOT_COMMS = 0x20
STATUS_RADIO_PING = 0x10
STATUS_RIO_PING = 0x08
STATUS_ENABLED = 0x04
STATUS_MODE = 0x03

TAG_FIELD_RADIO = 0x00
TAG_COMMS = 0x01
TAG_LAPTOP = 0x02
TAG_ROBOT_RADIO = 0x03
TAG_PD_INFO = 0x04

MAX_BATTERY = 0xFFFF / 256  # 255.996 V: the largest value the u16 holds


# -- exact fixed-point helpers --------------------------------------------------------------
def _fixed(message: str, field: str, value: Any, scale: int, hi: int) -> int:
    """``value * scale`` as the wire's integer, refusing anything that would not round-trip."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ProtocolError(message, field, None, f"{value!r} is not a number")
    if not math.isfinite(value):
        raise ProtocolError(message, field, None, f"{value!r} is not a finite number")
    raw = value * scale
    if not math.isfinite(raw) or raw != int(raw):
        raise ProtocolError(message, field, None, f"{value!r} is not a multiple of 1/{scale}")
    raw = int(raw)
    if not 0 <= raw <= hi:
        raise ProtocolError(message, field, None, f"{value!r} is outside 0..{hi / scale:g}")
    return raw


def quantize_battery(volts: float) -> float:
    """The nearest voltage the wire can carry (steps of 1/256 V, 0..255.996): what a DS
    should put in ``battery`` from a measured voltage."""
    if volts != volts:
        return 0.0
    return min(max(round(volts * 256), 0), 0xFFFF) / 256


def quantize_half(value: float) -> float:
    """The nearest value a "halved" u8 field can carry (steps of 0.5, 0..127.5)."""
    if value != value:
        return 0.0
    return min(max(round(value * 2), 0), 0xFF) / 2


def _battery_text(raw: int) -> str:
    return f"battery: {raw / 256:.3f} V ({raw >> 8} + {raw & 0xFF}/256)"


# -- UDP tags -------------------------------------------------------------------------------
@dataclass(frozen=True, slots=True)
class FieldRadioMetrics:
    """UDP tag 0x00: the field radio's view of this DS's link."""

    signal_strength: int = 0
    bandwidth_utilization: int = 0


@dataclass(frozen=True, slots=True)
class CommsMetrics:
    """UDP tag 0x01: DS -> robot packet counts and trip time; the tag a real FMS reads for trip
    time and loss (Cheesy Arena reads it only when its size byte is 6)."""

    lost_packets: int = 0
    sent_packets: int = 0
    average_trip_time_ms: int = 0


@dataclass(frozen=True, slots=True)
class LaptopMetrics:
    """UDP tag 0x02: the DS laptop's battery and CPU, in percent."""

    battery_percent: int = 0
    cpu_percent: int = 0


@dataclass(frozen=True, slots=True)
class RobotRadioMetrics:
    """UDP tag 0x03: the robot radio's signal and bandwidth (same layout as tag 0x00)."""

    signal_strength: int = 0
    bandwidth_utilization: int = 0


@dataclass(frozen=True, slots=True)
class PdInfo:
    """UDP tag 0x04: power distribution info, empty."""


@dataclass(frozen=True, slots=True)
class EmptyTag:
    """A tag size byte of 0: no id, no data. docs/protocol.md#conventions does not allow it, but Cheesy
    Arena's reader skips such a byte and reads on, so it decodes (and re-encodes) as one byte."""


StatusTag = Union[FieldRadioMetrics, CommsMetrics, LaptopMetrics, RobotRadioMetrics, PdInfo,
                  EmptyTag, UnknownTag]

# tag id -> (class, struct of its payload, field names with their ranges)
_U8, _U16 = 0xFF, 0xFFFF
_TAGS: dict[int, tuple[type, struct.Struct, tuple[tuple[str, int], ...]]] = {
    TAG_FIELD_RADIO: (FieldRadioMetrics, struct.Struct(">BH"),
                      (("signal_strength", _U8), ("bandwidth_utilization", _U16))),
    TAG_COMMS: (CommsMetrics, struct.Struct(">HHB"),
                (("lost_packets", _U16), ("sent_packets", _U16), ("average_trip_time_ms", _U8))),
    TAG_LAPTOP: (LaptopMetrics, struct.Struct(">BB"), (("battery_percent", _U8), ("cpu_percent", _U8))),
    TAG_ROBOT_RADIO: (RobotRadioMetrics, struct.Struct(">BH"),
                      (("signal_strength", _U8), ("bandwidth_utilization", _U16))),
    TAG_PD_INFO: (PdInfo, struct.Struct(">"), ()),
}
_TAG_IDS = {cls: tag_id for tag_id, (cls, _, _) in _TAGS.items()}
_TAG_TITLES = {
    TAG_FIELD_RADIO: "field radio metrics", TAG_COMMS: "comms metrics",
    TAG_LAPTOP: "laptop metrics", TAG_ROBOT_RADIO: "robot radio metrics", TAG_PD_INFO: "PD info",
}
_FIELD_MEANINGS = {
    "signal_strength": "signal strength",
    "bandwidth_utilization": "bandwidth utilisation",
    "lost_packets": "DS -> robot packets lost",
    "sent_packets": "DS -> robot packets sent",
    "average_trip_time_ms": "average DS <-> robot trip time, ms (what Cheesy Arena shows)",
    "battery_percent": "laptop battery, %",
    "cpu_percent": "laptop CPU, %",
}


def _encode_status_tag(where: str, tag: object) -> bytes:
    if type(tag) is EmptyTag:
        return b"\x00"
    if type(tag) is UnknownTag:
        validate_unknown_tag(STATUS, where, tag)
        return udp_tag(STATUS, where, tag.tag_id, bytes(tag.data))
    tag_id = _TAG_IDS.get(type(tag))
    if tag_id is None:
        raise ProtocolError(STATUS, where, None, f"{type(tag).__name__} is not a status packet tag")
    _, st, fields = _TAGS[tag_id]
    values = [check_int(STATUS, f"{where}.{name}", getattr(tag, name), 0, hi) for name, hi in fields]
    return udp_tag(STATUS, where, tag_id, st.pack(*values))


# -- the status packet -------------------------------------------------------------------
@dataclass(frozen=True, slots=True)
class DsStatusPacket:
    """DS -> FMS UDP 1160, at least every 500 ms. The FMS finds the station by ``team``."""

    sequence: int = 0
    comm_version: int = 0x00
    estop: bool = False
    robot_comms: bool = False
    radio_ping: bool = False
    rio_ping: bool = False
    enabled: bool = False
    mode: Mode = Mode.TELEOP
    team: int = 0
    battery: float = 0.0  # volts, a multiple of 1/256 (see quantize_battery)
    tags: tuple[StatusTag, ...] = ()
    status_other: int = 0  # the reserved bit 0x40, kept for byte identity

    @property
    def status_byte(self) -> int:
        return ((STATUS_ESTOP if self.estop else 0) | (STATUS_ROBOT_COMMS if self.robot_comms else 0)
                | (STATUS_RADIO_PING if self.radio_ping else 0) | (STATUS_RIO_PING if self.rio_ping else 0)
                | (STATUS_ENABLED if self.enabled else 0) | int(self.mode) | self.status_other)

    def tag(self, cls: type) -> Any:
        """The first tag of type ``cls``, or None."""
        return next((t for t in self.tags if type(t) is cls), None)

    def encode(self) -> bytes:
        check_int(STATUS, "sequence", self.sequence, 0, 0xFFFF)
        check_int(STATUS, "comm_version", self.comm_version, 0, 0xFF)
        check_int(STATUS, "mode", self.mode, 0, 3)
        if check_int(STATUS, "status_other", self.status_other, 0, 0xFF) & ~STATUS_RESERVED:
            raise ProtocolError(STATUS, "status_other", None, "may only hold bit 0x40")
        check_int(STATUS, "team", self.team, 0, 0xFFFF)
        battery = _fixed(STATUS, "battery", self.battery, 256, 0xFFFF)
        head = _HEADER.pack(self.sequence, self.comm_version, self.status_byte, self.team, battery)
        data = head + b"".join(_encode_status_tag(f"tags[{i}]", t) for i, t in enumerate(self.tags))
        return check_packet(STATUS, data, len(self.tags), MAX_STATUS_SIZE, _STATUS_WHAT)


_HEADER = struct.Struct(">HBBHH")


def _status_text(b: int) -> str:
    words = ["E-STOP" if b & STATUS_ESTOP else "no e-stop",
             "robot comms" if b & STATUS_ROBOT_COMMS else "no robot comms",
             "radio ping ok" if b & STATUS_RADIO_PING else "no radio ping",
             "roboRIO ping ok" if b & STATUS_RIO_PING else "no roboRIO ping",
             "enabled" if b & STATUS_ENABLED else "disabled",
             MODE_TEXT[b & STATUS_MODE]]
    if b & STATUS_RESERVED:
        words.append("reserved bit 0x40")
    return ", ".join(words)


def walk_status(r: Reader) -> DsStatusPacket:
    ann = r.spans is not None
    seq = r.u16("sequence", "sequence number, one more per packet")
    ver = r.u8("comm_version", "comm version (0x00)")
    st = r.u8("status")
    if ann:
        r.explain(f"0x{st:02x}", f"status: {_status_text(st)}")
    team = r.u16("team", "team number: the FMS finds this DS's station by it, not by address")
    raw = r.u16("battery")
    if ann:
        r.explain(raw / 256, _battery_text(raw))
    r.refuse_over(MAX_STATUS_SIZE, _STATUS_WHAT)
    tags = walk_tags(r, _walk_status_tag)
    return DsStatusPacket(seq, ver, bool(st & STATUS_ESTOP), bool(st & STATUS_ROBOT_COMMS),
                          bool(st & STATUS_RADIO_PING), bool(st & STATUS_RIO_PING),
                          bool(st & STATUS_ENABLED), Mode(st & STATUS_MODE), team, raw / 256,
                          tags, st & STATUS_RESERVED)


def _walk_status_tag(r: Reader, where: str) -> StatusTag:
    size = r.u8(f"{where}.size", "tag size, counting the id byte")
    if size == 0:
        # docs/protocol.md's tags always hold an id; Cheesy Arena skips a 0 size byte and reads on.
        if r.spans is not None:
            r.explain(0, "tag size 0: an empty tag with no id (Cheesy Arena skips this byte)")
        return EmptyTag()
    t = r.child(size, where)
    tag_id = t.u8("id")
    known = _TAGS.get(tag_id)
    if known is not None and known[1].size == size - 1:
        cls, st, fields = known
        if t.spans is not None:
            t.explain(cls.__name__, f"tag 0x{tag_id:02x}: {_TAG_TITLES[tag_id]}")
        values = []
        for name, hi in fields:
            read = t.u8 if hi == _U8 else t.u16
            values.append(read(name, _FIELD_MEANINGS[name]))
        tag: StatusTag = cls(*values)
        return tag
    notes = None
    if known is not None and t.spans is not None:
        # Cheesy Arena ignores a comms tag whose size byte is not 6; so do we: kept raw.
        notes = {tag_id: f"tag 0x{tag_id:02x} ({_TAG_TITLES[tag_id]}) with {size - 1} data byte(s), "
                         f"not the {known[1].size} its layout has: kept raw"}
    return keep_raw(t, UnknownTag, "tag", tag_id, "tag data, kept raw", notes)


def decode_status(data: bytes) -> DsStatusPacket:
    """Decode a DS -> FMS status packet. Raises only :class:`ProtocolError`: at once, for a
    packet over :data:`MAX_STATUS_SIZE`."""
    if len(data) > MAX_STATUS_SIZE:
        raise over_bound(STATUS, len(data), MAX_STATUS_SIZE, _STATUS_WHAT)
    return walk_status(Reader(data, STATUS))


def annotate_status(data: bytes) -> list[Span]:
    return annotate_with(walk_status, STATUS, data)


# -- the challenge --------------------------------------------------------------------------
#: docs/protocol.md#fms-challenge: the 23 answers, by index ``(team * random) % 23``.
ROBOT_NAMES = (
    "Johnny Five", "Data", "ED-209", "Bishop", "NXT", "Optimus Prime", "Roomba", "Rosie",
    "The Terminator", "HAL 9000", "Sojourner", "R2-D2", "C-3PO", "Wall-E", "Curiosity",
    "Opportunity", "Spirit", "Cylons", "Stinky", "Iron Giant", "RCX", "EV3", "ASIMO",
)


def challenge_answer(team: int, random_value: int) -> str:
    """The robot name a DS of ``team`` answers to a challenge question with ``random_value``."""
    check_int("ChallengeResponse", "team", team, 0, 0xFFFF)
    check_int("ChallengeResponse", "random_value", random_value, 0, 0xFFFF)
    return ROBOT_NAMES[(team * random_value) % len(ROBOT_NAMES)]


def check_challenge_answer(team: int, random_value: int, answer: str) -> bool:
    """Whether ``answer`` is the right one (exact text) for ``team`` and ``random_value``."""
    return isinstance(answer, str) and answer == challenge_answer(team, random_value)


# -- TCP 1750, DS -> FMS ----------------------------------------------------------------------
FRAME_USAGE_REPORT = 0x15
FRAME_LOG_DATA = 0x16
FRAME_ERROR_EVENT_DATA = 0x17
FRAME_TEAM_NUMBER = 0x18
FRAME_CHALLENGE_RESPONSE = 0x1B
FRAME_DS_PING = 0x1C
FRAME_DS_PING_ALT = 0x1D
FRAME_HELLO = 0x1E  # tag 30: the 2027 FIRST Driver Station's login

LOG_RECORD_SIZE = 9
#: An error/event entry is at least a 16-byte timestamp and a u32 string length.
ERROR_EVENT_MIN_SIZE = 20
#: LabVIEW's epoch: the timestamps in error/event data count seconds from here.
LABVIEW_EPOCH = _dt.datetime(1904, 1, 1, tzinfo=_dt.timezone.utc)


@dataclass(frozen=True, slots=True)
class TeamNumber:
    """Frame 0x18: the login, the first frame on a connection: ``00 03 18 hi lo``. A real FMS
    closes a connection whose first frame is anything else."""

    team: int = 0

    def encode(self) -> bytes:
        check_int(TCP, "team", self.team, 0, 0xFFFF)
        return tcp_frame(TCP, FRAME_TEAM_NUMBER, U16.pack(self.team))


@dataclass(frozen=True, slots=True)
class UsageReport(UsageReportFrame):
    """Frame 0x15: u16 team, a u8 nobody has named, then usage entries (kept raw)."""

    MESSAGE: ClassVar[str] = TCP
    FRAME_ID: ClassVar[int] = FRAME_USAGE_REPORT


# Log-data robot status byte (docs/protocol.md#ds-to-fms-tcp); every bit is named, so nothing is kept aside.
LOG_BROWNOUT = 0x80
LOG_WATCHDOG = 0x40
LOG_DS_TELEOP = 0x20
LOG_DS_AUTO = 0x10
LOG_DS_DISABLED = 0x08
LOG_ROBOT_TELEOP = 0x04
LOG_ROBOT_AUTO = 0x02
LOG_ROBOT_DISABLED = 0x01
_LOG_BITS = (("brownout", LOG_BROWNOUT), ("watchdog", LOG_WATCHDOG), ("ds_teleop", LOG_DS_TELEOP),
             ("ds_auto", LOG_DS_AUTO), ("ds_disabled", LOG_DS_DISABLED),
             ("robot_teleop", LOG_ROBOT_TELEOP), ("robot_auto", LOG_ROBOT_AUTO),
             ("robot_disabled", LOG_ROBOT_DISABLED))


@dataclass(frozen=True, slots=True)
class LogRecord:
    """One 9-byte record of a log-data frame.

    The trip-time byte is the DS <-> robot round trip in whole ms, the same figure as the
    comms-metrics UDP tag (docs/protocol.md#log-trip; FRCture: "actual trip time is half",
    which is why Cheesy Arena shows byte / 2 as the one-way time). The CAN and signal bytes
    are "halved": they carry the value times two (0.5 steps), as the DS's own .dslog files do.
    """

    trip_time_ms: int = 0  # round trip, ms
    lost_packets: int = 0
    battery: float = 0.0  # volts, byte pair / 256
    brownout: bool = False
    watchdog: bool = False
    ds_teleop: bool = False
    ds_auto: bool = False
    ds_disabled: bool = False
    robot_teleop: bool = False
    robot_auto: bool = False
    robot_disabled: bool = False
    can_utilization: float = 0.0  # percent, byte / 2
    signal_db: float = 0.0  # byte / 2
    bandwidth: float = 0.0  # Mbit/s, u16 / 256

    @property
    def status_byte(self) -> int:
        return sum(bit for name, bit in _LOG_BITS if getattr(self, name))

    def _pack(self, where: str) -> bytes:
        return _LOG_RECORD.pack(
            check_int(TCP, f"{where}.trip_time_ms", self.trip_time_ms, 0, 0xFF),
            check_int(TCP, f"{where}.lost_packets", self.lost_packets, 0, 0xFF),
            _fixed(TCP, f"{where}.battery", self.battery, 256, 0xFFFF),
            self.status_byte,
            _fixed(TCP, f"{where}.can_utilization", self.can_utilization, 2, 0xFF),
            _fixed(TCP, f"{where}.signal_db", self.signal_db, 2, 0xFF),
            _fixed(TCP, f"{where}.bandwidth", self.bandwidth, 256, 0xFFFF))


_LOG_RECORD = struct.Struct(">BBHBBBH")
assert _LOG_RECORD.size == LOG_RECORD_SIZE
_new_log_record = unchecked_constructor(LogRecord)
assert [bit for _, bit in _LOG_BITS] == [0x80, 0x40, 0x20, 0x10, 0x08, 0x04, 0x02, 0x01]  # the fast path's order


@dataclass(frozen=True, slots=True)
class LogData:
    """Frame 0x16: log records, 9 bytes each. A DS sends one per frame; Cheesy Arena reads only
    the first (its status byte at frame offset 7), so a frame of several decodes as several."""

    records: tuple[LogRecord, ...] = ()

    def encode(self) -> bytes:
        if len(self.records) > 0xFFFE // LOG_RECORD_SIZE:
            raise ProtocolError(TCP, "records", None, f"{len(self.records)} records do not fit a frame")
        parts = []
        for i, rec in enumerate(self.records):
            if type(rec) is not LogRecord:
                raise ProtocolError(TCP, f"records[{i}]", None, f"{type(rec).__name__} is not a LogRecord")
            parts.append(rec._pack(f"records[{i}]"))
        return tcp_frame(TCP, FRAME_LOG_DATA, b"".join(parts))


@dataclass(frozen=True, slots=True)
class ErrorEvent:
    """One entry of an error/event data frame: a LabVIEW timestamp and the message text.

    fieldbox's protocol notes list a u64 timestamp (seconds since 1904-01-01 GMT) then 8 unknown
    bytes (docs/protocol.md#ds-to-fms-tcp):
    that is LabVIEW's 16-byte timestamp, whose second half is the fraction of a second in
    units of 2**-64 s, so the 8 bytes are kept as ``fraction``.
    """

    seconds: int = 0  # since 1904-01-01 00:00 UTC
    fraction: int = 0  # of a second, in 2**-64 s (the notes' "8 unknown bytes")
    text: str = ""

    @classmethod
    def at(cls, when: _dt.datetime, text: str) -> "ErrorEvent":
        """An entry stamped ``when`` (naive means UTC), to the microsecond."""
        if when.tzinfo is None:
            when = when.replace(tzinfo=_dt.timezone.utc)
        delta = when - LABVIEW_EPOCH
        seconds = delta.days * 86400 + delta.seconds
        return cls(seconds, (delta.microseconds << 64) // 1_000_000, text)

    def to_datetime(self) -> _dt.datetime | None:
        try:
            return LABVIEW_EPOCH + _dt.timedelta(seconds=self.seconds,
                                                 microseconds=(self.fraction * 1_000_000 + (1 << 63)) >> 64)
        except OverflowError:
            return None


@dataclass(frozen=True, slots=True)
class ErrorEventData:
    """Frame 0x17: errors and events the DS logged, for the FMS's match log.

    fieldbox's protocol notes give u32 count, u64 timestamp, 8 unknown bytes, u32-length string
    (docs/protocol.md#ds-to-fms-tcp). A u32
    count ahead of the elements is how LabVIEW (the DS is a LabVIEW program) flattens an
    array, so the count is read as the number of (timestamp, string) entries that follow,
    bounded by the bytes left; a frame with count 1 is exactly the notes' layout.
    """

    entries: tuple[ErrorEvent, ...] = ()

    def encode(self) -> bytes:
        parts = [U32.pack(len(self.entries))]
        for i, e in enumerate(self.entries):
            if type(e) is not ErrorEvent:
                raise ProtocolError(TCP, f"entries[{i}]", None, f"{type(e).__name__} is not an ErrorEvent")
            check_int(TCP, f"entries[{i}].seconds", e.seconds, 0, 2**64 - 1)
            check_int(TCP, f"entries[{i}].fraction", e.fraction, 0, 2**64 - 1)
            text = encode_text(TCP, f"entries[{i}].text", e.text, 0xFFFE)
            parts.append(U64.pack(e.seconds) + U64.pack(e.fraction) + U32.pack(len(text)) + text)
        return tcp_frame(TCP, FRAME_ERROR_EVENT_DATA, b"".join(parts))


@dataclass(frozen=True, slots=True)
class ChallengeResponse:
    """Frame 0x1b: the answer to the FMS's challenge question, raw text to the end of the frame.

    open-ds writes the answer's bytes with no length prefix (``SendTag.CHALLENGE_RESPONSE``);
    Cheesy Arena never reads this frame. See :func:`challenge_answer`.
    """

    answer: str = ""

    def encode(self) -> bytes:
        return tcp_frame(TCP, FRAME_CHALLENGE_RESPONSE, encode_text(TCP, "answer", self.answer, 0xFFFE))


@dataclass(frozen=True, slots=True)
class DsPing:
    """Frames 0x1c / 0x1d: the DS's keep-alive, empty.

    The FMS documents name 0x1c; Cheesy Arena (since 2024-07) and open-ds use 0x1d, and
    Cheesy Arena logs 0x1c as an unknown packet type. Send 0x1d, accept both; ``tag_id``
    keeps which one came so it re-encodes identically.
    """

    tag_id: int = FRAME_DS_PING_ALT

    def encode(self) -> bytes:
        if self.tag_id not in (FRAME_DS_PING, FRAME_DS_PING_ALT):
            raise ProtocolError(TCP, "tag_id", None, f"{self.tag_id!r} is not a DS ping id (0x1c or 0x1d)")
        return tcp_frame(TCP, self.tag_id, b"")


#: The longest team number text a hello carries: 5 digits name every u16 team.
MAX_HELLO_TEAM_DIGITS = 5


@dataclass(frozen=True, slots=True)
class DsHello:
    """Frame 0x1e (tag 30): the 2027 FIRST Driver Station's login, in place of 0x18.

    ``[u16 size][0x1e][u16 UDP reply port][u8 flags][u8 team length][team number in ASCII]``
    (Cheesy Arena, ``field/driver_station_connection.go`` at commit 1612d071, June 2026;
    docs/protocol.md#cheesy-2027). The FMS answers with ``fms_to_ds.HelloReply`` (0x1f) and
    sends its UDP control packets to ``udp_port`` on the DS's address. No source names a flag
    bit, so ``flags`` is kept as the byte. The team is text on the wire: ``team_text`` keeps
    it as it came (so ``0254`` re-encodes as ``0254``); :attr:`team` is its number, or None
    when the text is not 1-5 ASCII digits (an FMS cannot place such a DS). Build one with
    :meth:`for_team`.
    """

    udp_port: int = 1121
    flags: int = 0
    team_text: str = "0"

    @classmethod
    def for_team(cls, team: int, udp_port: int = 1121, flags: int = 0) -> "DsHello":
        check_int(TCP, "team", team, 0, 0xFFFF)
        return cls(udp_port, flags, str(team))

    @property
    def team(self) -> int | None:
        return hello_team(self.team_text)

    def encode(self) -> bytes:
        check_int(TCP, "udp_port", self.udp_port, 0, 0xFFFF)
        check_int(TCP, "flags", self.flags, 0, 0xFF)
        if not isinstance(self.team_text, str):
            raise ProtocolError(TCP, "team_text", None, f"{self.team_text!r} is not a string")
        team = encode_text(TCP, "team_text", self.team_text, 0xFF)
        return tcp_frame(TCP, FRAME_HELLO, U16.pack(self.udp_port) + bytes((self.flags, len(team))) + team)


def hello_team(text: str) -> int | None:
    """The team number a hello's team text names: 1-5 ASCII digits up to 65535, else None."""
    if not 1 <= len(text) <= MAX_HELLO_TEAM_DIGITS or not all("0" <= c <= "9" for c in text):
        return None
    team = int(text)
    return team if team <= 0xFFFF else None


@dataclass(frozen=True, slots=True)
class UnknownFrame(RawFrame):
    """A DS -> FMS frame with an id this library does not know: kept raw."""

    MESSAGE: ClassVar[str] = TCP


DsToFmsFrame = Union[KeepAlive, DeviceVersion, UsageReport, LogData, ErrorEventData, TeamNumber,
                     ChallengeResponse, DsPing, DsHello, UnknownFrame]


def walk_tcp(r: Reader) -> DsToFmsFrame:
    ann = r.spans is not None
    tag_id, shared = walk_frame_start(r, MAX_TCP_FRAME, _TCP_WHAT)
    if shared is not None:
        return shared
    if tag_id == FRAME_TEAM_NUMBER:
        if ann:
            r.explain("team_number", "frame 0x18: team number, the login (first frame)")
        value: DsToFmsFrame = TeamNumber(r.u16("team", "team number"))
    elif tag_id == FRAME_USAGE_REPORT:
        return walk_usage_report(r, UsageReport, "team number", "not documented")
    elif tag_id == FRAME_LOG_DATA:
        if ann:
            r.explain("log_data", "frame 0x16: log data")
        value = LogData(_walk_log_records(r))
    elif tag_id == FRAME_ERROR_EVENT_DATA:
        if ann:
            r.explain("error_event_data", "frame 0x17: error and event data")
        value = ErrorEventData(_walk_error_events(r))
    elif tag_id == FRAME_CHALLENGE_RESPONSE:
        if ann:
            r.explain("challenge_response", "frame 0x1b: challenge response")
        return ChallengeResponse(r.rest_text("answer", "the answer, raw text to the end of the frame"))
    elif tag_id == FRAME_HELLO:
        value = _walk_hello(r)
    elif tag_id in (FRAME_DS_PING, FRAME_DS_PING_ALT):
        if ann:
            r.explain("ds_ping", f"frame 0x{tag_id:02x}: DS ping (keep-alive), empty")
        value = DsPing(tag_id)
    else:
        return keep_raw(r, UnknownFrame, "frame", tag_id, "frame data, kept raw")
    r.expect_end()
    return value


def _walk_hello(r: Reader) -> DsHello:
    ann = r.spans is not None
    if ann:
        r.explain("ds_hello", "frame 0x1e (30): the 2027 FIRST Driver Station's hello, its login")
    port = r.u16("udp_port", "UDP port the FMS sends its control packets to, on this DS's address")
    flags = r.u8("flags")
    if ann:
        r.explain(f"0x{flags:02x}", "flags (no source names a bit yet; Cheesy Arena reads none)")
    text = r.text8("team_text")
    if ann:
        team = hello_team(text)
        r.explain(None, f"team number in ASCII: {team}" if team is not None
                  else f"team number in ASCII: {text!r} names no team (1-5 digits): an FMS cannot place this DS")
    return DsHello(port, flags, text)


def _log_status_text(b: int) -> str:
    words = [name.replace("_", " ") for name, bit in _LOG_BITS if b & bit]
    return "robot status: " + (", ".join(words) or "no bits set")


def _walk_log_records(r: Reader) -> tuple[LogRecord, ...]:
    left = r.remaining()
    if left % LOG_RECORD_SIZE:
        r.fail("records", f"{left} byte(s) is not a whole number of {LOG_RECORD_SIZE}-byte log records")
    if r.spans is None:  # decoding only: a record a struct, not eight named reads (1,800 in a 16 KiB frame)
        records = tuple(
            _new_log_record(trip, lost, battery / 256, status & 0x80 != 0, status & 0x40 != 0, status & 0x20 != 0,
                            status & 0x10 != 0, status & 0x08 != 0, status & 0x04 != 0, status & 0x02 != 0,
                            status & 0x01 != 0, can / 2, signal / 2, bw / 256)
            for trip, lost, battery, status, can, signal, bw in _LOG_RECORD.iter_unpack(r.data[r.pos:r.end]))
        r.pos = r.end
        return records
    walked: list[LogRecord] = []
    for i in range(left // LOG_RECORD_SIZE):
        w = f"records[{i}]"
        trip = r.u8(f"{w}.trip_time_ms")
        if r.spans is not None:
            r.explain(trip, f"trip time: {trip} ms DS <-> robot round trip (as the comms tag; one way is half)")
        lost = r.u8(f"{w}.lost_packets", "lost packets")
        battery = r.u16(f"{w}.battery")
        if r.spans is not None:
            r.explain(battery / 256, _battery_text(battery))
        status = r.u8(f"{w}.status")
        if r.spans is not None:
            r.explain(f"0x{status:02x}", _log_status_text(status))
        can = r.u8(f"{w}.can_utilization")
        if r.spans is not None:
            r.explain(can / 2, f"CAN utilisation: {can / 2:g} % (byte / 2)")
        signal = r.u8(f"{w}.signal_db")
        if r.spans is not None:
            r.explain(signal / 2, f"signal: {signal / 2:g} dB (byte / 2)")
        bw = r.u16(f"{w}.bandwidth")
        if r.spans is not None:
            r.explain(bw / 256, f"bandwidth: {bw / 256:.3f} Mbit/s (u16 / 256)")
        walked.append(LogRecord(trip, lost, battery / 256, can_utilization=can / 2, signal_db=signal / 2,
                                bandwidth=bw / 256, **{name: bool(status & bit) for name, bit in _LOG_BITS}))
    return tuple(walked)


def _walk_error_events(r: Reader) -> tuple[ErrorEvent, ...]:
    count = r.u32("count", "number of entries (a LabVIEW array length)")
    if count > r.remaining() // ERROR_EVENT_MIN_SIZE:
        r.fail("count", f"{count} entries cannot fit the {r.remaining()} byte(s) left "
                        f"(each takes at least {ERROR_EVENT_MIN_SIZE})", r.pos - 4)
    entries = []
    for i in range(count):
        w = f"entries[{i}]"
        seconds = r.u64(f"{w}.seconds")
        if r.spans is not None:
            when = ErrorEvent(seconds).to_datetime()
            r.explain(None, "timestamp, seconds since 1904-01-01 UTC"
                            + (f": {when.isoformat(' ', 'seconds')}" if when else " (out of range)"))
        fraction = r.u64(f"{w}.fraction")
        if r.spans is not None:
            r.explain(None, f"fraction of a second in 2**-64 s: {fraction / 2**64:.6f} s "
                            "(the notes' 8 unknown bytes; LabVIEW's timestamp layout)")
        text = r.text32(f"{w}.text", "error or event message")
        entries.append(ErrorEvent(seconds, fraction, text))
    return tuple(entries)


def decode_tcp(frame: bytes) -> DsToFmsFrame:
    """Decode one whole DS -> FMS TCP frame (its u16 size included)."""
    return decode_frame(walk_tcp, TCP, frame, MAX_TCP_FRAME, _TCP_WHAT)


def annotate_tcp(frame: bytes) -> list[Span]:
    return annotate_with(walk_tcp, TCP, frame)


__all__ = [
    "ChallengeResponse", "CommsMetrics", "DeviceVersion", "DsHello", "DsPing", "DsStatusPacket", "EmptyTag",
    "ErrorEvent", "ErrorEventData", "FieldRadioMetrics", "KeepAlive", "LaptopMetrics", "LogData",
    "LogRecord", "MAX_STATUS_SIZE", "MAX_TCP_FRAME", "PdInfo", "ROBOT_NAMES", "RobotRadioMetrics", "TeamNumber", "UnknownFrame",
    "UnknownTag", "UsageReport", "VersionDevice", "annotate_status", "annotate_tcp",
    "challenge_answer", "check_challenge_answer", "decode_status", "decode_tcp", "hello_team",
    "quantize_battery", "quantize_half", "walk_status", "walk_tcp",
]

KINDS = (
    Kind("ds-to-fms", "DS -> FMS, UDP 1160", STATUS, walk_status, decode_status),
    Kind("ds-to-fms-tcp", "DS -> FMS, TCP 1750", TCP, walk_tcp, decode_tcp, tcp=True),
)
