"""The packet inspector: the live packets of any link, every byte explained.

Four panes, moved between with Tab:

* **Links** -- every (role, link, direction, kind) the engine's taps have seen, e.g.
  ``ds 254 robot out ds-to-rio``. Moving the highlight picks the link.
* **Packets** -- time, direction, size and a one-line summary, newest at the bottom. At the
  last row the list follows the wire; move up to stay on a packet.
* **Hex** -- the selected packet, each field in its own colour; the cursor byte's field is
  highlighted and explained under the panes. A bad packet shows its undecodable bytes in
  the error colour.
* **Fields** -- the same spans as a list (offset, length, field path, value); moving here
  moves the hex cursor too.

Keys: ``p`` pauses the view (the capture keeps recording; a counter says how much arrived),
``r`` starts/stops recording to a pcap file in the user data folder, ``R`` records to a path
you choose, ``x`` exports the capture ring as a pcap, ``X`` to a chosen path, ``c`` clears the
ring, ``[``/``]`` previous/next field.

The capture (``fieldbox/capture.py``) is fed by an engine tap that only appends to a deque on
the wire thread; this panel drains it at the app's 10 Hz refresh (also while hidden, so a
recording loses nothing) and appends only the new rows.
"""

from __future__ import annotations

import logging
import math
from collections import OrderedDict, deque
from pathlib import Path
from typing import TYPE_CHECKING, Any, Sequence

from rich.segment import Segment
from rich.style import Style
from rich.text import Text
from textual import on
from textual.app import ComposeResult
from textual.binding import Binding
from textual.containers import Horizontal, Vertical
from textual.geometry import Size
from textual.message import Message
from textual.screen import ModalScreen
from textual.scroll_view import ScrollView
from textual.strip import Strip
from textual.widget import Widget
from textual.widgets import Input, Label, OptionList
from textual.widgets.option_list import Option

from protocol import kinds as protocol_kinds

from ..capture import (CapturedPacket, CaptureRing, Endpoints, LinkKey, Recorder, clock_offset_for,
                       default_capture_path, link_label, write_pcap)
from .base import Panel

if TYPE_CHECKING:
    from roles.engine import Engine

log = logging.getLogger("fieldbox.inspector")

UNDECODABLE = "(undecodable)"
NO_PACKET = "No packet selected: the links appear as soon as packets cross the wire."
#: Fields that say how a packet is built rather than what it says: left out of summaries.
_STRUCTURAL = {"size", "id", "comm_version"}
#: A packet's running number, shown as ``#N`` after the message name.
_SEQUENCE_FIELDS = {"sequence", "packet_index", "packet_number"}
#: Bit-field bytes whose meaning ("control: no e-stop, disabled, teleop") says more than a value.
_FLAG_FIELDS = {"control", "status", "trace", "request"}


# -- what a packet says ------------------------------------------------------------------
class Annotation:
    """A packet's spans, its decode error (if any) and a byte -> span index."""

    __slots__ = ("spans", "error", "owner")

    def __init__(self, kind: str, data: bytes) -> None:
        try:
            spans, error = protocol_kinds.get(kind).annotate_lenient(data)
        except KeyError:
            from protocol.wire import Span

            spans, error = [Span(0, len(data), UNDECODABLE, data.hex(" "), f"no decoder for kind {kind!r}")], None
        self.spans = sorted(spans, key=lambda s: (s.offset, s.length))
        self.error = error
        self.owner = [0] * len(data)
        for i, s in enumerate(self.spans):
            for b in range(s.offset, min(s.offset + s.length, len(data))):
                self.owner[b] = i

    def span_at(self, byte: int) -> int:
        if not self.owner:
            return 0
        return self.owner[max(0, min(byte, len(self.owner) - 1))]

    def is_bad(self, index: int) -> bool:
        return self.spans[index].field == UNDECODABLE if 0 <= index < len(self.spans) else False


def _value_text(value: Any) -> str:
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
            parts.append(f"{path} {_value_text(s.value)}")
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


