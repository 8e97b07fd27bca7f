"""``fieldbox run SCRIPT``: the headless command language as a test harness for robot code.

A script is a file of headless commands, one per line (``#`` starts a comment), with steps
that wait and check (roles/cores/commands.py): ``sleep S``, ``wait comms|code|enabled|disabled
[S]``, ``expect console REGEX within S``, ``expect robot mode MODE within S``, ``expect
battery > V [within S]``. It is played against a field built from the same options as
``fieldbox --headless`` (``--roles ds --robot 127.0.0.1`` drives WPILib's simulator); with
``--launch CMD`` fieldbox first starts the robot program itself and reads its output as
console lines (WPILib's simulator prints to its stdout, not to the DS's console).

Each step's result is printed as it ends (TAP by default, one JSON object each with
``--json``; ``--junit FILE`` also writes JUnit XML for CI). The first step that fails (a
refused command, an expectation not met in time) ends the run: the rest are reported as
skipped, the launched program is stopped, and the exit code is 1 (2: the script or the
field could not start). Nothing here measures speed: "within S" is a deadline for the
robot's behaviour, as a mentor writes it.
"""

from __future__ import annotations

import asyncio
import json
import os
import re
import shlex
import signal
import sys
import time
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from typing import Any, Callable, TextIO

from roles.cores.commands import (Command, CommandSyntaxError, ExpectBattery, ExpectConsole, ExpectRobotMode,
                                  Sleep, Wait, parse)
from roles.cores.core import CommandError

from .lineout import LineOut

#: How often a waiting step looks again.
POLL = 0.02
#: Console lines a run keeps for its expectations (the newest; older ones are matched or gone).
CONSOLE_KEPT = 20_000
#: How long a launched robot program has to end after SIGINT before it is killed.
LAUNCH_STOP = 5.0
#: How long the end of the run waits for its reader to take the last results (then they are dropped, counted).
REPORT_DRAIN = 10.0


@dataclass
class Step:
    number: int  # 1-based, as TAP counts
    line: int  # the line of the script it came from
    text: str
    command: Command


@dataclass
class StepResult:
    step: Step
    ok: bool
    seconds: float
    detail: str = ""
    skipped: bool = False


class ScriptError(ValueError):
    """A script that cannot be played: the message names the file and line."""


def load_script(path: str) -> list[Step]:
    try:
        with open(path, encoding="utf-8") as f:
            lines = f.read(1 << 20).splitlines()
    except (OSError, UnicodeDecodeError) as exc:
        raise ScriptError(f"{path}: cannot read: {getattr(exc, 'strerror', None) or exc}") from None
    steps: list[Step] = []
    for number, text in enumerate(lines, 1):
        try:
            command = parse(text)
        except CommandSyntaxError as exc:
            raise ScriptError(f"{path}, line {number}: {exc}") from None
        if command is None:
            continue
        if command.verb in ("quit", "help", "status"):
            raise ScriptError(f"{path}, line {number}: {command.verb} has no place in a script")
        steps.append(Step(len(steps) + 1, number, text.split("#", 1)[0].strip(), command))
    if not steps:
        raise ScriptError(f"{path}: no steps")
    return steps


# -- what a step waits on ------------------------------------------------------------------------
class Console:
    """Every console line the run has seen (the DS's, and the launched program's output), with
    a cursor: each ``expect console`` looks from the line after the last one matched."""

    def __init__(self) -> None:
        self.lines: list[str] = []
        self.first = 0  # the index in the whole run of self.lines[0]
        self.cursor = 0
        self._seen: dict[int, int] = {}  # id(ds) -> its console_total already taken

    def add(self, text: str) -> None:
        self.lines.append(text)
        if len(self.lines) > CONSOLE_KEPT:
            drop = len(self.lines) - CONSOLE_KEPT
            del self.lines[:drop]
            self.first += drop

    def take_from(self, ds: Any) -> None:
        total = ds.console_total
        seen = self._seen.get(id(ds), total - len(ds.console))
        new = min(total - seen, len(ds.console))
        if new > 0:
            for entry in list(ds.console)[-new:]:
                self.add(str(entry[2]))
        self._seen[id(ds)] = total

    def match(self, pattern: re.Pattern) -> str | None:
        start = max(self.cursor, self.first)
        for i in range(start - self.first, len(self.lines)):
            if pattern.search(self.lines[i]):
                self.cursor = self.first + i + 1
                return self.lines[i]
        return None

    def tail(self, n: int = 5) -> list[str]:
        return self.lines[-n:]


