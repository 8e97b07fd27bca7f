"""The fieldbox app: a Textual front end over an :class:`~roles.runtime.engine.Engine`.

The wire runs apart from drawing (a thread of its own, or a fake clock in tests). The app
copies state out of the role cores on a 10 Hz timer that re-arms only after a refresh has
finished (natural back-pressure), and sends commands through the engine without ever
waiting for the wire: a command is pending until the wire answers (the status line says
so), and its refusal is a notification then. When the wire has not answered for
``STALE_AFTER`` (roles/runtime/engine.py), every screen says it no longer knows (a banner, grey
lights, enable state unknown) instead of showing the last state it saw. The banner has a timer
of its own, due the moment the wire's last answer is ``STALE_AFTER`` old. When the wire's
process has ended, the banner says so, how it ended, and how to start the field again
(``RESTART_KEY``, F9: a fresh field, every robot disabled).

Keys that work everywhere, as on the NI Driver Station: Space e-stops, Enter disables, whatever
has the focus: a tab, a text box, a dialog (F8, a path prompt), the command palette. They are
taken before any binding or widget sees them (:meth:`FieldboxApp.on_event`), so a driver never
has to think where the focus is. In a text box ctrl+space types a space (:data:`SPACE_KEYS`),
and Enter also applies the box; a dialog has keys of its own for its controls (it says which).
Enabling takes a deliberate double press of ``e`` (a second ``e`` within two seconds).
"""

from __future__ import annotations

import dataclasses
import logging
import os
import select
import sys
import threading
from concurrent.futures import Future, InvalidStateError
from typing import Any, Callable, Iterable, cast

from textual import actions, events, on
from textual.app import App, ComposeResult, SystemCommand
from textual.binding import Binding
from textual.notifications import Notify
from textual.screen import ModalScreen
from textual.widgets import Header, Input, Static, TabbedContent, TabPane

from roles.cores.commands import FMS_COMMANDS, Command, Disable, Enable, EStop

from .language import CommandSyntaxError, parse
from roles.cores.core import CommandError
from roles.cores.views import DsView
from roles.runtime import process_tuning
from roles.runtime.engine import RESTART_KEY, STALE_AFTER, Engine, FieldView
from roles.runtime.field import FieldConfig

from . import textual_fixes
from .history import DsHistory
from .panels.base import Panel, Reading, selected_station
from .pcstatus import PcReading, PcStatus
from .textual_fixes import FieldboxFooter, FieldboxTabs
from .seats import NOT_2010, STUDENT, WATCHING, WATCHING_CSS, hidden_tabs, offered, refusal, seat_title, student
from .toasts import TOAST_CSS, clear_of_hints, make_room
from .themes import fieldbox_theme_names, install_themes, variable_defaults

log = logging.getLogger("fieldbox.app")

REFRESH_PERIOD = 0.1
ENABLE_CONFIRM_WINDOW = 2.0
#: A command still unanswered after this long is shown as pending (a quicker answer is not).
PENDING_SHOWN_AFTER = 0.25
#: The robot's keys and their actions, as on the NI Driver Station: taken whatever has the focus.
ROBOT_KEYS = {"space": "estop", "enter": "disable"}
#: The key that types a space in a text box, Space being the robot's: ctrl+space, which a
#: terminal sends as NUL (Textual's "ctrl+@"), and the kitty keyboard protocol as itself. Not
#: shift+space: typing capitals, a thumb presses it by accident (and most terminals send it as
#: a plain space).
SPACE_KEYS = ("ctrl+@", "ctrl+space")


@dataclasses.dataclass
class Pending:
    """A command sent to the wire and not yet answered."""

    what: str
    future: Future
    sent_at: float
    done: Callable[[Future], Any] | None = None  # on the app's thread, once answered


def panel_classes() -> list[type[Panel]]:
    """The tabs, in order. Imported here so a broken panel module is one clear error."""
    from .panels.charts import ChartsPanel
    from .panels.console import ConsolePanel
    from .panels.diagnostics import DiagnosticsPanel
    from .panels.ds import DriverStationPanel
    from .panels.faults import FaultsPanel
    from .panels.fms import FmsPanel
    from .panels.inspector import InspectorPanel
    from .panels.joysticks import JoysticksPanel
    from .panels.legacy import LegacyPanel
    from .panels.setup import SetupPanel
    from .panels.timeline import TimelinePanel

    return [DriverStationPanel, DiagnosticsPanel, SetupPanel, ChartsPanel, JoysticksPanel, ConsolePanel,
            FaultsPanel, FmsPanel, InspectorPanel, TimelinePanel, LegacyPanel]


#: The function keys and their tabs: a key shows its first tab, and pressed again on one of
#: them, the next (F1 F1 is the Driver Station's Diagnostics), as the NI Driver Station keeps
#: Operation, Diagnostics, Setup and Charts together. Seven keys to learn, not eleven.
TAB_KEYS: tuple[tuple[str, tuple[str, ...]], ...] = (
    ("f1", ("ds", "diagnostics", "setup", "charts")),
    ("f2", ("joysticks",)),
    ("f3", ("console",)),
    ("f4", ("faults",)),
    ("f5", ("fms",)),
    ("f6", ("inspector", "timeline")),
    ("f7", ("legacy",)),
)


