"""Joystick input for the Driver Station: real joysticks through pygame (SDL), a keyboard
joystick for terminals, and the six slots they are assigned to.

No textual here, so a headless DS could use it too; pygame is imported only when real
devices are started (:meth:`JoystickHub.start_devices`): it costs about 0.2 s, and SDL must
see its environment first (``SDL_VIDEODRIVER=dummy``, background joystick events, and no
signal handlers, or SDL would swallow Ctrl-C and SIGTERM).

* :class:`KeyboardJoystick`: a 6-axis, 12-button, 1-POV gamepad driven by key presses.
  Terminals send no key-up events, so axes either *spring* (a press pushes the axis fully,
  it returns to 0 once the key stops repeating) or *step* (each press moves it 0.25, a key
  centres), and buttons either *pulse* (down for 0.2 s per press) or *toggle*.
* :class:`PygameDevices`: SDL joysticks, with hot-plug (device added / removed events).
* :class:`JoystickHub`: which source sits in which slot, locking a device to its slot (a
  locked device that is unplugged keeps its slot, reported neutral, until it returns), and
  the difference between what the DS has and what it should have, as one
  :class:`JoystickUpdate` per poll (one ``engine.call`` carries every change).

Times are ``time.monotonic()`` seconds passed in by the caller (the key timing is the
user's, not the wire's).
"""

from __future__ import annotations

import logging
import math
import os
from collections import deque
from dataclasses import dataclass, field
from typing import Any, Callable, Iterable

log = logging.getLogger("fieldbox.joysticks")

SLOTS = 6
MAX_AXES = 12
MAX_BUTTONS = 32
MAX_POVS = 12
KEYBOARD_NAME = "fieldbox keyboard"

#: SDL reads these when it starts; set before pygame is imported.
SDL_ENVIRONMENT = {
    "SDL_VIDEODRIVER": "dummy",
    "SDL_JOYSTICK_ALLOW_BACKGROUND_EVENTS": "1",
    "SDL_NO_SIGNAL_HANDLERS": "1",
    "PYGAME_HIDE_SUPPORT_PROMPT": "1",  # its banner on stdout would scribble over the TUI
}

#: Joystick type numbers of the descriptor (protocol.enums.JoystickType).
TYPE_UNKNOWN = -1
TYPE_XINPUT_GAMEPAD = 1
TYPE_HID_JOYSTICK = 20
TYPE_HID_GAMEPAD = 21


@dataclass(frozen=True)
class Descriptor:
    """What the DS declares for a slot (its joystick descriptor)."""

    name: str
    axes: int
    buttons: int
    povs: int
    is_xbox: bool = False
    joystick_type: int = TYPE_UNKNOWN

    def neutral(self) -> "Reading":
        return Reading((0.0,) * self.axes, 0, (-1,) * self.povs)


@dataclass(frozen=True)
class Reading:
    """A slot's live values: axes -1..1, buttons as a word (bit 0 = button 1), POVs in
    degrees or -1."""

    axes: tuple[float, ...]
    buttons: int
    povs: tuple[int, ...]


def axis_int8(value: float) -> int:
    """The wire's int8 for an axis (as protocol.ds_to_rio.axis_to_int8): what "changed" means."""
    if not math.isfinite(value):
        return 0
    value = max(-1.0, min(1.0, value))
    return round(value * 128) if value < 0 else round(value * 127)


# -- the keyboard joystick -------------------------------------------------------------------
AXIS_KEYS: dict[str, tuple[int, int]] = {
    # left stick (WPILib: axis 0 X, axis 1 Y, pushing forward is negative Y)
    "a": (0, -1), "d": (0, +1), "w": (1, -1), "s": (1, +1),
    # triggers, axes 2 and 3: r / y raise, f / h lower
    "f": (2, -1), "r": (2, +1), "h": (3, -1), "y": (3, +1),
    # right stick, axes 4 and 5
    "j": (4, -1), "l": (4, +1), "i": (5, -1), "k": (5, +1),
}
BUTTON_KEYS: dict[str, int] = {**{str(n): n for n in range(1, 10)}, "0": 10, "-": 11, "=": 12}
POV_KEYS: dict[str, int] = {"up": 0, "right": 90, "down": 180, "left": 270}
CENTRE_KEY = "c"
AXIS_MODE_KEY = "v"
BUTTON_MODE_KEY = "b"
KEYBOARD_KEYS = frozenset([*AXIS_KEYS, *BUTTON_KEYS, *POV_KEYS, CENTRE_KEY, AXIS_MODE_KEY, BUTTON_MODE_KEY])