def robot_mode(ds: Any) -> str:
    """What the robot reports it runs: its program's mode bits where it sends them, else the
    mode it applies as its status byte echoes it (WPILib's simulator sends no mode bits)."""
    if not ds.robot_comms or ds.status is None:
        return "no robot"
    program = ds.robot_program_mode
    if program:
        return program
    return ds.status.mode.label if ds.status.enabled else "disabled"


def condition(command: Command, ds: Any, console: Console) -> Callable[[], tuple[bool, str]]:
    """A check for a wait or expect step: ``() -> (met, what is the case now)``."""
    if isinstance(command, Wait):
        def wait() -> tuple[bool, str]:
            state = {"comms": ds.robot_comms, "code": ds.robot_comms and ds.robot_code,
                     "enabled": ds.enabled, "disabled": not ds.enabled}[command.what]
            now = (f"comms {'ok' if ds.robot_comms else 'none'}, code {'ok' if ds.robot_code else 'none'}, "
                   f"{'enabled' if ds.enabled else 'disabled'}")
            return state, now
        return wait
    if isinstance(command, ExpectConsole):
        pattern = re.compile(command.pattern)

        def console_line() -> tuple[bool, str]:
            console.take_from(ds)
            line = console.match(pattern)
            if line is not None:
                return True, f"matched {line!r}"
            return False, "last lines: " + (" | ".join(console.tail()) or "(none)")
        return console_line
    if isinstance(command, ExpectRobotMode):
        def mode() -> tuple[bool, str]:
            now = robot_mode(ds)
            return now == command.mode, f"the robot reports {now}"
        return mode
    assert isinstance(command, ExpectBattery)
    compare = {">": float.__gt__, ">=": float.__ge__, "<": float.__lt__, "<=": float.__le__}[command.op]

    def battery() -> tuple[bool, str]:
        value = ds.battery
        if value is None:
            return False, "no battery reading (no robot comms)"
        return compare(float(value), command.volts), f"battery {value:.2f} V"
    return battery


def timeout_of(command: Wait | ExpectConsole | ExpectRobotMode | ExpectBattery) -> float:
    return command.timeout if isinstance(command, Wait) else command.within


# -- playing -------------------------------------------------------------------------------------
class Runner:
    """Plays steps against a running field (``field``, its ``runtime``), one at a time."""

    def __init__(self, field: Any, runtime: Any, console: Console | None = None) -> None:
        self.field = field
        self.runtime = runtime
        self.console = console or Console()

    async def perform(self, step: Step) -> StepResult:
        command = step.command
        t0 = time.monotonic()
        try:
            detail = await self._perform(command)
        except CommandError as exc:
            return StepResult(step, False, time.monotonic() - t0, str(exc))
        except _NotMet as exc:
            return StepResult(step, False, time.monotonic() - t0, str(exc))
        return StepResult(step, True, time.monotonic() - t0, detail)

    async def _perform(self, command: Command) -> str:
        if isinstance(command, Sleep):
            await asyncio.sleep(command.seconds)
            return ""
        if command.verb in ("wait", "expect"):
            ds = self.field.station_for(command.team).ds
            if ds is None:
                raise CommandError("no Driver Station runs here: a test step watches a DS (add it with --roles ds)")
            check = condition(command, ds, self.console)
            deadline = time.monotonic() + timeout_of(command)
            while True:
                met, now = check()
                if met:
                    return now
                if time.monotonic() >= deadline:
                    raise _NotMet(f"not within {timeout_of(command):g} s: {now}")
                await asyncio.sleep(POLL)
        host = self.field.host_for(command)
        reply = self.field.execute(command, self.runtime.clock())
        if host and host in self.runtime.hosts:
            self.runtime.hosts[host].kick()
        return reply or ""


class _NotMet(Exception):
    pass


# -- reports -------------------------------------------------------------------------------------
class Report:
    """TAP on ``out`` by default, or one JSON object per step. Written as headless writes
    (fieldbox/lineout.py): a reader that went away (``| head``) or that does not read never
    holds the loop the field runs on; said once on stderr, and the run goes on."""

    def __init__(self, out: TextIO, as_json: bool, err: TextIO | None = None) -> None:
        self.errors = LineOut(err or sys.stderr, "stderr")
        self.out = LineOut(out, "stdout", problems=self.errors)
        self.as_json = as_json

    def begin(self, steps: list[Step]) -> None:
        if not self.as_json:
            self._print("TAP version 13")
            self._print(f"1..{len(steps)}")

    def result(self, r: StepResult) -> None:
        if self.as_json:
            self._print(json.dumps({"type": "step", "n": r.step.number, "line": r.step.line, "step": r.step.text,
                                    "ok": r.ok, "skipped": r.skipped, "seconds": round(r.seconds, 3),
                                    "detail": r.detail}))
            return
        if r.skipped:
            self._print(f"ok {r.step.number} - {r.step.text} # SKIP {r.detail}")
            return
        took = f" ({r.seconds:.2f} s)" if r.seconds >= 0.005 else ""
        self._print(f"{'ok' if r.ok else 'not ok'} {r.step.number} - {r.step.text}{took}")
        if not r.ok:
            self._print("  ---")
            self._print(f"  line: {r.step.line}")
            self._print(f"  message: {json.dumps(r.detail)}")
            self._print("  ...")

    def _print(self, text: str) -> None:
        self.out.line(text)

    def close(self) -> None:
        """Every result written (within REPORT_DRAIN), before anything else is said."""
        self.out.close(REPORT_DRAIN)
        self.errors.close(REPORT_DRAIN)


