"""The Legacy 2010 panel: the cRIO-era protocol's own fields, live.

What the DS sends the robot (UDP 1110: the control bits, packet index, team, station, the
eight DS digital inputs and four analog inputs), what the robot answers (UDP 1150: the
battery as its two BCD bytes and in volts, the DS digital outputs, the 6 x 21 LCD, the error
string), the dashboard packets the DS sends (UDP 1165) and the robot's NetConsole text
(UDP 6666).

Keys (this tab): ``1``-``8`` toggle DS digital inputs 1-8; Tab moves to the four analog
sliders, where Left/Right move 8 steps, Shift+Left/Right or PgUp/PgDn 128, Home/End to
0/1023. Clicking an input toggle or a slider works too. Changes go to the DS core through
``engine.call`` (the wire's side); the panel only reads.
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any

from rich.text import Text
from textual import on
from textual.app import ComposeResult
from textual.binding import Binding
from textual.containers import Horizontal, Vertical
from textual.message import Message
from textual.widget import Widget
from textual.widgets import Log, Static

from roles.cores.commands import Command, SetAnalogInput, ToggleDigitalInput

from ..widgets import StatusLight, StreamCursor, key_hints, level_bar
from .base import Panel

LCD_WIDTH = 21
LCD_LINES = 6
ANALOG_MAX = 1023
NETCONSOLE_LINES = 500

#: The 2010 control byte, high bit first: (mask, label, what a set bit means).
CONTROL_BITS = ((0x80, "reset", "reboot the cRIO"), (0x40, "not-e-stop", "set in normal operation"),
                (0x20, "enabled", ""), (0x10, "auto", "autonomous"), (0x08, "FMS", "FMS attached"),
                (0x04, "resync", ""), (0x02, "cRIO ck", "cRIO checksum"), (0x01, "FPGA ck", "FPGA checksum"))


_COLUMNS = [max(len(CONTROL_BITS[c][1]), len(CONTROL_BITS[c + 4][1])) for c in range(4)]


def control_text(byte: int | None, title: str = "control", per_line: int = 4) -> Text:
    """The control byte as hex and as eight named lamps (``●`` set, ``○`` clear), high bit
    first, on two lines of four (``per_line=2``: four lines of two, for a narrow column)."""
    text = Text()
    text.append(f"{title:<8}", "dim")
    if byte is None:
        return text.append("—\n", "dim")
    text.append(f"0x{byte:02x}", "bold")
    columns = _COLUMNS if per_line == 4 else [max(_COLUMNS[0], _COLUMNS[2]), max(_COLUMNS[1], _COLUMNS[3])]
    for i, (mask, label, _) in enumerate(CONTROL_BITS):
        if i and i % per_line == 0:
            text.append("\n" + " " * 12)
        on = bool(byte & mask)
        warn = mask == 0x40 and not on  # a clear not-e-stop bit IS the e-stop
        text.append("  ●" if on else "  ○", "bold red" if warn else "bold green" if on else "dim")
        text.append(label.ljust(columns[i % per_line]), "bold red" if warn else "" if on else "dim")
    return text


def lcd_text(lines: tuple[str, ...]) -> Text:
    """The DS LCD: six lines of 21 characters in a box, as the 2010 DS drew it."""
    text = Text("┌" + "─" * LCD_WIDTH + "┐\n", "dim")
    for i in range(LCD_LINES):
        line = lines[i] if i < len(lines) else ""
        text.append("│", "dim")
        text.append(line[:LCD_WIDTH].ljust(LCD_WIDTH), "bold")
        text.append("│\n", "dim")
    text.append("└" + "─" * LCD_WIDTH + "┘", "dim")
    return text


class DigitalToggle(StatusLight):
    """One DS digital input: a lamp that toggles when clicked (or with its number key)."""

    class Toggled(Message):
        def __init__(self, number: int) -> None:
            super().__init__()
            self.number = number

    def __init__(self, number: int, **kwargs: Any) -> None:
        super().__init__(f"{number}", "idle", **kwargs)
        self.number = number

    def on_click(self) -> None:
        self.post_message(self.Toggled(self.number))


class AnalogSlider(Widget, can_focus=True):
    """One DS analog input, 0..1023: a bar and the value; keys move it when focused."""

    DEFAULT_CSS = """
    AnalogSlider { height: 1; width: 1fr; }
    AnalogSlider:focus { background: $accent 30%; }
    """
    BINDINGS = [
        Binding("left", "step(-8)", "-8", show=False), Binding("right", "step(8)", "+8", show=False),
        Binding("shift+left", "step(-128)", show=False), Binding("shift+right", "step(128)", show=False),
        Binding("pagedown", "step(-128)", show=False), Binding("pageup", "step(128)", show=False),
        Binding("home", "to(0)", show=False), Binding("end", "to(1023)", show=False),
    ]

    class Changed(Message):
        def __init__(self, number: int, value: int) -> None:
            super().__init__()
            self.number = number
            self.value = value

    def __init__(self, number: int, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        self.number = number
        self.value = 0

    def show(self, value: int) -> None:
        """The DS's value (from the refresh); ignored while this slider has focus: the
        user's own moves win until they land on the wire."""
        if value != self.value and not self.has_focus:
            self.value = value
            self.refresh()

    def _move(self, value: int) -> None:
        value = max(0, min(ANALOG_MAX, value))
        if value != self.value:
            self.value = value
            self.refresh()
            self.post_message(self.Changed(self.number, value))

    def action_step(self, delta: int) -> None:
        self._move(self.value + delta)

    def action_to(self, value: int) -> None:
        self._move(value)

    def on_click(self, event) -> None:
        bar = self._bar_width()
        x = event.x - 5
        if 0 <= x < bar:
            self._move(round(x / max(1, bar - 1) * ANALOG_MAX))

    def _bar_width(self) -> int:
        return max(4, self.size.width - 11)

    def render(self) -> Text:
        text = Text(f"A{self.number}  ", "bold")
        text.append_text(level_bar(self.value / ANALOG_MAX, self._bar_width(), style="bold"))
        text.append(f" {self.value:4d}")
        return text


