"""FMS -> Driver Station: the UDP control packet (port 1121, or 1120 from an FMS in "FMS
Lite" mode: a DS listens on both) and the TCP 1750 frames (versions, event code, station
info, challenge question, game data).

Source: docs/protocol.md#fms-to-ds (the seed fms_to_ds.rst), settled by docs/protocol.md#fms-behaviour
and by what Cheesy Arena (``Team254/cheesy-arena``,
``field/driver_station_connection.go``), a widely used open FMS, puts on the wire.

The control packet goes out every 500 ms, so there is no fast path: ``decode_control`` is the
reference :class:`~protocol.wire.Reader` walk, which also serves ``annotate_control``.

The version frames (ids 0x00-0x07) have the same layout in both directions, so
:class:`DeviceVersion`, :func:`walk_version` and :func:`walk_frame_start` (keep-alive or
version frame) live here and ``ds_to_fms`` uses them too.
"""

from __future__ import annotations

import datetime as _dt
import enum
import struct
from dataclasses import dataclass
from typing import ClassVar, Union

from .enums import MODE_TEXT, AllianceStation, Mode, StationStatus, TournamentLevel, enum_or_int
from .errors import ProtocolError
from .frames import (KeepAlive, RawFrame, check_packet, decode_frame, keep_raw, validate_unknown_tag, walk_frame_header,
                     walk_station, walk_tag_header, walk_tags)
from .kinds import Kind
from .wire import Reader, Span, UnknownTag, annotate_with, check_int, encode_text, over_bound, tcp_frame, text8, udp_tag

CONTROL = "FmsControlPacket"
TCP = "FmsToDsFrame"
VERSION = "DeviceVersion"

#: The largest control packet decoded; a longer one is refused by its length alone, before
#: anything is walked. A real FMS's is the 22-byte header and at most Cheesy Arena's game-data
#: tag (256 bytes by its u8 size): 278 bytes. UDP would carry 65,507.
MAX_CONTROL_SIZE = 1024
_CONTROL_WHAT = "an FMS control packet (a real FMS's is at most 278 bytes)"
#: The largest FMS -> DS frame decoded (and what the DS's framer takes). The longest a real
#: FMS sends is a u8-length string (event code, game data, the challenge question): 258 bytes.
MAX_TCP_FRAME = 1024
_TCP_WHAT = "an FMS -> DS frame (a real FMS's are at most 258 bytes)"

# Control byte: seed table "Control" (e-stop, enabled, mode); a-stop 0x40 from
# docs/protocol.md#fms-to-ds-control and Cheesy Arena (``AStop`` sets 0x40). 0x38 is named by
# nothing: kept in control_other.
CONTROL_ESTOP = 0x80
CONTROL_ASTOP = 0x40
CONTROL_ENABLED = 0x04
CONTROL_MODE = 0x03
CONTROL_OTHER_MASK = 0x38

# Cheesy Arena sends game data to the 2027 FIRST Driver Station as control packet tag 0x20
# (32), in place of TCP frame 0x1c: ``[n + 1][0x20][n characters]``, at most 8 characters
# (field/driver_station_connection.go at commit 1612d071; docs/protocol.md#cheesy-2027).
TAG_GAME_DATA = 0x20
TAG_CHEESY_GAME_DATA = TAG_GAME_DATA  # the name it had before the tag was decoded
#: The most characters (bytes) of game data tag 0x20 carries; a longer one is kept raw.
MAX_GAME_DATA_TAG = 8


