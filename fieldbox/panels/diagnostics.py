"""The Diagnostics tab (F1 F1): what the NI Driver Station's Diagnostics tab tells, for the
selected DS.

* **Connections**: robot comms with the round trip of control packets to their status echo
  (the average of the last 256, the last one and the worst), the robot's TCP link, its code,
  the FMS with how long ago its last control packet came and, when the FMS runs in this
  process too, its round trip: control out to the DS plus the DS's status back, timed at
  both ends from the inspector's capture. (The FMS protocol has no echo: a DS alone cannot
  time it, and fieldbox does not ping hosts.)
* **Robot software**: the versions the robot sent in its TCP version frames (0x0a).
* **roboRIO**: CPU, RAM, disk and CAN figures from its status packets' tags, battery,
  brownouts and the disable and rail fault counters from its TCP frames.
* **This PC**: its CPU and battery (fieldbox/pcstatus.py), and the DS's missed send slots.

Keys (this tab): ``R`` restart robot code, ``B`` reboot the roboRIO (as on the Driver
Station tab).
"""

from __future__ import annotations

from typing import Any

from rich.text import Text
from textual import on
from textual.app import ComposeResult
from textual.binding import Binding
from textual.containers import Horizontal, Vertical
from textual.widgets import Button, Static

from roles.cores.commands import RebootRoboRIO, RestartCode

from ..exchange import delivery, last_time
from ..history import cpu_percent
from ..widgets import EventLog, key_hints, theme_colour
from .base import Panel

MB = 1_000_000


