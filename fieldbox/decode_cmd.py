"""``fieldbox decode``: one packet, every byte explained.

A value that decodes but is out of the range a real peer sends (a POV over 359, a battery
over 30 V) is a warning, in the text and in ``--json``: the packet is what it is, and a
teacher or a mentor sees at once what a DS or a robot got wrong. Floats are printed as a
person reads them (``24.58``), the exact value in ``--json``.

Input is bounded before it is read whole (issue 27: 1 MB of hex took over two minutes and
1.9 GB): no packet is longer than :data:`MAX_PACKET` bytes, so more hex text than that can
spell is refused at once, and stdin is read only that far. A packet over its kind's size
bound is refused by the decoder at once; a big legal one (a 16 KiB log-data frame: 12,700
fields) prints as plain columns, a row each, where the table would take seconds.

Each line of the input is one packet (issue 30: several pasted lines were joined into one
packet without a word): two lines are two packets, each decoded, titled with its line number
and judged on its own (``--json`` prints one object a line, with its ``line``); the exit code
is 1 if any line failed. A packet wrapped over several lines must be joined first.
"""

from __future__ import annotations

import json
import re
import sys

_SEPARATORS = re.compile(r"[\s:,_-]+")
_INDEX = re.compile(r"\[\d+\]$")

#: The longest packet of any kind: a TCP frame, its u16 size and 65,535 bytes (a UDP datagram
#: holds at most 65,507).
MAX_PACKET = 0xFFFF + 2
#: Characters of input read at most: eight a byte leaves room for ``0x00, `` and line breaks.
MAX_TEXT = 8 * MAX_PACKET
#: Fields shown as a drawn table; more print as plain columns (a table row costs about half a
#: millisecond to lay out: 12,700 rows took seven seconds).
MAX_TABLE_ROWS = 400
#: Characters of one value shown in the text (``--json`` has every value whole).
MAX_VALUE_TEXT = 400
#: Packets (non-empty lines) decoded in one run at most: each prints a table.
MAX_LINES = 1000

#: Field name (its last part, without an index) -> (lowest, highest, what the range means).
RANGES = {
    "povs": (-1, 359, "0..359 degrees, or -1 when centred"),
    "pov": (-1, 359, "0..359 degrees, or -1 when centred"),
    "battery": (0.0, 30.0, "a robot battery reads 0..30 V"),
    "voltage": (0.0, 30.0, "a robot battery reads 0..30 V"),
    "volts": (0.0, 30.0, "a robot battery reads 0..30 V"),
    "station": (0, 5, "0..5: R1, R2, R3, B1, B2, B3"),
}
#: The fields of :data:`RANGES` that are lists of such values, each element judged alone; an
#: element of any other field is not one (the 2010 battery's two BCD bytes, 0x12 0x60 for
#: 12.60 V, are not volts).
LISTS = frozenset({"povs"})


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

    out = out or sys.stdout
    err = err or sys.stderr
    if text == "-":
        text = sys.stdin.read(MAX_TEXT + 1)  # bounded: what a pipe holds beyond is never read
    if len(text) > MAX_TEXT:
        print(f"fieldbox decode: more than {MAX_TEXT:,} characters of input: no packet is longer than "
              f"{MAX_PACKET:,} bytes", file=err)
        return 1
    kind = kinds.get(kind_name)
    lines = [(n, line) for n, line in enumerate(text.splitlines(), 1) if line.strip()]
    if len(lines) <= 1:  # one packet: as it always was
        return _decode_one(kind, lines[0][1] if lines else text, None, as_json, out, err)
    if len(lines) > MAX_LINES:
        print(f"fieldbox decode: {len(lines):,} lines of input: one packet a line, at most {MAX_LINES:,}", file=err)
        return 1
    failed = 0
    for n, line in lines:
        if not as_json and n != lines[0][0]:
            print(file=out)
        failed += _decode_one(kind, line, n, as_json, out, err)
    if failed:
        print(f"fieldbox decode: {failed} of {len(lines)} lines did not decode (one packet a line: join a "
              "packet wrapped over lines first)", file=err)
    return 1 if failed else 0


def _decode_one(kind, text: str, line: int | None, as_json: bool, out, err) -> int:
    """Decode and print one packet (``line``: its line number when the input had several);
    0, or 1 with one line on ``err`` saying why."""
    from protocol.errors import ProtocolError

    where = f"line {line}: " if line is not None else ""
    try:
        data = parse_hex(text)
    except HexError as exc:
        print(f"fieldbox decode: {where}{exc}", file=err)
        return 1
    if len(data) > MAX_PACKET:
        print(f"fieldbox decode: {where}{len(data):,} bytes: no packet is longer than {MAX_PACKET:,} bytes",
              file=err)
        return 1
    try:
        message = kind.decode(data)
        spans = kind.annotate(data)
    except ProtocolError as exc:
        print(f"fieldbox decode: {where}{exc}", file=err)
        return 1
    warnings = range_warnings(message, spans)
    if as_json:
        obj = packet_json(kind.name, data, message, spans, warnings)
        if line is not None:
            obj = {"line": line, **obj}
        print(json.dumps(obj), file=out)
        return 0
    if line is not None:
        print(f"line {line}:", file=out)
    _print_table(kind, data, message, spans, out)
    for w in warnings:
        where = f"byte {w['offset']}" if w["offset"] is not None else "field"
        print(f"warning: {where} ({w['field']}): {w['warning']}", file=out)
    return 0


