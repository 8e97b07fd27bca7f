"""The Console panel: the robot's stdout, warnings and errors, with timestamps, filterable.

It stays fast with tens of thousands of lines (the toolong shape, docs/style.md#textual):

* the lines live in a ring buffer (:data:`CAPACITY` lines, the oldest dropped);
* :class:`ConsoleView` is a Line API widget (a ``ScrollView`` whose ``render_line`` draws
  only the rows on screen) over the *filtered* ring, with a cache of rendered strips keyed by
  each line's number, so scrolling and new lines never re-render what is already drawn;
* new lines are appended incrementally (the cores' ``console_total`` says whether anything is
  new, :mod:`fieldbox.consolelog` copies only what is): the view is rebuilt only when a
  filter changes, never at the 10 Hz refresh;
* auto-scroll follows the newest line and pauses as soon as the user scrolls up; End (or
  scrolling back to the bottom) resumes it.

The panel collects lines while hidden too (``ALWAYS_REFRESH``): a core keeps only its last
2000 lines, and a console that shows only what arrived while you watched is no console.
"""

from __future__ import annotations

import re
import time
from collections import deque
from types import EllipsisType
from typing import NamedTuple

from rich.cells import cell_len
from rich.style import Style
from rich.text import Text
from textual import on
from textual.app import ComposeResult
from textual.binding import Binding
from textual.cache import LRUCache
from textual.containers import Horizontal
from textual.scroll_view import ScrollView
from textual.strip import Strip
from textual.widgets import Checkbox, Input, Static

from roles.runtime.process_tuning import untrack_plain

from ..console_feed import ConsoleEntry, ConsoleReader, console_sources
from ..textual_fixes import set_virtual_rows
from ..widgets import TextBox, Tick
from .base import Panel

#: Lines kept by the panel (the oldest are dropped; the run's log files keep every line:
#: roles/runtime/logfiles.py). Six robot programs printing a line every beat fill it in a minute, one
#: in under seven. It was 50 000: about 18 MB when full, and with six such programs the
#: two processes passed 150 MB (benchmarks/memory.py --program benchmarks/chatty_robot.py).
CAPACITY = 20_000

#: Level -> (the toggle that shows it, the badge drawn, the component class that colours it).
LEVELS = {
    "stdout": ("stdout", "out  ", "console--stdout"),
    "radio": ("stdout", "radio", "console--radio"),
    "warning": ("warning", "WARN ", "console--warning"),
    "error": ("error", "ERROR", "console--error"),
    "notice": ("notice", "     ", "console--notice"),  # fieldbox's own notes (lost lines)
}
TOGGLES = ("stdout", "warning", "error")

_CONTROL = re.compile("[\x00-\x08\x0b-\x1f\x7f]")


class Row(NamedTuple):
    """One line in the ring: its number (never reused: the strip cache's key), the entry, its
    width and when it arrived. About 360 bytes with its entry for a line of 52 characters;
    the text folded for the search is made when a search runs, not kept (it was another 100
    bytes a line, 5 MB of a full ring)."""

    n: int
    entry: ConsoleEntry
    cells: int  # the text's width on screen
    wall: float  # when it arrived, on the wall clock


def _clean(text: str) -> str:
    return _CONTROL.sub("\ufffd", text.replace("\r\n", "\n").replace("\n", " \u21b5 ").expandtabs())


