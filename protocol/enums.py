"""Enumerations shared by the wire formats."""

from __future__ import annotations

import enum
from typing import TypeVar

E = TypeVar("E", bound=enum.IntEnum)


class Mode(enum.IntEnum):
    """The 2-bit robot mode in every control and status byte (seeds: 0 teleop, 1 test, 2 auto)."""

    TELEOP = 0
    TEST = 1
    AUTONOMOUS = 2
    RESERVED = 3  # never sent by a real DS; decoded rather than refused

    @property
    def label(self) -> str:
        return {0: "teleop", 1: "test", 2: "auto", 3: "mode 3"}[self.value]

    @classmethod
    def parse(cls, text: str) -> "Mode":
        key = text.strip().lower()
        aliases = {"teleop": cls.TELEOP, "tele": cls.TELEOP, "test": cls.TEST,
                   "auto": cls.AUTONOMOUS, "autonomous": cls.AUTONOMOUS}
        if key not in aliases:
            raise ValueError(f"unknown mode {text!r}: use teleop, auto or test")
        return aliases[key]


#: The mode bits in the words every annotation uses (``Mode.label`` is the short form).
MODE_TEXT = {0: "teleop", 1: "test", 2: "autonomous", 3: "mode 3 (undefined)"}


class Alliance(enum.Enum):
    RED = "red"
    BLUE = "blue"


class AllianceStation(enum.IntEnum):
    """Alliance station byte: red 1-3 are 0-2, blue 1-3 are 3-5 (seed: ``value < 3`` is red)."""

    RED1 = 0
    RED2 = 1
    RED3 = 2
    BLUE1 = 3
    BLUE2 = 4
    BLUE3 = 5

    @property
    def alliance(self) -> Alliance:
        return Alliance.RED if self.value < 3 else Alliance.BLUE

    @property
    def position(self) -> int:
        return self.value % 3 + 1

    @property
    def label(self) -> str:
        return f"{'R' if self.value < 3 else 'B'}{self.position}"

    @classmethod
    def parse(cls, text: str) -> "AllianceStation":
        """``R1``..``B3`` (also ``red1``, ``blue 3``)."""
        key = text.strip().lower().replace(" ", "")
        for prefix, base in (("red", 0), ("blue", 3), ("r", 0), ("b", 0 + 3)):
            if key.startswith(prefix) and key[len(prefix):] in ("1", "2", "3"):
                return cls(base + int(key[len(prefix):]) - 1)
        raise ValueError(f"unknown station {text!r}: use R1, R2, R3, B1, B2 or B3")


class MatchType(enum.IntEnum):
    """Match type in the DS -> roboRIO match info frame (TCP 0x07)."""

    NONE = 0
    PRACTICE = 1
    QUALIFICATION = 2
    ELIMINATION = 3


class TournamentLevel(enum.IntEnum):
    """Tournament level in the FMS control packet."""

    MATCH_TEST = 0
    PRACTICE = 1
    QUALIFICATION = 2
    PLAYOFF = 3


class StationStatus(enum.IntEnum):
    """Station status in the FMS station info frame (TCP 0x19)."""

    GOOD = 0
    BAD = 1
    WAITING = 2


class JoystickType(enum.IntEnum):
    """Joystick type in the joystick descriptor (ds_to_rio seed table)."""

    UNKNOWN = -1
    XINPUT_UNKNOWN = 0
    XINPUT_GAMEPAD = 1
    XINPUT_WHEEL = 2
    XINPUT_ARCADE = 3
    XINPUT_FLIGHT_STICK = 4
    XINPUT_DANCE_PAD = 5
    XINPUT_GUITAR = 6
    XINPUT_GUITAR_2 = 7
    XINPUT_DRUM_KIT = 8
    XINPUT_GUITAR_3 = 11
    XINPUT_ARCADE_PAD = 19
    HID_JOYSTICK = 20
    HID_GAMEPAD = 21
    HID_DRIVING = 22
    HID_FLIGHT = 23
    HID_FIRST_PERSON = 24


class AxisType(enum.IntEnum):
    X = 0
    Y = 1
    Z = 2
    TWIST = 3
    THROTTLE = 4


class DeviceType(enum.IntEnum):
    """Device type in the roboRIO version info frame (TCP 0x0a)."""

    SOFTWARE = 0
    CAN_TALON = 2
    PDP = 8
    PCM = 9


def enum_or_int(cls: type[E], value: int) -> E | int:
    """``cls(value)`` when it is a member, else the plain int (decoders never refuse a value
    a real peer might send just because no document names it)."""
    try:
        return cls(value)
    except ValueError:
        return value