class KeyboardJoystick:
    """A gamepad made of keys (see ``AXIS_KEYS``, ``BUTTON_KEYS``, ``POV_KEYS``).

    Spring axes and POV: a first press holds for ``first_hold`` seconds (longer than a
    terminal's key-repeat delay, so a held key does not flicker to 0 before it starts
    repeating); every repeat holds ``repeat_hold`` more; with no repeat the value returns to
    0. Step axes: each press moves ``step``; ``c`` centres. Pulse buttons are down for
    ``pulse`` seconds per press (a repeat keeps them down); toggle buttons flip per press.
    """

    AXES = 6
    BUTTONS = 12
    POVS = 1
    DESCRIPTOR = Descriptor(KEYBOARD_NAME, AXES, BUTTONS, POVS)

    def __init__(self, *, first_hold: float = 0.55, repeat_hold: float = 0.15, pulse: float = 0.2,
                 step: float = 0.25) -> None:
        self.first_hold, self.repeat_hold, self.pulse, self.step = first_hold, repeat_hold, pulse, step
        self.axis_mode = "spring"  # spring | step
        self.button_mode = "pulse"  # pulse | toggle
        self.axes = [0.0] * self.AXES
        self.buttons = 0
        self.pov = -1
        self._axis_until = [math.inf] * self.AXES
        self._button_until = [math.inf] * self.BUTTONS
        self._pov_until = math.inf

    # -- keys ----------------------------------------------------------------------------
    def press(self, key: str, now: float) -> bool:
        """Apply one key press (a character, or ``up``/``down``/``left``/``right``).
        Returns False for a key that is not the keyboard joystick's."""
        if key in AXIS_KEYS:
            axis, direction = AXIS_KEYS[key]
            self._press_axis(axis, direction, now)
        elif key in BUTTON_KEYS:
            self._press_button(BUTTON_KEYS[key], now)
        elif key in POV_KEYS:
            self._press_pov(POV_KEYS[key], now)
        elif key == CENTRE_KEY:
            self.centre()
        elif key == AXIS_MODE_KEY:
            self.axis_mode = "step" if self.axis_mode == "spring" else "spring"
            self._centre_axes()
        elif key == BUTTON_MODE_KEY:
            self.button_mode = "toggle" if self.button_mode == "pulse" else "pulse"
            self._release_buttons()
        else:
            return False
        return True

    def _press_axis(self, axis: int, direction: int, now: float) -> None:
        if self.axis_mode == "step":
            steps = round(self.axes[axis] / self.step) + direction
            self.axes[axis] = max(-1.0, min(1.0, steps * self.step))
            self._axis_until[axis] = math.inf
            return
        target = float(direction)
        if self.axes[axis] == target and now < self._axis_until[axis]:
            self._axis_until[axis] = max(self._axis_until[axis], now + self.repeat_hold)
        else:
            self.axes[axis] = target
            self._axis_until[axis] = now + self.first_hold

    def _press_button(self, number: int, now: float) -> None:
        bit = 1 << (number - 1)
        if self.button_mode == "toggle":
            self.buttons ^= bit
            self._button_until[number - 1] = math.inf
            return
        i = number - 1
        if self.buttons & bit and now < self._button_until[i]:
            self._button_until[i] = max(self._button_until[i], now + self.repeat_hold)
        else:
            self.buttons |= bit
            self._button_until[i] = now + self.pulse

    def _press_pov(self, degrees: int, now: float) -> None:
        if self.axis_mode == "step":
            self.pov, self._pov_until = degrees, math.inf
        elif self.pov == degrees and now < self._pov_until:
            self._pov_until = max(self._pov_until, now + self.repeat_hold)
        else:
            self.pov, self._pov_until = degrees, now + self.first_hold

    def centre(self) -> None:
        """Every axis to 0, the POV centred, every button up."""
        self._centre_axes()
        self._release_buttons()

    def _centre_axes(self) -> None:
        self.axes = [0.0] * self.AXES
        self._axis_until = [math.inf] * self.AXES
        self.pov, self._pov_until = -1, math.inf

    def _release_buttons(self) -> None:
        self.buttons = 0
        self._button_until = [math.inf] * self.BUTTONS

    # -- time ----------------------------------------------------------------------------
    def tick(self, now: float) -> bool:
        """Let springs return and pulses end; True if anything changed."""
        changed = False
        for i, until in enumerate(self._axis_until):
            if now >= until:
                self.axes[i] = 0.0
                self._axis_until[i] = math.inf
                changed = True
        for i, until in enumerate(self._button_until):
            if now >= until:
                self.buttons &= ~(1 << i)
                self._button_until[i] = math.inf
                changed = True
        if now >= self._pov_until:
            self.pov, self._pov_until = -1, math.inf
            changed = True
        return changed

    def next_change(self) -> float | None:
        """When :meth:`tick` will next change something (None: nothing pending)."""
        t = min(min(self._axis_until), min(self._button_until), self._pov_until)
        return None if t == math.inf else t

    def reading(self) -> Reading:
        return Reading(tuple(self.axes), self.buttons, (self.pov,))

    # -- what to show ----------------------------------------------------------------------
    def key_map(self) -> list[tuple[str, str]]:
        """(keys, what they do), for the screen."""
        axes = ("spring back when the key stops repeating" if self.axis_mode == "spring"
                else f"step ±{self.step:g} per press")
        buttons = "pulse 0.2 s" if self.button_mode == "pulse" else "toggle per press"
        return [
            ("w a s d", "left stick    axis 0: a ← d →    axis 1: w ↑ s ↓"),
            ("i j k l", "right stick   axis 4: j ← l →    axis 5: i ↑ k ↓"),
            ("r f y h", "axis 2: r + f −    axis 3: y + h −"),
            ("1-9 0 - =", f"buttons 1-12, {buttons}   (b: {'toggle' if self.button_mode == 'pulse' else 'pulse'})"),
            ("← ↑ → ↓", "POV 0: ↑ 0°  → 90°  ↓ 180°  ← 270°"),
            ("c", f"centre all · axes {axes}   (v: {'step' if self.axis_mode == 'spring' else 'spring'})"),
        ]