# -- the date block ---------------------------------------------------------------------
@dataclass(frozen=True, slots=True)
class FmsDate:
    """The control packet's 10-byte date block, kept as the raw numbers on the wire.

    The seed says month 0 = January, and the hour is (probably) UTC. Cheesy Arena sends
    ``time.Now()``: month 1-12 and local time, and an early fork of it sent nanoseconds in the
    microseconds field. Decoding never judges the numbers; :meth:`to_datetime` reads them
    either way and gives ``None`` for a date that does not exist.
    """

    microseconds: int = 0
    second: int = 0
    minute: int = 0
    hour: int = 0
    day: int = 0
    month: int = 0  # 0 = January (seed); Cheesy Arena sends 1 = January
    year: int = 0  # years since 1900

    @classmethod
    def from_datetime(cls, when: _dt.datetime) -> "FmsDate":
        """The seed's encoding: month 0-based, year - 1900, an aware time converted to UTC."""
        when = when.astimezone(_dt.timezone.utc) if when.tzinfo else when
        return cls(when.microsecond, when.second, when.minute, when.hour, when.day,
                   when.month - 1, when.year - 1900)

    def to_datetime(self, *, one_based_month: bool = False,
                    tz: _dt.tzinfo | None = _dt.timezone.utc) -> _dt.datetime | None:
        """The date as a datetime, or ``None`` when the numbers name no real date.

        ``one_based_month=True`` reads the month as Cheesy Arena sends it (1-12); pass
        ``tz=None`` for the naive local time that FMS sends. Microseconds above 999 999 (an
        FMS that sent nanoseconds) are clamped, as ``ds_to_rio.Date`` does.
        """
        month = self.month if one_based_month else self.month + 1
        try:
            return _dt.datetime(self.year + 1900, month, self.day, self.hour, self.minute,
                                self.second, min(self.microseconds, 999_999), tzinfo=tz)
        except (ValueError, OverflowError, TypeError):
            return None

    def _validate(self, message: str, where: str) -> None:
        check_int(message, f"{where}.microseconds", self.microseconds, 0, 0xFFFFFFFF)
        for name in ("second", "minute", "hour", "day", "month", "year"):
            check_int(message, f"{where}.{name}", getattr(self, name), 0, 0xFF)


# -- the control packet's tags -----------------------------------------------------------------
@dataclass(frozen=True, slots=True)
class GameDataTag:
    """Control packet tag 0x20 (32): game data for the 2027 FIRST Driver Station, at most
    :data:`MAX_GAME_DATA_TAG` characters, the tag's size byte counting the id (n + 1). The NI
    DS gets the same text as TCP frame 0x1c (:class:`GameData`). A tag 0x20 of more than 8
    bytes is no FMS's: it decodes as an :class:`UnknownTag`, kept raw."""

    text: str = ""

    def encode(self, where: str = "tags") -> bytes:
        data = encode_text(CONTROL, f"{where}.text", self.text, MAX_GAME_DATA_TAG)
        return udp_tag(CONTROL, where, TAG_GAME_DATA, data)


ControlTag = Union[GameDataTag, UnknownTag]


def _encode_control_tag(where: str, tag: object) -> bytes:
    if type(tag) is GameDataTag:
        return tag.encode(where)
    validate_unknown_tag(CONTROL, where, tag)
    assert isinstance(tag, UnknownTag)
    return udp_tag(CONTROL, where, tag.tag_id, tag.data)