# -- a list drawn with the Line API ---------------------------------------------------------
class LineList(ScrollView, can_focus=True):
    """Rows drawn on demand (``render_row``) with a cursor; only visible rows are drawn."""

    BINDINGS = [
        Binding("up", "cursor(-1)", "Up", show=False),
        Binding("down", "cursor(1)", "Down", show=False),
        Binding("pageup", "page(-1)", "Page up", show=False),
        Binding("pagedown", "page(1)", "Page down", show=False),
        Binding("home", "first", "First", show=False),
        Binding("end", "last", "Last", show=False),
    ]
    COMPONENT_CLASSES = {"linelist--cursor", "linelist--dim", "linelist--error"}
    DEFAULT_CSS = """
    LineList { background: $surface; overflow-x: hidden; }
    LineList > .linelist--cursor { background: $panel-lighten-1; }
    LineList:focus > .linelist--cursor { background: $accent 60%; color: $text; text-style: bold; }
    LineList > .linelist--dim { color: $text-muted; }
    LineList > .linelist--error { color: $error; text-style: bold; }
    """

    class CursorMoved(Message):
        def __init__(self, widget: "LineList", row: int) -> None:
            super().__init__()
            self.widget = widget
            self.row = row

        @property
        def control(self) -> "LineList":
            return self.widget

    def __init__(self, *, id: str | None = None) -> None:
        super().__init__(id=id)
        self.cursor = 0
        self._rows = 0
        self._strips: OrderedDict[Any, Strip] = OrderedDict()

    # subclasses
    def render_row(self, row: int, width: int, base: Style) -> Text:
        return Text("")

    # the row count and the cursor
    @property
    def row_count(self) -> int:
        return self._rows

    def set_row_count(self, rows: int) -> None:
        self._rows = rows
        self.virtual_size = Size(max(1, self.size.width), rows)
        self.refresh()

    def move_cursor(self, row: int, *, notify: bool = True, scroll: bool = True) -> None:
        row = max(0, min(row, self._rows - 1)) if self._rows else 0
        self.cursor = row
        if scroll:
            self.scroll_to_row(row)
            # A row count set just now is not laid out yet: scrolling is clamped to the old
            # size, so do it again once the new size is known.
            self.call_after_refresh(self._scroll_to_cursor)
        self.refresh()
        if notify:
            self.post_message(self.CursorMoved(self, row))

    def _scroll_to_cursor(self) -> None:
        self.scroll_to_row(self.cursor)

    def scroll_to_row(self, row: int) -> None:
        height = max(1, self.scrollable_content_region.height)
        top = int(self.scroll_offset.y)
        if row < top:
            self.scroll_to(y=row, animate=False, immediate=True)
        elif row >= top + height:
            self.scroll_to(y=row - height + 1, animate=False, immediate=True)

    def action_cursor(self, delta: int) -> None:
        self.move_cursor(self.cursor + delta)

    def action_page(self, delta: int) -> None:
        self.move_cursor(self.cursor + delta * max(1, self.scrollable_content_region.height - 1))

    def action_first(self) -> None:
        self.move_cursor(0)

    def action_last(self) -> None:
        self.move_cursor(self._rows - 1)

    def on_click(self, event) -> None:
        row = int(self.scroll_offset.y) + event.y
        if 0 <= row < self._rows:
            self.move_cursor(row)

    def render_line(self, y: int) -> Strip:
        width = self.scrollable_content_region.width
        base = self.rich_style
        row = int(self.scroll_offset.y) + y
        if row >= self._rows or width <= 0:
            return Strip.blank(width, base)
        key = self.row_key(row)
        if key is not None:
            key = (key, width, row == self.cursor, self.has_focus, self.app.theme)
            strip = self._strips.get(key)
            if strip is not None:
                return strip
        text = self.render_row(row, width, base)
        text.truncate(width, overflow="ellipsis", pad=True)
        if row == self.cursor:
            text.stylize(self.get_component_rich_style("linelist--cursor"), 0, len(text))
        segments = list(text.render(self.app.console))
        strip = Strip(segments, width).adjust_cell_length(width, base)
        if key is not None:
            self._strips[key] = strip
            if len(self._strips) > 512:
                self._strips.popitem(last=False)
        return strip

    def row_key(self, row: int) -> Any:
        """What a row shows, when it never changes (its drawn strip is then kept)."""
        return None


class LinkList(OptionList):
    """Every link the taps have seen; the highlighted one is shown."""

    def __init__(self, *, id: str | None = None) -> None:
        super().__init__(id=id)
        self.keys: list[LinkKey] = []

    def update_links(self, keys: list[LinkKey]) -> None:
        if keys == self.keys:
            return
        current = self.keys[self.highlighted] if self.highlighted is not None and self.keys else None
        self.keys = list(keys)
        self.clear_options()
        self.add_options([Option(_link_prompt(k)) for k in keys])
        if current in keys:
            self.highlighted = keys.index(current)


def _link_prompt(key: LinkKey) -> Text:
    role, link, direction, kind = key
    text = Text(f"{role} {link} ", no_wrap=True, overflow="ellipsis")
    text.append(direction, style="bold" if direction == "out" else "italic")
    text.append(f" {kind or '?'}", style="dim")
    return text


