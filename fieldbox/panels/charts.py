"""The Charts tab (F1 F1 F1 F1): the selected DS's last minutes, as the NI Driver Station's
Charts tab draws them.

Round trip (worst of each half second), lost control packets per second, the battery (its
lowest of each half second, on a fixed 6-14 V scale so a sag looks like one) and the
roboRIO's CPU, over a window of 1, 5 or 10 minutes (``w``), with a strip under them saying
what the robot was told (disabled, autonomous, teleop, test, e-stopped, no comms). The
samples come from the app's :class:`~fieldbox.history.DsHistory`, taken whatever tab is
shown, so a chart opened after a fault still shows it.
"""

from __future__ import annotations

from typing import Any

from rich.text import Text
from textual.app import ComposeResult
from textual.binding import Binding
from textual.containers import Horizontal, Vertical
from textual.widget import Widget
from textual.widgets import Static

from ..history import SAMPLE_PERIOD
from ..linechart import LineChart
from ..widgets import theme_colour
from .base import Panel

WINDOWS = (60.0, 300.0, 600.0)
LABEL_WIDTH = 6

#: mode -> (cell, theme colour, fallback, legend)
MODE_CELLS = {
    "estop": ("█", "fb-estop", "red", "e-stop"),
    "auto": ("█", "warning", "yellow", "auto"),
    "teleop": ("█", "success", "green", "teleop"),
    "test": ("█", "primary", "blue", "test"),
    "disabled": ("▁", "text-muted", "grey50", "disabled"),
    "no comms": ("·", "error", "red", "no comms"),
}


def window_text(seconds: float) -> str:
    return f"{seconds / 60:g} min"


class ModeStrip(Widget):
    """One row: what the robot was told, a cell per time bucket, under the charts."""

    DEFAULT_CSS = "ModeStrip { height: 1; width: 1fr; }"

    def __init__(self, *, id: str | None = None) -> None:
        super().__init__(id=id)
        self._cells: tuple = ()

    def plot(self, points: Any, start: float, end: float) -> None:
        width = max(1, self.size.width - LABEL_WIDTH - 1)
        cells: list[str | None] = [None] * width
        if end > start and points:
            scale = width / (end - start)
            for t, mode in points:
                if start <= t <= end:
                    cells[min(width - 1, int((t - start) * scale))] = mode
        key = tuple(cells)
        if key != self._cells:
            self._cells = key
            self.refresh()

    def render(self) -> Text:
        text = Text(no_wrap=True, overflow="crop")
        text.append("mode".rjust(LABEL_WIDTH - 1) + "  ", "dim")
        for mode in self._cells:
            if mode is None:
                text.append(" ")
                continue
            cell, name, fallback, _ = MODE_CELLS.get(mode, ("?", "text", "white", mode))
            text.append(cell, theme_colour(self.app, name, fallback))
        return text


class ChartsPanel(Panel):
    TITLE = "Charts"
    SHORT_TITLE = "Charts"
    ID = "charts"
    can_focus = True

    BINDINGS = [Binding("w", "window", "Window 1/5/10 min")]

    DEFAULT_CSS = """
    ChartsPanel { layout: vertical; padding: 0 1; }
    ChartsPanel #charts-head { height: 1; }
    ChartsPanel #charts-grid { height: 1fr; layout: vertical; }
    ChartsPanel .charts-column { height: 1fr; }
    ChartsPanel #charts-modes-0 { display: none; }
    ChartsPanel.-wide #charts-grid { layout: horizontal; }
    ChartsPanel.-wide .charts-column { width: 1fr; height: 1fr; }
    ChartsPanel.-wide #charts-column-0 { margin-right: 3; }
    ChartsPanel.-wide #charts-modes-0 { display: block; }
    ChartsPanel.-wide LineChart { margin-bottom: 1; }
    ChartsPanel LineChart { height: 1fr; min-height: 4; }
    ChartsPanel #charts-none { height: auto; margin: 1 2; }
    """

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self.window = WINDOWS[0]  # a minute: the rest is a w away
        self._plotted: tuple | None = None  # what the charts were last drawn from

    def compose(self) -> ComposeResult:
        yield Static("", id="charts-none")
        yield Static("", id="charts-head")
        # two columns of two charts, each with the mode strip under it (side by side where the
        # panel is wide, one above the other elsewhere, the upper strip hidden)
        with Horizontal(id="charts-grid"):
            with Vertical(id="charts-column-0", classes="charts-column"):
                yield LineChart("Round trip", "ms", 0.0, 2.0, auto=True, warn=20.0, bad=100.0, digits=1,
                                label_width=LABEL_WIDTH, hold=SAMPLE_PERIOD, id="chart-trip")
                yield LineChart("Lost packets", "/s", 0.0, 5.0, auto=True, warn=0.0, bad=5.0, digits=1,
                                label_width=LABEL_WIDTH, hold=SAMPLE_PERIOD, id="chart-lost")
                yield ModeStrip(id="charts-modes-0")
            with Vertical(id="charts-column-1", classes="charts-column"):
                yield LineChart("Battery", "V", 6.0, 14.0, aggregate="min", warn=11.0, bad=7.0, below=True,
                                digits=2, label_width=LABEL_WIDTH, hold=SAMPLE_PERIOD, id="chart-battery")
                yield LineChart("roboRIO CPU", "%", 0.0, 100.0, warn=80.0, bad=95.0, digits=0,
                                label_width=LABEL_WIDTH, hold=SAMPLE_PERIOD, id="chart-cpu")
                yield ModeStrip(id="charts-modes-1")

    def on_mount(self) -> None:
        self.query_one("#charts-none").display = False

    def on_resize(self) -> None:
        self.set_class(self.size.width >= 140 and self.size.height >= 20, "-wide")

    def action_window(self) -> None:
        self.window = WINDOWS[(WINDOWS.index(self.window) + 1) % len(WINDOWS)]
        self.redraw_now()

    def refresh_view(self, engine, now: float) -> None:
        st = self.station()
        history = self.app.history.get(st.team) if st is not None and st.ds is not None else None  # type: ignore[attr-defined]
        none = st is None or st.ds is None
        self.set_shown("none", none, self._show_none)
        if none:
            self.set_text("charts-none", "No Driver Station runs here: nothing to chart. "
                                         "Press F8 to pick the roles.", layout=True)
            return
        # the samples come twice a second: the charts move when one comes, not ten times a
        # second (four charts bucketed and drawn again each refresh were a tenth of a core)
        latest = history.battery[-1][0] if history is not None and history.battery else now
        key = (st.team, latest, self.window, self.size, self.app.theme)
        if key == self._plotted:
            return
        self._plotted = key
        start, end = latest - self.window, latest
        text = window_text(self.window)
        head = Text()
        head.append(f"team {st.team}", "bold")
        head.append("  w: window   ", "dim")
        for mode, (cell, name, fallback, legend) in MODE_CELLS.items():
            head.append(cell, theme_colour(self.app, name, fallback))
            head.append(f" {legend}  ", "dim")
        self.set_text("charts-head", head)
        for ident, series in (("chart-trip", "trip"), ("chart-lost", "lost"), ("chart-battery", "battery"),
                              ("chart-cpu", "cpu")):
            points = list(history.series(series)) if history is not None else []
            self.query_one(f"#{ident}", LineChart).plot(points, start, end, text)
        modes = list(history.mode) if history is not None else []
        for strip in self.query(ModeStrip):
            strip.plot(modes, start, end)

    def _show_none(self, none: bool) -> None:
        self.query_one("#charts-none").display = none
        for ident in ("#charts-head", "#charts-grid"):
            self.query_one(ident).display = not none