# -- the control packet -------------------------------------------------------------------
@dataclass(frozen=True, slots=True)
class FmsControlPacket:
    """FMS -> DS UDP 1121 (1120 in FMS Lite mode), every 500 ms and at once on every match
    phase change. Cheesy Arena's "500 ms" is since its last send, on a 10 ms loop: a median of
    506 ms, gaps to 1.5 s while a match loads."""

    sequence: int = 0
    comm_version: int = 0x00
    estop: bool = False
    astop: bool = False
    enabled: bool = False
    mode: Mode = Mode.TELEOP
    request: int = 0x00  # seed: "Stays at 0x00, not used"; kept raw
    station: AllianceStation = AllianceStation.RED1
    tournament_level: TournamentLevel | int = TournamentLevel.MATCH_TEST
    match_number: int = 0
    play_number: int = 0
    date: FmsDate = FmsDate()
    remaining_seconds: int = 0  # counts down the CURRENT period (docs/protocol.md#fms-behaviour)
    tags: tuple[ControlTag, ...] = ()
    control_other: int = 0  # control bits no document names (0x38), kept for byte identity

    @property
    def game_data(self) -> str | None:
        """The text of the first game data tag (0x20), or None when the packet has none."""
        return next((t.text for t in self.tags if type(t) is GameDataTag), None)

    @property
    def control_byte(self) -> int:
        return ((CONTROL_ESTOP if self.estop else 0) | (CONTROL_ASTOP if self.astop else 0)
                | (CONTROL_ENABLED if self.enabled else 0) | int(self.mode) | self.control_other)

    def encode(self) -> bytes:
        self._validate()
        d = self.date
        head = _HEADER.pack(self.sequence, self.comm_version, self.control_byte, self.request,
                            int(self.station), int(self.tournament_level), self.match_number,
                            self.play_number, d.microseconds, d.second, d.minute, d.hour, d.day,
                            d.month, d.year, self.remaining_seconds)
        if not self.tags:
            return head
        data = head + b"".join(_encode_control_tag(f"tags[{i}]", t) for i, t in enumerate(self.tags))
        return check_packet(CONTROL, data, len(self.tags), MAX_CONTROL_SIZE, _CONTROL_WHAT)

    def _validate(self) -> None:
        check_int(CONTROL, "sequence", self.sequence, 0, 0xFFFF)
        check_int(CONTROL, "comm_version", self.comm_version, 0, 0xFF)
        check_int(CONTROL, "mode", self.mode, 0, 3)
        if check_int(CONTROL, "control_other", self.control_other, 0, 0xFF) & ~CONTROL_OTHER_MASK:
            raise ProtocolError(CONTROL, "control_other", None, "may only hold bits 0x38")
        check_int(CONTROL, "request", self.request, 0, 0xFF)
        check_int(CONTROL, "station", self.station, 0, 5)
        check_int(CONTROL, "tournament_level", self.tournament_level, 0, 0xFF)
        check_int(CONTROL, "match_number", self.match_number, 0, 0xFFFF)
        check_int(CONTROL, "play_number", self.play_number, 0, 0xFF)
        if not isinstance(self.date, FmsDate):
            raise ProtocolError(CONTROL, "date", None, f"{self.date!r} is not an FmsDate")
        self.date._validate(CONTROL, "date")
        check_int(CONTROL, "remaining_seconds", self.remaining_seconds, 0, 0xFFFF)
        for i, tag in enumerate(self.tags):
            if type(tag) is GameDataTag:
                tag.encode(f"tags[{i}]")
            else:
                validate_unknown_tag(CONTROL, f"tags[{i}]", tag)


#: sequence, comm version, control, request, station, level, match, play, date (u32 + 6 u8),
#: remaining time: the 22 bytes every FMS sends.
_HEADER = struct.Struct(">HBBBBBHBIBBBBBBH")
HEADER_SIZE = _HEADER.size


# -- decoding -------------------------------------------------------------------------
_LEVEL_TEXT = "0 match test, 1 practice, 2 qualification, 3 playoff"
_MONTHS = ("January", "February", "March", "April", "May", "June", "July", "August",
           "September", "October", "November", "December")


def _control_text(b: int) -> str:
    words = ["E-STOP" if b & CONTROL_ESTOP else "no e-stop",
             "A-STOP" if b & CONTROL_ASTOP else "no a-stop",
             "enabled" if b & CONTROL_ENABLED else "disabled",
             MODE_TEXT[b & CONTROL_MODE]]
    if b & CONTROL_OTHER_MASK:
        words.append(f"other bits 0x{b & CONTROL_OTHER_MASK:02x}")
    return ", ".join(words)


def _month_text(m: int) -> str:
    zero = _MONTHS[m] if m < 12 else "no month"
    one = _MONTHS[m - 1] if 1 <= m <= 12 else "no month"
    return f"month {m}: {zero} if 0-based (seed), {one} if 1-based (Cheesy Arena)"


