"""Byte-level building blocks shared by every message module.

Two halves:

* :class:`Reader` walks a packet field by field. Every read is bounds-checked and names the
  message, the dotted field path and the byte offset when it fails. With ``annotate=True``
  it also records a :class:`Span` per field, which is what ``annotate(data)`` returns and
  what the packet inspector draws. A message module writes its decoder once against a
  Reader; the same walk serves decoding and annotating.
* Encoding helpers that validate before packing: a value out of range is a
  :class:`ProtocolError`, never a silent wrap.

Text on every wire here is handled as UTF-8 with ``surrogateescape``: any bytes decode, and
re-encode byte-identical.
"""

from __future__ import annotations

import dataclasses
import enum
import struct
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Callable, NoReturn, TypeVar

from .errors import ProtocolError

if TYPE_CHECKING:
    from _typeshed import DataclassInstance

D = TypeVar("D", bound="DataclassInstance")

TEXT_ENCODING = "utf-8"
TEXT_ERRORS = "surrogateescape"

U8 = struct.Struct(">B")
I8 = struct.Struct(">b")
U16 = struct.Struct(">H")
I16 = struct.Struct(">h")
U32 = struct.Struct(">I")
I32 = struct.Struct(">i")
U64 = struct.Struct(">Q")
F32 = struct.Struct(">f")


@dataclass(frozen=True, slots=True)
class Span:
    """One annotated run of bytes: what the inspector highlights and explains."""

    offset: int
    length: int
    field: str
    value: Any
    meaning: str

    def to_json(self) -> dict[str, Any]:
        return {
            "offset": self.offset,
            "length": self.length,
            "field": self.field,
            "value": jsonable(self.value),
            "meaning": self.meaning,
        }


@dataclass(frozen=True, slots=True)
class UnknownTag:
    """A tag this library does not know: kept raw, re-encoded byte-identical."""

    tag_id: int
    data: bytes = b""