class ConsoleView(ScrollView, can_focus=True):
    """The console lines, drawn with the Line API over the filtered ring."""

    COMPONENT_CLASSES = {
        "console--time", "console--team", "console--stdout", "console--radio",
        "console--warning", "console--error", "console--notice", "console--match",
    }
    DEFAULT_CSS = """
    ConsoleView { background: $surface; overflow: auto auto; }
    ConsoleView:focus { background-tint: $foreground 4%; }
    ConsoleView > .console--time { color: $text-muted; }
    ConsoleView > .console--team { color: $secondary; text-style: bold; }
    ConsoleView > .console--stdout { color: $text-muted; }
    ConsoleView > .console--radio { color: $accent; }
    ConsoleView > .console--warning { color: $warning; text-style: bold; }
    ConsoleView > .console--error { color: $error; text-style: bold; }
    ConsoleView > .console--notice { color: $text-muted; text-style: italic; }
    ConsoleView > .console--match { background: $warning 45%; }
    """

    def __init__(self, capacity: int = CAPACITY, *, id: str | None = None) -> None:
        super().__init__(id=id)
        self.capacity = capacity
        self._ring: deque[Row] = deque(maxlen=capacity)
        self._view: list[Row] = []   # the filtered rows; the visible ones start at _start
        self._start = 0
        self._next_n = 0
        self._width = 0
        self._cache: LRUCache[int, Strip] = LRUCache(2048)
        self.levels: set[str] = set(TOGGLES) | {"notice"}
        self.text_filter = ""
        self.team_filter: int | None = None
        self.show_team = False
        self.time_offset = 0.0  # engine clock -> wall clock, for the lines appended from now on
        self.following = True
        self.unseen = 0         # lines added below the screen while paused
        # counters the tests read: how often the view was rebuilt / a line was rendered
        self.rebuilds = 0
        self.strips_rendered = 0

    # -- what is in it --------------------------------------------------------------------
    @property
    def total(self) -> int:
        """Lines in the ring (whatever the filters)."""
        return len(self._ring)

    @property
    def shown(self) -> int:
        """Lines that pass the filters."""
        return len(self._view) - self._start

    def shown_entries(self) -> list[ConsoleEntry]:
        return [r.entry for r in self._view[self._start:]]

    def _passes(self, row: Row) -> bool:
        e = row.entry
        if LEVELS.get(e.level, LEVELS["stdout"])[0] not in self.levels:
            return False
        if self.team_filter is not None and e.team != self.team_filter:
            return False
        return not self.text_filter or self.text_filter in e.text.casefold()

    # -- changing it ----------------------------------------------------------------------
    def append(self, entries: list[ConsoleEntry]) -> None:
        """Add lines at the end: O(new lines), nothing already drawn is redrawn."""
        if not entries:
            return
        ring, view = self._ring, self._view
        before = self.shown
        width = self._width
        prefix = self._prefix_width()
        for e in entries:
            row = Row(self._next_n, e, cell_len(_clean(e.text)), e.time + self.time_offset)
            # A full ring is 40 000 objects of plain data, never in a cycle: out of the
            # collector's sight (as the inspector's packets: fieldbox/capture.py).
            untrack_plain(row)
            untrack_plain(e)
            self._next_n += 1
            ring.append(row)
            if self._passes(row):
                view.append(row)
                width = max(width, prefix + row.cells)
        # Rows that fell out of the ring leave the view too.
        oldest = ring[0].n
        trimmed = 0
        while self._start < len(view) and view[self._start].n < oldest:
            self._start += 1
            trimmed += 1
        if self._start > self.capacity // 4:  # compact now and then, not on every line
            del view[:self._start]
            self._start = 0
        self._width = width
        added = self.shown - before + trimmed
        if trimmed and not self.following:
            # keep the lines the user is reading where they are; before the new size, which
            # clamps the scroll: clamped to the bottom, the view would follow again
            self.scroll_to(y=max(0, self.scroll_y - trimmed), animate=False, immediate=True)
        self._resize()
        if self.following:
            self.unseen = 0
            self.scroll_end(animate=False, immediate=True, x_axis=False, force=True)
        else:
            self.unseen += added
        self.refresh()  # redraws the lines on screen: from the cache, except the new ones

    def rebuild(self) -> None:
        """Filter the whole ring again (a filter changed)."""
        self.rebuilds += 1
        self._view = [r for r in self._ring if self._passes(r)]
        self._start = 0
        self._cache.clear()
        prefix = self._prefix_width()
        self._width = prefix + max((r.cells for r in self._view), default=0)
        self._resize()
        self.unseen = 0
        if self.following:
            self.scroll_end(animate=False, immediate=True, x_axis=False, force=True)
        self.refresh()

    def set_filters(self, *, levels: set[str] | None = None, text: str | None = None,
                    team: int | None | EllipsisType = ..., show_team: bool | None = None) -> None:
        changed = False
        if levels is not None and levels | {"notice"} != self.levels:
            self.levels = set(levels) | {"notice"}
            changed = True
        if text is not None and text.casefold() != self.text_filter:
            self.text_filter = text.casefold()
            changed = True
        if team is not ... and team != self.team_filter:
            self.team_filter = team
            changed = True
        if show_team is not None and show_team != self.show_team:
            self.show_team = show_team
            changed = True
        if changed:
            self.rebuild()

    def clear(self) -> None:
        self._ring.clear()
        self._view = []
        self._start = 0
        self._width = 0
        self._cache.clear()
        self.unseen = 0
        self.following = True
        self._resize()
        self.scroll_to(0, 0, animate=False, immediate=True)
        self.refresh()

    def resume(self) -> None:
        """Follow the newest line again."""
        self.following = True
        self.unseen = 0
        self.scroll_end(animate=False, immediate=True, force=True)

    def _resize(self) -> None:
        set_virtual_rows(self, self.shown, self._width)

    # -- following ------------------------------------------------------------------------
    def watch_scroll_y(self, old_value: float, new_value: float) -> None:
        super().watch_scroll_y(old_value, new_value)
        if new_value >= self.max_scroll_y:
            self.following = True
            self.unseen = 0
        elif new_value < old_value:
            self.following = False  # the user went up to read: stop following

    # -- drawing --------------------------------------------------------------------------
    def notify_style_update(self) -> None:
        super().notify_style_update()
        self._cache.clear()

    def _prefix_width(self) -> int:
        return 13 + (7 if self.show_team else 0) + 6

    def render_line(self, y: int) -> Strip:
        scroll_x, scroll_y = self.scroll_offset
        index = self._start + scroll_y + y
        width = self.size.width
        base = self.rich_style
        if not 0 <= index - self._start < self.shown:
            return Strip.blank(width, base)
        row = self._view[index]
        strip = self._cache.get(row.n)
        if strip is None:
            strip = self._render_row(row, base)
            self._cache[row.n] = strip
        return strip.crop_extend(scroll_x, scroll_x + width, base)

    def _render_row(self, row: Row, base: Style) -> Strip:
        self.strips_rendered += 1
        e = row.entry
        style = self.get_component_rich_style
        t = row.wall
        stamp = time.strftime("%H:%M:%S", time.localtime(t)) + f".{int(t * 1000) % 1000:03d}"
        _, badge, cls = LEVELS.get(e.level, LEVELS["stdout"])
        text = Text(no_wrap=True, end="")
        text.append(stamp, style("console--time"))
        text.append("  ")
        if self.show_team:
            text.append(f"{e.team:>5}", style("console--team"))
            text.append("  ")
        text.append(badge, style(cls))
        text.append(" ")
        body = _clean(e.text)
        start = len(text)
        text.append(body, style(cls) if e.level in ("warning", "error", "notice") else None)
        needle = self.text_filter
        if needle:
            match = style("console--match")
            folded = body.casefold()
            if len(folded) == len(body):  # case folding kept offsets: mark each match
                at = folded.find(needle)
                while at >= 0:
                    text.stylize(match, start + at, start + at + len(needle))
                    at = folded.find(needle, at + len(needle))
        text.stylize_before(base)
        segments = list(text.render(self.app.console))
        return Strip(segments, text.cell_len)


