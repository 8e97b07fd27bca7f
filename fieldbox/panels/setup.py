"""The Setup tab (F1 F1 F1): what the NI Driver Station's Setup tab holds, for the selected DS.

* **Team and station**: the robot's address follows the team (10.TE.AM.2, 127.TE.AM.2 on
  loopback), so a new team or station restarts the field with them, as the roles dialog (F8)
  does. A field of six (``--teams``) keeps its teams: this box then only shows them.
* **Game data**: the text the DS sends its robot over TCP (frame 0x0e), as a practice field's
  game data; an FMS's replaces it during a match (``set_game_data`` on the DS).
* **Practice match timing**: countdown, autonomous, pause and teleop lengths of the practice
  run the DS times itself (``p`` on the Driver Station tab), for the next run.
* **Dashboard**: in 2010 mode the DS sends a dashboard packet to an address after each control
  packet (it restarts the field); today's dashboards speak NetworkTables to the robot and
  never to the DS, so fieldbox has nothing to set for them.

Keys (this tab): ``t`` team, ``g`` game data, ``p`` practice times, ``d`` dashboard (2010):
each puts the cursor in its box; Tab moves on, Enter applies (and disables the robot, as it
does everywhere), Esc leaves the box. Space e-stops, in a box too: ctrl+space types a space.
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any

from rich.text import Text
from textual import on
from textual.app import ComposeResult
from textual.binding import Binding
from textual.containers import Horizontal, Vertical
from textual.widgets import Input, Label, Static

from protocol.enums import AllianceStation
from roles.cores import addresses as A
from roles.cores.commands import Command, SetGameData, SetPracticeTiming

from ..widgets import TextBox, key_hints
from .base import Panel

PRACTICE = ("countdown", "auto", "pause", "teleop")


class SetupPanel(Panel):
    TITLE = "Setup"
    SHORT_TITLE = "Setup"
    ID = "setup"
    can_focus = True

    BINDINGS = [
        Binding("up", "scroll_up", "Scroll up", show=False),
        Binding("down", "scroll_down", "Scroll down", show=False),
        Binding("t", "edit('setup-team')", "Team"),
        Binding("g", "edit('setup-game-data')", "Game data"),
        Binding("p", "edit('setup-countdown')", "Practice times"),
        Binding("d", "edit('setup-dashboard')", "Dashboard", show=False),
        Binding("escape", "leave", "Leave the box", show=False),
    ]

    DEFAULT_CSS = """
    SetupPanel { layout: vertical; padding: 0 1; overflow-y: auto; }
    SetupPanel .setup-box { height: auto; padding: 0 1; border: round $panel-lighten-2;
                            border-title-color: $text; }
    SetupPanel .setup-box:focus-within { border: round $accent; }
    SetupPanel #setup-top { height: auto; }
    SetupPanel #setup-top > .setup-box { width: 1fr; }
    SetupPanel .setup-row { height: auto; }
    SetupPanel .setup-row Label { padding: 0 1 0 0; }
    SetupPanel Input { width: 12; }
    SetupPanel #setup-game-data { width: 1fr; max-width: 40; }
    SetupPanel #setup-dashboard { width: 1fr; max-width: 32; }
    SetupPanel .setup-note { height: auto; color: $text-muted; }
    SetupPanel .setup-note.-empty { display: none; }
    SetupPanel .setup-note.-error { color: $error; }
    SetupPanel #setup-keys { height: auto; margin-top: 1; color: $text-muted; }
    SetupPanel.-wide #setup-top, SetupPanel.-wide .setup-box { margin-bottom: 1; }
    """

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self._config_shown: Any = None
        self._team_locked = False  # the team is set elsewhere (_lock_team)

    # -- layout ------------------------------------------------------------------------------
    def compose(self) -> ComposeResult:
        yield Static("", id="setup-none")
        with Horizontal(id="setup-top"):
            with Vertical(id="setup-team-box", classes="setup-box"):
                with Horizontal(classes="setup-row"):
                    yield Label("Team")
                    yield TextBox(id="setup-team", type="integer", max_length=5, compact=True, select_on_focus=True)
                    yield Label("  Station")
                    yield TextBox(id="setup-station", max_length=2, restrict=r"[RrBb1-3]*", compact=True,
                                select_on_focus=True)
                yield Static("", id="setup-team-note", classes="setup-note")
            with Vertical(id="setup-game-box", classes="setup-box"):
                with Horizontal(classes="setup-row"):
                    yield Label("Game data")
                    yield TextBox(id="setup-game-data", max_length=255, compact=True, select_on_focus=True)
                yield Static("", id="setup-game-note", classes="setup-note")
        with Vertical(id="setup-practice-box", classes="setup-box"):
            with Horizontal(classes="setup-row"):
                for key in PRACTICE:
                    yield Label(f"{key}" if key == "countdown" else f"  {key}")
                    yield TextBox(id=f"setup-{key}", type="number", restrict=r"[0-9.]*", max_length=6,
                                compact=True, select_on_focus=True)
                yield Label("  seconds")
            yield Static("", id="setup-practice-note", classes="setup-note")
        with Vertical(id="setup-dashboard-box", classes="setup-box"):
            with Horizontal(classes="setup-row"):
                yield Label("Dashboard packets to")
                yield TextBox(id="setup-dashboard", compact=True, select_on_focus=True,
                            placeholder="HOST:PORT or off")
            yield Static("", id="setup-dashboard-note", classes="setup-note")
        yield Static(self._keys_text(), id="setup-keys", classes="key-hints")

    def on_mount(self) -> None:
        self.query_one("#setup-team-box").border_title = "Team and station"
        self.query_one("#setup-game-box").border_title = "Game data"
        self.query_one("#setup-practice-box").border_title = "Practice match timing"
        self.query_one("#setup-dashboard-box").border_title = "Dashboard"
        self.query_one("#setup-none").display = False
        for inp in self.query(Input):
            inp.cursor_blink = False
        self.query_one("#setup-practice-note").add_class("-empty")  # until something is said

    def on_resize(self) -> None:
        self.set_class(self.size.height >= 30, "-wide")

    @staticmethod
    def _keys_text(team: bool = True) -> Text:
        """The tab's keys; without ``t`` where the team is not this app's to set."""
        return key_hints([("This tab", [("t", "team")] * team + [("g", "game data"), ("p", "practice times"),
                                        ("d", "dashboard"), ("Tab", "next box"), ("Enter", "apply"),
                                        ("Esc", "leave the box"), ("ctrl+space", "types a space")])],
                         title_width=9)

    # -- the 10 Hz refresh -------------------------------------------------------------------
    def refresh_view(self, engine, now: float) -> None:
        st = self.station()
        ds = st.ds if st is not None else None
        config = getattr(self.app, "config", None)
        none = ds is None
        self.set_shown("none", none, self._show_none)
        if ds is None:  # none
            self.set_text("setup-none", "No Driver Station runs here: its setup has nothing to set. "
                                        "Press F8 to pick the roles.", layout=True)
            return
        field_of_six = bool(config is not None and config.teams)
        shared = getattr(self.app, "seat", None) is not None  # a classroom's field is the teacher's
        self._value("setup-team", str(ds.team))
        self._value("setup-station", ds.station.label)
        self.set_shown("field-of-six", field_of_six or shared, self._lock_team)
        if shared:
            team_note = "This app shares the classroom's field: its teams are the teacher's."
        elif field_of_six:
            team_note = "A field's teams come from --teams: [ ] on the Driver Station tab picks the one shown here."
        else:
            plan = config.plan if config is not None else "loopback"
            robot = A.robot_address(ds.team, plan, config.robot if config is not None else None)
            team_note = f"The robot is at {robot} ({plan}). Enter applies: the field restarts with the team."
        if not self.has_class("-error-team"):
            self.set_text("setup-team-note", team_note, layout=True)
        game = ds.tcp.game_data
        self._value("setup-game-data", game or "")
        note = Text()
        note.append("The robot has: ", "dim")
        note.append(repr(game) if game else "none", "bold")
        if ds.fms.attached:
            note.append("   (the FMS's: an FMS replaces it)", "dim")
        self.set_text("setup-game-note", note, layout=True)
        timing = ds.arbiter.practice_timing
        for key in PRACTICE:
            self._value(f"setup-{key}", f"{getattr(timing, key):g}")
        legacy = ds.legacy is not None
        self.set_shown("legacy", legacy, self._show_dashboard)
        if legacy:
            self._value("setup-dashboard", (config.dashboard if config is not None else None) or "")
            self.set_text("setup-dashboard-note", "2010 mode: after each control packet the DS sends a dashboard "
                          "packet here (empty: this machine, port 1165). Enter applies: the field restarts.",
                          layout=True)
        else:
            self.set_text("setup-dashboard-note", "Today's dashboards (Shuffleboard, Elastic, SmartDashboard) "
                          "speak NetworkTables to the robot, never to the Driver Station: start yours "
                          "beside fieldbox. In 2010 mode (F8) the DS sends a dashboard packet, set here.",
                          layout=True)

    def _show_none(self, none: bool) -> None:
        self.query_one("#setup-none").display = none
        for box in ("#setup-top", "#setup-practice-box", "#setup-dashboard-box"):
            self.query_one(box).display = not none

    def _lock_team(self, locked: bool) -> None:
        """A team set elsewhere (a field's --teams, a classroom's teacher): its boxes locked,
        and its key neither in the footer nor in the key help (it would do nothing)."""
        for ident in ("#setup-team", "#setup-station"):
            self.query_one(ident, Input).disabled = locked
        self._team_locked = locked
        self.set_text("setup-keys", self._keys_text(not locked), layout=True)
        self.app.refresh_bindings()

    def refusal(self, action: str, parameters: tuple[object, ...] = ()) -> str | None:
        if action == "edit" and parameters[:1] == ("setup-team",) and self._team_locked:
            return ("this app shares the classroom's field: its teams are the teacher's"
                    if getattr(self.app, "seat", None) is not None else
                    "a field's teams come from --teams: [ ] on the Driver Station tab picks the one shown here")
        return super().refusal(action, parameters)

    def _show_dashboard(self, legacy: bool) -> None:
        self.query_one("#setup-dashboard").display = legacy
        self.query_one("#setup-dashboard-box .setup-row").display = legacy

    def _value(self, ident: str, value: str) -> None:
        """An input shows the DS's value unless the user is typing in its box (a team typed,
        then Tab to the station, is applied with the station)."""
        inp = self.query_one(f"#{ident}", Input)
        box = inp.parent.parent if inp.parent is not None else None
        focused = self.screen.focused if self.is_mounted else None
        typing = focused is not None and box is not None and box in focused.ancestors_with_self
        if not typing and inp.value != value:
            inp.value = value

    # -- keys ---------------------------------------------------------------------------------
    def action_edit(self, ident: str) -> None:
        inp = self.query_one(f"#{ident}", Input)
        if inp.display and not inp.disabled:
            inp.focus()
        elif ident == "setup-dashboard":
            self.notify("the dashboard packet is a 2010 mode thing: F8 and tick 2010 legacy", timeout=4)

    def action_leave(self) -> None:
        self.focus()

    # -- applying -----------------------------------------------------------------------------
    @on(Input.Submitted)
    def _submitted(self, event: Input.Submitted) -> None:
        event.stop()
        ident = event.input.id or ""
        if ident in ("setup-team", "setup-station"):
            self._apply_team()
        elif ident == "setup-game-data":
            self._apply_game_data(event.value)
        elif ident == "setup-dashboard":
            self._apply_dashboard(event.value)
        elif ident.removeprefix("setup-") in PRACTICE:
            self._apply_practice(ident.removeprefix("setup-"), event.value)

    @on(Input.Blurred)
    def _blurred(self, event: Input.Blurred) -> None:
        key = (event.input.id or "").removeprefix("setup-")
        if key in PRACTICE:  # as the FMS's period lengths: leaving the box applies it
            self._apply_practice(key, event.value)

    def _note(self, ident: str, text: str, error: bool) -> None:
        note = self.query_one(f"#{ident}", Static)
        note.update(text)
        note.set_class(error, "-error")
        note.set_class(not text, "-empty")
        self._shown.pop(ident, None)  # the refresh may draw it again later

    def _apply_team(self) -> None:
        config = getattr(self.app, "config", None)
        if config is None or config.teams or getattr(self.app, "seat", None) is not None:
            return
        try:
            team = A.check_team(int(self.query_one("#setup-team", Input).value or "0"))
            station = AllianceStation.parse(self.query_one("#setup-station", Input).value or "")
        except ValueError as exc:
            self.set_class(True, "-error-team")
            self._note("setup-team-note", f"not applied: {exc}", True)
            return
        self.set_class(False, "-error-team")
        self.query_one("#setup-team-note", Static).set_class(False, "-error")
        if (team, station) == (config.team, config.station):
            return
        self.focus()
        if self.app.start_engine(replace(config, team=team, station=station)):  # type: ignore[attr-defined]
            self.notify(f"team {team} at {station.label}: the field restarted", timeout=4)

    def _ds_send(self, command: Command, done=None) -> bool:
        """A command to the shown station's DS; False (nothing sent) without one."""
        st = self.station()
        if st is None or st.ds is None:
            return False
        return self.send(replace(command, team=st.team), done)

    def _apply_game_data(self, text: str) -> None:
        def answered(answer) -> None:
            exc = answer.exception()
            if exc is not None:
                self.notify(str(exc), title="game data not set", severity="warning")
            self._refresh_now()

        self._ds_send(SetGameData(text.strip()), done=answered)

    def _apply_practice(self, key: str, text: str) -> None:
        st = self.station()
        if st is None or st.ds is None:
            return
        current = getattr(st.ds.arbiter.practice_timing, key)
        try:
            value = float(text)
        except ValueError:
            value = None
        if value is None or value == current:
            self.query_one(f"#setup-{key}", Input).value = f"{current:g}"
            return

        def answered(answer) -> None:
            exc = answer.exception()
            if exc is not None:
                self._note("setup-practice-note", f"{key}: {exc}", True)
            else:
                self._note("setup-practice-note", f"{key} is now {value:g} s, from the next practice run", False)
            self._refresh_now()

        length: dict[str, Any] = {key: value}  # the one phase this box names
        self._ds_send(SetPracticeTiming(**length), answered)

    def _apply_dashboard(self, text: str) -> None:
        config = getattr(self.app, "config", None)
        if config is None or not config.legacy or getattr(self.app, "seat", None) is not None:
            return
        value = text.strip() or None
        if value == config.dashboard:
            return
        from roles.runtime.field import parse_dashboard

        try:
            parse_dashboard(value, "127.0.0.1")
        except ValueError as exc:
            self._note("setup-dashboard-note", f"not applied: {exc}", True)
            return
        self.focus()
        self.app.start_engine(replace(config, dashboard=value))  # type: ignore[attr-defined]

    def _refresh_now(self) -> None:
        if self.is_mounted:
            self.redraw_now()