def link_order(engine: Any) -> dict[str, tuple[int, int]]:
    """Roles in the order a person reads the field: DS R1..B3, roboRIO R1..B3, the FMS."""
    order: dict[str, tuple[int, int]] = {}
    field = getattr(engine, "field", None)
    for i, st in enumerate(getattr(field, "stations", [])):
        order[st.ds_name or f"ds {st.team}"] = (0, i)
        order[st.rio_name or f"rio {st.team}"] = (1, i)
    if field is not None:
        order[getattr(field, "fms_name", "fms")] = (2, 0)
    return order


def sort_links(keys, order: dict[str, tuple[int, int]]) -> list[LinkKey]:
    def key(k: LinkKey) -> tuple:
        role, link, direction, _ = k
        name, _, n = link.partition("#")
        return (order.get(role, (3, 0)), role, name, int(n) if n.isdigit() else 0, direction != "out")

    return sorted(keys, key=key)


class PacketList(LineList):
    """The packets of one link: time, direction, size, summary."""

    def __init__(self, *, id: str | None = None) -> None:
        super().__init__(id=id)
        self.source: Sequence[CapturedPacket] = ()
        self.t0 = 0.0
        self.follow = True
        self._first_index = 0
        self._summaries: OrderedDict[int, tuple[str, bool]] = OrderedDict()

    def set_source(self, source: Sequence[CapturedPacket], *, keep_index: int | None = None) -> None:
        """Show ``source`` (a live ring or a paused copy)."""
        self.source = source
        self._first_index = source[0].index if source else 0
        self.set_row_count(len(source))
        if keep_index is not None and source and not self.follow:
            self.move_cursor(keep_index - self._first_index)
        else:
            self.follow = True
            self.move_cursor(len(source) - 1)

    def grew(self) -> None:
        """The live ring changed: new rows at the end, maybe old ones gone from the start."""
        source = self.source
        first = source[0].index if source else 0
        dropped = first - self._first_index
        self._first_index = first
        rows = len(source)
        if dropped > 0 and not self.follow:
            self.cursor = max(0, self.cursor - dropped)
            self.scroll_to(y=max(0, self.scroll_offset.y - dropped), animate=False, immediate=True)
        if rows == self.row_count and dropped <= 0:
            return
        self.set_row_count(rows)
        if self.follow:
            self.move_cursor(rows - 1)
        elif dropped > 0:
            self.move_cursor(self.cursor, scroll=False)

    def row_key(self, row: int) -> Any:
        return self.source[row].seq if row < len(self.source) else None

    def selected(self) -> CapturedPacket | None:
        if not self.source or not 0 <= self.cursor < len(self.source):
            return None
        return self.source[self.cursor]

    def move_cursor(self, row: int, *, notify: bool = True, scroll: bool = True) -> None:
        super().move_cursor(row, notify=notify, scroll=scroll)
        self.follow = self.cursor >= self.row_count - 1

    def summary(self, p: CapturedPacket) -> tuple[str, bool]:
        cached = self._summaries.get(p.seq)
        if cached is None:
            a = Annotation(p.kind, p.data)
            cached = (summarize(p.kind, p.data, a), a.error is not None)
            self._summaries[p.seq] = cached
            if len(self._summaries) > 4096:
                self._summaries.popitem(last=False)
        return cached

    def render_row(self, row: int, width: int, base: Style) -> Text:
        if row >= len(self.source):  # the ring moved on since the row count was set
            return Text("", style=base)
        p = self.source[row]
        summary, bad = self.summary(p)
        text = Text(style=base, no_wrap=True)
        text.append(f"{p.time - self.t0:9.3f} ")
        text.append("out" if p.direction == "out" else " in",
                    style="bold" if p.direction == "out" else "")
        text.append(f" {len(p.data):5d}  ")
        text.append(summary, style=self.get_component_rich_style("linelist--error") if bad else "")
        return text


class FieldList(LineList):
    """The spans of the selected packet."""

    def __init__(self, *, id: str | None = None) -> None:
        super().__init__(id=id)
        self.annotation: Annotation | None = None

    def set_annotation(self, annotation: Annotation | None, span: int = 0) -> None:
        self.annotation = annotation
        self.set_row_count(len(annotation.spans) if annotation else 0)
        self.move_cursor(span, notify=False)

    def render_row(self, row: int, width: int, base: Style) -> Text:
        assert self.annotation is not None
        s = self.annotation.spans[row]
        text = Text(style=base, no_wrap=True)
        text.append(f"{s.offset:4d} {s.length:3d} ", style=self.get_component_rich_style("linelist--dim"))
        style = self.get_component_rich_style("linelist--error") if s.field == UNDECODABLE else ""
        text.append(f"{s.field}", style=style or "bold")
        text.append(f" = {_value_text(s.value)}", style=style)
        return text