def tab_key_text(tab: str) -> str:
    """How the keyboard reaches ``tab``: ``F1``, ``F1 F1``..."""
    for key, tabs in TAB_KEYS:
        if tab in tabs:
            return " ".join([key.upper()] * (tabs.index(tab) + 1))
    return ""


class StatusLine(Static):
    """One line under the header: what the selected DS is doing, always visible. Also, as on
    the NI Driver Station, the time since the robot was enabled (held when it is disabled,
    from zero at the next enable) and the PC's CPU and battery. A narrow terminal drops the
    PC's figures first, then the elapsed time, then the FMS: never the robot's state, nor
    what waits for the wire."""

    _shown = ""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self._elapsed_of: tuple[int, int] | None = None  # (engine id, team) the elapsed time is of
        self._enabled_since: float | None = None
        self._seen_disabled: float | None = None  # the last refresh that saw the robot disabled
        self._elapsed = 0.0

    def elapsed(self, key: tuple[int, int], enabled: bool, now: float) -> float:
        """Seconds enabled, counted from the last enable and held while disabled. The enable
        came after the last refresh that saw the robot disabled: the count starts there (on a
        fake clock, the same figure whenever the app's own timer happened to refresh)."""
        if key != self._elapsed_of:
            self._elapsed_of, self._enabled_since, self._elapsed = key, None, 0.0
            self._seen_disabled = None
        if enabled:
            if self._enabled_since is None:
                self._enabled_since = self._seen_disabled if self._seen_disabled is not None else now
            self._elapsed = max(0.0, now - self._enabled_since)
        else:
            self._enabled_since = None
            self._seen_disabled = now
        return self._elapsed

    def refresh_view(self, engine: Engine, now: float, stale: bool = False, pending: str = "",
                     pc: str = "") -> None:
        field = engine.field
        assert isinstance(field, FieldView)  # the app reads views (a Reading), never the cores
        parts: list[tuple[int, str]] = []  # (rank: the lowest goes last when room is short, text)
        seat = getattr(engine, "seat", None)
        if seat is not None:  # a classroom's shared field: who this app is
            parts.append((2, f"classroom: {seat.describe()}"))
        selected = getattr(self.app, "selected_team", None)
        shown = [st for st in field.stations if st.team == selected] or field.stations[:1]
        for st in shown[:1]:
            ds = st.ds
            if ds is not None and stale:  # the last state seen is not the state now
                parts.append((1, f"team {ds.team} {ds.station.label}  ENABLE STATE UNKNOWN  comms ?  code ?"))
            elif ds is not None:
                state = ("FMS E-STOP" if ds.estop_kind == "fms" else "E-STOPPED") if ds.arbiter.estopped \
                    else ("ENABLED" if ds.enabled else "disabled")
                parts.append((1, f"team {ds.team} {ds.station.label}  {ds.mode.label}  {state}  "
                                 f"comms {'●' if ds.link.robot_comms else '○'}  code {'●' if ds.link.robot_code else '○'}"))
                seconds = int(self.elapsed((id(engine), st.team), ds.enabled, now))
                parts.append((4, f"elapsed {seconds // 60}:{seconds % 60:02d}"))
            elif st.rio is not None:
                rio = st.rio
                state = "state unknown" if stale else rio.code_state + (", enabled" if rio.enabled else ", disabled")
                parts.append((1, f"roboRIO {st.team}: {state}"))
        if field.fms is not None and not stale:
            fms = field.fms
            parts.append((3, f"FMS {fms.match.phase} {fms.remaining_left} s"))
        if pending:
            parts.append((0, f"waiting for the wire: {pending}"))
        if pc:
            parts.append((5, pc))
        room = max(20, self.size.width - 2) if self.size.width else 10_000
        while len(parts) > 1 and len("   ".join(text for _, text in parts)) > room:
            parts.remove(max(parts, key=lambda part: part[0]))
        text = "   ".join(part for _, part in parts) or "no roles running"
        if text != self._shown:  # one line, as wide as the screen: new text needs no layout
            self._shown = text
            self.update(text, layout=False)
            self.set_class(stale, "-stale")


class StaleBanner(Static):
    """Shown on every tab while the wire does not answer: the screens below are its last word."""

    def show_age(self, age: float | None) -> None:
        if age is None:
            self.display = False
            return
        self.update(f"NO ANSWER FROM THE WIRE for {age:.1f} s: the tabs show the last state it sent, "
                    "not the state now (enable state unknown). Keys wait and go when it answers.")
        self.display = True

    def show_ended(self, why: str, classroom: bool = False) -> None:
        """The wire will never answer again: say so, and what to do (not "keys wait")."""
        again = ("Quit with ctrl+q and join the classroom again." if classroom else
                 f"{RESTART_KEY} starts the field again (every robot disabled), or quit with ctrl+q "
                 "and start fieldbox again.")
        self.update(f"THE FIELD STOPPED: {why}. Nothing runs and no key reaches a robot; the tabs "
                    f"show the last state it sent. {again}")
        self.display = True


def stale_check_in(age: float) -> float:
    """Seconds from now until the banner is due for a wire last heard ``age`` s ago: the
    moment that answer is STALE_AFTER old (a 10 Hz refresh alone showed the banner up to a
    refresh and its run later: ~440 ms after the last answer). Once stale, a look every
    STALE_AFTER (the refresh keeps the banner's count): never a timer due at once, again and
    again."""
    return STALE_AFTER - age if age < STALE_AFTER else STALE_AFTER


