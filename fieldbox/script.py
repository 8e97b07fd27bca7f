"""``fieldbox run SCRIPT``: the headless command language as a test harness for robot code.

A script is a file of headless commands, one per line (``#`` starts a comment), with steps
that wait and check (fieldbox/language.py): ``sleep S``, ``wait comms|code|enabled|disabled
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

Bounded on purpose: a script is a regular file of at most :data:`MAX_SCRIPT_BYTES` (a FIFO or
a bigger file is refused, never waited on or cut), and an ``expect console`` pattern is
matched in a process of its own (:class:`ConsoleMatcher`), so a pattern that backtracks
without end fails its step after :data:`MATCH_LIMIT` seconds instead of stopping the field.
"""

from __future__ import annotations

import asyncio
import json
import os
import shlex
import signal
import sys
import time
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from typing import Any, Awaitable, Callable, TextIO

from roles.cores.commands import Command
from roles.cores.core import CommandError
from roles.cores.views import DsView
from roles.runtime.engine import Engine, LoopEngine
from roles.runtime.field import FieldConfig

from .child_env import child_env
from .language import CommandSyntaxError, ExpectBattery, ExpectConsole, ExpectRobotMode, Sleep, Wait, parse
from .lineout import LineOut

#: How often a waiting step looks again.
POLL = 0.02
#: Console lines a run keeps for its expectations (the newest; older ones are matched or gone).
CONSOLE_KEPT = 20_000
#: How long a launched robot program has to end after SIGINT before it is killed.
LAUNCH_STOP = 5.0
#: The largest script ``fieldbox run`` plays: a script is a person's text, and one cut short
#: would pass without its last steps, so a bigger file is refused (exit code 2), never cut.
MAX_SCRIPT_BYTES = 1 << 20
#: How long matching one batch of console lines against an ``expect console`` pattern may
#: take before the step fails (see :class:`ConsoleMatcher`): a sane pattern takes
#: microseconds a line; one that backtracks catastrophically takes minutes.
MATCH_LIMIT = 2.0
#: How long the matcher's process may take to start (a loaded machine; not the pattern's time).
MATCHER_START = 30.0
#: The most console lines, and characters, in one batch (each batch has MATCH_LIMIT).
BATCH_LINES = 500
BATCH_CHARS = 1 << 20
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


def read_script(path: str) -> str:
    """The text of a script: a regular file of at most :data:`MAX_SCRIPT_BYTES`, read whole;
    ScriptError saying why not. Opened without blocking (a FIFO would wait for a writer, deaf
    to Ctrl+C) and checked once open (a symlink may lead anywhere), as themes are."""
    from .themes import read_small_file

    try:
        data = read_small_file(path, MAX_SCRIPT_BYTES, "a script")
    except ValueError as exc:
        raise ScriptError(str(exc)) from None
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise ScriptError(f"{path}: cannot read: not UTF-8 text: {exc}") from None


def load_script(path: str) -> list[Step]:
    lines = read_script(path).splitlines()
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
        self._seen: dict[int, int] = {}  # a DS's team -> the number of its next console line

    def add(self, text: str) -> None:
        self.lines.append(text)
        if len(self.lines) > CONSOLE_KEPT:
            drop = len(self.lines) - CONSOLE_KEPT
            del self.lines[:drop]
            self.first += drop

    def take_from(self, ds: DsView) -> None:
        """The console lines of ``ds`` new since the last look (at first, all it keeps)."""
        console = ds.tcp.console
        for _, _, text in console.since(self._seen.get(ds.team, console.first_seq)):
            self.add(text)
        self._seen[ds.team] = console.end

    async def match(self, matcher: ConsoleMatcher, looked: int = 0) -> tuple[str | None, int]:
        """The first line from the cursor that ``matcher`` finds, the cursor moved past it (or
        None); and where the next look starts. ``looked``: the lines before it (indices in
        the whole run) were looked at already, by the same step."""
        start = max(self.cursor, looked)
        end = self.first + len(self.lines)
        while True:
            # lines may come (and the oldest go) while the matcher works: indices are the run's
            start = max(start, self.first)
            if start >= end:
                return None, start
            batch: list[str] = []
            size = 0
            for text in self.lines[start - self.first:end - self.first]:
                if batch and (len(batch) >= BATCH_LINES or size + len(text) > BATCH_CHARS):
                    break
                batch.append(text)
                size += len(text)
            found = await matcher.first(batch)
            if found is not None:
                self.cursor = start + found + 1
                return batch[found], self.cursor
            start += len(batch)

    def tail(self, n: int = 5) -> list[str]:
        return self.lines[-n:]


