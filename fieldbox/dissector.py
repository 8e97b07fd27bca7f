"""The wire layouts of every packet kind, found by asking protocol/ itself: what
``fieldbox dissector`` turns into a Wireshark Lua plugin.

Nothing here restates a layout. For each message, tag and frame class the model takes an
instance, encodes it with the class's own ``encode``, and reads the annotation
(:func:`protocol.kinds.Kind.annotate`, the spans ``fieldbox decode`` prints) for the wire
items: their order, widths and the meaning text. It then changes one dataclass field at a
time and encodes again: the bytes that change say which wire item holds the field and which
bits of it (the e-stop bit of the control byte, the mode's low two bits), and how a number
is scaled (a battery of 1.0 V is 0x0100: 1/256 V a step). What a decoder does with a tag
that is not laid out as documented (kept raw, malformed, or the whole packet refused) is
found the same way, by decoding such a packet. So a layout changed in protocol/ changes the
plugin, and tests/test_dissector.py holds the plugin to ``fieldbox decode`` field by field.

Counts are found the same way (a span that reads 1 with one element and 2 with two), as are
the forms one class takes (a bare joystick slot, an idle output, the seed's 4-byte disk tag),
tried by the plugin by their size.

The 2010 packets are fixed-size and are read the same way, with what they add found by
asking the decoder too: a 4-byte span holding zlib's CRC-32 of what precedes it is a CRC the
plugin checks (the probe seals its own changed packets again before decoding them); padding
that runs up to a fixed offset, what follows sitting there however long the user data is;
lengths before bytes; fixed-length texts and lists; records of ``[size][id][data]`` that a
size of 0 ends; a team sent as its hundreds and its last two digits (each byte's weight is the
value that sets it alone); a little-endian count; the largest value the decoder takes (an
analog input's 1023); a bit that is set when the field is false (the 2010 "not e-stopped").
A structure the probe still cannot walk front to back is named in :attr:`Struct.opaque`: the
plugin shows its bytes as one field and says why, rather than guess.
"""

from __future__ import annotations

import dataclasses
import enum
import re
import struct
import types
import typing
import zlib
from dataclasses import dataclass, field
from typing import Any, Callable, Union

from protocol import kinds as protocol_kinds
from protocol.errors import ProtocolError
from protocol.frames import KeepAlive, MalformedTag, RawFrame
from protocol.wire import Span, UnknownTag

#: Kind -> the short name its Wireshark fields start with (``frc.ds.sequence``).
PREFIXES = {
    "ds-to-rio": "ds", "rio-to-ds": "rio", "ds-to-rio-tcp": "dstcp", "rio-to-ds-tcp": "riotcp",
    "ds-to-fms": "dsfms", "fms-to-ds": "fms", "ds-to-fms-tcp": "dsfmstcp", "fms-to-ds-tcp": "fmstcp",
    "legacy-ds-to-robot": "ds2010", "legacy-robot-to-ds": "rio2010", "legacy-dashboard": "dash2010",
    "legacy-netconsole": "netconsole",
}

_INDEX = re.compile(r"\[\d+\]")


def snake(name: str) -> str:
    """``GameDataTag`` -> ``game_data_tag``: a class as a Wireshark field name part."""
    return re.sub(r"(?<=[a-z0-9])(?=[A-Z])|(?<=[A-Z])(?=[A-Z][a-z])", "_", name).lower()


# -- the model ------------------------------------------------------------------------------
@dataclass
class Bits:
    """One dataclass field carried in (some bits of) a wire item."""

    path: str  # the dataclass field, dotted for a nested one (``date.month``)
    kind: str  # "bool", "int", "enum", "float", "f32"
    mask: int  # of the wire item's big-endian integer
    shift: int  # value = (raw & mask) >> shift
    scale: float = 1.0  # "float": value = raw * scale
    values: dict[int, str] | None = None  # "enum": member names by value
    signed: bool = False
    strict: bool = False  # a value outside ``values`` makes the decoder refuse the packet
    invert: bool = False  # "bool": true when the bit is clear (a 2010 control byte's 0x40, "not e-stopped")
    little: bool = False  # little-endian on the wire (the 2010 dashboard's reply count)
    most: int | None = None  # the largest value the decoder takes (a 2010 analog input: 1023)
    or_bytes: bool = False  # a value ``values`` does not name is kept as its bytes (a 2010 station)
    weights: list[int] | None = None  # value = sum of each byte times its weight (a 2010 team: 2, 94)
    mosts: list[int] | None = None  # with weights: the largest each byte may hold (99 for the 94)


@dataclass
class Item:
    """One wire span of fixed width: a number, or a byte of bits."""

    name: str  # the span's field name (relative to its struct)
    width: int
    meaning: str  # the span's meaning when it does not depend on the value, else ""
    bits: list[Bits] = field(default_factory=list)
    width_from: str | None = None  # its width is ceil(that field / 8) bytes (a joystick's buttons)


@dataclass
class Text:
    path: str
    prefix: int  # bytes of the length before it; 0: to the end of the struct
    meaning: str = ""
    optional: bool = False  # absent when what is left is exactly one more prefixed text
    most: int | None = None  # a longer text makes the decoder keep its tag raw
    length: int = 0  # exactly this many bytes (a 2010 version string: 8)
    strip: str = ""  # the padding character the decoder strips from its end (an LCD line's spaces)
    upto: int | None = None  # runs up to this offset of its struct, where what follows sits


@dataclass
class Raw:
    path: str  # bytes to the end of the struct, or ``length`` of them
    meaning: str = ""
    length: int = 0  # bytes the encoder takes exactly; 0: any, to the end
    prefix: int = 0  # bytes of the length before it (a 2010 user data area's u32)
    strip: bool = False  # the decoder strips its trailing zeros (a 2010 packet's padding)
    upto: int | None = None  # runs up to this offset of its struct, where what follows sits


@dataclass
class Tags:
    """``[u8 size][u8 id][payload]`` to the end of the packet."""

    path: str
    by_id: dict[int, str]  # tag id -> struct name
    empty: str  # a size byte of 0: "EmptyTag", "malformed" or "error"
    wrong: str  # a known id laid out otherwise: "UnknownTag", "malformed" or "error"
    over: str  # a size running past the packet: "malformed" or "error"
    max_tags: int = 32


@dataclass
class Struct:
    name: str  # the dataclass's name
    items: list[Item | Text | Raw | Tags | Array | Ints | Crc | Group]
    opaque: str = ""  # why the plugin shows it as bytes only (see the module docstring)
    fixed: int | None = None  # exactly this many bytes (tags, frames), or None
    id_field: str | None = None  # a frame class sent under several ids: the field the id is
    id_values: dict[int, str] | None = None  # that field's enum names
    consts: list[Const] = field(default_factory=list)
    forms: list[str] = field(default_factory=list)  # other forms of the same class, tried by size
    cls: str = ""  # the class (a form's name is "Class/flag")


@dataclass
class Ints:
    """A list of integers, ``count``-prefixed (0: to the end of the struct)."""

    path: str
    width: int
    signed: bool
    count: int
    meaning: str = ""
    values: dict[int, str] | None = None  # a list of enum members (a joystick's axis types)


@dataclass
class Const:
    """A field this form of the struct never puts on the wire (a bare joystick slot's
    ``bare``, True; every other form's, False): the plugin shows the value it must have."""

    path: str
    kind: str  # "bool", "int", "none"
    value: Any


@dataclass
class Array:
    """A list of one struct, each ``count``-prefixed or to the end of its struct."""

    path: str
    element: str  # struct name
    count: int  # bytes of the element count before the list; 0: elements to the end
    count_name: str = ""
    exactly: int = 0  # always this many elements (a 2010 control packet's four joysticks)
    sized: bool = False  # each element after a u8 size of the rest, a size of 0 ending the list
    upto: int | None = None  # a sized list ends by this offset of its struct; a size past it
    # ends the list, that element and the rest kept raw in the next item (malformed)


@dataclass
class Crc:
    """A CRC-32 (zlib's) of its struct's bytes up to its own end, itself taken as zero."""

    name: str


@dataclass
class Magic:
    """Bytes the decoder requires as they are (the 2010 status packet's LCD marker, 9f ff)."""

    name: str
    value: bytes
    meaning: str = ""


@dataclass
class Group:
    """Items present only when bytes are left (the 2010 status packet's LCD text): a field that
    is None when they are absent."""

    path: str
    items: list[Item | Text | Raw | Magic]


@dataclass
class KindModel:
    kind: str
    prefix: str
    title: str
    message: str
    tcp: bool
    root: str | None  # the UDP message's struct
    frames: dict[int, str]  # TCP: frame id -> struct name
    structs: dict[str, Struct]
    bound: int | None  # the decoder's size bound, in bytes
    frame_bound: int | None = None
    sizes: tuple[int, ...] = ()  # the only sizes the decoder takes (a 2010 packet's 1024), or ()


# -- probing -----------------------------------------------------------------------------
def _spans(kind: protocol_kinds.Kind, data: bytes) -> list[Span]:
    return sorted(kind.annotate(data), key=lambda s: s.offset)


def _type_hints(cls: type) -> dict[str, Any]:
    import sys

    module = sys.modules[cls.__module__]
    return typing.get_type_hints(cls, vars(module))


def _field_kind(hint: Any) -> tuple[str, Any]:
    """(what the field is, its enum class) from its annotation."""
    args = typing.get_args(hint)
    origin = typing.get_origin(hint)
    if hint is bool:
        return "bool", None
    if hint is int:
        return "int", None
    if hint is float:
        return "float", None
    if hint is str:
        return "str", None
    if hint is bytes:
        return "bytes", None
    if isinstance(hint, type) and issubclass(hint, enum.IntEnum):
        return "enum", hint
    if origin is Union or origin is types.UnionType:
        members = [a for a in args if a is not type(None)]
        if type(None) in args and members == [str]:
            return "optstr", None
        enums = [a for a in members if isinstance(a, type) and issubclass(a, enum.IntEnum)]
        if enums and all(a is int or a in enums for a in members):
            return "enum", enums[0]
        if len(enums) == 1 and set(members) == {enums[0], bytes}:
            return "enum_or_bytes", enums[0]
        if type(None) in args and members == [int]:
            return "optint", None
        if type(None) in args and len(members) == 1 and typing.get_origin(members[0]) is tuple:
            return "opttuple", members[0]
    if origin is tuple:
        return "tuple", None
    if dataclasses.is_dataclass(hint):
        return "struct", hint
    return "other", None


class Probe:
    """Encode variants of one dataclass ``base`` inside a whole packet and read the changes."""

    def __init__(self, kind: protocol_kinds.Kind, wrap: Callable[[Any], bytes], base: Any, start: int,
                 prefix: str) -> None:
        self.kind = kind
        self.wrap = wrap  # struct instance -> the whole packet's bytes
        self.base = base
        self.start = start  # where the struct's bytes start in the packet
        self.prefix = prefix  # its span names' prefix ("tags[0]."), or ""
        self.data = wrap(base)
        self.spans = [s for s in _spans(kind, self.data) if s.offset >= start]

    def variant(self, path: str, value: Any) -> bytes | None:
        try:
            return self.wrap(_replace(self.base, path, value))
        except (ProtocolError, TypeError, ValueError, OverflowError, struct.error):
            return None

    def span_at(self, offset: int) -> Span | None:
        return next((s for s in self.spans if s.offset <= offset < s.offset + s.length), None)

    def diff(self, other: bytes) -> list[int]:
        if len(other) != len(self.data):
            return []
        return [i for i, (a, b) in enumerate(zip(self.data, other)) if a != b]


#: Where the kind being built carries a CRC-32 (the 2010 packets': 0x3fc), filled by
#: :func:`build_kind`: bytes the probe changes are sealed again before they are decoded, so
#: the decoder answers about the field changed, not about the CRC.
_CRC_AT: list[int] = []


def _seal(data: bytes) -> bytes:
    for at in _CRC_AT:
        if at + 4 <= len(data):
            data = data[:at] + zlib.crc32(bytes(4), zlib.crc32(data[:at])).to_bytes(4, "big") + data[at + 4:]
    return data


def _decode(kind: protocol_kinds.Kind, data: bytes) -> Any:
    """``kind.decode`` of bytes the probe changed (its CRC made right first)."""
    return kind.decode(_seal(bytes(data)))


def _decoded_value(probe: Probe, data: bytes, path: str) -> Any:
    """The value of ``path`` (in the probed struct) when ``data`` is decoded, or None."""
    try:
        obj = _decode(probe.kind, data)
    except ProtocolError:
        return None
    return _follow(obj, probe.prefix + path)


