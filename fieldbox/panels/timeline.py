"""The Timeline tab (F6 F6): one exchange across the FMS, a Driver Station and its roboRIO,
drawn for a classroom.

Three lanes, FMS, Driver Station and roboRIO, and one arrow a packet between them, in time
order: control to the robot and its status echo, the FMS's control and the DS's status, the
TCP frames (dashed). Each link gives its last few packets (more on a taller screen), so the
FMS's two packets a second stand beside the robot's fifty. Times are before the newest
packet shown (``-20.0 ms``): the echo of a control packet comes a fraction of a millisecond
after it on loopback; a delay fault shows as a wider gap.

The view changes once a second, slowly enough to read aloud; ``p`` holds it still. The
arrows come from the inspector's capture (fieldbox/exchange.py says which packets); ``↑``
``↓`` pick one, whose whole summary is under the lanes, and ``i`` opens it in the inspector,
every byte explained.

Keys (this tab): ``p`` pause, ``↑`` ``↓`` pick a packet, ``i`` open it in the inspector,
``+`` ``-`` more or fewer packets per link, ``[`` ``]`` another team on a field.
"""

from __future__ import annotations

from typing import Any

from rich.text import Text
from textual.app import ComposeResult
from textual.binding import Binding
from textual.message import Message
from textual.widget import Widget
from textual.widgets import Static

from ..exchange import LANES, Hop, Summaries, center_role, hops
from ..widgets import key_hints, theme_colour
from .base import Panel, engine_of

#: Seconds between two pictures while live.
REDRAW = 1.0
MAX_PER_LINK = 12
TIME_WIDTH = 10


def time_text(seconds: float) -> str:
    """``-20.0 ms``, ``-1.24 s``: before the newest packet shown."""
    if abs(seconds) < 1.0:
        return f"{seconds * 1000:+.1f} ms".replace("+0.0", " 0.0").replace("+", " ")
    return f"{seconds:+.2f} s".replace("+", " ")


