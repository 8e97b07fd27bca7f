"""The log viewer: ``fieldbox logs [FOLDER|FILE]``, as the NI Driver Station's Log File Viewer.

A list of runs (the ``.dslog``/``.dsevents`` pairs in a folder, newest first, with date,
length, team and match), then one run: battery, trip time, lost packets and roboRIO CPU as
line charts (fieldbox/linechart.py), the modes under them on the same time axis (what the DS
sent, what the robot said it ran, brownout, e-stop, comms), the events as marks on that axis
and as a list. A cursor runs along the axis: each chart's title says its value there, the line
under the modes says the state there, and picking an event in the list moves the cursor to it.

Keys: ←/→ move the cursor a column (shift: ten), Home/End, +/- zoom around it, 0 the whole run,
n/p the next or previous event, Tab to the event list (↑/↓ move the cursor with it), Esc back
to the list of runs, q quits. It fits 80x24: the charts shrink to two rows, never away.
"""

from __future__ import annotations

import datetime as _dt
import math
from bisect import bisect_left, bisect_right
from pathlib import Path
from typing import Sequence

from rich.style import Style
from rich.text import Text
from textual.app import App, ComposeResult
from textual.binding import Binding
from textual.containers import Vertical
from textual.screen import Screen
from textual.widget import Widget
from textual.widgets import DataTable, Footer, OptionList, Static
from textual.widgets.option_list import Option

from .dslog_read import RECORD_PERIOD, LogEvent, LogRecord, estop_at
from .linechart import LineChart
from .logview_runs import LoadedRun, Run, find_runs, load
from .themes import install_themes, variable_defaults

#: Columns left of every plot: the charts' scale labels and the mode rows' names line up in time.
LABEL_WIDTH = 6
#: A mode row's words where the whole one does not fit (past these: its first letter, repeated).
_SHORT = {"disabled": "dis", "teleop": "tele", "no comms": "no com", "brownout": "brown", "watchdog": "wdog",
          "e-stop": "stop"}
#: Seconds between time labels on the axis, the smallest that leaves room for each label.
_TIME_STEPS = (0.1, 0.2, 0.5, 1, 2, 5, 10, 15, 30, 60, 120, 300, 600, 900, 1800, 3600)


def clock(seconds: float, precise: bool = True) -> str:
    """Seconds since the run began as m:ss.ss (h:mm:ss past an hour)."""
    sign = "-" if seconds < 0 else ""
    s = abs(seconds)
    if s >= 3600:
        return f"{sign}{int(s // 3600)}:{int(s % 3600 // 60):02d}:{int(s % 60):02d}"
    if precise:
        return f"{sign}{int(s // 60)}:{s % 60:05.2f}"
    return f"{sign}{int(s // 60)}:{int(s % 60):02d}"


def length_text(seconds: float | None) -> str:
    if seconds is None:
        return "—"
    return clock(seconds, precise=False)


def when_text(unix: float) -> str:
    """A run's start in local time, as the NI DS names its files."""
    try:
        return _dt.datetime.fromtimestamp(unix).strftime("%Y-%m-%d %H:%M:%S")
    except (OverflowError, OSError, ValueError):
        return "?"


