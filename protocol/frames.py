"""What every wire direction shares around its messages: the TCP frame header, the keep-alive,
unknown frames and usage reports; the UDP tag header and unknown tags; the station byte.

A TCP frame is ``[u16 size][u8 id][payload]`` with the size counting the id byte (see
:mod:`protocol.framing`); a UDP tag is ``[u8 size][u8 id][payload]`` the same way. Classes
here that carry a message name in their errors are subclassed by each direction, which sets
``MESSAGE`` (``"RioToDsFrame"``, ``"DsToFmsFrame"``, ...) so errors keep naming the message.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Callable, ClassVar, TypeVar

from .enums import AllianceStation
from .errors import ProtocolError
from .framing import frame_payload
from .wire import U16, Reader, Span, UnknownTag, check_bytes, check_int, over_bound, tcp_frame

T = TypeVar("T")
U = TypeVar("U", bound="UsageReportFrame")


# -- TCP frames ---------------------------------------------------------------------------
@dataclass(frozen=True, slots=True)
class KeepAlive:
    """A frame of size 0: no id, no payload."""

    def encode(self) -> bytes:
        return b"\x00\x00"


@dataclass(frozen=True, slots=True)
class RawFrame:
    """A TCP frame with an id this library does not know, kept raw. Each direction's
    ``UnknownFrame`` subclasses it with its message name."""

    tag_id: int
    data: bytes = b""
    MESSAGE: ClassVar[str] = "TcpFrame"

    def encode(self) -> bytes:
        check_int(self.MESSAGE, "tag_id", self.tag_id, 0, 0xFF)
        return tcp_frame(self.MESSAGE, self.tag_id, check_bytes(self.MESSAGE, "data", self.data))


@dataclass(frozen=True, slots=True)
class UsageReportFrame:
    """A usage report: u16 team, a u8 no document names, then usage entries kept raw. The
    layout is the same both ways it travels (roboRIO -> DS and DS -> FMS); each direction's
    ``UsageReport`` subclasses this with its message name and frame id."""

    team: int = 0
    unknown: int = 0
    entries: bytes = b""
    MESSAGE: ClassVar[str] = "TcpFrame"
    FRAME_ID: ClassVar[int] = 0

    def encode(self) -> bytes:
        check_int(self.MESSAGE, "team", self.team, 0, 0xFFFF)
        check_int(self.MESSAGE, "unknown", self.unknown, 0, 0xFF)
        entries = check_bytes(self.MESSAGE, "entries", self.entries)
        return tcp_frame(self.MESSAGE, self.FRAME_ID, U16.pack(self.team) + bytes((self.unknown,)) + entries)


def walk_usage_report(r: Reader, cls: type[U], team_meaning: str, unknown_meaning: str) -> U:
    """A usage report's payload as ``cls``; ``r`` stands just after the id byte."""
    if r.spans is not None:
        r.explain("usage_report", f"frame 0x{cls.FRAME_ID:02x}: usage report")
    team = r.u16("team", team_meaning)
    unknown = r.u8("unknown", unknown_meaning)
    return cls(team, unknown, r.rest("entries", "usage entries, kept raw"))


def walk_frame_header(r: Reader) -> int | None:
    """Check the u16 size against the frame and read the id: ``None`` for a keep-alive."""
    size = r.u16("size", "frame size, counting the id byte")
    if size + 2 != r.end:
        r.fail("size", f"size field says {size} byte(s) follow, {r.end - 2} do", 0)
    if size == 0:
        if r.spans is not None:
            r.explain(0, "frame size 0: an empty keep-alive frame")
        return None
    return r.u8("id")


def decode_frame(walk: Callable[[Reader], T], message: str, frame: bytes, bound: int | None = None,
                 what: str = "") -> T:
    """Decode one whole TCP frame (its u16 size included) with ``walk``; a frame over
    ``bound`` bytes is refused before anything is walked (``what`` names the frame kind)."""
    if bound is not None and len(frame) > bound:
        raise over_bound(message, len(frame), bound, what)
    frame_payload(message, frame)
    return walk(Reader(frame, message))


# -- UDP tags and anything kept raw ---------------------------------------------------------
def walk_tag_header(r: Reader, where: str) -> tuple[Reader, int]:
    """``[u8 size][u8 id]``: a reader over the rest of the tag, and the id. The size counts the
    id byte, so a size of 0 is refused."""
    size = r.u8(f"{where}.size", "tag size, counting the id byte")
    if size == 0:
        r.fail(f"{where}.size", "a tag size of 0 leaves no room for the id", r.pos - 1)
    t = r.child(size, where)
    return t, t.u8("id")


def keep_raw(r: Reader, make: Callable[[int, bytes], T], what: str, tag_id: int, data_meaning: str,
             notes: dict[int, str] | None = None) -> T:
    """``make(tag_id, the rest of r)``: a tag or frame no document describes, kept raw.
    ``notes`` say what is known of some ids (what a real peer sends there)."""
    if r.spans is not None:
        note = (notes or {}).get(tag_id, f"{what} 0x{tag_id:02x}: not documented, kept as raw bytes")
        r.explain(f"0x{tag_id:02x}", note)
    return make(tag_id, r.rest("data", data_meaning))


#: The last part of the field name of a malformed tag's span (``tags[2].malformed``): the
#: inspector marks these bytes as bad though the packet as a whole decoded.
MALFORMED = "malformed"


