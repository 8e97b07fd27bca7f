"""Every packet kind by name: decode, annotate and the coverage rule the inspector relies on.

A kind is one wire direction and transport, named as on the command line
(``fieldbox decode --as KIND``). For the TCP kinds a packet is one whole frame, its u16 size
included.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Callable

from .errors import ProtocolError
from .wire import Reader, Span, annotate_with


@dataclass(frozen=True)
class Kind:
    name: str
    title: str
    message: str  # the message name errors carry
    walk: Callable[[Reader], Any]
    decode: Callable[[bytes], Any]
    tcp: bool = False

    def annotate(self, data: bytes) -> list[Span]:
        """Spans covering every byte of ``data``. Raises ProtocolError on bad input."""
        return annotate_with(self.walk, self.message, bytes(data))

    def annotate_lenient(self, data: bytes) -> tuple[list[Span], ProtocolError | None]:
        """Spans for as much as decodes; the rest is one span that names the error.

        What the packet inspector shows for a bad packet: the good part explained, the bad
        part marked, every byte still covered.
        """
        data = bytes(data)
        r = Reader(data, self.message, annotate=True)
        try:
            self.walk(r)
            return r.spans or [], None
        except ProtocolError as exc:
            spans = sorted(r.spans or [], key=lambda s: s.offset)
            kept: list[Span] = []
            pos = 0
            for s in spans:
                if s.offset >= pos:
                    kept.append(s)
                    pos = s.offset + s.length
            if pos < len(data):
                kept.append(Span(pos, len(data) - pos, "(undecodable)", data[pos:].hex(" "), str(exc)))
            return kept, exc


def coverage_gaps(spans: list[Span], length: int) -> list[tuple[int, int]]:
    """``(offset, length)`` of every byte run not covered by exactly one span, plus overlaps.

    Empty for a good annotation: spans tile the packet, in order, with no overlap.
    """
    problems = []
    pos = 0
    for s in sorted(spans, key=lambda s: (s.offset, s.length)):
        if s.offset > pos:
            problems.append((pos, s.offset - pos))
        elif s.offset < pos:
            problems.append((s.offset, pos - s.offset))
        pos = max(pos, s.offset + s.length)
    if pos < length:
        problems.append((pos, length - pos))
    return problems


_REGISTRY: dict[str, Kind] = {}


def register(kind: Kind) -> Kind:
    _REGISTRY[kind.name] = kind
    return kind


def _load() -> dict[str, Kind]:
    if not _REGISTRY:
        from . import ds_to_rio
        register(Kind("ds-to-rio", "DS -> roboRIO, UDP 1110/1115", ds_to_rio.CONTROL,
                      ds_to_rio.walk_control, ds_to_rio.decode_control))
        register(Kind("ds-to-rio-tcp", "DS -> roboRIO, TCP 1740", ds_to_rio.TCP,
                      ds_to_rio.walk_tcp, ds_to_rio.decode_tcp, tcp=True))
        for module_name in ("rio_to_ds", "fms_to_ds", "ds_to_fms", "legacy"):
            try:
                module = __import__(f"protocol.{module_name}", fromlist=["KINDS"])
            except ImportError:
                continue
            for kind in getattr(module, "KINDS", ()):
                register(kind)
    return _REGISTRY


def kinds() -> dict[str, Kind]:
    return dict(_load())


def get(name: str) -> Kind:
    table = _load()
    if name not in table:
        raise KeyError(f"unknown kind {name!r}: one of {', '.join(table)}")
    return table[name]


def decode(kind: str, data: bytes) -> Any:
    return get(kind).decode(bytes(data))


def annotate(kind: str, data: bytes) -> list[Span]:
    return get(kind).annotate(data)
