"""The Joysticks panel: the DS's six slots with their live axes, buttons and POVs, the robot's
rumble and outputs for each, real joysticks (pygame, hot-plug, locked slots) and a keyboard
joystick for terminals (SSH).

Input runs on a 50 Hz timer in the UI thread, whichever tab is shown (a driver watching the
console still drives): it reads the devices and hot-plug events, lets the keyboard's springs
return, and sends every change of the poll to the selected team's DS in one ``engine.call``.
The keyboard joystick's keys work only while this tab is shown (it takes focus then).

pygame is imported only when real joysticks start: the first time this tab is shown, or on
the rescan key. ``FIELDBOX_JOYSTICKS=off`` keeps them off (tests, machines without SDL);
``FIELDBOX_JOYSTICKS=on`` starts them with the app.
"""

from __future__ import annotations

import logging
import os
import time
from concurrent.futures import Future
from dataclasses import replace
from typing import Any, Callable

from rich.text import Text
from textual import events
from textual.app import ComposeResult
from textual.binding import Binding
from textual.widgets import Static

from roles.cores.core import CommandError
from roles.cores.commands import ClearJoystick, UpdateJoysticks

from ..joystick_input import KEYBOARD_KEYS, SLOTS, JoystickHub
from ..seats import watching
from ..widgets import axis_bar, level_bar, pov_arrow
from .base import Panel

log = logging.getLogger("fieldbox.joysticks")

POLL_PERIOD = 0.02  # 50 Hz, the DS's own packet rate
ERROR_REPEAT = 5.0  # the same failure is shown again at most this often


#: What a served tab's Joysticks tab says of real joysticks (it once said "plug one in").
BROWSER_JOYSTICKS = ("in a browser tab your gamepad cannot reach the field (it is plugged into your "
                     "computer, not the server's): drive with the keyboard joystick (its keys below; K turns it on and off)")


def devices_setting() -> str:
    """``auto`` (start real joysticks when the tab is first shown), ``on`` or ``off``."""
    value = os.environ.get("FIELDBOX_JOYSTICKS", "auto").strip().lower()
    return value if value in ("auto", "on", "off") else "auto"


class SlotView(Static):
    """One slot's lines; a click selects it."""

    DEFAULT_CSS = """
    SlotView { height: auto; }
    SlotView.-selected { background: $boost; }
    """

    def __init__(self, slot: int) -> None:
        super().__init__(id=f"js-slot-{slot}")
        self.slot = slot
        self.key: Any = None

    def on_click(self) -> None:
        panel = next((a for a in self.ancestors if isinstance(a, JoysticksPanel)), None)
        if panel is not None:
            panel.select(self.slot)
            panel.focus()