def _walk_date(r: Reader) -> FmsDate:
    ann = r.spans is not None
    us = r.u32("date.microseconds", "microseconds (an early Cheesy Arena fork sent nanoseconds)")
    sec = r.u8("date.second", "second")
    minute = r.u8("date.minute", "minute")
    hour = r.u8("date.hour", "hour (UTC per the seed; Cheesy Arena sends local time)")
    day = r.u8("date.day", "day of the month")
    month = r.u8("date.month")
    if ann:
        r.explain(None, _month_text(month))
    year = r.u8("date.year")
    date = FmsDate(us, sec, minute, hour, day, month, year)
    if ann:
        seed, cheesy = date.to_datetime(), date.to_datetime(one_based_month=True, tz=None)
        whole = "; ".join(
            f"{label}: {when.isoformat(' ', 'seconds') if when else 'not a date'}"
            for label, when in (("0-based month", seed), ("1-based month", cheesy)))
        r.explain(year + 1900, f"years since 1900: {year} = {year + 1900}. Whole date, {whole}")
    return date


def walk_control(r: Reader) -> FmsControlPacket:
    ann = r.spans is not None
    seq = r.u16("sequence", "sequence number, one more per packet")
    ver = r.u8("comm_version", "comm version (0x00 from every FMS seen)")
    ctl = r.u8("control")
    if ann:
        r.explain(f"0x{ctl:02x}", f"control: {_control_text(ctl)}")
    req = r.u8("request")
    if ann:
        r.explain(f"0x{req:02x}", "request byte (seed: stays 0x00, not used)")
    station = walk_station(r)
    lv = r.u8("tournament_level")
    level = enum_or_int(TournamentLevel, lv)
    if ann:
        r.explain(getattr(level, "name", lv), f"tournament level {lv} ({_LEVEL_TEXT})")
    match = r.u16("match_number", "match number")
    play = r.u8("play_number", "play number: goes up by one for each replay (Cheesy Arena sends 1)")
    date = _walk_date(r)
    left = r.u16("remaining_seconds")
    if ann:
        r.explain(None, f"{left} s ({left // 60}:{left % 60:02d}) left in the current period")
    r.refuse_over(MAX_CONTROL_SIZE, _CONTROL_WHAT)
    tags = walk_tags(r, _walk_control_tag)
    return FmsControlPacket(seq, ver, bool(ctl & CONTROL_ESTOP), bool(ctl & CONTROL_ASTOP),
                            bool(ctl & CONTROL_ENABLED), Mode(ctl & CONTROL_MODE), req, station,
                            level, match, play, date, left, tags, ctl & CONTROL_OTHER_MASK)


def _walk_control_tag(r: Reader, where: str) -> ControlTag:
    t, tag_id = walk_tag_header(r, where)
    if tag_id != TAG_GAME_DATA:
        return keep_raw(t, UnknownTag, "tag", tag_id, "tag data, kept raw")
    n = t.remaining()
    if n > MAX_GAME_DATA_TAG:
        notes = {tag_id: f"tag 0x20 (game data) with {n} bytes, over the {MAX_GAME_DATA_TAG} an FMS sends: "
                         "kept raw"}
        return keep_raw(t, UnknownTag, "tag", tag_id, "tag data, kept raw", notes)
    if t.spans is not None:
        t.explain("game_data", "tag 0x20 (32): game data for the 2027 FIRST Driver Station (Cheesy Arena), "
                               "in place of TCP frame 0x1c")
    return GameDataTag(t.rest_text("text", f"game data, {n} character(s) (at most {MAX_GAME_DATA_TAG})"))


def decode_control(data: bytes) -> FmsControlPacket:
    """Decode an FMS -> DS control packet. Raises only :class:`ProtocolError`: at once, for a
    packet over :data:`MAX_CONTROL_SIZE`."""
    if len(data) > MAX_CONTROL_SIZE:
        raise over_bound(CONTROL, len(data), MAX_CONTROL_SIZE, _CONTROL_WHAT)
    return walk_control(Reader(data, CONTROL))