def screen_reader_gone(fd: int | None = None) -> bool:
    """Whether nothing reads this process's output any more (a pipe whose reader closed)."""
    try:
        poller = select.poll()
        if fd is None:
            if sys.__stdout__ is None:  # started without a stdout: nothing to ask
                return False
            fd = sys.__stdout__.fileno()
        poller.register(fd, select.POLLOUT)
        return any(events & (select.POLLERR | select.POLLHUP | select.POLLNVAL) for _, events in poller.poll(0))
    except (AttributeError, OSError, ValueError):
        return False


class FieldboxApp(App):
    """One field, its panels, and the keys to drive it."""

    TITLE = "fieldbox"
    CSS = """
    StatusLine { height: 1; padding: 0 1; background: $boost; }
    StatusLine.-stale { color: $text-muted; }
    StaleBanner { height: auto; padding: 0 1; background: $error; color: $text; text-style: bold; }
    TabbedContent { height: 1fr; }
    """ + TOAST_CSS + WATCHING_CSS
    BINDINGS = [
        # the footer's first keys (a click runs them too); the keys themselves are taken before
        # any binding, wherever the focus is (on_event, ROBOT_KEYS)
        Binding("space", "estop", "E-stop", priority=True),
        Binding("enter", "disable", "Disable", priority=True),
        Binding("e", "enable", "Enable (twice)"),
        Binding("f1", "tab_key('f1')", "Driver Station", show=False),
        Binding("f2", "tab_key('f2')", "Joysticks", show=False),
        Binding("f3", "tab_key('f3')", "Console", show=False),
        Binding("f4", "tab_key('f4')", "Faults", show=False),
        Binding("f5", "tab_key('f5')", "FMS", show=False),
        Binding("f6", "tab_key('f6')", "Inspector", show=False),
        Binding("f7", "tab_key('f7')", "Legacy", show=False),
        Binding("f8", "pick_roles", "Roles"),
        Binding(RESTART_KEY.lower(), "restart_field", "Start the field again", show=False),
        Binding("ctrl+q", "quit", "Quit", priority=True),
    ]

    def __init__(self, engine_factory: Callable[[FieldConfig], Engine], config: FieldConfig, *,
                 panel: str | None = None, theme_name: str | None = None, animate: bool = True,
                 pc_status: Callable[[], PcReading] | None = None, hold_collector: bool = False) -> None:
        textual_fixes.install()  # only on the Textual releases they were written for
        super().__init__()
        self.engine_factory = engine_factory
        #: The app's main asks for it: while a wire runs, the collector keeps out of its way
        #: (roles/runtime/process_tuning.py). Tests on a fake clock leave the collector alone.
        self.hold_collector = hold_collector
        self._collector_held = False
        self.config = config
        self.engine: Engine | None = None
        self.started_at = 0.0
        self.first_panel = panel
        self.requested_theme = theme_name
        self._enable_armed_at: float | None = None
        #: The team the DS keys act on when a field runs several stations (None: the first);
        #: send() gives a DS's commands that team.
        self.selected_team: int | None = None
        self._refreshing = False
        self._problems_shown = 0  # the engine's problems already notified
        self._seat_shown: Any = None  # the classroom seat the screen was last made for
        #: The tabs this app's tab bar leaves out (a classroom seat's: fieldbox/seats.py).
        self.hidden_tabs: frozenset[str] = frozenset()
        self._ticks = 0  # the refresh timer's count
        self._server_gone = False  # a served tab that saw its server go (see _check_server)
        self._pending: list[Pending] = []
        #: Whether the wire has not answered for STALE_AFTER (panels grey their live state).
        self.wire_stale = False
        #: When the banner is due on the engine's clock: its last answer + STALE_AFTER (set by
        #: the banner's own timer, :meth:`_watch_wire`).
        self.banner_due_at: float | None = None
        self._views: tuple | None = None  # (screen, status line, tabs, panels): found once
        #: What the panels read of the engine: its views, made once per refresh (:class:`Reading`).
        self.reading: Reading | None = None
        #: Every DS's last minutes, sampled whatever tab is shown (the Charts tab draws them).
        self.history = DsHistory()
        #: The PC's CPU and battery for the status line (tests give a fixed reading).
        self.pc_status: Callable[[], PcReading] = pc_status or PcStatus().read
        if not animate:
            self.animation_level = "none"
        self._theme_problems = install_themes(self, theme_name)

    #: The line under the title (a replay has one of its own: fieldbox/replay.py).
    STATUS_LINE: type[Static] = StatusLine

    def tab_classes(self) -> list[type[Panel]]:
        """This app's tabs (a replay shows two of them: fieldbox/replay.py)."""
        return panel_classes()

    # -- layout ------------------------------------------------------------------------------
    def compose(self) -> ComposeResult:
        yield Header(show_clock=False)
        yield self.STATUS_LINE(id="status-line")
        banner = StaleBanner(id="stale-banner")
        banner.display = False
        yield banner
        with FieldboxTabs(id="tabs", initial=self.first_panel or "ds"):
            for cls in self.tab_classes():
                with TabPane(cls.TITLE, id=cls.ID):
                    yield cls(id=f"panel-{cls.ID}")
        yield FieldboxFooter()

    def on_resize(self, event) -> None:
        self._fit_tab_titles(event.size.width)
        self.call_after_refresh(self._place_toasts)

    def _fit_tab_titles(self, width: int) -> None:
        """Short tab titles where the long ones do not fit (at 80 columns the tab bar showed
        seven of eleven tabs, and the one shown could be cut)."""
        classes = [cls for cls in self.tab_classes() if cls.ID not in self.hidden_tabs]
        long = sum(len(cls.TITLE) + 2 for cls in classes) <= width - 2
        try:
            tabs = self.screen_stack[0].query_one(TabbedContent) if self.screen_stack else None
        except Exception:  # noqa: BLE001 - not composed yet
            return
        if tabs is None or getattr(self, "_long_titles", None) == long:
            return
        self._long_titles: bool | None = long  # None: not all fitted yet
        for cls in classes:
            try:
                tabs.get_tab(cls.ID).label = cls.TITLE if long else (cls.SHORT_TITLE or cls.TITLE)
            except Exception:  # noqa: BLE001 - a tab not mounted yet: the next resize fits it
                self._long_titles = None

    def on_mount(self) -> None:
        self._fit_tab_titles(self.size.width)
        if self._theme_problems:  # one notification for every bad theme file: toasts are few on a small screen
            self.notify("\n".join(self._theme_problems), title="theme", severity="error", timeout=15)
        if self.start_engine(self.config):
            self._first_hint()
        self.set_timer(REFRESH_PERIOD, self._refresh_tick)
        self._watch_wire()
        if self.is_web:  # a browser tab's app (fieldbox serve): it ends when its server does
            self.set_interval(1.0, self._check_server)

    def _check_server(self) -> None:
        """A served tab whose server died (killed, crashed) has no one reading its screen; left
        alone it would draw into a dead pipe and keep its field, or its classroom seat, for
        ever. It stops its engine and ends; if ending itself hangs, the process ends anyway."""
        if self._server_gone or not screen_reader_gone():
            return
        self._server_gone = True
        log.warning("this tab's server is gone: the app ends")
        hard = threading.Timer(5.0, os._exit, (1,))  # first: stopping the engine may hang too
        hard.daemon = True
        hard.start()
        if self.engine is not None:
            self._stop(self.engine)
        self.exit()

    def start_engine(self, config: FieldConfig) -> bool:
        """(Re)start the field. The old one stops first (the new one may need its ports); if
        the new one cannot start, a notification says why and the old configuration comes back."""
        old_engine, old_config = self.engine, self.config
        if old_engine is not None:
            self._stop(old_engine)
            self.engine = None
        self._settle()  # what the old field never answered is refused now (it stopped)
        try:
            engine = self.engine_factory(config)
        except (OSError, ValueError) as exc:
            self.notify(f"cannot start: {exc}", severity="error", timeout=10)
            if old_engine is not None and config is not old_config:
                self.start_engine(old_config)
            return False
        if self.hold_collector and not self._collector_held:
            process_tuning.hold_collector()
            self._collector_held = True
        for problem in getattr(engine, "problems", ()):
            self.notify(problem, severity="warning", timeout=10)
        self._problems_shown = len(getattr(engine, "problems", ()))
        self.engine = engine
        self.config = config
        #: The field's clock when it started: logs on screen count their seconds from it. A
        #: classroom's field started before this tab joined: its start, the same in every tab
        #: (each tab's own start made the same event 144.462 in one and 158.517 in another).
        field_started = getattr(engine, "field_started", None)
        self.started_at = field_started if isinstance(field_started, float) else engine.now()
        self._show_seat()
        for panel in self.query(Panel):
            panel.engine_changed(engine) if hasattr(panel, "engine_changed") else None
        return True

    def _show_seat(self) -> None:
        """The title and the screen for this app's seat in a classroom (fieldbox/seats.py):
        a driver's team in the title; an observer without the buttons and keys it may not use;
        a student without the teacher's controls, and the tabs it has no use for."""
        seat = self.seat
        self._seat_shown = seat
        if seat is not None and seat.kind == "driver":  # its DS tab shows the team it drives
            self.selected_team = seat.team
        shared = getattr(self.engine, "shared_config", None)  # a classroom's field: its own, not this app's options
        self.sub_title = seat_title(seat, shared, self._describe) or self._describe(self.config)
        if self.screen_stack:
            base = self.screen_stack[0]
            base.set_class(not offered(seat, "enable"), WATCHING)
            base.set_class(student(seat), STUDENT)
            hidden = hidden_tabs(seat, shared)
            if hidden != self.hidden_tabs:
                self._show_tabs(base, hidden)
        self.refresh_bindings()

    def _show_tabs(self, base: Any, hidden: frozenset[str]) -> None:
        """The tab bar without the tabs ``hidden`` (and with the ones hidden before)."""
        try:
            tabs = base.query_one(FieldboxTabs)
            for tab in self.hidden_tabs - hidden:
                tabs.show_tab(tab)
            for tab in hidden:
                tabs.hide_tab(tab)
        except Exception:  # noqa: BLE001 - not mounted yet: the seat is shown again at the next refresh
            self._seat_shown = None
            return
        self.hidden_tabs = hidden
        self._long_titles = None  # fewer tabs may fit their long titles
        self._fit_tab_titles(self.size.width)

    def check_action(self, action: str, parameters: tuple[object, ...]) -> bool | None:
        """The footer offers no key this app may not use (:meth:`refusal`)."""
        return self.refusal(action, parameters) is None

    def refusal(self, action: str, parameters: tuple[object, ...] = ()) -> str | None:
        """Why this app may not do ``action`` (an app-wide key's), or None: in a classroom, a
        seat may not command what is not its own, nor show a tab its tab bar leaves out
        (fieldbox/seats.py)."""
        if action == "tab_key" and parameters and all(tab in self.hidden_tabs
                                                       for tab in dict(TAB_KEYS).get(str(parameters[0]), ())):
            return NOT_2010
        said = refusal(self.seat, action)
        if said is None and action == "enable":  # an attached FMS decides it: e is not offered
            said = self._enable_refused_now()
        return said

    def on_key(self, event: events.Key) -> None:
        """A key the footer does not offer here, pressed anyway: the app says why (a key
        that nothing took would otherwise do nothing, and say nothing)."""
        if not self.screen_stack:
            return
        chain = self.screen._modal_binding_chain  # what Textual's own key dispatch walks
        found = [(node, binding) for node, bindings in chain for binding in bindings.key_to_bindings.get(event.key, ())]
        reasons = []
        for node, binding in found:
            _, action, parameters = actions.parse(binding.action)
            ask = getattr(node, "refusal", None)
            why = ask(action, parameters) if callable(ask) and "." not in binding.action else None
            if why is None:
                return  # a binding of this key that this app may use: it ran
            reasons.append(why)
        if reasons:
            event.stop()
            self.notify(reasons[0], severity="warning")

    @staticmethod
    def _describe(config: FieldConfig) -> str:
        # In 2010 mode the FMS does not run (its protocol is not documented): say what runs.
        roles = "+".join(r for r in ("ds", "rio", "fms") if r in config.roles
                         and not (r == "fms" and config.legacy))
        teams = ",".join(str(t) for _, t in config.stations())
        legacy = " 2010" if config.legacy else ""
        return f"{roles} team {teams} {config.plan}{legacy}"

    def _stop(self, engine: Engine) -> None:
        engine.stop()
        if self._collector_held:
            self._collector_held = False
            process_tuning.release_collector()

    def on_unmount(self) -> None:
        if self.engine is not None:
            self._stop(self.engine)

    def deliver_screenshot(self, filename: str | None = None, path: str | None = None,
                           time_format: str | None = None) -> str | None:
        """Textual saves to the Downloads folder, which an SSH session often lacks (the
        screenshot then failed): fieldbox saves to this run's log folder, else the current
        folder, and the notification says where. A browser tab still downloads it."""
        if path is None:
            folder = getattr(self.engine, "log_folder", None)
            path = folder if folder and os.path.isdir(folder) and os.access(folder, os.W_OK) else os.getcwd()
        return super().deliver_screenshot(filename, path, time_format)

    def get_theme_variable_defaults(self) -> dict[str, str]:
        return {**super().get_theme_variable_defaults(), **variable_defaults()}

    def get_system_commands(self, screen) -> Iterable[SystemCommand]:
        yield from super().get_system_commands(screen)
        for name in fieldbox_theme_names(self):
            yield SystemCommand(f"Theme: {name}", f"Switch to the {name} theme",
                                lambda n=name: setattr(self, "theme", n))
        for cls in self.tab_classes():
            if cls.ID in self.hidden_tabs:
                continue
            yield SystemCommand(f"Panel: {cls.TITLE}", f"Show the {cls.TITLE} tab ({tab_key_text(cls.ID)})",
                                lambda tab=cls.ID: self.action_show_tab(tab))
        seat = self.seat
        if seat is None or seat.kind == "teacher":  # the server's files: not for a classroom's students
            yield SystemCommand("Logs: the NI log viewer", "Pick a run's .dslog/.dsevents: battery, trip time, "
                                "modes and events over time (fieldbox logs)", self.open_log_viewer)
        if seat is not None and seat.kind == "teacher" and self.engine is not None:
            for st in self.engine.field.stations:
                yield SystemCommand(f"Classroom: take back team {st.team}",
                                    f"Team {st.team}'s driver watches from now on; its DS is disabled",
                                    lambda team=st.team: self.take_back(team))

    def open_log_viewer(self) -> None:
        """The runs in the log folder (this run's among them, newest first) in the log viewer."""
        from pathlib import Path

        from roles.runtime.logfiles import default_log_dir

        from .logview import open_viewer

        folder = getattr(self.engine, "log_folder", None)
        open_viewer(self, Path(folder).parent if folder else default_log_dir())

    def take_back(self, team: int) -> bool:
        """The teacher takes a station back from its driver (roles/runtime/classroom.py)."""
        from roles.runtime.classroom import JoinedEngine, TakeBack

        # The classroom's engine takes a TakeBack as well as a command (its submit, classroom.py).
        return self.submit(lambda engine: cast(JoinedEngine, engine).submit(TakeBack(team)),  # type: ignore[arg-type]
                           f"take back team {team}")

    # -- the wire's silence ------------------------------------------------------------------------
    def _watch_wire(self) -> None:
        """The banner's own timer, due the moment the wire's last answer is STALE_AFTER old:
        a firing that finds a newer answer sets itself for that one's due time; one that finds
        the wire silent shows the banner at once, not at the next refresh."""
        engine, delay = self.engine, STALE_AFTER
        try:
            if engine is not None:
                age = engine.age()
                self.banner_due_at = engine.now() - age + STALE_AFTER
                delay = stale_check_in(age)
                if age >= STALE_AFTER and not self.wire_stale:
                    self.refresh_views()
        finally:
            self.set_timer(delay, self._watch_wire)

    def action_restart_field(self) -> None:
        """A field whose wire ended starts again, as it was configured: a fresh wire, every
        robot disabled (nothing of the old field's enables carries over). Only then: a running
        field is changed with F8."""
        engine = self.engine
        why = getattr(engine, "end_reason", None)
        if engine is not None and why is None:
            self.notify("the field runs: nothing to start again (F8 changes its roles)", severity="warning")
            return
        if self.seat is not None:
            self.notify("this app shares the classroom's field: quit with ctrl+q and join it again",
                        severity="warning")
            return
        if self.start_engine(self.config):  # (none runs: the last start failed, said then)
            self.notify(f"the field started again{f' after {why}' if why else ''}: every robot is disabled",
                        timeout=10)
            self.refresh_views()

    # -- the 10 Hz refresh ---------------------------------------------------------------------
    def _refresh_tick(self) -> None:
        self._ticks += 1
        try:
            if self._ticks % 5 == 0 and self._notifications:  # a tab's hints can grow under a toast
                self._place_toasts()
            self.refresh_views(self._ticks)
        finally:
            self.set_timer(REFRESH_PERIOD, self._refresh_tick)  # re-arm only after finishing

    def refresh_views(self, tick: int | None = None) -> None:
        """Read the wire's views into the status line and the panels. ``tick``: the timer's
        count, where a panel of many numbers skips the ticks its ``REFRESH_TICKS`` says; None
        (a key, a tab switch, a test) refreshes every panel that is due at all."""
        engine = self.engine
        if engine is None:
            return
        problems = getattr(engine, "problems", ())
        if len(problems) > self._problems_shown:  # e.g. the wire process ended
            for problem in problems[self._problems_shown:]:
                self.notify(problem, severity="error", timeout=30)
            self._problems_shown = len(problems)
        now = engine.now()
        if self.seat != self._seat_shown:  # the teacher took this driver's station back
            self._show_seat()
        self._settle()
        age = engine.age()
        ended = getattr(engine, "end_reason", None)
        self.wire_stale = age >= STALE_AFTER or ended is not None
        reading = self.read_now(now)
        if reading is None:
            return
        # From here the panels read the Reading, which stands in for the engine (it forwards
        # all but the views).
        engine = cast(Engine, reading)
        if not self.screen_stack:
            return
        base = self.screen_stack[0]  # the main screen, also while a dialog is open over it
        try:
            views = self._views
            if views is None or views[0] is not base:
                # found once all are mounted: querying the DOM ten times a second took 5 % of
                # the app's time (py-spy, benchmarks/field.py --app)
                views = (base, base.query_one(StatusLine), base.query_one(TabbedContent), tuple(base.query(Panel)),
                         base.query_one(StaleBanner))
                if len(views[3]) == len(self.tab_classes()):
                    self._views = views
            _, status, tabs, panels, banner = views
            if ended is not None:
                banner.show_ended(ended, classroom=self.seat is not None)
            else:
                banner.show_age(age if self.wire_stale else None)
            if not self.wire_stale:  # a silent wire's last state is not a sample of the field
                self.history.sample(engine, now)
            status.refresh_view(engine, now, self.wire_stale, self._pending_text(now), self.pc_status().text())
            active = tabs.active
            for panel in panels:
                if (panel.ID == active or getattr(panel, "ALWAYS_REFRESH", False)) and \
                        (tick is None or tick % panel.REFRESH_TICKS == 0):
                    panel.refresh_view(engine, now)
        except Exception:  # a panel bug must not stop the refresh, nor the wire
            log.exception("refresh failed")

    def read_now(self, now: float | None = None) -> Reading | None:
        """The engine as the panels read it, with its views made now (None: no engine, or
        no view could be made yet)."""
        engine = self.engine
        if engine is None:
            return None
        reading = self.reading
        if reading is None or reading.engine is not engine:
            reading = self.reading = Reading(engine)
        try:
            reading.field = engine.views(engine.now() if now is None else now)
        except Exception:  # a view that cannot be made: the last ones stay, said in the log
            log.exception("views failed")
        return reading if reading.field is not None else None

    # -- commands -------------------------------------------------------------------------------
    def send(self, command: Command, done: Callable[[Future], Any] | None = None) -> bool:
        """A key's or a panel's command (roles/cores/commands.py), sent without waiting: a DS's
        acts on the selected team unless it names one. True if it went to the wire; a
        refusal comes later as a notification (or to ``done``)."""
        if self.engine is None:
            return False
        seat = self.seat
        if seat is not None and seat.kind == "driver":  # a classroom's driver drives one team
            self.selected_team = seat.team
        if command.team is None and self.selected_team is not None and not isinstance(command, FMS_COMMANDS):
            command = dataclasses.replace(command, team=self.selected_team)
        command = dataclasses.replace(command, issued=self.engine.now())
        return self.submit(lambda engine: engine.submit_command(command), command.verb, done)

    def run_command(self, text: str, done: Callable[[Future], Any] | None = None) -> bool:
        """A line of the command language (fieldbox/language.py), as a person would type it
        to the headless mode: parsed, then sent as :meth:`send` sends a key's command."""
        try:
            command = parse(text)
        except CommandSyntaxError as exc:
            self.notify(str(exc), severity="error")
            return False
        return command is not None and self.send(command, done)

    def submit(self, send: Callable[[Engine], Future], what: str,
               done: Callable[[Future], Any] | None = None) -> bool:
        """``send(engine)`` returns a future of the wire's answer; the app never waits for it.
        ``done(future)`` runs on the app's thread once it is answered; without ``done``, a
        refusal is a notification. False if there is no field to send to, or it refused at
        once (a fake clock's field, a wire that has ended)."""
        engine = self.engine
        if engine is None:
            return False
        try:
            future = send(engine)
        except CommandError as exc:
            self.notify(str(exc), severity="warning")
            return False
        self._pending.append(Pending(what, future, engine.now(), done))
        if future.done():  # a field on a fake clock answers at once, a stopped wire refuses at once
            self._settle()
            return future.exception() is None
        return True

    def _settle(self) -> None:
        """Deal with every answered command, in the order they were sent."""
        pending, self._pending = self._pending, []
        for item in pending:
            if not item.future.done() and self.engine is not None:
                self._pending.append(item)
                continue
            if not item.future.done():  # the field it went to was stopped
                try:
                    item.future.set_exception(CommandError("the field stopped before it answered"))
                except InvalidStateError:  # it answered just now after all
                    pass
            if item.done is not None:
                try:
                    item.done(item.future)
                except Exception:  # a panel's handler must not stop the others
                    log.exception("handling the answer to %s failed", item.what)
                continue
            exc = item.future.exception()
            if isinstance(exc, CommandError):
                self.notify(str(exc), severity="warning")
            elif exc is not None:
                log.error("%s failed: %s", item.what, exc)
                self.notify(f"{item.what}: {exc}", severity="error")

    def _pending_text(self, now: float) -> str:
        late = [item.what for item in self._pending if now - item.sent_at >= PENDING_SHOWN_AFTER]
        if len(late) > 3:
            return ", ".join(late[:3]) + f" and {len(late) - 3} more"
        return ", ".join(late)

    async def on_event(self, event: events.Event) -> None:
        """Space and Enter are the robot's wherever the focus is, as on the NI Driver Station:
        taken here, before any binding or widget. (Textual hands a focused text box the
        printable keys before the app's bindings, Space among them, and a dialog's own Enter
        and Space came first too: with the roles dialog or the palette open, Space did not
        e-stop.) In a text box, ctrl+space types the space Space no longer types."""
        if isinstance(event, events.Key) and not event.is_forwarded:
            action = ROBOT_KEYS.get(event.key)
            if action is not None:
                self.app_focus = True
                why = self.refusal(action)
                if why is not None:  # an observer's: it says why, as any key refused does
                    self.notify(why, severity="warning")
                await self.run_action(action)
                return
            if event.key in SPACE_KEYS and isinstance(self.focused, Input):
                self._type_space(self.focused)
                return
        await super().on_event(event)

    @staticmethod
    def _type_space(box: Input) -> None:
        """A space into ``box`` as a typed one goes: over the selection, else at the cursor."""
        if box.selection.is_empty:
            box.insert_text_at_cursor(" ")
        else:
            box.replace(" ", *box.selection)

    def action_estop(self) -> None:
        if self.send(EStop()):
            self.notify("E-STOP: restart robot code to clear it", severity="error")

    async def action_disable(self) -> None:
        # Enter disables from anywhere, as on the NI Driver Station: safety before typing.
        # In a tab's text box it then also applies what was typed; a dialog's box is applied
        # with the dialog's own key (ctrl+s), never by the key that disables.
        self._enable_armed_at = None
        self.send(Disable())
        focused = self.focused
        if isinstance(focused, Input) and not isinstance(self.screen, ModalScreen):
            await focused.action_submit()

    def action_enable(self) -> None:
        now = self.engine.now() if self.engine else 0.0
        refused = self._enable_refused_now()
        if refused:  # never ask for a second press that would be refused
            self._enable_armed_at = None
            self.notify(refused, severity="warning")
            return
        if self._enable_armed_at is not None and now - self._enable_armed_at <= ENABLE_CONFIRM_WINDOW:
            self._enable_armed_at = None
            self.send(Enable())
        else:
            self._enable_armed_at = now
            self.notify("Press e again to ENABLE", timeout=ENABLE_CONFIRM_WINDOW)

    def _on_notify(self, event: Notify) -> None:
        """Room for a new toast: a small screen shows two at once, the newest (fieldbox/toasts.py).
        Textual's own handler runs next and shows it."""
        make_room(self._notifications, event.notification, self.size.height)
        self._place_toasts()

    def _place_toasts(self) -> None:
        """Toasts above the shown tab's key-hint rows, never over them (fieldbox/toasts.py).
        Done as a toast comes, and after a tab switch or a resize (the hints moved)."""
        if not self.screen_stack or self.screen is not self.screen_stack[0]:
            return  # a dialog's toasts: the tab's hints are behind the dialog
        base = self.screen_stack[0]
        try:
            panel = base.query_one(f"#panel-{base.query_one(TabbedContent).active}", Panel)
        except Exception:  # noqa: BLE001 - not composed yet, or no tab shown
            return
        clear_of_hints(base, panel)

    def _enable_refused_now(self) -> str | None:
        """Why an enable from the keys would be refused whatever happens in the next second:
        an FMS decides it (the DS keys' station, as the field shows it now)."""
        reading = self.read_now()
        st = selected_station(reading, self.selected_team) if reading is not None else None
        ds = getattr(st, "ds", None)
        if not isinstance(ds, DsView) or not ds.fms.attached:  # (a replay's station has no DS view)
            return None
        fms = "start a match in the FMS tab (F5)" if self.config.roles >= {"fms"} else "the field's FMS runs the match"
        return f"an FMS is attached: it decides enable ({fms}; F8 to drive without one)"

    def _first_hint(self) -> None:
        """A word beside the first screen, once the field started (a live field's DS tab says
        who enables in its own note; a replay says what it plays)."""

    def action_tab_key(self, key: str) -> None:
        """A function key: its first tab, or from one of its tabs the next (TAB_KEYS)."""
        tabs = dict(TAB_KEYS)[key]
        active = self.query_one(TabbedContent).active
        self.action_show_tab(tabs[(tabs.index(active) + 1) % len(tabs)] if active in tabs else tabs[0])

    def action_show_tab(self, tab: str) -> None:
        if tab in self.hidden_tabs:
            self.notify(NOT_2010, severity="warning")
            return
        self.query_one(TabbedContent).active = tab
        self._focus_tab(tab)
        self.refresh_views()  # the tab's new content is laid out with the switch, not a frame later

    def _focus_tab(self, tab: str) -> None:
        """The panel shown takes the focus at once, not when its Show event comes: a widget of
        the tab left that still has the focus hands it, as it hides, to a sibling in its own
        tab, and the tab of a focused widget becomes the active one (Textual 8): the tabs went
        back to the inspector when F7 came within a frame or two of F6."""
        for panel in self.screen_stack[0].query(Panel) if self.screen_stack else ():
            if panel.ID == tab and not panel.focus_is_inside():
                panel.take_focus()

    @property
    def seat(self) -> Any:
        """In a classroom (roles/runtime/classroom.py), who this app is: driver, observer or teacher."""
        return getattr(self.engine, "seat", None)

    def action_command_palette(self) -> None:
        """Textual's palette, with ctrl+s to run a command: Enter is the robot's (widgets.Palette)."""
        from textual.command import CommandPalette

        from .widgets import Palette

        if self.use_command_palette and not CommandPalette.is_open(self):
            self.push_screen(Palette(id="--command-palette"))

    def action_pick_roles(self) -> None:
        from .picker import RolePicker

        if self.seat is not None:
            self.notify("this app shares the classroom's field: its roles are the teacher's", severity="warning")
            return

        def chosen(config: FieldConfig | None) -> None:
            if config is not None:
                self.start_engine(config)

        self.push_screen(RolePicker(self.config), chosen)

    @on(TabPane.Focused)
    def _focus_in_a_tab(self, event: TabPane.Focused) -> None:
        tabs = next((node for node in event.tab_pane.ancestors if isinstance(node, FieldboxTabs)), None)
        if tabs is not None and event.tab_pane.id != tabs.active:  # late, from a tab left:
            self._focus_tab(tabs.active)  # back to the tab shown

    @on(TabbedContent.TabActivated)
    def _tab_changed(self, event: TabbedContent.TabActivated) -> None:
        self._focus_tab(event.tabbed_content.active)  # a tab clicked: no key went through show_tab
        self.refresh_views()
        self.call_after_refresh(self._place_toasts)


