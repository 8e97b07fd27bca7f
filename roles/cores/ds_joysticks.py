"""The Driver Station's six joystick slots: what the operator plugged in, the values the
control packets carry, the descriptors robot TCP carries, and what the robot sends back.

Slots keep their numbers: an empty slot before one in use goes out empty. Commands check
every argument first and change nothing when refused (:class:`~roles.cores.core.CommandError`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from protocol import rio_to_ds
from protocol.ds_to_rio import (EMPTY_JOYSTICK, MAX_AXES, MAX_BUTTONS, MAX_JOYSTICKS, MAX_POVS, Joystick,
                                JoystickDescriptor, axis_to_int8)
from protocol.enums import JoystickType

from .core import CommandError
from .views import JoystickSlotView, JoystickView


@dataclass
class JoystickSlot:
    """One occupied slot: its descriptor and its live values (axes -1.0..1.0, buttons as a
    word with bit 0 = button 1, POVs in degrees or -1)."""

    name: str
    is_xbox: bool
    joystick_type: JoystickType | int
    axis_types: tuple[int, ...]
    axes: list[float]
    button_count: int
    povs: list[int]
    buttons: int = 0

    def view(self) -> JoystickSlotView:
        return JoystickSlotView(self.name, self.is_xbox, int(self.joystick_type), self.axis_types, tuple(self.axes),
                                self.button_count, tuple(self.povs), self.buttons)

    def wire(self) -> Joystick:
        return Joystick(tuple(axis_to_int8(a) for a in self.axes), self.buttons, self.button_count,
                        tuple(self.povs))

    def descriptor(self, index: int) -> JoystickDescriptor:
        return JoystickDescriptor(index, self.is_xbox, self.joystick_type, self.name, self.axis_types,
                                  self.button_count, len(self.povs))


def _empty_descriptor(index: int) -> JoystickDescriptor:
    return JoystickDescriptor(index, False, JoystickType.UNKNOWN, "", (), 0, 0)


def _int_arg(value: Any, what: str, lo: int, hi: int) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or not lo <= value <= hi:
        raise CommandError(f"{what} must be a whole number {lo}..{hi}, not {value!r}")
    return value


class JoystickSlots:
    """The six slots of one DS (``slots``), their control-packet tags, and the robot's
    outputs for them (rumble and output bits, from its status packets)."""

    def __init__(self) -> None:
        self.slots: list[JoystickSlot | None] = [None] * MAX_JOYSTICKS
        self._wire: list[Joystick] = [EMPTY_JOYSTICK] * MAX_JOYSTICKS  # each slot's tag, kept encoded-ready
        self.outputs: list[rio_to_ds.JoystickOutput | None] = [None] * MAX_JOYSTICKS
        #: a slot was plugged or unplugged since the descriptors last went out
        self.descriptors_dirty = False

    @property
    def in_use(self) -> bool:
        return any(j is not None for j in self.slots)

    def view(self) -> JoystickView:
        return JoystickView(tuple(None if j is None else j.view() for j in self.slots), tuple(self.outputs),
                            self.in_use)

    # -- commands ---------------------------------------------------------------------------
    def set_joystick(self, slot: int, axes_count: int, button_count: int, pov_count: int, *, name: str = "",
                     is_xbox: bool = False, joystick_type: JoystickType | int = JoystickType.UNKNOWN,
                     axis_types: tuple[int, ...] | list[int] | None = None) -> None:
        _int_arg(slot, "joystick slot", 0, MAX_JOYSTICKS - 1)
        _int_arg(axes_count, "axis count", 0, MAX_AXES)
        _int_arg(button_count, "button count", 0, MAX_BUTTONS)
        _int_arg(pov_count, "POV count", 0, MAX_POVS)
        if not isinstance(name, str) or len(name.encode("utf-8", "surrogateescape")) > 255:
            raise CommandError("joystick name must be text of at most 255 bytes")
        _int_arg(joystick_type, "joystick type", -128, 127)
        types = tuple(axis_types) if axis_types is not None else tuple(min(i, 4) for i in range(axes_count))
        if len(types) != axes_count:
            raise CommandError(f"{len(types)} axis types given for {axes_count} axes")
        for t in types:
            _int_arg(t, "axis type", 0, 255)
        joy = JoystickSlot(name, bool(is_xbox), joystick_type, tuple(int(t) for t in types),
                           [0.0] * axes_count, button_count, [-1] * pov_count)
        self.slots[slot] = joy
        self._wire[slot] = joy.wire()
        self.descriptors_dirty = True

    def clear_joystick(self, slot: int) -> None:
        _int_arg(slot, "joystick slot", 0, MAX_JOYSTICKS - 1)
        if self.slots[slot] is not None:
            self.slots[slot] = None
            self._wire[slot] = EMPTY_JOYSTICK
            self.descriptors_dirty = True

    def is_empty(self, slot: Any) -> bool:
        """Whether no joystick is in ``slot`` (CommandError: no such slot)."""
        _int_arg(slot, "joystick slot", 0, MAX_JOYSTICKS - 1)
        return self.slots[slot] is None

    def _slot(self, slot: Any) -> JoystickSlot:
        _int_arg(slot, "joystick slot", 0, MAX_JOYSTICKS - 1)
        joy: JoystickSlot | None = self.slots[slot]
        if joy is None:
            raise CommandError(f"no joystick in slot {slot}")
        return joy

    def set_axis(self, slot: int, axis: int, value: float) -> None:
        joy = self._slot(slot)
        if not joy.axes:
            raise CommandError(f"the joystick in slot {slot} has no axes")
        _int_arg(axis, "axis", 0, len(joy.axes) - 1)
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) \
                or not -1.0 <= value <= 1.0:
            raise CommandError(f"axis value must be -1.0..1.0, not {value!r}")
        joy.axes[axis] = float(value)
        self._wire[slot] = joy.wire()

    def set_button(self, slot: int, button: int, pressed: bool) -> None:
        joy = self._slot(slot)
        if not joy.button_count:
            raise CommandError(f"the joystick in slot {slot} has no buttons")
        _int_arg(button, "button", 1, joy.button_count)
        if pressed not in (True, False, 0, 1) or isinstance(pressed, float):
            raise CommandError(f"pressed must be true or false, not {pressed!r}")
        bit = 1 << (button - 1)
        joy.buttons = joy.buttons | bit if pressed else joy.buttons & ~bit
        self._wire[slot] = joy.wire()

    def set_pov(self, slot: int, pov: int, degrees: int) -> None:
        joy = self._slot(slot)
        if not joy.povs:
            raise CommandError(f"the joystick in slot {slot} has no POVs")
        _int_arg(pov, "POV", 0, len(joy.povs) - 1)
        if isinstance(degrees, bool) or not isinstance(degrees, int) or not -1 <= degrees <= 359:
            raise CommandError(f"POV angle must be 0..359 or -1 (centred), not {degrees!r}")
        joy.povs[pov] = degrees
        self._wire[slot] = joy.wire()

    # -- what goes out, what comes back -----------------------------------------------------
    def tags(self, simulator: bool) -> tuple[Joystick, ...]:
        """The joystick tags of a control packet: slots 0 to the last one in use, an empty slot
        before it sent empty so slots keep their numbers. With no joystick, none: a real NI DS
        sent no joystick tag at all in 3,118 packets of the 2021 capture, one when a controller
        sat in slot 0 (e.g. frame 7366). To WPILib's simulator all six, each with at most one
        POV (roles/cores/ds.py's module docstring says why)."""
        if simulator:
            return tuple(j if len(j.povs) <= 1 else Joystick(j.axes, j.buttons, j.button_count, j.povs[:1])
                         for j in self._wire)
        used = [i for i, slot in enumerate(self.slots) if slot is not None]
        return tuple(self._wire[:used[-1] + 1]) if used else ()

    def resend_descriptors(self) -> None:
        """A new robot TCP connection: all six descriptors go out again."""
        self.descriptors_dirty = True

    def take_descriptors(self) -> list[JoystickDescriptor]:
        """All six descriptors, empty slots included, when a slot changed since last taken; else none."""
        if not self.descriptors_dirty:
            return []
        self.descriptors_dirty = False
        return [slot.descriptor(i) if slot else _empty_descriptor(i) for i, slot in enumerate(self.slots)]

    def take_outputs(self, tags: tuple[Any, ...]) -> None:
        """The robot's outputs from a status packet's tags, slot by slot (none: all cleared)."""
        outputs: list[rio_to_ds.JoystickOutput | None] = [t for t in tags if type(t) is rio_to_ds.JoystickOutput]
        del outputs[MAX_JOYSTICKS:]  # a 7th slot overwrites nothing
        self.outputs = outputs + [None] * (MAX_JOYSTICKS - len(outputs))
