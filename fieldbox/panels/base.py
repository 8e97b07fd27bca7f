"""What every panel shares."""

from __future__ import annotations

from concurrent.futures import Future
from typing import TYPE_CHECKING, Any, Callable, cast

from textual.binding import Binding
from textual.containers import Container
from textual.widget import Widget
from textual.widgets import Static

from .. import seats

if TYPE_CHECKING:
    from roles.cores.commands import Command
    from roles.runtime.engine import Engine


class Reading:
    """What the panels read of an engine: its views (``field``, roles/cores/views.py, made
    once per refresh), everything else the engine's own. One per engine, so a panel that
    keeps the engine it last read sees the same object."""

    __slots__ = ("engine", "field")

    def __init__(self, engine: "Engine") -> None:
        self.engine = engine
        self.field: Any = None

    def __getattr__(self, name: str) -> Any:
        return getattr(self.engine, name)


def engine_of(engine: Any) -> Any:
    """The engine itself, where a panel was given what it reads of it (a :class:`Reading`)."""
    return engine.engine if isinstance(engine, Reading) else engine


def selected_station(engine: Any, team: int | None) -> Any:
    """The station of ``team`` on the engine's field, else its first (None: no stations)."""
    if engine is None or not engine.field.stations:
        return None
    stations = engine.field.stations
    return next((st for st in stations if st.team == team), stations[0])


#: How often a figure that changes with every packet is redrawn (``Panel.paced``), seconds.
NUMBERS_PERIOD = 0.5


