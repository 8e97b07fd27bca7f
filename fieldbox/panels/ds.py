"""The Driver Station panel: what the NI Driver Station's main tab shows, for one team.

Control (state, team and station, mode, enable / disable / e-stop, restart code, reboot),
the robot (comms, code and joystick lights, the robot program's mode, battery with a chart,
trip time, lost packets) and the match (FMS status, practice run, countdown).

Keys (this tab): ``t`` teleop, ``a`` auto, ``s`` test, ``p`` practice start/stop, ``R``
restart robot code, ``B`` reboot the roboRIO, ``[`` ``]`` previous / next team when a field
runs several stations. Everywhere (the app's): Space e-stops, Enter disables, ``e`` twice
enables. Every key has a button too.
"""

from __future__ import annotations

from typing import Any

from rich.text import Text
from textual import on
from textual.app import ComposeResult
from textual.binding import Binding
from textual.containers import Horizontal, Vertical
from textual.widgets import Button, Digits, Static

from roles.cores.commands import Enable, Practice, RebootRoboRIO, RestartCode, SetMode
from roles.cores.views import DsView

from ..history import SAMPLE_PERIOD
from ..linechart import LineChart
from ..widgets import EventLog, StatusLight, key_hints
from .base import Panel

#: The battery chart: the last minute, on a fixed 6..14 V scale.
CHART_SECONDS = 60.0
CHART_LO, CHART_HI = 6.0, 14.0
BATTERY_LOW = 11.0  # warning colour below (a battery that needs charging)
BATTERY_BAD = 7.0  # error colour below (the roboRIO browns out at 6.8 V)

#: What the DS tab says of what blocks an enable (the core's kinds, roles/cores/ds_enable.py blocker).
_BLOCKER_NOTE = {
    "fms": "The FMS decides enable, mode and station. Enter still disables; Space still e-stops.",
    "estop": "E-stop latched: restart the robot code (R) or reboot the roboRIO (B) to clear it.",
    "comms": "No robot comms: enabling waits for the robot to answer.",
    "robot-estop": "The robot still reports an e-stop: restart its code (R).",
    "code": "No robot code: enabling waits for the robot program.",
    "practice": "A practice run enables the robot itself. Enter or Space stops it.",
}
MODES = (("teleop", "Teleop", "t"), ("auto", "Auto", "a"), ("test", "Test", "s"))
#: Button labels (usual, narrow): a narrow label is shorter but keeps its key.
BUTTONS = {
    "ds-mode-teleop": ("Teleop t", "Tele t"), "ds-mode-auto": ("Auto a", "Auto a"),
    "ds-mode-test": ("Test s", "Test s"),
    "ds-enable-btn": ("Enable e e", "Enable e e"), "ds-disable-btn": ("Disable Enter", "Disable ⏎"),
    "ds-estop-btn": ("E-STOP  Space", "E-STOP Space"),
    "ds-restart-btn": ("Restart code R", "Restart R"), "ds-reboot-btn": ("Reboot RIO B", "Reboot B"),
}

_FMS_LIGHT = {"off": "idle", "connecting": "warn", "connected": "warn", "waiting": "warn",
              "good": "on", "wrong station": "off"}
_FMS_TEXT = {"off": "FMS: none (local control)", "connecting": "FMS: connecting…",
             "connected": "FMS: connected, no station yet", "waiting": "FMS: waiting for the match",
             "good": "FMS: good", "wrong station": "FMS: WRONG STATION"}


#: The tab's keys an attached FMS decides instead, and what a press says (the core's words).
FMS_DECIDES = {"mode": "an FMS is attached: it decides the mode",
               "practice": "an FMS is attached: it runs the match, not a practice run"}


#: The buttons of what an attached FMS decides: greyed while it is attached.
FMS_BUTTONS = ("ds-mode-teleop", "ds-mode-auto", "ds-mode-test", "ds-enable-btn", "ds-practice-btn")


