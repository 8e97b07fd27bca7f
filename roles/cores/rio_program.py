"""The fake roboRIO's side of the robot program: which program runs, its code state (starting,
running, stuck, none), the 20 ms calls through a host (roles/runtime/program_host.py) and what
comes back: outputs, console lines, errors, overruns.

The Rio owns the beat and decides when a call is offered; :class:`ProgramRunner` never sees the
network. It tells the Rio two things through the hooks the Rio hands it: ``emit`` (a console
line, sent to the DS) and ``changed`` (the code state moved: the Rio applies enable again).
"""

from __future__ import annotations

import os
from functools import partial
from typing import TYPE_CHECKING, Any, Callable

from ..runtime.program_host import (NO_OUTPUTS, STUCK_AFTER, Ended, InlineHost, LoadFailed, Loaded, Message,
                                    ProcessHost, ProgramOutputs, Result, check_program)
from .core import Events
from .robot_program import BuiltinProgram, ControlState, Program, RobotApi, load_program

if TYPE_CHECKING:
    from .rio import RioFaults

BEAT = 0.020  # the robot program's period (TimedRobot's default)
#: How often overruns of the program's 20 ms are reported (WPILib prints each loop's).
OVERRUN_REPORT = 1.0

CODE_RUNNING = "running"
CODE_STARTING = "starting"
CODE_REBOOTING = "rebooting"
CODE_NONE = "no code"
CODE_STUCK = "stuck"  # the program's call has not returned for STUCK_AFTER: the robot still answers
CODE_ALIVE = (CODE_RUNNING, CODE_STUCK)


class ProgramSource:
    """Which program the code runs: a file, a Python callable or the built-in one. A factory,
    so each code start gets a fresh program. A file runs in a process of its own when
    ``isolate`` is set; otherwise its top level runs here once, to check it."""

    # a class for ``program``: an instance made afresh at each code start
    def __init__(self, program: Program | type[Any] | str | os.PathLike[str] | None, *, isolate: bool,
                 console: Callable[..., None]) -> None:
        self.isolate = isolate
        self.path: str | None = None
        self._callable: Program | type[Any] | None = None
        self._preloaded: Program | None = None
        self.name = BuiltinProgram.name
        if isinstance(program, (str, os.PathLike)):
            self.path = os.fspath(program)
            if isolate:  # its top level runs in its own process, never here
                check_program(self.path)  # ProgramError
            else:
                self._preloaded = load_program(self.path, console=console)  # ProgramError
            self.name = os.path.basename(self.path)
        elif program is not None:
            if not callable(program):
                raise TypeError(f"program must be a path or a callable, not {program!r}")
            self._callable = program
            self.name = getattr(program, "__name__", type(program).__name__)

    @property
    def apart(self) -> bool:
        """Whether the program runs in a process of its own."""
        return self.isolate and self.path is not None

    def use_file(self, path: str | os.PathLike[str], console: Callable[..., None]) -> None:
        """The file at ``path`` from the next code start (ProgramError, and nothing changes,
        if it cannot run: isolated, only what can be checked without running it)."""
        check_program(path) if self.isolate else load_program(path, console=console)
        self.path = os.fspath(path)
        self._callable = None
        self._preloaded = None
        self.name = os.path.basename(self.path)

    def use_builtin(self) -> None:
        self.path = None
        self._callable = None
        self._preloaded = None
        self.name = BuiltinProgram.name

    def make(self, console: Callable[..., None]) -> Program:
        if self._preloaded is not None:
            program, self._preloaded = self._preloaded, None
            return program
        if self.path is not None:
            return load_program(self.path, console=console)
        if isinstance(self._callable, type):
            fresh: Program = self._callable()  # a class: a fresh instance each time the code starts
            return fresh
        if self._callable is not None:
            return self._callable
        return BuiltinProgram()


class ProgramRunner:
    """The robot program as the roboRIO runs it: code state, calls, results."""

    def __init__(self, source: ProgramSource, robot: RobotApi, *, restart_time: float, max_failures: int,
                 events: Events, faults: RioFaults, emit: Callable[..., None],
                 changed: Callable[[float], None]) -> None:
        self.source = source
        self.robot = robot
        self.restart_time = restart_time
        self.max_failures = max_failures
        self.events = events
        self.faults = faults
        self._emit = emit
        self._changed = changed
        self._host: InlineHost | ProcessHost | None = None
        self._fresh()

    def _fresh(self) -> None:
        """Everything a reboot forgets."""
        self.code_state = CODE_RUNNING
        self.program_out: ProgramOutputs = NO_OUTPUTS  # the program's outputs, as checked
        self.trace_mode: str | None = None  # the mode the program last ran in
        self.started_at = 0.0  # when the code last started: the program's clock counts from it
        self._ready_at: float | None = None  # a restart: when the code starts
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
    def host(self) -> InlineHost | ProcessHost | None:
        """Where the program runs now (None: no code)."""
        return self._host

    @property
    def ready_for_call(self) -> bool:
        """Whether a call can be offered: code runs and its last call has returned."""
        return self._host is not None and self.code_state in CODE_ALIVE and self._host.idle

    def deadline(self) -> float | None:
        """When the code starts after a restart, or when a call under way becomes stuck."""
        times = []
        if self.code_state == CODE_STARTING and self._ready_at is not None:
            times.append(self._ready_at)
        busy = self._host.busy_since if self._host is not None else None
        if busy is not None and self._stuck_since is None:
            times.append(busy + STUCK_AFTER)
        return min(times) if times else None

    # -- time ---------------------------------------------------------------------------
    def advance(self, now: float) -> None:
        """Start the code when a restart is over; take what the program did; see if it hangs."""
        if self.code_state == CODE_STARTING and self._ready_at is not None and now >= self._ready_at:
            self.start(now)
        self.collect(now)
        self._check_stuck(now)

    def call(self, state: ControlState, inputs: tuple[int, tuple[int, ...]], now: float) -> None:
        """Offer the program this beat's ``state`` (and the 2010 DS's ``inputs``)."""
        if self._host is not None and self._host.offer(state, inputs, now):
            self._call_state = state
            self.collect(now)  # an inline program has already run

    def collect(self, now: float) -> None:
        host = self._host
        if host is None:
            return
        for event in host.collect(now):
            if type(event) is Message:
                self._emit(event.kind, event.text, event.code, event.location, event.call_stack)
            elif type(event) is Result:
                self._result(event, now)
            elif type(event) is Loaded:
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
            if self._host is not host:
                return  # the code stopped: what it sent after that is moot

    def _result(self, result: Result, now: float) -> None:
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
        busy = self._host.busy_since if self._host is not None else None
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
        if self.source.apart:
            assert self.source.path is not None  # apart: a file, in a process of its own
            try:
                self._host = ProcessHost(self.source.path, now)
            except OSError as exc:
                self._stop_code(now, f"robot code failed to start: {exc}",
                                f"Robot code failed to start: cannot start its process: {exc.strerror or exc}")
                return
            self.code_state = CODE_STARTING  # until its top level has run (Loaded)
            self.events.add(now, f"robot code loading ({self.name}) in a process of its own")
            return
        self._host = InlineHost(partial(self.source.make, self.robot.print), self.robot)
        self.collect(now)  # Loaded or LoadFailed, at once

    def stop(self) -> None:
        """The program stops where it is (a process is killed); its outputs go off."""
        if self._host is not None:
            self._host.stop()
            self._host = None
        self.robot.reset()
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