def wire_kind(args=None) -> str:
    """``process`` (default) or ``thread``: ``--wire``, else FIELDBOX_WIRE.

    The wire runs in a process of its own by default (roles/runtime/wireproc.py): drawing never holds
    its interpreter. On a thread of the app's process the beat wavers (the app's full garbage
    collections stop it), for a little less CPU and memory (docs/figures.md). ``thread`` is
    there for a machine where a second process is not wanted."""
    kind = getattr(args, "wire", None) or os.environ.get("FIELDBOX_WIRE") or "process"
    if kind not in ("process", "thread"):
        raise ValueError(f"bad wire {kind!r}: process or thread")
    return kind


def engine_factory(kind: str = "process") -> Callable[[FieldConfig], Engine]:
    """Builds and starts the app's engines: the wire in a child process (roles/runtime/wireproc.py)
    or on a thread of this one (roles/runtime/engine.py ThreadEngine)."""
    from roles.runtime.engine import ThreadEngine
    from roles.runtime.wireproc import ProcessEngine

    def factory(cfg: FieldConfig) -> Engine:
        engine = ProcessEngine(cfg) if kind == "process" else ThreadEngine(cfg)
        engine.start()
        return engine

    return factory


def run_app(config: FieldConfig, args) -> int:
    app = FieldboxApp(engine_factory(wire_kind(args)), config, theme_name=args.theme, hold_collector=True)
    app.run()
    return 0
