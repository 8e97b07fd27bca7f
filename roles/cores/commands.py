"""Commands: one typed, frozen value per change a person can make to the field.

A command is the only way in, whatever asks: a key or a panel's button (fieldbox/app.py and
fieldbox/panels/ build them directly), a line of the command language (fieldbox/language.py
parses text into them), a script, a classroom's seat (roles/runtime/classroom.py: a driver's
commands act on its own station only). :meth:`roles.runtime.field.Field.execute` carries each
out against the right core, and a refusal is a :class:`~roles.cores.core.CommandError` saying
why (nothing changed). Being plain frozen values, they cross to a wire in another process
pickled, and nothing else does.

Joystick slots and axes count from 0 (as WPILib numbers joystick ports and axes), buttons
from 1 (as WPILib numbers buttons), POVs from 0.
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields
from typing import ClassVar

from protocol.enums import AllianceStation, TournamentLevel


@dataclass(frozen=True, kw_only=True)
class Command:
    """A command: a typed value (``Enable``, ``SetAxis``...), the same from a key, the command
    language or a script. ``verb`` names its kind (the language's word where it has one);
    ``args`` is its own fields, in order."""

    verb: ClassVar[str] = ""
    #: The team whose station it acts on (None: the field's first, or the field itself).
    team: int | None = None
    #: When a person asked for it (the wire's clock), where a wire that did not answer at
    #: once could carry it out late: an enable that waited too long is refused.
    issued: float | None = field(default=None, compare=False)

    @property
    def args(self) -> tuple[object, ...]:
        return tuple(getattr(self, f.name) for f in fields(self) if f.name not in ("team", "issued"))


# -- the Driver Station's -----------------------------------------------------------------------
@dataclass(frozen=True)
class Enable(Command):
    verb: ClassVar[str] = "enable"


@dataclass(frozen=True)
class Disable(Command):
    verb: ClassVar[str] = "disable"


@dataclass(frozen=True)
class EStop(Command):
    verb: ClassVar[str] = "estop"


@dataclass(frozen=True)
class RestartCode(Command):
    verb: ClassVar[str] = "restart"


@dataclass(frozen=True)
class RebootRoboRIO(Command):
    verb: ClassVar[str] = "reboot"


@dataclass(frozen=True)
class SetMode(Command):
    verb: ClassVar[str] = "mode"
    mode: str  # "teleop", "auto" or "test"


@dataclass(frozen=True)
class SetAxis(Command):
    verb: ClassVar[str] = "axis"
    joystick: int
    axis: int
    value: float


@dataclass(frozen=True)
class SetButton(Command):
    verb: ClassVar[str] = "button"
    joystick: int
    button: int
    down: bool


@dataclass(frozen=True)
class SetPov(Command):
    verb: ClassVar[str] = "pov"
    joystick: int
    pov: int
    degrees: int


@dataclass(frozen=True)
class DeclareJoystick(Command):
    """A joystick plugged into ``slot``: what the DS declares for it (its values neutral)."""

    verb: ClassVar[str] = "joystick"
    slot: int
    name: str
    axes: int
    buttons: int
    povs: int
    is_xbox: bool = False
    joystick_type: int = -1  # unknown


@dataclass(frozen=True)
class ClearJoystick(Command):
    """The joystick in ``slot`` unplugged."""

    verb: ClassVar[str] = "unplug"
    slot: int


#: What one :class:`UpdateJoysticks` may change (their own ``team`` is not read: the update's is).
JoystickChange = DeclareJoystick | ClearJoystick | SetAxis | SetButton | SetPov


@dataclass(frozen=True)
class UpdateJoysticks(Command):
    """Every change to one DS's joysticks since the last poll (fieldbox/joystick_input), in
    order, carried out in one go. Unlike ``axis`` in the language, a value for an empty slot
    is refused: the joystick tab declares what it sends first."""

    verb: ClassVar[str] = "joysticks"
    changes: tuple[JoystickChange, ...]


@dataclass(frozen=True)
class Practice(Command):
    verb: ClassVar[str] = "practice"
    action: str  # "start" or "stop"


@dataclass(frozen=True)
class SetPracticeTiming(Command):
    """The DS's practice match phases, in seconds (None: keep that one), for its next
    practice run."""

    verb: ClassVar[str] = "practice-timing"
    countdown: float | None = None
    auto: float | None = None
    pause: float | None = None
    teleop: float | None = None


@dataclass(frozen=True)
class SetGameData(Command):
    """The DS's local game data (an FMS's replaces it)."""

    verb: ClassVar[str] = "game-data"
    text: str


@dataclass(frozen=True)
class ToggleDigitalInput(Command):
    """A 2010 DS's digital input ``number`` (1..8) flipped."""

    verb: ClassVar[str] = "digital-input"
    number: int


@dataclass(frozen=True)
class SetAnalogInput(Command):
    """A 2010 DS's analog input ``number`` (1..4) set to ``value`` (0..1023)."""

    verb: ClassVar[str] = "analog-input"
    number: int
    value: int


@dataclass(frozen=True)
class KeepRoundTrips(Command):
    """The DS keeps its last ``samples`` round-trip times, the ones before forgotten (its
    panel shows 256; a benchmark keeps a whole run's)."""

    verb: ClassVar[str] = "keep-trips"
    samples: int


# -- the fake roboRIO's -------------------------------------------------------------------------
@dataclass(frozen=True)
class SetBattery(Command):
    verb: ClassVar[str] = "battery"
    volts: float


# -- the FMS's ----------------------------------------------------------------------------------
@dataclass(frozen=True)
class MatchControl(Command):
    verb: ClassVar[str] = "match"
    action: str  # "start", "abort" or "next"


@dataclass(frozen=True)
class ReplayMatch(Command):
    """Back to pre-match with the same match (after a played one, the play number goes up);
    every e-stop and a-stop cleared. Not while a match runs."""

    verb: ClassVar[str] = "replay"


@dataclass(frozen=True)
class SetUpMatch(Command):
    """A new match in pre-match: ``number`` (None: the next) at ``level`` (None: the same)."""

    verb: ClassVar[str] = "set-up-match"
    level: TournamentLevel | None = None
    number: int | None = None


@dataclass(frozen=True)
class SetMatchTiming(Command):
    """New period lengths in seconds (None: keep that one), for the next match that starts."""

    verb: ClassVar[str] = "timing"
    auto: float | None = None
    pause: float | None = None
    teleop: float | None = None


@dataclass(frozen=True)
class Bypass(Command):
    verb: ClassVar[str] = "fms-bypass"
    station: AllianceStation
    on: bool = True


@dataclass(frozen=True)
class StationEStop(Command):
    verb: ClassVar[str] = "fms-estop"
    station: AllianceStation
    on: bool = True


@dataclass(frozen=True)
class StationAStop(Command):
    verb: ClassVar[str] = "fms-astop"
    station: AllianceStation
    on: bool = True


# -- the field's ------------------------------------------------------------------------------
@dataclass(frozen=True)
class Fault(Command):
    verb: ClassVar[str] = "fault"
    #: A fault spec (roles/sim/faults.py's language, e.g. ``ds-rio:loss=10%``); None lists the faults.
    spec: str | None = None

    @property
    def args(self) -> tuple[object, ...]:
        return () if self.spec is None else (self.spec,)


#: The FMS's commands (they act on the FMS, not a station's DS; a classroom's teacher's alone).
FMS_COMMANDS = (MatchControl, ReplayMatch, SetUpMatch, SetMatchTiming, Bypass, StationEStop, StationAStop)