class Timeline:
    """One run's records and events on a single axis: seconds since the .dslog's first record
    (the .dsevents' times are moved onto it by the difference of the two headers)."""

    def __init__(self, loaded: LoadedRun) -> None:
        log, events = loaded.log, loaded.events
        self.records: tuple[LogRecord, ...] = log.records if log is not None else ()
        origin = log.start if log is not None else events.start if events is not None else 0.0
        shift = (events.start - origin) if events is not None else 0.0
        self.events: list[LogEvent] = []
        self.event_times: list[float] = []
        if events is not None:
            for e in sorted(events.events, key=lambda e: e.t):
                self.events.append(e)
                self.event_times.append(e.t + shift)
        self.start_unix = origin
        last_event = self.event_times[-1] if self.event_times else 0.0
        first_event = self.event_times[0] if self.event_times else 0.0
        recorded = len(self.records) * RECORD_PERIOD
        if self.records:
            # events a minute past either end of the records (a clock that jumped) stay in the
            # list but do not squash the charts into a corner
            last_event, first_event = min(last_event, recorded + 60.0), max(first_event, -60.0)
        self.end = max(recorded, last_event, RECORD_PERIOD)
        self.begin = min(0.0, first_event)
        e_at = estop_at(tuple(self.events))
        self.estop = None if e_at is None else e_at + shift
        # the charts' points, once
        # no battery without comms; above 20 V is no battery either: the NI DS's last record
        # sometimes says so (AdvantageScope's DSLogReader.ts skips it too)
        self.battery = [(r.t, r.battery if (r.comms or r.battery) and r.battery <= 20.0 else None)
                        for r in self.records]
        self.trip = [(r.t, r.trip_ms) for r in self.records]
        self.lost = [(r.t, r.lost * 100) for r in self.records]
        self.cpu = [(r.t, r.cpu) for r in self.records]

    def record_at(self, t: float) -> LogRecord | None:
        if not self.records:
            return None
        i = min(max(int(t / RECORD_PERIOD), 0), len(self.records) - 1)
        return self.records[i]

    def records_in(self, t0: float, t1: float) -> Sequence[LogRecord]:
        i0 = max(0, math.ceil(t0 / RECORD_PERIOD - 1e-9))
        i1 = max(i0, math.ceil(t1 / RECORD_PERIOD - 1e-9))
        return self.records[i0:i1]


def column_of(t: float, start: float, end: float, width: int) -> int | None:
    """The plot column of time ``t`` in a window of ``width`` columns, as LineChart buckets it
    (two buckets a column), None outside the window."""
    if width <= 0 or end <= start or not start <= t <= end:
        return None
    return min(width * 2 - 1, int((t - start) * width * 2 / (end - start))) // 2


class CursorChart(LineChart):
    """A LineChart whose title gives the value at the cursor, and whose cursor column is drawn."""

    DEFAULT_CSS = """
    CursorChart { height: 1fr; min-height: 3; max-height: 9; }
    CursorChart > .line-chart--cursor { background: $accent 40%; }
    """
    COMPONENT_CLASSES = LineChart.COMPONENT_CLASSES | {"line-chart--cursor"}

    cursor: float | None = None

    _shown: tuple[int, float, float, int] | None = None

    def show(self, points: Sequence[tuple[float, float | None]], start: float, end: float, cursor: float) -> None:
        self.cursor = cursor
        key = (id(points), start, end, self.size.width)
        if key != self._shown:  # a cursor that moves re-buckets nothing (an hour is 180,000 points)
            self._shown = key
            self.plot(points, start, end)
        i = min(max(int(cursor / RECORD_PERIOD), 0), len(points) - 1) if points else -1
        value = points[i][1] if i >= 0 else None
        if value != self.latest:
            self.latest = value
            self._drawn = None
        self.refresh()

    def render(self) -> Text:
        text = super().render()
        plot_w = self._plot_width()
        column = None if self.cursor is None else column_of(self.cursor, *self._span, plot_w)
        if column is None:
            return text
        style = self.get_component_rich_style("line-chart--cursor")
        offset = 0
        for n, line in enumerate(text.plain.split("\n")):
            x = LABEL_WIDTH + 1 + column
            if n > 0 and x < len(line):
                text.stylize(style, offset + x, offset + x + 1)
            offset += len(line) + 1
        return text