def junit(results: list[StepResult], name: str) -> bytes:
    """The run as JUnit XML: one test case a step."""
    failures = sum(1 for r in results if not r.ok and not r.skipped)
    skipped = sum(1 for r in results if r.skipped)
    suite = ET.Element("testsuite", name=name, tests=str(len(results)), failures=str(failures),
                       skipped=str(skipped), time=f"{sum(r.seconds for r in results):.3f}")
    for r in results:
        case = ET.SubElement(suite, "testcase", classname=name, name=f"{r.step.number}: {r.step.text}",
                             time=f"{r.seconds:.3f}")
        if r.skipped:
            ET.SubElement(case, "skipped", message=r.detail)
        elif not r.ok:
            failure = ET.SubElement(case, "failure", message=r.detail)
            failure.text = f"line {r.step.line}: {r.step.text}\n{r.detail}"
    return ET.tostring(ET.ElementTree(suite).getroot(), encoding="utf-8", xml_declaration=True)


# -- the command ----------------------------------------------------------------------------------
async def run_script(config: Any, path: str, *, launch: str | None = None, as_json: bool = False,
                     junit_path: str | None = None, out: TextIO | None = None,
                     err: TextIO | None = None) -> int:
    from .headless import start_field

    out = out or sys.stdout
    err = err or sys.stderr
    try:
        steps = load_script(path)
    except ScriptError as exc:
        print(f"fieldbox run: {exc}", file=err)
        return 2
    console = Console()
    program = None
    readers: list[asyncio.Task] = []
    if launch:
        try:
            program = await asyncio.create_subprocess_exec(
                *shlex.split(launch), stdin=asyncio.subprocess.DEVNULL, stdout=asyncio.subprocess.PIPE,
                stderr=asyncio.subprocess.STDOUT, start_new_session=True,
                env=dict(os.environ, PYTHONUNBUFFERED="1"))
        except (OSError, ValueError) as exc:
            print(f"fieldbox run: cannot launch {launch!r}: {exc}", file=err)
            return 2
        readers.append(asyncio.create_task(_read_lines(program.stdout, console)))
    try:
        runtime, field = await start_field(config)
    except (OSError, ValueError) as exc:
        await _stop(program, readers)
        print(f"fieldbox run: {exc}", file=err)
        return 2
    runtime.start()
    report = Report(out, as_json, err)
    report.begin(steps)
    runner = Runner(field, runtime, console)
    results: list[StepResult] = []
    failed = False
    try:
        for step in steps:
            if failed:
                result = StepResult(step, False, 0.0, "after a failed step", skipped=True)
            else:
                result = await runner.perform(step)
                failed = not result.ok
            results.append(result)
            report.result(result)
    finally:
        await runtime.close()
        await _stop(program, readers)
        report.close()
        if junit_path:
            try:
                with open(junit_path, "wb") as f:
                    f.write(junit(results, os.path.basename(path)))
            except OSError as exc:
                print(f"fieldbox run: cannot write {junit_path}: {exc.strerror or exc}", file=err)
                failed = True
    return 1 if failed else 0


async def _read_lines(stream: asyncio.StreamReader, console: Console) -> None:
    while True:
        try:
            line = await stream.readline()
        except (ValueError, asyncio.LimitOverrunError):  # a line too long: skip it
            continue
        if not line:
            return
        console.add(line.decode("utf-8", "replace").rstrip("\r\n"))


async def _stop(program: Any, readers: list[asyncio.Task]) -> None:
    if program is not None and program.returncode is None:
        try:
            os.killpg(program.pid, signal.SIGINT)
        except (ProcessLookupError, PermissionError):
            pass
        try:
            await asyncio.wait_for(program.wait(), LAUNCH_STOP)
        except asyncio.TimeoutError:
            try:
                os.killpg(program.pid, signal.SIGKILL)
            except (ProcessLookupError, PermissionError):
                pass
            await program.wait()
    for task in readers:
        task.cancel()
    await asyncio.gather(*readers, return_exceptions=True)