class Reader:
    """A bounds-checked cursor over one packet (or one tag inside it)."""

    __slots__ = ("data", "pos", "end", "message", "path", "spans")

    def __init__(
        self,
        data: bytes,
        message: str,
        *,
        annotate: bool = False,
        start: int = 0,
        end: int | None = None,
        path: str = "",
        spans: list[Span] | None = None,
    ) -> None:
        self.data = data
        self.pos = start
        self.end = len(data) if end is None else end
        self.message = message
        self.path = path
        self.spans = spans if spans is not None else ([] if annotate else None)

    # -- where we are ------------------------------------------------------------------
    def remaining(self) -> int:
        return self.end - self.pos

    def at_end(self) -> bool:
        return self.pos >= self.end

    def name(self, field: str) -> str:
        if not self.path:
            return field
        if not field:
            return self.path
        return f"{self.path}.{field}" if not field.startswith("[") else f"{self.path}{field}"

    def fail(self, field: str, reason: str, offset: int | None = None) -> NoReturn:
        raise ProtocolError(self.message, self.name(field), self.pos if offset is None else offset, reason)

    def need(self, n: int, field: str) -> None:
        if n < 0 or self.pos + n > self.end:
            left = self.end - self.pos
            self.fail(field, f"needs {n} byte{'s' if n != 1 else ''}, {left} left")

    # -- spans -------------------------------------------------------------------------
    def note(self, offset: int, length: int, field: str, value: Any, meaning: str = "") -> None:
        """Record a span by hand (a no-op unless annotating)."""
        if self.spans is not None:
            self.spans.append(Span(offset, length, self.name(field), value, meaning))

    def explain(self, value: Any = None, meaning: str | None = None) -> None:
        """Replace the value and/or meaning of the span recorded last."""
        if self.spans:
            last = self.spans[-1]
            self.spans[-1] = dataclasses.replace(
                last,
                value=last.value if value is None else value,
                meaning=last.meaning if meaning is None else meaning,
            )

    # -- fixed-size reads ----------------------------------------------------------------
    def _unpack(self, st: struct.Struct, field: str, meaning: str) -> Any:
        # Any, as struct's unpack is; each caller below names the type its format gives.
        self.need(st.size, field)
        (value,) = st.unpack_from(self.data, self.pos)
        if self.spans is not None:
            self.spans.append(Span(self.pos, st.size, self.name(field), value, meaning))
        self.pos += st.size
        return value

    def u8(self, field: str, meaning: str = "") -> int:
        value: int = self._unpack(U8, field, meaning)
        return value

    def i8(self, field: str, meaning: str = "") -> int:
        value: int = self._unpack(I8, field, meaning)
        return value

    def u16(self, field: str, meaning: str = "") -> int:
        value: int = self._unpack(U16, field, meaning)
        return value

    def i16(self, field: str, meaning: str = "") -> int:
        value: int = self._unpack(I16, field, meaning)
        return value

    def u32(self, field: str, meaning: str = "") -> int:
        value: int = self._unpack(U32, field, meaning)
        return value

    def i32(self, field: str, meaning: str = "") -> int:
        value: int = self._unpack(I32, field, meaning)
        return value

    def u64(self, field: str, meaning: str = "") -> int:
        value: int = self._unpack(U64, field, meaning)
        return value

    def f32(self, field: str, meaning: str = "") -> float:
        value: float = self._unpack(F32, field, meaning)
        return value

    def uint(self, n: int, field: str, meaning: str = "") -> int:
        """An n-byte big-endian unsigned integer (n may be 0)."""
        self.need(n, field)
        value = int.from_bytes(self.data[self.pos : self.pos + n], "big")
        if self.spans is not None and n:
            self.spans.append(Span(self.pos, n, self.name(field), value, meaning))
        self.pos += n
        return value

    def raw(self, n: int, field: str, meaning: str = "") -> bytes:
        self.need(n, field)
        value = bytes(self.data[self.pos : self.pos + n])
        if self.spans is not None and n:
            self.spans.append(Span(self.pos, n, self.name(field), value.hex(" "), meaning))
        self.pos += n
        return value

    def rest(self, field: str, meaning: str = "") -> bytes:
        return self.raw(self.end - self.pos, field, meaning)

    # -- text ----------------------------------------------------------------------------
    def text(self, n: int, field: str, meaning: str = "") -> str:
        self.need(n, field)
        value = bytes(self.data[self.pos : self.pos + n]).decode(TEXT_ENCODING, TEXT_ERRORS)
        if self.spans is not None and n:
            self.spans.append(Span(self.pos, n, self.name(field), value, meaning))
        self.pos += n
        return value

    def rest_text(self, field: str, meaning: str = "") -> str:
        return self.text(self.end - self.pos, field, meaning)

    def _prefixed_text(self, st: struct.Struct, field: str, meaning: str) -> str:
        n = self._unpack(st, f"{field}.length", f"length of {field}, in bytes")
        return self.text(n, field, meaning)

    def text8(self, field: str, meaning: str = "") -> str:
        """A string with a u8 length prefix."""
        return self._prefixed_text(U8, field, meaning)

    def text16(self, field: str, meaning: str = "") -> str:
        """A string with a u16 length prefix."""
        return self._prefixed_text(U16, field, meaning)

    def text32(self, field: str, meaning: str = "") -> str:
        """A string with a u32 length prefix (bounded by the bytes left, so never huge)."""
        return self._prefixed_text(U32, field, meaning)

    # -- structure -----------------------------------------------------------------------
    def child(self, length: int, path: str) -> "Reader":
        """A reader over the next ``length`` bytes whose field names start with ``path``.

        The parent moves past those bytes at once; the child shares the span list.
        """
        self.need(length, path)
        sub = Reader(self.data, self.message, start=self.pos, end=self.pos + length,
                     path=self.name(path), spans=self.spans)
        self.pos += length
        return sub

    def expect_end(self, field: str = "") -> None:
        if self.pos != self.end:
            self.fail(field or "end", f"{self.end - self.pos} unexpected trailing byte(s)")

    def refuse_over(self, bound: int, what: str) -> None:
        """Fail (a :func:`over_bound` error) if the packet is longer than ``bound`` bytes: what
        a walk calls once its header is read, before any loop. Annotating, the rest of the
        packet is first one span saying so, so the header is explained and every byte covered,
        in a time that does not grow with what was not walked."""
        if self.end <= bound:
            return
        if self.spans is not None and self.pos < self.end:
            n = self.end - self.pos
            self.spans.append(Span(self.pos, n, self.name(NOT_DECODED), f"{n} bytes",
                                   f"not decoded: {self.end} bytes is over the {bound}-byte bound of {what}"))
        raise over_bound(self.message, self.end, bound, what)


def annotate_with(walk: Callable[[Reader], Any], message: str, data: bytes) -> list[Span]:
    """The spans ``walk`` records over ``data``: what every ``annotate_*`` function returns."""
    r = Reader(data, message, annotate=True)
    walk(r)
    return r.spans or []


#: The field name of the span over the bytes of a packet past its size bound (see
#: :meth:`Reader.refuse_over`).
NOT_DECODED = "not_decoded"


def over_bound(message: str, size: int, bound: int, what: str) -> ProtocolError:
    """The error for a message of ``size`` bytes whose kind is bounded at ``bound``: raised
    before any walk (a ``len()``, whatever the bytes), naming the first byte over the bound.
    Each message module names its bound and says why a real peer never comes near it."""
    return ProtocolError(message, "size", bound, f"{size} bytes is over the {bound}-byte bound of {what}: "
                                                 "not decoded")


class Irregular(Exception):
    """A hand-unrolled fast path met something only the reference walk can name: fall back."""


