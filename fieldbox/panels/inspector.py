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
recording loses nothing) and appends only the new rows. The pcap files are written by
``fieldbox/pcap.py``, the panes are in ``fieldbox/packetview.py``, what a packet says in
``fieldbox/packet_text.py``.
"""

from __future__ import annotations

import logging
from collections import OrderedDict, deque
from pathlib import Path
from typing import TYPE_CHECKING, Any

from rich.text import Text
from textual import on
from textual.app import ComposeResult
from textual.binding import Binding
from textual.containers import Horizontal
from textual.widget import Widget
from textual.widgets import OptionList

from ..capture import CapturedPacket, CaptureRing, Endpoints, LinkKey, link_label
from ..packet_text import Annotation, value_text
from ..packetview import FieldList, HexView, LineList, LinkList, PacketList, default_link, link_order, sort_links
from ..pcap import Recorder, clock_offset_for, default_capture_dir, default_capture_path, write_pcap
from ..serve import tab_allows_path
from ..widgets import InfoLine, PathPrompt
from .base import Panel, engine_of

if TYPE_CHECKING:
    from roles.runtime.engine import Engine

log = logging.getLogger("fieldbox.inspector")

#: Packets whose decode (the field list's spans) is kept, the latest looked at: enough to
#: move the cursor back and forth over a screen of rows. Each is about 20 kB (a six-joystick
#: control packet: 86 spans) and takes 0.3-0.4 ms to make again; 256 of them were 5 MB.
ANNOTATIONS_KEPT = 64

NO_PACKET = "No packet selected: the links appear as soon as packets cross the wire."


class InspectorPanel(Panel):
    TITLE = "Inspector"
    SHORT_TITLE = "Insp"
    ID = "inspector"
    REFRESH_TICKS = 2
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
        self.ring_total = self.ring.total
        self.tapping = False
        self._readers: set[str] | None = None  # ids of the panels that read the capture
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
            yield _pane(LinkList(id="inspector-links"), "Links")
            yield _pane(PacketList(id="inspector-packets"), "Packets")
        with Horizontal(id="inspector-bottom"):
            yield _pane(HexView(id="inspector-hex"), "Bytes")
            yield _pane(FieldList(id="inspector-fields"), "Fields")
        yield InfoLine(NO_PACKET, id="inspector-meaning")
        yield InfoLine("", id="inspector-state")

    def on_mount(self) -> None:
        self.packets.border_subtitle = "time  size  summary"
        self.packets.t0 = self.t0
        if self.app.current_theme is not None and not self.app.current_theme.dark:
            self.hexview.add_class("-light")
        self.app.theme_changed_signal.subscribe(self, self._theme_changed)

    def _theme_changed(self, theme) -> None:
        self.hexview.set_class(not theme.dark, "-light")

    def on_resize(self) -> None:
        # Below ~110 columns the hex dump goes to 8 bytes a row so the field list keeps room.
        self.set_class(self.size.width < 110, "-narrow")

    def take_focus(self) -> None:
        self.packets.focus()

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
        if old is not None and self.tapping:
            try:
                old.remove_tap(self.ring.tap)
            except Exception:  # noqa: BLE001 - a stopped engine
                pass
        self.tapping = False
        self.ring.clear()
        # A classroom's tab keeps fewer packets (roles/runtime/classroom.py: memory per tab).
        self.ring.total = getattr(engine, "capture_total", None) or self.ring_total
        self._annotations.clear()
        self.attached = engine
        self.endpoints = Endpoints()
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
        self._tap(engine, not getattr(engine, "capture_when_shown", False))

    def _reader_shown(self) -> bool:
        """Whether the tab shown reads this capture (the timeline, diagnostics)."""
        if self._readers is None:
            self._readers = {p.ID for p in self.app.query(Panel) if p.READS_CAPTURE}
        return self.shown_tab() in self._readers

    def _tap(self, engine: "Engine", wanted: bool) -> None:
        """Capture or stop. A classroom's driver or observer captures only while its Inspector
        is shown or recording, and keeps what it captured only while shown or paused
        (roles/runtime/classroom.py: thirty tabs' memory and CPU)."""
        if wanted and not self.tapping:
            engine.add_tap(self.ring.tap)
        elif self.tapping and not wanted:
            engine.remove_tap(self.ring.tap)
        self.tapping = wanted

    def on_unmount(self) -> None:
        if self.recorder is not None:
            self._stop_recording(closing=True)  # the app is closing: its widgets are going

    # -- the 10 Hz refresh -----------------------------------------------------------------
    def refresh_view(self, engine: "Engine", now: float) -> None:
        engine = engine_of(engine)  # taps are the engine's own
        if engine is not self.attached:
            self.attach(engine)
        if getattr(engine, "capture_when_shown", False):
            wanted = (self.display and self.tab_shown) or self._reader_shown() or self.recorder is not None
            if not wanted and not self.paused and (self.ring.pending() or any(self.ring.links.values())):
                self.action_clear()  # a hidden tab's packets cost thirty tabs' memory; paused ones stay
            self._tap(engine, wanted)
        new = self.drain()
        if not self.display or not self.tab_shown:
            return
        if len(self.ring.links) != len(self.links.keys):
            self.links.update_links(sort_links(self.ring.links, link_order(engine)))
        keys = self.links.keys
        if self.link is None and keys:
            self.select_link(default_link(keys))
        # new rows; or rows filed while the tab was hidden (its list was not told then)
        if not self.paused and self.link is not None and (new or self.packets.row_count != len(self.packets.source)):
            self.packets.grew()  # new rows, or old ones pushed out by other links' traffic
            # the packet followed, shown now rather than when the cursor's message arrives:
            # the panes are then drawn in the same frame as the list, not in a second one
            self._show(self.packets.selected())
        self._update_state()

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
        self.packets.border_title = f"Packets · {link_label(key)}{_message_name(key)}"
        self._show(self.packets.selected())

    def show_packet(self, packet: CapturedPacket) -> bool:
        """Select ``packet`` (its link, then its row), as the timeline's ``i`` asks; False if
        the ring no longer holds it."""
        keys = self.links.keys
        if packet.key not in keys:
            self.links.update_links(sort_links(self.ring.links, link_order(self.attached)))
        self.select_link(packet.key)
        if not self.paused:
            self.packets.grew()  # the rows filed while another tab was shown (the timeline's i)
        source = self.packets.source
        if not source or not source[0].index <= packet.index <= source[-1].index:
            self.notify("that packet is no longer held: the capture moved on", severity="warning")
            return False
        self.packets.move_cursor(packet.index - source[0].index)
        self._show(self.packets.selected())
        self.packets.focus()
        return True

    @on(OptionList.OptionHighlighted, "#inspector-links")
    def _link_highlighted(self, event: OptionList.OptionHighlighted) -> None:
        keys = self.links.keys
        # A message that comes after the highlight moved on (two packets shown in quick
        # succession, a replay's steps) is late: acting on it took the list back a link.
        if 0 <= event.option_index < len(keys) and event.option_index == self.links.highlighted:
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
        if a is not None:
            self._annotations.move_to_end(p.seq)  # the latest looked at are kept
        else:
            a = self._annotations[p.seq] = Annotation(p.kind, p.data)
            if len(self._annotations) > ANNOTATIONS_KEPT:
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
        before = self.ring.previous(p)
        hexview.set_packet(p.data, a, before.data if before is not None else None)
        changed = hexview.changed
        note = "" if changed is None else f" · {len(changed)} changed (underlined)"
        hexview.border_title = f"Bytes · {len(p.data)} bytes at {p.time - self.packets.t0:.3f} s{note}"
        self.fields.set_annotation(a, a.span_at(hexview.cursor))
        self._explain()

    def _explain(self) -> None:
        meaning = self.query_one("#inspector-meaning", InfoLine)
        a = self.hexview.annotation
        if a is None or not a.spans:
            meaning.update(NO_PACKET)
            meaning.remove_class("-bad")
            return
        index = a.span_at(self.hexview.cursor)
        s = a.spans[index]
        where = f"byte {s.offset}" if s.length == 1 else f"bytes {s.offset}-{s.offset + s.length - 1}"
        text = Text()
        text.append(f"{where}  ", style="dim")
        text.append(s.field, style="bold")
        text.append(f" = {value_text(s.value)}  ")
        text.append(s.meaning)
        meaning.update(text)
        meaning.set_class(a.is_bad(index), "-bad")

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
            live = getattr(self.attached, "follow_word", "LIVE")  # a replay's is REPLAY (fieldbox/replay.py)
            parts.append(live if self.packets.follow else f"{live}, holding a packet (End follows)")
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
        def chosen(path: str | None) -> None:
            if path:  # None or "": cancelled
                self.start_recording(path)

        self.app.push_screen(PathPrompt("Record packets to", str(default_capture_path("fieldbox-rec"))), chosen)

    def _may_write(self, path: str | Path) -> bool:
        """In a browser tab (fieldbox serve) only the capture folder is written: a tab must
        not put files where the server loads code from."""
        if tab_allows_path(path, default_capture_dir()):
            return True
        self.notify(f"in a browser tab, captures go to the server's capture folder only "
                    f"({default_capture_dir()})", severity="warning", timeout=10)
        return False

    def start_recording(self, path: str | Path) -> bool:
        if self.endpoints is None or not self._may_write(path):
            return False
        try:
            self.recorder = Recorder.start(path, self.endpoints, self.clock_offset)
        except OSError as exc:
            self.notify(f"cannot record to {path}: {exc.strerror or exc}", severity="error", timeout=10)
            return False
        self.notify(f"recording every packet to {path}", timeout=5)
        self._update_state()
        return True

    def _stop_recording(self, closing: bool = False) -> None:
        recorder, self.recorder = self.recorder, None
        if recorder is None:
            return
        try:
            self.drain_into(recorder)
            written = recorder.stop()
        except OSError as exc:
            self.notify(f"recording to {recorder.path} failed: {exc}", severity="error")
            return
        if self.is_attached and not closing:
            self.notify(f"recorded {written:,} packets to {recorder.path}", timeout=8)
            self._update_state()

    def drain_into(self, recorder: Recorder) -> None:
        new = self.ring.drain()
        if new:
            recorder.feed(new)

    def action_export(self) -> None:
        self.export(default_capture_path("fieldbox"))

    def action_export_to(self) -> None:
        def chosen(path: str | None) -> None:
            if path:  # None or "": cancelled
                self.export(path)

        self.app.push_screen(PathPrompt("Export the capture to", str(default_capture_path("fieldbox"))), chosen)

    def export(self, path: str | Path) -> int | None:
        """Write the whole ring (every link) as a pcap; returns the packets written."""
        if self.endpoints is None or not self._may_write(path):
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


def _message_name(key: LinkKey) -> str:
    """`` · ControlPacket``: the one message a UDP link carries (its rows leave it out)."""
    from protocol import kinds as protocol_kinds

    kind = key[3]
    try:
        spec = protocol_kinds.get(kind)
    except KeyError:
        return ""
    return "" if spec.tcp else f" · {spec.message}"


def _pane(widget: Widget, title: str) -> Widget:
    """One of the four panes: a bordered box with its title."""
    widget.border_title = title
    widget.add_class("pane")
    return widget
