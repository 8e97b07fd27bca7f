"""Small widgets and renderers the panels share.

* :class:`StatusLight`: the Driver Station's lights (robot comms, robot code, joysticks, FMS):
  a coloured lamp and a label, coloured by the theme (``$success``, ``$warning``,
  ``$error``), so they read from the back of a classroom.
* :class:`InfoLine`: a line of text that repaints only itself when it changes.
* :class:`EventLog`: the ``(time, text)`` events a core keeps, written as they come.
* :class:`PathPrompt`: a modal that asks where to write a file.
* :class:`Palette`: Textual's command palette, whose command runs with ctrl+s (Enter is the
  robot's disable key everywhere).
* :func:`axis_bar`, :func:`level_bar`, :func:`pov_arrow`: one-line pictures of a joystick
  axis (-1..1 from the centre), a level (0..1) and a POV angle, as rich ``Text``.
* :func:`key_hints`: a panel's keys as the panels show them; :func:`theme_colour`: a theme
  colour for a rich style.

Widgets here only redraw when their content changes: panels call them ten times a second.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any, Iterable, TypeVar

from rich.style import Style
from rich.text import Text
from textual.app import ComposeResult
from textual.binding import Binding
from textual.content import Content
from textual.css.styles import RulesMap
from textual.strip import Strip
from textual.style import Style as VisualStyle
from textual.visual import RenderOptions, Visual
from textual.command import CommandPalette
from textual.containers import Vertical
from textual.screen import ModalScreen
from textual.widget import Widget
from textual.widgets import Checkbox, Input, Label, Log

from roles.cores.views import StreamView

T = TypeVar("T")


# -- text boxes --------------------------------------------------------------------------------
class TextBox(Input):
    """A text box of fieldbox's. Space is the robot's e-stop wherever the focus is (the app takes
    it before any widget, fieldbox/app.py ``on_event``; ctrl+space types a space): the box says
    it does not take Space, so the footer keeps offering "space E-stop" while it has the focus
    (Textual leaves out of the footer every key the focused widget takes)."""

    def check_consume_key(self, key: str, character: str | None) -> bool:
        return key != "space" and super().check_consume_key(key, character)


# -- one-line pictures ---------------------------------------------------------------------
_EIGHTHS_LEFT = " ▏▎▍▌▋▊▉█"  # a cell filled from its left edge, in eighths
_POV_ARROWS = "↑↗→↘↓↙←↖"


def axis_bar(value: float, width: int = 21, *, style: str | Style = "", track: str | Style = "dim") -> Text:
    """An axis -1..1 as a bar growing from a centre mark, in half-cell steps.

    ``width`` is the whole bar (odd: a centre cell and two equal halves)."""
    half = max(1, (width - 1) // 2)
    if not math.isfinite(value):
        value = 0.0
    value = max(-1.0, min(1.0, value))
    steps = round(abs(value) * half * 2)  # half cells
    full, odd = divmod(steps, 2)
    bar = "█" * full
    text = Text()
    if value < 0:
        fill = ("▐" if odd else "") + bar
        text.append("·" * (half - len(fill)), track)
        text.append(fill, style)
    else:
        text.append("·" * half, track)
    text.append("│", "bold")
    if value > 0:
        fill = bar + ("▌" if odd else "")
        text.append(fill, style)
        text.append("·" * (half - len(fill)), track)
    else:
        text.append("·" * half, track)
    return text


def level_bar(fraction: float, width: int = 8, *, style: str | Style = "", track: str | Style = "dim") -> Text:
    """A level 0..1 as a bar filled from the left, in eighths of a cell."""
    if not math.isfinite(fraction):
        fraction = 0.0
    eighths = round(max(0.0, min(1.0, fraction)) * width * 8)
    full, part = divmod(eighths, 8)
    text = Text("█" * full, style)
    if full < width:
        if part:
            text.append(_EIGHTHS_LEFT[part], style)
        empty = width - full - (1 if part else 0)
        text.append("·" * empty, track)
    return text


def pov_arrow(degrees: int) -> str:
    """The arrow for a POV angle (0 = up, clockwise), or a dot when centred (-1)."""
    if degrees < 0:
        return "·"
    return _POV_ARROWS[round(degrees / 45) % 8]


def key_hints(rows: Iterable[tuple[str, Iterable[tuple[str, str]]]], *, title_width: int,
              gap: int = 3) -> Text:
    """Rows of ``(title, [(key, what it does), ...])``: the title in bold, padded to
    ``title_width``, then each key drawn as a keycap and what it does, ``gap`` spaces apart.
    Where a row does not fit, it breaks between two keys, never inside one (:class:`KeyHints`)."""
    return KeyHints([(title, list(pairs)) for title, pairs in rows], title_width=title_width, gap=gap)


class KeyHints(Text):
    """Key hints that break only between keys. As text (``.plain``, ``str()``) each row is one
    line; drawn in a widget, a row too long for its width goes on under its title, a whole key
    and what it does at a time. Plain wrapping broke anywhere: "F1" ended one line and "more"
    began the next, which reads as nothing (issue 31)."""

    def __init__(self, rows: list[tuple[str, list[tuple[str, str]]]], *, title_width: int, gap: int) -> None:
        super().__init__()
        self.rows = rows
        self.title_width = title_width
        self.gap = gap
        self.append_text(self.laid_out(None))

    @staticmethod
    def _piece(key: str, what: str) -> Text:
        piece = Text()
        piece.append(f" {key} ", "reverse bold")
        piece.append(f" {what}")
        return piece

    def laid_out(self, width: int | None) -> Text:
        """The hints with a line break wherever the next key would pass ``width`` (None: one
        line a row)."""
        text = Text()
        for n, (title, pairs) in enumerate(self.rows):
            if n:
                text.append("\n")
            text.append(f"{title:<{self.title_width}}", "bold")
            column = max(self.title_width, len(title))
            first = True
            for key, what in pairs:
                piece = self._piece(key, what)
                gap = 0 if first else self.gap
                if width is not None and not first and column + gap + piece.cell_len > width:
                    text.append("\n" + " " * self.title_width)
                    column, gap = self.title_width, 0
                if gap:
                    text.append(" " * gap)
                text.append_text(piece)
                column += gap + piece.cell_len
                first = False
        return text

    def visualize(self) -> Visual:
        """What Textual draws (it asks a renderable for this first): the hints laid out for
        the width they get."""
        return _KeyHintsVisual(self)


class _KeyHintsVisual(Visual):
    def __init__(self, hints: KeyHints) -> None:
        self.hints = hints
        self._laid: dict[int, Content] = {}

    def _content(self, width: int) -> Content:
        content = self._laid.get(width)
        if content is None:
            content = self._laid[width] = Content.from_rich_text(self.hints.laid_out(width))
        return content

    @property
    def plain(self) -> str:
        """The hints as text, a row a line (as a Content's ``plain``, before wrapping)."""
        return self.hints.plain

    def render_strips(self, width: int, height: int | None, style: VisualStyle,
                      options: RenderOptions) -> list[Strip]:
        return self._content(width).render_strips(width, height, style, options)

    def get_optimal_width(self, rules: RulesMap, container_width: int) -> int:
        return max((line.cell_len for line in self.hints.split("\n")), default=0)

    def get_minimal_width(self, rules: RulesMap) -> int:
        return self._content(1).get_minimal_width(rules)

    def get_height(self, rules: RulesMap, width: int) -> int:
        return self._content(width).get_height(rules, width)


def theme_colour(app: Any, name: str, fallback: str) -> str:
    """The app theme's ``$name`` as a colour a rich style takes, or ``fallback`` when the
    theme does not set it to a plain ``#rrggbb`` (rich styles know nothing of themes: a cell
    drawn with one is drawn again when the theme changes)."""
    value = app.theme_variables.get(name)
    return value if value and value.startswith("#") else fallback


# -- a checkbox -------------------------------------------------------------------------
class Tick(Checkbox):
    """A checkbox whose mark says ticked or not without colour: "X" ticked, blank not.

    Textual's Checkbox shows the same "X" either way and only changes its colour, which a
    colour-blind user, a monochrome terminal or a screenshot in print cannot tell apart (F8's
    roles, the Console tab's levels)."""

    @property
    def _button(self) -> Content:
        self.BUTTON_INNER = "X" if self.value else " "
        return super()._button


# -- a line of text ------------------------------------------------------------------------
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


# -- a core's events --------------------------------------------------------------------------
class EventLog(Log):
    """The ``(time, text)`` items of a core's bounded deque (a DS's events, an FMS's match log):
    each call writes only what was added since the last one, found by the identity of the
    last item written (the deque drops its oldest as it fills, so a count would not do)."""

    DEFAULT_CSS = """
    EventLog { border: round $panel-lighten-2; border-title-color: $text; overflow-x: hidden; overflow-y: auto; }
    """

    def __init__(self, *, max_lines: int = 200, id: str | None = None) -> None:
        super().__init__(max_lines=max_lines, id=id)
        self.can_focus = False
        self._cursor = StreamCursor()

    def follow(self, items: StreamView[tuple[float, str]], t0: float, source: object = None) -> None:
        """Write the new items of the stream ``items`` (another ``source``'s starts afresh),
        each as its seconds since ``t0`` and its text."""
        new, fresh = self._cursor.take(items, source)
        if fresh:
            self.clear()
        new = new[-self.max_lines:] if self.max_lines else new
        if new:  # a narrow log gives its width to the text: tenths of a second there
            stamp = "{:6.1f} " if 0 < self.size.width < 50 else "{:9.3f}  "
            # (a wire in its own process starts a moment before the app reads its clock)
            self.write_lines(stamp.format(max(0.0, t - t0)) + text for t, text in new)


class StreamCursor:
    """Where a reader stands in a view's stream (roles/cores/views.py StreamView: console
    lines, events, the match log): the items appended since the last look, found by their
    numbers. A stream from another source (``source``: whose it is, e.g. the DS's team) starts
    over, and ``take`` says so."""

    __slots__ = ("source", "seq")

    def __init__(self) -> None:
        self.source: object = None
        self.seq = -1  # the number of the next item not yet taken; -1: nothing taken

    def take(self, stream: StreamView[T], source: object = None) -> tuple[list[T], bool]:
        """``(new items, fresh)``: ``fresh`` when the reader should forget what it showed."""
        fresh = self.seq < 0 or source != self.source or not stream.first_seq <= self.seq <= stream.end
        new = list(stream.items) if fresh else list(stream.since(self.seq))
        self.source, self.seq = source, stream.end
        return new, fresh

    def reset(self) -> None:
        self.source = None
        self.seq = -1


# -- asking for a path -----------------------------------------------------------------------
#: What a dialog's text box says of the robot's keys, which work there too (fieldbox/app.py).
ROBOT_KEYS_HINT = "Space e-stops, Enter disables the robot · ctrl+space types a space"


class PathPrompt(ModalScreen[str | None]):
    """Where to write a file. Ctrl+S accepts, Escape cancels. (Enter is the app's disable key
    everywhere, and Space its e-stop: a space in the path is typed with ctrl+space.)"""

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
            yield TextBox(self.default, id="pcap-path")
            yield Label("ctrl+s: write here   escape: cancel", classes="hint")
            yield Label(ROBOT_KEYS_HINT, classes="hint")

    def on_mount(self) -> None:
        field = self.query_one(Input)
        field.cursor_blink = False
        field.focus()

    def action_accept(self) -> None:
        value = self.query_one(Input).value.strip()
        self.dismiss(str(Path(value).expanduser()) if value else None)

    def action_cancel(self) -> None:
        self.dismiss(None)


# -- the command palette -----------------------------------------------------------------------
class Palette(CommandPalette):
    """Textual's command palette (ctrl+p), where Enter and Space are the robot's, as everywhere:
    ctrl+s runs the highlighted command (what Enter did), and a search needs no spaces (the
    match is fuzzy: "themenord" finds "Theme: nord"), or types one with ctrl+space."""

    BINDINGS = [Binding("ctrl+s", "run", "Run the command")]
    #: (70 characters: it shows whole in an 80-column terminal)
    PLACEHOLDER = "ctrl+s runs · ctrl+space types a space · Space e-stops, Enter disables"

    def __init__(self, **kwargs: Any) -> None:
        kwargs.setdefault("placeholder", self.PLACEHOLDER)
        super().__init__(**kwargs)

    async def action_run(self) -> None:
        # as Enter did: the first press highlights the first match (or runs the only one),
        # the next runs the highlighted command
        await self.query_one(Input).action_submit()


# -- the lights ----------------------------------------------------------------------------
class StatusLight(Widget):
    """A lamp and a label: ``set("on" | "off" | "warn" | "idle", label)``."""

    DEFAULT_CSS = """
    StatusLight { height: 1; width: 1fr; }
    StatusLight > .status-light--on { color: $success; }
    StatusLight > .status-light--off { color: $error; }
    StatusLight > .status-light--warn { color: $warning; }
    StatusLight > .status-light--idle { color: $text-muted; }
    """
    COMPONENT_CLASSES = {"status-light--on", "status-light--off", "status-light--warn", "status-light--idle"}
    STATES = ("on", "off", "warn", "idle")
    LAMP = "██"

    def __init__(self, label: str = "", state: str = "idle", *, id: str | None = None,
                 classes: str | None = None) -> None:
        super().__init__(id=id, classes=classes)
        self._label = label
        self._state = state if state in self.STATES else "idle"

    @property
    def state(self) -> str:
        return self._state

    @property
    def label(self) -> str:
        return self._label

    def set(self, state: str, label: str | None = None) -> None:
        """Change the lamp (and the label); redraws only when something changed."""
        if state not in self.STATES:
            raise ValueError(f"a status light is one of {', '.join(self.STATES)}, not {state!r}")
        label = self._label if label is None else label
        if (state, label) != (self._state, self._label):
            self._state, self._label = state, label
            self.refresh()

    def render(self) -> Text:
        lamp = self.get_component_rich_style(f"status-light--{self._state}")
        text = Text(self.LAMP, lamp)
        text.append(" ")
        text.append(self._label)
        return text
