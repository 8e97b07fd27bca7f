"""``fieldbox decode``: one packet, every byte explained."""

from __future__ import annotations

import json
import re
import sys

_SEPARATORS = re.compile(r"[\s:,_-]+")


class HexError(ValueError):
    pass


def parse_hex(text: str) -> bytes:
    """Hex with optional spaces, colons or dashes between bytes and optional 0x prefixes."""
    cleaned = _SEPARATORS.sub("", re.sub(r"0[xX](?=[0-9a-fA-F])", "", text.strip()))
    bad = re.search(r"[^0-9a-fA-F]", cleaned)
    if bad:
        raise HexError(f"not a hex digit: {bad.group()!r} at character {bad.start()}")
    if len(cleaned) % 2:
        raise HexError(f"odd number of hex digits ({len(cleaned)}): a byte is two digits")
    return bytes.fromhex(cleaned)


def run_decode(kind_name: str, text: str, *, as_json: bool = False, out=None, err=None) -> int:
    from protocol import kinds
    from protocol.errors import ProtocolError
    from protocol.wire import jsonable

    out = out or sys.stdout
    err = err or sys.stderr
    if text == "-":
        text = sys.stdin.read()
    try:
        data = parse_hex(text)
    except HexError as exc:
        print(f"fieldbox decode: {exc}", file=err)
        return 1
    kind = kinds.get(kind_name)
    try:
        message = kind.decode(data)
        spans = kind.annotate(data)
    except ProtocolError as exc:
        print(f"fieldbox decode: {exc}", file=err)
        return 1
    if as_json:
        obj = {"kind": kind.name, "length": len(data), "fields": jsonable(message),
               "spans": [s.to_json() for s in spans]}
        print(json.dumps(obj), file=out)
        return 0
    _print_table(kind, data, message, spans, out)
    return 0


def _print_table(kind, data: bytes, message, spans, out) -> None:
    from rich.console import Console
    from rich.table import Table
    from rich.text import Text

    console = Console(file=out, highlight=False, soft_wrap=False,
                      width=max(100, Console(file=out).width))
    table = Table(title=f"{kind.title}: {type(message).__name__}, {len(data)} bytes",
                  title_justify="left", show_lines=False, header_style="bold")
    table.add_column("offset", justify="right", no_wrap=True)
    table.add_column("bytes", no_wrap=False, max_width=26)
    table.add_column("field", no_wrap=True)
    table.add_column("value", max_width=28)
    table.add_column("meaning")
    for s in spans:
        raw = data[s.offset:s.offset + s.length]
        shown = raw.hex(" ") if len(raw) <= 8 else f"{raw[:8].hex(' ')} … ({len(raw)} bytes)"
        value = s.value if isinstance(s.value, str) else repr(s.value)
        table.add_row(f"{s.offset}", shown, s.field, Text(value), Text(s.meaning))
    console.print(table)