class TimelineView(Widget, can_focus=True):
    """The lanes and arrows; ``↑`` ``↓`` move the selection."""

    DEFAULT_CSS = """
    TimelineView { height: 1fr; }
    TimelineView:focus { background-tint: $accent 3%; }
    """
    BINDINGS = [
        Binding("up", "move(-1)", "Up", show=False),
        Binding("down", "move(1)", "Down", show=False),
        Binding("home", "move(-1000000)", show=False),
        Binding("end", "move(1000000)", show=False),
    ]

    def __init__(self, *, id: str | None = None) -> None:
        super().__init__(id=id)
        self.hops: list[Hop] = []
        self.cursor = 0
        self.names = {"fms": "FMS", "ds": "Driver Station", "rio": "roboRIO"}

    def show(self, new: list[Hop], names: dict[str, str]) -> None:
        """New hops; the packet selected stays selected while it is still shown."""
        selected = self.hops[self.cursor].packet.seq if self.hops and 0 <= self.cursor < len(self.hops) else None
        at_end = not self.hops or self.cursor >= len(self.hops) - 1
        self.hops, self.names = new, names
        seqs = [h.packet.seq for h in new]
        if selected in seqs and not at_end:
            self.cursor = seqs.index(selected)
        else:
            self.cursor = max(0, len(new) - 1)
        self.refresh()

    def selected(self) -> Hop | None:
        return self.hops[self.cursor] if 0 <= self.cursor < len(self.hops) else None

    def action_move(self, delta: int) -> None:
        if self.hops:
            self.cursor = max(0, min(len(self.hops) - 1, self.cursor + delta))
            self.refresh()
            self.post_message(TimelineView.Moved())

    class Moved(Message):
        """The selection moved."""

    # -- drawing -----------------------------------------------------------------------------
    def _geometry(self, width: int) -> tuple[int, dict[str, int]]:
        """(diagram width, the x of each lane in it): all the width under 120 columns, else
        about half of it, the rest for what each packet says."""
        room = max(30, width - TIME_WIDTH - 1)
        diagram = room if room < 110 else max(80, min(int(room * 0.55), 120))
        return diagram, {"fms": 1, "ds": diagram // 2, "rio": diagram - 2}

    def render(self) -> Text:
        width, height = self.size.width, self.size.height
        diagram, x = self._geometry(width)
        detail_w = width - TIME_WIDTH - diagram - 2
        colours = {lane: theme_colour(self.app, name, fallback)
                   for lane, name, fallback in (("fms", "accent", "yellow"), ("ds", "primary", "blue"),
                                                ("rio", "success", "green"))}
        link_colour = {"robot": theme_colour(self.app, "primary", "blue"),
                       "fms": theme_colour(self.app, "accent", "yellow"),
                       "tcp": theme_colour(self.app, "secondary", "grey50")}
        text = Text(no_wrap=True, overflow="crop")
        # the lanes' names
        head = [" "] * diagram
        spans: list[tuple[int, int, str]] = []
        for lane in LANES:
            name = self.names.get(lane, lane)[: max(4, diagram // 3 - 1)]
            start = max(0, min(diagram - len(name), x[lane] - len(name) // 2))
            head[start:start + len(name)] = list(name)
            spans.append((start, start + len(name), lane))
        text.append(" " * TIME_WIDTH)
        line = "".join(head)
        pos = 0
        for start, end, lane in spans:
            text.append(line[pos:start])
            text.append(line[start:end], f"bold {colours[lane]}")
            pos = end
        text.append(line[pos:])
        if detail_w >= 20:
            text.append("  what it says", "dim")
        rows = max(0, height - 1)
        if not self.hops:
            text.append("\n\n" + " " * TIME_WIDTH + "no packets yet: they appear as the roles talk", "dim")
            return text
        first = max(0, min(self.cursor - rows + 1, len(self.hops) - rows)) if len(self.hops) > rows else 0
        newest = self.hops[-1].time
        for i in range(first, min(len(self.hops), first + rows)):
            hop = self.hops[i]
            text.append("\n")
            selected = i == self.cursor
            base = "reverse" if selected and self.has_focus else ("bold" if selected else "")
            text.append(time_text(hop.time - newest).rjust(TIME_WIDTH - 1) + " ", f"dim {base}".strip())
            kind = "tcp" if hop.tcp else ("fms" if "fms" in (hop.src, hop.dst) else "robot")
            self._arrow(text, hop, diagram, x, link_colour[kind], base)
            if detail_w >= 20:
                detail = hop.detail
                text.append("  ")
                text.append(detail[: detail_w - 1] + ("…" if len(detail) > detail_w - 1 else ""), "dim")
        return text

    @staticmethod
    def _arrow(text: Text, hop: Hop, diagram: int, x: dict[str, int], colour: str, base: str) -> None:
        cells = [" "] * diagram
        for lane in LANES:
            cells[x[lane]] = "│"
        a, b = x[hop.src], x[hop.dst]
        lo, hi = min(a, b), max(a, b)
        rule = "╌" if hop.tcp else "─"
        for i in range(lo + 1, hi):
            cells[i] = rule
        cells[a] = "├" if b > a else "┤"
        if b > a:
            cells[b - 1] = "▶"
        else:
            cells[b + 1] = "◀"
        label = f" {hop.name} "
        inner = hi - lo - 3
        if inner >= 4:
            label = label[:inner]
            start = lo + 2 + (inner - len(label)) // 2
            cells[start:start + len(label)] = list(label)
        line = "".join(cells)
        text.append(line[:lo + 1], "dim")
        text.append(line[lo + 1:hi], f"bold {colour} {base}".strip())
        text.append(line[hi:], "dim")


class TimelinePanel(Panel):
    TITLE = "Timeline"
    SHORT_TITLE = "Timeline"
    ID = "timeline"
    READS_CAPTURE = True

    BINDINGS = [
        Binding("p", "pause", "Pause/resume"),
        Binding("i", "inspect", "Inspect"),
        Binding("plus", "per_link(1)", "More", show=False),
        Binding("minus", "per_link(-1)", "Fewer", show=False),
        Binding("left_square_bracket", "team(-1)", "Prev team", show=False),
        Binding("right_square_bracket", "team(1)", "Next team", show=False),
    ]

    DEFAULT_CSS = """
    TimelinePanel { layout: vertical; padding: 0 1; }
    TimelinePanel #timeline-head { height: 1; }
    TimelinePanel #timeline-head.-paused { color: $warning; text-style: bold; }
    TimelinePanel #timeline-detail { height: 3; padding: 0 1; background: $boost; }
    TimelinePanel #timeline-keys { height: 1; color: $text-muted; }
    """

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self.paused = False
        self.per_link: int | None = None  # None: as many as the height allows
        self._drawn_at = float("-inf")
        self._summaries = Summaries()
        self._links = 1

    def compose(self) -> ComposeResult:
        yield Static("", id="timeline-head")
        yield TimelineView(id="timeline-view")
        yield Static("", id="timeline-detail")
        yield Static(key_hints([("", [("p", "pause"), ("↑↓", "pick"), ("i", "inspect"), ("+ -", "packets per link"),
                                      ("[ ]", "team")])], title_width=0), id="timeline-keys", classes="key-hints")

    def take_focus(self) -> None:
        self.query_one(TimelineView).focus()

    def on_resize(self) -> None:
        # the packets per link follow the height: a new size is a new picture, at once
        engine = getattr(self.app, "engine", None)
        if engine is not None and not self.paused:
            self.call_after_refresh(lambda: self.redraw(engine, engine.now()))

    @property
    def view(self) -> TimelineView:
        return self.query_one(TimelineView)

    # -- the refresh ----------------------------------------------------------------------------
    def refresh_view(self, engine, now: float) -> None:
        if self.paused or (0 <= now - self._drawn_at < REDRAW):
            self._head(engine)
            return
        self.redraw(engine, now)

    def redraw(self, engine, now: float) -> None:
        self._drawn_at = now
        ring = self.capture_ring()
        team = getattr(self.app, "selected_team", None)
        role, _ = center_role(engine, team)
        if ring is None or role is None:
            self.view.show([], self._names(engine))
            self._head(engine)
            return
        self._links = max(1, sum(1 for key in ring.links if key[0] == role))
        rows = max(1, self.view.size.height - 1)
        per_link = self.per_link or max(1, min(MAX_PER_LINK, rows // self._links))
        self.view.show(hops(ring, role, per_link, self._summaries), self._names(engine))
        self._head(engine)
        self._detail()

    def _names(self, engine) -> dict[str, str]:
        field = engine.field
        team = getattr(self.app, "selected_team", None)
        stations = list(field.stations)
        st = next((s for s in stations if s.team == team), stations[0] if stations else None)
        legacy = getattr(field.config, "legacy", False)
        left = "dashboard" if legacy else "FMS" + ("" if field.fms is not None else " (not here)")
        ds = f"DS {st.team}" if st is not None else "DS"
        rio = f"roboRIO {st.team}" if st is not None else "roboRIO"
        if st is not None and st.ds is not None and st.rio is None:
            rio += " (not here)"
        if st is not None and st.ds is None:
            ds += " (not here)"
        return {"fms": left, "ds": ds, "rio": rio}

    def _head(self, engine) -> None:
        per_link = self.per_link or "as many as fit"
        text = Text()
        live = getattr(engine_of(engine), "follow_word", "LIVE")  # a replay's is REPLAY (fieldbox/replay.py)
        text.append("PAUSED (p resumes)" if self.paused else f"{live}, a picture a second", "bold")
        if self.size.width >= 100:
            text.append(f"   the last packets of each of {self._links} links, oldest at the top "
                        f"({per_link} per link)", "dim")
        else:
            text.append(f"   {self._links} links, their last packets", "dim")
        self.set_text("timeline-head", text)
        self.set_shown("paused", self.paused, lambda p: self.query_one("#timeline-head").set_class(p, "-paused"))

    def _detail(self) -> None:
        hop = self.view.selected()
        text = Text()
        if hop is None:
            text.append("Pick a packet with ↑ ↓ to read it here.", "dim")
        else:
            p = hop.packet
            text.append(f"{hop.name}", "bold")
            text.append(f"   {p.role} {p.link} {p.direction} {p.kind} · {len(p.data)} bytes", "dim")
            if self.size.width >= 100:
                text.append("   i: every byte in the inspector", "dim")
            text.append("\n")
            text.append(hop.detail)
        self.set_text("timeline-detail", text)

    def on_timeline_view_moved(self, _message: Any) -> None:
        self._detail()

    # -- keys -------------------------------------------------------------------------------------
    def action_pause(self) -> None:
        self.paused = not self.paused
        engine = self.engine
        if engine is not None:
            if not self.paused:
                self.redraw(engine, engine.now())
            self._head(engine)

    def action_per_link(self, step: int) -> None:
        current = self.per_link or max(1, min(MAX_PER_LINK, max(1, self.view.size.height - 1) // self._links))
        self.per_link = max(1, min(MAX_PER_LINK, current + step))
        engine = self.engine
        if engine is not None:
            self.redraw(engine, engine.now())

    def action_team(self, step: int) -> None:
        engine = self.engine
        if engine is None or len(engine.field.stations) < 2:
            self.notify("Only one team runs here", timeout=2)
            return
        teams = [st.team for st in engine.field.stations]
        current = self.station()
        i = teams.index(current.team) if current is not None else 0
        self.app.selected_team = teams[(i + step) % len(teams)]  # type: ignore[attr-defined]
        self.redraw(engine, engine.now())

    def action_inspect(self) -> None:
        hop = self.view.selected()
        if hop is None:
            self.notify("no packet picked", timeout=2)
            return
        from .inspector import InspectorPanel  # here: the inspector's module is the larger, and needs no timeline

        inspector = self.app.screen_stack[0].query_one("#panel-inspector", InspectorPanel)
        self.app.action_show_tab("inspector")  # type: ignore[attr-defined]
        inspector.show_packet(hop.packet)