def _follow(obj: Any, dotted: str) -> Any:
    for part in dotted.split("."):
        m = re.fullmatch(r"(\w+)\[(\d+)\]", part)
        try:
            obj = getattr(obj, m.group(1))[int(m.group(2))] if m else getattr(obj, part)
        except (AttributeError, IndexError, TypeError):
            return None
    return obj


def _replace(obj: Any, path: str, value: Any) -> Any:
    """``obj`` with the field at ``path`` (``date.month``, ``currents[3]``) set to ``value``."""
    head, _, rest = path.partition(".")
    m = re.fullmatch(r"(\w+)\[(\d+)\]", head)
    if m:
        name, k = m.group(1), int(m.group(2))
        items = list(getattr(obj, name))
        items[k] = _replace(items[k], rest, value) if rest else value
        return dataclasses.replace(obj, **{name: tuple(items)})
    if rest:
        return dataclasses.replace(obj, **{head: _replace(getattr(obj, head), rest, value)})
    return dataclasses.replace(obj, **{head: value})


def _item_int(data: bytes, span: Span) -> int:
    return int.from_bytes(data[span.offset:span.offset + span.length], "big")


def probe_struct(probe: Probe, name: str) -> Struct:
    """The struct of ``probe.base``'s class, its items in wire order."""
    cls = type(probe.base)
    items: dict[float, Item | Text | Raw | Tags | Array | Ints | Crc | Group] = {}  # by offset
    consts: list[Const] = []
    opaque: list[str] = []
    rel = {s.offset: s for s in probe.spans}

    def local(span: Span) -> str:
        return span.field[len(probe.prefix):] if span.field.startswith(probe.prefix) else span.field

    def item_for(span: Span) -> Item:
        found = items.get(span.offset)
        if not isinstance(found, Item):
            found = Item(local(span), span.length, _static_meaning(probe, span))
            items[span.offset] = found
        return found

    def scalars(obj: Any, path_prefix: str) -> None:
        for f in dataclasses.fields(obj):
            path = path_prefix + f.name
            what, enum_cls = _field_kind(_type_hints(type(obj))[f.name])
            value = getattr(obj, f.name)
            if what == "struct":
                scalars(value, path + ".")
            elif what in ("bool", "int", "enum", "float") or (what == "optint" and value is not None):
                what = "int" if what == "optint" else what
                bits = _probe_scalar(probe, path, what, enum_cls, value)
                if bits is None and what == "int":
                    own = next((s for s in probe.spans if local(s) == path), None)
                    if own is not None and own.offset not in items:  # a count: changing it changes the length
                        items[own.offset] = Item(path, own.length, "", [Bits(path, "int", (1 << 8 * own.length) - 1, 0)])
                        continue
                    sized = _probe_sized_int(probe, path, obj)
                    if sized is not None:
                        items[sized[0] - 0.5] = sized[1]  # before what follows it when it is 0 bytes
                        continue
                if bits is None:
                    consts.append(Const(path, "bool" if what == "bool" else "int", value))
                    continue
                span, b = bits
                item_for(span).bits.append(b)
            elif what == "optint" and value is None:
                consts.append(Const(path, "none", None))
            elif what in ("str", "optstr"):
                text = next((s for s in probe.spans if local(s) == path), None)
                if text is None:
                    opaque.append(f"{path}: no span for the text")
                    continue
                length = rel.get(text.offset - 1) or rel.get(text.offset - 2) or rel.get(text.offset - 4)
                meaning = _text_meaning(probe, path, text)
                if length is not None and local(length) == f"{path}.length":
                    items[length.offset] = Text(path, length.length, meaning, what == "optstr")
                else:
                    n = text.length
                    exact = probe.variant(path, "x" * n) is not None and probe.variant(path, "x" * (n + 1)) is None \
                        and probe.variant(path, "x" * (n - 1)) is None
                    items[text.offset] = Text(path, 0, meaning, length=n if exact else 0)
            elif what == "bytes":
                raw = next((s for s in probe.spans if local(s) == path), None)
                if raw is None:
                    opaque.append(f"{path}: no span for the bytes")
                    continue
                n = raw.length
                exact = probe.variant(path, bytes(n + 1)) is None and probe.variant(path, bytes(n)) is not None \
                    and (n == 0 or probe.variant(path, bytes(n - 1)) is None)
                length = next((rel[raw.offset - k] for k in (1, 2, 4) if raw.offset - k in rel
                               and local(rel[raw.offset - k]) == f"{path}.length"), None)
                wire = probe.data[raw.offset:raw.offset + n]
                strip = not exact and _decoded_value(probe, probe.data, path) == wire.rstrip(b"\0") != wire
                if length is not None:
                    items[length.offset] = Raw(path, raw.meaning, prefix=length.length)
                else:
                    items[raw.offset] = Raw(path, _raw_meaning(probe, raw), n if exact else 0, strip=strip)
            elif what == "enum_or_bytes":
                found_eb = _probe_enum_or_bytes(probe, path, enum_cls)
                if found_eb is None:
                    opaque.append(f"{path}: a value or its bytes, which this probe cannot read")
                else:
                    items[found_eb[0]] = found_eb[1]
            elif what == "opttuple" and value is None:
                group = _probe_group(probe, path)
                if group is None:
                    opaque.append(f"{path}: an optional part this probe cannot read")
                else:
                    items[group[0]] = group[1]
            elif what == "tuple" and _union_members(_type_hints(type(obj))[f.name]) == [bytes]:
                # a list of a fixed length of byte strings (a 2010 packet's four FPGA checksums)
                if not value or probe.variant(path, tuple(value[:-1])) is not None:
                    opaque.append(f"{path}: a list of byte strings this probe cannot read")
                    continue
                for k in range(len(value)):
                    part = next((s for s in probe.spans if local(s) == f"{path}[{k}]"), None)
                    if part is None:
                        opaque.append(f"{path}[{k}]: no span for the bytes")
                        break
                    items[part.offset] = Raw(f"{path}[{k}]", part.meaning, part.length)
            elif what == "tuple" and path != "tags" and _int_members(_type_hints(type(obj))[f.name]):
                ints = _probe_ints(probe, path, _int_members(_type_hints(type(obj))[f.name]))
                if ints is None and value and probe.variant(path, tuple(value[:-1])) is None:
                    # a list of a fixed length (a PDP's 16 currents): each number on its own, its bits
                    found = [_probe_scalar(probe, f"{path}[{k}]", "int", None, v) for k, v in enumerate(value)]
                    if all(found):
                        for k, one in enumerate(found):
                            assert one is not None
                            one[1].signed = probe.variant(f"{path}[{k}]", -1) is not None  # a 2010 axis: int8
                            item_for(one[0]).bits.append(one[1])
                        continue
                if ints is None and value == ():
                    consts.append(Const(path, "none", None))  # a form with no room for the list
                elif ints is None:
                    opaque.append(f"{path}: a list of numbers this probe cannot read")
                else:
                    items[ints[0]] = ints[1]
            elif what == "tuple" and path != "tags":
                array = _probe_array(probe, path, _type_hints(type(obj))[f.name])
                if array is None:
                    opaque.append(f"{path}: a list this probe cannot read")
                else:
                    offset, arr = array
                    items[offset] = arr
            elif what == "tuple":
                pass
            else:
                opaque.append(f"{path}: {what}")

    scalars(probe.base, "")
    if not probe.prefix:
        for crc_at in _CRC_AT:
            if crc_at >= probe.start:
                items[crc_at] = Crc("crc")
    _bound_areas(probe, items)
    for at, it in items.items():
        # A number alone in its item is read from all of it (a station byte of 0x5b is 91, not
        # 3): the probe only saw the bits its allowed values use.
        if isinstance(it, Item) and len(it.bits) == 1 and it.bits[0].kind in ("enum", "int") and it.width:
            b = it.bits[0]
            b.mask, b.shift = (1 << 8 * it.width) - 1, 0
            if b.kind == "int" and not b.little and not b.weights and not b.signed and at == int(at):
                b.most = _most(probe, b.path, Span(int(at), it.width, "", None, ""), b.mask, 0)
    ordered = [items[k] for k in sorted(items)]
    # The plugin walks a struct front to back: an item that runs to the end with more after it,
    # or a field found in two places, is a layout it cannot walk (the 2010 packets' user data
    # areas, a team number split over two bytes).
    for it in ordered[:-1]:
        if (isinstance(it, Raw) and not it.length and not it.prefix and it.upto is None) or \
                (isinstance(it, Text) and not it.prefix and not it.length and it.upto is None):
            opaque.append(f"{it.path}: runs to the end, but more follows it")
        if isinstance(it, Array) and it.sized and it.upto is None:
            opaque.append(f"{it.path}: a list of sized records with no end this probe can find")
    paths = [b.path for it in ordered if isinstance(it, Item) for b in it.bits]
    opaque.extend(f"{p}: in two places" for p in sorted({p for p in paths if paths.count(p) > 1}))
    return Struct(name, ordered, "; ".join(opaque), consts=consts, cls=cls.__name__)


def _raw_meaning(probe: Probe, span: Span) -> str:
    """Bytes' meaning if it reads the same whether they are all zero or not (else "": a
    padding's "all zero" would be wrong on a packet whose padding is not)."""
    texts = {span.meaning}
    for fill in (0x00, 0x01):
        data = bytearray(probe.data)
        data[span.offset:span.offset + span.length] = bytes([fill]) * span.length
        try:
            texts.update(s.meaning for s in probe.kind.annotate(bytes(data)) if s.offset == span.offset)
        except ProtocolError:
            continue
    return span.meaning if len(texts) == 1 else ""


def _changed(a: bytes, b: bytes) -> list[int]:
    """The offsets where ``a`` and ``b`` differ, leaving out a CRC (it changes with anything)."""
    crc = {at + k for at in _CRC_AT for k in range(4)}
    return [i for i, (x, y) in enumerate(zip(a, b)) if x != y and i not in crc] if len(a) == len(b) else []


def _probe_enum_or_bytes(probe: Probe, path: str, enum_cls: Any) -> tuple[int, Item] | None:
    """A field that is an enum member when its bytes name one and the bytes themselves when not
    (a 2010 station: ASCII "R1" is RED1): the bytes every member changes, read as one number
    named by the members, and kept as bytes of that width when no member names them."""
    datas = {}
    for m in enum_cls:
        d = probe.variant(path, m)
        if d is None or len(d) != len(probe.data):
            return None
        datas[m] = d
    first = next(iter(datas.values()))
    changed = sorted({i for d in datas.values() for i in _changed(first, d)})
    spans = [probe.span_at(i) for i in changed]
    if not spans or any(s is None for s in spans):
        return None
    lo = min(s.offset for s in spans if s is not None)
    hi = max(s.offset + s.length for s in spans if s is not None)
    if hi - lo > 4 or probe.variant(path, bytes(hi - lo)) is None:
        return None
    values = {int.from_bytes(d[lo:hi], "big"): m.name for m, d in datas.items()}
    if len(values) != len(datas):
        return None
    return lo, Item(path, hi - lo, "", [Bits(path, "enum", (1 << 8 * (hi - lo)) - 1, 0, values=values,
                                              or_bytes=True)])


def _probe_group(probe: Probe, path: str) -> tuple[int, Group] | None:
    """A field that is None or a list of texts, the list on the wire after everything else
    (the 2010 status packet's LCD lines): what a one-line list adds, span by span. A span that
    is none of the texts is a marker when the decoder refuses it changed."""
    data = probe.variant(path, ("ab",))
    if data is None or len(data) <= len(probe.data):
        return None
    try:
        decoded = _follow(_decode(probe.kind, data), probe.prefix + path)
    except ProtocolError:
        return None
    items: list[Item | Text | Raw | Magic] = []
    for s in _spans(probe.kind, data):
        if s.offset < len(probe.data):
            continue
        m = re.fullmatch(re.escape(probe.prefix + path) + r"\[(\d+)\]", s.field)
        wire = data[s.offset:s.offset + s.length]
        if m and isinstance(decoded, tuple) and int(m.group(1)) < len(decoded):
            text = wire.decode("utf-8", "surrogateescape")
            value = decoded[int(m.group(1))]
            pad = text[len(value):] if text.startswith(value) else ""
            if len(set(pad)) > 1 or not isinstance(value, str) or (text != value and not pad):
                return None
            items.append(Text(s.field[len(probe.prefix):], 0, s.meaning, length=s.length, strip=pad[:1]))
            continue
        altered = data[:s.offset] + bytes(b ^ 0xFF for b in wire) + data[s.offset + s.length:]
        try:
            _decode(probe.kind, altered)
            return None  # not a marker: a field this probe does not know
        except ProtocolError:
            items.append(Magic(s.field[len(probe.prefix):], wire, s.meaning))
    return len(probe.data), Group(path, items)


