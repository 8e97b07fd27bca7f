"""What a joystick slot is and what it reads, whichever source fills it (the keyboard
joystick or an SDL device): the DS's :class:`Descriptor` and the live :class:`Reading`."""

from __future__ import annotations

import math
from dataclasses import dataclass

SLOTS = 6
MAX_AXES = 12
MAX_BUTTONS = 32
MAX_POVS = 12

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