class ModeStrip(Widget):
    """What the DS sent, what the robot ran, its alerts and the events, a row each, on the
    charts' time axis; the cursor a highlighted column; time labels under them."""

    DEFAULT_CSS = """
    ModeStrip { height: 5; width: 1fr; }
    ModeStrip > .mode-strip--teleop { color: $success; text-style: bold; }
    ModeStrip > .mode-strip--auto { color: $accent; text-style: bold; }
    ModeStrip > .mode-strip--test { color: $warning; text-style: bold; }
    ModeStrip > .mode-strip--off { color: $text-muted; }
    ModeStrip > .mode-strip--bad { color: $error; text-style: bold; }
    ModeStrip > .mode-strip--note { color: $secondary; }
    ModeStrip > .mode-strip--axis { color: $text-muted; }
    ModeStrip > .mode-strip--cursor { background: $accent 40%; }
    """
    COMPONENT_CLASSES = {"mode-strip--teleop", "mode-strip--auto", "mode-strip--test", "mode-strip--off",
                         "mode-strip--bad", "mode-strip--note", "mode-strip--axis", "mode-strip--cursor"}

    def __init__(self, timeline: Timeline, id: str | None = None) -> None:
        super().__init__(id=id)
        self.timeline = timeline
        self.window = (timeline.begin, timeline.end)
        self.cursor = 0.0
        self._cache: tuple[tuple[tuple[float, float], int], tuple[list[str | None], ...]] | None = None

    def show(self, start: float, end: float, cursor: float) -> None:
        self.window, self.cursor = (start, end), cursor
        self.refresh()

    def plot_width(self) -> int:
        return max(1, self.size.width - LABEL_WIDTH - 1)

    def _columns(self) -> list[tuple[float, float]]:
        start, end = self.window
        w = self.plot_width()
        return [(start + (end - start) * c / w, start + (end - start) * (c + 1) / w) for c in range(w)]

    def _values(self, columns: list[tuple[float, float]]) -> tuple[list[str | None], ...]:
        """Per column: what the DS sent, what the robot ran, the alert (cached per window and
        width: a cursor that moves reads no record again)."""
        key = (self.window, len(columns))
        if self._cache is not None and self._cache[0] == key:
            return self._cache[1]
        values = self._read(columns)
        self._cache = (key, values)
        return values

    def _read(self, columns: list[tuple[float, float]]) -> tuple[list[str | None], ...]:
        tl = self.timeline
        ds: list[str | None] = []
        robot: list[str | None] = []
        alert: list[str | None] = []
        for t0, t1 in columns:
            recs = tl.records_in(t0, t1)
            if not recs:
                ds.append(None)
                robot.append(None)
                alert.append("e-stop" if tl.estop is not None and t1 > tl.estop and t0 < tl.end else None)
                continue
            # an enabled moment in a column shows over the disabled ones; no comms over a mode
            modes = {r.ds_mode for r in recs}
            ds.append(next((m for m in ("auto", "teleop", "test") if m in modes), "disabled"))
            rmodes = {r.robot_mode for r in recs}
            robot.append("no comms" if None in rmodes else
                         next((m for m in ("auto", "teleop", "disabled") if m in rmodes), "disabled"))
            if tl.estop is not None and t1 > tl.estop:
                alert.append("e-stop")
            elif any(r.brownout for r in recs):
                alert.append("brownout")
            elif any(r.watchdog for r in recs):
                alert.append("watchdog")
            else:
                alert.append(None)
        return ds, robot, alert

    def render(self) -> Text:
        styles = {name: self.get_component_rich_style(f"mode-strip--{name}")
                  for name in ("teleop", "auto", "test", "off", "bad", "note", "axis", "cursor")}
        columns = self._columns()
        ds, robot, alert = self._values(columns)
        cursor_col = column_of(self.cursor, *self.window, len(columns))
        text = Text(no_wrap=True, overflow="crop")
        rows = [("DS", ds), ("Robot", robot), ("Alert", alert)]
        for n, (name, values) in enumerate(rows):
            if n:
                text.append("\n")
            text.append(name.ljust(LABEL_WIDTH - 1)[:LABEL_WIDTH - 1] + "  ", styles["axis"])
            self._runs(text, values, styles, cursor_col)
        text.append("\n")
        text.append("Event".ljust(LABEL_WIDTH - 1) + "  ", styles["axis"])
        self._events(text, columns, styles, cursor_col)
        text.append("\n")
        text.append(self._axis(columns), styles["axis"])
        return text

    @staticmethod
    def _style_of(value: str, styles: dict[str, Style]) -> Style:
        if value in ("teleop", "auto", "test"):
            return styles[value]
        if value in ("no comms", "e-stop", "brownout", "watchdog"):
            return styles["bad"]
        return styles["off"]

    def _runs(self, text: Text, values: list[str | None], styles: dict[str, Style], cursor: int | None) -> None:
        """Each run of one value: its name, then a line to its end ("teleop────"), or a short
        form ("tele─"), or its first letter over and over where neither fits."""
        cells: list[tuple[str, Style]] = []
        i = 0
        while i < len(values):
            j = i
            while j < len(values) and values[j] == values[i]:
                j += 1
            value, length = values[i], j - i
            if value is None:
                cells += [(" ", styles["off"])] * length
            else:
                style = self._style_of(value, styles)
                short = _SHORT.get(value, value)
                word = value if length > len(value) else short if length > len(short) else value[0].upper() * length
                body = (word + "─" * length)[:length] if len(word) < length else word[:length]
                cells += [(ch, style) for ch in body]
            i = j
        for c, (ch, style) in enumerate(cells):
            text.append(ch, style + styles["cursor"] if c == cursor else style)

    def _events(self, text: Text, columns: list[tuple[float, float]], styles: dict[str, Style],
                cursor: int | None) -> None:
        tl = self.timeline
        start, end = self.window
        marks: list[tuple[str, Style]] = [(" ", styles["off"])] * len(columns)
        rank = {"print": 0, "info": 1, "fms": 2, "mode": 2, "comms": 3, "warning": 4, "error": 5, "estop": 6}
        best = [-1] * len(columns)
        lo, hi = bisect_left(tl.event_times, start), bisect_right(tl.event_times, end)
        for k in range(lo, hi):
            e = tl.events[k]
            c = column_of(tl.event_times[k], start, end, len(columns))
            if c is None or rank[e.kind] <= best[c]:
                continue
            best[c] = rank[e.kind]
            if e.kind in ("estop", "error"):
                marks[c] = ("▲", styles["bad"])
            elif e.kind == "warning":
                marks[c] = ("▲", styles["test"])
            elif e.kind == "print":
                marks[c] = ("·", styles["off"])
            else:
                marks[c] = ("▲", styles["note"])
        for c, (ch, style) in enumerate(marks):
            text.append(ch, style + styles["cursor"] if c == cursor else style)

    def _axis(self, columns: list[tuple[float, float]]) -> str:
        """└ and the time every few columns: "0:00    0:30    1:00"."""
        start, end = self.window
        w = len(columns)
        line = [" "] * (LABEL_WIDTH - 1) + ["└"] + ["─"] * (w + 1)
        per_col = (end - start) / max(1, w)
        step = next((s for s in _TIME_STEPS if s / per_col >= 9), _TIME_STEPS[-1])
        value = math.ceil(start / step) * step
        while value <= end:
            c = column_of(value, start, end, w)
            if c is not None:
                label = clock(value, precise=step < 1)
                if step >= 1 and label.endswith(".00"):
                    label = label[:-3]
                x = LABEL_WIDTH + 1 + c
                if x + len(label) <= len(line):
                    line[x:x + len(label)] = list(label)
            value += step
        return "".join(line)[:self.size.width]


