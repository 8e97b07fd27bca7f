"""The FMS panel: the match and the six alliance stations, as a field's scorer's table sees them.

At the top, the time left in the current period (big, for a projector), the phase and the
match. Below, one row per station: its team, its links (DS, robot, radio and roboRIO pings as
the DS reports them), battery, trip time and lost packets, and what the field commands
(enabled, bypass, e-stop, a-stop). Under the table, what the FMS refused for each station
(logins while its DS was live, status from another address: roles/cores/ownership.py), shown only
once something was; whether a match can start now and every reason it cannot
(the view's ``refusals``, live), and the period lengths, editable. What each station's row
says (its readiness and the words for it) is the core's (roles/cores/fms_station.py); the
panel gives it a colour.

Keys (shown in the footer): ``1``-``6`` or the arrow keys pick a station (R1..B3); ``b``
bypasses it (again: removes the bypass), ``x`` e-stops it (again, after the match: clears),
``a`` a-stops it (auto only); ``s`` starts the match, ``ctrl+a`` aborts it, ``n`` sets up
the next match, ``r`` replays this one, ``t`` changes the match type, ``l`` goes to the match
log (its newest line shows unless a person scrolled back in it), ``d`` goes to the
period lengths (Tab or Esc applies what was typed; Enter is the app's disable). Space stays the app's
own e-stop of the Driver Station, in those boxes too; the station e-stop is ``x``.

Station commands go through the headless command language (``bypass R1 on``, ``estop R1``,
``astop R1``, ``match start|abort|next``), so the panel does exactly what a script can.
"""

from __future__ import annotations

from typing import Any, Iterable

from rich.text import Text
from textual import on
from textual.app import ComposeResult
from textual.binding import Binding
from textual.containers import Horizontal, Vertical
from textual.widgets import DataTable, Digits, Input, Label, Log, Static

from protocol.enums import AllianceStation, TournamentLevel
from roles.cores.commands import (Bypass, Command, MatchControl, ReplayMatch, SetMatchTiming, SetUpMatch,
                                  StationAStop, StationEStop)
from roles.cores.fms import MatchStartRefused
from roles.cores.fms_station import Readiness
from roles.cores.match import Phase
from roles.cores.views import StationView

from ..widgets import StreamCursor, TextBox, theme_colour
from .base import Panel

#: Seconds the "start refused" banner stays up after a refused start.
REFUSED_SHOWN = 8.0

LEVEL_NAMES = {TournamentLevel.MATCH_TEST: "Test", TournamentLevel.PRACTICE: "Practice",
               TournamentLevel.QUALIFICATION: "Qualification", TournamentLevel.PLAYOFF: "Playoff"}
LEVEL_CYCLE = (TournamentLevel.PRACTICE, TournamentLevel.QUALIFICATION, TournamentLevel.PLAYOFF,
               TournamentLevel.MATCH_TEST)

COLUMNS = (
    ("station", "Stn"), ("team", "Team"), ("ds", "DS"), ("robot", "Robot"), ("radio", "Radio"),
    ("rio", "RIO"), ("battery", "Battery"), ("trip", "Trip"), ("lost", "Lost"), ("field", "Field"),
    ("bypass", "Bypass"), ("estop", "E-stop"), ("astop", "A-stop"), ("status", "Status"),
)
#: Under NARROW columns the table keeps what a match is run by: the stops and the status (the
#: Field column says again what Status says; the pings follow the robot link; trip time and
#: lost packets are on the Faults tab).
NARROW = 110
NARROW_COLUMNS = (
    ("station", "Stn"), ("team", "Team"), ("ds", "DS"), ("robot", "Rbt"), ("battery", "Batt"),
    ("bypass", "Byp"), ("estop", "E-stop"), ("astop", "A-stop"), ("status", "Status"),
)
#: Match log lines kept on screen (the FMS keeps its own, bounded).
LOG_LINES = 200

HELP = ("1-6 or ↑↓ pick a station · b bypass · x e-stop station · a a-stop · s start · ctrl+a abort · "
        "n next match · r replay · t match type · d durations · l log")

#: What a classroom's driver or observer reads instead of the help: the match is the teacher's
#: (fieldbox/seats.py hides the keys, the help and the period lengths' boxes).
STUDENT_NOTE = "The match is the teacher's: this tab shows it (l scrolls the match log)"

