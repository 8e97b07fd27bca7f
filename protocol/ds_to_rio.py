"""Driver Station -> roboRIO: the UDP control packet (port 1110, 1115 under an FMS) and the
TCP 1740 frames (joystick descriptors, match info, game data).

Source: docs/protocol.md#ds-to-rio (the seed ds_to_rio.rst, settled by what real peers do).

A tag that is not laid out as documented does not make the packet bad: it decodes as a
:class:`~protocol.frames.MalformedTag` beside the good ones, because a real robot applies the
header (enable, mode, station) before it walks the tags and drops only what it cannot read
(WPILib's ``DSCommPacket::DecodeUDP``). Only a short header or a station above 5 is a
``ProtocolError``.

The control packet is the 50 Hz hot path, so it has two decoders: ``walk_control`` is the
reference (a :class:`~protocol.wire.Reader` walk that names field and offset on failure and
records spans for ``annotate``), and ``decode_control`` is a hand-unrolled fast path that
falls back to the walk on anything irregular. A property test holds them equal.
"""

from __future__ import annotations

import datetime as _dt
import struct
from dataclasses import dataclass
from typing import ClassVar, Union

from .enums import MODE_TEXT, AllianceStation, AxisType, JoystickType, MatchType, Mode, enum_or_int
from .errors import ProtocolError
from .frames import (MAX_TAGS, KeepAlive, MalformedTag, RawFrame, check_packet, decode_frame, keep_raw,
                     validate_malformed_tag, walk_frame_header, walk_station, walk_tag_or_malformed, walk_tags)
from .wire import (F32, U16, Irregular, Reader, Span, UnknownTag, annotate_with, check_f32, check_int,
                   encode_text, irregular, over_bound, tcp_frame, text8, udp_tag, unchecked_constructor)

CONTROL = "ControlPacket"

#: The largest control packet decoded; a longer one is refused by its length alone, before
#: anything is walked. A real DS's is at most 550 bytes by the layout: the 6-byte header, the
#: countdown (6), six joysticks at WPILib's limits of 12 axes, 32 buttons and 12 POVs (45
#: each), the date (12) and a time zone name of 254 bytes (256); in practice far less (the
#: real NI DS of the 2021 capture: 27 bytes at most). UDP would carry 65,507.
MAX_CONTROL_SIZE = 1024
_CONTROL_WHAT = "a control packet (a real DS's is at most 550 bytes)"

# Control byte (seed table "Control").
CONTROL_ESTOP = 0x80
CONTROL_FMS = 0x08
CONTROL_ENABLED = 0x04
CONTROL_MODE = 0x03
# Request byte. 0x10 is what a DS sends in normal operation: WPILib's simulator treats the DS
# as attached when any of the high four bits is set (docs/protocol.md#ds-to-rio-control). A real NI
# DS also sets 0x01 for about 80 ms every 4-6 s (62 packets of the 2021 capture, e.g. frames
# 309-319); what it asks is unknown, so fieldbox's DS never sets it and the inspector names it.
REQUEST_REBOOT = 0x08
REQUEST_RESTART_CODE = 0x04
REQUEST_NORMAL = 0x10
REQUEST_UNKNOWN_01 = 0x01

TAG_COUNTDOWN = 0x07
TAG_JOYSTICK = 0x0C
TAG_DATE = 0x0F
TAG_TIMEZONE = 0x10

# WPILib's HAL keeps fixed arrays of these sizes; sending more would overflow a peer.
MAX_AXES = 12
MAX_POVS = 12
MAX_BUTTONS = 32
MAX_JOYSTICKS = 6


# -- tags -----------------------------------------------------------------------------
@dataclass(frozen=True, slots=True)
class Countdown:
    """Tag 0x07: seconds left in the current match period (f32)."""

    seconds: float


@dataclass(frozen=True, slots=True)
class Joystick:
    """Tag 0x0c: one joystick slot. ``buttons`` is the button word, bit 0 = button 1.

    An empty slot is ``04 0c 00 00 00`` (every count 0). ``bare`` is the 2-byte form
    ``01 0c``, no counts at all, which WPILib's robot side also reads as an empty slot; it
    re-encodes as it came.
    """

    axes: tuple[int, ...] = ()
    buttons: int = 0
    button_count: int = 0
    povs: tuple[int, ...] = ()
    bare: bool = False

    def pressed(self, button: int) -> bool:
        """Whether button ``button`` (1-based, as WPILib numbers them) is down."""
        return 1 <= button <= self.button_count and bool(self.buttons >> (button - 1) & 1)

    @property
    def is_empty(self) -> bool:
        return not self.axes and not self.button_count and not self.povs