def robot_mode(ds: DsView) -> str:
    """What the robot reports it runs: its program's mode bits where it sends them, else the
    mode it applies as its status byte echoes it (WPILib's simulator sends no mode bits)."""
    if not ds.link.robot_comms or ds.link.status is None:
        return "no robot"
    program = ds.link.program_mode
    if program:
        return program
    return ds.link.status.mode.label if ds.link.status.enabled else "disabled"


def condition(command: Command, console: Console,
              matcher: ConsoleMatcher | None = None) -> Callable[[DsView], Awaitable[tuple[bool, str]]]:
    """A check for a wait or expect step: ``async (the DS's view now) -> (met, what is the
    case now)``. An ``expect console`` step's lines are matched by ``matcher`` (of its pattern)."""
    if isinstance(command, Wait):
        async def wait(ds: DsView) -> tuple[bool, str]:
            state = {"comms": ds.link.robot_comms, "code": ds.link.robot_comms and ds.link.robot_code,
                     "enabled": ds.enabled, "disabled": not ds.enabled}[command.what]
            now = (f"comms {'ok' if ds.link.robot_comms else 'none'}, code {'ok' if ds.link.robot_code else 'none'}, "
                   f"{'enabled' if ds.enabled else 'disabled'}")
            return state, now
        return wait
    if isinstance(command, ExpectConsole):
        assert matcher is not None
        looked = 0

        async def console_line(ds: DsView) -> tuple[bool, str]:
            nonlocal looked
            console.take_from(ds)
            line, looked = await console.match(matcher, looked)
            if line is not None:
                return True, f"matched {line!r}"
            return False, "last lines: " + (" | ".join(console.tail()) or "(none)")
        return console_line
    if isinstance(command, ExpectRobotMode):
        async def mode(ds: DsView) -> tuple[bool, str]:
            now = robot_mode(ds)
            return now == command.mode, f"the robot reports {now}"
        return mode
    assert isinstance(command, ExpectBattery)
    compare = {">": float.__gt__, ">=": float.__ge__, "<": float.__lt__, "<=": float.__le__}[command.op]

    async def battery(ds: DsView) -> tuple[bool, str]:
        value = ds.link.battery
        if value is None:
            return False, "no battery reading (no robot comms)"
        return compare(float(value), command.volts), f"battery {value:.2f} V"
    return battery


class ConsoleMatcher:
    """``re.search`` of an ``expect console`` pattern over console lines, in a process of its own.

    Python's ``re`` backtracks: a pattern such as ``(a+)+$`` takes minutes on a line of 30
    ``a`` and a ``!``, and holds the interpreter's lock all along, so no thread of this
    process runs meanwhile: not the wire's loop (the DS's packets stop, the robot's watchdog
    disables it) nor a signal's timer. Telling such patterns apart beforehand is not
    reliable (``(a|a)*$``, ``.*.*.*x`` on a long line), and no engine without backtracking
    comes with Python. So each step's lines go, a batch at a time, to a small ``python``
    child that compiles the pattern once and answers with the first line that matches; the
    loop only writes lines and reads answers. A batch not answered within ``limit`` seconds
    fails the step, saying why, and the child is killed; the child also ends itself (its own
    timer, SIGALRM's default action) should this process be gone. One child a step: it
    starts in some 40 ms, and nothing of a slow pattern outlives its step."""

    #: The child: the pattern (a JSON string) on its first line, then a JSON list of lines per
    #: line; it answers ``ready``, then the index of the first line that matches, or -1.
    CODE = """\
import json, re, signal, sys
signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl+C is for fieldbox: it ends this child
limit = float(sys.argv[1])
pattern = re.compile(json.loads(sys.stdin.readline()))
print("ready", flush=True)
for request in sys.stdin:
    signal.setitimer(signal.ITIMER_REAL, limit)  # SIGALRM, not handled: the end of this process
    lines = json.loads(request)
    print(next((i for i, text in enumerate(lines) if pattern.search(text)), -1), flush=True)
    signal.setitimer(signal.ITIMER_REAL, 0)
"""

    def __init__(self, pattern: str, limit: float = MATCH_LIMIT) -> None:
        self.pattern = pattern
        self.limit = limit
        self._proc: asyncio.subprocess.Process | None = None

    async def start(self) -> None:
        """Start the child (raises _NotMet saying why it cannot be)."""
        try:
            # -I -S: no site, no environment: the child starts fast and runs only the code above
            self._proc = await asyncio.create_subprocess_exec(
                sys.executable, "-I", "-S", "-c", self.CODE, str(2 * self.limit),
                stdin=asyncio.subprocess.PIPE, stdout=asyncio.subprocess.PIPE, stderr=asyncio.subprocess.DEVNULL)
        except (OSError, ValueError) as exc:
            raise _NotMet(f"cannot start the console matcher: {exc}") from None
        try:
            reply = await asyncio.wait_for(self._ask(json.dumps(self.pattern)), MATCHER_START)
        except asyncio.TimeoutError:
            reply = b""
        if reply.strip() != b"ready":
            await self.close()
            raise _NotMet(f"the console matcher did not start within {MATCHER_START:g} s")

    async def first(self, lines: list[str]) -> int | None:
        """The index of the first of ``lines`` the pattern matches, or None (raises _NotMet
        when the child took longer than ``limit``, or ended)."""
        if self._proc is None:
            await self.start()
        assert self._proc is not None  # started
        try:
            reply = await asyncio.wait_for(self._ask(json.dumps(lines)), self.limit)
        except asyncio.TimeoutError:
            reply = None
        if not reply:  # too slow, or gone (its own timer, or killed from outside)
            await self.close()
            what = "a console line" if len(lines) == 1 else f"{len(lines)} console lines"
            if reply is None or self._proc.returncode == -signal.SIGALRM:
                raise _NotMet(f"the pattern took longer than {self.limit:g} s to match {what}: it may "
                              f"backtrack catastrophically (a repeat inside a repeat, such as (a+)+)")
            raise _NotMet(f"the console matcher ended (exit code {self._proc.returncode})")
        try:
            found = int(reply)
        except ValueError:
            await self.close()
            raise _NotMet(f"the console matcher answered {reply[:80]!r}, not a line's index") from None
        return found if 0 <= found < len(lines) else None

    async def _ask(self, request: str) -> bytes:
        assert self._proc is not None and self._proc.stdin is not None and self._proc.stdout is not None
        try:
            self._proc.stdin.write(request.encode("ascii") + b"\n")  # JSON's escapes: ASCII, one line
            await self._proc.stdin.drain()
        except (BrokenPipeError, ConnectionResetError):
            return b""
        return await self._proc.stdout.readline()

    async def close(self) -> None:
        """Kill the child (it holds nothing worth a goodbye) and reap it."""
        proc = self._proc
        if proc is None:
            return
        if proc.returncode is None:
            try:
                proc.kill()
            except ProcessLookupError:
                pass
        await proc.wait()


