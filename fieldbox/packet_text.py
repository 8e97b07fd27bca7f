"""What a captured packet says, in words: every byte's field (:class:`Annotation`) and a
one-line summary, most telling first (:func:`summarize`).

The packet inspector draws these; nothing here needs Textual.
"""

from __future__ import annotations

from typing import Any

from protocol import kinds as protocol_kinds
from protocol.frames import MALFORMED

#: The field name of bytes no decoder could explain (a bad packet's tail).
UNDECODABLE = "(undecodable)"
_MALFORMED_SUFFIX = "." + MALFORMED
#: Fields that say how a packet is built rather than what it says: left out of summaries.
_STRUCTURAL = {"size", "id", "comm_version"}
#: A packet's running number, shown as ``#N`` after the message name.
_SEQUENCE_FIELDS = {"sequence", "packet_index", "packet_number"}
#: Bit-field bytes whose meaning ("control: no e-stop, disabled, teleop") says more than a value.
_FLAG_FIELDS = {"control", "status", "trace", "request"}


class Annotation:
    """A packet's spans, its decode error (if any) and a byte -> span index. Bytes are bad
    when no decoder explains them, or when they are a malformed tag the packet decoded around
    (a robot applies such a packet's header and drops the tag)."""

    __slots__ = ("spans", "error", "owner", "bad")

    def __init__(self, kind: str, data: bytes) -> None:
        try:
            spans, error = protocol_kinds.get(kind).annotate_lenient(data)
        except KeyError:
            from protocol.wire import Span

            spans, error = [Span(0, len(data), UNDECODABLE, data.hex(" "), f"no decoder for kind {kind!r}")], None
        self.spans = sorted(spans, key=lambda s: (s.offset, s.length))
        self.error = error
        self.bad = error is not None or any(s.field.endswith(_MALFORMED_SUFFIX) for s in self.spans)
        self.owner = [0] * len(data)
        for i, s in enumerate(self.spans):
            for b in range(s.offset, min(s.offset + s.length, len(data))):
                self.owner[b] = i

    def span_at(self, byte: int) -> int:
        if not self.owner:
            return 0
        return self.owner[max(0, min(byte, len(self.owner) - 1))]

    def is_bad(self, index: int) -> bool:
        if not 0 <= index < len(self.spans):
            return False
        field = self.spans[index].field
        return field == UNDECODABLE or field.endswith(_MALFORMED_SUFFIX)


def value_text(value: Any) -> str:
    """A field's value on one line: floats short, bytes in hex, control characters escaped."""
    if isinstance(value, float):
        return f"{value:g}"
    if isinstance(value, (bytes, bytearray)):
        return value.hex(" ")
    text = str(value)
    if not text.isprintable():  # a console line's newline must not break a row in two
        text = "".join(c if c.isprintable() else repr(c)[1:-1] for c in text)
    return text


def summarize(kind: str, data: bytes, annotation: Annotation | None = None) -> str:
    """One line, most telling first: the message, its sequence number, what its flag bytes
    mean, its other top-level fields, then its tags."""
    a = annotation or Annotation(kind, data)
    try:
        name = protocol_kinds.get(kind).message
    except KeyError:
        name = kind or "?"
    head: list[str] = []
    parts: list[str] = []
    tags: list[str] = []
    for s in a.spans:
        path = s.field
        if path == UNDECODABLE:
            continue
        if path.endswith(_MALFORMED_SUFFIX) and path.startswith("tags["):
            tags.append("MALFORMED")
            continue
        if path == "id" and isinstance(s.value, str):
            name = s.value
            continue
        if path.startswith("tags[") and path.endswith("].id"):
            tags.append(str(s.value).split(" ")[0])
            continue
        if "." in path or "[" in path or path in _STRUCTURAL:
            continue
        if path in _SEQUENCE_FIELDS:
            head.append(f"#{s.value}")
        elif path in _FLAG_FIELDS and s.meaning.startswith(f"{path}: "):
            parts.append(s.meaning[len(path) + 2:])
        else:
            parts.append(f"{path} {value_text(s.value)}")
    if tags:
        counted: list[str] = []
        for tag in dict.fromkeys(tags):
            n = tags.count(tag)
            counted.append(f"{tag}×{n}" if n > 1 else tag)
        parts.append("tags " + ", ".join(counted))
    line = " ".join([name] + head)
    if parts:
        line += ": " + " · ".join(parts)
    if a.error is not None:
        line = f"BAD {a.error} | {line}"
    return line