class LogScreen(Screen[None]):
    """One run: its charts, its modes and its events on one time axis, with a cursor."""

    BINDINGS = [
        Binding("left", "move(-1)", "◀ cursor", show=False),
        Binding("right", "move(1)", "cursor ▶", show=False),
        Binding("shift+left", "move(-10)", show=False),
        Binding("shift+right", "move(10)", show=False),
        Binding("home", "jump(0)", show=False),
        Binding("end", "jump(1)", show=False),
        Binding("plus,equals_sign", "zoom(0.5)", "zoom in"),
        Binding("minus", "zoom(2)", "zoom out"),
        Binding("0", "whole", "all", show=False),
        Binding("n", "event(1)", "next event"),
        Binding("p", "event(-1)", "previous", show=False),
        Binding("escape", "back", "runs"),
        Binding("q", "close", "close"),
    ]

    DEFAULT_CSS = """
    LogScreen { layout: vertical; }
    LogScreen #log-title { height: 1; text-style: bold; background: $panel; }
    LogScreen #log-problems { height: auto; max-height: 3; color: $warning; }
    LogScreen #log-readout { height: 1; }
    LogScreen #log-events { height: 1fr; min-height: 3; border: none; padding: 0; }
    """

    def __init__(self, loaded: LoadedRun, can_go_back: bool = False, embedded: bool = False) -> None:
        super().__init__()
        self.embedded = embedded
        self.loaded = loaded
        self.timeline = Timeline(loaded)
        self.window = (self.timeline.begin, self.timeline.end)
        self.cursor = 0.0
        self.can_go_back = can_go_back
        self._following_list = False

    # -- layout ---------------------------------------------------------------------------------
    def compose(self) -> ComposeResult:
        yield Static(self._title(), id="log-title")
        if self.loaded.problems:
            yield Static("\n".join(f"⚠ {p}" for p in self.loaded.problems), id="log-problems")
        with Vertical(id="log-charts"):
            yield CursorChart("Battery", "V", 6.0, 14.0, aggregate="min", warn=11.0, bad=7.0, below=True, digits=2,
                              id="log-battery", label_width=LABEL_WIDTH)
            yield CursorChart("Trip time", "ms", 0.0, 2.0, auto=True, warn=20.0, bad=100.0, digits=1,
                              id="log-trip", label_width=LABEL_WIDTH)
            yield CursorChart("Lost packets", "%", 0.0, 10.0, auto=True, warn=0.0, bad=10.0, digits=0,
                              id="log-lost", label_width=LABEL_WIDTH)
            yield CursorChart("roboRIO CPU", "%", 0.0, 100.0, warn=80.0, bad=95.0, digits=0,
                              id="log-cpu", label_width=LABEL_WIDTH)
        yield ModeStrip(self.timeline, id="log-modes")
        yield Static("", id="log-readout")
        options = [Option(self._event_line(k), id=str(k)) for k in range(len(self.timeline.events))]
        yield OptionList(*options, id="log-events")
        yield Footer()

    def on_mount(self) -> None:
        self.query_one("#log-charts").styles.height = "4fr"
        if not self.timeline.events:
            self.query_one(OptionList).add_option(Option("no events in this run", disabled=True))
        self.call_after_refresh(self.redraw)

    def on_resize(self) -> None:
        self.call_after_refresh(self.redraw)

    def _title(self) -> str:
        run = self.loaded.run
        parts = [when_text(self.timeline.start_unix), length_text(self.loaded.log.duration if self.loaded.log else None)]
        if run.team is not None:
            parts.append(f"team {run.team}")
        if run.match:
            parts.append(run.match)
        version = self.loaded.log.version if self.loaded.log else self.loaded.events.version if self.loaded.events else 0
        parts.append(f"v{version}")
        return " " + " · ".join(parts) + f" · {run.stem.name}"

    def _event_line(self, k: int) -> Text:
        e, t = self.timeline.events[k], self.timeline.event_times[k]
        style = {"estop": "bold red", "error": "red", "warning": "yellow", "print": "", "comms": "cyan",
                 "mode": "cyan", "fms": "magenta"}.get(e.kind, "")
        line = Text(no_wrap=True, overflow="ellipsis")
        line.append(clock(t).rjust(8) + "  ", "dim")
        line.append(e.text, style)
        return line

    # -- drawing --------------------------------------------------------------------------------
    def redraw(self) -> None:
        tl = self.timeline
        start, end = self.window
        self.query_one("#log-battery", CursorChart).show(tl.battery, start, end, self.cursor)
        self.query_one("#log-trip", CursorChart).show(tl.trip, start, end, self.cursor)
        self.query_one("#log-lost", CursorChart).show(tl.lost, start, end, self.cursor)
        self.query_one("#log-cpu", CursorChart).show(tl.cpu, start, end, self.cursor)
        self.query_one(ModeStrip).show(start, end, self.cursor)
        self.query_one("#log-readout", Static).update(self._readout())

    def _readout(self) -> Text:
        """The state at the cursor, in words: when, what the DS sent, what the robot ran."""
        tl = self.timeline
        r = tl.record_at(self.cursor)
        text = Text(no_wrap=True, overflow="ellipsis")
        text.append(f" ▸ {clock(self.cursor)}  ", "bold")
        if r is None:
            text.append("no records: this run has no readable .dslog", "dim")
            return text
        if r.enabled:
            text.append(f"DS {r.ds_mode} enabled", "bold green")
        else:
            text.append("DS disabled", "dim")
        text.append(" · ")
        text.append(f"robot {r.robot_mode}" if r.comms else "no robot comms", "" if r.comms else "bold red")
        if tl.estop is not None and self.cursor >= tl.estop:
            text.append(" · E-STOPPED", "bold red")
        if r.brownout:
            text.append(" · BROWNOUT", "bold red")
        if r.watchdog:
            text.append(" · watchdog", "yellow")
        window = f"   {clock(self.window[0], False)}–{clock(self.window[1], False)}"
        if self.window != (tl.begin, tl.end) and text.cell_len + len(window) <= self.size.width:
            text.append(window, "dim")
        return text

    # -- actions --------------------------------------------------------------------------------
    def _column_seconds(self) -> float:
        return (self.window[1] - self.window[0]) / self.query_one(ModeStrip).plot_width()

    def set_cursor(self, t: float) -> None:
        tl = self.timeline
        self.cursor = min(max(t, tl.begin), tl.end)
        start, end = self.window
        if not start <= self.cursor <= end:  # keep the cursor in view: move the window to it
            span = end - start
            start = min(max(self.cursor - span / 2, tl.begin), tl.end - span)
            self.window = (start, start + span)
        self.redraw()

    def action_move(self, columns: int) -> None:
        self.set_cursor(self.cursor + columns * self._column_seconds())

    def action_jump(self, where: int) -> None:
        self.set_cursor(self.timeline.begin if where == 0 else self.timeline.end)

    def action_zoom(self, factor: float) -> None:
        tl = self.timeline
        span = min(max((self.window[1] - self.window[0]) * factor, 1.0), tl.end - tl.begin)
        start = min(max(self.cursor - span / 2, tl.begin), tl.end - span)
        self.window = (start, start + span)
        self.redraw()

    def action_whole(self) -> None:
        self.window = (self.timeline.begin, self.timeline.end)
        self.redraw()

    def action_event(self, direction: int) -> None:
        times = self.timeline.event_times
        if not times:
            self.notify("no events in this run", timeout=3)
            return
        if direction > 0:
            k = bisect_right(times, self.cursor + 1e-6)
        else:
            k = bisect_left(times, self.cursor - 1e-6) - 1
        if 0 <= k < len(times):
            self.query_one(OptionList).highlighted = k  # moves the cursor (below)

    def action_close(self) -> None:
        """q: quit ``fieldbox logs``; in the app, close the viewer (this screen and the list)."""
        if not self.embedded:
            self.app.exit()
            return
        self.app.pop_screen()
        if isinstance(self.app.screen, RunsScreen):
            self.app.pop_screen()

    def action_back(self) -> None:
        if self.can_go_back:
            self.app.pop_screen()
        else:
            self.app.exit()

    def on_option_list_option_highlighted(self, message: OptionList.OptionHighlighted) -> None:
        if message.option.id is not None:
            self.set_cursor(self.timeline.event_times[int(message.option.id)])

    def on_option_list_option_selected(self, message: OptionList.OptionSelected) -> None:
        if message.option.id is not None:
            self.set_cursor(self.timeline.event_times[int(message.option.id)])