# -- real devices through pygame ------------------------------------------------------------
class DeviceError(Exception):
    """Real joysticks are unavailable; the message says why (for the screen)."""


HAT_TO_POV = {(0, 1): 0, (1, 1): 45, (1, 0): 90, (1, -1): 135, (0, -1): 180, (-1, -1): 225,
              (-1, 0): 270, (-1, 1): 315}


def import_pygame() -> Any:
    """pygame, imported with SDL's environment set first (values the user set win)."""
    for name, value in SDL_ENVIRONMENT.items():
        os.environ.setdefault(name, value)
    import pygame  # noqa: PLC0415 - lazy on purpose

    return pygame


@dataclass(eq=False)
class Device:
    """One open SDL joystick."""

    instance_id: int
    name: str
    guid: str
    descriptor: Descriptor
    handle: Any = field(repr=False, default=None)
    rumble: tuple[float, float] = (0.0, 0.0)
    key: tuple[str, str, int] | None = None  # set by the hub: (GUID, name, n-th of its kind)


def describe_device(name: str, n_axes: int, n_buttons: int, n_hats: int) -> Descriptor:
    """The DS descriptor for a device: counts clipped to what the protocol carries, and a type
    guessed from the name (Xbox pads are XInput gamepads; sticks are HID joysticks)."""
    lowered = name.lower()
    is_xbox = any(word in lowered for word in ("xbox", "x-box", "xinput"))
    if is_xbox:
        kind = TYPE_XINPUT_GAMEPAD
    elif any(word in lowered for word in ("stick", "flight", "attack", "extreme 3d")):
        kind = TYPE_HID_JOYSTICK
    else:
        kind = TYPE_HID_GAMEPAD
    clipped = name.encode("utf-8", "replace")[:60].decode("utf-8", "ignore")
    return Descriptor(clipped, min(n_axes, MAX_AXES), min(n_buttons, MAX_BUTTONS), min(n_hats, MAX_POVS),
                      is_xbox, kind)