def annotate_control(data: bytes) -> list[Span]:
    return annotate_with(walk_control, CONTROL, data)


# -- TCP 1750, FMS -> DS ----------------------------------------------------------------
FRAME_EVENT_CODE = 0x14
FRAME_STATION_INFO = 0x19
FRAME_CHALLENGE_QUESTION = 0x1A
FRAME_GAME_DATA = 0x1C
FRAME_HELLO_REPLY = 0x1F  # tag 31: the answer to the 2027 DS's hello
HELLO_FMS_LITE = 0x01  # hello reply flags bit 0: the FMS is in FMS Lite mode


class VersionDevice(enum.IntEnum):
    """Frame ids 0x00-0x07: whose version a version frame carries (seed "Tags" table)."""

    WPILIB = 0
    ROBORIO = 1
    DS = 2
    PDP = 3
    PCM = 4
    CANJAG = 5
    CANTALON = 6
    THIRD_PARTY = 7

    @property
    def label(self) -> str:
        return ("WPILib", "roboRIO", "Driver Station", "PDP", "PCM", "CAN Jaguar", "CAN Talon",
                "third-party device")[self.value]


@dataclass(frozen=True, slots=True)
class DeviceVersion:
    """Frames 0x00-0x07 (both directions): a status string and a version string.

    The seed gives no lengths. Every other string on TCP 1750 has a u8 length prefix (event
    code, challenge question, game data: seed "1 + n" and Cheesy Arena), open-ds's version
    reader takes two printable runs split by non-printable bytes (the length bytes; its TCP
    parser fails before any frame reaches it), and an early Cheesy Arena fork sent ``[u8
    len][version]`` alone. So: ``[u8 len][status][u8 len][version]``, and a frame holding
    exactly one u8-length string is that older form, decoded with ``status=None`` so it
    re-encodes byte-identical.
    """

    device: VersionDevice | int
    status: str | None = "<good>"  # "<bad>", "<good>" or "<preferred>" (seed); None: absent
    version: str = ""

    def encode(self) -> bytes:
        check_int(VERSION, "device", self.device, 0, 7)
        if self.status is not None and not isinstance(self.status, str):
            raise ProtocolError(VERSION, "status", None, f"{self.status!r} is not a string or None")
        payload = (b"" if self.status is None else text8(VERSION, "status", self.status)) \
            + text8(VERSION, "version", self.version)
        return tcp_frame(VERSION, int(self.device), payload)


def walk_version(r: Reader, tag_id: int) -> DeviceVersion:
    """The payload of a version frame; ``r`` stands just after the id byte."""
    device = VersionDevice(tag_id)
    if r.spans is not None:
        r.explain(device.name, f"frame 0x{tag_id:02x}: {device.label} version")
    r.need(1, "status.length")
    if r.pos + 1 + r.data[r.pos] == r.end:
        # One string filling the frame: the version alone, as an early Cheesy Arena fork sent.
        version = r.text8("version", f"{device.label} version (no status string before it)")
        return DeviceVersion(device, None, version)
    status = r.text8("status", "status: <bad>, <good> or <preferred>")
    version = r.text8("version", f"{device.label} version")
    r.expect_end()
    return DeviceVersion(device, status, version)


def walk_frame_start(r: Reader, bound: int, what: str) -> tuple[int, KeepAlive | DeviceVersion | None]:
    """What every TCP 1750 frame starts with, both ways: the size and id, and the frames both
    directions share (keep-alive, versions 0x00-0x07) read whole. ``(id, None)`` for any other
    frame, with ``r`` just after the id; ``(id or -1, frame)`` for a shared one. A frame over
    ``bound`` bytes (that direction's) is refused after its id (``what`` names it)."""
    tag_id = walk_frame_header(r)
    if tag_id is None:
        return -1, KeepAlive()
    r.refuse_over(bound, what)
    if tag_id <= 0x07:
        return tag_id, walk_version(r, tag_id)
    return tag_id, None


