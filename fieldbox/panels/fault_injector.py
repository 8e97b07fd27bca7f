"""The fault injector: faults on purpose, from the app (roles/sim/faults.py).

A spec typed in the input (``ds-rio:loss=10%,delay=30ms~10ms``, ``ds-rio:cut``...) goes as
the same ``Fault`` command as ``fault SPEC`` on stdin (roles/cores/commands.py, ``app.send``),
so the app, stdin and ``--fault`` share one path and one set of error messages. Buttons pull and put
back the cables (robot: UDP and TCP; FMS: UDP and TCP) and clear everything. A table shows
each link's faults and what they did (dropped, delayed, duplicated, reordered, corrupted,
retransmitted, held, refused connects).

Mount it in any panel (the Faults panel is its home) and call :meth:`refresh_view` from the
panel's own ``refresh_view``; mounted elsewhere it refreshes itself at 4 Hz. It only reads
the faults' plain counters and changes them only with commands.
"""

from __future__ import annotations

from typing import Any

from textual.app import ComposeResult
from textual.containers import Horizontal
from textual.reactive import reactive
from textual.widget import Widget
from textual.widgets import Button, DataTable, Input, Static

from roles.cores.commands import Fault

from ..widgets import TextBox

LINKS = ("ds-rio", "ds-rio-tcp", "ds-fms", "ds-fms-tcp")
#: (column key, heading) of the counters (roles.sim.faults.FaultCounters fields).
COUNTERS = (("dropped", "Dropped"), ("delayed", "Delayed"), ("duplicated", "Dup"), ("reordered", "Reord"),
            ("corrupted", "Corrupt"), ("retransmitted", "Retrans"), ("held", "Held"),
            ("refused_connects", "Refused"))
BUTTONS = (
    ("fault-cut-robot", "Pull robot cable", "ds-rio+ds-rio-tcp:cut", "error"),
    ("fault-uncut-robot", "Plug robot back", "ds-rio+ds-rio-tcp:uncut", "success"),
    ("fault-cut-fms", "Pull FMS cable", "ds-fms+ds-fms-tcp:cut", "error"),
    ("fault-uncut-fms", "Plug FMS back", "ds-fms+ds-fms-tcp:uncut", "success"),
    ("fault-clear", "Clear all", "clear", "default"),
)
#: The buttons' labels where the injector is compact (all five on an 80-column line).
COMPACT_LABELS = {"fault-cut-robot": "Pull robot", "fault-uncut-robot": "Plug robot", "fault-cut-fms": "Pull FMS",
                  "fault-uncut-fms": "Plug FMS", "fault-clear": "Clear all"}
AUTO_REFRESH = 0.25