EMPTY_JOYSTICK = Joystick()
BARE_EMPTY_JOYSTICK = Joystick(bare=True)
_BARE_JOYSTICK_TAG = bytes((1, 0x0C))


def axis_to_int8(value: float) -> int:
    """-1.0..1.0 to the wire's int8, the way WPILib reads it back (negative /128, positive /127)."""
    if value != value:  # NaN
        return 0
    value = max(-1.0, min(1.0, value))
    return round(value * 128) if value < 0 else round(value * 127)


def int8_to_axis(raw: int) -> float:
    return raw / 128.0 if raw < 0 else raw / 127.0


@dataclass(frozen=True, slots=True)
class Date:
    """Tag 0x0f: the DS's clock, sent once when the robot asks. Month 0-based, year - 1900, UTC."""

    microseconds: int
    second: int
    minute: int
    hour: int
    day: int
    month: int
    year: int

    @classmethod
    def from_datetime(cls, when: _dt.datetime) -> "Date":
        when = when.astimezone(_dt.timezone.utc) if when.tzinfo else when
        return cls(when.microsecond, when.second, when.minute, when.hour, when.day,
                   when.month - 1, when.year - 1900)

    def to_datetime(self) -> _dt.datetime | None:
        try:
            return _dt.datetime(self.year + 1900, self.month + 1, self.day, self.hour, self.minute,
                                self.second, min(self.microseconds, 999_999), tzinfo=_dt.timezone.utc)
        except (ValueError, OverflowError):
            return None


@dataclass(frozen=True, slots=True)
class Timezone:
    """Tag 0x10: the DS's time zone name, text to the end of the tag."""

    name: str


ControlTag = Union[Countdown, Joystick, Date, Timezone, UnknownTag, MalformedTag]


# -- the control packet ---------------------------------------------------------------
@dataclass(frozen=True, slots=True)
class ControlPacket:
    """DS -> roboRIO UDP, every 20 ms."""

    sequence: int = 0
    comm_version: int = 0x01
    estop: bool = False
    fms_attached: bool = False
    enabled: bool = False
    mode: Mode = Mode.TELEOP
    reboot_roborio: bool = False
    restart_code: bool = False
    station: AllianceStation = AllianceStation.RED1
    tags: tuple[ControlTag, ...] = ()
    control_other: int = 0  # control bits no document names (0x70), kept for byte identity
    request_other: int = REQUEST_NORMAL  # request bits besides reboot/restart

    @property
    def joysticks(self) -> tuple[Joystick, ...]:
        """The joystick slots in order; a malformed joystick tag keeps its slot, empty."""
        return tuple(t if type(t) is Joystick else EMPTY_JOYSTICK for t in self.tags
                     if type(t) is Joystick or (type(t) is MalformedTag and t.tag_id == TAG_JOYSTICK))

    @property
    def malformed_tags(self) -> tuple[MalformedTag, ...]:
        return tuple(t for t in self.tags if type(t) is MalformedTag)

    @property
    def control_byte(self) -> int:
        return ((CONTROL_ESTOP if self.estop else 0) | (CONTROL_FMS if self.fms_attached else 0)
                | (CONTROL_ENABLED if self.enabled else 0) | (int(self.mode) & 3) | self.control_other)

    @property
    def request_byte(self) -> int:
        return ((REQUEST_REBOOT if self.reboot_roborio else 0)
                | (REQUEST_RESTART_CODE if self.restart_code else 0) | self.request_other)

    def encode(self) -> bytes:
        try:
            head = _HEADER.pack(self.sequence, self.comm_version, self.control_byte,
                                self.request_byte, self.station)
            if not self.tags:
                return head
            parts = [head]
            for tag in self.tags:
                parts.append(_encode_joystick(tag) if type(tag) is Joystick else _encode_tag(tag))
            data = b"".join(parts)
        except (struct.error, TypeError, ValueError, OverflowError) as exc:
            self._validate()
            raise ProtocolError(CONTROL, "?", None, str(exc)) from None
        if len(data) > MAX_CONTROL_SIZE or len(self.tags) > MAX_TAGS:
            check_packet(CONTROL, data, len(self.tags), MAX_CONTROL_SIZE, _CONTROL_WHAT)
        return data

    def _validate(self) -> None:
        check_int(CONTROL, "sequence", self.sequence, 0, 0xFFFF)
        check_int(CONTROL, "comm_version", self.comm_version, 0, 0xFF)
        check_int(CONTROL, "mode", self.mode, 0, 3)
        check_int(CONTROL, "station", self.station, 0, 5)
        if check_int(CONTROL, "control_other", self.control_other, 0, 0xFF) & 0x8F:
            raise ProtocolError(CONTROL, "control_other", None, "may only hold bits 0x70")
        if check_int(CONTROL, "request_other", self.request_other, 0, 0xFF) & 0x0C:
            raise ProtocolError(CONTROL, "request_other", None, "may not hold reboot/restart bits 0x0c")
        for i, tag in enumerate(self.tags):
            _validate_tag(tag, f"tags[{i}]")