def _bound_areas(probe: Probe, items: dict[float, Any]) -> None:
    """Bytes or text that run up to a fixed offset, what follows them sitting there whatever
    came before (a 2010 packet's padding after its user data): each gets ``upto``, as does a
    sized list before such padding (the 2010 control packet's dynamic blocks)."""
    keys = sorted(items)
    for k, key in enumerate(keys[:-1]):
        it = items[key]
        if not (isinstance(it, (Raw, Text)) and not it.length and not it.prefix):
            continue
        after = keys[k + 1]
        value = _follow(probe.base, it.path)
        if not isinstance(value, (bytes, str)) or after != int(after):
            continue
        longer = probe.variant(it.path, value + b"\0" if isinstance(value, bytes) else value + "x")
        before = {s.offset: s.field for s in probe.spans}
        if longer is None or len(longer) != len(probe.data) or int(after) not in before:
            continue
        if {s.offset: s.field for s in _spans(probe.kind, longer)}.get(int(after)) == before[int(after)]:
            it.upto = int(after) - probe.start
            prev = items[keys[k - 1]] if k else None
            if isinstance(prev, Array) and prev.sized:
                prev.upto = it.upto
                _sized_ends(probe, prev, int(keys[k - 1] + 0.5), int(after))


def _sized_ends(probe: Probe, arr: Array, start: int, end: int) -> None:
    """How the decoder ends a list of sized records: a size of 0 must end it, and a size that
    runs past ``end`` must end it with that record and the rest kept raw in what follows;
    else the list is not one the plugin walks (``upto`` taken back)."""
    data = bytearray(probe.data)
    data[start:start + 4] = bytes((0, 2, 1, 1))  # a 0 size byte, then what would be a record
    try:
        zero = _follow(_decode(probe.kind, bytes(data)), probe.prefix + arr.path) == ()
    except ProtocolError:
        zero = False
    data = bytearray(probe.data)
    pos = start
    while end - pos > 256:
        data[pos:pos + 2] = bytes((255, 1))
        pos += 256
    data[pos] = end - pos  # runs one byte past the end
    try:
        got = _follow(_decode(probe.kind, bytes(data)), probe.prefix + arr.path)
        over = isinstance(got, tuple) and len(got) == (pos - start) // 256
    except ProtocolError:
        over = False
    if not (zero and over):
        arr.upto = None


def _forms(st: Struct, inst: Any, wrap: Callable[[Any], bytes], make_probe: Callable[[Any], Probe],
           structs: dict[str, Struct]) -> None:
    """The other forms of a class: each flag this form leaves off the wire set (a bare
    joystick slot, an idle joystick output), each absent optional number given (a disk tag's
    block): probed as structs of their own, tried by the plugin by size."""
    for c in st.consts:
        value = True if c.kind == "bool" and c.value is False else 0 if c.kind == "none" else None
        if value is None:
            continue
        alt = _replace(inst, c.path, value)
        try:
            wrap(alt)
        except (ProtocolError, TypeError, ValueError):
            continue
        form = probe_struct(make_probe(alt), st.cls)
        form.name = f"{st.cls}/{c.path}"
        payload = [i for i in form.items if isinstance(i, Item)]
        if all(isinstance(i, Item) and i.width_from is None for i in form.items):
            form.fixed = sum(i.width for i in payload)
        structs[form.name] = form
        st.forms.append(form.name)


def _int_members(hint: Any) -> list[type]:
    """The member types of a tuple of integers (``tuple[int, ...]``, ``tuple[AxisType | int, ...]``),
    or [] for any other tuple."""
    args = typing.get_args(hint)
    inner = args[0] if args else None
    members = [a for a in (typing.get_args(inner) or (inner,)) if isinstance(a, type)]
    ok = members and all(a is int or issubclass(a, enum.IntEnum) for a in members) and int in members
    return members if ok else []


def _probe_ints(probe: Probe, path: str, members: list[type]) -> tuple[int, Ints] | None:
    """A list of integers: the width of one (its span), signed if -1 encodes, and a count
    before the list if one (a span reading 1, then 2 with two elements) precedes it."""
    one, two = probe.variant(path, (1,)), probe.variant(path, (1, 1))
    if one is None or two is None:
        return None
    element = next((s for s in _spans(probe.kind, one) if s.field == f"{probe.prefix}{path}[0]"), None)
    if element is None:
        return None
    signed = probe.variant(path, (-1,)) is not None
    by_offset = {s.offset: s for s in _spans(probe.kind, two)}
    count = 0
    start = element.offset
    for s in _spans(probe.kind, one):
        t = by_offset.get(s.offset)
        if s.offset < element.offset and s.value == 1 and t is not None and t.value == 2 and s.offset + s.length == element.offset:
            count, start = s.length, s.offset
    enums = [m for m in members if issubclass(m, enum.IntEnum)]
    values = {int(v): v.name for v in enums[0]} if enums else None
    return start, Ints(path, element.length, signed, count, element.meaning if count == 0 else "", values)


def _probe_sized_int(probe: Probe, path: str, obj: Any) -> tuple[int, Item] | None:
    """An integer whose width is another field's count of bits (a joystick's buttons: as many
    bytes as its button count needs): set each other int field to 9 and look for a 2-byte span."""
    for f in dataclasses.fields(obj):
        if f.name == path or _field_kind(_type_hints(type(obj))[f.name])[0] != "int":
            continue
        data = probe.variant(f.name, 9)
        if data is None:
            continue
        span = next((s for s in _spans(probe.kind, data) if s.field == f"{probe.prefix}{path}"), None)
        if span is not None and span.length == 2:
            offset = span.offset
            bits = Bits(path, "int", 0xFFFFFFFF, 0)
            return offset, Item(path, 0, "", [bits], width_from=f.name)
    return None


def _text_meaning(probe: Probe, path: str, span: Span) -> str:
    """A text's meaning if it does not quote or count the text, else ""."""
    other = probe.variant(path, "xyz") or probe.variant(path, "x" * span.length)  # "x" * 8: a fixed-size text
    if other is None:
        return span.meaning
    try:
        found = [s.meaning for s in probe.kind.annotate(other) if s.field == span.field]
    except ProtocolError:
        return ""
    return span.meaning if found == [span.meaning] else ""


#: Structs found inside lists, by name: filled by :func:`_probe_array` while a kind is built.
_ELEMENTS: dict[str, Struct] = {}


def _probe_array(probe: Probe, path: str, hint: Any) -> tuple[float, Array] | None:
    members = _union_members(hint)
    if len(members) != 1 or not dataclasses.is_dataclass(members[0]):
        return None
    cls = members[0]
    current = _follow(probe.base, path)
    if current and probe.variant(path, tuple(current[:-1])) is None:
        return _probe_fixed_array(probe, path, cls, current)
    elem = _instance(cls, lambda e: probe.wrap(_replace(probe.base, path, (e,))))
    one, two = probe.variant(path, (elem,)), probe.variant(path, (elem, elem))
    none = probe.variant(path, ())
    if one is None or two is None or none is None:
        return None
    if len(one) == len(none):
        return _probe_sized_array(probe, path, cls, elem, one)
    size = len(two) - len(one)
    start = len(none) - 0
    spans_one = {s.offset: s for s in _spans(probe.kind, one)}
    spans_two = {s.offset: s for s in _spans(probe.kind, two)}
    count = 0
    count_name = ""
    for off, s in spans_one.items():  # a count before the list: 1 with one element, 2 with two
        t = spans_two.get(off)
        if t is not None and s.value == 1 and t.value == 2 and off < len(none):
            count, count_name = s.length, s.field
            start = off + s.length
    inner = Probe(probe.kind, lambda e: probe.wrap(_replace(probe.base, path, (e,))), elem, start,
                  f"{probe.prefix}{path}[0].")
    st = probe_struct(inner, cls.__name__)
    if all(isinstance(i, Item) for i in st.items):
        st.fixed = size
    _ELEMENTS[cls.__name__] = st
    at = start - count if count else start
    return at, Array(path, cls.__name__, count, count_name)


def _element_start(probe: Probe, data: bytes, path: str, k: int) -> int | None:
    inside = f"{probe.prefix}{path}[{k}]."
    found = [s.offset for s in _spans(probe.kind, data) if s.field.startswith(inside)]
    return min(found) if found else None


def _probe_fixed_array(probe: Probe, path: str, cls: type, current: tuple[Any, ...]) -> tuple[int, Array] | None:
    """A list of always the same number of one struct, back to back (a 2010 control packet's
    four joysticks): the first element probed where it sits."""
    starts = [_element_start(probe, probe.data, path, k) for k in range(len(current))]
    if None in starts or len(starts) < 2:
        return None
    first = starts[0]
    assert first is not None
    size = (starts[1] or 0) - first
    if size <= 0 or starts != [first + k * size for k in range(len(current))]:
        return None
    inner = Probe(probe.kind, lambda e: probe.wrap(_replace(probe.base, f"{path}[0]", e)), current[0], first,
                  f"{probe.prefix}{path}[0].")
    st = probe_struct(inner, cls.__name__)
    if not all(isinstance(i, Item) for i in st.items) or sum(i.width for i in st.items if isinstance(i, Item)) != size:
        return None
    st.fixed = size
    _ELEMENTS[cls.__name__] = st
    return first, Array(path, cls.__name__, 0, exactly=len(current))


def _probe_sized_array(probe: Probe, path: str, cls: type, elem: Any, one: bytes) -> tuple[float, Array] | None:
    """A list inside a packet of a fixed size, each element after a u8 size of the rest (a 2010
    control packet's dynamic blocks): the element probed after its size byte. Where the list
    ends is found with what follows it (:func:`_bound_areas`)."""
    start = _element_start(probe, one, path, 0)
    if start is None:
        return None
    inside = [s for s in _spans(probe.kind, one) if s.field.startswith(f"{probe.prefix}{path}[0].")]
    end = max(s.offset + s.length for s in inside)
    head = next(s for s in inside if s.offset == start)
    if head.length != 1 or one[start] != end - start - 1:
        return None
    inner = Probe(probe.kind, lambda e: probe.wrap(_replace(probe.base, path, (e,))), elem, start + 1,
                  f"{probe.prefix}{path}[0].")
    st = probe_struct(inner, cls.__name__)
    _ELEMENTS[cls.__name__] = st
    # before what the list leaves (its padding), which starts where the list does when it is empty
    return start - 0.5, Array(path, cls.__name__, 0, sized=True)


def _static_meaning(probe: Probe, span: Span) -> str:
    """The span's meaning if it reads the same whatever the item holds (a value of all ones
    and of one), else "": the plugin then shows the value and its bits, not stale words."""
    texts = {span.meaning}
    for fill in (0xFF, 0x01):
        data = bytearray(probe.data)
        data[span.offset:span.offset + span.length] = bytes([fill]) * span.length
        try:
            found = [s for s in probe.kind.annotate(bytes(data)) if s.offset == span.offset]
        except ProtocolError:
            continue
        texts.update(s.meaning for s in found)
    return span.meaning if len(texts) == 1 else ""