@dataclass(frozen=True, slots=True)
class EventCode:
    """Frame 0x14: the event code, a u8-length string (Cheesy Arena strips leading digits of
    the TBA code and sends at most 62 characters)."""

    code: str = ""

    def encode(self) -> bytes:
        return tcp_frame(TCP, FRAME_EVENT_CODE, text8(TCP, "code", self.code))


@dataclass(frozen=True, slots=True)
class StationInfo:
    """Frame 0x19: the station the FMS puts this DS in, and whether that is right.

    A team not in the match gets ``00 03 19 00 02`` (station R1, waiting) and stays connected.
    """

    station: AllianceStation = AllianceStation.RED1
    status: StationStatus | int = StationStatus.GOOD

    def encode(self) -> bytes:
        check_int(TCP, "station", self.station, 0, 5)
        check_int(TCP, "status", self.status, 0, 0xFF)
        return tcp_frame(TCP, FRAME_STATION_INFO, bytes((int(self.station), int(self.status))))


@dataclass(frozen=True, slots=True)
class ChallengeQuestion:
    """Frame 0x1a: a u8-length question (``Coolest robot EVER!!??``) and a u16 random value
    (1000-2000) the DS answers with ``ds_to_fms.challenge_answer``."""

    question: str = "Coolest robot EVER!!??"
    random_value: int = 1000

    def encode(self) -> bytes:
        check_int(TCP, "random_value", self.random_value, 0, 0xFFFF)
        payload = text8(TCP, "question", self.question) + struct.pack(">H", self.random_value)
        return tcp_frame(TCP, FRAME_CHALLENGE_QUESTION, payload)


@dataclass(frozen=True, slots=True)
class GameData:
    """Frame 0x1c: the game-specific message, a u8-length string (seed "1 + n"; Cheesy Arena
    writes ``[size][0x1c][len][text]``). Not the same layout as ds_to_rio's game data frame."""

    text: str = ""

    def encode(self) -> bytes:
        return tcp_frame(TCP, FRAME_GAME_DATA, text8(TCP, "text", self.text))


@dataclass(frozen=True, slots=True)
class HelloReply:
    """Frame 0x1f (tag 31): the FMS's answer to the 2027 DS's hello (``ds_to_fms.DsHello``),
    in place of station info 0x19: ``00 06 1f station status flags team_hi team_lo``, flags
    bit 0 set when the FMS is in FMS Lite mode (Cheesy Arena at commit 1612d071;
    docs/protocol.md#cheesy-2027). Flag bits no source names are kept in ``flags``."""

    station: AllianceStation = AllianceStation.RED1
    status: StationStatus | int = StationStatus.GOOD
    flags: int = 0
    team: int = 0

    @property
    def fms_lite(self) -> bool:
        return bool(self.flags & HELLO_FMS_LITE)

    def encode(self) -> bytes:
        check_int(TCP, "station", self.station, 0, 5)
        check_int(TCP, "status", self.status, 0, 0xFF)
        check_int(TCP, "flags", self.flags, 0, 0xFF)
        check_int(TCP, "team", self.team, 0, 0xFFFF)
        payload = bytes((int(self.station), int(self.status), self.flags)) + struct.pack(">H", self.team)
        return tcp_frame(TCP, FRAME_HELLO_REPLY, payload)


@dataclass(frozen=True, slots=True)
class UnknownFrame(RawFrame):
    """An FMS -> DS frame with an id this library does not know: kept raw."""

    MESSAGE: ClassVar[str] = TCP


FmsToDsFrame = Union[KeepAlive, DeviceVersion, EventCode, StationInfo, ChallengeQuestion, GameData,
                     HelloReply, UnknownFrame]


