"""The Faults panel: fault counters per link, as each role counts them.

One table row per link of every role running here: the Driver Station's robot UDP (both
directions), robot TCP and FMS links; the fake roboRIO's; the FMS's UDP and TCP and its
per-station links. The robot's own fault counters sit on the row of the link that carries
them: comms and 12 V disables and rail faults arrive on robot TCP (frames 0x04 and 0x05),
brownouts are a bit of each status packet. Each link also counts the packets it did not
obey: *stale* ones (well formed, but delayed, duplicated or reordered: older than one already
taken) and *foreign* ones (from an address the link does not follow, dropped before they are
decoded: a second DS at a robot, FMS control from elsewhere at a DS, a station's status from
an address that is not its DS's at the FMS, whose TCP row counts the logins it refused).
*Bad* ones did not decode (from the peer followed, or where no peer is followed yet; a 64 KB
datagram is over every kind's size bound). Counters that belong to no link are on
the line under the table.

The table is built once per engine (the rows a field has do not change while it runs) and
updated in place, cell by cell, only where a value changed. A count that went up in the
last :data:`RECENT` seconds is highlighted, so a fault that just happened catches the eye.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from typing import Any, Callable

from rich.text import Text
from textual.app import ComposeResult
from textual.binding import Binding
from textual.containers import VerticalScroll
from textual.widgets import DataTable, Input, Static
from textual.widgets.data_table import ColumnKey

from ..console_feed import station_role
from ..widgets import theme_colour
from .base import Panel
from .fault_injector import FaultInjector

#: Seconds a count stays highlighted after it went up.
RECENT = 5.0

#: (column key, heading). Counts are right-aligned; "last error" is free text.
COLUMNS = (
    ("link", "Link"),
    ("in", "In"),
    ("out", "Out"),
    ("bad", "Bad"),
    ("lost", "Lost"),
    ("stale", "Stale"),
    ("foreign", "Foreign"),
    ("trip", "Trip ms"),
    ("comms", "Comms"),
    ("12v", "12 V"),
    ("6v", "6 V"),
    ("5v", "5 V"),
    ("3.3v", "3.3 V"),
    ("brownouts", "Brownouts"),
    ("error", "Last error"),
)
#: Counts that are faults: non-zero is shown in the warning colour, and highlighted for
#: RECENT seconds after it went up (packets in and out go up all the time: never highlighted).
FAULTS = ("bad", "lost", "stale", "foreign", "comms", "12v", "6v", "5v", "3.3v", "brownouts")
MAX_ERROR = 60
#: Columns that move with every packet: redrawn twice a second, not ten times. (Any change
#: makes a DataTable draw all its rows again; faults, which are rare, still show at once.)
TRAFFIC = ("in", "out", "trip")
TRAFFIC_PERIOD = 0.5

#: What a classroom's driver or observer reads instead of the fault injector (fieldbox/seats.py
#: hides it, and its key): faults on purpose are the teacher's, these counters everyone's.
STUDENT_NOTE = "Faults on purpose are the teacher's: these counters show what each one does"

Values = dict[str, Any]


@dataclass
class LinkRow:
    """One row: its key, its label and how to read its values from the cores."""

    key: str
    label: str
    read: Callable[[], Values]


def _stats(s) -> Values:
    if s is None:  # a core without this link (the 2010 protocol has no robot TCP)
        return {}
    return {"in": s.packets_in, "out": s.packets_out, "bad": s.bad_packets, "lost": s.lost_packets,
            "stale": s.stale_packets, "foreign": s.foreign_packets, "error": s.last_error}


# Each read takes the core's view at call time (``core()``): a wire in another process sends a
# new view of each core every few beats, so a view kept from when the rows were built would
# stop moving.
def _ds_rows(team: int, core: Callable[[], Any]) -> list[LinkRow]:
    def control() -> Values:
        ds = core()
        v = _stats(ds.link_stats("ds->rio"))
        v["lost"] = ds.link.echoes.lost_packets
        trip = ds.trip_ms
        v["trip"] = None if trip is None else round(trip, 1)
        return v

    def status() -> Values:
        ds = core()
        return {**_stats(ds.link_stats("rio->ds")), "brownouts": ds.telemetry.brownouts}

    def tcp() -> Values:
        ds = core()
        f = dict(ds.tcp.faults)
        return {**_stats(ds.link_stats("robot-tcp")), "comms": f["comms"], "12v": f["12v"], "6v": f["6v"],
                "5v": f["5v"], "3.3v": f["3.3v"]}

    p = f"DS {team}"
    return [
        LinkRow(f"ds{team}-control", f"{p}  control → robot", control),
        LinkRow(f"ds{team}-status", f"{p}  status ← robot", status),
        LinkRow(f"ds{team}-tcp", f"{p}  robot TCP", tcp),
        LinkRow(f"ds{team}-fms-udp", f"{p}  FMS UDP", lambda: _stats(core().link_stats("fms-udp"))),
        LinkRow(f"ds{team}-fms-tcp", f"{p}  FMS TCP", lambda: _stats(core().link_stats("fms-tcp"))),
    ]


def _rio_rows(team: int, core: Callable[[], Any]) -> list[LinkRow]:
    def control() -> Values:
        rio = core()
        return {**_stats(rio.stats.get("ds->rio")), "comms": rio.faults.comms}

    def status() -> Values:
        rio = core()
        return {**_stats(rio.stats.get("rio->ds")), "12v": rio.faults.rail_12v, "brownouts": rio.battery.brownouts}

    def tcp() -> Values:
        rio = core()
        f = rio.faults
        return {**_stats(rio.stats.get("rio-tcp")), "6v": f.rail_6v, "5v": f.rail_5v, "3.3v": f.rail_3v3}

    p = f"roboRIO {team}"
    return [
        LinkRow(f"rio{team}-control", f"{p}  control ← DS", control),
        LinkRow(f"rio{team}-status", f"{p}  status → DS", status),
        LinkRow(f"rio{team}-tcp", f"{p}  TCP 1740", tcp),
    ]


def _fms_rows(engine) -> list[LinkRow]:
    rows = [
        LinkRow("fms-udp", "FMS  UDP 1160", lambda: _stats(engine.field.fms.udp_stats)),
        LinkRow("fms-tcp", "FMS  TCP 1750", lambda: _stats(engine.field.fms.tcp_stats)),
    ]
    for i, station in enumerate(engine.field.fms.stations):
        def read(i=i) -> Values:
            s = engine.field.fms.stations[i]
            return {**_stats(s.link), "trip": s.report.trip_time_ms}
        rows.append(LinkRow(f"fms-{station.label}", "", read))
    return rows


def _fms_label(station) -> str:
    return f"FMS  {station.label} ({station.team if station.team is not None else 'empty'})"


def build_rows(engine) -> list[LinkRow]:
    rows: list[LinkRow] = []
    field = engine.field
    for i, st in enumerate(field.stations):  # read through the engine: new views each refresh
        if st.ds is not None:
            rows += _ds_rows(st.team, functools.partial(station_role, engine, i, "ds"))
        if st.rio is not None:
            rows += _rio_rows(st.team, functools.partial(station_role, engine, i, "rio"))
    if field.fms is not None:
        rows += _fms_rows(engine)
    return rows


def other_counters(engine) -> str:
    """The counters that belong to no link, one line per role; the lines where something
    counted come first (a short screen shows three)."""
    lines: list[tuple[str, tuple[int, ...]]] = []

    def line(head: str, counters: tuple[tuple[str, int], ...]) -> None:
        lines.append((f"{head}: " + " · ".join(f"{name} {value}" for name, value in counters),
                      tuple(value for _, value in counters)))

    field = engine.field
    for st in field.stations:
        if st.ds is not None:
            d = st.ds
            if d.fms.refused:  # what the FMS control count below is doing now, and why
                lines.append((f"DS {st.team}: {d.fms.refused}", (1,)))
            line(f"DS {st.team}", (("missed send slots", d.link.missed_slots),
                                   ("late or duplicate echoes", d.link.echoes.stale_echoes),
                                   ("status from another address", d.link.foreign_packets),
                                   ("FMS control from another address", d.fms.foreign_packets),
                                   ("unknown TCP frames", d.tcp.unknown_frames)))
        if st.rio is not None:
            f = st.rio.faults
            line(f"roboRIO {st.team}", (("program errors", f.program_errors),
                                        ("packets from a second DS", f.foreign_packets),
                                        ("stale control packets", f.stale_packets),
                                        ("missed 20 ms beats", f.missed_beats),
                                        ("console lines dropped", f.console_dropped),
                                        ("refused TCP clients", f.refused_clients),
                                        ("evicted TCP clients", f.evicted_clients),
                                        ("program overruns", f.program_overruns),
                                        ("sequence jumps", f.sequence_jumps), ("outputs refused", f.output_problems),
                                        ("malformed tags dropped (header applied)", f.malformed_tags)))
    if field.fms is not None:
        fms = field.fms
        line("FMS", (("refused connections", fms.refused_connections), ("evicted connections", fms.evicted_connections),
                     ("status from teams not in the match", fms.udp_unknown_team),
                     ("status from another address", fms.refused_status), ("logins refused", fms.refused_logins),
                     ("challenge failures", fms.challenge_failures), ("missed control slots", fms.missed_sends)))
    failed = getattr(engine, "log_errors", 0)
    if failed:
        lines.insert(0, (f"Log files: {failed} writes failed (a full disk or a folder gone): the logs are incomplete",
                         (failed,)))
    lines.sort(key=lambda item: not any(item[1]))  # stable: the field's order otherwise
    return "\n".join(text for text, _ in lines)


class FaultsPanel(Panel):
    """Fault counters per link, highlighting what went up recently."""

    TITLE = "Faults"
    SHORT_TITLE = "Faults"
    ID = "faults"
    REFRESH_TICKS = 2
    #: Counts are watched while the tab is hidden too (cheap: no drawing), so a fault that
    #: happened just before you look is still highlighted when you do.
    ALWAYS_REFRESH = True
    # The injector's input is a key away, said in the footer: reached only by Tabs, the keys
    # typed before it had the focus went to the app's shortcuts ("e" arms an enable).
    BINDINGS = [
        Binding("f", "focus_injector", "Type a fault"),
        Binding("escape", "leave_injector", "Back to the table", show=False),
    ]

    # Under 30 rows (an 80x24 terminal) the help goes, the other counters keep three lines
    # (Tab scrolls them) and the fault injector is compact: the table keeps its rows.
    DEFAULT_CSS = """
    FaultsPanel { layout: vertical; }
    FaultsPanel #faults-help { height: auto; padding: 0 1; color: $text-muted; }
    FaultsPanel #faults-table { height: 1fr; min-height: 6; }
    FaultsPanel #faults-other-box { height: auto; max-height: 8; background: $boost; }
    FaultsPanel #faults-other-box:focus { background-tint: $accent 10%; }
    FaultsPanel #faults-other { height: auto; padding: 0 1; }
    FaultsPanel #faults-student { height: auto; padding: 0 1; color: $text-muted; }
    FaultsPanel.-short #faults-help { display: none; }
    FaultsPanel.-short #faults-other-box { max-height: 3; }
    """

    def __init__(self, *, id: str | None = None) -> None:
        super().__init__(id=id)
        self._engine = None
        self._rows: list[LinkRow] = []
        self._last: dict[tuple[str, str], Any] = {}       # the last value seen per cell
        self._went_up: dict[tuple[str, str], float] = {}  # when it last went up
        self._drawn: dict[tuple[str, str], Any] = {}      # what the cell shows now
        self._other = ""
        self._traffic_at = float("-inf")
        self._theme: str | None = None
        self.builds = 0          # how often the table was built (the tests read it)
        self.cell_updates = 0    # how many cells were redrawn

    def compose(self) -> ComposeResult:
        yield Static("Counters that went up in the last 5 s are highlighted. Comms and 12 V disables and "
                     "rail faults come from the robot in TCP frames 0x04/0x05; brownouts are the status "
                     "packet's brownout bit; trip time is control packet → status echo. Stale: delayed, "
                     "duplicated or reordered packets, not obeyed; foreign: from an address the link does not "
                     "follow, dropped.", id="faults-help")
        table: DataTable = DataTable(id="faults-table", cursor_type="row", zebra_stripes=True)
        yield table
        with VerticalScroll(id="faults-other-box", can_focus=True):
            yield Static("", id="faults-other")
        yield FaultInjector(refresh_itself=False, id="fault-injector")
        yield Static(STUDENT_NOTE, id="faults-student", classes="student-only")

    def on_mount(self) -> None:
        table = self.query_one(DataTable)
        for key, heading in COLUMNS:
            table.add_column(heading, key=key)

    def take_focus(self) -> None:
        self.query_one(DataTable).focus()

    def action_focus_injector(self) -> None:
        self.query_one("#fault-spec", Input).focus()

    def action_leave_injector(self) -> None:
        self.take_focus()

    def on_resize(self) -> None:
        short = self.size.height < 30
        self.set_class(short, "-short")
        self.query_one(FaultInjector).compact = short

    # -- building (once per engine) ---------------------------------------------------------
    def _build(self, engine) -> None:
        table = self.query_one(DataTable)
        table.clear()
        self._engine = engine
        self._rows = build_rows(engine)
        self._last.clear()
        self._went_up.clear()
        self._drawn.clear()
        self._traffic_at = float("-inf")
        self.builds += 1
        for row in self._rows:
            table.add_row(*([""] * len(COLUMNS)), key=row.key)

    # -- the 10 Hz refresh ------------------------------------------------------------------
    def refresh_view(self, engine, now: float) -> None:
        if engine is not self._engine:
            self._build(engine)
        self.query_one(FaultInjector).refresh_view(engine, now)
        table = self.query_one(DataTable)
        shown = self.parent is None or self.parent.display  # our tab is the one showing
        if not shown:
            for row in self._rows:
                values = row.read()
                for key in FAULTS:
                    self._watch((row.key, key), values.get(key), now)
            return
        if self.app.theme != self._theme:  # colours come from the theme: redraw every cell
            self._theme = self.app.theme
            self._drawn.clear()
        fms = engine.field.fms
        labels = {f"fms-{s.label}": _fms_label(s) for s in fms.stations} if fms is not None else {}
        traffic = now - self._traffic_at >= TRAFFIC_PERIOD or now < self._traffic_at
        if traffic:
            self._traffic_at = now
        for row in self._rows:
            values = row.read()
            values["link"] = labels.get(row.key, row.label)
            for key, _ in COLUMNS:
                if traffic or key not in TRAFFIC or (row.key, key) not in self._drawn:
                    self._cell(table, row.key, key, values.get(key), now)
        other = other_counters(engine)
        if other != self._other:
            self._other = other
            self.query_one("#faults-other", Static).update(other)

    def _watch(self, cell: tuple[str, str], value: Any, now: float) -> None:
        if value is not None:
            old = self._last.get(cell)
            if old is not None and value > old:
                self._went_up[cell] = now
            self._last[cell] = value

    def _cell(self, table: DataTable, row: str, column: str, value: Any, now: float) -> None:
        cell = (row, column)
        if column in FAULTS:
            self._watch(cell, value, now)
        recent = cell in self._went_up and now - self._went_up[cell] < RECENT
        drawn = (value, recent)
        if self._drawn.get(cell) == drawn:
            return
        self._drawn[cell] = drawn
        self.cell_updates += 1
        text = self._cell_text(column, value, recent)
        # Columns only grow (a count never gets shorter for long): measuring is for growth.
        wider = text.cell_len > table.columns[ColumnKey(column)].content_width
        table.update_cell(row, column, text, update_width=wider)

    def _cell_text(self, column: str, value: Any, recent: bool) -> Text:
        if column == "link":
            return Text(str(value), style="bold")
        if column == "error":
            text = str(value or "")
            return Text(text if len(text) <= MAX_ERROR else text[:MAX_ERROR - 1] + "…",
                        style=self._colour("error") if text else "")
        if value is None:
            return Text("–", justify="right", style="dim")
        shown = f"{value:g}" if isinstance(value, float) else f"{value:,}"
        style = ""
        if column in FAULTS and value:
            style = self._colour("warning")
        if recent:
            style = f"bold reverse {self._colour('warning')}"
        return Text(shown, justify="right", style=style)

    def _colour(self, name: str) -> str:
        return theme_colour(self.app, name, {"warning": "yellow", "error": "red"}[name])

    # -- what the tests read ------------------------------------------------------------------
    def value(self, row: str, column: str) -> Any:
        return self._drawn.get((row, column), (None, False))[0]

    def highlighted(self, row: str, column: str) -> bool:
        return self._drawn.get((row, column), (None, False))[1]