def timeout_of(command: Wait | ExpectConsole | ExpectRobotMode | ExpectBattery) -> float:
    return command.timeout if isinstance(command, Wait) else command.within


# -- playing -------------------------------------------------------------------------------------
class Runner:
    """Plays steps against a running field, one at a time: commands go in as typed commands,
    and a wait or expect step reads the field's views (one a look, every :data:`POLL`)."""

    def __init__(self, engine: Engine, console: Console | None = None) -> None:
        self.engine = engine
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
        if isinstance(command, (Wait, ExpectConsole, ExpectRobotMode, ExpectBattery)):  # the wait and expect steps
            ds = self._ds(command.team)  # no DS: refused before anything starts
            matcher = ConsoleMatcher(command.pattern) if isinstance(command, ExpectConsole) else None
            check = condition(command, self.console, matcher)
            deadline = time.monotonic() + timeout_of(command)
            try:
                while True:
                    met, now = await check(ds)
                    if met:
                        return now
                    if time.monotonic() >= deadline:
                        raise _NotMet(f"not within {timeout_of(command):g} s: {now}")
                    await asyncio.sleep(POLL)
                    ds = self._ds(command.team)
            finally:
                if matcher is not None:  # ended, failed or cancelled (quit, SIGTERM): its child goes
                    await matcher.close()
        return self.engine.execute(command) or ""

    def _ds(self, team: int | None) -> DsView:
        """The view of ``team``'s DS, made now."""
        ds = self.engine.station_view(team, self.engine.now()).ds
        if ds is None:
            raise CommandError("no Driver Station runs here: a test step watches a DS (add it with --roles ds)")
        return ds


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
    return ET.tostring(suite, encoding="utf-8", xml_declaration=True)


# -- the command ----------------------------------------------------------------------------------
async def run_script(config: FieldConfig, path: str, *, launch: str | None = None, as_json: bool = False,
                     junit_path: str | None = None, out: TextIO | None = None,
                     err: TextIO | None = None) -> int:
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
                env=child_env(PYTHONUNBUFFERED="1"))
        except (OSError, ValueError) as exc:
            print(f"fieldbox run: cannot launch {launch!r}: {exc}", file=err)
            return 2
        assert program.stdout is not None  # a pipe
        readers.append(asyncio.create_task(_read_lines(program.stdout, console)))
    engine = LoopEngine(config)
    try:
        await engine.start()
    except (OSError, ValueError) as exc:
        await _stop(program, readers)
        print(f"fieldbox run: {exc}", file=err)
        return 2
    report = Report(out, as_json, err)
    report.begin(steps)
    runner = Runner(engine, console)
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
        await engine.close()
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