_HEADER = struct.Struct(">HBBBB")
_JOY_CACHE: dict[tuple[int, int, int], struct.Struct] = {}


def _joystick_struct(n_axes: int, n_button_bytes: int, n_povs: int) -> struct.Struct:
    key = (n_axes, n_button_bytes, n_povs)
    st = _JOY_CACHE.get(key)
    if st is None:
        st = struct.Struct(f">BBB{n_axes}bB{n_button_bytes}sB{n_povs}h")
        _JOY_CACHE[key] = st
    return st


def _encode_joystick(joy: Joystick) -> bytes:
    axes, povs, count = joy.axes, joy.povs, joy.button_count
    if joy.bare:
        if axes or povs or count or joy.buttons:
            raise ValueError("a bare empty slot (01 0c) carries nothing")
        return _BARE_JOYSTICK_TAG
    n_bytes = (count + 7) >> 3
    if len(axes) > MAX_AXES or len(povs) > MAX_POVS or not 0 <= count <= MAX_BUTTONS \
            or joy.buttons >> count or joy.buttons < 0:
        raise ValueError("joystick out of range")
    st = _joystick_struct(len(axes), n_bytes, len(povs))
    return st.pack(st.size - 1, TAG_JOYSTICK, len(axes), *axes, count,
                   joy.buttons.to_bytes(n_bytes, "big"), len(povs), *povs)


def _encode_tag(tag: ControlTag) -> bytes:
    if type(tag) is Countdown:
        return udp_tag(CONTROL, "countdown", TAG_COUNTDOWN, F32.pack(tag.seconds))
    if type(tag) is Date:
        return udp_tag(CONTROL, "date", TAG_DATE, _DATE.pack(tag.microseconds, tag.second, tag.minute,
                                                              tag.hour, tag.day, tag.month, tag.year))
    if type(tag) is Timezone:
        return udp_tag(CONTROL, "timezone", TAG_TIMEZONE, encode_text(CONTROL, "timezone", tag.name, 0xFE))
    if type(tag) is UnknownTag:
        return udp_tag(CONTROL, "unknown", tag.tag_id, tag.data)
    if type(tag) is MalformedTag:
        return bytes(tag.raw)
    raise TypeError(f"{tag!r} is not a control packet tag")


_DATE = struct.Struct(">IBBBBBB")


