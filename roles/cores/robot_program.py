"""The robot program the fake roboRIO runs: a Python hook called every 20 ms.

A class writes its own robot program as a plain ``.py`` file::

    def robot_periodic(state, robot):
        if state.enabled and state.joystick(0).button(1):
            robot.print("button 1 pressed at", round(state.time, 2))
            robot.set_rumble(0, left=1.0)

``state`` is a :class:`ControlState` (what the DS asked for, as the roboRIO applies it) and
``robot`` a :class:`RobotApi` (console, warnings and errors, joystick outputs and rumble).
The file's top level runs once each time the code starts (like a robot program's
constructor): module-level variables keep state between calls. Inside the file, ``print``
writes to the robot console (TCP 1740 to the DS), as ``System.out`` does on a real robot.

:func:`roles.runtime.program_host.load_program` loads such a file (the runtime reads and runs
files; this module only says what a program sees and does); :class:`BuiltinProgram` is the program that runs
when none is given: it reports mode changes and joystick readouts and echoes buttons to the
joystick outputs and rumble, so every DS feature has something to show.
"""

from __future__ import annotations

import math
import os
import sys
import traceback
from dataclasses import dataclass
from typing import Any, Callable

from protocol.ds_to_rio import MatchInfo

SLOTS = 6  # joystick slots, as on every DS
MAX_TEXT = 4000  # longest console line or error text sent; the frame allows ~64 KiB


# -- what the program sees ------------------------------------------------------------
@dataclass(frozen=True, slots=True)
class JoystickState:
    """One joystick slot as the robot program reads it (WPILib numbering: button 1 first)."""

    axes: tuple[float, ...] = ()  # -1.0..1.0
    buttons: int = 0  # bit 0 = button 1
    button_count: int = 0
    povs: tuple[int, ...] = ()  # degrees, -1 when centred
    name: str = ""  # from the DS's joystick descriptor, when it sent one

    def button(self, number: int) -> bool:
        """Whether button ``number`` (1-based) is down."""
        return 1 <= number <= self.button_count and bool(self.buttons >> (number - 1) & 1)

    def axis(self, index: int, default: float = 0.0) -> float:
        return self.axes[index] if 0 <= index < len(self.axes) else default

    def pov(self, index: int = 0) -> int:
        return self.povs[index] if 0 <= index < len(self.povs) else -1

    @property
    def pressed(self) -> tuple[int, ...]:
        return tuple(b + 1 for b in range(self.button_count) if self.buttons >> b & 1)

    @property
    def is_empty(self) -> bool:
        return not self.axes and not self.button_count and not self.povs

    def readout(self) -> str:
        """A one-line readout: ``axes +0.50 -0.25 buttons 1,3 pov 90``."""
        parts = []
        if self.axes:
            parts.append("axes " + " ".join(f"{a:+.2f}" for a in self.axes))
        if self.button_count:
            parts.append("buttons " + (",".join(map(str, self.pressed)) or "none"))
        if self.povs:
            parts.append("pov " + " ".join(str(p) for p in self.povs))
        return " ".join(parts) or "empty"


EMPTY_JOYSTICK_STATE = JoystickState()


@dataclass(frozen=True, slots=True)
class ControlState:
    """What the robot program sees each 20 ms."""

    time: float = 0.0  # seconds since the code started
    enabled: bool = False  # as the roboRIO applies it (watchdog, e-stop, code state)
    mode: str = "teleop"  # "teleop", "auto" or "test"
    estop: bool = False
    joysticks: tuple[JoystickState, ...] = ()  # slot order, as the DS sends them
    ds_attached: bool = False
    fms_attached: bool = False
    station: str = "R1"
    match_info: MatchInfo | None = None
    game_data: str = ""
    countdown: float | None = None  # seconds left in the match period, when the DS sends it
    battery: float = 0.0
    brownout: bool = False

    def joystick(self, slot: int) -> JoystickState:
        return self.joysticks[slot] if 0 <= slot < len(self.joysticks) else EMPTY_JOYSTICK_STATE


# -- what the program can do ----------------------------------------------------------
Emit = Callable[..., None]  # emit(kind, text, code=0, location="", call_stack="")


