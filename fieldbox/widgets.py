"""Small widgets and renderers the panels share.

* :class:`StatusLight`: the Driver Station's lights (robot comms, robot code, joysticks, FMS):
  a coloured lamp and a label, coloured by the theme (``$success``, ``$warning``,
  ``$error``), so they read from the back of a classroom.
* :class:`InfoLine`: a line of text that repaints only itself when it changes.
* :class:`EventLog`: the ``(time, text)`` events a core keeps, written as they come.
* :class:`PathPrompt`: a modal that asks where to write a file.
* :class:`FieldboxFooter`: Textual's Footer without its leak (textual#6666).
* :class:`FieldboxTabs`: Textual's TabbedContent, whose tab changes only when the user picks one.
* :func:`axis_bar`, :func:`level_bar`, :func:`pov_arrow`: one-line pictures of a joystick
  axis (-1..1 from the centre), a level (0..1) and a POV angle, as rich ``Text``.
* :func:`key_hints`: a panel's keys as the panels show them; :func:`theme_colour`: a theme
  colour for a rich style.

Widgets here only redraw when their content changes: panels call them ten times a second.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any, Iterable

from rich.style import Style
from rich.text import Text
from textual import on
from textual.app import ComposeResult
from textual.binding import Binding
from textual.containers import Vertical
from textual.geometry import Size
from textual.screen import ModalScreen
from textual.scroll_view import ScrollView
from textual.widget import Widget
from textual.widgets import Footer, Input, Label, Log, TabbedContent, TabPane
from textual.widgets._footer import FooterKey


def set_virtual_rows(view: ScrollView, rows: int, width: int | None = None) -> None:
    """Give ``view`` (one line per row, its own size set by its container) ``rows`` rows.

    Setting ``virtual_size`` asks for a layout of the whole screen, and a list that grows
    every 100 ms made the inspector lay out ten times a second, 19 ms each (docs/figures.md).
    The view's own size does not depend on its rows, so only its scrollbars change: this does
    what Textual's own ``_size_updated(layout=False)`` does for them. A scrollbar that appears
    or goes still lays the screen out (``show_vertical_scrollbar`` asks for it)."""
    size = Size(max(1, view.size.width if width is None else width), rows)
    old = view.virtual_size
    if size == old:
        return
    if not view.is_mounted or size.width != old.width:
        view.virtual_size = size
        return
    view.set_reactive(Widget.virtual_size, size)
    view._scroll_update(size)  # Textual 8 (pinned <9): scrollbars, and scroll clamped to the size
    view.refresh()


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


def key_hints(rows: Iterable[tuple[str, Iterable[tuple[str, str]]]], *, title_width: int) -> Text:
    """Rows of ``(title, [(key, what it does), ...])``: the title in bold, padded to
    ``title_width``, then each key drawn as a keycap and what it does."""
    text = Text()
    for n, (title, pairs) in enumerate(rows):
        if n:
            text.append("\n")
        text.append(f"{title:<{title_width}}", "bold")
        for i, (key, what) in enumerate(pairs):
            if i:
                text.append("   ")
            text.append(f" {key} ", "reverse bold")
            text.append(f" {what}")
    return text


def theme_colour(app: Any, name: str, fallback: str) -> str:
    """The app theme's ``$name`` as a colour a rich style takes, or ``fallback`` when the
    theme does not set it to a plain ``#rrggbb`` (rich styles know nothing of themes: a cell
    drawn with one is drawn again when the theme changes)."""
    value = app.theme_variables.get(name)
    return value if value and value.startswith("#") else fallback


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
        self._source: Any = None
        self._last: Any = None

    def follow(self, items: Any, t0: float) -> None:
        """Write the new items of the stream ``items`` (another stream starts afresh), each as
        its seconds since ``t0`` and its text."""
        source = items  # a stream keeps its identity from one view of its core to the next
        last = items[-1] if items else None
        if source is self._source and last is self._last:
            return
        copied = list(items)  # one C-level copy: the wire may append meanwhile
        start: int | None = 0
        if source is self._source and self._last is not None:
            start = next((i + 1 for i in range(len(copied) - 1, -1, -1) if copied[i] is self._last), None)
        if source is not self._source or start is None:
            self.clear()
            start = 0
        self._source, self._last = source, (copied[-1] if copied else None)
        new = copied[start:][-self.max_lines:] if self.max_lines else copied[start:]
        if new:  # a narrow log gives its width to the text: tenths of a second there
            stamp = "{:6.1f} " if 0 < self.size.width < 50 else "{:9.3f}  "
            # (a wire in its own process starts a moment before the app reads its clock)
            self.write_lines(stamp.format(max(0.0, t - t0)) + text for t, text in new)


# -- asking for a path -----------------------------------------------------------------------
class PathPrompt(ModalScreen[str | None]):
    """Where to write a file. Ctrl+S accepts, Escape cancels. (Enter is the app's disable key
    everywhere, so it cannot be the one that accepts.)"""

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


class FieldboxFooter(Footer):
    """Textual's Footer, whose keys are relabelled in place when they change.

    Textual's Footer rebuilds every key each time the screen says its bindings were updated:
    three to four times a tab switch, mostly with the same keys. Each key it mounts is
    styled from scratch (with two virtual style nodes for its component classes), then
    restyled twice more as its ``compact`` flag is bound to the Footer's (set, then cleared),
    and it dies in a reference cycle. Under ``benchmarks/field.py --app`` that was nearly
    all the app's cyclic garbage (230 000 objects every 10 s), and the full collections that
    freed it stopped the wire for 50-130 ms at a time.

    The binding also leaked: ``data_bind`` adds each key to the Footer's watcher list, which
    Textual 8 prunes only when ``compact`` changes, and it never does here, so every removed
    key stayed alive (Textualize/textual#6666; measured, 1.4 MB a tab switch).

    Here nothing happens while the keys show what they should. When they change (a tab
    switch), the keys already mounted are relabelled in place; keys left over are hidden and
    kept for a tab with more, and only keys missing are mounted. Keys mounted and dropped at
    each switch were still most of the app's cyclic garbage after the fixes in
    fieldbox/cycles.py. Keys get the Footer's ``compact`` before they mount instead of a
    binding; a change of ``compact`` rebuilds them all, and so does anything this does not
    relabel (binding groups, the palette's key).
    """

    _shown: tuple | None = None
    #: Keys shown first, whatever tab is in front: a narrow terminal cuts the footer's end,
    #: and the keys that stop the robot and quit must never be what is cut.
    FIRST_KEYS = ("space", "enter", "ctrl+q")

    @classmethod
    def _first(cls, key: str) -> int:
        return cls.FIRST_KEYS.index(key) if key in cls.FIRST_KEYS else len(cls.FIRST_KEYS)

    def _plain_keys(self) -> tuple[tuple, ...] | None:
        """The keys Footer.compose would show now, left to right, as ``(key, display,
        description, action, enabled, tooltip)``: one a action, its first binding. None where
        Textual would group keys."""
        get_display = self.app.get_key_display
        first: dict[str, tuple] = {}
        for _node, binding, enabled, tooltip in self.screen.active_bindings.values():
            if not binding.show:
                continue
            if binding.group is not None:
                return None
            if binding.action not in first:
                first[binding.action] = (binding.key, get_display(binding), binding.description,
                                         binding.action, enabled, tooltip)
        return tuple(sorted(first.values(), key=lambda spec: self._first(spec[0])))

    def _signature(self) -> tuple | None:
        """What the footer would show now, as ``(keys, fixed)``: the plain keys, which
        :meth:`_relabel` can change in place, and what only a rebuild changes (the palette's
        key, ``compact``, whether keys are grouped). None before the screen's bindings are
        known."""
        if not self._bindings_ready or not self.is_attached:
            return None
        palette = None
        if self.show_command_palette and self.app.ENABLE_COMMAND_PALETTE:
            found = self.screen.active_bindings.get(self.app.COMMAND_PALETTE_BINDING)
            if found is not None:
                _node, binding, enabled, tooltip = found
                palette = (binding.key, binding.description, enabled, binding.tooltip)
        keys = self._plain_keys()
        grouped = keys is None
        if grouped:  # anything that changes rebuilds
            keys = tuple((binding.key, binding.action, binding.description, enabled, tooltip,
                          binding.group)
                         for _node, binding, enabled, tooltip in self.screen.active_bindings.values()
                         if binding.show)
        return keys, (palette, self.compact, grouped)

    async def recompose(self) -> None:
        if not self.is_attached or self._pruning:
            return
        signature = self._signature()
        if signature is not None and signature == self._shown:
            return
        old = self._shown
        if (signature is not None and old is not None and signature[1] == old[1]
                and not signature[1][2] and await self._relabel(signature[0])):
            self._shown = signature
            return
        await super().recompose()

    async def _relabel(self, specs: tuple[tuple, ...]) -> bool:
        """Show ``specs`` with the keys mounted now: the keys left over are hidden, and only
        the keys missing are mounted (at most once each: as many as the most any tab shows).
        False (nothing touched) where the footer holds anything else than plain keys and the
        palette's key: then it is rebuilt."""
        keys: list[FooterKey] = []
        palette: FooterKey | None = None
        for child in self.children:
            if child.has_class("-textual-system"):
                continue
            if type(child) is not FooterKey or child.has_class("-grouped"):
                return False
            if child.has_class("-command-palette"):
                palette = child
            else:
                keys.append(child)
        async with self.batch():  # drawn once, as Textual's recompose is
            for key, spec in zip(keys, specs):
                self._label(key, *spec)
                key.display = True
            for key in keys[len(specs):]:  # kept, hidden, for a tab with more keys: a key
                key.display = False          # removed would die in a reference cycle
            if len(specs) > len(keys):
                new = [self._new_key(*spec) for spec in specs[len(keys):]]
                await self.mount_all(new, before=palette)
            self.styles.grid_size_columns = len(specs)
        return True

    @staticmethod
    def _label(key: FooterKey, name: str, display: str, description: str, action: str,
               enabled: bool, tooltip: str) -> None:
        """Give a mounted key what Footer.compose would give a new one."""
        if (key.key, key.key_display, key.description, key.action, not key._disabled,
                key.tooltip or "") == (name, display, description, action, enabled, tooltip or ""):
            return
        key.key, key.key_display, key.description, key.action = name, display, description, action
        key._disabled = not enabled
        key.set_class(not enabled, "-disabled")
        if (key.tooltip or "") != (tooltip or ""):
            key.tooltip = tooltip or None
        key.refresh(layout=True)  # its width follows its text

    def _new_key(self, name: str, display: str, description: str, action: str, enabled: bool,
                 tooltip: str) -> FooterKey:
        key = FooterKey(name, display, description, action, disabled=not enabled, tooltip=tooltip)
        self._give_compact(key)
        return key

    def _give_compact(self, key: FooterKey) -> None:
        """What Footer.compose's ``data_bind(compact=...)`` gave a key before it mounts: the
        Footer's ``compact``, and its class (the first watch that would set it is skipped)."""
        key.set_reactive(FooterKey.compact, self.compact)
        key.set_class(self.compact, "-compact")

    def _watch_compact(self, compact: bool) -> None:
        # Textual's keys followed the Footer's ``compact`` through their binding; ours are
        # made again (it is part of the signature, so the recompose does not skip).
        if self.is_attached:
            self.call_after_refresh(self.recompose)

    def compose(self) -> ComposeResult:
        self._shown = self._signature()
        widgets = list(super().compose())
        if self._plain_keys() is not None:  # no groups: the keys in the order _relabel gives them
            keys = [w for w in widgets if type(w) is FooterKey and not w.has_class("-command-palette")]
            ordered = iter(sorted(keys, key=lambda k: self._first(k.key)))
            widgets = [next(ordered) if w in keys else w for w in widgets]
        for widget in widgets:
            if isinstance(widget, FooterKey) and widget._reactive_connect:
                # Undo the data_bind Footer.compose made (the palette key has none: it stays
                # as Textual draws it) and give the key the value the binding would.
                widget._reactive_connect = None
                self._give_compact(widget)
            yield widget


class FieldboxTabs(TabbedContent):
    """Textual's TabbedContent, whose tab changes only when the user picks one.

    Textual makes the tab of a widget that receives the focus the active tab. Focus moves
    are queued, so a focus asked for in the tab being left (the inspector's list, when F7
    came a frame after F6), or handed by a focused widget to its sibling as its tab hides,
    arrived after the new tab was shown and took the user back to the old one (measured:
    F6 then F7 less than 30 ms apart ended on the inspector; the benchmark's tab cycling
    stayed on it for seconds). Here a focus arriving late is not a tab change: the message
    goes on to the app, which gives the focus back to the tab shown (``FieldboxApp``).
    """

    def _on_tab_pane_focused(self, event: TabPane.Focused) -> None:
        event.prevent_default()  # not TabbedContent's own handler, which switches tabs
