"""The six joystick slots: which source sits in which (the keyboard joystick or an SDL
device), locking a device to its slot, and what to send the DS as one command
(:class:`~roles.cores.commands.UpdateJoysticks`) per poll."""

from __future__ import annotations

import logging
import math
from collections import deque
from dataclasses import dataclass
from typing import Any, Callable, Iterable

from roles.cores.commands import (ClearJoystick, DeclareJoystick, JoystickChange, SetAxis, SetButton, SetPov,
                                  UpdateJoysticks)

from .descriptor import SLOTS, Descriptor, Reading, axis_int8
from .devices import Device, DeviceError, PygameDevices
from .keyboard import KeyboardJoystick

log = logging.getLogger("fieldbox.joysticks")

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
            entry = self.slots[slot]
            assert entry is not None  # found above
            entry.device = dev
            entry.descriptor = dev.descriptor
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
        """Forward the robot's rumble (``ds.sticks.outputs``) to the devices in the slots."""
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

    def take_update(self) -> UpdateJoysticks | None:
        """The changes since the last update, as one command (and remember them as sent); it
        names no team: the caller says which DS."""
        ops: list[JoystickChange] = []
        want = self.wanted()
        for slot, (new, old) in enumerate(zip(want, self._pushed)):
            if new is None:
                if old is not None:
                    ops.append(ClearJoystick(slot))
                continue
            desc, reading = new
            if old is _UNKNOWN or old is None or old[0] != desc:
                ops.append(DeclareJoystick(slot, desc.name, desc.axes, desc.buttons, desc.povs,
                                           desc.is_xbox, desc.joystick_type))
                old_reading = desc.neutral()
            else:
                old_reading = old[1]
            ops += _value_ops(slot, old_reading, reading)
        self._pushed = list(want)
        return UpdateJoysticks(tuple(ops)) if ops else None


def _value_ops(slot: int, old: Reading, new: Reading) -> list[JoystickChange]:
    ops: list[JoystickChange] = []
    for i, (a, b) in enumerate(zip(old.axes, new.axes)):
        if axis_int8(a) != axis_int8(b):
            ops.append(SetAxis(slot, i, max(-1.0, min(1.0, float(b))) if math.isfinite(b) else 0.0))
    changed = old.buttons ^ new.buttons
    n = 0
    while changed:
        if changed & 1:
            ops.append(SetButton(slot, n + 1, bool(new.buttons >> n & 1)))
        changed >>= 1
        n += 1
    for i, (a, b) in enumerate(zip(old.povs, new.povs)):
        if a != b:
            ops.append(SetPov(slot, i, b))
    return ops
