"""The keyboard joystick: a 6-axis, 12-button, 1-POV gamepad driven by key presses, for
terminals (over SSH too). Terminals send no key-up events, so axes either *spring* or
*step*, and buttons either *pulse* or *toggle* (see :class:`KeyboardJoystick`)."""

from __future__ import annotations

import math

from .descriptor import Descriptor, Reading

KEYBOARD_NAME = "fieldbox keyboard"

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