def walk_tcp(r: Reader) -> FmsToDsFrame:
    ann = r.spans is not None
    tag_id, shared = walk_frame_start(r, MAX_TCP_FRAME, _TCP_WHAT)
    if shared is not None:
        return shared
    if tag_id == FRAME_EVENT_CODE:
        if ann:
            r.explain("event_code", "frame 0x14: event code")
        value: FmsToDsFrame = EventCode(r.text8("code", "event code"))
    elif tag_id == FRAME_STATION_INFO:
        if ann:
            r.explain("station_info", "frame 0x19: station info")
        station = walk_station(r)
        status = enum_or_int(StationStatus, r.u8("status"))
        if ann:
            r.explain(getattr(status, "name", status), _STATUS_TEXT.get(status, "undocumented status"))
        value = StationInfo(station, status)
    elif tag_id == FRAME_CHALLENGE_QUESTION:
        if ann:
            r.explain("challenge_question", "frame 0x1a: challenge question")
        question = r.text8("question", "the question")
        rnd = r.u16("random_value", "random value (1000-2000): answer index = team * value % 23")
        value = ChallengeQuestion(question, rnd)
    elif tag_id == FRAME_GAME_DATA:
        if ann:
            r.explain("game_data", "frame 0x1c: game-specific message")
        value = GameData(r.text8("text", "game data"))
    elif tag_id == FRAME_HELLO_REPLY:
        value = _walk_hello_reply(r)
    else:
        return keep_raw(r, UnknownFrame, "frame", tag_id, "frame data, kept raw")
    r.expect_end()
    return value


def _walk_hello_reply(r: Reader) -> HelloReply:
    ann = r.spans is not None
    if ann:
        r.explain("hello_reply", "frame 0x1f (31): the answer to the 2027 DS's hello, its station")
    station = walk_station(r)
    status = enum_or_int(StationStatus, r.u8("status"))
    if ann:
        r.explain(getattr(status, "name", status), _STATUS_TEXT.get(status, "undocumented status"))
    flags = r.u8("flags")
    if ann:
        words = ["FMS Lite" if flags & HELLO_FMS_LITE else "full FMS (not FMS Lite)"]
        if flags & ~HELLO_FMS_LITE:
            words.append(f"other bits 0x{flags & ~HELLO_FMS_LITE:02x}")
        r.explain(f"0x{flags:02x}", "flags: " + ", ".join(words) + " (bit 0 FMS Lite)")
    team = r.u16("team", "team number the FMS placed")
    return HelloReply(station, status, flags, team)


_STATUS_TEXT: dict[int, str] = {
    StationStatus.GOOD: "station status 0 good: the DS shows FMS Connected",
    StationStatus.BAD: "station status 1 bad: wrong station, the DS says where to go",
    StationStatus.WAITING: "station status 2 waiting: this team is not in the current match",
}


def decode_tcp(frame: bytes) -> FmsToDsFrame:
    """Decode one whole FMS -> DS TCP frame (its u16 size included)."""
    return decode_frame(walk_tcp, TCP, frame, MAX_TCP_FRAME, _TCP_WHAT)


def annotate_tcp(frame: bytes) -> list[Span]:
    return annotate_with(walk_tcp, TCP, frame)


__all__ = [
    "CONTROL_ASTOP", "CONTROL_ENABLED", "CONTROL_ESTOP", "ChallengeQuestion", "DeviceVersion",
    "EventCode", "FmsControlPacket", "FmsDate", "GameData", "GameDataTag", "HelloReply", "KeepAlive", "MAX_CONTROL_SIZE", "MAX_TCP_FRAME",
    "StationInfo",
    "UnknownFrame", "UnknownTag", "VersionDevice", "annotate_control", "annotate_tcp",
    "decode_control", "decode_tcp", "walk_control", "walk_tcp", "walk_version",
]

KINDS = (
    Kind("fms-to-ds", "FMS -> DS, UDP 1121/1120", CONTROL, walk_control, decode_control),
    Kind("fms-to-ds-tcp", "FMS -> DS, TCP 1750", TCP, walk_tcp, decode_tcp, tcp=True),
)