class HexView(ScrollView, can_focus=True):
    """A hex dump with every field coloured and the cursor's field highlighted."""

    BINDINGS = [
        Binding("left", "move(-1)", "Byte left", show=False),
        Binding("right", "move(1)", "Byte right", show=False),
        Binding("up", "move_row(-1)", "Row up", show=False),
        Binding("down", "move_row(1)", "Row down", show=False),
        Binding("home", "edge(0)", "First byte", show=False),
        Binding("end", "edge(1)", "Last byte", show=False),
    ]
    COMPONENT_CLASSES = {"hex--offset", "hex--field-a", "hex--field-b", "hex--span", "hex--cursor",
                         "hex--error", "hex--ascii"}
    DEFAULT_CSS = """
    HexView { background: $surface; overflow-x: hidden; }
    HexView > .hex--offset { color: $text-muted; }
    HexView > .hex--field-a { color: $foreground; }
    HexView > .hex--field-b { color: $secondary-lighten-2; }
    HexView.-light > .hex--field-b { color: $secondary-darken-1; }
    HexView > .hex--span { background: $primary 45%; }
    HexView > .hex--cursor { background: $accent; color: $background; text-style: bold; }
    HexView > .hex--error { color: $error; text-style: bold reverse; }
    HexView > .hex--ascii { color: $text-muted; }
    """

    class CursorMoved(Message):
        def __init__(self, widget: "HexView", byte: int) -> None:
            super().__init__()
            self.widget = widget
            self.byte = byte

        @property
        def control(self) -> "HexView":
            return self.widget

    def __init__(self, *, id: str | None = None) -> None:
        super().__init__(id=id)
        self.data = b""
        self.annotation: Annotation | None = None
        self.cursor = 0

    @property
    def per_row(self) -> int:
        return 16 if self.scrollable_content_region.width >= 74 or not self.is_mounted else 8

    def set_packet(self, data: bytes, annotation: Annotation | None) -> None:
        self.data = data
        self.annotation = annotation
        self.cursor = min(self.cursor, max(0, len(data) - 1))
        self._resize()

    def _resize(self) -> None:
        rows = math.ceil(len(self.data) / self.per_row) if self.data else 0
        self.virtual_size = Size(max(1, self.size.width), rows)
        self.refresh()

    def on_resize(self) -> None:
        self._resize()

    def move_to(self, byte: int, *, notify: bool = True) -> None:
        if not self.data:
            return
        self.cursor = max(0, min(byte, len(self.data) - 1))
        self._scroll_to_cursor()
        self.call_after_refresh(self._scroll_to_cursor)
        self.refresh()
        if notify:
            self.post_message(self.CursorMoved(self, self.cursor))

    def _scroll_to_cursor(self) -> None:
        row = self.cursor // self.per_row
        height = max(1, self.scrollable_content_region.height)
        top = int(self.scroll_offset.y)
        if row < top:
            self.scroll_to(y=row, animate=False, immediate=True)
        elif row >= top + height:
            self.scroll_to(y=row - height + 1, animate=False, immediate=True)

    def action_move(self, delta: int) -> None:
        self.move_to(self.cursor + delta)

    def action_move_row(self, delta: int) -> None:
        self.move_to(self.cursor + delta * self.per_row)

    def action_edge(self, end: int) -> None:
        self.move_to(len(self.data) - 1 if end else 0)

    def on_click(self, event) -> None:
        per_row = self.per_row
        row = int(self.scroll_offset.y) + event.y
        x = event.x - 6
        if x < 0:
            return
        col = x // 3 if x < 3 * 8 else (x - 1) // 3
        if 0 <= col < per_row:
            self.move_to(row * per_row + col)

    def render_line(self, y: int) -> Strip:
        width = self.scrollable_content_region.width
        base = self.rich_style
        per_row = self.per_row
        row = int(self.scroll_offset.y) + y
        start = row * per_row
        data = self.data
        if start >= len(data) or width <= 0:
            return Strip.blank(width, base)
        a = self.annotation
        styles = {name: self.get_component_rich_style(name) for name in self.COMPONENT_CLASSES}
        cursor_span = a.span_at(self.cursor) if a else -1
        segments = [Segment(f"{start:04x}  ", base + styles["hex--offset"])]
        ascii_parts = []
        for i in range(start, min(start + per_row, len(data))):
            span = a.span_at(i) if a else 0
            if a and a.is_bad(span):
                style = base + styles["hex--error"]
            else:
                style = base + styles["hex--field-b" if span % 2 else "hex--field-a"]
            if span == cursor_span:
                style += styles["hex--span"]
            if i == self.cursor:
                style += styles["hex--cursor"]
            segments.append(Segment(f"{data[i]:02x}", style))
            gap = "  " if (i - start) == 7 else " "
            segments.append(Segment(gap, base))
            ch = chr(data[i]) if 32 <= data[i] < 127 else "."
            ascii_parts.append(Segment(ch, style if span == cursor_span else base + styles["hex--ascii"]))
        used = 6 + 3 * per_row + 1
        drawn = sum(s.cell_length for s in segments)
        if drawn < used:
            segments.append(Segment(" " * (used - drawn), base))
        segments.append(Segment(" ", base))
        segments.extend(ascii_parts)
        return Strip(segments).crop(0, width).adjust_cell_length(width, base)


