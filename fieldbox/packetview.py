"""The packet inspector's panes, drawn with Textual's Line API (only the rows on screen are
drawn; a row's strip is kept while what it shows does not change).

* :class:`LineList`: rows drawn on demand with a cursor, the base of the two lists below;
* :class:`LinkList`: every (role, link, direction, kind) the taps have seen
  (:func:`sort_links` orders them as a person reads the field, :func:`default_link` picks
  the one shown first);
* :class:`PacketList`: the packets of one link, newest at the bottom, following the wire
  while the cursor is on the last row;
* :class:`FieldList`: the spans of the selected packet;
* :class:`HexView`: the packet's bytes, each field in its own colour.
"""

from __future__ import annotations

import math
from collections import OrderedDict
from contextlib import contextmanager
from typing import Any, Iterator, Sequence

from rich.segment import Segment
from rich.style import Style
from rich.text import Text
from textual.binding import Binding
from textual.message import Message
from textual.scroll_view import ScrollView
from textual.strip import Strip
from textual.widgets import OptionList
from textual.widgets.option_list import Option

from .capture import CapturedPacket, LinkKey, is_tcp_kind
from .packet_text import Annotation, summarize, value_text
from .textual_fixes import set_virtual_rows


#: Packet summaries a list keeps (rows drawn lately; a screen shows a few dozen). There were
#: 4096: with the inspector shown one second in seven they took ten minutes to fill (about
#: 1.2 MB), the lines on top of the app's traced growth in the second half of
#: benchmarks/memory.py (``--trace``: fieldbox/packet_text.py and this module's summary).
SUMMARIES = 512


def _frame_of(view: ScrollView) -> tuple[int, Style, int]:
    """What every row of one frame shares: the width, the base style, the top row."""
    return view.scrollable_content_region.width, view.rich_style, int(view.scroll_offset.y)


@contextmanager
def frame_constants(view: ScrollView) -> Iterator[None]:
    """While a view draws a frame, ``view._frame`` holds :func:`_frame_of` (computing the
    base style walks the DOM: done for every row, it was half of the time the rows took)."""
    view._frame = _frame_of(view)  # type: ignore[attr-defined]  # the views that draw with it declare it
    try:
        yield
    finally:
        view._frame = None  # type: ignore[attr-defined]


def changed_bytes(before: bytes, after: bytes) -> frozenset[int]:
    """Offsets of ``after`` that differ from ``before`` (bytes past its end count as changed)."""
    return frozenset(i for i, b in enumerate(after) if i >= len(before) or before[i] != b)


def bytes_per_row(width: int) -> int:
    """The hex view's bytes a row: 16 where they fit, else 8."""
    return 16 if width >= 74 else 8


def scroll_row_into_view(view: ScrollView, row: int) -> None:
    """Scroll ``view`` (one line per row) just enough that ``row`` is on screen."""
    height = max(1, view.scrollable_content_region.height)
    top = int(view.scroll_offset.y)
    if row < top:
        view.scroll_to(y=row, animate=False, immediate=True)
    elif row >= top + height:
        view.scroll_to(y=row - height + 1, animate=False, immediate=True)


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
        self._frame: tuple[int, Style, int] | None = None

    # subclasses
    def render_row(self, row: int, width: int, base: Style) -> Text:
        return Text("")

    # the row count and the cursor
    @property
    def row_count(self) -> int:
        return self._rows

    def set_row_count(self, rows: int) -> None:
        self._rows = rows
        set_virtual_rows(self, rows)
        self.refresh()

    def move_cursor(self, row: int, *, notify: bool = True, scroll: bool = True) -> None:
        row = max(0, min(row, self._rows - 1)) if self._rows else 0
        self.cursor = row
        if scroll:
            self.scroll_to_row(row)
            # Rows that made a scrollbar appear just now change the list's size only at the
            # next layout: scroll again once it is done.
            self.call_after_refresh(self._scroll_to_cursor)
        self.refresh()
        if notify:
            self.post_message(self.CursorMoved(self, row))

    def _scroll_to_cursor(self) -> None:
        self.scroll_to_row(self.cursor)

    def scroll_to_row(self, row: int) -> None:
        scroll_row_into_view(self, row)

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

    def render_lines(self, crop):
        with frame_constants(self):
            return super().render_lines(crop)

    def render_line(self, y: int) -> Strip:
        width, base, top = self._frame or _frame_of(self)
        row = top + y
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