class DiagnosticsPanel(Panel):
    TITLE = "Diagnostics"
    SHORT_TITLE = "Diag"
    ID = "diagnostics"
    REFRESH_TICKS = 2
    READS_CAPTURE = True
    can_focus = True

    BINDINGS = [
        Binding("up", "scroll_up", "Scroll up", show=False),
        Binding("down", "scroll_down", "Scroll down", show=False),
        Binding("R", "restart_code", "Restart code"),
        Binding("B", "reboot", "Reboot RIO"),
    ]

    DEFAULT_CSS = """
    DiagnosticsPanel { layout: vertical; padding: 0 1; overflow-y: auto; }
    DiagnosticsPanel #diag-columns { height: auto; }
    DiagnosticsPanel #diag-columns > Vertical { width: 1fr; height: auto; }
    DiagnosticsPanel.-narrow #diag-columns { layout: vertical; }
    DiagnosticsPanel .diag-box { height: auto; padding: 0 1; border: round $panel-lighten-2;
                                 border-title-color: $text; }
    DiagnosticsPanel #diag-buttons { height: auto; margin-top: 1; }
    DiagnosticsPanel #diag-buttons Button { margin-right: 2; }
    DiagnosticsPanel #diag-keys { height: auto; margin-top: 1; color: $text-muted; }
    DiagnosticsPanel #diag-none { height: auto; margin: 1 2; }
    DiagnosticsPanel #diag-events { height: 1fr; min-height: 5; margin-top: 1; }
    DiagnosticsPanel.-short #diag-events { display: none; }
    """

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self._shapes: dict[str, tuple[int, int]] = {}

    def compose(self) -> ComposeResult:
        yield Static("", id="diag-none")
        with Horizontal(id="diag-columns"):
            with Vertical():  # one above the other where narrow: the robot first
                yield Static("", id="diag-links", classes="diag-box")
                yield Static("", id="diag-rio", classes="diag-box")
            with Vertical():
                yield Static("", id="diag-versions", classes="diag-box")
                yield Static("", id="diag-pc", classes="diag-box")
        with Horizontal(id="diag-buttons"):
            yield Button("Restart robot code  R", id="diag-restart-btn", compact=True)
            yield Button("Reboot roboRIO  B", id="diag-reboot-btn", compact=True)
        yield Static(key_hints([("This tab", [("R", "restart robot code"), ("B", "reboot the roboRIO")])],
                               title_width=9), id="diag-keys", classes="key-hints")
        yield EventLog(id="diag-events")

    def on_mount(self) -> None:
        for ident, title in (("diag-links", "Connections"), ("diag-pc", "This PC"), ("diag-rio", "roboRIO"),
                             ("diag-versions", "Robot software (its TCP version frames)")):
            self.query_one(f"#{ident}").border_title = title
        self.query_one("#diag-none").display = False
        self.query_one("#diag-events").border_title = "The Driver Station's events · seconds since the field started"

    def on_resize(self) -> None:
        self._shapes.clear()  # the boxes wrap anew
        self.set_class(self.size.width < 100, "-narrow")
        self.set_class(self.size.height < 30, "-short")

    # -- the 10 Hz refresh -------------------------------------------------------------------
    def refresh_view(self, engine, now: float) -> None:
        st = self.station()
        ds = st.ds if st is not None else None
        self.set_shown("none", ds is None, self._show_none)
        if ds is None:
            self.set_text("diag-none", "No Driver Station runs here: nothing to diagnose from its side. "
                                       "Press F8 to pick the roles.", layout=True)
            return
        stale = getattr(self.app, "wire_stale", False)
        self._box("diag-links", self._links(engine, st, ds, now, stale))
        self._box("diag-rio", self._rio(ds, stale))
        self._box("diag-versions", self._versions(ds))
        self._box("diag-pc", self._pc(ds))
        events = self.query_one("#diag-events", EventLog)
        if events.display:
            events.follow(ds.events.items, getattr(self.app, "started_at", 0.0), ds.team)

    def _box(self, ident: str, text: Text) -> None:
        """Update a box; lay the screen out only when its shape changed (its figures change
        ten times a second, and a layout pass each time left 300 objects a second to the
        garbage collector)."""
        lines = text.plain.split("\n")
        shape = (len(lines), max(len(line) for line in lines))
        relayout = self._shapes.get(ident) != shape
        self._shapes[ident] = shape
        self.set_text(ident, text, layout=relayout)

    def _show_none(self, none: bool) -> None:
        self.query_one("#diag-none").display = none
        self.query_one("#diag-columns").display = not none
        self.query_one("#diag-buttons").display = not none
        self.query_one("#diag-events").display = not none

    # -- the boxes -----------------------------------------------------------------------------
    def _lamp(self, text: Text, state: str, label: str) -> None:
        colour = {"on": theme_colour(self.app, "success", "green"), "off": theme_colour(self.app, "error", "red"),
                  "warn": theme_colour(self.app, "warning", "yellow")}.get(state, "grey50")
        text.append("██ ", colour)
        text.append(f"{label:<15}", "bold")

    def _links(self, engine, st, ds, now: float, stale: bool) -> Text:
        text = Text()
        if stale:
            text.append("The wire does not answer: these are its last figures.\n", "bold")
        self._lamp(text, "idle" if stale else "on" if ds.link.robot_comms else "off", "Robot comms")
        trip = ds.trip_ms
        samples = list(ds.link.echoes.trip.samples)
        if ds.link.robot_comms and trip is not None:
            text.append(f"round trip {trip:.2f} ms", "bold")
            last = ds.link.echoes.trip.last_ms
            if samples and last is not None:
                text.append(f"\n{'':18}last {last:.2f} · worst {max(samples):.2f} (of {len(samples)})", "dim")
        else:
            text.append("no status packets from the robot", "dim")
        text.append("\n")
        tcp = ds.tcp.state
        self._lamp(text, "idle" if stale else {"open": "on", "connecting": "warn"}.get(tcp, "off"), "Robot TCP")
        text.append(tcp if ds.legacy is None else "none in the 2010 protocol", "dim" if tcp != "open" else "")
        text.append("\n")
        self._lamp(text, "idle" if stale else "on" if ds.link.robot_code else "off", "Robot code")
        text.append((ds.link.program_mode or "—") if ds.link.robot_code else "no robot code", "")
        text.append("\n")
        status = ds.fms.status
        self._lamp(text, "idle" if stale or status == "off" else "on" if status == "good" else "warn", "FMS")
        text.append(status if status != "off" else "none (local control)")
        ring = self.capture_ring()
        if status != "off" and ring is not None:
            heard = last_time(ring, (st.ds_name, "fms", "in", "fms-to-ds"))
            if heard is not None:
                text.append(f"   last control {max(0.0, now - heard):.2f} s ago", "dim")
            rtt = self._fms_round_trip(engine, ring, st.ds_name)
            text.append("\n" + " " * 18)
            if rtt is not None:
                text.append(f"round trip {rtt * 1000:.2f} ms", "bold")
            else:
                text.append("round trip not timed: no echo in the FMS protocol", "dim")
        text.append("\n" + " " * 18)
        text.append(f"lost {ds.link.echoes.lost_packets:,} of {ds.link.echoes.sent_packets:,} control packets")
        return text

    @staticmethod
    def _fms_round_trip(engine, ring, ds_name: str) -> float | None:
        fms = getattr(engine.field, "fms_name", "fms") if engine.field.fms is not None else None
        if fms is None:
            return None
        out = delivery(ring, (fms, "udp", "out", "fms-to-ds"), (ds_name, "fms", "in", "fms-to-ds"))
        back = delivery(ring, (ds_name, "fms-out", "out", "ds-to-fms"), (fms, "udp", "in", "ds-to-fms"))
        return None if out is None or back is None else out + back

    def _rio(self, ds, stale: bool) -> Text:
        text = Text()
        rows: list[tuple[str, str]] = []
        tel = ds.telemetry
        cpu = cpu_percent(tel.cpu)
        rows.append(("CPU", "—" if cpu is None else f"{cpu:.0f} %"))
        rows.append(("RAM free", "—" if tel.ram is None else f"{tel.ram.free_bytes / MB:,.0f} MB"))
        rows.append(("disk free", "—" if tel.disk is None else f"{tel.disk.free_bytes / MB:,.0f} MB"))
        rows.append(("CAN bus", "—" if tel.can is None else f"{tel.can.utilization:.1f} % used"))
        battery = ds.link.battery
        rows.append(("battery", "—" if battery is None else f"{battery:.2f} V"))
        rows.append(("brownouts", f"{tel.brownouts:,}" + ("  BROWNOUT NOW" if tel.brownout else "")))
        f = dict(ds.tcp.faults)
        rows.append(("disables", f"comms {f['comms']:,} · 12 V {f['12v']:,}"))
        rows.append(("rail faults", f"6 V {f['6v']:,} · 5 V {f['5v']:,} · 3.3 V {f['3.3v']:,}"))
        for i, (label, value) in enumerate(rows):
            if i:
                text.append("\n")
            text.append(f"{label:<12}", "dim")
            text.append(value, "bold" if not stale else "dim")
        if not ds.link.robot_comms:
            text.append("\n(the last figures the robot sent)", "dim")
        return text

    @staticmethod
    def _versions(ds) -> Text:
        versions = dict(ds.tcp.versions)
        if not versions:
            return Text("none yet: the robot sends them over TCP once its link is up"
                        if ds.legacy is None else "the 2010 protocol sends none", "dim")
        width = min(28, max(len(name) for name in versions) + 2)
        text = Text()
        for i, (name, version) in enumerate(sorted(versions.items())):
            if i:
                text.append("\n")
            text.append(f"{name:<{width}}", "dim")
            text.append(version or "—", "bold")
        return text

    def _pc(self, ds) -> Text:
        reading = self.app.pc_status()  # type: ignore[attr-defined]
        text = Text()
        text.append(f"{'CPU':<12}", "dim")
        text.append("not known here" if reading.cpu is None else f"{reading.cpu:.0f} %", "bold")
        text.append(f"\n{'battery':<12}", "dim")
        if reading.battery is None:
            text.append("none (mains power)", "bold")
        else:
            text.append(f"{reading.battery:.0f} %{' charging' if reading.charging else ''}", "bold")
        text.append(f"\n{'send slots':<12}", "dim")
        text.append(f"{ds.link.missed_slots:,} missed", "bold")
        text.append("  (of its 20 ms beat)", "dim")
        return text

    # -- keys ------------------------------------------------------------------------------------
    def action_restart_code(self) -> None:
        if self.send(RestartCode()):
            self.notify("Restart robot code requested")

    def action_reboot(self) -> None:
        if self.send(RebootRoboRIO()):
            self.notify("Reboot roboRIO requested")

    @on(Button.Pressed)
    def _button(self, event: Button.Pressed) -> None:
        event.stop()
        if event.button.id == "diag-restart-btn":
            self.action_restart_code()
        elif event.button.id == "diag-reboot-btn":
            self.action_reboot()