def _validate_tag(tag: object, where: str) -> None:
    if type(tag) is Joystick:
        if len(tag.axes) > MAX_AXES:
            raise ProtocolError(CONTROL, f"{where}.axes", None, f"{len(tag.axes)} axes, at most {MAX_AXES}")
        for j, a in enumerate(tag.axes):
            check_int(CONTROL, f"{where}.axes[{j}]", a, -128, 127)
        check_int(CONTROL, f"{where}.button_count", tag.button_count, 0, MAX_BUTTONS)
        check_int(CONTROL, f"{where}.buttons", tag.buttons, 0, (1 << tag.button_count) - 1)
        if len(tag.povs) > MAX_POVS:
            raise ProtocolError(CONTROL, f"{where}.povs", None, f"{len(tag.povs)} POVs, at most {MAX_POVS}")
        for j, p in enumerate(tag.povs):
            check_int(CONTROL, f"{where}.povs[{j}]", p, -32768, 32767)
        if type(tag.bare) is not bool:
            raise ProtocolError(CONTROL, f"{where}.bare", None, f"{tag.bare!r} is not a bool")
        if tag.bare and not tag.is_empty:
            raise ProtocolError(CONTROL, f"{where}.bare", None, "a bare empty slot (01 0c) carries nothing")
    elif type(tag) is Countdown:
        check_f32(CONTROL, f"{where}.seconds", tag.seconds)
    elif type(tag) is Date:
        for name in ("second", "minute", "hour", "day", "month", "year"):
            check_int(CONTROL, f"{where}.{name}", getattr(tag, name), 0, 0xFF)
        check_int(CONTROL, f"{where}.microseconds", tag.microseconds, 0, 0xFFFFFFFF)
    elif type(tag) is Timezone:
        encode_text(CONTROL, f"{where}.name", tag.name, 0xFE)
    elif type(tag) is UnknownTag:
        check_int(CONTROL, f"{where}.tag_id", tag.tag_id, 0, 0xFF)
        if len(tag.data) > 0xFE:
            raise ProtocolError(CONTROL, f"{where}.data", None, f"{len(tag.data)} bytes, at most 254")
    elif type(tag) is MalformedTag:
        validate_malformed_tag(CONTROL, where, tag)
    else:
        raise ProtocolError(CONTROL, where, None, f"{type(tag).__name__} is not a control packet tag")


# -- decoding: the reference walk ----------------------------------------------------
def _control_text(b: int) -> str:
    words = ["E-STOP" if b & CONTROL_ESTOP else "no e-stop",
             "FMS attached" if b & CONTROL_FMS else "no FMS",
             "enabled" if b & CONTROL_ENABLED else "disabled",
             MODE_TEXT[b & 3]]
    if b & 0x70:
        words.append(f"other bits 0x{b & 0x70:02x}")
    return ", ".join(words)


def _request_text(b: int) -> str:
    words = []
    if b & REQUEST_REBOOT:
        words.append("REBOOT roboRIO")
    if b & REQUEST_RESTART_CODE:
        words.append("RESTART robot code")
    if b & 0xF0:
        words.append(f"DS attached (0x{b & 0xF0:02x})")
    if b & REQUEST_UNKNOWN_01:
        words.append("bit 0x01 (meaning unknown; a real NI DS sets it for a few packets every 4-6 s)")
    if b & 0x02:
        words.append("bit 0x02 (named by no document)")
    return ", ".join(words) or "nothing requested"


def walk_control(r: Reader) -> ControlPacket:
    seq = r.u16("sequence", "sequence number, echoed by the robot")
    ver = r.u8("comm_version", "comm version (0x01 on every real DS)")
    ctl = r.u8("control")
    r.explain(f"0x{ctl:02x}", f"control: {_control_text(ctl)}")
    req = r.u8("request")
    r.explain(f"0x{req:02x}", f"request: {_request_text(req)}")
    station = walk_station(r)
    r.refuse_over(MAX_CONTROL_SIZE, _CONTROL_WHAT)
    tags = walk_tags(r, _walk_tag)
    return ControlPacket(seq, ver, bool(ctl & CONTROL_ESTOP), bool(ctl & CONTROL_FMS),
                         bool(ctl & CONTROL_ENABLED), Mode(ctl & 3),
                         bool(req & REQUEST_REBOOT), bool(req & REQUEST_RESTART_CODE), station,
                         tags, ctl & 0x70, req & ~0x0C & 0xFF)


_TAG_TITLES = {TAG_JOYSTICK: "joystick", TAG_COUNTDOWN: "countdown", TAG_DATE: "date", TAG_TIMEZONE: "time zone"}


def _walk_tag(r: Reader, where: str) -> ControlTag:
    return walk_tag_or_malformed(r, where, _walk_known_tag, _TAG_TITLES)