class DriverStationPanel(Panel):
    TITLE = "Driver Station"
    SHORT_TITLE = "DS"
    ID = "ds"
    can_focus = True

    BINDINGS = [
        Binding("t", "mode('teleop')", "Teleop"),
        Binding("a", "mode('auto')", "Auto"),
        Binding("s", "mode('test')", "Test"),
        Binding("p", "practice", "Practice"),
        Binding("R", "restart_code", "Restart code"),
        Binding("B", "reboot", "Reboot RIO"),
        Binding("left_square_bracket", "team(-1)", "Prev team", show=False),
        Binding("right_square_bracket", "team(1)", "Next team", show=False),
    ]

    # Three sizes: the usual; -narrow (under 100 columns: shorter button labels that keep
    # their keys, no padding); -short (under 30 rows: no margins, the battery on one line, a
    # small chart), so an 80x24 terminal shows everything at once; and a tall screen gives
    # the state and the battery chart its rows (-tall).
    DEFAULT_CSS = """
    DriverStationPanel { layout: vertical; padding: 0 1; overflow-y: auto; }
    #ds-columns { height: 1fr; min-height: 16; }
    #ds-columns > Vertical { width: 1fr; height: 100%; padding: 0 1; border: round $panel-lighten-2; }
    #ds-columns > Vertical:focus-within { border: round $accent; }
    #ds-state { height: 5; content-align: center middle; text-style: bold; background: $panel;
                color: $text; }
    #ds-state.-enabled { background: $fb-enabled; color: black; }
    #ds-state.-estop { background: $fb-estop; color: white; }
    #ds-state.-unknown { background: $panel-darken-1; color: $text-muted; }
    #ds-team { height: 1; margin-top: 1; }
    .ds-row { height: 1; margin-top: 1; }
    .ds-row Button { width: 1fr; min-width: 6; margin-right: 1; }
    .ds-row Button.-current { background: $primary; color: $text; text-style: bold; }
    #ds-estop-btn { background: $fb-estop; color: white; text-style: bold; }
    #ds-note { height: auto; margin-top: 1; color: $text-muted; }
    #ds-robot StatusLight, #ds-light-fms { height: auto; }
    #ds-program { height: auto; margin-top: 1; }
    #ds-battery-row { height: 3; margin-top: 1; }
    #ds-battery-label { width: 9; height: 3; content-align: left middle; }
    #ds-battery { width: auto; }
    #ds-battery.-low { color: $warning; }
    #ds-battery.-bad { color: $error; }
    #ds-chart { height: 1fr; min-height: 4; margin-top: 1; }
    #ds-trip-chart { height: 1fr; min-height: 4; margin-top: 1; }
    #ds-messages { height: 1fr; min-height: 4; margin-top: 1; }
    #ds-link { height: auto; margin-top: 1; }
    #ds-phase { height: auto; margin-top: 1; text-style: bold; }
    #ds-countdown { width: auto; margin-top: 1; }
    #ds-match-note { height: auto; color: $text-muted; }
    #ds-teams { height: auto; margin-bottom: 1; }
    .ds-teams-label { width: auto; margin-right: 2; }
    #ds-teams Button { margin-right: 1; min-width: 12; }
    #ds-teams Button.-selected { background: $primary; text-style: bold; }
    #ds-teams Button.-red { color: $fb-alliance-red; }
    #ds-teams Button.-blue { color: $fb-alliance-blue; }
    #ds-teams Button.-selected.-red, #ds-teams Button.-selected.-blue { color: $text; }
    #ds-keys { height: auto; margin-top: 1; color: $text-muted; }
    #ds-none { height: auto; margin: 1 2; }
    DriverStationPanel.-narrow #ds-columns > Vertical { padding: 0; }
    DriverStationPanel.-narrow #ds-teams Button { min-width: 0; }
    DriverStationPanel.-narrow .ds-teams-label { margin-right: 1; }
    DriverStationPanel.-short #ds-state { height: 3; }
    DriverStationPanel.-short #ds-team, DriverStationPanel.-short .ds-row,
    DriverStationPanel.-short #ds-note, DriverStationPanel.-short #ds-program,
    DriverStationPanel.-short #ds-link, DriverStationPanel.-short #ds-phase,
    DriverStationPanel.-short #ds-countdown, DriverStationPanel.-short #ds-keys,
    DriverStationPanel.-short #ds-chart { margin-top: 0; }
    DriverStationPanel.-short #ds-battery-row { display: none; }
    DriverStationPanel.-short #ds-trip-chart { display: none; }
    DriverStationPanel.-short #ds-messages { min-height: 0; }
    DriverStationPanel.-short #ds-teams { margin-bottom: 0; }
    DriverStationPanel.-short #ds-columns { min-height: 14; }
    DriverStationPanel.-tall #ds-state { height: 1fr; min-height: 9; }
    """

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self._team_list: tuple[tuple[int, str], ...] = ()
        self._fms_attached = False  # the shown DS's FMS decides enable, the mode, a practice run
        self._trip_plotted: tuple | None = None  # (team, the history sample) the round-trip chart ends at
        self._link_urgent: tuple | None = None  # what of the link block is shown at once when it changes

    # -- layout ------------------------------------------------------------------------------
    def compose(self) -> ComposeResult:
        yield Static("", id="ds-none")
        yield Horizontal(id="ds-teams")
        with Horizontal(id="ds-columns"):
            with Vertical(id="ds-control"):
                yield Static("DISABLED", id="ds-state")
                yield Static("", id="ds-team")
                with Horizontal(classes="ds-row"):
                    for mode, _, _ in MODES:
                        yield Button(BUTTONS[f"ds-mode-{mode}"][0], id=f"ds-mode-{mode}", compact=True)
                with Horizontal(classes="ds-row"):
                    yield Button(BUTTONS["ds-enable-btn"][0], id="ds-enable-btn", compact=True)
                    yield Button(BUTTONS["ds-disable-btn"][0], id="ds-disable-btn", compact=True)
                with Horizontal(classes="ds-row"):
                    yield Button(BUTTONS["ds-estop-btn"][0], id="ds-estop-btn", compact=True)
                with Horizontal(classes="ds-row"):
                    yield Button(BUTTONS["ds-restart-btn"][0], id="ds-restart-btn", compact=True)
                    yield Button(BUTTONS["ds-reboot-btn"][0], id="ds-reboot-btn", compact=True)
                yield Static("", id="ds-note")
            with Vertical(id="ds-robot"):
                yield StatusLight("Communications", id="ds-light-comms")
                yield StatusLight("Robot code", id="ds-light-code")
                yield StatusLight("Joysticks", id="ds-light-joysticks")
                yield Static("", id="ds-program")
                with Horizontal(id="ds-battery-row"):
                    yield Static("Battery\nvolts", id="ds-battery-label")
                    yield Digits("--.--", id="ds-battery")
                yield LineChart("Battery", "V", CHART_LO, CHART_HI, aggregate="min", warn=BATTERY_LOW,
                                bad=BATTERY_BAD, below=True, digits=2, window_text=f"{CHART_SECONDS:.0f} s",
                                id="ds-chart")
                yield LineChart("Round trip", "ms", 0.0, 2.0, auto=True, warn=20.0, bad=100.0, digits=1,
                                window_text=f"{CHART_SECONDS:.0f} s", hold=SAMPLE_PERIOD, id="ds-trip-chart")
                yield Static("", id="ds-link")
            with Vertical(id="ds-match"):
                yield StatusLight("FMS", id="ds-light-fms")
                yield Static("", id="ds-phase")
                yield Digits("", id="ds-countdown")
                with Horizontal(classes="ds-row"):
                    yield Button("Start practice p", id="ds-practice-btn", compact=True)
                yield Static("", id="ds-match-note")
                yield EventLog(id="ds-messages")
        yield Static(self._keys_text(False), id="ds-keys", classes="key-hints")

    def on_mount(self) -> None:
        self.query_one("#ds-messages").border_title = "Messages"
        self.query_one("#ds-none").display = False
        self.query_one("#ds-teams").display = False

    def on_resize(self) -> None:
        narrow = self.size.width < 100
        if narrow != self.has_class("-narrow"):
            for ident, labels in BUTTONS.items():
                button = self.query_one(f"#{ident}", Button)
                button.label = labels[narrow]
                button.styles.line_pad = 0 if narrow else 1  # (CSS refuses a line-pad of 0)
        self.set_class(narrow, "-narrow")
        self._show_keys()
        self.set_class(self.size.height < 30, "-short")
        self.set_class(self.size.height >= 40, "-tall")

    @staticmethod
    def _keys_text(several: bool, narrow: bool = False, tabs: str = "F1…F7", fms: bool = False) -> Text:
        """The tab's keys; ``tabs``: the function keys that show a tab (a classroom's student
        has no 2010 tab: F1…F6); ``fms``: an FMS is attached, so enable, the mode and a
        practice run are its, and their keys are not offered (Enter and Space still are)."""
        if narrow:  # the footer has Space, Enter and ctrl+q: this tab's keys on as few lines as can be
            # One line at 80 columns (75 cells in 78), two gaps apart. With the team keys it
            # cannot be: then it breaks between two keys on purpose, never between a key and
            # what it does (a wrapped "F1" over "more" reads as nothing).
            keys = ([] if fms else [("e e", "enable"), ("t a s", "mode"), ("p", "practice")]) \
                + [("R", "restart"), ("B", "reboot"), ("F1", "more")] + ([("[ ]", "team")] if several else [])
            rows = [("", keys)] if len(keys) <= 6 else [("", keys[:4]), ("", keys[4:])]
            return key_hints(rows, title_width=0, gap=2)
        return key_hints([("Everywhere", ([] if fms else [("e e", "enable")])
                           + [("Enter", "disable"), ("Space", "e-stop"),
                              (tabs, "tabs"), ("F1", "again: Diagnostics, Setup, Charts")]),
                          ("This tab", ([] if fms else [("t a s", "teleop / auto / test"), ("p", "practice")])
                           + [("R", "restart code"), ("B", "reboot roboRIO")]
                           + ([("[ ]", "team")] if several else []))], title_width=11)

    def refusal(self, action: str, parameters: tuple[object, ...] = ()) -> str | None:
        """A seat's refusal (:class:`Panel`), and under an FMS its own: the mode and a practice
        run are the FMS's, so their keys are not offered while it is attached."""
        said = super().refusal(action, parameters)
        if said is None and self._fms_attached and action in FMS_DECIDES:
            return FMS_DECIDES[action]
        return said

    # -- which DS -----------------------------------------------------------------------------
    def station(self) -> Any:
        """The selected team's station roles (None when nothing runs). A selected team that
        went with a new field is forgotten."""
        st = super().station()
        selected = getattr(self.app, "selected_team", None)
        if st is not None and selected is not None and st.team != selected:
            self.app.selected_team = None  # type: ignore[attr-defined]
        return st

    # -- the 10 Hz refresh -------------------------------------------------------------------
    def refresh_view(self, engine, now: float) -> None:
        st = self.station()
        self._refresh_teams(engine)
        ds = st.ds if st is not None else None
        self.set_shown("none", ds is None, self._show_none)
        if ds is None:
            self.set_text("ds-none", self._none_text(st), layout=True)
            return
        self._refresh_control(ds)
        self._refresh_robot(ds, now, st.rio)
        self._refresh_match(ds, now)

    def _show_none(self, none: bool) -> None:
        self.query_one("#ds-none").display = none
        self.query_one("#ds-columns").display = not none

    @staticmethod
    def _none_text(st: Any) -> Text:
        text = Text("No Driver Station runs here.\n", "bold")
        if st is not None and st.rio is not None:
            text.append(f"This is the fake roboRIO of team {st.team} ({st.rio.code_state}, "
                        f"{'enabled' if st.rio.enabled else 'disabled'}).\n")
        text.append("Press F8 to pick the roles (ds, rio, fms).")
        return text

    def _refresh_control(self, ds: Any) -> None:
        if getattr(self.app, "wire_stale", False):  # the last state seen may not be the state now
            state, cls = "STATE UNKNOWN · the wire does not answer", "-unknown"
        elif ds.arbiter.estopped:
            state, cls = ("FMS E-STOP" if ds.estop_kind == "fms" else "E-STOPPED"), "-estop"
        elif ds.enabled:
            state, cls = f"ENABLED · {ds.mode.label.upper()}", "-enabled"
        else:
            state, cls = f"DISABLED · {ds.mode.label.upper()}", ""

        def show_state(v: tuple[str, str]) -> None:
            w = self.query_one("#ds-state", Static)
            w.update(v[0])
            w.set_class(v[1] == "-enabled", "-enabled")
            w.set_class(v[1] == "-estop", "-estop")
            w.set_class(v[1] == "-unknown", "-unknown")

        self.set_shown("state", (state, cls), show_state)
        station = ds.station
        colour = "bold red" if station.value < 3 else "bold blue"
        team = Text.assemble(("Team ", "bold"), (str(ds.team), "bold"), "   ",
                             (f"{'Red' if station.value < 3 else 'Blue'} {station.position}", colour))
        if ds.fms.attached:
            team.append("  (FMS)", "dim")
        self.set_text("ds-team", team)
        self.set_shown("fms-attached", ds.fms.attached, self._show_fms_attached)
        mode = ds.mode.label

        def show_mode(m: str) -> None:
            for key, _, _ in MODES:
                self.query_one(f"#ds-mode-{key}", Button).set_class(key == m, "-current")

        self.set_shown("mode", mode, show_mode)
        self.set_text("ds-note", self._note(ds), layout=True)

    @staticmethod
    def _note(ds: DsView) -> str:
        kind = ds.estop_kind  # what holds an e-stop, and its words, are the core's (ds_enable.py)
        if kind in ("fms", "fms-held"):
            return f"{ds.estop_reason}. Then restart the robot code (R) to clear it."
        if kind == "latched":
            return "E-stop latched: restart the robot code (R) or reboot the roboRIO (B) to clear it."
        if kind == "stale":
            return f"{ds.estop_reason[0].upper()}{ds.estop_reason[1:]} (R). The next match will not enable it."
        # what blocks an enable is the core's (ds_enable.py blocker): here only its words, with keys
        blocker = ds.enable_blocker
        if blocker is not None:
            return _BLOCKER_NOTE.get(blocker) or f"{ds.enable_refusal}."
        return "" if ds.enabled else "Ready: press e twice to enable."

    def _refresh_robot(self, ds: Any, now: float, rio: Any = None) -> None:
        comms = ds.link.robot_comms
        if getattr(self.app, "wire_stale", False):  # grey: a lamp must not vouch for what it cannot know
            self.query_one("#ds-light-comms", StatusLight).set("idle", "Communications: unknown")
            self.query_one("#ds-light-code", StatusLight).set("idle", "Robot code: unknown")
            self.query_one("#ds-light-joysticks", StatusLight).set("idle", "Joysticks: unknown")
            return
        self.query_one("#ds-light-comms", StatusLight).set("on" if comms else "off", "Communications")
        if ds.link.robot_code:
            code = ("on", "Robot code")
        elif comms and ds.link.code_starting:
            code = ("warn", "Robot code starting…")
        else:
            code = ("off", "Robot code" if comms else "Robot code (no comms)")
        self.query_one("#ds-light-code", StatusLight).set(*code)
        n = sum(1 for j in ds.sticks.slots if j is not None)
        self.query_one("#ds-light-joysticks", StatusLight).set(
            "on" if n else "off", f"Joysticks: {n}" if n else "Joysticks: none (F2)")
        program = ds.link.program_mode
        brown = "   BROWNOUT" if ds.telemetry.brownout else ""
        if rio is not None and rio.code_state == "stuck":  # our own fake roboRIO: we know more than its DS
            self.set_text("ds-program", Text.assemble(("Robot program: ", "dim"), ("STUCK", "bold red"),
                                                      (" (robot_periodic does not return; R restarts it)", "dim")))
        else:
            self.set_text("ds-program", Text.assemble(("Robot program: ", "dim"), (program or "—", "bold"),
                                                      (brown, "bold red")))
        battery = ds.link.battery
        label = "--.--" if battery is None else f"{battery:5.2f}".strip()

        def show_battery(v: tuple[str, str]) -> None:
            w = self.query_one("#ds-battery", Digits)
            w.update(v[0])
            w.set_class(v[1] == "low", "-low")
            w.set_class(v[1] == "bad", "-bad")

        level = "" if battery is None else "bad" if battery < BATTERY_BAD else "low" if battery < BATTERY_LOW else ""
        self.set_shown("battery", (label, level), show_battery)
        points = list(ds.telemetry.battery_history)  # one C-level copy: the wire thread appends to it
        self.query_one("#ds-chart", LineChart).plot(points, now - CHART_SECONDS, now)
        trips = self.query_one("#ds-trip-chart", LineChart)
        history = self.app.history.get(ds.team)  # type: ignore[attr-defined]
        latest = (ds.team, history.trip[-1][0]) if history is not None and history.trip else None
        if trips.display and latest != self._trip_plotted:  # the app's history, twice a second
            self._trip_plotted = latest
            trips.plot(list(history.trip) if history is not None else [], now - CHART_SECONDS, now)
        self._refresh_link(ds, now)

    def _refresh_link(self, ds: Any, now: float) -> None:
        """Trip time, lost packets, brownouts. A loss, a brownout or a link lost shows at once;
        the trip time and the packets sent, which move with every packet, twice a second (a
        person reads no faster, and each redraw is a repaint)."""
        trip = ds.trip_ms
        narrow = self.has_class("-narrow")
        urgent = (trip is None, ds.link.echoes.lost_packets, ds.telemetry.brownouts, ds.team, narrow)
        if urgent == self._link_urgent and not self.paced("link", now):
            return
        self._link_urgent = urgent
        link = Text()
        link.append("Trip time  " if narrow else "Trip time     ", "dim")
        link.append("—" if trip is None else f"{trip:.1f} ms", "bold")
        link.append("\nLost       " if narrow else "\nLost packets  ", "dim")
        link.append(f"{ds.link.echoes.lost_packets}", "bold")
        sent = ds.link.echoes.sent_packets
        link.append(f" of {sent}" if narrow else f"  of {sent} sent", "dim")
        link.append("\nBrownouts  " if narrow else "\nBrownouts     ", "dim")
        link.append(f"{ds.telemetry.brownouts}", "bold")
        self.set_text("ds-link", link)

    def _refresh_match(self, ds: Any, now: float) -> None:
        status = ds.fms.status
        light = (_FMS_LIGHT.get(status, "warn"), _FMS_TEXT.get(status, f"FMS: {status}"))
        refused = ds.fms.refused
        if refused and not ds.fms.attached:  # logged in, perhaps "good", yet its control is refused
            light = ("off", "FMS: CONTROL REFUSED")
        self.query_one("#ds-light-fms", StatusLight).set(*light)
        countdown = ds.countdown_left
        if ds.fms.attached:
            phase = f"Match: {ds.mode.label}, {'enabled' if ds.enabled else 'disabled'}"
        elif ds.arbiter.practising and ds.arbiter.practice_phase is not None:
            phase = f"Practice: {ds.arbiter.practice_phase}"
        else:
            phase = "No match running"
        self.set_text("ds-phase", phase)

        def show_countdown(v: str) -> None:
            w = self.query_one("#ds-countdown", Digits)
            w.update(v)
            w.display = bool(v)

        self.set_shown("countdown", "" if countdown is None else f"{max(0.0, countdown):.0f}", show_countdown)
        practising = ds.arbiter.practising
        self.set_shown("practice-btn", practising, lambda on: self.query_one("#ds-practice-btn", Button)
                       .__setattr__("label", "Stop practice p" if on else "Start practice p"))
        timing = ds.arbiter.practice_timing
        note = (f"Practice: {timing.countdown:g} s countdown, {timing.auto:g} s auto, {timing.pause:g} s pause, "
                f"{timing.teleop:g} s teleop.")
        if ds.fms.attached:
            note = "Under an FMS the match is the field's."
        if refused:
            note = f"{refused}."
        self.set_text("ds-match-note", note, layout=True)
        messages = self.query_one("#ds-messages", EventLog)
        if messages.display:
            messages.follow(ds.events.items, getattr(self.app, "started_at", 0.0), ds.team)

    def _show_fms_attached(self, attached: bool) -> None:
        """An FMS came or went: the keys it refuses leave the hints and the footer, or come back."""
        self._fms_attached = attached
        self._show_keys()
        self.refresh_bindings()
        for ident in FMS_BUTTONS:  # greyed, not gone: the current mode still shows on its button
            self.query_one(f"#{ident}", Button).disabled = attached

    def _show_keys(self) -> None:
        several = len(self._team_list) > 1
        tabs = "F1…F6" if "legacy" in getattr(self.app, "hidden_tabs", ()) else "F1…F7"
        self.set_text("ds-keys", self._keys_text(several, self.has_class("-narrow"), tabs, self._fms_attached),
                      layout=True)

    def _refresh_teams(self, engine) -> None:
        stations = engine.field.stations if engine is not None else []
        teams = tuple((st.team, st.station.label) for st in stations)
        several = len(teams) > 1
        if teams != self._team_list:
            self._team_list = teams
            bar = self.query_one("#ds-teams", Horizontal)
            bar.remove_children()
            if several:
                # no ids: the old widgets may not be gone yet when the new ones mount
                bar.mount_all([Static(Text.assemble(("Team ", "bold"), (" [ ] ", "reverse bold")),
                                      classes="ds-teams-label")]
                              + [Button(f"{label} {team}", name=f"team-{team}", compact=True,
                                        classes="ds-team -red" if label.startswith("R") else "ds-team -blue")
                                 for team, label in teams])
            bar.display = several
            self._show_keys()
        self.set_shown("tabs", getattr(self.app, "hidden_tabs", None), lambda _: self._show_keys())
        st = self.station()
        selected = st.team if st is not None else None
        self.set_shown("team-selected", (teams, selected), self._mark_team)

    def _mark_team(self, value: tuple) -> None:
        _, selected = value
        for button in self.query("#ds-teams Button").results(Button):
            button.set_class(button.name == f"team-{selected}", "-selected")

    # -- actions -------------------------------------------------------------------------------
    def action_mode(self, mode: str) -> None:
        self.send(SetMode(mode))
        self.app.refresh_views()  # type: ignore[attr-defined]

    def action_practice(self) -> None:
        st = self.station()
        running = st is not None and st.ds is not None and st.ds.arbiter.practising
        self.send(Practice("stop" if running else "start"))

    def action_restart_code(self) -> None:
        if self.send(RestartCode()):
            self.notify("Restart robot code requested")

    def action_reboot(self) -> None:
        if self.send(RebootRoboRIO()):
            self.notify("Reboot roboRIO requested")

    def action_team(self, step: int) -> None:
        engine = self.app.engine  # type: ignore[attr-defined]
        if engine is None or len(engine.field.stations) < 2:
            self.notify("Only one team runs here", timeout=2)
            return
        teams = [st.team for st in engine.field.stations]
        current = self.station()
        i = teams.index(current.team) if current is not None else 0
        self.select_team(teams[(i + step) % len(teams)])

    def select_team(self, team: int) -> None:
        self.app.selected_team = team  # type: ignore[attr-defined]
        self.app.refresh_views()  # type: ignore[attr-defined]

    @on(Button.Pressed)
    async def _button(self, event: Button.Pressed) -> None:
        bid = event.button.id or ""
        event.stop()
        name = event.button.name or ""
        if name.startswith("team-"):
            self.select_team(int(name.removeprefix("team-")))
            return
        if bid.startswith("ds-mode-"):
            self.action_mode(bid.removeprefix("ds-mode-"))
        elif bid == "ds-enable-btn":
            self.send(Enable())  # a click is deliberate: no second press
        elif bid == "ds-disable-btn":
            await self.app.run_action("disable")  # the app's own action, as the Enter key
        elif bid == "ds-estop-btn":
            await self.app.run_action("estop")  # the app's own action, as the Space key
        elif bid == "ds-restart-btn":
            self.action_restart_code()
        elif bid == "ds-reboot-btn":
            self.action_reboot()
        elif bid == "ds-practice-btn":
            self.action_practice()
        self.app.refresh_views()  # type: ignore[attr-defined]