def _probe_scalar(probe: Probe, path: str, what: str, enum_cls: Any,
                  value: Any) -> tuple[Span, Bits] | None:
    if what == "bool":
        flipped = probe.variant(path, not value)
        changed = probe.diff(flipped) if flipped else []
        at = probe.span_at(changed[0]) if changed else None
        if at is None or flipped is None:
            return None
        bit = _item_int(probe.data, at) ^ _item_int(flipped, at)
        invert = bool(_item_int(probe.data, at) & bit) != bool(value)
        return at, Bits(path, "bool", bit, (bit & -bit).bit_length() - 1, invert=invert)
    if what == "float":
        one = probe.variant(path, 1.0)
        if one is None:
            return None
        nothing = probe.variant(path, 0.0)
        changed = probe.diff(one) if nothing is None else [i for i, (a, b) in enumerate(zip(nothing, one)) if a != b]
        at = probe.span_at(changed[0]) if changed else None
        if at is None or nothing is None:
            return None
        raw = _item_int(one, at)
        if at.length == 4 and one[at.offset:at.offset + 4] == struct.pack(">f", 1.0):
            return at, Bits(path, "f32", 0xFFFFFFFF, 0)
        return at, Bits(path, "float", (1 << 8 * at.length) - 1, 0, scale=1.0 / raw)
    # int or enum: which bits it may take
    members = {int(m): m for m in enum_cls} if what == "enum" and enum_cls is not None else {}
    candidates = sorted(members) + [1 << k for k in range(64)]
    zero = probe.variant(path, members.get(0, 0))
    if zero is None and members:
        zero = probe.variant(path, members[min(members)])
    if zero is None:
        zero = probe.data  # a field 0 is not allowed in (a DS ping's id): compare with the base
    span: Span | None = None
    mask = 0
    spill = False
    lowest: tuple[int, int] | None = None
    if all(probe.variant(path, members.get(v, v)) is None for v in candidates[:16]):
        candidates = list(range(256))  # a field of a few allowed values (a DS ping's id: 0x1c, 0x1d)
    for v in candidates:
        other = probe.variant(path, members.get(v, v))
        if other is None:
            continue
        changed = [i for i, (a, b) in enumerate(zip(zero, other)) if a != b] if len(other) == len(zero) else []
        if not changed:
            continue
        if span is None:
            span = probe.span_at(changed[0])
            if span is None:
                return None
        x = _item_int(zero, span) ^ _item_int(other, span)
        mask |= x
        spill = spill or any(not span.offset <= i < span.offset + span.length for i in _changed(zero, other))
        if lowest is None and v:
            lowest = (v, x)
    if span is None or lowest is None:
        return None
    if spill:  # the number is spread over more than one span (a 2010 dashboard's team: 2, 94)
        return _probe_radix(probe, path, zero) if what == "int" else None
    v, x = lowest
    if what == "int" and span.length == 2 and v == 1 and x == 0x100:
        # 1 sets the first byte and 256 the second: little-endian (the 2010 dashboard's reply count)
        other = probe.variant(path, 256)
        if other is not None and _item_int(zero, span) ^ _item_int(other, span) == 1:
            return span, Bits(path, "int", 0xFFFF, 0, little=True)
    shift = (x & -x).bit_length() - 1 - ((v & -v).bit_length() - 1)
    if what == "int" and shift == 0:
        # The encoder may take bits the decoder does not keep in this field (a control byte's
        # other bits hold the named flags): what decoding the item's bits all set gives is the mask.
        data = bytearray(probe.data)
        data[span.offset:span.offset + span.length] = bytes([0xFF]) * span.length
        kept = _decoded_value(probe, bytes(data), path)
        if isinstance(kept, int) and not isinstance(kept, bool) and 0 < kept < mask:
            mask = kept
    values = {int(m): m.name for m in enum_cls} if what == "enum" and enum_cls else None
    signed = what == "enum" and enum_cls is not None and min(int(m) for m in enum_cls) < 0
    strict = False
    if values:  # does the decoder refuse a value no member names? (a station byte of 6 is refused)
        outside = next((v for v in range((mask >> shift) + 1) if v not in values), None)
        if outside is not None:
            data = bytearray(probe.data)
            raw = (_item_int(probe.data, span) & ~mask) | (outside << shift)
            data[span.offset:span.offset + span.length] = raw.to_bytes(span.length, "big")
            try:
                _decode(probe.kind, bytes(data))
            except ProtocolError:
                strict = True
    return span, Bits(path, "enum" if values else "int", mask, shift, values=values, signed=signed, strict=strict)


def _accepts(probe: Probe, path: str, data: bytes) -> bool:
    """Whether the decoder takes ``data``; refusing it for another field than ``path`` counts
    as taking it (the probe asks about this field only)."""
    try:
        _decode(probe.kind, data)
    except ProtocolError as exc:
        return exc.field != probe.prefix + path
    return True


def _most(probe: Probe, path: str, span: Span, mask: int, shift: int) -> int | None:
    """The largest value the decoder takes in these bits (a 2010 analog input's 1023), or None
    if it takes them all set."""
    def with_value(v: int) -> bytes:
        data = bytearray(probe.data)
        raw = (_item_int(probe.data, span) & ~mask) | (v << shift)
        data[span.offset:span.offset + span.length] = raw.to_bytes(span.length, "big")
        return bytes(data)

    top = mask >> shift
    if _accepts(probe, path, with_value(top)) or not _accepts(probe, path, with_value(0)):
        return None
    lo, hi = 0, top  # lo is taken, hi is not
    while hi - lo > 1:
        mid = (lo + hi) // 2
        lo, hi = (mid, hi) if _accepts(probe, path, with_value(mid)) else (lo, mid)
    return lo


def _probe_radix(probe: Probe, path: str, zero: bytes) -> tuple[Span, Bits] | None:
    """A number whose bytes each hold a digit of some weight (a 2010 dashboard's team 294 as 2
    and 94): each byte's weight is the value that makes it 1 alone, checked on other values,
    and the largest each byte may hold is what the decoder takes."""
    tries = {v: d for v in (1, 10, 100, 1000, 256, 65536) if (d := probe.variant(path, v)) is not None}
    region = sorted({i for d in tries.values() for i in _changed(zero, d)})
    if not region or region[-1] - region[0] > 3:
        return None
    lo, hi = region[0], region[-1] + 1
    weights = []
    for i in range(lo, hi):
        w = next((v for v, d in sorted(tries.items()) if _changed(zero, d) == [i] and d[i] - zero[i] == 1), None)
        if w is None:
            return None
        weights.append(w)
    for v in (7, 294, 9999, 12345):
        d = probe.variant(path, v)
        if d is not None and sum(d[lo + k] * w for k, w in enumerate(weights)) != v:
            return None
    mosts = []
    for i in range(lo, hi):
        a, b = 0, 256  # a is taken, b is not
        while b - a > 1:
            mid = (a + b) // 2
            data = bytearray(probe.data)
            data[i] = mid
            a, b = (mid, b) if _taken(probe, bytes(data)) else (a, mid)  # the base is good: this byte is refused
        mosts.append(a)
    span = Span(lo, hi - lo, probe.prefix + path, None, "")
    return span, Bits(path, "int", (1 << 8 * (hi - lo)) - 1, 0, weights=weights, mosts=mosts)


def _taken(probe: Probe, data: bytes) -> bool:
    try:
        _decode(probe.kind, data)
    except ProtocolError:
        return False
    return True


# -- whole kinds -----------------------------------------------------------------------------
_SKIP_TAGS = (UnknownTag, MalformedTag)


def _instance(cls: type, wrap: Callable[[Any], bytes] | None = None) -> Any:
    """A default instance of ``cls``, its required fields filled (first enum member, 0, ""),
    and each empty text or bytes field given two characters so the annotation gives it a span,
    where ``wrap`` (instance -> the packet's bytes) still encodes with them."""
    hints = _type_hints(cls)
    kwargs: dict[str, Any] = {}
    fills: dict[str, Any] = {}
    for f in dataclasses.fields(cls):
        what, enum_cls = _field_kind(hints[f.name])
        required = f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING
        empty = required or not f.default
        if what in ("str", "optstr") and empty:
            fills[f.name] = "ab"
        elif what == "bytes" and empty:
            fills[f.name] = b"\x01\x02"
        if required:
            kwargs[f.name] = (next(iter(enum_cls)) if enum_cls is not None and what == "enum" else
                              "" if what in ("str", "optstr") else b"" if what == "bytes" else 0)
    inst = cls(**kwargs)
    for name, value in fills.items():
        filled = dataclasses.replace(inst, **{name: value})
        try:
            (wrap or (lambda x: x.encode()))(filled)
        except (ProtocolError, TypeError, ValueError):
            continue
        inst = filled
    return inst


def _union_members(hint: Any) -> list[type]:
    args = typing.get_args(hint)
    if typing.get_origin(hint) is tuple:
        args = typing.get_args(args[0]) or (args[0],)
    return [a for a in args if isinstance(a, type)]


def _decode_outcome(kind: protocol_kinds.Kind, data: bytes, index: int) -> str:
    try:
        message = kind.decode(data)
    except ProtocolError:
        return "error"
    tag = message.tags[index]
    return "malformed" if type(tag) is MalformedTag else type(tag).__name__


def _bound(kind: protocol_kinds.Kind) -> int | None:
    """The decoder's size bound, read from the error a packet over any bound gets."""
    try:
        kind.decode(bytes(0xFFFF + 2))
    except ProtocolError as exc:
        if exc.field == "size" and exc.offset:
            return exc.offset
    return None


def build_kind(name: str) -> KindModel:
    kind = protocol_kinds.get(name)
    root_hint = typing.get_type_hints(kind.walk, vars(__import__(kind.walk.__module__, fromlist=["x"])))["return"]
    structs: dict[str, Struct] = {}
    _ELEMENTS.clear()
    _CRC_AT.clear()
    model = KindModel(name, PREFIXES[name], kind.title, kind.message, kind.tcp, None, {}, structs, _bound(kind))
    model.sizes = _sizes(kind, model.bound)
    if kind.tcp:
        for cls in _union_members(root_hint):
            if cls is KeepAlive or issubclass(cls, RawFrame):
                continue
            inst = _instance(cls)
            data = inst.encode()
            probe = Probe(kind, lambda x: x.encode(), inst, 2, "")
            st = probe_struct(probe, cls.__name__)
            ids = _frame_ids(probe, st, data[2])
            if st.id_field is not None and len(ids) > 1:  # a text's meaning that names the id is not static
                other = probe.variant(st.id_field, _enum_member(inst, st.id_field, ids[-1]))
                named = {x.field: x.meaning for x in kind.annotate(other)} if other else {}
                for it in st.items:
                    if isinstance(it, Text) and named.get(it.path) != it.meaning:
                        it.meaning = ""
            st.items = [i for i in st.items if not (isinstance(i, Item) and i.name == "id")]
            structs[cls.__name__] = st
            _forms(st, inst, lambda x: x.encode(), lambda x: Probe(kind, lambda y: y.encode(), x, 3, ""), structs)
            for i in ids:
                model.frames.setdefault(i, cls.__name__)
        structs.update(_ELEMENTS)
        return model
    base_cls: type = root_hint
    base = _instance(base_cls)
    hints = _type_hints(base_cls)
    tags_field = next((f.name for f in dataclasses.fields(base_cls) if f.name == "tags"), None)
    if tags_field:
        base = dataclasses.replace(base, tags=())
    _CRC_AT.extend(_crcs(kind, base.encode()))
    probe = Probe(kind, lambda x: x.encode(), base, 0, "")
    root = probe_struct(probe, base_cls.__name__)
    root.opaque = "; ".join(p for p in root.opaque.split("; ") if p and not p.startswith("tags:"))
    structs[base_cls.__name__] = root
    model.root = base_cls.__name__
    if tags_field:
        root.items.append(_probe_tags(kind, base, hints[tags_field], structs))
    structs.update(_ELEMENTS)
    return model


def _crcs(kind: protocol_kinds.Kind, data: bytes) -> list[int]:
    """Where the packet carries a CRC-32 the decoder checks (the 2010 packets' at 0x3fc): a
    4-byte span holding zlib's CRC-32 of the bytes before it and itself as zero, whose
    decoder refuses the packet, naming that span, when a byte it covers changes."""
    found = []
    for s in kind.annotate(data):
        if s.length != 4 or int.from_bytes(data[s.offset:s.offset + 4], "big") != \
                zlib.crc32(bytes(4), zlib.crc32(data[:s.offset])):
            continue
        try:
            kind.decode(bytes((data[0] ^ 0x01,)) + data[1:])
        except ProtocolError as exc:
            if exc.field == s.field:
                found.append(s.offset)
    return found


def _sizes(kind: protocol_kinds.Kind, bound: int | None) -> tuple[int, ...]:
    """The only sizes the decoder takes, when it names the size in refusing every other (the
    2010 packets: 1024 bytes, or 1024 and 1152); () when it takes many."""
    if bound is None or bound > 4096 or kind.tcp:  # a TCP frame's size field is another matter
        return ()
    taken = []
    for n in range(bound + 1):
        try:
            kind.decode(bytes(n))
        except ProtocolError as exc:
            if exc.field == "size":
                continue
        taken.append(n)
        if len(taken) > 4:
            return ()
    return tuple(taken)


def _frame_ids(probe: Probe, st: Struct, first: int) -> list[int]:
    """The frame ids a frame class is sent with: its own, or every value of the field that
    sets it (a version frame's device, 0x00-0x07; a DS ping's 0x1c or 0x1d)."""
    item = next((i for i in st.items if isinstance(i, Item) and i.name == "id"), None)
    if item is None or not item.bits:
        return [first]
    b = item.bits[0]
    st.id_field = b.path
    st.id_values = b.values
    ids = []
    for v in range(256):
        data = probe.variant(b.path, (b.values and v in b.values and _enum_member(probe.base, b.path, v)) or v)
        if data is not None and data[2] == v:
            ids.append(v)
    return ids


def _enum_member(obj: Any, path: str, v: int) -> Any:
    hint = _type_hints(type(obj))[path]
    _, enum_cls = _field_kind(hint)
    return enum_cls(v) if enum_cls is not None else v