class Panel(Container):
    """A tab's content. ``refresh_view`` copies state from the engine; it must be cheap and
    must not raise (the app logs and carries on if it does)."""

    #: The tab title.
    TITLE = ""
    #: The tab title where the long ones do not all fit (an 80-column terminal).
    SHORT_TITLE = ""
    #: The tab id (also the key used by ``--panel`` and the command palette).
    ID = ""
    #: It shows packets of the inspector's capture (:meth:`capture_ring`): while it is shown,
    #: a classroom tab's inspector captures as if it were.
    READS_CAPTURE = False

    #: A panel taller than the screen scrolls from the keyboard (a widget that uses these
    #: keys itself, a list or a slider, has them first).
    BINDINGS = [
        Binding("pageup", "page_up", "Page up", show=False),
        Binding("pagedown", "page_down", "Page down", show=False),
    ]

    def check_action(self, action: str, parameters: tuple[object, ...]) -> bool | None:
        """The footer offers no key this app may not use here (:meth:`refusal`)."""
        return self.refusal(action, parameters) is None

    def refusal(self, action: str, parameters: tuple[object, ...] = ()) -> str | None:
        """Why this app may not do ``action`` of this tab's keys, or None: a classroom seat
        may not command what is not its own (fieldbox/seats.py). A key refused here is not
        in the footer; pressed anyway, the app says why (``FieldboxApp.on_key``)."""
        return seats.refusal(getattr(self.app, "seat", None), action, self.ID)

    #: Refreshed by the app's timer every this many ticks (``REFRESH_PERIOD``, 100 ms): a
    #: panel of counters and lists redraws at a pace a person can read (each redraw of a
    #: table or a list is most of the app's CPU while it is shown); the state a driver acts
    #: on (the DS, the joysticks) every tick.
    REFRESH_TICKS = 1
    #: The widgets inside whose style follows the panel's own focus (CSS such as
    #: ``JoysticksPanel:focus #js-keys``), as selectors.
    FOCUS_STYLED: tuple[str, ...] = ()

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self._shown: dict[str, Any] = {}  # what set_shown last applied, per key
        self._paced: dict[str, float] = {}  # when paced() last said yes, per key

    def paced(self, key: str, now: float, period: float = NUMBERS_PERIOD) -> bool:
        """True at most once every ``period`` seconds of the wire's clock for ``key`` (and
        again after the clock went back): for figures that change with every packet."""
        last = self._paced.get(key)
        if last is not None and 0.0 <= now - last < period:
            return False
        self._paced[key] = now
        return True

    def watch_has_focus(self, has_focus: bool) -> None:
        """Restyle the panel and :data:`FOCUS_STYLED`, not every widget of its tab: Textual
        restyles a focused widget's whole subtree, which made a panel's focus and blur the
        heaviest part of a tab switch. (A test checks every panel's styles against Textual's
        full restyle.)"""
        nodes: list[Widget] = [self]
        for selector in self.FOCUS_STYLED:
            nodes.extend(self.query(selector))
        self.app.stylesheet.update_nodes(nodes, animate=True)

    def refresh_view(self, engine: "Engine", now: float) -> None:
        """Copy what changed from the engine's cores into the widgets."""

    @property
    def engine(self) -> "Engine":
        """The app's engine as the panels read it: its views from the last refresh (the
        app's ``reading``), its commands the engine's own."""
        engine: Engine | None = getattr(self.app, "engine", None)
        reading: Reading | None = getattr(self.app, "reading", None)
        if reading is not None and reading.engine is engine and reading.field is not None:
            return cast("Engine", reading)  # a Reading stands in for its engine: it forwards all but the views
        return cast("Engine", engine)  # None only before the app has one: the panels that may run then check

    def redraw_now(self) -> None:
        """Refresh this panel at once (after a key), from views made now."""
        reading = self.app.read_now()  # type: ignore[attr-defined]
        if reading is not None:
            self.refresh_view(reading, reading.now())

    def send(self, command: Command, done: Callable[[Future], Any] | None = None) -> bool:
        """Send a command (roles/cores/commands.py) to the wire without waiting (``app.send``);
        a refusal (CommandError) is a warning notification with the reason, or goes to
        ``done(future)``. True if it was sent."""
        return self.app.send(command, done)  # type: ignore[attr-defined]

    def station(self) -> Any:
        """The station of the team the DS keys act on (the app's ``selected_team``), else
        the field's first, as the last refresh's views show it; None when no station runs."""
        return selected_station(self.engine, getattr(self.app, "selected_team", None))

    def capture_ring(self) -> Any:
        """The inspector's capture ring (None without one): one capture serves every view of
        the packets, and the inspector drains it whatever tab is shown."""
        ring = getattr(self, "_capture_ring", None)
        if ring is None:
            try:
                ring = self.app.screen_stack[0].query_one("#panel-inspector").ring  # type: ignore[attr-defined]
            except Exception:  # noqa: BLE001 - no inspector: nothing captured
                return None
            self._capture_ring = ring
        return ring

    def focus_is_inside(self) -> bool:
        """Whether the panel or one of its widgets has the focus (a tab's keys work only then:
        panels take the focus when shown unless they have it)."""
        focused = self.screen.focused if self.is_mounted else None
        return focused is not None and self in focused.ancestors_with_self

    @property
    def tab_shown(self) -> bool:
        """Whether this panel's tab is the one the app shows (True outside the app's tabs)."""
        shown = self.shown_tab()
        return shown is None or shown == self.ID

    def shown_tab(self) -> str | None:
        """The id of the tab the app shows (None outside the app's tabs)."""
        try:
            return self.app.screen_stack[0].query_one("TabbedContent").active  # type: ignore[attr-defined]
        except Exception:  # noqa: BLE001
            return None

    def take_focus(self) -> None:
        """Focus what a shown tab's keys start on: the panel itself, unless a panel says."""
        self.focus()

    # -- drawing only what changed (panels refresh ten times a second) -----------------------
    def set_shown(self, key: str, value: Any, apply: Callable[[Any], Any]) -> None:
        """``apply(value)`` unless ``value`` is what was applied last for ``key``."""
        if self._shown.get(key, _NEVER) != value:
            self._shown[key] = value
            apply(value)

    def set_text(self, widget_id: str, content: Any, layout: bool = False) -> None:
        """Update the Static ``#widget_id`` if its content changed. Most keep their size (a
        fixed number of lines): no layout pass for them, which is most of a refresh's cost."""
        self.set_shown(widget_id, content,
                       lambda c: self.query_one(f"#{widget_id}", Static).update(c, layout=layout))


_NEVER = object()  # set_shown's "nothing applied yet" (None is a value)