class RunsScreen(Screen[None]):
    """The runs in a folder, newest first: Enter (or o) opens one. ``embedded``: opened from the
    app (its command palette), where Esc and q close the viewer rather than quit, and Enter
    stays the robot's Disable (so o opens)."""

    BINDINGS = [Binding("enter", "open", "open", show=False), Binding("o", "open", "open"),
                Binding("r", "reload", "reload"), Binding("q,escape", "close", "close")]
    DEFAULT_CSS = """
    RunsScreen #runs-title { height: auto; text-style: bold; background: $panel; }
    RunsScreen DataTable { height: 1fr; }
    """

    def __init__(self, folder: Path, runs: list[Run], embedded: bool = False) -> None:
        super().__init__()
        self.folder, self.runs, self.embedded = folder, runs, embedded

    def compose(self) -> ComposeResult:
        yield Static(self._title(), id="runs-title")
        yield DataTable(cursor_type="row", zebra_stripes=True, id="runs")
        yield Footer()

    def _title(self) -> str:
        n = len(self.runs)
        return f" {n} run{'' if n == 1 else 's'} in {self.folder} · {'o' if self.embedded else 'Enter'} opens one"

    def action_close(self) -> None:
        if self.embedded:
            self.app.pop_screen()
        else:
            self.app.exit()

    def on_mount(self) -> None:
        self._fill()

    def _fill(self) -> None:
        table = self.query_one(DataTable)
        table.clear(columns=True)
        table.add_columns("Date", "Length", "Team", "Match", "File")
        for k, run in enumerate(self.runs):
            name = run.stem.name if not run.problem else f"{run.stem.name}  ⚠ {run.problem}"
            table.add_row(when_text(run.start), length_text(run.duration),
                          "—" if run.team is None else str(run.team), run.match or "—", name, key=str(k))
        table.focus()

    def action_open(self) -> None:
        table = self.query_one(DataTable)
        if self.runs and table.cursor_row is not None and 0 <= table.cursor_row < len(self.runs):
            self._open(self.runs[table.cursor_row])

    def _open(self, run: Run) -> None:
        """The run's screen; a run none of whose files can be read stays in the list, and a
        toast says why (an empty chart would say nothing)."""
        loaded = load(run)
        if loaded.log is None and loaded.events is None:
            self.notify("\n".join(loaded.problems), title="cannot open this run", severity="error", timeout=8)
            return
        self.app.push_screen(LogScreen(loaded, can_go_back=True, embedded=self.embedded))

    def action_reload(self) -> None:
        self.runs = find_runs(self.folder)
        self.query_one("#runs-title", Static).update(self._title())
        self._fill()

    def on_data_table_row_selected(self, message: DataTable.RowSelected) -> None:
        if message.row_key.value is None:
            return
        self._open(self.runs[int(message.row_key.value)])