def _probe_tags(kind: protocol_kinds.Kind, base: Any, hint: Any, structs: dict[str, Struct]) -> Tags:
    head = base.encode()
    by_id: dict[int, str] = {}
    for cls in _union_members(hint):
        if cls in _SKIP_TAGS or not dataclasses.fields(cls):
            if cls not in _SKIP_TAGS and dataclasses.is_dataclass(cls):  # an empty tag class: by its id
                try:
                    data = dataclasses.replace(base, tags=(cls(),)).encode()
                except ProtocolError:
                    continue
                if len(data) > len(head) + 1:
                    by_id[data[len(head) + 1]] = cls.__name__
                    structs[cls.__name__] = Struct(cls.__name__, [], fixed=len(data) - len(head) - 2)
            continue
        inst = _instance(cls, lambda t: dataclasses.replace(base, tags=(t,)).encode())
        data = dataclasses.replace(base, tags=(inst,)).encode()
        tag_id = data[len(head) + 1]
        probe = Probe(kind, lambda t: dataclasses.replace(base, tags=(t,)).encode(), inst, len(head) + 2, "tags[0].")
        st = probe_struct(probe, cls.__name__)
        if all((isinstance(i, Item) and i.width_from is None) or (isinstance(i, Raw) and i.length) for i in st.items):
            st.fixed = sum(i.width if isinstance(i, Item) else i.length for i in st.items if isinstance(i, (Item, Raw)))
        structs[cls.__name__] = st
        by_id[tag_id] = cls.__name__
        _forms(st, inst, lambda t: dataclasses.replace(base, tags=(t,)).encode(),
               lambda t: Probe(kind, lambda x: dataclasses.replace(base, tags=(x,)).encode(), t, len(head) + 2,
                               "tags[0]."), structs)
        last = st.items[-1] if st.items else None
        if isinstance(last, Text) and last.prefix == 0 and len(st.items) == 1:
            # the longest text the decoder still reads as this tag (game data: 8)
            for n in range(0, 254):
                payload = b"a" * n
                if _decode_outcome(kind, head + bytes((n + 1, tag_id)) + payload, 0) != cls.__name__:
                    last.most = n - 1
                    break
    empty = _decode_outcome(kind, head + b"\x00", 0)
    known = next(iter(by_id), 0)
    extra = (structs[by_id[known]].fixed or 0) + 1 if by_id else 0
    wrong = _decode_outcome(kind, head + bytes((1 + extra, known)) + bytes(extra), 0) if by_id else "UnknownTag"
    over = _decode_outcome(kind, head + bytes((9, 0x42, 0)), 0)
    return Tags("tags", by_id, empty, wrong, over)


# -- what `fieldbox decode --json` says, as Wireshark fields -------------------------------------
def struct_abbrev(model: KindModel, struct_name: str | None, path: str) -> str:
    """The Wireshark field of a dataclass field: ``frc.fms.station`` for the message itself,
    ``frc.fms.game_data_tag.text`` inside a tag, frame or list element."""
    path = _INDEX.sub("", path)
    if struct_name is None or struct_name == model.root:
        return f"frc.{model.prefix}.{path}"
    return f"frc.{model.prefix}.{snake(struct_name)}.{path}"


def _bits_of(model: KindModel, struct_name: str) -> dict[str, Bits]:
    st = model.structs.get(struct_name)
    found: dict[str, Bits] = {}
    if st is not None and st.id_field is not None:
        found[st.id_field] = Bits(st.id_field, "enum" if st.id_values else "int", 0xFF, 0, values=st.id_values)
    for it in st.items if st else ():
        if isinstance(it, Item):
            for b in it.bits:
                found[b.path] = b
    return found


def expected_fields(model: KindModel, fields: dict[str, Any]) -> list[tuple[str, str]]:
    """(Wireshark field, value as tshark prints it) for every value in ``fields``, the
    ``"fields"`` object of ``fieldbox decode --json``: what the plugin must show."""
    out: list[tuple[str, str]] = []
    opaque = {st.cls for st in model.structs.values() if st.opaque}

    def value_text(b: Bits | None, v: Any) -> str:
        if isinstance(v, bool):
            return "1" if v else "0"
        if isinstance(v, str) and b is not None and b.values:
            if b.or_bytes and v not in b.values.values():
                return str(int(v, 16))  # bytes no member names, kept as they came: the plugin's number
            return str(next(k for k, name in b.values.items() if name == v))
        if isinstance(v, float):
            return repr(v)
        return str(v)

    def walk(obj: dict[str, Any], struct_name: str | None, prefix: str) -> None:
        name = obj.get("type", "")
        out.append((f"frc.{model.prefix}.type", name))
        if name in opaque:  # the plugin shows its bytes only, and says so
            return
        st_name = name if name not in ("UnknownTag", "MalformedTag") and not name.startswith("Unknown") else name
        bits = _bits_of(model, st_name)
        for key, v in obj.items():
            if key in ("type", "reason"):
                continue
            path = f"{prefix}{key}"
            if isinstance(v, dict):  # a nested struct (the date block)
                walk_nested(v, st_name, path + ".", bits)
            elif isinstance(v, list):
                for e in v:
                    if isinstance(e, dict):
                        walk(e, e.get("type"), "")
                    else:
                        ints = next((i for i in model.structs[st_name].items if isinstance(i, Ints) and i.path == path),
                                    None) if st_name in model.structs else None
                        out.append((struct_abbrev(model, st_name if st_name != model.root else None, path),
                                    value_text(Bits(path, "enum", 0, 0, values=ints.values) if ints else None, e)))
            elif v is not None:
                out.append((struct_abbrev(model, st_name if st_name != model.root else None, path),
                            value_text(bits.get(path), v)))

    def walk_nested(obj: dict[str, Any], st_name: str, prefix: str, bits: dict[str, Bits]) -> None:
        for key, v in obj.items():
            if key == "type":
                continue
            path = f"{prefix}{key}"
            out.append((struct_abbrev(model, st_name if st_name != model.root else None, path),
                        value_text(bits.get(path), v)))

    walk(fields, None, "")
    return out


# -- the Lua plugin ----------------------------------------------------------------------------
def _lua_quote(text: str) -> str:
    """``text`` as a Lua string literal: ASCII as is, anything else as its UTF-8 bytes escaped."""
    out = []
    for ch in text:
        if ch in '"\\':
            out.append("\\" + ch)
        elif ch.isprintable() and ord(ch) < 128:
            out.append(ch)
        else:
            out.extend(f"\\{b:03d}" for b in ch.encode("utf-8"))
    return '"' + "".join(out) + '"'


_UINT = {1: "uint8", 2: "uint16", 3: "uint24", 4: "uint32", 8: "uint64"}
_INT = {1: "int8", 2: "int16", 3: "int24", 4: "int32", 8: "int64"}


class _Fields:
    """Every ProtoField the plugin declares, each abbreviation once."""

    def __init__(self) -> None:
        self.lines: list[str] = []
        self.index: dict[str, int] = {}

    def add(self, abbrev: str, ctor: str, label: str, *args: str, blurb: str = "") -> int:
        if abbrev in self.index:
            return self.index[abbrev]
        n = len(self.lines) + 1
        self.index[abbrev] = n
        # Each constructor takes the description at its own place: pad the arguments before it.
        width = {"string": 1, "bytes": 1, "double": 0, "float": 0}.get(ctor, 3)
        padded = list(args[:width]) + ["nil"] * (width - len(args[:width]))
        if blurb:
            padded.append(_lua_quote(blurb))
        rest = ", ".join(padded)
        self.lines.append(f"F[{n}] = ProtoField.{ctor}({_lua_quote(abbrev)}, {_lua_quote(label)}"
                          + (f", {rest}" if rest else "") + ")")
        return n


def _values_table(values: dict[int, str] | None) -> str:
    if not values:
        return "nil"
    return "{" + ", ".join(f"[{k}]={_lua_quote(v)}" for k, v in sorted(values.items())) + "}"


def _lua_item(model: KindModel, cls: str, it: Any, fields: _Fields) -> str:
    """One item of a struct as the engine's table."""
    if isinstance(it, Item):
        bits = []
        whole = len(it.bits) == 1 and (it.width_from or it.bits[0].mask == (1 << 8 * it.width) - 1)
        container = "nil"
        if not whole:
            abbrev = struct_abbrev(model, cls, it.name.replace(".", "_"))
            if any(abbrev == struct_abbrev(model, cls, b.path) for b in it.bits):
                abbrev += "_byte"
            container = str(fields.add(abbrev, _UINT[it.width], it.name, "base.HEX", "nil", "nil",
                                       blurb=it.meaning) if it.width in (1, 2, 3, 4) else
                            fields.add(abbrev, "bytes", it.name, "base.NONE", blurb=it.meaning))
        for b in it.bits:
            abbrev = struct_abbrev(model, cls, b.path)
            label = _INDEX.sub("", b.path)  # one field serves axes[0] ... axes[5]
            blurb = it.meaning if whole else ""
            if b.kind == "bool" and b.invert:  # no bit pattern: it would show the bit set when it is clear
                n = fields.add(abbrev, "bool", label, "base.NONE", blurb=blurb)
            elif b.kind == "bool":
                n = fields.add(abbrev, "bool", label, str(it.width * 8), "nil", hex(b.mask), blurb=blurb)
            elif b.kind == "float":
                n = fields.add(abbrev, "double", label, "nil", blurb=blurb)
            elif b.kind == "f32":
                n = fields.add(abbrev, "float", label, "nil", blurb=blurb)
            else:
                width = 4 if it.width_from or b.weights or (it.width > 4 and b.mask >> b.shift < 2**32) else it.width
                ctor = (_INT if b.signed else _UINT)[width if width in _UINT else 4]
                n = fields.add(abbrev, ctor, label, "base.DEC", _values_table(b.values), "nil", blurb=blurb)
            extra = ""
            if b.invert:
                extra += ", invert=true"
            if b.little:
                extra += ", little=true"
            if b.most is not None:
                extra += f", most={b.most}"
            if b.or_bytes:
                extra += ", nowarn=true"
            if b.weights:
                extra += ", wts={%s}, wmost={%s}" % (", ".join(map(str, b.weights)), ", ".join(map(str, b.mosts or [])))
            bits.append("{k=%s, f=F[%d], mask=%d, mlo=%d, mhi=%d, shift=%d, scale=%r, vals=%s, name=%s, "
                        "signed=%s, m=%s%s}" % (
                _lua_quote(b.kind), n, b.mask if b.mask < 2**53 else 0, b.mask & 0xFFFFFFFF, b.mask >> 32, b.shift,
                b.scale,
                _values_table(b.values) if b.strict else "nil", _lua_quote(b.path),
                "true" if b.signed else "false", _lua_quote(blurb) if blurb else "nil", extra))
        return "{k=\"item\", name=%s, w=%d, wfrom=%s, box=%s, bits={%s}}" % (
            _lua_quote(it.name), it.width, _lua_quote(it.width_from) if it.width_from else "nil",
            f"F[{container}]" if container != "nil" else "nil", ", ".join(bits))
    if isinstance(it, Ints):
        ctor = (_INT if it.signed else _UINT)[it.width]
        n = fields.add(struct_abbrev(model, cls, it.path), ctor, it.path, "base.DEC", _values_table(it.values), "nil",
                       blurb=it.meaning)
        cf = fields.add(struct_abbrev(model, cls, it.path) + "_count", _UINT[it.count], f"{it.path} count",
                        "base.DEC") if it.count else 0
        return "{k=\"ints\", name=%s, f=F[%d], cf=%s, count=%d, w=%d, m=%s}" % (
            _lua_quote(it.path), n, f"F[{cf}]" if cf else "nil", it.count, it.width,
            _lua_quote(it.meaning) if it.meaning else "nil")
    if isinstance(it, Text):
        n = fields.add(struct_abbrev(model, cls, it.path), "string", _INDEX.sub("", it.path), "base.UNICODE",
                       blurb=it.meaning)
        ln = fields.add(struct_abbrev(model, cls, it.path) + "_length", _UINT.get(it.prefix, "uint8"),
                        f"{it.path} length", "base.DEC") if it.prefix else 0
        return "{k=\"text\", name=%s, f=F[%d], lf=%s, prefix=%d, optional=%s, most=%s, m=%s, len=%d, strip=%s, " \
            "upto=%s}" % (
            _lua_quote(it.path), n, f"F[{ln}]" if ln else "nil", it.prefix,
            "true" if it.optional else "false", it.most if it.most is not None else "nil",
            _lua_quote(it.meaning) if it.meaning else "nil", it.length,
            _lua_quote(it.strip) if it.strip else "nil", it.upto if it.upto is not None else "nil")
    if isinstance(it, Raw):
        n = fields.add(struct_abbrev(model, cls, it.path), "bytes", _INDEX.sub("", it.path), "base.NONE",
                       blurb=it.meaning)
        ln = fields.add(struct_abbrev(model, cls, it.path) + "_length", _UINT.get(it.prefix, "uint8"),
                        f"{it.path} length", "base.DEC") if it.prefix else 0
        return "{k=\"raw\", name=%s, f=F[%d], m=%s, len=%d, prefix=%d, lf=%s, strip=%s, upto=%s}" % (
            _lua_quote(it.path), n, _lua_quote(it.meaning) if it.meaning else "nil", it.length, it.prefix,
            f"F[{ln}]" if ln else "nil", "true" if it.strip else "false",
            it.upto if it.upto is not None else "nil")
    if isinstance(it, Array):
        cf = fields.add(struct_abbrev(model, cls, it.path) + "_count", _UINT.get(it.count, "uint32"),
                        f"{it.path} count", "base.DEC") if it.count else 0
        sf = fields.add(struct_abbrev(model, it.element, "size"), "uint8", "size", "base.DEC",
                        blurb="bytes that follow in this record") if it.sized else 0
        return "{k=\"array\", name=%s, element=%s, count=%d, cf=%s, exactly=%d, sf=%s, upto=%s}" % (
            _lua_quote(it.path), _lua_quote(it.element), it.count, f"F[{cf}]" if cf else "nil", it.exactly,
            f"F[{sf}]" if sf else "nil", it.upto if it.upto is not None else "nil")
    if isinstance(it, Tags):
        ids = ", ".join(f"[{k}]={_lua_quote(v)}" for k, v in sorted(it.by_id.items()))
        return "{k=\"tags\", name=\"tags\", by_id={%s}, empty=%s, wrong=%s, over=%s, max=%d}" % (
            ids, _lua_quote(it.empty), _lua_quote(it.wrong), _lua_quote(it.over), it.max_tags)
    if isinstance(it, Crc):
        n = fields.add(struct_abbrev(model, cls, it.name), "uint32", it.name, "base.HEX",
                       blurb="CRC-32 (zlib) of the bytes before it and itself as zero")
        return "{k=\"crc\", name=%s, f=F[%d]}" % (_lua_quote(it.name), n)
    if isinstance(it, Magic):
        n = fields.add(struct_abbrev(model, cls, it.name.replace(".", "_")), "bytes", it.name, "base.NONE",
                       blurb=it.meaning)
        return "{k=\"magic\", name=%s, f=F[%d], value=%s}" % (
            _lua_quote(it.name), n, '"' + "".join(f"\\{b:03d}" for b in it.value) + '"')
    if isinstance(it, Group):
        return "{k=\"group\", name=%s, items={%s}}" % (
            _lua_quote(it.path), ", ".join(_lua_item(model, cls, i, fields) for i in it.items))
    raise TypeError(f"no Lua for {it!r}")