class InfoLine(Widget):
    """A fixed-height line of text. Unlike a Static, changing it repaints only itself: at
    10 Hz a Static's layout pass would re-lay the whole screen."""

    def __init__(self, text: str | Text = "", *, id: str | None = None) -> None:
        super().__init__(id=id)
        self._text: str | Text = text

    def update(self, text: str | Text) -> None:
        if text != self._text:
            self._text = text
            self.refresh()

    def render(self) -> str | Text:
        return self._text


# -- asking for a path -----------------------------------------------------------------------
class PathPrompt(ModalScreen[str | None]):
    """Where to write a pcap file. Ctrl+S accepts, Escape cancels. (Enter is the app's
    disable key everywhere, so it cannot be the one that accepts.)"""

    DEFAULT_CSS = """
    PathPrompt { align: center middle; }
    PathPrompt > Vertical { width: 80; height: auto; border: thick $primary; padding: 1 2; background: $surface; }
    PathPrompt Label { width: 100%; }
    """
    BINDINGS = [Binding("escape", "cancel", "Cancel"), Binding("ctrl+s", "accept", "Write here", priority=True)]

    def __init__(self, title: str, default: str) -> None:
        super().__init__()
        self.title_text = title
        self.default = default

    def compose(self) -> ComposeResult:
        with Vertical():
            yield Label(f"[b]{self.title_text}[/b]")
            yield Input(self.default, id="pcap-path")
            yield Label("ctrl+s: write here   escape: cancel", classes="hint")

    def on_mount(self) -> None:
        field = self.query_one(Input)
        field.cursor_blink = False
        field.focus()

    @on(Input.Submitted)
    def action_accept(self) -> None:
        value = self.query_one(Input).value.strip()
        self.dismiss(str(Path(value).expanduser()) if value else None)

    def action_cancel(self) -> None:
        self.dismiss(None)