def _walk_known_tag(t: Reader, tag_id: int) -> ControlTag:
    if tag_id == TAG_JOYSTICK:
        if t.at_end():
            t.explain("joystick (bare empty slot)", "tag 0x0c: joystick, an empty slot in the 2-byte form "
                                                    "01 0c (no counts; WPILib reads it as empty)")
            return BARE_EMPTY_JOYSTICK
        t.explain("joystick", "tag 0x0c: joystick")
        return _walk_joystick(t)
    if tag_id == TAG_COUNTDOWN:
        t.explain("countdown", "tag 0x07: countdown")
        t.need(4, "seconds")
        value: ControlTag = Countdown(t.f32("seconds", "seconds left in this match period"))
    elif tag_id == TAG_DATE:
        t.explain("date", "tag 0x0f: date, sent once when the robot asks")
        us = t.u32("microseconds")
        parts = [t.u8(name, meaning) for name, meaning in (
            ("second", "second"), ("minute", "minute"), ("hour", "hour, UTC"), ("day", "day of month"),
            ("month", "month, 0 = January"), ("year", "years since 1900"))]
        value = Date(us, *parts)
    elif tag_id == TAG_TIMEZONE:
        t.explain("timezone", "tag 0x10: time zone, sent once when the robot asks")
        value = Timezone(t.rest_text("name", "time zone name"))
    else:
        return keep_raw(t, UnknownTag, "tag", tag_id, "undocumented tag data")
    t.expect_end()
    return value


def _walk_joystick(t: Reader) -> Joystick:
    n_axes = t.u8("axis_count", "number of axes")
    t.need(n_axes, "axes")
    axes = []
    for k in range(n_axes):
        a = t.i8(f"axes[{k}]")
        t.explain(None, f"axis {k}: {int8_to_axis(a):+.3f} (int8; negative /128, positive /127)")
        axes.append(a)
    count = t.u8("button_count", "number of buttons")
    n_bytes = (count + 7) // 8
    buttons = t.uint(n_bytes, "buttons")
    if n_bytes:
        down = [str(b + 1) for b in range(count) if buttons >> b & 1]
        t.explain(f"0x{buttons:0{n_bytes * 2}x}",
                  f"buttons, bit 0 = button 1 (in the last byte); down: {', '.join(down) or 'none'}")
    n_povs = t.u8("pov_count", "number of POVs")
    t.need(2 * n_povs, "povs")
    povs = tuple(t.i16(f"povs[{k}]", "POV angle in degrees, -1 when centred") for k in range(n_povs))
    t.expect_end()
    return Joystick(tuple(axes), buttons, count, povs)


# -- decoding: the fast path ----------------------------------------------------------
_AXES_CACHE: dict[int, struct.Struct] = {}
_POVS_CACHE: dict[int, struct.Struct] = {}
_MODES = tuple(Mode)
_STATIONS = tuple(AllianceStation)


_new_joystick = unchecked_constructor(Joystick)
_new_control = unchecked_constructor(ControlPacket)
_new_countdown = unchecked_constructor(Countdown)


def decode_control(data: bytes) -> ControlPacket:
    """Decode a DS -> roboRIO control packet. Raises only :class:`ProtocolError`: at once,
    for a packet over :data:`MAX_CONTROL_SIZE`."""
    if len(data) > MAX_CONTROL_SIZE:
        raise over_bound(CONTROL, len(data), MAX_CONTROL_SIZE, _CONTROL_WHAT)
    try:
        return _fast_control(data)
    except (Irregular, IndexError, struct.error, KeyError):
        return walk_control(Reader(data, CONTROL))