@dataclass(frozen=True, slots=True)
class MalformedTag:
    """A UDP tag that is not laid out as documented, kept as it came.

    ``raw`` is the whole tag, its size byte included; when the size runs past the packet it
    is the rest of the packet, and a size of 0 is a 1-byte tag with no id (``tag_id`` None).
    A robot applies the packet's header all the same and drops this tag's data, as WPILib's
    robot side does (it applies enable, mode and station before it walks the tags): a peer
    with one wrong size byte (LibDS's joystick tags) must not lose its whole packet.
    ``reason`` names the field and byte offset; it is not part of the bytes.
    """

    tag_id: int | None
    raw: bytes
    reason: str = field(default="", compare=False)

    def encode(self) -> bytes:
        return bytes(self.raw)


def validate_malformed_tag(message: str, where: str, tag: MalformedTag) -> None:
    if len(check_bytes(message, f"{where}.raw", tag.raw)) == 0:
        raise ProtocolError(message, f"{where}.raw", None, "a malformed tag has at least its size byte")


def walk_tag_or_malformed(r: Reader, where: str, walk_known: Callable[[Reader, int], T],
                          titles: dict[int, str]) -> T | MalformedTag:
    """One ``[u8 size][u8 id][data]`` tag read by ``walk_known(reader_over_the_tag, id)``,
    or a :class:`MalformedTag` when its size is 0, runs past the packet, or its data is not
    laid out as ``walk_known`` expects. A malformed tag is one span, ``{where}.malformed``."""
    start = r.pos
    size = r.data[start]
    left = r.end - start - 1
    if size == 0 or size > left:
        end = start + 1 if size == 0 else r.end
        tag_id = None if size == 0 or left == 0 else r.data[start + 1]
        reason = (f"{where}.size at byte {start}: " + ("a size of 0 leaves no room for an id" if size == 0
                  else f"{size} byte(s) said, {left} left in the packet"))
        return _malformed(r, where, start, end, tag_id, reason, titles)
    kept = len(r.spans) if r.spans is not None else 0
    t, tag_id = walk_tag_header(r, where)
    try:
        return walk_known(t, tag_id)
    except ProtocolError as exc:
        if r.spans is not None:
            del r.spans[kept:]
        at = f" at byte {exc.offset}" if exc.offset is not None else ""
        return _malformed(r, where, start, t.end, tag_id, f"{exc.field}{at}: {exc.reason}", titles)


def _malformed(r: Reader, where: str, start: int, end: int, tag_id: int | None, reason: str,
               titles: dict[int, str]) -> MalformedTag:
    raw = bytes(r.data[start:end])
    r.pos = end
    if r.spans is not None:
        what = "no id" if tag_id is None else f"tag 0x{tag_id:02x}" + (
            f" ({titles[tag_id]})" if tag_id in titles else "")
        r.spans.append(Span(start, end - start, r.name(f"{where}.{MALFORMED}"), raw.hex(" "),
                            f"MALFORMED, {what}: {reason}. A robot applies the header and drops this tag's data"))
    return MalformedTag(tag_id, raw, reason)


#: The most tags one UDP packet may hold, in every direction. A real DS sends at most 9 to
#: its robot (six joysticks, the countdown, the date and the time zone) and 5 to its FMS, a
#: real roboRIO at most 12 (six joystick outputs, disk, CPU, RAM, PDP, 0x09 and CAN), an FMS
#: 1 (Cheesy Arena's game data). A packet with more comes from no real peer: it is refused
#: at its 33rd tag, so what one packet costs to walk stays bounded (a tag that is not laid
#: out as documented costs a few microseconds to name; a packet within its size bound could
#: otherwise hold 500 of them).
MAX_TAGS = 32


def check_packet(message: str, data: bytes, tags: int, bound: int, what: str) -> bytes:
    """``data``, a packet just encoded with ``tags`` tags, if its peer will decode it: at most
    ``bound`` bytes and :data:`MAX_TAGS` tags. Else a ProtocolError: nothing here sends what
    the other end refuses."""
    if tags > MAX_TAGS:
        raise ProtocolError(message, "tags", None, f"{tags} tags, at most {MAX_TAGS}")
    if len(data) > bound:
        raise ProtocolError(message, "size", None, f"{len(data)} bytes is over the {bound}-byte bound of {what}")
    return data


def walk_tags(r: Reader, walk_tag: Callable[..., T], *args: Any) -> tuple[T, ...]:
    """Tags to the end of the packet, each ``walk_tag(r, "tags[i]", *args)``; more than
    :data:`MAX_TAGS` is a ProtocolError at the first one over."""
    tags: list[T] = []
    while not r.at_end():
        if len(tags) == MAX_TAGS:
            r.fail(f"tags[{MAX_TAGS}]", f"more than {MAX_TAGS} tags (a real peer sends at most 12): "
                                        "the packet is refused")
        tags.append(walk_tag(r, f"tags[{len(tags)}]", *args))
    return tuple(tags)


def validate_unknown_tag(message: str, where: str, tag: object) -> None:
    """Refuse (ProtocolError naming ``where``) anything but an UnknownTag that fits a u8 tag."""
    if type(tag) is not UnknownTag:
        raise ProtocolError(message, where, None, f"{type(tag).__name__} is not a tag of this packet")
    check_int(message, f"{where}.tag_id", tag.tag_id, 0, 0xFF)
    if len(check_bytes(message, f"{where}.data", tag.data)) > 0xFE:
        raise ProtocolError(message, f"{where}.data", None, f"{len(tag.data)} bytes, at most 254")


# -- fields -------------------------------------------------------------------------------
def walk_station(r: Reader) -> AllianceStation:
    """The alliance station byte: 0-2 red, 3-5 blue; anything else names no station."""
    st = r.u8("station")
    if st > 5:
        r.fail("station", f"{st} is not an alliance station (0-5)", r.pos - 1)
    station = AllianceStation(st)
    if r.spans is not None:
        r.explain(station.label, f"alliance station {station.label} (0-2 red, 3-5 blue)")
    return station