def _lua_struct(model: KindModel, st: Struct, fields: _Fields) -> str:
    cls = st.cls or st.name
    parts = [_lua_item(model, cls, it, fields) for it in st.items]
    consts = []
    for c in st.consts:
        if c.kind == "none":
            continue
        abbrev = struct_abbrev(model, cls, c.path)
        n = fields.add(abbrev, "bool", c.path, "base.NONE") if c.kind == "bool" else \
            fields.add(abbrev, "uint32", c.path, "base.DEC")
        consts.append("{f=F[%d], v=%s}" % (n, ("true" if c.value else "false") if c.kind == "bool" else int(c.value)))
    id_field = "nil"
    if st.id_field is not None:
        n = fields.add(struct_abbrev(model, cls, st.id_field), "uint8", st.id_field, "base.DEC",
                       _values_table(st.id_values))
        id_field = f"F[{n}]"
    whole = "nil"
    if st.opaque:
        whole = "F[%d]" % fields.add(struct_abbrev(model, cls, "bytes"), "bytes", f"{cls} bytes", "base.NONE",
                                     blurb="shown as bytes only: " + st.opaque)
    return "{name=%s, cls=%s, fixed=%s, opaque=%s, whole=%s, id_field=%s, forms={%s}, consts={%s}, items={\n    %s}}" % (
        _lua_quote(st.name), _lua_quote(cls), st.fixed if st.fixed is not None else "nil", _lua_quote(st.opaque),
        whole, id_field, ", ".join(_lua_quote(f) for f in st.forms), ", ".join(consts), ",\n    ".join(parts))


