"""The fake roboRIO's side of the robot program: which program runs, its code state (starting,
running, stuck, none), the 20 ms calls and what comes back: outputs, console lines, errors,
overruns.

The Rio owns the beat and decides when a call is offered; it never runs the program itself,
reads its file or waits for it. It asks through a :class:`ProgramHost` the runtime hands it
(roles/runtime/program_host.py): each ask is a typed :data:`ProgramRequest` (check this
program, start it, call it with this :class:`ControlState`, stop it) and the answer is the
:data:`ProgramEvent` values available at once (an inline program has run by then). A
program in a process of its own answers later: the runtime's shell reads its channel and
hands what came to :meth:`ProgramRunner.take` (``Rio.program_events``) before the core's
next event.

:class:`ProgramRunner` tells the Rio two things through the hooks the Rio hands it: ``emit``
(a console line, sent to the DS) and ``changed`` (the code state moved: the Rio applies
enable again).
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Callable, Protocol, Sequence

from .core import Events
from .robot_program import SLOTS, BuiltinProgram, ControlState, Program, ProgramError

if TYPE_CHECKING:
    from .rio import RioFaults

BEAT = 0.020  # the robot program's period (TimedRobot's default)
#: How often overruns of the program's 20 ms are reported (WPILib prints each loop's).
OVERRUN_REPORT = 1.0
#: How long a call (or the file's top level) may go without returning before the program is
#: reported as stuck.
STUCK_AFTER = 1.0

CODE_RUNNING = "running"
CODE_STARTING = "starting"
CODE_REBOOTING = "rebooting"
CODE_NONE = "no code"
CODE_STUCK = "stuck"  # the program's call has not returned for STUCK_AFTER: the robot still answers
CODE_ALIVE = (CODE_RUNNING, CODE_STUCK)


# -- which program --------------------------------------------------------------------------
@dataclass(frozen=True)
class ProgramSource:
    """Which program the code runs: a file (``path``), a Python callable or class
    (``program``: a class is made afresh at each code start) or the built-in one (neither).
    A file runs in a process of its own when ``isolate`` is set."""

    path: str | None = None
    program: Program | type[Any] | None = None
    isolate: bool = False

    @classmethod
    def of(cls, program: Program | type[Any] | str | os.PathLike[str] | None, isolate: bool) -> ProgramSource:
        if isinstance(program, (str, os.PathLike)):
            return cls(path=os.fspath(program), isolate=isolate)
        if program is not None and not callable(program):
            raise TypeError(f"program must be a path or a callable, not {program!r}")
        return cls(program=program, isolate=isolate)

    @property
    def name(self) -> str:
        if self.path is not None:
            return os.path.basename(self.path)
        if self.program is not None:
            return str(getattr(self.program, "__name__", type(self.program).__name__))
        return BuiltinProgram.name

    @property
    def apart(self) -> bool:
        """Whether the program runs in a process of its own."""
        return self.isolate and self.path is not None


# -- what the Rio asks of its host -----------------------------------------------------------
@dataclass(frozen=True, slots=True)
class CheckProgram:
    """Can ``source`` run? Answered by a :class:`LoadFailed` if not. ``keep``: a file checked by
    running its top level (not isolated) is kept, and the next start uses it (that top level
    runs once, as the program's constructor)."""

    source: ProgramSource
    keep: bool = False


@dataclass(frozen=True, slots=True)
class StartProgram:
    """Start fresh code from ``source`` (whatever ran before is stopped, its outputs off)."""

    source: ProgramSource


@dataclass(frozen=True, slots=True)
class CallProgram:
    """Call the program with this beat's ``state`` (and the 2010 DS's ``(digital, analog)``
    ``inputs``). Offered only when the last call has returned."""

    state: ControlState
    inputs: tuple[int, tuple[int, ...]]


@dataclass(frozen=True, slots=True)
class StopProgram:
    """The program stops where it is (a process is killed); its outputs go off."""


ProgramRequest = CheckProgram | StartProgram | CallProgram | StopProgram


# -- what comes back -------------------------------------------------------------------------
@dataclass(frozen=True, slots=True)
class ProgramOutputs:
    """What the program's outputs are, as the wire sends them (always valid)."""

    outputs: tuple[int, ...] = (0,) * SLOTS  # HID outputs per slot, bit n-1 = output n
    left_rumble: tuple[float, ...] = (0.0,) * SLOTS  # 0.0..1.0
    right_rumble: tuple[float, ...] = (0.0,) * SLOTS
    digital_out: int = 0  # 2010: the DS's eight digital outputs
    lcd: tuple[str, ...] | None = None  # 2010: six LCD lines once the program wrote one


NO_OUTPUTS = ProgramOutputs()


@dataclass(frozen=True, slots=True)
class Loading:
    """The program's process started; its file's top level runs (busy until Loaded)."""


@dataclass(frozen=True, slots=True)
class Loaded:
    """The program's top level ran: calls may start."""


@dataclass(frozen=True, slots=True)
class LoadFailed:
    text: str


@dataclass(frozen=True, slots=True)
class Message:
    kind: str  # "stdout", "warning" or "error"
    text: str
    code: int = 0
    location: str = ""
    call_stack: str = ""


@dataclass(frozen=True, slots=True)
class Result:
    """One call returned (or raised)."""

    took: float  # seconds the call ran, as measured where it ran
    outputs: ProgramOutputs
    problems: tuple[str, ...]  # what the host refused or clamped in the outputs
    error: tuple[str, str, str] | None  # (details, location, call stack) of what it raised
    dropped: int = 0  # console messages dropped by the per-window bound


@dataclass(frozen=True, slots=True)
class Ended:
    """The program's process is gone (``os._exit``, a crash, killed from outside)."""

    text: str


ProgramEvent = Loading | Loaded | LoadFailed | Message | Result | Ended


class ProgramHost(Protocol):
    """Where the program runs (roles/runtime/program_host.py): takes a request, returns what
    the program answered at once."""

    def __call__(self, request: ProgramRequest, now: float) -> Sequence[ProgramEvent]: ...


class ProgramRunner:
    """The robot program as the roboRIO runs it: code state, calls, results."""

    def __init__(self, source: ProgramSource, host: ProgramHost, *, restart_time: float, max_failures: int,
                 events: Events, faults: RioFaults, emit: Callable[..., None],
                 changed: Callable[[float], None]) -> None:
        self.source = source
        self.host = host
        self.restart_time = restart_time
        self.max_failures = max_failures
        self.events = events
        self.faults = faults
        self._emit = emit
        self._changed = changed
        self._running = False  # the host has code started (False: none, or stopped)
        self._stops = 0  # what a stopped code sent after it stopped is moot
        self._inbox: list[ProgramEvent] = []  # what a process sent, taken at the next advance
        self._now = 0.0
        self._fresh()

    def _fresh(self) -> None:
        """Everything a reboot forgets."""
        self.code_state = CODE_RUNNING
        self.program_out: ProgramOutputs = NO_OUTPUTS  # the program's outputs, as checked
        self.trace_mode: str | None = None  # the mode the program last ran in
        self.started_at = 0.0  # when the code last started: the program's clock counts from it
        self._ready_at: float | None = None  # a restart: when the code starts
        self._loaded = False  # the program's top level ran: calls may start
        self._busy_since: float | None = None  # a call (or the top level) under way since
        self._call_state: ControlState | None = None  # the state of the call under way
        self._stuck_since: float | None = None
        self._overruns = 0  # since the last report
        self._longest_ms = 0.0
        self._overrun_reported_at = float("-inf")
        self._problems_reported: set[str] = set()
        self._consecutive_failures = 0

    @property
    def name(self) -> str:
        return self.source.name

    @property
    def code_alive(self) -> bool:
        """Whether robot code runs (stuck included: it is there, it has not returned)."""
        return self.code_state in CODE_ALIVE

    @property
    def ready_for_call(self) -> bool:
        """Whether a call can be offered: code runs and its last call has returned."""
        return (self._running and self._loaded and self._busy_since is None
                and self.code_state in CODE_ALIVE)

    def deadline(self) -> float | None:
        """When the code starts after a restart, or when a call under way becomes stuck."""
        times = []
        if self.code_state == CODE_STARTING and self._ready_at is not None:
            times.append(self._ready_at)
        busy = self._busy_since
        if busy is not None and self._stuck_since is None:
            times.append(busy + STUCK_AFTER)
        if self._inbox:
            times.append(self._now)
        return min(times) if times else None

    def _ask(self, request: ProgramRequest, now: float) -> None:
        self._now = now
        self._take(self.host(request, now), now)

    # -- time ---------------------------------------------------------------------------
    def advance(self, now: float) -> None:
        """Start the code when a restart is over; take what the program did; see if it hangs."""
        self._now = now
        if self.code_state == CODE_STARTING and self._ready_at is not None and now >= self._ready_at:
            self.start(now)
        if self._inbox:
            events, self._inbox = self._inbox, []
            self._take(events, now)
        self._check_stuck(now)

    def check(self, source: ProgramSource, now: float, keep: bool = False) -> None:
        """Whether ``source`` can run (ProgramError, saying why, if not)."""
        for event in self.host(CheckProgram(source, keep), now):
            if type(event) is LoadFailed:
                raise ProgramError(event.text)
            if type(event) is Message:  # a file's top level printed while it was checked
                self._emit(event.kind, event.text, event.code, event.location, event.call_stack)

    def call(self, state: ControlState, inputs: tuple[int, tuple[int, ...]], now: float) -> None:
        """Offer the program this beat's ``state`` (and the 2010 DS's ``inputs``)."""
        if not self.ready_for_call:
            return
        self._call_state = state
        self._busy_since = now
        self._ask(CallProgram(state, inputs), now)  # an inline program has already run

    def receive(self, events: Sequence[ProgramEvent], now: float) -> None:
        """What the program's process sent (the shell read it), taken at the next advance:
        where the core would have read it itself, so the order of what follows is the same."""
        if self._running:
            self._inbox.extend(events)
            self._now = now

    def _take(self, events: Sequence[ProgramEvent], now: float) -> None:
        stops = self._stops
        for event in events:
            if self._stops != stops or not self._running:
                return  # the code stopped: what it sent after that is moot
            if type(event) is Message:
                self._emit(event.kind, event.text, event.code, event.location, event.call_stack)
            elif type(event) is Result:
                self._result(event, now)
            elif type(event) is Loading:
                self._busy_since = now  # its top level runs
                self.code_state = CODE_STARTING  # until it has run (Loaded)
                self.events.add(now, f"robot code loading ({self.name}) in a process of its own")
            elif type(event) is Loaded:
                self._loaded = True
                self._busy_since = None
                self.code_state = CODE_RUNNING
                self._stuck_since = None
                self.events.add(now, f"robot code running ({self.name})")
                self._changed(now)
            elif type(event) is LoadFailed:
                self._stop_code(now, f"robot code failed to start: {event.text}",
                                f"Robot code failed to start: {event.text}")
            elif type(event) is Ended:
                self._stop_code(now, f"robot code ended: {event.text}",
                                f"Robot code ended: {event.text}; restart the code to run it again")

    def _result(self, result: Result, now: float) -> None:
        self._busy_since = None
        state, self._call_state = self._call_state, None
        self.program_out = result.outputs
        for problem in result.problems:
            what = problem.split(" = ", 1)[0]
            if what not in self._problems_reported:  # once per output and code start
                self._problems_reported.add(what)
                self.faults.output_problems += 1
                self._emit("warning", f"robot program output not sent as written: {problem}", bounded=False)
        if result.took > BEAT:
            self.faults.program_overruns += 1
            self._overruns += 1
            self._longest_ms = max(self._longest_ms, result.took * 1000.0)
        self.faults.console_dropped += result.dropped
        if self._stuck_since is not None:
            text = f"robot program returned after {now - self._stuck_since:.1f} s stuck"
            self._stuck_since = None
            self.code_state = CODE_RUNNING if self.code_state == CODE_STUCK else self.code_state
            self.events.add(now, text)
            self._emit("warning", text, bounded=False)
        if result.error is not None:
            self._program_failed(result.error, now)
        else:
            self._consecutive_failures = 0
        if self.code_state == CODE_RUNNING and state is not None:  # what WPILib's HAL_ObserveUserProgram* report
            self.trace_mode = _mode_bits_label(state)

    def _check_stuck(self, now: float) -> None:
        busy = self._busy_since
        if busy is None or self._stuck_since is not None or now - busy < STUCK_AFTER:
            return
        self._stuck_since = busy
        if self.code_state == CODE_RUNNING:
            self.code_state = CODE_STUCK
            text = (f"robot program stuck: robot_periodic has not returned for {now - busy:.1f} s "
                    "(the robot still answers its DS; restart the code to stop it)")
        else:
            text = (f"robot program stuck: its file's top level has not finished for {now - busy:.1f} s "
                    "(restart the code to stop it)")
        self.events.add(now, text)
        self._emit("warning", text, bounded=False)

    def report_overruns(self, now: float) -> None:
        """At most once a second, as WPILib reports loop overruns (its "Loop time of 0.02s overrun")."""
        if not self._overruns or now - self._overrun_reported_at < OVERRUN_REPORT:
            return
        calls = "call" if self._overruns == 1 else "calls"
        self._emit("warning", f"Loop time of {BEAT:g}s overrun: {self._overruns} {calls} of robot_periodic "
                              f"took longer (the longest {self._longest_ms:.0f} ms)", bounded=False)
        self._overrun_reported_at = now
        self._overruns = 0
        self._longest_ms = 0.0

    def _program_failed(self, error: tuple[str, str, str], now: float) -> None:
        self.faults.program_errors += 1
        self._consecutive_failures += 1
        details, location, stack = error
        self._emit("error", details, code=1, location=location, call_stack=stack, bounded=False)
        if self._consecutive_failures >= self.max_failures:
            text = (f"Robot code stopped after {self._consecutive_failures} consecutive errors; "
                    "restart the code to run it again")
            self._stop_code(now, text, text)

    # -- code states --------------------------------------------------------------------
    def start(self, now: float) -> None:
        self.stop()
        self.trace_mode = None
        self._consecutive_failures = 0
        self.started_at = now
        self._ready_at = None
        self._problems_reported = set()
        self._running = True
        self._ask(StartProgram(self.source), now)  # inline: Loaded or LoadFailed, at once

    def stop(self) -> None:
        """The program stops where it is (a process is killed); its outputs go off."""
        self._stops += 1
        self._running = False
        self._loaded = False
        self._busy_since = None
        self._inbox = []
        self.host(StopProgram(), self._now)
        self.program_out = NO_OUTPUTS
        self._call_state = None
        self._stuck_since = None

    def _stop_code(self, now: float, event: str, console: str) -> None:
        self.stop()
        self.code_state = CODE_NONE
        self.trace_mode = None
        self.events.add(now, event)
        self._emit("error", console, code=1, bounded=False)
        self._changed(now)

    def restart(self, now: float, why: str) -> None:
        """The code restarts: "starting" for ``restart_time``, then a fresh program."""
        self.code_state = CODE_STARTING
        self._ready_at = now + self.restart_time
        self.stop()
        self.trace_mode = None
        self.events.add(now, f"robot code restarting: {why}")
        self._changed(now)

    def power_off(self) -> None:
        """The roboRIO reboots: the program stops with it."""
        self.code_state = CODE_REBOOTING
        self.stop()
        self.trace_mode = None

    def power_on(self, now: float) -> None:
        """The roboRIO is back: a fresh start, the code starting after ``restart_time``."""
        self._fresh()
        self.code_state = CODE_STARTING
        self._ready_at = now + self.restart_time


def _mode_bits_label(state: ControlState) -> str:
    if not state.enabled or state.mode not in ("teleop", "auto", "test"):
        return "disabled"
    return state.mode