class ConsolePanel(Panel):
    """The robot console of the selected team's DS, or of every team with a team column.

    ``t`` steps through all teams and each team; picking a team for the DS keys (the app's
    ``selected_team``) shows that team's console.
    """

    TITLE = "Console"
    SHORT_TITLE = "Console"
    ID = "console"
    REFRESH_TICKS = 2
    ALWAYS_REFRESH = True  # collect lines while hidden: the cores keep only their last 2000

    BINDINGS = [
        Binding("1", "toggle_level('stdout')", "stdout"),
        Binding("2", "toggle_level('warning')", "warnings"),
        Binding("3", "toggle_level('error')", "errors"),
        Binding("slash", "focus_filter", "Filter"),
        Binding("t", "next_team", "Team"),
        Binding("end", "follow", "Follow"),
        Binding("c", "clear", "Clear"),
        Binding("escape", "leave_filter", "Back to the log", show=False),
    ]

    DEFAULT_CSS = """
    ConsolePanel { layout: vertical; }
    ConsolePanel #console-bar { height: 3; padding: 0 1; }
    ConsolePanel #console-bar Input { width: 1fr; min-width: 20; }
    ConsolePanel #console-bar Checkbox { width: auto; border: none; padding: 0 1; margin: 1 0 0 1; height: 1; }
    ConsolePanel #console-bar #console-team { width: auto; margin: 1 0 0 2; }
    ConsolePanel ConsoleView { height: 1fr; }
    ConsolePanel #console-status { height: 1; padding: 0 1; background: $boost; color: $text-muted; }
    ConsolePanel.-short #console-bar { height: 1; }
    ConsolePanel.-short #console-bar Checkbox { margin: 0 0 0 1; }
    ConsolePanel.-short #console-bar #console-team { margin: 0 0 0 2; }
    ConsolePanel.-narrow #console-bar Input { min-width: 12; }
    """
    #: The level boxes' labels: usual, and under 100 columns (the team filter must not be cut).
    LEVEL_LABELS = {"stdout": ("1 stdout", "1 out"), "warning": ("2 warnings", "2 warn"),
                    "error": ("3 errors", "3 err")}

    def __init__(self, *, id: str | None = None) -> None:
        super().__init__(id=id)
        self._reader = ConsoleReader()
        self._engine = None
        self._teams: list[int] = []
        self._lost_reported = 0
        self._status = ""
        self._app_team: int | None = None

    def compose(self) -> ComposeResult:
        with Horizontal(id="console-bar"):
            yield TextBox(placeholder="filter: text to find (/)", id="console-filter")
            for level, label in (("stdout", "1 stdout"), ("warning", "2 warnings"), ("error", "3 errors")):
                box = Tick(label, True, id=f"console-show-{level}")  # ticked reads without colour
                box.can_focus = False
                yield box
            yield Static("", id="console-team")
        yield ConsoleView(id="console-view")
        yield Static("", id="console-status")

    @property
    def view(self) -> ConsoleView:
        return self.query_one(ConsoleView)

    def on_mount(self) -> None:
        self.query_one("#console-filter", Input).cursor_blink = False

    def take_focus(self) -> None:
        self.view.focus()

    def on_resize(self) -> None:
        # an 80x24 terminal: the filter is one line and the level boxes are short, so the
        # lines get the rows and the team filter is not cut
        narrow, short = self.size.width < 100, self.size.height < 30
        if narrow != self.has_class("-narrow"):
            for level, labels in self.LEVEL_LABELS.items():
                self.query_one(f"#console-show-{level}", Checkbox).label = labels[narrow]
        self.set_class(narrow, "-narrow")
        self.set_class(short, "-short")
        self.query_one("#console-filter", Input).compact = short

    # -- the 10 Hz refresh ----------------------------------------------------------------
    def refresh_view(self, engine, now: float) -> None:
        view = self.view
        if engine is not self._engine:
            self._engine = engine
            self._reader = ConsoleReader()
            self._teams = [team for team, _ in console_sources(engine)]
            self._lost_reported = 0
            view.time_offset = time.time() - engine.now()
            team = view.team_filter if view.team_filter in self._teams else None
            view.set_filters(team=team, show_team=len(self._teams) > 1)
            self._show_team_label()
        self._follow_app_team()
        entries = self._reader.read(engine)
        lost = self._reader.missed
        if lost != self._lost_reported:
            entries.insert(0, ConsoleEntry(entries[0].time if entries else now, 0, "notice",
                                           f"{lost - self._lost_reported} console lines scrolled out "
                                           "of the Driver Station before the panel saw them"))
            self._lost_reported = lost
        view.append(entries)
        if self.display and self.is_attached:
            self._update_status()

    def _update_status(self) -> None:
        view = self.view
        parts = [f"{view.shown:,} of {view.total:,} lines"]
        if not self._teams:
            parts = ["no Driver Station or roboRIO runs here: nothing to show"]
        if view.following:
            parts.append("following the newest line")
        else:
            parts.append(f"PAUSED ({view.unseen:,} new below): End to follow")
        hidden = [name for name in TOGGLES if name not in view.levels]
        if hidden:
            parts.append("hiding " + ", ".join(hidden))
        if self.query_one("#console-filter", Input).has_focus:  # first: a narrow line cuts the end
            parts.insert(0, "ctrl+space types a space (Space e-stops)")
        status = "   ·   ".join(parts)
        if status != self._status:
            self._status = status
            self.query_one("#console-status", Static).update(status)

    def _follow_app_team(self) -> None:
        """When the team picked for the DS keys changes, show that team's console."""
        team = getattr(self.app, "selected_team", None)
        if team != self._app_team:
            self._app_team = team
            if team in self._teams and len(self._teams) > 1:
                self.view.set_filters(team=team)
                self._show_team_label()

    def _show_team_label(self) -> None:
        label = self.query_one("#console-team", Static)
        if len(self._teams) > 1:
            team = self.view.team_filter
            label.update(f"team: {'all' if team is None else team} (t)")
        else:
            label.update(f"team {self._teams[0]}" if self._teams else "")

    # -- filters --------------------------------------------------------------------------
    @on(Input.Changed, "#console-filter")
    def _filter_changed(self, event: Input.Changed) -> None:
        self.view.set_filters(text=event.value)
        self._update_status()

    @on(Input.Submitted, "#console-filter")
    def _filter_done(self) -> None:
        self.view.focus()

    @on(Checkbox.Changed)
    def _toggle_changed(self, event: Checkbox.Changed) -> None:
        level = (event.checkbox.id or "").removeprefix("console-show-")
        if level in TOGGLES:
            levels = set(self.view.levels)
            levels.add(level) if event.value else levels.discard(level)
            self.view.set_filters(levels=levels)
            self._update_status()

    def action_toggle_level(self, level: str) -> None:
        box = self.query_one(f"#console-show-{level}", Checkbox)
        box.value = not box.value  # Checkbox.Changed does the rest

    def action_focus_filter(self) -> None:
        self.query_one("#console-filter", Input).focus()

    def action_leave_filter(self) -> None:
        self.view.focus()

    def action_next_team(self) -> None:
        if len(self._teams) < 2:
            self.notify("one team only: nothing to pick", timeout=2)
            return
        choices: list[int | None] = [None, *self._teams]
        current = self.view.team_filter
        index = choices.index(current) if current in choices else 0
        self.view.set_filters(team=choices[(index + 1) % len(choices)])
        self._show_team_label()
        self._update_status()

    def action_follow(self) -> None:
        self.view.resume()
        self._update_status()

    def action_clear(self) -> None:
        self.view.clear()
        self._update_status()