_ENGINE = r'''
-- The engine: one walk for every struct of every kind, driven by the tables above.
local ef_error = ProtoExpert.new("frc.error", "Does not decode", expert.group.MALFORMED, expert.severity.ERROR)
local ef_malformed = ProtoExpert.new("frc.malformed", "Malformed tag", expert.group.MALFORMED, expert.severity.WARN)
local ef_warning = ProtoExpert.new("frc.warning", "Out of the range real peers send", expert.group.PROTOCOL,
                                   expert.severity.WARN)
local ef_opaque = ProtoExpert.new("frc.not_dissected", "Shown as bytes only", expert.group.UNDECODED,
                                  expert.severity.NOTE)
frc.experts = {ef_error, ef_malformed, ef_warning, ef_opaque}

local FAIL = {}
local function fail(msg, off)
  error({[FAIL] = true, msg = msg, off = off}, 0)
end

local function need(n, left, what, off)
  if n > left then fail(what .. ": needs " .. n .. " byte" .. (n == 1 and "" or "s") .. ", " .. left .. " left", off) end
end

-- Bitwise and without Lua 5.3's operators or a bit library (Wireshark has shipped Lua 5.1,
-- 5.2 and 5.4): the items it masks are at most 32 bits.
local function band(a, b)
  local r, v = 0, 1
  while a > 0 and b > 0 do
    if a % 2 == 1 and b % 2 == 1 then r = r + v end
    a, b, v = math.floor(a / 2), math.floor(b / 2), v * 2
  end
  return r
end

local function add(tree, ...)
  if tree then return tree:add(...) end
end

-- Text as fieldbox reads it: UTF-8, each invalid run one U+FFFD (Python's "replace": the
-- maximal subpart of a sequence), a NUL shown as \0 (a Wireshark string would end there).
local FFFD = "\239\191\189"
local function text_of(raw)
  local out, i, n = {}, 1, #raw
  while i <= n do
    local b = raw:byte(i)
    local need, lo, hi = 0, 0x80, 0xBF
    if b == 0 then out[#out + 1] = "\\0"; i = i + 1
    elseif b < 0x80 then out[#out + 1] = string.char(b); i = i + 1
    else
      if b >= 0xC2 and b <= 0xDF then need = 1
      elseif b == 0xE0 then need, lo = 2, 0xA0
      elseif b == 0xED then need, hi = 2, 0x9F
      elseif b >= 0xE1 and b <= 0xEF then need = 2
      elseif b == 0xF0 then need, lo = 3, 0x90
      elseif b == 0xF4 then need, hi = 3, 0x8F
      elseif b >= 0xF1 and b <= 0xF3 then need = 3 end
      if need == 0 then out[#out + 1] = FFFD; i = i + 1
      else
        local j, ok = i + 1, true
        for k = 1, need do
          local c = raw:byte(j)
          local l, h = 0x80, 0xBF
          if k == 1 then l, h = lo, hi end
          if c == nil or c < l or c > h then ok = false; break end
          j = j + 1
        end
        if ok then out[#out + 1] = raw:sub(i, j - 1) else out[#out + 1] = FFFD end
        i = j
      end
    end
  end
  return table.concat(out)
end

-- The meaning fieldbox decode prints beside a field, where it does not depend on the value.
local function said(item, m)
  if item and m then item:append_text("  \226\128\148 " .. m) end
  return item
end

local function warn_range(tree, item, path, value, pinfo)
  -- as decode's range_warnings: a field's last name, an element only of a list of values
  local last = path:match("([%w_%[%]]+)$") or path
  local name = last:gsub("%[%d+%]$", "")
  local rule = (name == last or LISTS[name]) and RANGES[name] or nil
  if rule and tree and type(value) == "number" and (value < rule[1] or value > rule[2]) then
    item:add_proto_expert_info(ef_warning, path .. " " .. value .. " is out of range (" .. rule[3] .. ")")
  end
end

local walk_struct

-- zlib's CRC-32 (the 2010 packets'), with Wireshark's bit32 or bit library where it has one.
local B = bit32 or bit
local function xor(a, b)
  if B then
    local v = B.bxor(a, b)
    if v < 0 then v = v + 4294967296 end  -- LuaBitOp's results are signed
    return v
  end
  local r, v = 0, 1
  while a > 0 or b > 0 do
    if a % 2 ~= b % 2 then r = r + v end
    a, b, v = math.floor(a / 2), math.floor(b / 2), v * 2
  end
  return r
end
local CRC_TABLE = {}
for i = 0, 255 do
  local c = i
  for _ = 1, 8 do
    if c % 2 == 1 then c = xor(math.floor(c / 2), 0xEDB88320) else c = math.floor(c / 2) end
  end
  CRC_TABLE[i] = c
end
local function crc32(s)
  local c = 0xFFFFFFFF
  for i = 1, #s do
    c = xor(CRC_TABLE[xor(c % 256, s:byte(i))], math.floor(c / 256))
  end
  return xor(c, 0xFFFFFFFF)
end

local function hex_of(raw)
  return (raw:gsub(".", function(c) return string.format("%02x ", c:byte()) end)):sub(1, -2)
end

-- Items in order from ``off``; ``base`` is where their struct starts (an ``upto`` is counted
-- from there: a 2010 packet's padding runs up to a fixed offset).
local function walk_list(K, items, tvb, off, stop, tree, pinfo, base)
  local ctx = {}
  local malformed = nil  -- a sized record running past its list's end: the next item keeps it
  -- how far a prefixed length may reach: to the next item that ends at a fixed offset
  local limits, limit = {}, stop
  for i = #items, 1, -1 do
    limits[i] = limit
    if items[i].upto then limit = base + items[i].upto end
  end
  for index, it in ipairs(items) do
    if it.k == "item" then
      local w = it.w
      if it.wfrom then w = math.ceil(ctx[it.wfrom] / 8) end
      need(w, stop - off, it.name, off)
      if w > 4 and it.wfrom then fail(it.name .. ": " .. w .. " bytes is more than this plugin reads", off) end
      local range = tvb(off, w)
      local parent = tree
      if it.box then parent = add(tree, it.box, range) end
      local raw = w == 0 and 0 or (w <= 4 and range:uint() or nil)
      for _, b in ipairs(it.bits) do
        if w == 0 then
          add(parent, b.f, range, 0)
          ctx[b.name] = 0
        elseif b.k == "bool" and b.invert then
          -- true when the bit is clear (the 2010 control byte's 0x40 is "not e-stopped")
          local clear = band(raw, b.mask) == 0
          local item = said(add(parent, b.f, range, clear and 1 or 0), b.m)
          if item then item:append_text(string.format(" (bit 0x%02x %s)", b.mask, clear and "clear" or "set")) end
        elseif b.k == "bool" then
          said(add(parent, b.f, range), b.m)
        elseif b.k == "f32" then
          said(add(parent, b.f, range), b.m)
        elseif w > 4 and b.mhi == 2 ^ (8 * (w - 4)) - 1 and b.mlo == 0xFFFFFFFF then
          said(add(parent, b.f, range), b.m)  -- a whole u64
        elseif w > 4 then
          -- some bits of a wide item (a PDP's 10-bit currents in a 64-bit group)
          local v = range:uint64():band(UInt64.new(b.mlo, b.mhi)):rshift(b.shift):tonumber()
          local item = said(add(parent, b.f, range, v), b.m)
          warn_range(parent, item, b.name, v, pinfo)
        else
          local v
          if b.wts then  -- each byte a digit of its weight (a 2010 dashboard's team: 2, 94 is 294)
            v = 0
            for i, weight in ipairs(b.wts) do
              local d = tvb(off + i - 1, 1):uint()
              if d > b.wmost[i] then
                fail(b.name .. ": byte " .. i .. " holds " .. d .. ", at most " .. b.wmost[i], off + i - 1)
              end
              v = v + d * weight
            end
          elseif b.little then
            v = range:le_uint()
          else
            v = math.floor(band(raw, b.mask) / 2 ^ b.shift)
          end
          if b.signed and v >= 2 ^ (8 * w - 1) then v = v - 2 ^ (8 * w) end
          if b.most and v > b.most then
            fail(b.name .. ": " .. v .. " is more than " .. b.most .. ", the most it may be", off)
          end
          if b.k == "float" then
            v = raw * b.scale
            local item = said(add(parent, b.f, range, v), b.m)
            warn_range(parent, item, b.name, v, pinfo)
          else
            if b.vals and b.vals[v] == nil then fail(b.name .. ": " .. v .. " is not a value it may take", off) end
            local item = said(add(parent, b.f, range, v), b.m)
            if not b.nowarn then warn_range(parent, item, b.name, v, pinfo) end
            ctx[b.name] = v
          end
        end
      end
      off = off + w
    elseif it.k == "ints" then
      local n
      if it.count > 0 then
        need(it.count, stop - off, it.name .. " count", off)
        n = tvb(off, it.count):uint()
        add(tree, it.cf, tvb(off, it.count))
        off = off + it.count
        need(n * it.w, stop - off, it.name, off)
      else
        if (stop - off) % it.w ~= 0 then fail(it.name .. ": not a whole number of " .. it.w .. "-byte values", off) end
        n = (stop - off) / it.w
      end
      for i = 0, n - 1 do
        local item = said(add(tree, it.f, tvb(off, it.w)), it.m)
        warn_range(tree, item, it.name, tvb(off, it.w):int(), pinfo)
        off = off + it.w
      end
    elseif it.k == "text" then
      local n
      if it.prefix > 0 then
        need(it.prefix, stop - off, it.name .. ".length", off)
        n = tvb(off, it.prefix):uint()
        if it.optional and off + it.prefix + n == stop then
          -- one string filling what is left: the next text alone, this one absent
        else
          add(tree, it.lf, tvb(off, it.prefix))
          off = off + it.prefix
          need(n, limits[index] - off, it.name, off)
          said(add(tree, it.f, tvb(off, n), text_of(tvb:raw(off, n))), it.m)
          off = off + n
        end
      else
        if it.len > 0 then n = it.len elseif it.upto then n = base + it.upto - off else n = stop - off end
        if n < 0 then fail(it.name .. ": what comes before it runs past where it ends", off) end
        need(n, stop - off, it.name, off)
        local raw = tvb:raw(off, n)
        if it.strip then  -- the padding the decoder strips (an LCD line's spaces)
          while #raw > 0 and raw:sub(-1) == it.strip do raw = raw:sub(1, -2) end
        end
        said(add(tree, it.f, tvb(off, n), text_of(raw)), it.m)
        off = off + n
      end
    elseif it.k == "raw" then
      local n
      if it.prefix > 0 then
        need(it.prefix, stop - off, it.name .. ".length", off)
        n = tvb(off, it.prefix):uint()
        add(tree, it.lf, tvb(off, it.prefix))
        off = off + it.prefix
        need(n, limits[index] - off, it.name, off)
      elseif it.len > 0 then n = it.len
      elseif it.upto then n = base + it.upto - off
      else n = stop - off end
      if n < 0 then fail(it.name .. ": what comes before it runs past where it ends", off) end
      need(n, stop - off, it.name, off)
      local shown = n
      if it.strip and n > 0 then  -- the decoder keeps it without its trailing zeros
        local raw = tvb:raw(off, n)
        while shown > 0 and raw:byte(shown) == 0 do shown = shown - 1 end
      end
      local item = said(add(tree, it.f, tvb(off, shown)), it.m)
      if item and shown < n then
        if shown == 0 then item:set_text(it.name .. ": none") end
        item:append_text(" (then " .. (n - shown) .. " zero bytes up to byte 0x" ..
                         string.format("%03x", off + n - base - 1) .. ", which fieldbox does not keep)")
      end
      if malformed then
        if item then item:add_proto_expert_info(ef_malformed, malformed) end
        malformed = nil
      end
      off = off + n
    elseif it.k == "crc" then
      need(4, stop - off, it.name, off)
      local found = tvb(off, 4):uint()
      local want = crc32(tvb:raw(base, off - base) .. "\0\0\0\0")
      if found ~= want then
        fail(it.name .. string.format(": expected 0x%08x, found 0x%08x (CRC-32 of bytes 0x000-0x%03x with this " ..
                                      "field zeroed)", want, found, off - base + 3), off)
      end
      said(add(tree, it.f, tvb(off, 4)),
           string.format("CRC-32 of bytes 0x000-0x%03x with this field zeroed: OK", off - base + 3))
      off = off + 4
    elseif it.k == "magic" then
      local n = #it.value
      need(n, stop - off, it.name, off)
      local raw = tvb:raw(off, n)
      if raw ~= it.value then fail(it.name .. ": " .. hex_of(raw) .. " is not the marker " .. hex_of(it.value), off) end
      said(add(tree, it.f, tvb(off, n)), it.m)
      off = off + n
    elseif it.k == "group" then
      if off < stop then  -- present only when bytes are left
        local sub = add(tree, frc, tvb(off, stop - off), it.name)
        off = walk_list(K, it.items, tvb, off, stop, sub, pinfo, base)
      end
    elseif it.k == "array" and it.exactly > 0 then
      local E = K.structs[it.element]
      for i = 0, it.exactly - 1 do
        need(E.fixed, stop - off, it.name, off)
        local sub = add(tree, frc, tvb(off, E.fixed), it.element .. " " .. i)
        off = walk_struct(K, E, tvb, off, off + E.fixed, sub, pinfo)
      end
    elseif it.k == "array" and it.sf then
      -- records of [u8 size][size bytes] up to a fixed offset; a size of 0 ends them, and a size
      -- running past the end makes that record and the rest raw in the next item (malformed)
      local E = K.structs[it.element]
      local last = base + it.upto
      local i = 0
      while off < last do
        local size = tvb(off, 1):uint()
        if size == 0 then break end
        if off + 1 + size > last then
          malformed = it.name .. "[" .. i .. "]: size " .. size .. " runs past byte 0x" ..
                      string.format("%03x", last - 1) ..
                      " (" .. (last - off - 1) .. " byte(s) left): this record and the rest are kept raw, " ..
                      "and a robot drops them"
          break
        end
        local sub = add(tree, frc, tvb(off, size + 1), it.element .. " " .. i)
        add(sub, it.sf, tvb(off, 1))
        walk_struct(K, E, tvb, off + 1, off + 1 + size, sub, pinfo)
        off = off + 1 + size
        i = i + 1
      end
    elseif it.k == "array" then
      local E = K.structs[it.element]
      local count = nil
      if it.count > 0 then
        need(it.count, stop - off, it.name .. " count", off)
        count = tvb(off, it.count):uint()
        add(tree, it.cf, tvb(off, it.count))
        off = off + it.count
      elseif E.fixed and (stop - off) % E.fixed ~= 0 then
        fail(it.name .. ": " .. (stop - off) .. " byte(s) is not a whole number of " .. E.fixed .. "-byte records", off)
      end
      local i = 0
      while (count and i < count) or (not count and off < stop) do
        local sub = add(tree, frc, tvb(off, stop - off), it.element .. " " .. i)
        off = walk_struct(K, E, tvb, off, stop, sub, pinfo)
        i = i + 1
      end
    elseif it.k == "tags" then
      off = walk_tags(K, it, tvb, off, stop, tree, pinfo)
    end
  end
  return off
end

local function walk_items(K, S, tvb, off, stop, tree, pinfo)
  return walk_list(K, S.items, tvb, off, stop, tree, pinfo, off)
end

walk_struct = function(K, S, tvb, off, stop, tree, pinfo)
  add(tree, K.type_field, tvb(off, 0), S.cls)
  for _, c in ipairs(S.consts) do add(tree, c.f, tvb(off, 0), c.v) end
  if S.whole then
    -- a layout the probe could not read whole: its bytes, and why
    local n = S.fixed or (stop - off)
    need(n, stop - off, S.cls, off)
    local item = add(tree, S.whole, tvb(off, n))
    if item then item:add_proto_expert_info(ef_opaque, S.cls .. ": " .. S.opaque) end
    return off + n
  end
  return walk_items(K, S, tvb, off, stop, tree, pinfo)
end

-- The form of a class these bytes are (a bare joystick slot, an idle output, the seed's
-- 4-byte disk tag): forms of a fixed size by their size first, then any that walks them whole.
local function pick_form(K, S, tvb, off, stop, pinfo)
  local all = {S}
  for _, name in ipairs(S.forms) do all[#all + 1] = K.structs[name] end
  if #all == 1 then return S end
  for _, F in ipairs(all) do
    if F.fixed and F.fixed == stop - off then return F end
  end
  for _, F in ipairs(all) do
    if not F.fixed then
      local ok, to = pcall(walk_struct, K, F, tvb, off, stop, nil, pinfo)
      if ok and to == stop then return F end
    end
  end
  return S
end

local function tag_raw(K, tree, tvb, off, stop, id, typ)
  local f = typ == "malformed" and K.malformed or K.unknown
  add(tree, K.type_field, tvb(off, 0), typ == "malformed" and "MalformedTag" or "UnknownTag")
  if id ~= nil then add(tree, f.tag_id, tvb(off, 0), id) end
  if typ == "malformed" then
    add(tree, f.raw, tvb(off, stop - off))
  else
    add(tree, f.data, tvb(off, stop - off))
  end
end

function walk_tags(K, T, tvb, off, stop, tree, pinfo)
  local count = 0
  while off < stop do
    if count == T.max then fail("tags[" .. T.max .. "]: more than " .. T.max .. " tags", off) end
    local size = tvb(off, 1):uint()
    local where = "tags[" .. count .. "]"
    if size == 0 then
      local sub = add(tree, frc, tvb(off, 1), where .. ": size 0")
      if T.empty == "error" then fail(where .. ".size: a tag size of 0 leaves no room for the id", off) end
      add(sub, K.tag_size, tvb(off, 1))
      if T.empty == "malformed" then
        tag_raw(K, sub, tvb, off, off + 1, nil, "malformed")
        if sub then sub:add_proto_expert_info(ef_malformed, where .. ": a size of 0 leaves no room for an id") end
      else
        add(sub, K.type_field, tvb(off, 0), T.empty)
      end
      off = off + 1
    elseif off + 1 + size > stop then
      if T.over == "error" then fail(where .. ": needs " .. size .. " bytes, " .. (stop - off - 1) .. " left", off + 1) end
      local sub = add(tree, frc, tvb(off, stop - off), where .. ": MALFORMED")
      tag_raw(K, sub, tvb, off, stop, off + 1 < stop and tvb(off + 1, 1):uint() or nil, "malformed")
      if sub then sub:add_proto_expert_info(ef_malformed, where .. ".size: " .. size .. " byte(s) said, " ..
                                            (stop - off - 1) .. " left in the packet") end
      off = stop
    else
      local id = tvb(off + 1, 1):uint()
      local name = T.by_id[id]
      local body, tstop = off + 2, off + 1 + size
      local S = name and K.structs[name]
      local verdict = S and "known" or "UnknownTag"
      if S then
        S = pick_form(K, S, tvb, body, tstop, pinfo)
        local last = S.items[#S.items]
        if S.fixed and tstop - body ~= S.fixed then
          verdict = T.wrong
        elseif last and last.k == "text" and last.most and tstop - body > last.most then
          verdict = "UnknownTag"
        else
          local ok, err = pcall(walk_struct, K, S, tvb, body, tstop, nil, pinfo)
          if not ok then
            if type(err) ~= "table" or not err[FAIL] then error(err, 0) end
            verdict = T.wrong == "error" and "error" or "malformed"
            if verdict == "error" then fail(where .. "." .. err.msg, err.off) end
          else
            if err ~= tstop then verdict = T.wrong end
          end
        end
      end
      if verdict == "error" then fail(where .. ": tag 0x" .. string.format("%02x", id) .. " is not laid out as documented", body) end
      local sub = add(tree, frc, tvb(off, size + 1), where .. ": " .. (verdict == "known" and name or verdict))
      if verdict == "malformed" then
        tag_raw(K, sub, tvb, off, tstop, id, "malformed")
        if sub then sub:add_proto_expert_info(ef_malformed, where .. ": tag 0x" .. string.format("%02x", id) ..
                                              " is not laid out as documented; a robot drops its data") end
      else
        add(sub, K.tag_size, tvb(off, 1))
        add(sub, K.tag_id, tvb(off + 1, 1))
        if verdict == "known" then
          walk_struct(K, S, tvb, body, tstop, sub, pinfo)
        else
          tag_raw(K, sub, tvb, body, tstop, id, "UnknownTag")
        end
      end
      off = tstop
    end
    count = count + 1
  end
  return off
end

-- One packet (UDP) or one whole frame (TCP) of kind K; errors become expert info.
local function dissect_kind(K, tvb, pinfo, tree)
  local len = tvb:len()
  local top = tree:add(frc, tvb(), "FRC " .. K.title)
  pinfo.cols.protocol = "FRC"
  local ok, err = pcall(function()
    if K.bound and len > K.bound then
      fail("size: " .. len .. " bytes is over the " .. K.bound .. "-byte bound: not decoded", K.bound)
    end
    if K.sizes and not K.sizes[len] then
      fail("size: " .. len .. " bytes; this packet is exactly " .. K.sizes_text .. " bytes", 0)
    end
    if K.tcp then
      need(2, len, "size", 0)
      local size = tvb(0, 2):uint()
      add(top, K.frame_size, tvb(0, 2))
      if size + 2 ~= len then fail("size: size field says " .. size .. " byte(s) follow, " .. (len - 2) .. " do", 0) end
      if size == 0 then
        add(top, K.type_field, tvb(0, 0), "KeepAlive")
        pinfo.cols.info:append(" KeepAlive")
        return
      end
      local id = tvb(2, 1):uint()
      add(top, K.frame_id, tvb(2, 1))
      local name = K.frames[id]
      if not name then
        add(top, K.type_field, tvb(2, 0), "UnknownFrame")
        add(top, K.unknown_frame.tag_id, tvb(2, 1), id)
        add(top, K.unknown_frame.data, tvb(3, len - 3))
        pinfo.cols.info:append(" UnknownFrame 0x" .. string.format("%02x", id))
        return
      end
      local S = pick_form(K, K.structs[name], tvb, 3, len, pinfo)
      pinfo.cols.info:append(" " .. name)
      -- walk once without a tree: a frame that does not decode shows no half-read fields
      local stop = walk_struct(K, S, tvb, 3, len, nil, pinfo)
      if stop ~= len then fail("end: " .. (len - stop) .. " unexpected trailing byte(s)", stop) end
      local sub = top:add(frc, tvb(2, len - 2), name)
      if S.id_field then add(sub, S.id_field, tvb(2, 1)) end
      walk_struct(K, S, tvb, 3, len, sub, pinfo)
    else
      local S = K.structs[K.root]
      pinfo.cols.info:append(" " .. K.root)
      walk_struct(K, S, tvb, 0, len, nil, pinfo)
      walk_struct(K, S, tvb, 0, len, top, pinfo)
    end
  end)
  if not ok then
    if type(err) ~= "table" or not err[FAIL] then
      top:add_proto_expert_info(ef_error, "dissector error: " .. tostring(err))
    else
      top:add_proto_expert_info(ef_error, K.message .. "." .. err.msg .. (err.off and (" at byte " .. err.off) or ""))
      pinfo.cols.info:append(" [does not decode]")
    end
  end
  return len
end
'''