class PygameDevices:
    """SDL joysticks through pygame. Constructing it starts SDL's joystick subsystem; it
    raises :class:`DeviceError` with the reason when pygame or SDL cannot."""

    def __init__(self) -> None:
        try:
            pg = import_pygame()
        except ImportError as exc:
            raise DeviceError(f"pygame is not installed ({exc}): real joysticks are off") from None
        self.pg = pg
        try:
            pg.display.init()  # SDL delivers joystick events through its video/event loop
            pg.joystick.init()
        except Exception as exc:  # pygame.error, or SDL missing a backend
            raise DeviceError(f"SDL could not start joysticks: {exc}") from None
        self.devices: dict[int, Device] = {}

    def open_all(self) -> list[Device]:
        """Open every joystick SDL knows now (already open ones are returned as they are)."""
        self.pg.event.pump()
        found = []
        for index in range(self.pg.joystick.get_count()):
            dev = self._open(index)
            if dev is not None:
                found.append(dev)
        self._drain()  # their "added" events are already handled
        return found

    def _open(self, index: int) -> Device | None:
        try:
            js = self.pg.joystick.Joystick(index)
            iid = js.get_instance_id()
            if iid in self.devices:
                return self.devices[iid]
            desc = describe_device(js.get_name() or f"joystick {index}", js.get_numaxes(), js.get_numbuttons(),
                                   js.get_numhats())
            dev = Device(iid, desc.name, js.get_guid(), desc, js)
        except Exception as exc:  # a device that vanished between the event and the open
            log.info("cannot open joystick %s: %s", index, exc)
            return None
        self.devices[iid] = dev
        return dev

    def _drain(self) -> None:
        self.pg.event.get()

    def events(self) -> list[tuple[str, Any]]:
        """Hot-plug since the last call: ``("added", Device)`` and ``("removed", Device)``.
        Every other event is dropped (values are read as state, see :meth:`read`)."""
        pg = self.pg
        out: list[tuple[str, Any]] = []
        for event in pg.event.get():
            if event.type == pg.JOYDEVICEADDED:
                before = set(self.devices)
                dev = self._open(event.device_index)
                if dev is not None and dev.instance_id not in before:
                    out.append(("added", dev))
            elif event.type == pg.JOYDEVICEREMOVED:
                dev = self.devices.pop(event.instance_id, None)
                if dev is not None:
                    self._close(dev)
                    out.append(("removed", dev))
        return out

    def read(self, dev: Device) -> Reading:
        js, d = dev.handle, dev.descriptor
        try:
            axes = tuple(js.get_axis(i) for i in range(d.axes))
            buttons = 0
            for i in range(d.buttons):
                if js.get_button(i):
                    buttons |= 1 << i
            povs = tuple(HAT_TO_POV.get(tuple(js.get_hat(i)), -1) for i in range(d.povs))
        except Exception:  # unplugged this instant: the removed event follows
            return d.neutral()
        return Reading(axes, buttons, povs)

    def set_rumble(self, dev: Device, left: float, right: float) -> None:
        """The robot's rumble on the device (left is the heavy, low-frequency motor)."""
        if (left, right) == dev.rumble:
            return
        dev.rumble = (left, right)
        try:
            if left or right:
                dev.handle.rumble(left, right, 0)
            else:
                dev.handle.stop_rumble()
        except Exception as exc:  # no rumble motors, or unplugged
            log.debug("rumble on %s: %s", dev.name, exc)

    def rescan(self) -> list[Device]:
        """Restart SDL's joystick subsystem and open everything again (new instance ids)."""
        for dev in list(self.devices.values()):
            self._close(dev)
        self.devices.clear()
        self.pg.joystick.quit()
        self.pg.joystick.init()
        return self.open_all()

    def _close(self, dev: Device) -> None:
        try:
            dev.handle.quit()
        except Exception:
            pass

    def close(self) -> None:
        for dev in list(self.devices.values()):
            self._close(dev)
        self.devices.clear()
        try:
            self.pg.joystick.quit()
        except Exception:
            pass


# -- slots -----------------------------------------------------------------------------------
DeviceKey = tuple[str, str, int]  # (SDL GUID, name, n-th of that kind plugged in)


@dataclass
class SlotEntry:
    """What sits in a slot: the keyboard joystick, or a device (``device`` is None while a
    locked device is unplugged: the slot waits for it, reported neutral)."""

    source: str  # "keyboard" | "device"
    descriptor: Descriptor
    key: DeviceKey | None = None
    device: Device | None = None
    locked: bool = False

    @property
    def present(self) -> bool:
        return self.source == "keyboard" or self.device is not None