NO_FMS = ("No FMS runs here.\n\n"
          "Add it with F8 (Roles) and tick FMS, or start fieldbox with the FMS role:\n"
          "    fieldbox --roles ds,rio,fms --team 254\n"
          "    fieldbox field --teams 254,1114,2056,118,148,1678      (a full field of six)")


_UNSET = object()  # a cell never drawn (None is a value: "no team")

#: The Field column: what the robot is, as its DS reports it (the field's enable alone is not
#: an enabled robot); "disabled" for every other readiness.
FIELD_WORDS = {Readiness.RUNNING: "enabled", Readiness.ENABLING: "enabling", Readiness.HELD_BY_DS: "held"}
#: The Status column's colour by readiness: refused by the field (bad), waiting for something
#: a person must fix (warning), good to go (ok); the rest plain.
STATUS_STYLE = {Readiness.WRONG_STATION: "bad", Readiness.WRONG_ANSWER: "bad", Readiness.NO_ANSWER: "bad",
                Readiness.NO_DS: "warning", Readiness.NO_ROBOT: "warning", Readiness.ESTOPPED: "warning",
                Readiness.HELD_BY_DS: "warning", Readiness.READY: "ok", Readiness.RUNNING: "ok"}


def level_name(level: Any) -> str:
    try:
        return LEVEL_NAMES[TournamentLevel(level)]
    except ValueError:
        return f"Level {int(level)}"


def clock_text(seconds: int) -> str:
    return f"{seconds // 60}:{seconds % 60:02d}"


def refusals_text(fms) -> str:
    """One line per station the FMS refused something for (roles/cores/ownership.py), or "". Status
    that came before any DS logged in for the station is in the log only: every DS sends some
    at start."""
    lines = []
    for st in fms.stations:
        logins, status = st.refused_logins, st.link.foreign_packets - st.unclaimed_status
        if not (logins or status):
            continue
        parts = []
        if logins:
            parts.append(f"{logins:,} login{'s' if logins != 1 else ''} while its DS was live")
        if status:
            parts.append(f"{status:,} status packet{'s' if status != 1 else ''} from another address")
        last = f", last from {st.last_refused}" if st.last_refused else ""
        lines.append(f"{st.name} refused {' and '.join(parts)}{last}")
    return "\n".join(lines)


class MatchLog(Log):
    """The match log: its newest line always in view, unless a person scrolled back in it.

    Textual's Log follows only while it stands at its end, and a log first written before
    it was laid out (the FMS tab hidden at start) never stood there again: it stayed on its
    first lines for good. This one follows unless a person, with the focus in it, scrolled
    up (a key or the wheel); scrolling down to the end, End, or leaving it follows again.
    The scroll waits for the layout (``scroll_end`` without ``immediate``), so it lands on
    the real last line."""

    _held = False  # scrolled back by a person: new lines do not move it

    def write_lines(self, lines: Iterable[str], scroll_end: bool | None = None) -> "MatchLog":
        super().write_lines(lines, scroll_end=False)
        self._follow()
        return self

    def _follow(self) -> None:
        if not self._held:
            self.scroll_end(animate=False, x_axis=False)

    def _hold(self) -> None:
        self._held = self.has_focus

    def _release_at_end(self) -> None:
        if self.scroll_target_y >= self.max_scroll_y:
            self._held = False

    def action_scroll_up(self) -> None:
        self._hold()
        super().action_scroll_up()

    def action_page_up(self) -> None:
        self._hold()
        super().action_page_up()

    def action_scroll_home(self) -> None:
        self._hold()
        super().action_scroll_home()

    def on_mouse_scroll_up(self) -> None:
        self._hold()

    def action_scroll_down(self) -> None:
        super().action_scroll_down()
        self._release_at_end()

    def action_page_down(self) -> None:
        super().action_page_down()
        self._release_at_end()

    def action_scroll_end(self) -> None:
        self._held = False
        super().action_scroll_end()

    def on_resize(self) -> None:
        self._follow()

    def on_blur(self) -> None:
        self._held = False  # left: back to the newest line
        self._follow()