def irregular() -> NoReturn:
    """Raise :class:`Irregular` (usable inside an expression)."""
    raise Irregular


# -- encoding helpers -----------------------------------------------------------------
def check_int(message: str, field: str, value: object, lo: int, hi: int) -> int:
    """Return ``value`` if it is an int in ``lo..hi``, else raise ProtocolError."""
    if isinstance(value, bool):
        value = int(value)
    elif not isinstance(value, int):
        raise ProtocolError(message, field, None, f"{value!r} is not an integer")
    if not lo <= value <= hi:
        raise ProtocolError(message, field, None, f"{value} is outside {lo}..{hi}")
    return value


def check_f32(message: str, field: str, value: Any) -> float:
    try:
        F32.pack(value)
    except (struct.error, TypeError, OverflowError) as exc:
        raise ProtocolError(message, field, None, f"{value!r} is not a 32-bit float ({exc})") from None
    return float(value)


def check_bytes(message: str, field: str, value: Any) -> bytes:
    """``value`` as bytes if it is bytes or a bytearray, else a ProtocolError naming ``field``."""
    if not isinstance(value, (bytes, bytearray)):
        raise ProtocolError(message, field, None, f"{value!r} is not bytes")
    return bytes(value)


def encode_text(message: str, field: str, text: str, max_len: int | None = None) -> bytes:
    if not isinstance(text, str):
        raise ProtocolError(message, field, None, f"{text!r} is not a string")
    try:
        data = text.encode(TEXT_ENCODING, TEXT_ERRORS)
    except UnicodeEncodeError as exc:
        raise ProtocolError(message, field, None, f"cannot encode text: {exc.reason}") from None
    if max_len is not None and len(data) > max_len:
        raise ProtocolError(message, field, None, f"{len(data)} bytes is too long (at most {max_len})")
    return data


def text8(message: str, field: str, text: str) -> bytes:
    data = encode_text(message, field, text, 0xFF)
    return bytes((len(data),)) + data


def text16(message: str, field: str, text: str) -> bytes:
    data = encode_text(message, field, text, 0xFFFF)
    return U16.pack(len(data)) + data


def text32(message: str, field: str, text: str, max_len: int = 0xFFFFFFFF) -> bytes:
    data = encode_text(message, field, text, max_len)
    return U32.pack(len(data)) + data


def udp_tag(message: str, field: str, tag_id: int, payload: bytes) -> bytes:
    """``[u8 size][u8 id][payload]``; size counts the id byte."""
    if len(payload) > 0xFE:
        raise ProtocolError(message, field, None, f"{len(payload)}-byte payload does not fit a u8 tag size")
    return bytes((len(payload) + 1, tag_id)) + payload


def tcp_frame(message: str, tag_id: int, payload: bytes) -> bytes:
    """``[u16 size][u8 id][payload]``; size counts the id byte."""
    if len(payload) > 0xFFFE:
        raise ProtocolError(message, "size", None, f"{len(payload)}-byte payload does not fit a u16 frame size")
    return U16.pack(len(payload) + 1) + bytes((tag_id,)) + payload


# -- JSON view ------------------------------------------------------------------------
def jsonable(value: Any) -> Any:
    """A plain JSON-able view of a message, tag, enum or value (nested)."""
    if isinstance(value, enum.Enum):
        return value.name
    if isinstance(value, bool) or value is None or isinstance(value, (int, float, str)):
        if isinstance(value, str):
            return value.encode(TEXT_ENCODING, TEXT_ERRORS).decode(TEXT_ENCODING, "replace")
        return value
    if isinstance(value, (bytes, bytearray, memoryview)):
        return bytes(value).hex()
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        out: dict[str, Any] = {"type": type(value).__name__}
        for f in dataclasses.fields(value):
            out[f.name] = jsonable(getattr(value, f.name))
        return out
    if isinstance(value, dict):
        return {str(k): jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [jsonable(v) for v in value]
    return repr(value)


def unchecked_constructor(cls: type[D]) -> Callable[..., D]:
    """A positional constructor for a frozen, slotted dataclass that skips ``__init__``.

    Frozen dataclasses set each field through ``object.__setattr__``; on the 50 Hz decode
    path that is half the cost of a control packet. This sets the slots directly and is
    about twice as fast. Only for decoders, which build values they have already checked.
    """
    names = [f.name for f in dataclasses.fields(cls)]
    env: dict[str, Any] = {"_new": object.__new__, "_cls": cls}
    lines = [f"def make({', '.join(names)}):", "    o = _new(_cls)"]
    for i, name in enumerate(names):
        env[f"_s{i}"] = cls.__dict__[name].__set__
        lines.append(f"    _s{i}(o, {name})")
    lines.append("    return o")
    exec("\n".join(lines), env)  # noqa: S102 - generated from field names only
    make: Callable[..., D] = env["make"]
    return make