class JoysticksPanel(Panel):
    TITLE = "Joysticks"
    SHORT_TITLE = "Joy"
    ID = "joysticks"
    can_focus = True
    FOCUS_STYLED = ("#js-keys",)

    BINDINGS = [
        Binding("comma", "select(-1)", "Prev slot", show=False),
        Binding("full_stop", "select(1)", "Next slot", show=False),
        Binding("m", "move_keyboard", "Keyboard here"),
        Binding("K", "toggle_keyboard", "Keyboard on/off"),
        Binding("L", "lock", "Lock slot"),
        Binding("N", "rescan", "Rescan"),
    ]

    DEFAULT_CSS = """
    JoysticksPanel { layout: vertical; padding: 0 1; overflow-y: auto; }
    #js-head { height: auto; padding: 0 1; margin-bottom: 1; }
    #js-slots { height: auto; }
    #js-keys { height: auto; margin-top: 1; padding: 0 1; border: round $panel-lighten-2; }
    JoysticksPanel:focus #js-keys { border: round $accent; }
    JoysticksPanel.-tall #js-keys { dock: bottom; margin-bottom: 1; }
    """

    def __init__(self, *args: Any, devices_factory: Callable[[], Any] | None = None, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self.hub = JoystickHub(devices_factory=devices_factory)
        self.clock: Callable[[], float] = time.monotonic
        self.selected = 0
        self._target_key: tuple | None = None
        self._target: tuple | None = None
        self._inflight: Future | None = None  # the last update sent, until the wire answers
        self._errors: dict[str, float] = {}

    # -- layout ------------------------------------------------------------------------------
    def compose(self) -> ComposeResult:
        yield Static("", id="js-head")
        for slot in range(SLOTS):
            yield SlotView(slot)
        yield Static("", id="js-keys", classes="key-hints")

    def on_mount(self) -> None:
        self.set_interval(POLL_PERIOD, self.poll)
        if self._devices_setting() == "on":
            self.call_after_refresh(self.start_devices)
        self._render_keys()

    def on_unmount(self) -> None:
        self.hub.close()

    def on_show(self) -> None:
        if self._devices_setting() == "auto" and not self.hub.started:
            self.call_after_refresh(self.start_devices)  # paint first: pygame takes ~0.2 s to load

    def engine_changed(self, engine: Any) -> None:
        """A new field: everything goes to its DS afresh."""
        self._target_key = self._target = self._inflight = None
        self.hub.forget_pushed()
        self.sync()

    # -- devices -----------------------------------------------------------------------------
    def _devices_setting(self) -> str:
        """:func:`devices_setting`, or "browser" in a served tab (``fieldbox serve``, a classroom
        seat): the joysticks plugged into the server are not the student's, and a student's
        gamepad, in the browser's machine, cannot reach the server. The keyboard joystick can."""
        if getattr(self.app, "is_web", False) or getattr(self.app, "seat", None) is not None:
            return "browser"
        return devices_setting()

    def refusal(self, action: str, parameters: tuple[object, ...] = ()) -> str | None:
        """A browser's seat (a served tab, a classroom's) has no joysticks to rescan: the
        server's are not its own. Its footer and key help leave the key out."""
        if action == "rescan" and self._devices_setting() == "browser":
            return BROWSER_JOYSTICKS
        return super().refusal(action, parameters)

    def start_devices(self) -> None:
        if self._devices_setting() == "browser":
            self.hub.devices_status = BROWSER_JOYSTICKS
            return
        if devices_setting() == "off":
            self.hub.devices_status = "real joysticks are off (FIELDBOX_JOYSTICKS=off)"
            return
        for msg in self.hub.start_devices():
            self.notify(msg, timeout=4)
        self.sync()
        self._refresh_if_visible()

    def _refresh_if_visible(self) -> None:
        if self.is_mounted:
            self.redraw_now()

    # -- the 50 Hz input poll ----------------------------------------------------------------
    def poll(self) -> None:
        """Read devices and hot-plug, let the keyboard's springs act, send what changed."""
        for msg in self.hub.poll(self.clock()):
            self.notify(msg, timeout=4)
        target = self.sync()
        if target is not None and self.hub.started:
            self.hub.set_rumble(list(target[1].sticks.outputs))

    def _resolve_target(self) -> tuple | None:
        """(engine, ds, host name, team) of the selected team's DS, or None."""
        st = self.station()
        if st is None or st.ds is None:
            return None
        return self.app.engine, st.ds, st.ds_name, st.team  # type: ignore[attr-defined]

    def sync(self) -> tuple | None:
        """Send the DS what changed since the last call (one engine.call); returns the target."""
        target = self._resolve_target()
        key = None if target is None else (id(target[0]), target[2])
        if key != self._target_key:
            old = self._target
            if old is not None and target is not None and old[0] is target[0]:
                # joysticks follow the selected team: the old DS lets go of them
                self._call(old, UpdateJoysticks(tuple(ClearJoystick(s) for s in self.hub.owned_slots())))
            self._target_key, self._target = key, target
            self.hub.forget_pushed()
        if target is None:
            return None
        if not self._settled():
            return target  # the last update is still on its way: the changes wait and go together
        update = self.hub.take_update()
        if update:
            self._inflight = self._call(target, update)
        return target

    def _call(self, target: tuple, update: UpdateJoysticks) -> Future | None:
        """Send one update to the target's DS without waiting for the wire; its future (None
        if it could not go)."""
        engine, _, _, team = target
        try:
            return engine.submit_command(replace(update, team=team))
        except Exception as exc:  # noqa: BLE001 - the wire is gone: try again next poll
            self._failed(exc)
            return None

    def _settled(self) -> bool:
        """Whether no update is on its way (one that was refused is said, and everything goes again)."""
        future = self._inflight
        if future is None:
            return True
        if not future.done():
            return False
        self._inflight = None
        exc = future.exception()
        if exc is not None:
            self._failed(exc)
        return True

    def _failed(self, exc: BaseException) -> None:
        if isinstance(exc, CommandError):
            self._error(str(exc))
        else:  # the wire thread is gone or stuck
            log.warning("joystick update failed: %s", exc)
            self._error(f"joystick update failed: {exc}")
        self.hub.forget_pushed()

    def _error(self, text: str) -> None:
        now = time.monotonic()
        if now - self._errors.get(text, -ERROR_REPEAT) >= ERROR_REPEAT:
            self._errors[text] = now
            self.notify(text, severity="warning")

    # -- keys --------------------------------------------------------------------------------
    def on_key(self, event: events.Key) -> None:
        if self.hub.keyboard_slot is None:
            return
        name = event.character if event.is_printable and event.character else event.key
        if name not in KEYBOARD_KEYS:
            return
        if self.hub.keyboard.press(name, self.clock()):
            event.stop()
            event.prevent_default()
            self.sync()
            if name in ("v", "b"):
                self._render_keys()
            self._refresh_if_visible()

    def select(self, slot: int) -> None:
        self.selected = slot % SLOTS
        self._refresh_if_visible()

    def action_select(self, step: int) -> None:
        self.select(self.selected + step)

    def _after_change(self, msg: str) -> None:
        self.notify(msg, timeout=3)
        self.sync()
        self._render_keys()
        self._refresh_if_visible()

    def action_move_keyboard(self) -> None:
        self._after_change(self.hub.move_keyboard(self.selected))

    def action_toggle_keyboard(self) -> None:
        self._after_change(self.hub.toggle_keyboard(prefer=self.selected))

    def action_lock(self) -> None:
        self._after_change(self.hub.toggle_lock(self.selected))

    def action_rescan(self) -> None:
        if self._devices_setting() == "browser":
            self.notify(BROWSER_JOYSTICKS, severity="warning")
            return
        if devices_setting() == "off":
            self.notify("real joysticks are off (FIELDBOX_JOYSTICKS=off)", severity="warning")
            return
        for msg in self.hub.rescan():
            self.notify(msg, timeout=4)
        self.sync()
        self._refresh_if_visible()

    # -- drawing (10 Hz while shown) ---------------------------------------------------------
    def refresh_view(self, engine: Any, now: float) -> None:
        target = self._resolve_target()
        ds = target[1] if target is not None else None
        head = Text()
        if ds is None:
            head.append("No Driver Station runs here: joysticks have nowhere to go (F8 picks the roles).",
                        "bold")
        elif watching(getattr(self.app, "seat", None)):  # a classroom's observer: its keys are not offered
            head.append(f"You watch: no joystick drives from this tab (team {ds.team}'s are its driver's).", "bold")
        else:
            head.append("Joysticks drive ", "dim")
            head.append(f"team {ds.team}", "bold")
            head.append(f" ({ds.station.label})", "dim")
            several = len(engine.field.stations) > 1
            if several:
                head.append("  — the selected team: [ ] on the Driver Station tab", "dim")
        head.append("\nReal joysticks: ", "dim")
        if watching(getattr(self.app, "seat", None)):
            head.append("none here: the classroom refuses a watcher's joysticks")
        elif self._devices_setting() == "browser":
            head.append(BROWSER_JOYSTICKS)
        elif devices_setting() == "off" and not self.hub.started:
            head.append("off (FIELDBOX_JOYSTICKS=off); the keyboard joystick works")
        else:
            head.append(self.hub.devices_status)
        self.set_text("js-head", head, layout=True)
        self._render_keys()  # the keyboard's slot moves when a device takes slot 0
        width = max(40, self.query_one("#js-slot-0").size.width or self.size.width - 2)
        outputs = list(ds.sticks.outputs) if ds is not None else [None] * SLOTS
        joys = [ds.sticks.slots[slot] if ds is not None else None for slot in range(SLOTS)]
        # A tall screen gives each axis a line of its own, and a wide one longer bars: the
        # rows and columns the panel has, rather than an empty lower half.
        rows = self.size.height - self.query_one("#js-keys").outer_size.height - 3
        tall = sum(1 if joy is None else 4 + len(joy.axes) for joy in joys) <= rows
        self.set_class(tall, "-tall")  # the key map then sits at the bottom
        for slot in range(SLOTS):
            joy = joys[slot]
            view = self.query_one(f"#js-slot-{slot}", SlotView)
            snapshot = (self.selected == slot, _joy_key(joy), self._entry_key(slot),
                        _out_key(outputs[slot] if slot < len(outputs) else None), width, tall)
            if snapshot != view.key:
                view.key = snapshot
                view.update(self._render_slot(slot, joy, outputs[slot] if slot < len(outputs) else None, width,
                                              tall))
                view.set_class(self.selected == slot, "-selected")

    def _entry_key(self, slot: int) -> tuple:
        e = self.hub.slots[slot]
        if e is None:
            return ()
        return (e.source, e.descriptor.name, e.locked, e.device is not None)

    def _render_slot(self, slot: int, joy: Any, out: Any, width: int, tall: bool = False) -> Text:
        """The slot's lines, each cut to ``width`` (a narrow terminal loses the ends, not the
        layout)."""
        e = self.hub.slots[slot]
        lines: list[Text] = []
        title = Text()
        title.append("▶ " if slot == self.selected else "  ", "bold")
        title.append(f"{slot} ", "bold")
        lines.append(title)
        if joy is None:
            if e is not None and e.locked and e.device is None:
                title.append(f"[locked] {e.descriptor.name}: unplugged, waiting for it", "yellow")
            else:
                title.append("— empty —", "dim")
            return _cut(lines, width)
        title.append(joy.name or "(no name)", "bold")
        if e is None:
            source = "set by a command"
        elif e.source == "keyboard":
            source = "keyboard joystick (keys below)"
        elif e.device is None:
            source = "unplugged: neutral until it returns"
        else:
            source = "device"
        if e is not None and e.locked:
            title.append("  [locked]", "bold yellow")
        title.append(f"   {source}", "dim")
        title.append(f"   {len(joy.axes)} axes, {joy.button_count} buttons, {len(joy.povs)} POV"
                     f"{'s' if len(joy.povs) != 1 else ''}", "dim")
        # the robot's outputs for this slot
        robot = Text("   rumble L ", "dim")
        left = out.left_rumble / 65535 if out is not None and not out.idle else 0.0
        right = out.right_rumble / 65535 if out is not None and not out.idle else 0.0
        robot.append_text(level_bar(left, 6, style="magenta"))
        robot.append(" R ", "dim")
        robot.append_text(level_bar(right, 6, style="magenta"))
        bits = out.outputs if out is not None and not out.idle else 0
        on = [str(n + 1) for n in range(32) if bits >> n & 1]
        robot.append("   outputs ", "dim")
        robot.append(" ".join(on) if on else "—", "bold magenta" if on else "dim")
        lines.append(robot)
        # axes: one a line on a tall screen, else three a line (fewer where narrow); the bars
        # take the width there is (an axis is its number, its bar, its value: 10 cells and the bar)
        per_line = 1 if tall else max(1, min(3, (width - 3) // 20))
        bar = max(9, min(61 if tall else 41, (width - 3) // per_line - 11))
        bar -= 1 - bar % 2  # odd: a centre cell and two equal halves
        for i, value in enumerate(joy.axes):
            if i % per_line == 0:
                lines.append(Text("   "))
            else:
                lines[-1].append(" ")
            line = lines[-1]
            line.append(f"{i:>2} ", "dim")
            line.append_text(axis_bar(value, bar, style="cyan" if value else ""))
            line.append(" ")
            line.append(f"{value:+.2f}", "bold" if value else "dim")
        # buttons and POVs
        line = Text("   buttons", "dim")
        for b in range(joy.button_count):
            down = bool(joy.buttons >> b & 1)
            line.append(" ")
            line.append(f"{b + 1:>2}", "reverse bold green" if down else "dim")
        for p, degrees in enumerate(joy.povs):
            line.append(f"   POV {p} ", "dim")
            line.append(f"{pov_arrow(degrees)} {degrees}°" if degrees >= 0 else "· centred",
                        "bold cyan" if degrees >= 0 else "dim")
        lines.append(line)
        return _cut(lines, width)

    def _render_keys(self) -> None:
        kb = self.hub.keyboard
        slot = self.hub.keyboard_slot
        text = Text()
        text.append("Keyboard joystick", "bold")
        if slot is None:
            text.append(" is off (K turns it on)", "dim")
        else:
            text.append(f" → slot {slot}", "bold")
            text.append("   its keys work while this tab is shown", "dim")
            for keys, what in kb.key_map():
                text.append("\n ")
                text.append(f" {keys:<9} ", "reverse")
                text.append(f" {what}")
        text.append("\n")
        keys_here = [(", .", "select slot"), ("m", "keyboard here"), ("K", "keyboard on/off"),
                     ("L", "lock/unlock device")]
        if self.refusal("rescan") is None:
            keys_here.append(("N", "rescan devices"))
        for i, (keys, what) in enumerate(keys_here):
            text.append("   " if i else "Slots: ", "dim" if not i else "")
            text.append(f" {keys} ", "reverse bold")
            text.append(f" {what}")
        self.set_text("js-keys", text, layout=True)


def _cut(lines: list[Text], width: int) -> Text:
    for line in lines:
        line.truncate(width, overflow="ellipsis")
    return Text("\n").join(lines)


def _joy_key(joy: Any) -> tuple:
    if joy is None:
        return ()
    return (joy.name, tuple(joy.axes), joy.buttons, joy.button_count, tuple(joy.povs))


def _out_key(out: Any) -> tuple:
    if out is None:
        return ()
    return (out.outputs, out.left_rumble, out.right_rumble, out.idle)