class JoystickUpdate:
    """The changes to one DS's joystick slots, applied in one go on the wire's side."""

    __slots__ = ("ops",)

    def __init__(self, ops: list[tuple]) -> None:
        self.ops = ops

    def __bool__(self) -> bool:
        return bool(self.ops)

    def __repr__(self) -> str:
        return f"JoystickUpdate({self.ops!r})"

    def apply(self, ds: Any) -> None:
        """Call the DS core's joystick methods (run this through ``engine.call``)."""
        for op in self.ops:
            kind, slot = op[0], op[1]
            if kind == "declare":
                d: Descriptor = op[2]
                ds.set_joystick(slot, d.axes, d.buttons, d.povs, name=d.name, is_xbox=d.is_xbox,
                                joystick_type=d.joystick_type)
            elif kind == "clear":
                ds.clear_joystick(slot)
            elif kind == "axis":
                ds.set_axis(slot, op[2], op[3])
            elif kind == "button":
                ds.set_button(slot, op[2], op[3])
            elif kind == "pov":
                ds.set_pov(slot, op[2], op[3])


_UNKNOWN = object()  # what the DS has in a slot is not known: send it in full


class JoystickHub:
    """The six slots, their sources, and what to send the DS.

    ``devices_factory`` makes the device backend (default :class:`PygameDevices`); it is
    called by :meth:`start_devices` only, so pygame is imported only then.
    """

    def __init__(self, *, keyboard: bool = True,
                 devices_factory: Callable[[], Any] | None = None) -> None:
        self.slots: list[SlotEntry | None] = [None] * SLOTS
        self.keyboard = KeyboardJoystick()
        self.keyboard_placed = False  # the user put it somewhere: a device will not move it
        self.devices_factory = devices_factory or PygameDevices
        self.devices: Any = None
        self.devices_status = "not started yet"
        self.unassigned: list[Device] = []
        self.messages: deque[str] = deque(maxlen=20)
        self._remembered: dict[DeviceKey, int] = {}
        self._readings: dict[int, Reading] = {}
        self._pushed: list[Any] = [_UNKNOWN] * SLOTS
        if keyboard:
            self.slots[0] = SlotEntry("keyboard", KeyboardJoystick.DESCRIPTOR)

    # -- lookups ---------------------------------------------------------------------------
    @property
    def keyboard_slot(self) -> int | None:
        for i, e in enumerate(self.slots):
            if e is not None and e.source == "keyboard":
                return i
        return None

    @property
    def started(self) -> bool:
        return self.devices is not None

    def _free_slot(self, exclude: Iterable[int] = ()) -> int | None:
        for i, e in enumerate(self.slots):
            if e is None and i not in exclude:
                return i
        return None

    def _say(self, text: str) -> str:
        self.messages.append(text)
        log.info("%s", text)
        return text

    # -- devices ---------------------------------------------------------------------------
    def start_devices(self) -> list[str]:
        """Start real joysticks (imports pygame); messages to show. Safe to call again."""
        if self.devices is not None:
            return []
        try:
            self.devices = self.devices_factory()
        except DeviceError as exc:
            self.devices_status = str(exc)
            return [self._say(str(exc))]
        except Exception as exc:  # a broken SDL must not take the app down
            self.devices_status = f"real joysticks unavailable: {exc}"
            return [self._say(self.devices_status)]
        out = [self._add(dev) for dev in self.devices.open_all()]
        self._update_status()
        return [m for m in out if m]

    def rescan(self) -> list[str]:
        """Find the devices again (starting real joysticks if they were not)."""
        if self.devices is None:
            return self.start_devices() or [self._say(self.devices_status)]
        try:
            found = self.devices.rescan()
        except Exception as exc:
            self.devices_status = f"rescan failed: {exc}"
            return [self._say(self.devices_status)]
        for i, e in enumerate(self.slots):
            if e is not None and e.device is not None:
                self._detach(i, e)
        self.unassigned.clear()
        out = [m for m in (self._add(dev) for dev in found) if m]
        self._update_status()
        return out or [self._say(f"rescanned: {self._count_text()}")]

    def _count_text(self) -> str:
        n = len(self._connected())
        return "no joystick found" if n == 0 else f"{n} joystick{'s' if n != 1 else ''} found"

    def _update_status(self) -> None:
        if self.devices is not None:
            n = len(self._connected())
            self.devices_status = (f"{self._count_text()}; hot-plug is on" if n
                                   else "no joystick found: plug one in (hot-plug is on)")

    def poll(self, now: float) -> list[str]:
        """Read devices and hot-plug events, let the keyboard's springs act; messages to show."""
        out: list[str] = []
        if self.devices is not None:
            try:
                events = self.devices.events()
            except Exception as exc:
                events = []
                log.warning("joystick events failed: %s", exc)
            for what, dev in events:
                msg = self._add(dev) if what == "added" else self._remove(dev)
                if msg:
                    out.append(msg)
            if events:
                self._update_status()
            readings = {}
            for i, e in enumerate(self.slots):
                if e is not None and e.device is not None:
                    readings[i] = self.devices.read(e.device)
            self._readings = readings
        self.keyboard.tick(now)
        return out

    def _key_for(self, dev: Device) -> DeviceKey:
        """(GUID, name, n): the n-th connected device of its kind, so two identical pads
        each keep their own slot."""
        taken = {d.key[2] for d in self._connected()
                 if d is not dev and d.key is not None and d.key[:2] == (dev.guid, dev.name)}
        nth = 0
        while nth in taken:
            nth += 1
        dev.key = (dev.guid, dev.name, nth)
        return dev.key

    def _connected(self) -> list[Device]:
        return [e.device for e in self.slots if e is not None and e.device is not None] + list(self.unassigned)

    def _add(self, dev: Device) -> str:
        key = self._key_for(dev)
        slot = next((i for i, e in enumerate(self.slots)
                     if e is not None and e.locked and e.device is None and e.key == key), None)
        if slot is not None:
            self.slots[slot].device = dev
            self.slots[slot].descriptor = dev.descriptor
            return self._say(f"{dev.name} is back in its locked slot {slot}")
        remembered = self._remembered.get(key)
        if remembered is not None and self.slots[remembered] is None:
            slot = remembered
        elif self.slots[0] is not None and self.slots[0].source == "keyboard" and not self.keyboard_placed \
                and remembered is None and not any(e is not None and e.source == "device" for e in self.slots):
            # the first real device takes slot 0, as robot code expects; the keyboard moves on
            other = self._free_slot(exclude=(0,))
            if other is not None:
                self.slots[other], self.slots[0] = self.slots[0], None
                slot = 0
        if slot is None:
            slot = self._free_slot()
        if slot is None:
            self.unassigned.append(dev)
            return self._say(f"{dev.name} plugged in, but all six slots are taken")
        self.slots[slot] = SlotEntry("device", dev.descriptor, key, dev)
        self._remembered[key] = slot
        return self._say(f"{dev.name} plugged in: slot {slot}")

    def _detach(self, slot: int, e: SlotEntry) -> None:
        if e.key is not None:
            self._remembered[e.key] = slot
        if e.locked:
            e.device = None
        else:
            self.slots[slot] = None
        self._readings.pop(slot, None)

    def _remove(self, dev: Device) -> str:
        if dev in self.unassigned:
            self.unassigned.remove(dev)
            return self._say(f"{dev.name} unplugged")
        for i, e in enumerate(self.slots):
            if e is not None and e.device is dev:
                self._detach(i, e)
                msg = (f"{dev.name} unplugged: slot {i} stays locked to it (neutral until it returns)"
                       if e.locked else f"{dev.name} unplugged: slot {i} is free")
                self._fill_free()
                return self._say(msg)
        return ""

    def _fill_free(self) -> None:
        while self.unassigned:
            slot = self._free_slot()
            if slot is None:
                return
            dev = self.unassigned.pop(0)
            key = dev.key or self._key_for(dev)
            self.slots[slot] = SlotEntry("device", dev.descriptor, key, dev)
            self._remembered[key] = slot
            self._say(f"{dev.name}: slot {slot}")

    def set_rumble(self, outputs: Iterable[Any]) -> None:
        """Forward the robot's rumble (``ds.joystick_outputs``) to the devices in the slots."""
        if self.devices is None:
            return
        for i, out in enumerate(outputs):
            if i >= SLOTS:
                break
            e = self.slots[i]
            if e is None or e.device is None:
                continue
            if out is None or getattr(out, "idle", False):
                left = right = 0.0
            else:
                left, right = out.left_rumble / 65535, out.right_rumble / 65535
            self.devices.set_rumble(e.device, left, right)

    def close(self) -> None:
        if self.devices is not None:
            try:
                self.devices.close()
            finally:
                self.devices = None

    # -- what the operator does ------------------------------------------------------------
    def toggle_lock(self, slot: int) -> str:
        e = self.slots[slot]
        if e is None:
            return f"slot {slot} is empty: nothing to lock"
        if e.source == "keyboard":
            return "the keyboard joystick stays where you put it (m moves it)"
        if e.locked and e.device is None:
            self.slots[slot] = None
            if e.key is not None:
                self._remembered.pop(e.key, None)
            self._fill_free()
            return self._say(f"slot {slot} unlocked: {e.descriptor.name} no longer holds it")
        e.locked = not e.locked
        return self._say(f"slot {slot} {'locked to' if e.locked else 'unlocked from'} {e.descriptor.name}")

    def move_keyboard(self, slot: int) -> str:
        """Put the keyboard joystick in ``slot``; what was there takes the keyboard's old slot."""
        old = self.keyboard_slot
        self.keyboard_placed = True
        if old == slot:
            return f"the keyboard joystick is already in slot {slot}"
        occupant = self.slots[slot]
        if occupant is not None:
            dest = old if old is not None else self._free_slot(exclude=(slot,))
            if dest is None:
                return f"no free slot for {occupant.descriptor.name}: the keyboard stays off"
            self.slots[dest] = occupant
            if occupant.key is not None:
                self._remembered[occupant.key] = dest
        elif old is not None:
            self.slots[old] = None
        self.slots[slot] = SlotEntry("keyboard", KeyboardJoystick.DESCRIPTOR)
        return self._say(f"keyboard joystick: slot {slot}")

    def toggle_keyboard(self, prefer: int | None = None) -> str:
        old = self.keyboard_slot
        if old is not None:
            self.slots[old] = None
            self.keyboard.centre()
            self._fill_free()
            return self._say(f"keyboard joystick off (slot {old} is free)")
        slot = prefer if prefer is not None and self.slots[prefer] is None else self._free_slot()
        if slot is None:
            return "all six slots are taken: free one for the keyboard joystick"
        self.keyboard_placed = True
        self.slots[slot] = SlotEntry("keyboard", KeyboardJoystick.DESCRIPTOR)
        return self._say(f"keyboard joystick on: slot {slot}")

    # -- what the DS should have -----------------------------------------------------------
    def wanted(self) -> list[tuple[Descriptor, Reading] | None]:
        out: list[tuple[Descriptor, Reading] | None] = []
        for i, e in enumerate(self.slots):
            if e is None:
                out.append(None)
            elif e.source == "keyboard":
                out.append((e.descriptor, self.keyboard.reading()))
            elif e.device is None:
                out.append((e.descriptor, e.descriptor.neutral()))
            else:
                out.append((e.descriptor, self._readings.get(i) or e.descriptor.neutral()))
        return out

    def forget_pushed(self) -> None:
        """The DS's slots are unknown (a new engine, another team, a failed call): the next
        update sends everything."""
        self._pushed = [_UNKNOWN] * SLOTS

    def owned_slots(self) -> list[int]:
        """Slots this hub has declared on the DS (to clear them when it moves to another DS)."""
        return [i for i, p in enumerate(self._pushed) if p is not None]

    def take_update(self) -> JoystickUpdate | None:
        """The changes since the last update, as one batch (and remember them as sent)."""
        ops: list[tuple] = []
        want = self.wanted()
        for slot, (new, old) in enumerate(zip(want, self._pushed)):
            if new is None:
                if old is not None:
                    ops.append(("clear", slot))
                continue
            desc, reading = new
            if old is _UNKNOWN or old is None or old[0] != desc:
                ops.append(("declare", slot, desc))
                old_reading = desc.neutral()
            else:
                old_reading = old[1]
            ops += _value_ops(slot, old_reading, reading)
        self._pushed = list(want)
        return JoystickUpdate(ops) if ops else None


def _value_ops(slot: int, old: Reading, new: Reading) -> list[tuple]:
    ops: list[tuple] = []
    for i, (a, b) in enumerate(zip(old.axes, new.axes)):
        if axis_int8(a) != axis_int8(b):
            ops.append(("axis", slot, i, max(-1.0, min(1.0, float(b))) if math.isfinite(b) else 0.0))
    changed = old.buttons ^ new.buttons
    n = 0
    while changed:
        if changed & 1:
            ops.append(("button", slot, n + 1, bool(new.buttons >> n & 1)))
        changed >>= 1
        n += 1
    for i, (a, b) in enumerate(zip(old.povs, new.povs)):
        if a != b:
            ops.append(("pov", slot, i, b))
    return ops