def _lua_kind(model: KindModel, fields: _Fields) -> str:
    p = f"frc.{model.prefix}"
    common = {
        "type_field": fields.add(f"{p}.type", "string", "type", "base.ASCII",
                                 blurb="the message, tag or frame class fieldbox decodes it as"),
        "tag_size": fields.add(f"{p}.tag.size", "uint8", "tag size", "base.DEC", blurb="tag size, counting the id byte"),
        "tag_id": fields.add(f"{p}.tag.id", "uint8", "tag id", "base.HEX", _values_table(next(
            (it.by_id for st in model.structs.values() for it in st.items if isinstance(it, Tags)), None))),
        "frame_size": fields.add(f"{p}.size", "uint16", "frame size", "base.DEC",
                                 blurb="frame size, counting the id byte"),
        "frame_id": fields.add(f"{p}.id", "uint8", "frame id", "base.HEX",
                               _values_table(model.frames) if model.frames else "nil"),
    }
    unknown = {k: fields.add(f"{p}.unknown_tag.{k}", c, k, *a) for k, c, a in
               (("tag_id", "uint8", ("base.DEC",)), ("data", "bytes", ("base.NONE",)))}
    malformed = {k: fields.add(f"{p}.malformed_tag.{k}", c, k, *a) for k, c, a in
                 (("tag_id", "uint8", ("base.DEC",)), ("raw", "bytes", ("base.NONE",)))}
    frame = {k: fields.add(f"{p}.unknown_frame.{k}", c, k, *a) for k, c, a in
             (("tag_id", "uint8", ("base.DEC",)), ("data", "bytes", ("base.NONE",)))}
    structs = ",\n  ".join(f"[{_lua_quote(n)}] = {_lua_struct(model, st, fields)}"
                           for n, st in model.structs.items())
    frames = ", ".join(f"[{k}]={_lua_quote(v)}" for k, v in sorted(model.frames.items()))
    sizes = "{" + ", ".join(f"[{n}]=true" for n in model.sizes) + "}" if model.sizes else "nil"

    def tab(d: dict[str, int]) -> str:
        return "{" + ", ".join(f"{k}=F[{v}]" for k, v in d.items()) + "}"

    return (f"KINDS[{_lua_quote(model.kind)}] = {{\n  title={_lua_quote(model.title)}, "
            f"message={_lua_quote(model.message)}, tcp={'true' if model.tcp else 'false'}, "
            f"root={_lua_quote(model.root) if model.root else 'nil'}, bound={model.bound or 'nil'}, "
            f"sizes={sizes}, sizes_text={_lua_quote(' or '.join(map(str, model.sizes)))},\n  "
            + ", ".join(f"{k}=F[{v}]" for k, v in common.items())
            + f",\n  unknown={tab(unknown)}, malformed={tab(malformed)}, unknown_frame={tab(frame)},\n"
            f"  frames={{{frames}}},\n  structs={{\n  {structs}}}}}\n")


def generate(kind_names: list[str] | None = None) -> str:
    """The whole Lua plugin: every kind ``fieldbox decode`` knows (or those named)."""
    from . import capread
    from .decode_cmd import LISTS, RANGES

    names = kind_names or [k for k in protocol_kinds.kinds() if k in PREFIXES]
    fields = _Fields()
    models = [build_kind(n) for n in names]
    kinds_lua = [_lua_kind(m, fields) for m in models]
    opaque = "".join(f"\n--   {m.kind}: {st.cls}: {st.opaque}" for m in models for st in m.structs.values()
                     if st.opaque and st.name == st.cls)
    ranges = ", ".join(f"{k}={{{lo!r}, {hi!r}, {_lua_quote(text)}}}" for k, (lo, hi, text) in RANGES.items())
    lists = ", ".join(f"{name}=true" for name in sorted(LISTS))
    udp = ", ".join(f"[{port}]={_lua_quote(kind)}" for port, kind in sorted(capread.UDP_PORTS.items()) if kind in names)
    tcp = ", ".join(f"[{port}]={{{_lua_quote(c)}, {_lua_quote(s)}}}" for port, (c, s) in sorted(capread.TCP_PORTS.items()))
    legacy_control = " or ".join(str(n) for n in capread._LEGACY_CONTROL_SIZES)
    legacy_status = " or ".join(str(n) for n in capread._LEGACY_STATUS_SIZES)
    head = f"""-- FRC Driver Station, roboRIO and FMS protocols: a Wireshark dissector.
--
-- Generated by `fieldbox dissector` from fieldbox's protocol/ package: the layouts, field
-- names, value names and meanings are read from the same code `fieldbox decode` uses. Do not
-- edit by hand: run `fieldbox dissector -o frc.lua` again.
--
-- Install: copy this file into Wireshark's personal Lua plugins folder (Help > About
-- Wireshark > Folders > Personal Lua Plugins), or run `tshark -X lua_script:frc.lua`.
--
-- Kinds, by port (as `fieldbox decode --pcap` finds them): a UDP datagram by its destination
-- port; a TCP stream by which end is the server port (the client is the DS).
-- The 2010 (cRIO) protocol shares UDP 1110 and 1150 with today's. Its packets are fixed sizes
-- ({legacy_control} bytes DS -> robot, {legacy_status} robot -> DS) while today's are a few dozen
-- bytes, so the length alone tells them apart, exactly as `fieldbox decode --pcap` does
-- (fieldbox/capread.py, udp_kind): a datagram to 1110 of a 2010 control size is a 2010 control
-- packet, one to 1150 of a 2010 status size a 2010 status packet, and any other length is
-- today's protocol (a cut 2010 packet is decoded, and refused, as today's). No header byte is
-- looked at: the 2010 packets start with a packet index or the control byte, which can be
-- anything. The 2010 DS's dashboard packets (UDP 1165) and the cRIO's NetConsole text (UDP
-- 6666) have ports of their own. The 2010 packets end in a CRC-32, checked as fieldbox's
-- decoder checks it: a bad CRC is an error, and no field of the packet is shown.
--
-- Shown as bytes with a note, not field by field (the layouts this generator cannot walk
-- front to back yet):{opaque or " none"}

local frc = Proto("frc", "FRC Driver Station / roboRIO / FMS (fieldbox)")
local F = {{}}
local KINDS = {{}}
local RANGES = {{{ranges}}}
local LISTS = {{{lists}}}
local UDP_PORTS = {{{udp}}}
local TCP_PORTS = {{{tcp}}}
local LEGACY_CONTROL = {{{", ".join(f"[{n}]=true" for n in capread._LEGACY_CONTROL_SIZES)}}}
local LEGACY_STATUS = {{{", ".join(f"[{n}]=true" for n in capread._LEGACY_STATUS_SIZES)}}}
local walk_tags
"""
    fields_lua = "\n".join(fields.lines)
    tail = r'''
local pf = {}
for _, f in pairs(F) do pf[#pf + 1] = f end
frc.fields = pf

-- As fieldbox's capread.udp_kind: the destination port names the kind; on 1110 and 1150 a
-- packet of the 2010 protocol's fixed sizes is the 2010 kind.
local function udp_kind(dport, len)
  local kind = UDP_PORTS[dport]
  if kind == "ds-to-rio" and dport == 1110 and LEGACY_CONTROL[len] then return "legacy-ds-to-robot" end
  if kind == "rio-to-ds" and LEGACY_STATUS[len] then return "legacy-robot-to-ds" end
  return kind
end

local function udp_dissector(tvb, pinfo, tree)
  local name = udp_kind(pinfo.dst_port, tvb:len())
  local K = name and KINDS[name]
  if not K then return 0 end
  pinfo.cols.info = name
  return dissect_kind(K, tvb, pinfo, tree)
end

local function tcp_pdu_len(tvb, pinfo, offset)
  return tvb(offset, 2):uint() + 2
end

local function tcp_kind(pinfo)
  local pair = TCP_PORTS[pinfo.dst_port]
  if pair then return pair[1] end
  pair = TCP_PORTS[pinfo.src_port]
  if pair then return pair[2] end
end

local function tcp_frame(tvb, pinfo, tree)
  local K = KINDS[tcp_kind(pinfo)]
  pinfo.cols.info:append(" |")
  return dissect_kind(K, tvb, pinfo, tree)
end

local function tcp_dissector(tvb, pinfo, tree)
  local name = tcp_kind(pinfo)
  if not name or not KINDS[name] then return 0 end
  pinfo.cols.info = name
  -- TCP frames are [u16 size][id][payload]: reassembled across segments, split when several share one
  dissect_tcp_pdus(tvb, tree, 2, tcp_pdu_len, tcp_frame, true)
  return tvb:len()
end

function frc.dissector(tvb, pinfo, tree)
  if pinfo.port_type == 3 then return udp_dissector(tvb, pinfo, tree) end
  return tcp_dissector(tvb, pinfo, tree)
end

local udp_table = DissectorTable.get("udp.port")
for port, _ in pairs(UDP_PORTS) do udp_table:add(port, frc) end
local tcp_table = DissectorTable.get("tcp.port")
for port, _ in pairs(TCP_PORTS) do tcp_table:add(port, frc) end
'''
    return head + "\n" + fields_lua + "\n\n" + "".join(kinds_lua) + _ENGINE + tail


def value_abbrevs(model: KindModel) -> set[str]:
    """The Wireshark fields that carry a value ``fieldbox decode --json`` prints (not the
    size, id and length bytes around them): what the tests compare."""
    out = {f"frc.{model.prefix}.type"}
    for kind in ("unknown_tag", "malformed_tag", "unknown_frame"):
        out.update(f"frc.{model.prefix}.{kind}.{f}" for f in ("tag_id", "data", "raw"))
    opaque = {st.cls for st in model.structs.values() if st.opaque}
    for st in model.structs.values():
        cls = st.cls or st.name
        if cls in opaque:
            continue
        if st.id_field:
            out.add(struct_abbrev(model, cls, st.id_field))
        out.update(struct_abbrev(model, cls, c.path) for c in st.consts)
        for it in [i for top in st.items for i in (top.items if isinstance(top, Group) else [top])]:
            if isinstance(it, Item):
                out.update(struct_abbrev(model, cls, b.path) for b in it.bits)
            elif isinstance(it, (Text, Raw, Ints)):
                out.add(struct_abbrev(model, cls, it.path))
    return out


def run_dissector(output: str | None) -> int:
    """``fieldbox dissector [-o FILE]``: the plugin to stdout or a file; 1 with one line on
    stderr if the file cannot be written."""
    import sys

    text = generate()
    if output is None:
        sys.stdout.write(text)
        return 0
    try:
        with open(output, "w", encoding="utf-8") as f:
            f.write(text)
    except OSError as exc:
        print(f"fieldbox dissector: {output}: {exc.strerror or exc}", file=sys.stderr)
        return 1
    print(f"fieldbox dissector: wrote {output} ({len(text):,} bytes): run `tshark -X lua_script:{output}`, or copy "
          "it into Wireshark's personal Lua plugins folder", file=sys.stderr)
    return 0