def packet_json(kind_name: str, data: bytes, message, spans, warnings: list[dict]) -> dict:
    """A decoded packet as ``--json`` prints it (``spans`` None: left out, as ``--pcap`` does)."""
    from protocol.wire import jsonable

    obj = {"kind": kind_name, "length": len(data), "fields": jsonable(message)}
    if spans is not None:
        obj["spans"] = [s.to_json() for s in spans]
    obj["warnings"] = warnings
    return obj


def range_warnings(message, spans) -> list[dict]:
    """The values out of the range real peers send, one dict each (offset, field, value,
    warning), read from the decoded message (a span's value may be text, "12.50 V")."""
    offsets = {s.field: s.offset for s in spans}
    found = []
    for path, value in _fields(message, ""):
        last = path.rsplit(".", 1)[-1]
        name = _INDEX.sub("", last)
        rule = RANGES.get(name) if name == last or name in LISTS else None
        if rule is None or isinstance(value, bool) or not isinstance(value, (int, float)):
            continue
        low, high, meaning = rule
        if not low <= value <= high:
            found.append({"offset": offsets.get(path), "field": path, "value": value,
                          "warning": f"{human(value)} is out of range ({meaning})"})
    return found


def _fields(obj, prefix: str, depth: int = 0):
    """(path, value) of every field of a decoded message, nested ones as ``tags[0].povs[2]``."""
    import dataclasses
    import enum

    if depth > 8 or isinstance(obj, enum.Enum):
        return
    if dataclasses.is_dataclass(obj) and not isinstance(obj, type):
        for f in dataclasses.fields(obj):
            value = getattr(obj, f.name)
            path = f"{prefix}.{f.name}" if prefix else f.name
            yield path, value
            yield from _fields(value, path, depth + 1)
    elif isinstance(obj, (list, tuple)):
        for i, value in enumerate(obj):
            path = f"{prefix}[{i}]"
            yield path, value
            yield from _fields(value, path, depth + 1)


def human(value) -> str:
    """A value as a person reads it: floats to two decimals (three significant digits when
    smaller), containers item by item, anything else as it is."""
    if isinstance(value, float):
        if value != value or value in (float("inf"), float("-inf")):
            return str(value)
        if abs(value) >= 0.01 or value == 0:
            return f"{value:.2f}".rstrip("0").rstrip(".")
        return f"{value:.3g}"
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(human(v) for v in value) + "]"
    return value if isinstance(value, str) else repr(value)


def _clip(text: str, n: int) -> str:
    return text if len(text) <= n else f"{text[:n]}… ({len(text):,} characters)"


def _rows(data: bytes, spans, value_width: int):
    """(offset, bytes, field, value, meaning) as text, a row a span."""
    for s in spans:
        raw = data[s.offset:s.offset + s.length]
        shown = raw.hex(" ") if len(raw) <= 8 else f"{raw[:8].hex(' ')} … ({len(raw)} bytes)"
        yield f"{s.offset}", shown, s.field, _clip(human(s.value), value_width), s.meaning


def _print_table(kind, data: bytes, message, spans, out) -> None:
    title = f"{kind.title}: {type(message).__name__}, {len(data)} bytes"
    if len(spans) > MAX_TABLE_ROWS:
        _print_columns(title, data, spans, out)
        return
    from rich.console import Console
    from rich.table import Table
    from rich.text import Text

    console = Console(file=out, highlight=False, soft_wrap=False,
                      width=max(100, Console(file=out).width))
    table = Table(title=title, title_justify="left", show_lines=False, header_style="bold")
    table.add_column("offset", justify="right", no_wrap=True)
    table.add_column("bytes", no_wrap=False, max_width=26)
    table.add_column("field", no_wrap=True)
    table.add_column("value", max_width=28)
    table.add_column("meaning")
    for offset, shown, field, value, meaning in _rows(data, spans, MAX_VALUE_TEXT):
        table.add_row(offset, shown, field, Text(value), Text(meaning))
    console.print(table)


def _printable(text: str) -> str:
    """A value on one line: a console line's newline must not break a row in two."""
    return text if text.isprintable() else "".join(c if c.isprintable() else repr(c)[1:-1] for c in text)