class FmsPanel(Panel):
    """The match, the six stations, start/abort and the per-station stops."""

    TITLE = "FMS"
    SHORT_TITLE = "FMS"
    ID = "fms"
    REFRESH_TICKS = 2
    can_focus = True  # with no FMS, the panel itself takes the keys (and says what is missing)

    BINDINGS = [
        *(Binding(str(i + 1), f"pick({i})", AllianceStation(i).label, show=False) for i in range(6)),
        Binding("b", "bypass", "Bypass"),
        Binding("x", "station_estop", "E-stop station"),
        Binding("a", "astop", "A-stop"),
        Binding("s", "start", "Start match"),
        Binding("ctrl+a", "abort", "Abort match", priority=True),
        Binding("n", "next_match", "Next match"),
        Binding("r", "replay", "Replay"),
        Binding("t", "match_type", "Match type"),
        Binding("d", "edit_durations", "Durations"),
        Binding("l", "match_log", "Match log"),
        Binding("escape", "back_to_table", "Back to stations", show=False),
    ]

    # Under 30 rows the top and the period lengths take a line less each and the help and the
    # match log go; a tall screen gives the match log every row left.
    DEFAULT_CSS = """
    FmsPanel { layout: vertical; }
    FmsPanel #fms-none { padding: 1 2; height: auto; }
    FmsPanel #fms-main { height: 1fr; }
    FmsPanel #fms-top { height: 5; padding: 0 1; }
    FmsPanel #fms-clock { width: auto; min-width: 16; padding: 1 2 0 0; }
    FmsPanel #fms-match-box { width: 1fr; height: 5; }
    FmsPanel #fms-phase { width: auto; min-width: 14; height: 3; padding: 1 2; text-style: bold;
                          content-align: center middle; background: $panel; margin-top: 1; }
    FmsPanel #fms-phase.-auto { background: $warning; color: $background; }
    FmsPanel #fms-phase.-pause { background: $secondary; color: $background; }
    FmsPanel #fms-phase.-teleop { background: $success; color: $background; }
    FmsPanel #fms-phase.-post-match { background: $primary; color: $background; }
    FmsPanel #fms-match { width: 1fr; height: 3; padding: 0 2; margin-top: 1; }
    FmsPanel #fms-stations { height: auto; max-height: 9; }
    FmsPanel #fms-refused { height: auto; padding: 0 1; color: $warning; }
    FmsPanel #fms-start { height: auto; padding: 0 1; margin-top: 1; }
    FmsPanel #fms-start.-ready { color: $success; text-style: bold; }
    FmsPanel #fms-start.-blocked { color: $warning; }
    FmsPanel #fms-start.-refused { background: $error 30%; color: $text; }
    FmsPanel #fms-timing { height: 3; padding: 0 1; margin-top: 1; }
    FmsPanel #fms-timing Label { padding: 1 1 0 1; }
    FmsPanel #fms-timing Input { width: 10; }
    FmsPanel #fms-timing-note { width: 1fr; padding: 1 1 0 2; color: $text-muted; }
    FmsPanel #fms-timing-note.-error { color: $error; }
    FmsPanel #fms-help, FmsPanel #fms-student { height: auto; padding: 0 1; margin-top: 1; color: $text-muted; }
    FmsPanel #fms-log { height: 1fr; min-height: 4; margin-top: 1; border: round $panel-lighten-2;
                        border-title-color: $text; overflow-x: hidden; overflow-y: auto; }
    FmsPanel #fms-log:focus { border: round $accent; }
    FmsPanel.-short #fms-top { height: 3; }
    FmsPanel.-short #fms-clock { padding: 0 2 0 0; }
    FmsPanel.-short #fms-phase { margin-top: 0; padding: 0 2; }
    FmsPanel.-short #fms-match { margin-top: 0; }
    FmsPanel.-short #fms-start { margin-top: 0; }
    FmsPanel.-short #fms-timing { height: 1; margin-top: 0; }
    FmsPanel.-short #fms-timing Label { padding: 0 1; }
    FmsPanel.-short #fms-timing-note { padding: 0 1 0 2; }
    FmsPanel.-short #fms-help, FmsPanel.-short #fms-student { margin-top: 0; }
    FmsPanel.-short #fms-log { min-height: 0; margin-top: 0; }
    """

    def __init__(self, *, id: str | None = None) -> None:
        super().__init__(id=id)
        self._engine = None
        self._drawn: dict[tuple[str, str], Any] = {}
        self._refused: list[str] = []
        self._refused_at: float | None = None
        self._theme: str | None = None
        self.builds = 0
        self._narrow = False
        self._columns: set[str] = {key for key, _ in COLUMNS}
        self._log_cursor = StreamCursor()  # where the match log shown stands

    # -- layout ---------------------------------------------------------------------------
    def compose(self) -> ComposeResult:
        yield Static(NO_FMS, id="fms-none")
        with Vertical(id="fms-main"):
            with Horizontal(id="fms-top"):
                yield Digits("0:00", id="fms-clock")
                yield Static("", id="fms-phase")
                yield Static("", id="fms-match")
            table: DataTable = DataTable(id="fms-stations", cursor_type="row")
            yield table
            yield Static("", id="fms-refused")
            yield Static("", id="fms-start")
            with Horizontal(id="fms-timing"):
                for key in ("auto", "pause", "teleop"):
                    yield Label(f"{key} s")
                    yield TextBox(id=f"fms-{key}", type="number", restrict=r"[0-9.]*", max_length=7,
                                select_on_focus=True)
                yield Static("period lengths: d to edit, Tab or Esc applies", id="fms-timing-note")
            yield Static(HELP, id="fms-help")
            yield Static(STUDENT_NOTE, id="fms-student", classes="student-only")
            yield MatchLog(max_lines=LOG_LINES, id="fms-log")

    def on_mount(self) -> None:
        self._build_columns(False)
        for inp in self.query(Input):
            inp.cursor_blink = False
        log = self.query_one("#fms-log", Log)
        log.border_title = "Match log · seconds since the field started · l: ↑↓ scroll, Esc back"
        self.query_one("#fms-main").display = False
        self.query_one("#fms-refused").display = False

    def take_focus(self) -> None:
        self._focus_table()

    def on_resize(self) -> None:
        short = self.size.height < 30
        self.set_class(short, "-short")
        for inp in self.query("#fms-timing Input").results(Input):
            inp.compact = short
        narrow = self.size.width < NARROW
        if narrow != self._narrow:
            self._build_columns(narrow)
            if self._engine is not None and self._engine.field.fms is not None:
                self._stations(self._engine.field.fms)

    def _build_columns(self, narrow: bool) -> None:
        """The table's columns for the width (all rows drawn again)."""
        self._narrow = narrow
        table = self.query_one("#fms-stations", DataTable)
        cursor = table.cursor_row
        table.clear(columns=True)
        columns = NARROW_COLUMNS if narrow else COLUMNS
        for key, heading in columns:
            table.add_column(heading, key=key)
        for station in AllianceStation:
            table.add_row(*([""] * len(columns)), key=station.label)
        table.move_cursor(row=max(0, cursor))
        self._columns = {key for key, _ in columns}
        self._drawn.clear()

    def _focus_table(self) -> None:
        if self.query_one("#fms-main").display:
            self.query_one("#fms-stations", DataTable).focus()
        else:
            self.focus()

    # -- what the keys act on ---------------------------------------------------------------
    @property
    def fms(self):
        engine = self.engine
        return engine.field.fms if engine is not None else None

    @property
    def selected(self) -> AllianceStation:
        row = self.query_one("#fms-stations", DataTable).cursor_row
        return AllianceStation(min(max(row, 0), 5))

    def _need_fms(self) -> Any:
        fms = self.fms
        if fms is None:
            self.notify("no FMS runs here: add it with F8 (Roles)", severity="warning")
        return fms

    # -- the 10 Hz refresh ------------------------------------------------------------------
    def refresh_view(self, engine, now: float) -> None:
        fms = engine.field.fms
        if engine is not self._engine:
            self._engine = engine
            self.builds += 1
            self._drawn.clear()
            self._shown.clear()
            self._refused, self._refused_at = [], None
            self._log_cursor.reset()
            self.query_one("#fms-log", Log).clear()
            legacy = getattr(engine.field.config, "legacy", False)
            note = NO_FMS
            if legacy:
                from roles.runtime import field as field_module
                note = "No FMS runs here: " + getattr(field_module, "LEGACY_FMS_NOTE",
                                                      "the 2010 protocol has no FMS") + "."
            self.query_one("#fms-none", Static).update(note)
            self.query_one("#fms-none").display = fms is None
            self.query_one("#fms-main").display = fms is not None
            self.can_focus = fms is None  # otherwise the stations table takes the keys
            if self.is_visible_tab():
                self._focus_table()
        if fms is None:
            return
        if self.app.theme != self._theme:  # colours come from the theme: redraw every cell
            self._theme = self.app.theme
            self._drawn.clear()
        m = fms.match
        self.set_shown("clock", clock_text(fms.remaining_left),
                       lambda v: self.query_one("#fms-clock", Digits).update(v))
        self.set_shown("phase", Phase(m.phase), self._show_phase)
        play = f", play {m.play}" if m.play > 1 else ""
        timing = m.timing
        self.set_shown("match", f"{level_name(m.level)} match {m.number}{play}\n"
                                f"auto {timing.auto:g} s · pause {timing.pause:g} s · teleop {timing.teleop:g} s",
                       lambda v: self.query_one("#fms-match", Static).update(v))
        self._stations(fms)
        self.set_shown("refused", refusals_text(fms), self._show_refused)
        self._start_box(fms, now)
        self._timing_inputs(fms)
        self._match_log(fms)

    def _match_log(self, fms) -> None:
        """Append what the FMS logged since the last refresh (only when shown: the log is the
        FMS's, bounded, and read again from where it stands when the tab comes back)."""
        if not self.query_one("#fms-log").display:
            return
        new, fresh = self._log_cursor.take(fms.match_log)
        log = self.query_one("#fms-log", Log)
        if fresh:
            log.clear()
        t0 = getattr(self.app, "started_at", 0.0)
        log.write_lines(f"{max(0.0, t - t0):9.3f}  {text}" for t, text in new[-LOG_LINES:])

    def is_visible_tab(self) -> bool:
        try:
            return self.app.query_one("TabbedContent").active == self.ID  # type: ignore[attr-defined]
        except Exception:
            return False

    def _show_phase(self, phase: Phase) -> None:
        widget = self.query_one("#fms-phase", Static)
        widget.update(phase.value.upper())
        for p in Phase:
            widget.set_class(p is phase, f"-{p.value}")

    def _stations(self, fms) -> None:
        table = self.query_one("#fms-stations", DataTable)
        # Which DS each station has is said once a 2027 FIRST Driver Station is among them:
        # until then every DS is the NI DS, and the DS column is its link alone.
        mixed = any(st.ds_kind == "2027 DS" for st in fms.stations)
        for st in fms.stations:
            for column, value in self._station_cells(st, mixed).items():
                if column not in self._columns:
                    continue
                cell = (st.label, column)
                if self._drawn.get(cell, _UNSET) != value:
                    self._drawn[cell] = value
                    table.update_cell(st.label, column, self._cell_text(column, value, st),
                                      update_width=True)

    @staticmethod
    def _station_cells(st: StationView, kinds: bool = False) -> dict[str, Any]:
        """Plain values per column (what decides whether a cell is redrawn). The status is the
        core's readiness and its words (roles/cores/fms_station.py readiness); ``kinds``: the
        DS column names each station's DS ("NI DS", "2027 DS")."""
        readiness, report = Readiness(st.readiness), st.report
        return {
            "station": st.label,
            "team": st.team,
            # the link, and (kinds) which DS holds the station: the NI DS or the 2027 FIRST DS
            "ds": (st.ds_link, st.ds_kind if kinds else None) if st.team is not None else None,
            "robot": report.robot_link if st.team is not None else None,
            "radio": report.radio_ping if st.team is not None else None,
            "rio": report.rio_ping if st.team is not None else None,
            "battery": None if report.battery is None or not report.udp_link else round(report.battery, 1),
            "trip": report.trip_time_ms if report.udp_link else None,
            "lost": report.lost_packets if report.udp_link else None,
            "field": FIELD_WORDS.get(readiness, "disabled"),
            "bypass": st.bypass,
            "estop": st.estop,
            "astop": st.astop,
            "status": (readiness, st.reason),
        }

    def _cell_text(self, column: str, value: Any, st) -> Text:
        def colour(name: str, fallback: str) -> str:
            return theme_colour(self.app, name, fallback)

        ok, bad = colour("fb-comms-ok", "green"), colour("fb-comms-bad", "red")
        if column == "station":
            red = st.station.alliance.name == "RED"
            alliance = colour("fb-alliance-red", "red") if red else colour("fb-alliance-blue", "blue")
            return Text(f" {value} ", style=f"bold reverse {alliance}")
        if column == "team":
            return Text("—" if value is None else str(value), style="bold" if value is not None else "dim")
        if column == "ds" and value is not None:
            link, kind = value
            if kind is None:
                return Text("●" if link else "○", style=f"bold {ok if link else bad}", justify="center")
            dot = Text("●" if link else "○", style=f"bold {ok if link else bad}")
            dot.append(" " + (kind.removesuffix(" DS") if self._narrow else kind))  # "● 2027 DS"; narrow "● 2027"
            return dot
        if column in ("ds", "robot", "radio", "rio"):
            if value is None:
                return Text("—", style="dim", justify="center")
            return Text("●" if value else "○", style=f"bold {ok if value else bad}", justify="center")
        if column == "battery":
            unit = "" if self._narrow else " V"
            return Text("—" if value is None else f"{value:.1f}{unit}", justify="right",
                        style="dim" if value is None else "")
        if column in ("trip", "lost"):
            if value is None:
                return Text("—", justify="right", style="dim")
            return Text(f"{value} ms" if column == "trip" else str(value), justify="right")
        if column == "field":
            if value == "enabled":
                return Text("ENABLED", style=f"bold {colour('fb-enabled', 'green')}")
            if value == "held":
                return Text("HELD", style=f"bold {colour('warning', 'yellow')}")
            if value == "enabling":
                return Text("enabling…", style=colour("fb-enabled", "green"))
            return Text("disabled", style="dim")
        if column == "bypass":
            return Text("BYP" if self._narrow else "BYPASS", style=f"bold {colour('warning', 'yellow')}") if value \
                else Text("·", style="dim")
        if column == "estop":
            return Text("E-STOP", style=f"bold reverse {colour('fb-estop', 'red')}") if value \
                else Text("·", style="dim")
        if column == "astop":
            return Text("A-STOP", style=f"bold reverse {colour('warning', 'yellow')}") if value \
                else Text("·", style="dim")
        readiness, reason = value
        style = {"bad": f"bold {bad}", "warning": colour("warning", "yellow"), "ok": ok}.get(
            STATUS_STYLE.get(readiness, ""), "")
        return Text(reason, style=style)

    def _show_refused(self, text: str) -> None:
        box = self.query_one("#fms-refused", Static)
        box.update(text)
        box.display = bool(text)

    def _start_box(self, fms, now: float) -> None:
        m = fms.match
        runs = self.refusal("start") is None  # a classroom's students watch the teacher run it
        refused = self._refused_at is not None and now - self._refused_at < REFUSED_SHOWN
        if refused:
            text = "START REFUSED:\n" + "\n".join(f"  • {r}" for r in self._refused)
            kind = "-refused"
        elif m.running:
            text = f"{m.label} running: ctrl+a aborts it" if runs else f"{m.label} running"
            kind = "-ready"
        elif m.phase == Phase.POST_MATCH.value:
            text = (f"{m.label} {'aborted' if m.aborted else 'over'}: "
                    + ("n sets up the next match, r replays this one" if runs else "the teacher sets up the next one"))
            kind = "-blocked"
        else:
            reasons = fms.refusals
            # a DS's own e-stop does not stop the match (its latch is its own business), but the
            # box must not say "Ready" of a station whose robot cannot be enabled (the core's words)
            warnings = fms.warnings
            stopped = "\n".join(f"  • {w}" for w in warnings)
            if reasons:
                text = "Cannot start yet:\n" + "\n".join(f"  • {r}" for r in reasons)
                if warnings:
                    text += "\nand these robots will not be enabled:\n" + stopped
                kind = "-blocked"
            elif warnings:
                text = (("s starts the match" if runs else "The match can start") +
                        ", but these robots will not be enabled:\n" + stopped)
                kind = "-blocked"
            else:
                text = "Ready: s starts the match" if runs else "Ready: the teacher starts the match"
                kind = "-ready"
        self.set_shown("start", (text, kind), self._show_start)

    def _show_start(self, value: tuple[str, str]) -> None:
        text, kind = value
        box = self.query_one("#fms-start", Static)
        box.update(text)
        for k in ("-refused", "-ready", "-blocked"):
            box.set_class(k == kind, k)

    def _timing_inputs(self, fms) -> None:
        timing = fms.match.timing
        for key in ("auto", "pause", "teleop"):
            inp = self.query_one(f"#fms-{key}", Input)
            value = f"{getattr(timing, key):g}"
            if not inp.has_focus and inp.value != value:
                inp.value = value

    # -- keys ---------------------------------------------------------------------------------
    def action_pick(self, index: int) -> None:
        self.query_one("#fms-stations", DataTable).move_cursor(row=index)
        self._focus_table()

    def _station_command(self, verb: str) -> None:
        fms = self._need_fms()
        if fms is None:
            return
        station = self.selected
        st = fms.stations[int(station)]
        if verb == "bypass":
            self.send(Bypass(station, not st.bypass))
        elif verb == "estop":
            self.send(StationEStop(station, not st.estop))
        else:
            self.send(StationAStop(station))
        self._refresh_now()

    def action_bypass(self) -> None:
        self._station_command("bypass")

    def action_station_estop(self) -> None:
        self._station_command("estop")

    def action_astop(self) -> None:
        self._station_command("astop")

    def action_start(self) -> None:
        fms = self._need_fms()
        if fms is None:
            return
        self.send(MatchControl("start"), self._started)

    def _started(self, answer) -> None:
        """The wire's answer to "match start" (the app's thread)."""
        exc = answer.exception()
        if isinstance(exc, MatchStartRefused):
            self._refused, self._refused_at = list(exc.reasons), self.engine.now()
            self.notify("\n".join(exc.reasons), title="Cannot start the match", severity="warning")
        elif exc is not None:
            self.notify(str(exc), severity="warning")
        else:
            self._refused_at = None
        self._refresh_now()

    def action_abort(self) -> None:
        if self._need_fms() is not None:
            self.send(MatchControl("abort"))
            self._refresh_now()

    def action_next_match(self) -> None:
        if self._need_fms() is not None:
            self.send(MatchControl("next"))
            self._refresh_now()

    def action_replay(self) -> None:
        fms = self._need_fms()
        if fms is not None:
            self._call(ReplayMatch())

    def action_match_type(self) -> None:
        fms = self._need_fms()
        if fms is None:
            return
        m = fms.match
        try:
            index = LEVEL_CYCLE.index(TournamentLevel(m.level))
        except ValueError:
            index = -1
        level = LEVEL_CYCLE[(index + 1) % len(LEVEL_CYCLE)]
        self._call(SetUpMatch(level, m.number))

    def action_edit_durations(self) -> None:
        self.query_one("#fms-auto", Input).focus()

    def action_match_log(self) -> None:
        self.query_one("#fms-log", MatchLog).focus()

    def action_back_to_table(self) -> None:
        self._focus_table()

    def _call(self, command: Command) -> bool:
        """An FMS command; a refusal is a notification."""
        try:
            return self.send(command)
        finally:
            self._refresh_now()

    def _refresh_now(self) -> None:
        self.redraw_now()

    # -- period lengths ------------------------------------------------------------------------
    @on(Input.Submitted)
    @on(Input.Blurred)
    def _timing_entered(self, event: Input.Submitted | Input.Blurred) -> None:
        key = (event.input.id or "").removeprefix("fms-")
        fms = self.fms
        if key not in ("auto", "pause", "teleop") or fms is None:
            return
        note = self.query_one("#fms-timing-note", Static)
        current = getattr(fms.match.timing, key)
        try:
            value = float(event.value)
        except ValueError:
            value = None
        if value is None or value == current:
            event.input.value = f"{current:g}"
            return

        def answered(answer, field=event.input) -> None:
            exc = answer.exception()
            if exc is not None:
                field.value = f"{current:g}"
                note.update(f"{key}: {exc}")
                note.add_class("-error")
                self.notify(str(exc), title=f"{key} period not changed", severity="warning")
            else:
                note.update(f"{key} period is now {value:g} s")
                note.remove_class("-error")
            self._refresh_now()

        length: dict[str, Any] = {key: value}  # the one period this box names
        self.send(SetMatchTiming(**length), answered)