class RobotApi:
    """The robot program's handle on the roboRIO.

    ``print`` goes to the console (stdout frames on TCP 1740), ``warning``/``error`` to the
    DS's diagnostics (error frames), outputs and rumble to the joystick output tags of the
    next status packets. Bad arguments raise ValueError inside the program, where the
    roboRIO catches and reports them like any other exception.
    """

    def __init__(self, emit: Emit | None = None) -> None:
        self._emit = emit
        self.outputs = [0] * SLOTS  # bit n-1 = output n
        self.left_rumble = [0.0] * SLOTS  # 0.0..1.0
        self.right_rumble = [0.0] * SLOTS
        # the 2010 (cRIO) protocol only: the DS's I/O and LCD (the 2015+ protocol ignores them)
        self.ds_digital_in = 0  # the DS's eight digital inputs as last received, bit n-1 = input n
        self.ds_analog_in: tuple[int, ...] = (0, 0, 0, 0)  # the DS's analog inputs, 0..1023
        self.ds_digital_out = 0  # bit n-1 = DS digital output n
        self.lcd: list[str] | None = None  # six lines once the program wrote one

    def reset(self) -> None:
        """The code (re)starts: every output and rumble off."""
        self.outputs = [0] * SLOTS
        self.left_rumble = [0.0] * SLOTS
        self.right_rumble = [0.0] * SLOTS
        self.ds_digital_out = 0
        self.lcd = None

    # console and diagnostics
    def print(self, *values: Any, sep: str = " ", end: str = "\n") -> None:
        text = str(sep).join(str(v) for v in values) + str(end)
        self._send("stdout", text)

    def warning(self, text: str, code: int = 0) -> None:
        self._send("warning", str(text), code, _caller())

    def error(self, text: str, code: int = 1) -> None:
        self._send("error", str(text), code, _caller())

    def _send(self, kind: str, text: str, code: int = 0, location: str = "") -> None:
        if self._emit is not None:
            self._emit(kind, text, code=code, location=location)
        elif kind == "stdout":
            sys.stdout.write(text)

    # joystick outputs
    def set_outputs(self, slot: int, bits: int) -> None:
        """All 32 HID outputs of ``slot`` at once (bit n-1 = output n)."""
        _check_slot(slot)
        if isinstance(bits, bool) or not isinstance(bits, int) or not 0 <= bits <= 0xFFFFFFFF:
            raise ValueError(f"outputs must be an int 0..0xffffffff, not {bits!r}")
        self.outputs[slot] = bits

    def set_output(self, slot: int, number: int, on: bool = True) -> None:
        """HID output ``number`` (1..32) of ``slot`` on or off (``on``: a bool, or a number
        where 0 is off; None, NaN or text is refused, not read as off)."""
        _check_slot(slot)
        if isinstance(number, bool) or not isinstance(number, int) or not 1 <= number <= 32:
            raise ValueError(f"output number must be 1..32, not {number!r}")
        if not isinstance(on, (int, float)) or (isinstance(on, float) and math.isnan(on)):
            raise ValueError(f"output {number} of slot {slot} must be set True or False, not {on!r}")
        mask = 1 << (number - 1)
        self.outputs[slot] = self.outputs[slot] | mask if on else self.outputs[slot] & ~mask

    def set_rumble(self, slot: int, left: float | None = None, right: float | None = None) -> None:
        """Rumble of ``slot``, each side 0.0..1.0 (``None`` leaves that side as it is)."""
        _check_slot(slot)
        if left is not None:
            self.left_rumble[slot] = _check_rumble(left, "left")
        if right is not None:
            self.right_rumble[slot] = _check_rumble(right, "right")

    # the 2010 (cRIO) Driver Station: digital I/O and the LCD (--legacy-2010 only)
    def digital_in(self, number: int) -> bool:
        """DS digital input ``number`` (1..8), as the DS last sent it."""
        _check_number(number, "digital input", 8)
        return bool(self.ds_digital_in >> (number - 1) & 1)

    def analog_in(self, number: int) -> int:
        """DS analog input ``number`` (1..4), 0..1023."""
        _check_number(number, "analog input", 4)
        return self.ds_analog_in[number - 1]

    def set_digital_output(self, number: int, on: bool = True) -> None:
        """DS digital output ``number`` (1..8) on or off."""
        _check_number(number, "digital output", 8)
        mask = 1 << (number - 1)
        self.ds_digital_out = self.ds_digital_out | mask if on else self.ds_digital_out & ~mask

    def set_digital_outputs(self, bits: int) -> None:
        """All eight DS digital outputs at once (bit n-1 = output n)."""
        if isinstance(bits, bool) or not isinstance(bits, int) or not 0 <= bits <= 0xFF:
            raise ValueError(f"digital outputs must be an int 0..0xff, not {bits!r}")
        self.ds_digital_out = bits

    def set_lcd(self, line: int, text: str) -> None:
        """DS LCD line ``line`` (1..6): 21 ASCII characters (longer text is cut, others become ?)."""
        _check_number(line, "LCD line", 6)
        text = str(text)[:21]
        if not (text.isascii() and text.isprintable()):
            text = "".join(c if " " <= c <= "~" else "?" for c in text)
        if self.lcd is None:
            self.lcd = [""] * 6
        self.lcd[line - 1] = text


