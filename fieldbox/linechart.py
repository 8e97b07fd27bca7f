"""A time chart drawn as a line, readable when the value is flat.

The first battery chart filled every column up to its value: a steady 12.4 V was a solid
block, and a block says nothing at a glance. Here the value is a line of braille dots (two
time buckets and four levels a cell), steps joined by vertical strokes, over a labelled
scale: a flat 12.4 V is a thin line at four fifths of a 6-14 V scale, a sag is a dip in it.

* ``plot(points, start, end)``: ``(time, value)`` pairs in time order (value None: unknown),
  bucketed into two buckets a column; a bucket keeps its lowest value (``aggregate="min"``,
  a battery's dips) or its highest (``"max"``, a trip time's spikes). Buckets with no value
  stay blank: a gap in the data is a gap in the line.
* The scale is fixed (``lo``..``hi``), or grows from ``hi`` to a round figure above the
  highest value shown (``auto=True``: trip times, lost packets).
* Values past ``warn``/``bad`` thresholds (below for a battery, above for a trip time) are
  drawn in the theme's warning and error colours.

The title line says the latest value, the lowest and the highest of the window. Drawing
happens only when a bucket or the size changed.
"""

from __future__ import annotations

import bisect
import math
from typing import Sequence

from rich.style import Style
from rich.text import Text
from textual.widget import Widget

_BRAILLE = 0x2800
#: The dot bits of a braille cell, [column][row from the top].
_DOTS = ((0x01, 0x02, 0x04, 0x40), (0x08, 0x10, 0x20, 0x80))


def nice_ceiling(value: float) -> float:
    """The smallest of 1, 2, 5 times a power of ten at or above ``value`` (> 0)."""
    if value <= 0 or not math.isfinite(value):
        return 1.0
    power = 10.0 ** math.floor(math.log10(value))
    for step in (1.0, 2.0, 5.0, 10.0):
        if value <= step * power * (1 + 1e-9):
            return step * power
    return 10.0 * power


def bucket(points: Sequence[tuple[float, float | None]], start: float, end: float, n: int,
           lowest: bool, hold: float = 0.0) -> tuple[list[float | None], float | None, float | None]:
    """The lowest (or highest) value of each of ``n`` equal time buckets over [start, end],
    and the lowest and highest sample of the window (None, None: none): a title's "low · high"
    reads the samples, not the buckets, whose lowest values hide a window's highest one.

    A sample stands for the ``hold`` seconds before it (its sampling period): where buckets
    are shorter than that, it fills each of them, so samples twice a second draw a line on a
    wide chart rather than dots. None (nothing known then) fills nothing: a gap."""
    out: list[float | None] = [None] * max(0, n)
    low: float | None = None
    high: float | None = None
    if n <= 0 or end <= start:
        return out, low, high
    if not isinstance(points, list):
        points = list(points)
    scale = n / (end - start)
    last = n - 1
    span = int(hold * scale)  # buckets before its own that a sample covers too
    isfinite = math.isfinite
    for i in range(bisect.bisect_left(points, (start,)), len(points)):
        t, v = points[i]
        if t > end:
            break
        if v is None or not isfinite(v):
            continue
        if low is None or v < low:
            low = v
        if high is None or v > high:
            high = v
        column = min(last, int((t - start) * scale))
        for c in range(max(0, column - span), column + 1):
            current = out[c]
            if current is None or (v < current if lowest else v > current):
                out[c] = v
    return out, low, high


