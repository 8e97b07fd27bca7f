"""The command language: one command per line, as the headless mode reads stdin and a
script (fieldbox/script.py) reads its file.

:func:`parse` turns a line into the same typed command a key builds (roles/cores/commands.py),
or one of the language's own words (``quit``, ``help``, ``status``) and test steps (``sleep``,
``wait``, ``expect``), which the headless mode and the script runner carry out themselves.
Pure parsing, so every command and every refusal is testable without a field. Joystick slots
and axes count from 0 (as WPILib numbers joystick ports and axes), buttons from 1 (as WPILib
numbers buttons), POVs from 0.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from typing import ClassVar

from protocol.enums import AllianceStation
from roles.cores.commands import (Bypass, Command, Disable, Enable, EStop, Fault, MatchControl, Practice,
                                  RebootRoboRIO, RestartCode, SetAxis, SetBattery, SetButton, SetMode, SetPov,
                                  StationAStop, StationEStop)
from roles.sim.faults import FaultSpecError, parse_fault

HELP = """\
commands (one per line; prefix with @TEAM to pick a team on a field, e.g. '@254 enable'):
  enable | disable | estop              the DS's enable, disable and (latched) e-stop
  mode teleop|auto|test                 robot mode
  axis J A VALUE                        joystick J (0-5), axis A (0-11), VALUE -1.0..1.0
  button J B 0|1                        joystick J, button B (1-32) up or down
  pov J P DEGREES                       joystick J, POV P (0-11), 0-359 or -1 (centred)
  restart | reboot                      restart robot code | reboot the roboRIO
  practice start|stop                   a practice match run by the DS
  match start|abort|next                the FMS's match
  bypass|estop|astop STATION [on|off]   FMS per-station controls (R1..B3)
  battery VOLTS                         the fake roboRIO's battery
  fault LINK:SETTINGS                   faults on purpose, e.g. fault ds-rio:loss=10%,delay=30ms~10ms
                                        (links ds-rio, ds-rio-tcp, ds-fms, ds-fms-tcp, all; settings
                                        loss, delay=D~J, dup, reorder, corrupt, cut, uncut, clear)
  fault                                 list the faults and what they did
  status                                print the status line now
  help | quit