def default_link(keys: list[LinkKey]) -> LinkKey:
    """A DS's control packets if there are any: the packet everyone asks about first."""
    for kind in ("ds-to-rio", "legacy-ds-to-robot"):
        for key in keys:
            if key[0].startswith("ds") and key[2] == "out" and key[3] == kind:
                return key
    return keys[0]


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
            cached = (summarize(p.kind, p.data, a), a.bad)
            self._summaries[p.seq] = cached
            if len(self._summaries) > SUMMARIES:
                self._summaries.popitem(last=False)
        return cached

    def render_row(self, row: int, width: int, base: Style) -> Text:
        if row >= len(self.source):  # the ring moved on since the row count was set
            return Text("", style=base)
        p = self.source[row]
        summary, bad = self.summary(p)
        if not bad and not is_tcp_kind(p.kind):
            # A UDP link carries one message, named in the pane's title: the row's width goes to
            # what the packet says (at 160 columns a control packet's station was cut). So does
            # the direction's, which is the link's.
            name, _, rest = summary.partition(" ")
            summary = rest if rest.startswith("#") else summary
        text = Text(style=base, no_wrap=True)
        text.append(f"{p.time - self.t0:9.3f} ")
        text.append(f"{len(p.data):5d}  ")
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
        style = self.get_component_rich_style("linelist--error") if self.annotation.is_bad(row) else ""
        text.append(f"{s.field}", style=style or "bold")
        text.append(f" = {value_text(s.value)}", style=style)
        return text


class HexView(ScrollView, can_focus=True):
    """A hex dump with every field coloured and the cursor's field highlighted. Given the
    link's previous packet, the bytes that changed since are underlined: what the DS or the
    robot just did, at a glance (a teacher's "watch this byte")."""

    BINDINGS = [
        Binding("left", "move(-1)", "Byte left", show=False),
        Binding("right", "move(1)", "Byte right", show=False),
        Binding("up", "move_row(-1)", "Row up", show=False),
        Binding("down", "move_row(1)", "Row down", show=False),
        Binding("home", "edge(0)", "First byte", show=False),
        Binding("end", "edge(1)", "Last byte", show=False),
    ]
    COMPONENT_CLASSES = {"hex--offset", "hex--field-a", "hex--field-b", "hex--span", "hex--cursor",
                         "hex--error", "hex--ascii", "hex--changed"}
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
    HexView > .hex--changed { text-style: bold underline; }
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
        #: Offsets that differ from the link's previous packet (None: no previous to compare).
        self.changed: frozenset[int] | None = None
        self._frame: tuple[int, Style, int] | None = None
        self._styles: dict[str, Style] = {}

    @property
    def per_row(self) -> int:
        return bytes_per_row(self.scrollable_content_region.width) if self.is_mounted else 16

    def set_packet(self, data: bytes, annotation: Annotation | None, previous: bytes | None = None) -> None:
        self.data = data
        self.annotation = annotation
        self.changed = None if previous is None else changed_bytes(previous, data)
        self.cursor = min(self.cursor, max(0, len(data) - 1))
        self._resize()

    def _resize(self) -> None:
        rows = math.ceil(len(self.data) / self.per_row) if self.data else 0
        set_virtual_rows(self, rows)
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
        scroll_row_into_view(self, self.cursor // self.per_row)

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

    def render_lines(self, crop):
        with frame_constants(self):
            self._styles = self._hex_styles()
            return super().render_lines(crop)

    def _hex_styles(self) -> dict[str, Style]:
        return {name: self.get_component_rich_style(name) for name in self.COMPONENT_CLASSES}

    def render_line(self, y: int) -> Strip:
        width, base, top = self._frame or _frame_of(self)
        per_row = bytes_per_row(width)
        row = top + y
        start = row * per_row
        data = self.data
        if start >= len(data) or width <= 0:
            return Strip.blank(width, base)
        a = self.annotation
        styles = self._styles if self._frame else self._hex_styles()
        cursor_span = a.span_at(self.cursor) if a else -1
        changed = self.changed or ()
        segments = [Segment(f"{start:04x}  ", base + styles["hex--offset"])]
        ascii_parts = []
        for i in range(start, min(start + per_row, len(data))):
            span = a.span_at(i) if a else 0
            # The underline goes under the field's colours: a component style carries the
            # widget's default colours, which would cover an error's or a field's.
            style = base + styles["hex--changed"] if i in changed else base
            if a and a.is_bad(span):
                style += styles["hex--error"]
            else:
                style += styles["hex--field-b" if span % 2 else "hex--field-a"]
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