#: What an input key says where the field is not a 2010 one.
NO_LEGACY_DS = "no 2010 Driver Station runs here: press F8 and tick 2010 legacy"


class LegacyPanel(Panel):
    TITLE = "Legacy 2010"
    SHORT_TITLE = "2010"
    ID = "legacy"
    can_focus = True

    BINDINGS = [Binding(str(n), f"toggle_input({n})", "DIn 1-8" if n == 1 else f"DIn {n}", show=n == 1)
                for n in range(1, 9)]

    DEFAULT_CSS = """
    LegacyPanel { layout: vertical; padding: 0 1; overflow-y: auto; }
    #legacy-none { height: auto; margin: 1 2; }
    #legacy-columns { height: auto; }
    #legacy-columns > Vertical { width: 1fr; height: auto; padding: 0 1; border: round $panel-lighten-2;
                                 border-title-color: $text; }
    #legacy-columns > Vertical:focus-within { border: round $accent; }
    .legacy-row { height: 1; margin-top: 1; }
    .legacy-label { width: 12; color: $text-muted; }
    .legacy-row StatusLight { width: 1fr; min-width: 4; }
    #legacy-control, #legacy-status { height: auto; }
    #legacy-analog { height: auto; margin-top: 1; }
    #legacy-lcd { height: 8; width: auto; margin-top: 1; }
    #legacy-dashboard { height: auto; padding: 0 1; border: round $panel-lighten-2; }
    #legacy-netconsole { height: 1fr; min-height: 6; border: round $panel-lighten-2; }
    #legacy-keys { height: auto; color: $text-muted; }
    LegacyPanel.-narrow #legacy-columns > Vertical { padding: 0; }
    LegacyPanel.-narrow .legacy-label { width: 4; }
    LegacyPanel.-narrow .legacy-row StatusLight { min-width: 3; }
    LegacyPanel.-short .legacy-row, LegacyPanel.-short #legacy-analog, LegacyPanel.-short #legacy-lcd { margin-top: 0; }
    LegacyPanel.-short #legacy-netconsole { min-height: 4; }
    """

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self._netconsole = StreamCursor()  # where the NetConsole shown stands
        self._running = False  # a 2010 DS runs here: its input keys are offered

    def refusal(self, action: str, parameters: tuple[object, ...] = ()) -> str | None:
        """The digital-input keys are not offered, and say why, where no 2010 DS runs."""
        if action == "toggle_input" and not self._running:
            return NO_LEGACY_DS
        return super().refusal(action, parameters)

    # -- layout ------------------------------------------------------------------------------
    def compose(self) -> ComposeResult:
        yield Static("", id="legacy-none")
        with Horizontal(id="legacy-columns"):
            with Vertical(id="legacy-tx"):
                yield Static("", id="legacy-control")
                with Horizontal(classes="legacy-row"):
                    yield Static("digital in", id="legacy-din-label", classes="legacy-label")
                    for n in range(1, 9):
                        yield DigitalToggle(n, id=f"legacy-din-{n}")
                with Vertical(id="legacy-analog"):
                    for n in range(1, 5):
                        yield AnalogSlider(n, id=f"legacy-analog-{n}")
            with Vertical(id="legacy-rx"):
                yield Static("", id="legacy-status")
                with Horizontal(classes="legacy-row"):
                    yield Static("digital out", id="legacy-dout-label", classes="legacy-label")
                    for n in range(1, 9):
                        yield StatusLight(f"{n}", id=f"legacy-dout-{n}")
                yield Static(lcd_text(("",) * LCD_LINES), id="legacy-lcd")
        yield Static("", id="legacy-dashboard")
        yield Log(max_lines=NETCONSOLE_LINES, id="legacy-netconsole")
        yield Static(self._keys_text(), id="legacy-keys", classes="key-hints")

    def on_mount(self) -> None:
        self.query_one("#legacy-tx").border_title = "DS → robot · UDP 1110 · 1024 bytes every 20 ms"
        self.query_one("#legacy-rx").border_title = "robot → DS · UDP 1150"
        self.query_one("#legacy-dashboard").border_title = "DS → dashboard · UDP 1165 · 1018 bytes"
        self.query_one("#legacy-netconsole").border_title = "NetConsole · UDP 6666 · the robot's console"
        self.query_one("#legacy-netconsole", Log).can_focus = False

    def on_resize(self) -> None:
        narrow = self.size.width < 100
        if narrow != self.has_class("-narrow"):
            self.query_one("#legacy-din-label", Static).update("in" if narrow else "digital in")
            self.query_one("#legacy-dout-label", Static).update("out" if narrow else "digital out")
            self._shown.pop("legacy-control", None)  # the control bits fold to fit
            self._shown.pop("legacy-status", None)
        self.set_class(narrow, "-narrow")
        self.set_class(self.size.height < 30, "-short")

    @staticmethod
    def _keys_text() -> Text:
        return key_hints([("This tab", [("1-8", "digital inputs"), ("Tab", "analog sliders"), ("← →", "±8"),
                                        ("PgUp PgDn", "±128"), ("Home End", "0 / 1023")])], title_width=10)

    # -- the engine --------------------------------------------------------------------------
    def engine_changed(self, engine: Any) -> None:
        """A new field: forget what was drawn; say plainly when the FMS could not run."""
        self._shown.clear()
        self._netconsole.reset()
        if self.is_mounted:
            self.query_one("#legacy-netconsole", Log).clear()
        note = getattr(engine.field, "fms_note", None)
        if note:
            self.app.notify(note, title="FMS", severity="warning", timeout=12)

    # -- commands (on the wire's side) -------------------------------------------------------
    def _send(self, command: Command) -> None:
        st = self.station()
        if st is None or st.ds is None or st.ds.legacy is None:
            self.notify(NO_LEGACY_DS, severity="warning")
            return
        self.send(replace(command, team=st.team))

    def action_toggle_input(self, number: int) -> None:
        self._send(ToggleDigitalInput(number))
        self.redraw_now()

    @on(DigitalToggle.Toggled)
    def _toggled(self, event: DigitalToggle.Toggled) -> None:
        self.action_toggle_input(event.number)

    @on(AnalogSlider.Changed)
    def _analog(self, event: AnalogSlider.Changed) -> None:
        self._send(SetAnalogInput(event.number, event.value))

    # -- the 10 Hz refresh -------------------------------------------------------------------
    def refresh_view(self, engine, now: float) -> None:
        st = self.station()
        ds = st.ds if st is not None else None
        codec = ds.legacy if ds is not None else None
        legacy_rio = st.rio if st is not None and getattr(engine.field.config, "legacy", False) else None
        running = codec is not None
        self.set_shown("running", running, self._show_running)
        if not running:
            self.set_text("legacy-none", self._none_text(engine, legacy_rio), layout=True)
            return
        self._refresh_tx(ds, codec)
        self._refresh_rx(ds, codec)
        self._refresh_dashboard(codec)
        self._refresh_netconsole(codec, ds.team if ds is not None else None)

    def _show_running(self, running: bool) -> None:
        self._running = running
        self.query_one("#legacy-none").display = not running
        for wid in ("#legacy-columns", "#legacy-dashboard", "#legacy-netconsole", "#legacy-keys"):
            self.query_one(wid).display = running
        self.app.refresh_bindings()  # the footer offers the input keys only with a 2010 DS

    @staticmethod
    def _none_text(engine: Any, rio: Any) -> Text:
        text = Text()
        if rio is not None:
            text.append(f"The fake cRIO of team {rio.team} speaks 2010 ({rio.code_state}, "
                        f"{'enabled' if rio.enabled else 'disabled'}), but no Driver Station runs here.\n", "bold")
            lcd = rio.lcd
            if lcd:
                text.append("What its LCD says:\n")
                text.append_text(lcd_text(tuple(lcd)))
                text.append("\n")
        else:
            text.append("The 2010 (cRIO) mode is off.\n", "bold")
            text.append("Press F8 and tick \"2010 legacy\", or start fieldbox with --legacy-2010: the DS and "
                        "the fake robot then speak the 2010 protocol, and this tab shows its fields.\n")
        note = getattr(engine.field, "fms_note", None)
        if note:
            text.append(f"\n{note}.", "dim")
        return text

    def _refresh_tx(self, ds: Any, codec: Any) -> None:
        last = codec.last_control
        per_line = 2 if self.has_class("-narrow") else 4
        text = control_text(codec.control_byte, per_line=per_line)
        if last is not None:
            station = last.station
            where = getattr(station, "label", None) or bytes(station).decode("ascii", "replace")
            text.append("\npacket  ", "dim")
            text.append(f"#{last.packet_index:<6d}", "bold")
            text.append("team ", "dim")
            text.append(f"{last.team:<6d}", "bold")
            text.append("station ", "dim")
            text.append(f"{where:<4}", "bold")
            text.append("version ", "dim")
            text.append(last.ds_version, "bold")
            text.append("\nstick 1 ", "dim")
            j = last.joysticks[0]
            text.append(" ".join(f"{a:+4d}" for a in j.axes))
            text.append("  buttons ", "dim")
            text.append(f"0x{j.buttons:03x}")
        self.set_text("legacy-control", text)
        din = codec.digital_in

        def show_inputs(bits: int) -> None:
            for n in range(1, 9):
                self.query_one(f"#legacy-din-{n}", DigitalToggle).set("on" if bits >> (n - 1) & 1 else "idle")

        self.set_shown("din", din, show_inputs)
        for n, value in enumerate(codec.analog, 1):
            self.query_one(f"#legacy-analog-{n}", AnalogSlider).show(value)

    def _refresh_rx(self, ds: Any, codec: Any) -> None:
        st = codec.last_status if ds.link.robot_comms else None
        text = Text()
        if st is None:
            text.append("no reply from the robot" if not ds.link.robot_comms else "—", "dim")
        else:
            b1, b2 = st.battery
            text.append("battery ", "dim")
            text.append(f"0x{b1:02x} 0x{b2:02x}", "bold")
            text.append(" BCD → ", "dim")
            if st.no_code:
                text.append("no robot code (0x37 0x37)", "bold yellow")
            elif st.volts is None:
                text.append("not BCD", "bold red")
            else:
                text.append(f"{st.volts:.2f} V", "bold")
            text.append("\n")
            text.append_text(control_text(st.control, "echo", 2 if self.has_class("-narrow") else 4))
            text.append("\npacket  ", "dim")
            text.append(f"#{st.packet_index:<6d}", "bold")
            text.append("size ", "dim")
            text.append("1152 (LCD)" if st.lcd is not None else "1024      ", "bold")
            text.append(" FPGA ", "dim")
            text.append(st.fpga_version)
            text.append("\nMAC     ", "dim")
            text.append(":".join(f"{b:02x}" for b in st.mac))
            text.append("\nerror   ", "dim")
            text.append(st.error_text.strip().splitlines()[-1][:80] if st.error_text.strip() else "—",
                        "bold red" if st.error_text.strip() else "dim")
        self.set_text("legacy-status", text)
        dout = st.ds_digital_out if st is not None else 0

        def show_outputs(bits: int) -> None:
            for n in range(1, 9):
                self.query_one(f"#legacy-dout-{n}", StatusLight).set("on" if bits >> (n - 1) & 1 else "idle")

        self.set_shown("dout", dout, show_outputs)
        self.set_text("legacy-lcd", lcd_text(codec.lcd if st is not None else ("",) * LCD_LINES))

    def _refresh_dashboard(self, codec: Any) -> None:
        text = Text()
        if codec.dashboard is None:
            text.append("not sent (--dashboard off)", "dim")
        else:
            host, port = codec.dashboard
            text.append("to ", "dim")
            text.append(f"{host}:{port}", "bold")
            text.append("   packets sent ", "dim")
            text.append(f"{codec.dashboard_sent}", "bold")
            text.append("   robot replies counted ", "dim")
            text.append(f"{codec.replies}", "bold")
            text.append("   50 Hz, one after each control packet", "dim")
        self.set_text("legacy-dashboard", text)

    def _refresh_netconsole(self, codec: Any, team: int | None) -> None:
        lines, fresh = self._netconsole.take(codec.netconsole, team)  # another DS's: anew
        log = self.query_one("#legacy-netconsole", Log)
        if fresh:
            log.clear()
        log.write_lines(text for _, text in lines)