test steps (fieldbox run SCRIPT, or here; each waits, and fails if the time runs out):
  sleep S                               let S seconds pass
  wait comms|code|enabled|disabled [S]  until the DS's robot is so (default 10 s)
  expect console REGEX within S         a robot console line matching REGEX (a line since the
                                        last console expectation; with --launch, the launched
                                        program's output too)
  expect robot mode auto|teleop|test|disabled within S   what the robot reports it runs
  expect battery >|>=|<|<= VOLTS [within S]             the robot's battery voltage"""


class CommandSyntaxError(ValueError):
    """A line that is not a command; the message says what is wrong."""


#: How long a ``wait`` waits when no time is given.
WAIT_DEFAULT = 10.0
#: The longest a test step may wait (a script is a test, not a service).
MAX_WAIT = 3600.0
ROBOT_MODES = ("auto", "teleop", "test", "disabled")
COMPARISONS = (">=", "<=", ">", "<")




# -- the language's own words: what the headless mode and a script do, not the field ------------
@dataclass(frozen=True)
class Quit(Command):
    verb: ClassVar[str] = "quit"


@dataclass(frozen=True)
class Help(Command):
    verb: ClassVar[str] = "help"


@dataclass(frozen=True)
class Status(Command):
    verb: ClassVar[str] = "status"


@dataclass(frozen=True)
class Sleep(Command):
    verb: ClassVar[str] = "sleep"
    seconds: float


@dataclass(frozen=True)
class Wait(Command):
    verb: ClassVar[str] = "wait"
    what: str  # "comms", "code", "enabled" or "disabled"
    timeout: float = 10.0


@dataclass(frozen=True)
class ExpectConsole(Command):
    verb: ClassVar[str] = "expect"
    pattern: str
    within: float = 0.0


@dataclass(frozen=True)
class ExpectRobotMode(Command):
    verb: ClassVar[str] = "expect"
    mode: str
    within: float = 0.0


@dataclass(frozen=True)
class ExpectBattery(Command):
    verb: ClassVar[str] = "expect"
    op: str
    volts: float
    within: float = 0.0


#: The commands that name no field of their own, by word.
SIMPLE: dict[str, type[Command]] = {c.verb: c for c in (Enable, Disable, EStop, RestartCode, RebootRoboRIO,
                                                        Quit, Help, Status)}


def _int(text: str, what: str, lo: int, hi: int) -> int:
    try:
        value = int(text)
    except ValueError:
        raise CommandSyntaxError(f"{what} must be a whole number, not {text!r}") from None
    if not lo <= value <= hi:
        raise CommandSyntaxError(f"{what} must be {lo}..{hi}, not {value}")
    return value


def _float(text: str, what: str, lo: float, hi: float) -> float:
    try:
        value = float(text)
    except ValueError:
        raise CommandSyntaxError(f"{what} must be a number, not {text!r}") from None
    if not math.isfinite(value) or not lo <= value <= hi:
        raise CommandSyntaxError(f"{what} must be {lo:g}..{hi:g}, not {text}")
    return value


def _arity(words: list[str], n: int, usage: str) -> None:
    if len(words) != n:
        raise CommandSyntaxError(f"usage: {usage}")


def parse(line: str) -> Command | None:
    """A command, or None for a blank line or a comment. Raises CommandSyntaxError."""
    words = line.split("#", 1)[0].split()
    if not words:
        return None
    team = None
    if words[0].startswith("@"):
        team = _int(words[0][1:], "team", 1, 25599)
        words = words[1:]
        if not words:
            raise CommandSyntaxError("a team selector needs a command after it")
    verb, rest = words[0].lower(), words[1:]
    if verb in ("enable", "disable", "estop", "restart", "reboot", "quit", "exit", "help", "status") \
            and not rest:
        return SIMPLE["quit" if verb == "exit" else verb](team=team)
    if verb == "mode":
        _arity(words, 2, "mode teleop|auto|test")
        key = rest[0].lower()
        modes = {"teleop": "teleop", "tele": "teleop", "auto": "auto", "autonomous": "auto", "test": "test"}
        if key not in modes:
            raise CommandSyntaxError(f"unknown mode {rest[0]!r}: use teleop, auto or test")
        return SetMode(modes[key], team=team)
    if verb == "axis":
        _arity(words, 4, "axis J A VALUE (J 0-5, A 0-11, VALUE -1.0..1.0)")
        return SetAxis(_int(rest[0], "joystick", 0, 5), _int(rest[1], "axis", 0, 11),
                       _float(rest[2], "axis value", -1.0, 1.0), team=team)
    if verb == "button":
        _arity(words, 4, "button J B 0|1 (J 0-5, B 1-32)")
        if rest[2] not in ("0", "1"):
            raise CommandSyntaxError(f"button state must be 0 or 1, not {rest[2]!r}")
        return SetButton(_int(rest[0], "joystick", 0, 5), _int(rest[1], "button", 1, 32), rest[2] == "1",
                         team=team)
    if verb == "pov":
        _arity(words, 4, "pov J P DEGREES (J 0-5, P 0-11, DEGREES 0-359 or -1)")
        return SetPov(_int(rest[0], "joystick", 0, 5), _int(rest[1], "pov", 0, 11),
                      _int(rest[2], "POV angle", -1, 359), team=team)
    if verb in ("practice", "match"):
        choices = ("start", "stop") if verb == "practice" else ("start", "abort", "next")
        _arity(words, 2, f"{verb} {'|'.join(choices)}")
        if rest[0].lower() not in choices:
            raise CommandSyntaxError(f"usage: {verb} {'|'.join(choices)}")
        return (Practice if verb == "practice" else MatchControl)(rest[0].lower(), team=team)
    if verb in ("bypass", "astop") or (verb == "estop" and rest):
        if not 1 <= len(rest) <= 2:
            raise CommandSyntaxError(f"usage: {verb} STATION [on|off]")
        try:
            station = AllianceStation.parse(rest[0])
        except ValueError as exc:
            raise CommandSyntaxError(str(exc)) from None
        on = True
        if len(rest) == 2:
            if rest[1].lower() not in ("on", "off", "1", "0"):
                raise CommandSyntaxError(f"use on or off, not {rest[1]!r}")
            on = rest[1].lower() in ("on", "1")
        kind = {"bypass": Bypass, "estop": StationEStop, "astop": StationAStop}[verb]
        return kind(station, on, team=team)
    if verb in ("sleep", "wait", "expect"):
        return _test_step(verb, rest, line, team)
    if verb == "battery":
        _arity(words, 2, "battery VOLTS")
        return SetBattery(_float(rest[0], "battery voltage", 0.0, 16.0), team=team)
    if verb in ("fault", "faults"):
        if not rest:
            return Fault(team=team)
        spec = "".join(rest)
        try:
            parse_fault(spec)  # said now, in the language's words, not when the field applies it
        except FaultSpecError as exc:
            raise CommandSyntaxError(str(exc)) from None
        return Fault(spec, team=team)
    raise CommandSyntaxError(f"unknown command {' '.join(words)!r}; type 'help' for the list")


def _test_step(verb: str, rest: list[str], line: str, team: int | None) -> Command:
    """``sleep``, ``wait`` and ``expect``: the steps that make a script a test."""
    if verb == "sleep":
        if len(rest) != 1:
            raise CommandSyntaxError("usage: sleep SECONDS")
        return Sleep(_float(rest[0], "sleep seconds", 0.0, MAX_WAIT), team=team)
    if verb == "wait":
        waits = ("comms", "code", "enabled", "disabled")
        if not 1 <= len(rest) <= 2 or rest[0].lower() not in waits:
            raise CommandSyntaxError(f"usage: wait {'|'.join(waits)} [SECONDS]")
        timeout = _float(rest[1], "wait seconds", 0.0, MAX_WAIT) if len(rest) == 2 else WAIT_DEFAULT
        return Wait(rest[0].lower(), timeout, team=team)
    if not rest:
        raise CommandSyntaxError("usage: expect console REGEX within S | expect robot mode MODE within S | "
                                 "expect battery > VOLTS [within S]")
    what = rest[0].lower()
    within = 0.0
    timed = len(rest) >= 3 and rest[-2].lower() == "within"
    if timed:
        within = _float(rest[-1], "within seconds", 0.0, MAX_WAIT)
        rest = rest[:-2]
    if what == "console":
        # the pattern is the line's own text between "console" and "within" (spaces kept)
        text = line.split("#", 1)[0]
        start = text.lower().index("console") + len("console")
        end = text.lower().rindex("within") if timed else len(text)
        pattern = text[start:end].strip()
        if not pattern:
            raise CommandSyntaxError("usage: expect console REGEX within SECONDS")
        try:
            re.compile(pattern)
        except re.error as exc:
            raise CommandSyntaxError(f"not a regular expression: {pattern!r}: {exc}") from None
        return ExpectConsole(pattern, within, team=team)
    if what == "robot":
        if len(rest) != 3 or rest[1].lower() != "mode" or rest[2].lower() not in ROBOT_MODES:
            raise CommandSyntaxError(f"usage: expect robot mode {'|'.join(ROBOT_MODES)} within SECONDS")
        return ExpectRobotMode(rest[2].lower(), within, team=team)
    if what == "battery":
        if len(rest) != 3 or rest[1] not in COMPARISONS:
            raise CommandSyntaxError("usage: expect battery >|>=|<|<= VOLTS [within SECONDS]")
        return ExpectBattery(rest[1], _float(rest[2], "battery voltage", 0.0, 30.0), within, team=team)
    raise CommandSyntaxError(f"cannot expect {rest[0]!r}: console, robot mode or battery")