def _fast_control(data: bytes) -> ControlPacket:
    seq, ver, ctl, req, st = _HEADER.unpack_from(data, 0)
    station = _STATIONS[st] if st < 6 else irregular()
    tags: list[ControlTag] = []
    pos = 6
    n = len(data)
    while pos < n:
        size = data[pos]
        end = pos + 1 + size
        if size == 0 or end > n or len(tags) == MAX_TAGS:
            raise Irregular
        tag_id = data[pos + 1]
        if tag_id == TAG_JOYSTICK:
            if size == 1:
                tags.append(BARE_EMPTY_JOYSTICK)
                pos = end
                continue
            p = pos + 2
            n_axes = data[p]
            p += 1
            ast = _AXES_CACHE.get(n_axes)
            if ast is None:
                ast = _AXES_CACHE[n_axes] = struct.Struct(f">{n_axes}b")
            if p + n_axes > end:
                raise Irregular
            axes = ast.unpack_from(data, p)
            p += n_axes
            count = data[p]
            nb = (count + 7) >> 3
            b_end = p + 1 + nb
            buttons = int.from_bytes(data[p + 1:b_end], "big")
            n_povs = data[b_end]
            p = b_end + 1
            if p + 2 * n_povs != end or b_end >= end:
                raise Irregular
            pst = _POVS_CACHE.get(n_povs)
            if pst is None:
                pst = _POVS_CACHE[n_povs] = struct.Struct(f">{n_povs}h")
            tags.append(_new_joystick(axes, buttons, count, pst.unpack_from(data, p), False))
        elif tag_id == TAG_COUNTDOWN and size == 5:
            tags.append(_new_countdown(F32.unpack_from(data, pos + 2)[0]))
        else:
            raise Irregular  # date, time zone (sent once) and unknown tags: the walk decodes them
        pos = end
    return _new_control(seq, ver, ctl & 0x80 != 0, ctl & 0x08 != 0, ctl & 0x04 != 0, _MODES[ctl & 3],
                         req & 0x08 != 0, req & 0x04 != 0, station, tuple(tags), ctl & 0x70, req & 0xF3)


def annotate_control(data: bytes) -> list[Span]:
    return annotate_with(walk_control, CONTROL, data)


# -- TCP 1740, DS -> roboRIO ------------------------------------------------------------
TCP = "DsToRioFrame"
#: The largest DS -> roboRIO frame decoded (and what the fake roboRIO's framer takes). By the
#: layout a joystick descriptor is at most 520 bytes (a 255-byte name and 255 axis types;
#: 90 at WPILib's limits), match info 262, game data a few (WPILib keeps 64): no real DS
#: comes near it (the 2021 capture's largest: 49 bytes).
MAX_TCP_FRAME = 8192
_TCP_WHAT = "a DS -> roboRIO frame (a real DS's are at most a few hundred bytes)"
FRAME_JOYSTICK_DESCRIPTOR = 0x02
FRAME_MATCH_INFO = 0x07
FRAME_GAME_DATA = 0x0E


@dataclass(frozen=True, slots=True)
class JoystickDescriptor:
    """Frame 0x02: what the DS's USB tab shows for one slot, sent on connect and every change."""

    index: int
    is_xbox: bool = False
    joystick_type: JoystickType | int = JoystickType.UNKNOWN
    name: str = ""
    axis_types: tuple[AxisType | int, ...] = ()
    button_count: int = 0
    pov_count: int = 0

    def encode(self) -> bytes:
        check_int(TCP, "index", self.index, 0, 0xFF)
        check_int(TCP, "joystick_type", self.joystick_type, -128, 127)
        if len(self.axis_types) > 0xFF:
            raise ProtocolError(TCP, "axis_types", None, f"{len(self.axis_types)} axes, at most 255")
        for k, a in enumerate(self.axis_types):
            check_int(TCP, f"axis_types[{k}]", a, 0, 0xFF)
        check_int(TCP, "button_count", self.button_count, 0, 0xFF)
        check_int(TCP, "pov_count", self.pov_count, 0, 0xFF)
        payload = (bytes((self.index, 1 if self.is_xbox else 0, int(self.joystick_type) & 0xFF))
                   + text8(TCP, "name", self.name) + bytes((len(self.axis_types),))
                   + bytes(int(a) for a in self.axis_types) + bytes((self.button_count, self.pov_count)))
        return tcp_frame(TCP, FRAME_JOYSTICK_DESCRIPTOR, payload)


@dataclass(frozen=True, slots=True)
class MatchInfo:
    """Frame 0x07: competition name, match type, match number and replay number."""

    competition: str = ""
    match_type: MatchType | int = MatchType.NONE
    match_number: int = 0
    replay: int = 0

    def encode(self) -> bytes:
        check_int(TCP, "match_type", self.match_type, 0, 0xFF)
        check_int(TCP, "match_number", self.match_number, 0, 0xFFFF)
        check_int(TCP, "replay", self.replay, 0, 0xFF)
        payload = (text8(TCP, "competition", self.competition) + bytes((int(self.match_type),))
                   + U16.pack(self.match_number) + bytes((self.replay,)))
        return tcp_frame(TCP, FRAME_MATCH_INFO, payload)