# -- the panel --------------------------------------------------------------------------------
class InspectorPanel(Panel):
    TITLE = "Inspector"
    ID = "inspector"
    #: The capture is drained while hidden too: a recording must lose nothing.
    ALWAYS_REFRESH = True

    BINDINGS = [
        Binding("p", "pause", "Pause/resume"),
        Binding("r", "record", "Record pcap"),
        Binding("R", "record_to", "Record to…", show=False),
        Binding("x", "export", "Export pcap"),
        Binding("X", "export_to", "Export to…", show=False),
        Binding("c", "clear", "Clear"),
        Binding("left_square_bracket", "field(-1)", "Prev field", show=False),
        Binding("right_square_bracket", "field(1)", "Next field", show=False),
    ]

    DEFAULT_CSS = """
    InspectorPanel { layout: vertical; }
    InspectorPanel #inspector-top { height: 1fr; min-height: 6; }
    InspectorPanel #inspector-bottom { height: 1fr; min-height: 6; }
    InspectorPanel .pane { border: round $primary 50%; border-title-color: $text; }
    InspectorPanel .pane:focus, InspectorPanel .pane:focus-within { border: round $accent; }
    InspectorPanel #inspector-links { width: 38; text-wrap: nowrap; text-overflow: ellipsis; }
    InspectorPanel #inspector-packets { width: 1fr; }
    InspectorPanel #inspector-hex { width: 78; }
    InspectorPanel.-narrow #inspector-hex { width: 46; }
    InspectorPanel.-narrow #inspector-links { width: 28; }
    InspectorPanel #inspector-fields { width: 1fr; }
    InspectorPanel #inspector-meaning { height: 2; padding: 0 1; background: $boost; }
    InspectorPanel #inspector-meaning.-bad { color: $error; }
    InspectorPanel #inspector-state { height: 1; padding: 0 1; color: $text-muted; }
    InspectorPanel #inspector-state.-paused { color: $warning; text-style: bold; }
    """

    def __init__(self, *, id: str | None = None, ring: CaptureRing | None = None) -> None:
        super().__init__(id=id)
        self.ring = ring or CaptureRing()
        self.attached: Any = None
        self.endpoints: Endpoints | None = None
        self.clock_offset = 0.0
        self.t0 = 0.0
        self.recorder: Recorder | None = None
        self.paused = False
        self.link: LinkKey | None = None
        self._paused_counts: dict[LinkKey, int] = {}
        self._paused_total = 0
        self._annotations: OrderedDict[int, Annotation] = OrderedDict()
        self._shown_seq: int | None = None
        self._state_text = ""

    # -- layout ----------------------------------------------------------------------------
    def compose(self) -> ComposeResult:
        with Horizontal(id="inspector-top"):
            links = LinkList(id="inspector-links")
            links.border_title = "Links"
            links.add_class("pane")
            yield links
            packets = PacketList(id="inspector-packets")
            packets.border_title = "Packets"
            packets.add_class("pane")
            yield packets
        with Horizontal(id="inspector-bottom"):
            hexview = HexView(id="inspector-hex")
            hexview.border_title = "Bytes"
            hexview.add_class("pane")
            yield hexview
            fields = FieldList(id="inspector-fields")
            fields.border_title = "Fields"
            fields.add_class("pane")
            yield fields
        yield InfoLine(NO_PACKET, id="inspector-meaning")
        yield InfoLine("", id="inspector-state")

    def on_mount(self) -> None:
        self.packets.border_subtitle = "time  dir  size  summary"
        self.packets.t0 = self.t0
        if self.app.current_theme is not None and not self.app.current_theme.dark:
            self.hexview.add_class("-light")
        self.app.theme_changed_signal.subscribe(self, self._theme_changed)

    def _theme_changed(self, theme) -> None:
        self.hexview.set_class(not theme.dark, "-light")

    def on_resize(self) -> None:
        # Below ~110 columns the hex dump goes to 8 bytes a row so the field list keeps room.
        self.set_class(self.size.width < 110, "-narrow")

    def on_show(self) -> None:
        focused = self.app.focused
        if focused is None or self not in focused.ancestors:
            self.call_after_refresh(self.packets.focus)

    @property
    def packets(self) -> PacketList:
        return self.query_one("#inspector-packets", PacketList)

    @property
    def hexview(self) -> HexView:
        return self.query_one("#inspector-hex", HexView)

    @property
    def fields(self) -> FieldList:
        return self.query_one("#inspector-fields", FieldList)

    @property
    def links(self) -> LinkList:
        return self.query_one("#inspector-links", LinkList)

    # -- the engine ------------------------------------------------------------------------
    def engine_changed(self, engine: "Engine") -> None:
        self.attach(engine)

    def attach(self, engine: "Engine") -> None:
        if engine is self.attached:
            return
        old = self.attached
        if old is not None:
            try:
                old.remove_tap(self.ring.tap)
            except Exception:  # noqa: BLE001 - a stopped engine
                pass
        self.ring.clear()
        self._annotations.clear()
        self.attached = engine
        self.endpoints = Endpoints(engine)
        self.clock_offset = clock_offset_for(engine)
        if self.recorder is not None:
            self.recorder.writer.endpoints = self.endpoints
            self.recorder.writer.clock_offset = self.clock_offset
        self.link = None
        self.t0 = engine.now()
        if self.is_mounted:
            self.packets.t0 = self.t0
            self.packets.set_source(())
            self.links.update_links([])
            self._show(None)
        engine.add_tap(self.ring.tap)

    def on_unmount(self) -> None:
        if self.recorder is not None:
            self._stop_recording()

    # -- the 10 Hz refresh -----------------------------------------------------------------
    def refresh_view(self, engine: "Engine", now: float) -> None:
        if engine is not self.attached:
            self.attach(engine)
        new = self.drain()
        if not self.display or not self._tab_visible:
            return
        if len(self.ring.links) != len(self.links.keys):
            self.links.update_links(sort_links(self.ring.links, link_order(engine)))
        keys = self.links.keys
        if self.link is None and keys:
            self.select_link(_default_link(keys))
        if not self.paused and new and self.link is not None:
            self.packets.grew()  # new rows, or old ones pushed out by other links' traffic
        self._update_state()

    @property
    def _tab_visible(self) -> bool:
        try:
            return self.app.screen_stack[0].query_one("TabbedContent").active == self.ID  # type: ignore[attr-defined]
        except Exception:  # noqa: BLE001
            return True

    def drain(self) -> list[CapturedPacket]:
        """File the tapped packets; feed the recording (written and flushed at once)."""
        new = self.ring.drain()
        if new and self.recorder is not None:
            try:
                self.recorder.feed(new)
            except OSError as exc:
                path = self.recorder.path
                self.recorder = None
                self.notify(f"recording to {path} stopped: {exc}", severity="error", timeout=10)
        return new

    # -- selection -------------------------------------------------------------------------
    def select_link(self, key: LinkKey) -> None:
        if key == self.link:
            return
        self.link = key
        links = self.links
        if key in links.keys and links.highlighted != links.keys.index(key):
            links.highlighted = links.keys.index(key)
        ring = self.ring.links.get(key, deque())
        self.packets.follow = True
        self.packets.set_source(list(ring) if self.paused else ring)
        self.packets.border_title = f"Packets · {link_label(key)}"
        self._show(self.packets.selected())

    @on(OptionList.OptionHighlighted, "#inspector-links")
    def _link_highlighted(self, event: OptionList.OptionHighlighted) -> None:
        keys = self.links.keys
        if 0 <= event.option_index < len(keys):
            self.select_link(keys[event.option_index])

    @on(LineList.CursorMoved, "#inspector-packets")
    def _packet_moved(self, event: LineList.CursorMoved) -> None:
        self._show(self.packets.selected())

    @on(HexView.CursorMoved)
    def _byte_moved(self, event: HexView.CursorMoved) -> None:
        a = self.hexview.annotation
        if a is not None:
            self.fields.move_cursor(a.span_at(event.byte), notify=False)
        self._explain()

    @on(LineList.CursorMoved, "#inspector-fields")
    def _field_moved(self, event: LineList.CursorMoved) -> None:
        a = self.fields.annotation
        if a is not None and 0 <= event.row < len(a.spans):
            self.hexview.move_to(a.spans[event.row].offset, notify=False)
        self._explain()

    def action_field(self, delta: int) -> None:
        a = self.hexview.annotation
        if a is None or not a.spans:
            return
        span = max(0, min(a.span_at(self.hexview.cursor) + delta, len(a.spans) - 1))
        self.hexview.move_to(a.spans[span].offset)

    def annotation_for(self, p: CapturedPacket) -> Annotation:
        a = self._annotations.get(p.seq)
        if a is None:
            a = self._annotations[p.seq] = Annotation(p.kind, p.data)
            if len(self._annotations) > 256:
                self._annotations.popitem(last=False)
        return a

    def _show(self, p: CapturedPacket | None) -> None:
        """Show a packet in the hex view and field list, keeping the cursor's byte offset."""
        if p is not None and p.seq == self._shown_seq:
            return
        self._shown_seq = p.seq if p is not None else None
        hexview = self.hexview
        if p is None:
            hexview.set_packet(b"", None)
            self.fields.set_annotation(None)
            hexview.border_title = "Bytes"
            self._explain()
            return
        a = self.annotation_for(p)
        hexview.set_packet(p.data, a)
        hexview.border_title = f"Bytes · {len(p.data)} bytes at {p.time - self.packets.t0:.3f} s"
        self.fields.set_annotation(a, a.span_at(hexview.cursor))
        self._explain()

    def _explain(self) -> None:
        meaning = self.query_one("#inspector-meaning", InfoLine)
        a = self.hexview.annotation
        if a is None or not a.spans:
            meaning.update(NO_PACKET)
            meaning.remove_class("-bad")
            return
        s = a.spans[a.span_at(self.hexview.cursor)]
        where = f"byte {s.offset}" if s.length == 1 else f"bytes {s.offset}-{s.offset + s.length - 1}"
        text = Text()
        text.append(f"{where}  ", style="dim")
        text.append(s.field, style="bold")
        text.append(f" = {_value_text(s.value)}  ")
        text.append(s.meaning)
        meaning.update(text)
        meaning.set_class(s.field == UNDECODABLE, "-bad")

    # -- pause -------------------------------------------------------------------------------
    def action_pause(self) -> None:
        self.paused = not self.paused
        packets = self.packets
        if self.paused:
            self._paused_counts = dict(self.ring.counts)
            self._paused_total = self.ring.seq
            packets.set_source(list(packets.source), keep_index=self._cursor_index())
        else:
            ring = self.ring.links.get(self.link, deque()) if self.link else deque()
            packets.set_source(ring, keep_index=self._cursor_index())
        self._update_state()

    def _cursor_index(self) -> int | None:
        p = self.packets.selected()
        return p.index if p is not None else None

    def new_since_pause(self) -> tuple[int, int]:
        """(new packets on the shown link, new packets in all) since the view was paused."""
        if not self.paused:
            return 0, 0
        on_link = self.ring.counts.get(self.link, 0) - self._paused_counts.get(self.link, 0) if self.link else 0
        return on_link, self.ring.seq - self._paused_total

    def _update_state(self) -> None:
        parts = []
        if self.paused:
            on_link, total = self.new_since_pause()
            parts.append(f"PAUSED: {on_link:,} new on this link, {total:,} in all (p resumes)")
        else:
            parts.append("LIVE" if self.packets.follow else "LIVE, holding a packet (End follows)")
        parts.append(f"{len(self.ring):,} packets held")
        if self.ring.overflowed:
            parts.append(f"{self.ring.overflowed:,} lost to a full queue")
        if self.recorder is not None:
            parts.append(f"● REC {self.recorder.writer.written:,} → {self.recorder.path}")
        text = "   ".join(parts)
        if text != self._state_text:
            self._state_text = text
            state = self.query_one("#inspector-state", InfoLine)
            state.update(text)
            state.set_class(self.paused, "-paused")

    # -- pcap --------------------------------------------------------------------------------
    def action_record(self) -> None:
        if self.recorder is not None:
            self._stop_recording()
        else:
            self.start_recording(default_capture_path("fieldbox-rec"))

    def action_record_to(self) -> None:
        if self.recorder is not None:
            self._stop_recording()
            return
        self.app.push_screen(PathPrompt("Record packets to", str(default_capture_path("fieldbox-rec"))),
                             lambda path: path and self.start_recording(path))

    def start_recording(self, path: str | Path) -> bool:
        if self.endpoints is None:
            return False
        try:
            self.recorder = Recorder.start(path, self.endpoints, self.clock_offset)
        except OSError as exc:
            self.notify(f"cannot record to {path}: {exc.strerror or exc}", severity="error", timeout=10)
            return False
        self.notify(f"recording every packet to {path}", timeout=5)
        self._update_state()
        return True

    def _stop_recording(self) -> None:
        recorder, self.recorder = self.recorder, None
        if recorder is None:
            return
        try:
            self.drain_into(recorder)
            written = recorder.stop()
        except OSError as exc:
            self.notify(f"recording to {recorder.path} failed: {exc}", severity="error")
            return
        if self.is_attached:
            self.notify(f"recorded {written:,} packets to {recorder.path}", timeout=8)
            self._update_state()

    def drain_into(self, recorder: Recorder) -> None:
        new = self.ring.drain()
        if new:
            recorder.feed(new)

    def action_export(self) -> None:
        self.export(default_capture_path("fieldbox"))

    def action_export_to(self) -> None:
        self.app.push_screen(PathPrompt("Export the capture to", str(default_capture_path("fieldbox"))),
                             lambda path: path and self.export(path))

    def export(self, path: str | Path) -> int | None:
        """Write the whole ring (every link) as a pcap; returns the packets written."""
        if self.endpoints is None:
            return None
        self.drain()
        try:
            n = write_pcap(path, self.ring.packets(), self.endpoints, self.clock_offset)
        except OSError as exc:
            self.notify(f"cannot write {path}: {exc.strerror or exc}", severity="error", timeout=10)
            return None
        self.notify(f"wrote {n:,} packets to {path}", timeout=8)
        return n

    def action_clear(self) -> None:
        self.drain()
        self.ring.clear()
        self._annotations.clear()
        link, self.link = self.link, None
        self.packets.set_source(())
        self._show(None)
        if link is not None:
            self.link = link
            self.packets.set_source(self.ring.links.setdefault(link, deque()) if not self.paused else [])
            self.ring.counts.setdefault(link, 0)
        self._paused_counts = {}
        self._paused_total = 0
        self._update_state()


def _default_link(keys: list[LinkKey]) -> LinkKey:
    """A DS's control packets if there are any: the packet everyone asks about first."""
    for kind in ("ds-to-rio", "legacy-ds-to-robot"):
        for key in keys:
            if key[0].startswith("ds") and key[2] == "out" and key[3] == kind:
                return key
    return keys[0]