def open_viewer(app: App[object], folder: Path) -> bool:
    """The list of runs in ``folder`` over ``app``'s screen (the app's command palette); False,
    and a toast saying why, when there is none."""
    runs = find_runs(folder) if folder.is_dir() else []
    if not runs:
        app.notify(f"No NI log files (.dslog/.dsevents) in {folder} yet: a DS writes them once it has robot "
                   "comms or an FMS", severity="warning", timeout=6)
        return False
    app.push_screen(RunsScreen(folder, runs, embedded=True))
    return True


class LogViewerApp(App[None]):
    """``fieldbox logs``: the list of runs in a folder, or one run."""

    TITLE = "fieldbox logs"

    def __init__(self, folder: Path | None = None, runs: list[Run] | None = None,
                 loaded: LoadedRun | None = None, theme_name: str | None = None) -> None:
        super().__init__()
        self.folder, self.runs, self.loaded = folder, runs, loaded
        self.theme_problems = install_themes(self, theme_name)

    def get_theme_variable_defaults(self) -> dict[str, str]:
        return {**super().get_theme_variable_defaults(), **variable_defaults()}

    def on_mount(self) -> None:
        for problem in self.theme_problems:
            self.notify(problem, severity="warning")
        if self.loaded is not None:
            self.push_screen(LogScreen(self.loaded))
        else:
            assert self.folder is not None
            self.push_screen(RunsScreen(self.folder, self.runs or []))


__all__ = ["LogScreen", "LogViewerApp", "RunsScreen", "Timeline", "clock", "open_viewer"]