class LineChart(Widget):
    """A titled line chart over a time window (see the module docstring)."""

    DEFAULT_CSS = """
    LineChart { height: 6; width: 1fr; }
    LineChart > .line-chart--line { color: $success; text-style: bold; }
    LineChart > .line-chart--warn { color: $warning; text-style: bold; }
    LineChart > .line-chart--bad { color: $error; text-style: bold; }
    LineChart > .line-chart--axis { color: $text-muted; }
    LineChart > .line-chart--title { text-style: bold; }
    """
    COMPONENT_CLASSES = {"line-chart--line", "line-chart--warn", "line-chart--bad", "line-chart--axis",
                         "line-chart--title"}

    def __init__(self, title: str, unit: str, lo: float, hi: float, *, auto: bool = False,
                 aggregate: str = "max", warn: float | None = None, bad: float | None = None,
                 below: bool = False, digits: int = 1, window_text: str = "",
                 label_width: int | None = None, hold: float = 0.0, id: str | None = None,
                 classes: str | None = None) -> None:
        super().__init__(id=id, classes=classes)
        if not hi > lo:
            raise ValueError("a chart needs hi > lo")
        self.title, self.unit = title, unit
        self.lo, self.hi, self.auto = lo, hi, auto
        self.lowest = aggregate == "min"
        self.warn, self.bad, self.below = warn, bad, below
        self.digits = digits
        self.window_text = window_text
        self.label_width = label_width  # charts stacked with the same one line up in time
        self.hold = hold  # the samples' period (see bucket)
        self._points: Sequence[tuple[float, float | None]] = ()
        self._span = (0.0, 1.0)
        self._drawn: tuple | None = None
        self.buckets: list[float | None] = []
        self.latest: float | None = None
        self.range: tuple[float | None, float | None] = (None, None)  # the window's lowest and highest sample

    # -- data ----------------------------------------------------------------------------------
    def plot(self, points: Sequence[tuple[float, float | None]], start: float, end: float,
             window_text: str | None = None) -> None:
        """Draw ``(time, value)`` points (in time order) that fall in [start, end]."""
        self._points, self._span = points, (start, end)
        if window_text is not None:
            self.window_text = window_text
        width = self._plot_width()
        buckets, low, high = bucket(points, start, end, width * 2, self.lowest, self.hold)
        latest = next((v for _, v in reversed(points) if v is not None and start <= _ <= end), None) \
            if points else None
        key = (tuple(buckets), latest, low, high, self.window_text, self.size)
        if key != self._drawn:
            self._drawn = key
            self.buckets, self.latest, self.range = buckets, latest, (low, high)
            self.refresh()

    def on_resize(self) -> None:
        self.plot(self._points, *self._span)

    # -- geometry --------------------------------------------------------------------------------
    def _scale(self) -> tuple[float, float]:
        hi = self.hi
        if self.auto:
            top = max((v for v in self.buckets if v is not None), default=0.0)
            hi = max(hi, nice_ceiling(top))
        return self.lo, hi

    def _ticks(self, lo: float, hi: float, rows: int) -> dict[int, str]:
        """Labels by row: the scale's ends, and round values between them about every four
        rows (12, 10, 8 on a 6-14 V scale), each on the row nearest to it."""
        labels = {0: self._label(hi), rows - 1: self._label(lo)}
        if rows < 5:
            return labels
        step = nice_ceiling((hi - lo) / max(1, rows // 4))
        value = math.floor(hi / step) * step
        while value > lo + step / 2:
            row = round((hi - value) / (hi - lo) * (rows - 1))
            if 1 < row < rows - 2 and not any(abs(row - r) < 2 for r in labels):
                labels[row] = self._label(value)
            value -= step
        return labels

    def _label(self, value: float) -> str:
        if value == int(value):
            return f"{value:.0f}"
        return f"{value:.{max(1, min(self.digits, 2))}f}".rstrip("0")

    def _label_width(self) -> int:
        if self.label_width is not None:
            return self.label_width
        lo, hi = self.lo, self.hi
        if self.auto:
            hi = max(hi, 1000.0)  # room for a scale that grows, so the plot does not shift
        return max(len(self._label(lo)), len(self._label(hi)), len(self._label((lo + hi) / 2))) + 1

    def _plot_width(self) -> int:
        return max(1, self.size.width - self._label_width() - 1)

    def _classify(self, v: float) -> str:
        def past(limit: float | None) -> bool:
            return limit is not None and (v < limit if self.below else v > limit)

        return "bad" if past(self.bad) else "warn" if past(self.warn) else "line"

    # -- drawing ---------------------------------------------------------------------------------
    def render(self) -> Text:
        width, height = self.size.width, self.size.height
        styles = {name: self.get_component_rich_style(f"line-chart--{name}")
                  for name in ("line", "warn", "bad", "axis", "title")}
        text = Text(no_wrap=True, overflow="crop")
        text.append_text(self._title_line(width, styles))
        axis = height >= 6
        rows = max(1, height - 1 - (1 if axis else 0))
        lo, hi = self._scale()
        label_w = self._label_width()
        plot_w = max(1, width - label_w - 1)
        buckets: list[float | None] = self.buckets if len(self.buckets) == plot_w * 2 else [None] * (plot_w * 2)
        cells = self._cells(buckets, rows, plot_w, lo, hi)
        labels = self._ticks(lo, hi, rows)
        empty = all(v is None for v in buckets)
        for row in range(rows):
            text.append("\n")
            label = labels.get(row)
            text.append((label or "").rjust(label_w - 1) + (" ┤" if label else "  │")[-2:], styles["axis"])
            if empty and row == rows // 2:
                note = "no data yet"
                text.append(note.center(plot_w)[:plot_w], styles["axis"])
                continue
            self._append_row(text, cells[row], styles)
        if axis:  # the time axis: the window's start on the left, now on the right
            text.append("\n")
            start = f"-{self.window_text}" if self.window_text else ""
            line = " " * (label_w - 1) + " └" + "─" * max(0, plot_w - 1)
            if start and plot_w > len(start) + 8:
                line = line[:label_w + 1] + start + line[label_w + 1 + len(start):-3] + "now"
            text.append(line[:width], styles["axis"])
        return text

    def _title_line(self, width: int, styles: dict[str, Style]) -> Text:
        """The title, the latest value, the window's low and high, and how long the window is.

        When the line is too narrow, whole parts go, in an order chosen so that what stays
        still means what it says: first "last 10 s", then "low X · high Y" (a cut "low 12.56 V"
        with no "high" after it reads as a low-battery alarm), never a number cut in two.
        Only the title itself is ever cut, with an ellipsis."""
        line = Text(no_wrap=True, overflow="ellipsis")
        line.append(self.title, styles["title"])
        if self.latest is not None:
            value = f"  {self._value(self.latest)}"
            if line.cell_len + len(value) <= width:
                line.append(value, styles[self._classify(self.latest)])
            else:  # the value matters more than the end of the title: cut the title instead
                keep = width - len(value) - 1
                if keep >= 3:
                    line = Text(no_wrap=True, overflow="ellipsis")
                    line.append(self.title[:keep] + "…", styles["title"])
                    line.append(value, styles[self._classify(self.latest)])
        low, high = self.range
        if low is not None and high is not None:
            span = f"   low {self._value(low)} · high {self._value(high)}"
            if line.cell_len + len(span) <= width:
                line.append(span, styles["axis"])
        if self.window_text:
            window = f"last {self.window_text}"
            pad = width - line.cell_len - len(window)
            if pad >= 2:
                line.append(" " * pad + window, styles["axis"])
        line.truncate(width, overflow="ellipsis")
        return line

    def _value(self, v: float) -> str:
        return f"{v:.{self.digits}f}{' ' if self.unit and not self.unit.startswith('%') else ''}{self.unit}"

    def _cells(self, buckets: list[float | None], rows: int, plot_w: int, lo: float,
               hi: float) -> list[list[tuple[int, str]]]:
        """Per row, per column: (braille dot bits, style name)."""
        levels = rows * 4
        grid = [[0] * plot_w for _ in range(rows)]
        kind = [["" for _ in range(plot_w)] for _ in range(rows)]
        rank = {"": 0, "line": 1, "warn": 2, "bad": 3}
        previous: int | None = None
        span = hi - lo
        for i, v in enumerate(buckets):
            if v is None:
                previous = None
                continue
            level = round((min(max(v, lo), hi) - lo) / span * (levels - 1))
            name = self._classify(v)
            column, side = divmod(i, 2)
            lo_level, hi_level = (level, level) if previous is None else (min(level, previous), max(level, previous))
            if previous is not None and previous != level:  # a step: the stroke joins the old level
                lo_level, hi_level = (previous + 1, level) if level > previous else (level, previous - 1)
            for lv in range(lo_level, hi_level + 1):
                from_top = levels - 1 - lv
                row, dot = divmod(from_top, 4)
                grid[row][column] |= _DOTS[side][dot]
                if rank[name] > rank[kind[row][column]]:
                    kind[row][column] = name
            previous = level
        return [[(grid[r][c], kind[r][c]) for c in range(plot_w)] for r in range(rows)]

    @staticmethod
    def _append_row(text: Text, cells: list[tuple[int, str]], styles: dict[str, Style]) -> None:
        run: list[str] = []
        run_style = None
        for bits, name in cells:
            style = name or "axis"
            if style != run_style and run:
                text.append("".join(run), styles[run_style] if run_style else None)
                run = []
            run_style = style
            run.append(chr(_BRAILLE + bits) if bits else " ")
        if run:
            text.append("".join(run), styles[run_style] if run_style else None)