class FaultInjector(Widget):
    """An input for a fault spec, cut/uncut/clear buttons, and each link's faults and counts."""

    DEFAULT_CSS = """
    FaultInjector { height: auto; padding: 0 1; }
    FaultInjector #fault-title { text-style: bold; }
    FaultInjector #fault-spec { width: 1fr; }
    FaultInjector Horizontal { height: auto; }
    FaultInjector Button { min-width: 10; margin-right: 1; }
    FaultInjector DataTable { height: auto; max-height: 8; }
    FaultInjector #fault-status { color: $text-muted; }
    FaultInjector.-compact #fault-title { display: none; }
    FaultInjector.-compact #fault-row { margin-top: 0; }
    FaultInjector.-compact Button { padding: 0 1; }
    """

    #: One line each for the input and the buttons (a short terminal: the counters keep their rows).
    compact = reactive(False)

    def __init__(self, *, refresh_itself: bool = True, **kw: Any) -> None:
        super().__init__(**kw)
        self.refresh_itself = refresh_itself
        self._shown: dict[str, tuple] = {}
        self._driven = False  # a panel calls refresh_view: no timer of our own
        self._said = False  # the status line says what a command did

    def compose(self) -> ComposeResult:
        yield Static("Faults on purpose  (f types one, Esc goes back to the table)", id="fault-title")
        yield TextBox(placeholder="LINK:SETTINGS  e.g. ds-rio:loss=10%,delay=30ms~10ms  or  ds-rio:cut",
                    id="fault-spec")
        with Horizontal(id="fault-row"):
            for ident, label, _, variant in BUTTONS:
                yield Button(label, id=ident, variant=variant)  # type: ignore[arg-type]
        yield DataTable(id="fault-table", cursor_type="none", zebra_stripes=True)
        yield Static("", id="fault-status")

    def watch_compact(self, compact: bool) -> None:
        self.set_class(compact, "-compact")
        for widget in self.query(Input).results(Input):
            widget.compact = compact
        for button in self.query(Button).results(Button):
            button.compact = compact
            full = next(label for ident, label, _, _ in BUTTONS if ident == button.id)
            button.label = COMPACT_LABELS.get(button.id or "", full) if compact else full
        self._show_table()

    def _show_table(self) -> None:
        """Compact, the table shows only while some link has a fault or a count: a line says
        all is clear otherwise (the rows go to the Faults table above)."""
        busy = any(row[0] != "none" or any(row[1:]) for row in self._shown.values())
        self.query_one("#fault-table").display = busy or not self.compact
        if self.compact and not busy and not self._said:
            self.query_one("#fault-status", Static).update("No faults on purpose: every link is clear.")

    def on_mount(self) -> None:
        table = self.query_one("#fault-table", DataTable)
        table.add_column("Link", key="link")
        table.add_column("Faults", key="fault")
        for key, heading in COUNTERS:
            table.add_column(heading, key=key)
        for link in LINKS:
            table.add_row(link, "none", *("0" for _ in COUNTERS), key=link)
        if self.refresh_itself:
            self.set_interval(AUTO_REFRESH, self._tick)

    # -- what the user does ------------------------------------------------------------------------
    def on_input_submitted(self, event: Input.Submitted) -> None:
        event.stop()
        spec = event.value.strip()
        if not spec:
            return
        if self._run(spec):
            event.input.value = ""

    def on_button_pressed(self, event: Button.Pressed) -> None:
        for ident, _, spec, _ in BUTTONS:
            if event.button.id == ident:
                event.stop()
                self._run(spec)
                return

    def _run(self, spec: str) -> bool:
        """Send ``Fault(spec)``; its answer (or the field's refusal in words) shows below."""
        send = getattr(self.app, "send", None)
        if send is None:
            return False
        command = f"fault {spec}"
        status = self.query_one("#fault-status", Static)

        self._said = True

        def answered(answer) -> None:
            exc = answer.exception()
            status.update(f"{command}: {'done' if exc is None else 'refused'}")
            if exc is not None:  # the reason, as any refusal
                self.app.notify(str(exc), severity="warning")
            self._shown.clear()
            self._tick()

        status.update(f"{command}: sent")  # until the wire answers (at once on a fake clock)
        sent = bool(send(Fault(spec), answered))
        if not sent:
            status.update(f"{command}: refused")
        return sent

    # -- what it shows -------------------------------------------------------------------------------
    def _tick(self) -> None:
        if self._driven:
            return
        engine = getattr(self.app, "engine", None)
        if engine is not None:
            self._update(engine)

    def refresh_view(self, engine: Any, now: float | None = None) -> None:
        """Copy the faults' state into the table (cheap when nothing changed)."""
        self._driven = True
        self._update(engine)

    def _update(self, engine: Any) -> None:
        faults = getattr(getattr(engine, "field", None), "faults", None)
        if faults is None:
            return
        table = self.query_one("#fault-table", DataTable)
        changed = False
        for link in LINKS:
            fault = faults.links.get(link)
            counters = faults.counters.get(link)
            if fault is None or counters is None:
                continue
            row = (fault.describe(),) + tuple(getattr(counters, key) for key, _ in COUNTERS)
            if self._shown.get(link) == row:
                continue
            old = self._shown.get(link)
            self._shown[link] = row
            for i, (key, value) in enumerate(zip(("fault",) + tuple(k for k, _ in COUNTERS), row)):
                if old is None or old[i] != value:
                    # a column grows to its widest value: "loss=50%" was cut to "loss=5"
                    table.update_cell(link, key, str(value), update_width=True)
            changed = True
        if changed and self.compact:
            self._show_table()