def _print_columns(title: str, data: bytes, spans, out) -> None:
    """The table's rows as plain columns, one line each: linear in the number of fields."""
    rows = [(o, b, f, _printable(v), m) for o, b, f, v, m in _rows(data, spans, 28)]
    widths = [max(len(heading), *(len(r[i]) for r in rows)) for i, heading in
              enumerate(("offset", "bytes", "field", "value"))]
    widths = [min(w, cap) for w, cap in zip(widths, (6, 26, 48, 40))]
    print(f"{title} ({len(spans):,} fields, as plain columns; --json gives every value whole)", file=out)
    line = "{:>%d}  {:<%d}  {:<%d}  {:<%d}  {}" % tuple(widths)
    print(line.format("offset", "bytes", "field", "value", "meaning"), file=out)
    out.write("\n".join(line.format(*r).rstrip() for r in rows) + "\n")


def run_pcap(path: str, *, as_json: bool = False, out=None, err=None) -> int:
    """``fieldbox decode --pcap FILE``: every FRC packet of a capture, one a line (a JSON object
    a line with ``as_json``), with its time, link and kind, then a count line; packets that are
    not FRC are counted, not printed. 1 if the file cannot be read to its end (what was read
    is printed first), else 0."""
    try:
        return _run_pcap(path, as_json, out or sys.stdout, err or sys.stderr)
    except BrokenPipeError:  # the reader went away (``| head``): stop quietly, no traceback
        import os

        try:
            os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())  # so exit's flush is quiet
        except (OSError, ValueError):
            pass
        return 1


def _run_pcap(path: str, as_json: bool, out, err) -> int:
    from . import capread
    from .packet_text import Annotation, summarize

    reader = capread.Reader()
    by_kind: dict[str, int] = {}
    bad = 0
    failure: str | None = None
    try:
        f = open(path, "rb")
    except OSError as exc:
        print(f"fieldbox decode: {path}: {exc.strerror or exc}", file=err)
        return 1
    with f:
        try:
            for p in reader.packets(f):
                t0 = reader.counts.first_time or 0.0  # Wireshark's relative time: from the first packet
                by_kind[p.kind] = by_kind.get(p.kind, 0) + 1
                annotation = Annotation(p.kind, p.data)
                bad += annotation.error is not None
                if as_json:
                    print(json.dumps(_pcap_json(p, p.time - t0, annotation)), file=out)
                else:
                    line = f"{p.time - t0:11.6f}  {capread.link_text(p)}  {p.kind}  " \
                           f"{summarize(p.kind, p.data, annotation)}"
                    print(_printable(line), file=out)
        except capread.CaptureError as exc:
            failure = str(exc)
        except OSError as exc:  # a disk or network file system failing mid-read
            failure = f"read error: {exc.strerror or exc}"
    c = reader.counts
    if as_json:
        summary = {"type": "summary", "frc": c.frc, "other": c.other, "records": c.records, "by_kind": by_kind,
                   "bad": bad, "tcp_lost": c.tcp_lost, "tcp_lost_bytes": c.tcp_lost_bytes, "notes": c.notes,
                   "error": failure}
        print(json.dumps(summary), file=out)
    else:
        kinds = ", ".join(f"{n:,} {k}" for k, n in by_kind.items())
        print(f"{c.frc:,} FRC packets{f' ({kinds})' if kinds else ''}, {c.other:,} other packets (not printed)",
              file=out)
        if bad:
            print(f"{bad:,} FRC packets did not decode (marked BAD)", file=out)
        for note in c.notes:
            print(note, file=out)
    if failure is not None:
        print(f"fieldbox decode: {path}: {failure}", file=err)
        return 1
    if c.records == 0:
        print(f"fieldbox decode: {path}: no packets in the capture", file=err)
    return 0


def _pcap_json(p, relative: float, annotation) -> dict:
    """One packet of ``--pcap --json``: where and when, then what ``--json`` says of it."""
    from protocol import kinds
    from protocol.errors import ProtocolError

    from . import capread

    sender, receiver = capread.ROLES.get(p.kind, ("?", "?"))
    head = {"type": "packet", "time": round(relative, 9), "abs_time": p.time,
            "utc": _utc(p.time),
            "src": list(p.src), "dst": list(p.dst), "from": sender, "to": receiver,
            "from_team": capread.team_of(p.src[0]), "to_team": capread.team_of(p.dst[0]), "offset": p.offset}
    if annotation.error is None:
        try:
            message = kinds.get(p.kind).decode(p.data)
        except ProtocolError as exc:
            return {**head, "kind": p.kind, "length": len(p.data), "error": str(exc), "hex": p.data.hex()}
        spans = annotation.spans
        return {**head, **packet_json(p.kind, p.data, message, None, range_warnings(message, spans))}
    return {**head, "kind": p.kind, "length": len(p.data), "error": str(annotation.error), "hex": p.data.hex()}


def _utc(t: float) -> str | None:
    """A Unix time as ISO 8601 UTC; None for a stamp no calendar holds (a corrupt record)."""
    import datetime as dt

    try:
        return dt.datetime.fromtimestamp(t, dt.timezone.utc).isoformat()
    except (ValueError, OverflowError, OSError):
        return None