@dataclass(frozen=True, slots=True)
class GameData:
    """Frame 0x0e: the game-specific message, raw text to the end of the frame."""

    text: str = ""

    def encode(self) -> bytes:
        return tcp_frame(TCP, FRAME_GAME_DATA, encode_text(TCP, "text", self.text, 0xFFFE))


@dataclass(frozen=True, slots=True)
class UnknownFrame(RawFrame):
    """A DS -> roboRIO frame with an id this library does not know: kept raw."""

    MESSAGE: ClassVar[str] = TCP


DsToRioFrame = Union[KeepAlive, JoystickDescriptor, MatchInfo, GameData, UnknownFrame]


def walk_tcp(r: Reader) -> DsToRioFrame:
    tag_id = walk_frame_header(r)
    if tag_id is None:
        return KeepAlive()
    r.refuse_over(MAX_TCP_FRAME, _TCP_WHAT)
    if tag_id == FRAME_JOYSTICK_DESCRIPTOR:
        r.explain("joystick_descriptor", "frame 0x02: joystick descriptor")
        index = r.u8("index", "joystick slot, 0-5")
        xbox = r.u8("is_xbox", "1 if an Xbox controller")
        jt = r.i8("joystick_type")
        r.explain(getattr(enum_or_int(JoystickType, jt), "name", jt), "joystick type (HID or XInput)")
        name = r.text8("name", "device name")
        n_axes = r.u8("axis_count", "number of axes")
        r.need(n_axes, "axis_types")
        types = tuple(enum_or_int(AxisType, r.u8(f"axis_types[{k}]", "axis type: 0 X, 1 Y, 2 Z, 3 twist, 4 throttle"))
                      for k in range(n_axes))
        buttons = r.u8("button_count", "number of buttons")
        povs = r.u8("pov_count", "number of POVs")
        r.expect_end()
        return JoystickDescriptor(index, bool(xbox), enum_or_int(JoystickType, jt), name, types, buttons, povs)
    if tag_id == FRAME_MATCH_INFO:
        r.explain("match_info", "frame 0x07: match info")
        comp = r.text8("competition", "competition (event) name")
        mt = r.u8("match_type", "match type: 0 none, 1 practice, 2 qualification, 3 elimination")
        number = r.u16("match_number", "match number")
        replay = r.u8("replay", "replay number")
        r.expect_end()
        return MatchInfo(comp, enum_or_int(MatchType, mt), number, replay)
    if tag_id == FRAME_GAME_DATA:
        r.explain("game_data", "frame 0x0e: game-specific message")
        return GameData(r.rest_text("text", "game data, raw text to the end of the frame"))
    return keep_raw(r, UnknownFrame, "frame", tag_id, "undocumented frame data")


def decode_tcp(frame: bytes) -> DsToRioFrame:
    """Decode one whole DS -> roboRIO TCP frame (its u16 size included)."""
    return decode_frame(walk_tcp, TCP, frame, MAX_TCP_FRAME, _TCP_WHAT)


def annotate_tcp(frame: bytes) -> list[Span]:
    return annotate_with(walk_tcp, TCP, frame)


__all__ = [
    "BARE_EMPTY_JOYSTICK", "CONTROL_ENABLED", "CONTROL_ESTOP", "CONTROL_FMS", "Countdown", "ControlPacket",
    "Date", "EMPTY_JOYSTICK", "GameData", "Joystick", "JoystickDescriptor", "KeepAlive", "MAX_AXES",
    "MAX_BUTTONS", "MAX_CONTROL_SIZE", "MAX_JOYSTICKS", "MAX_POVS", "MAX_TCP_FRAME", "MalformedTag", "MatchInfo", "REQUEST_NORMAL", "Timezone",
    "UnknownFrame", "UnknownTag", "annotate_control", "annotate_tcp", "axis_to_int8",
    "decode_control", "decode_tcp", "int8_to_axis",
]