def _check_slot(slot: int) -> None:
    if isinstance(slot, bool) or not isinstance(slot, int) or not 0 <= slot < SLOTS:
        raise ValueError(f"joystick slot must be 0..{SLOTS - 1}, not {slot!r}")


def _check_number(number: int, what: str, top: int) -> None:
    if isinstance(number, bool) or not isinstance(number, int) or not 1 <= number <= top:
        raise ValueError(f"{what} must be 1..{top}, not {number!r}")


def _check_rumble(value: float, side: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not 0.0 <= value <= 1.0:
        raise ValueError(f"{side} rumble must be 0.0..1.0, not {value!r}")
    return float(value)


def _caller() -> str:
    """``file:line`` of the robot program line that called warning()/error()."""
    frame = sys._getframe(2)
    return f"{os.path.basename(frame.f_code.co_filename)}:{frame.f_lineno}"


Program = Callable[[ControlState, RobotApi], Any]


class ProgramError(ValueError):
    """A robot program file that cannot be used; the message says why and where (files are
    read and run by roles/runtime/program_host.py, never here)."""


def describe_exception(exc: BaseException) -> tuple[str, str, str]:
    """``(details, location, call stack)`` of an exception raised inside the program."""
    frames = traceback.extract_tb(exc.__traceback__)
    location = f"{os.path.basename(frames[-1].filename)}:{frames[-1].lineno}" if frames else ""
    details = f"Unhandled exception in the robot program: {type(exc).__name__}: {exc}"
    stack = "".join(traceback.format_exception(type(exc), exc, exc.__traceback__))
    return details[:MAX_TEXT], location[:MAX_TEXT], stack[-MAX_TEXT:]


# -- the built-in program -------------------------------------------------------------
class BuiltinProgram:
    """What the fake roboRIO runs when no program is given.

    * prints "Robot program started", then each mode change ("Robot enabled in teleop",
      "Robot disabled", "Robot e-stopped") and new game data;
    * prints each joystick's readout when it changes, at most every ``readout_interval``
      seconds per slot (the latest value is printed once the interval has passed);
    * echoes buttons: button n -> HID output n of the same slot, button 1 -> left rumble,
      button 2 -> right rumble.
    """

    name = "built-in"

    def __init__(self, readout_interval: float = 0.5) -> None:
        self.readout_interval = readout_interval
        self._started = False
        self._mode: str | None = None
        self._game_data = ""
        self._readouts: dict[int, str] = {}
        self._read: dict[int, JoystickState] = {}
        self._printed_at: dict[int, float] = {}

    def __call__(self, state: ControlState, robot: RobotApi) -> None:
        if not self._started:
            self._started = True
            robot.print("Robot program started (fieldbox built-in program)")
        mode = ("e-stopped" if state.estop else f"enabled in {state.mode}" if state.enabled
                else "disabled")
        if mode != self._mode:
            self._mode = mode
            robot.print(f"Robot {mode}")
        if state.game_data != self._game_data:
            self._game_data = state.game_data
            robot.print(f"Game data: {state.game_data!r}")
        for slot, joy in enumerate(state.joysticks[:SLOTS]):
            robot.set_outputs(slot, joy.buttons & 0xFFFFFFFF)
            robot.set_rumble(slot, left=1.0 if joy.button(1) else 0.0,
                             right=1.0 if joy.button(2) else 0.0)
            if (joy.is_empty or joy == self._read.get(slot)
                    or state.time - self._printed_at.get(slot, float("-inf")) < self.readout_interval):
                continue
            self._read[slot] = joy
            text = joy.readout()
            if text != self._readouts.get(slot):  # moves too small to show are not news
                self._readouts[slot] = text
                self._printed_at[slot] = state.time
                robot.print(f"Joystick {slot}: {text}")
