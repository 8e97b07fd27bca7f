"""What a conformance run does besides the wire: start the implementation under test
(``--launch CMD``), read what its robot program reports, and ask for what only the peer's
own user interface can do (enable a Driver Station, start a match, e-stop a station).

A hook is one of:

* ``stdin:TEXT``: write TEXT as a line to the launched program's stdin (fieldbox's headless
  commands: ``stdin:enable``, ``stdin:match start``, ``stdin:estop {station} on``);
* ``prompt``: ask the person at the terminal to do it, and wait for Enter;
* anything else: a shell command, run to its end (at most 15 s).

``{station}`` (R1..B3) and ``{team}`` in a hook are replaced by the station or team it acts on.
"""

from __future__ import annotations

import asyncio
import json
import os
import shlex
import signal
import sys
import time
from collections import deque
from dataclasses import dataclass
from typing import Any, TextIO

from ..child_env import child_env

#: Lines kept of a launched program's output.
MAX_LINES = 20_000
#: The longest line read from a launched program or a console frame; longer ones are skipped.
MAX_LINE = 64 * 1024
#: How long a launched program has to end after SIGINT before it is killed.
LAUNCH_STOP = 5.0
#: How long a shell-command hook may run.
HOOK_TIMEOUT = 15.0
#: What a robot program prints before each report (programs/fieldbox_robot.py, programs/wpilib_robot.py).
REPORT_PREFIX = "conform "


class Launched:
    """A program conform started: its output as lines (with arrival times), its stdin."""

    def __init__(self, command: str, process: asyncio.subprocess.Process) -> None:
        self.command = command
        self.process = process
        self.lines: deque[tuple[float, str]] = deque(maxlen=MAX_LINES)
        self.listeners: list[Any] = []
        self._reader = asyncio.get_running_loop().create_task(self._read())

    @classmethod
    async def start(cls, command: str, cwd: str | None = None) -> "Launched":
        """Start ``command`` (split as a shell would, run without one) in a session of its
        own, so stopping it stops what it started. Raises OSError or ValueError."""
        argv = shlex.split(command)
        if not argv:
            raise ValueError("an empty command")
        process = await asyncio.create_subprocess_exec(
            *argv, stdin=asyncio.subprocess.PIPE, stdout=asyncio.subprocess.PIPE,
            stderr=asyncio.subprocess.STDOUT, start_new_session=True, cwd=cwd, limit=MAX_LINE,
            env=child_env(PYTHONUNBUFFERED="1"))
        return cls(command, process)

    async def _read(self) -> None:
        stream = self.process.stdout
        assert stream is not None
        while True:
            try:
                line = await stream.readline()
            except (ValueError, asyncio.LimitOverrunError):  # a line too long: skipped
                continue
            if not line:
                return
            text = line.decode("utf-8", "replace").rstrip("\r\n")
            now = time.monotonic()
            self.lines.append((now, text))
            for listener in self.listeners:
                listener(now, text)

    @property
    def running(self) -> bool:
        return self.process.returncode is None

    async def send_line(self, text: str) -> bool:
        stdin = self.process.stdin
        if stdin is None or not self.running:
            return False
        try:
            stdin.write(text.encode("utf-8") + b"\n")
            await stdin.drain()
        except (ConnectionError, OSError, RuntimeError):
            return False
        return True

    def tail(self, n: int = 10) -> list[str]:
        return [t for _, t in list(self.lines)[-n:]]

    async def stop(self) -> None:
        """SIGINT to its process group, SIGKILL after LAUNCH_STOP: only what we started."""
        p = self.process
        if p.returncode is None:
            if p.stdin is not None:
                try:
                    p.stdin.close()  # a headless fieldbox ends at the end of its input
                except (ConnectionError, OSError, RuntimeError):
                    pass
            for sig, wait in ((signal.SIGINT, LAUNCH_STOP), (signal.SIGKILL, LAUNCH_STOP)):
                try:
                    os.killpg(p.pid, sig)
                except (ProcessLookupError, PermissionError):
                    break
                try:
                    await asyncio.wait_for(p.wait(), wait)
                    break
                except asyncio.TimeoutError:
                    continue
        self._reader.cancel()
        await asyncio.gather(self._reader, return_exceptions=True)


@dataclass(frozen=True)
class Hook:
    """How to make the peer do something a person would do at its screen (see module doc)."""

    what: str  # what it asks, for prompts and reports: "enable the Driver Station"
    spec: str | None

    @property
    def given(self) -> bool:
        return bool(self.spec)

    def describe(self) -> str:
        return self.spec or "(none)"

    async def fire(self, launched: Launched | None, *, err: TextIO | None = None,
                   ask: TextIO | None = None, **values: Any) -> tuple[bool, str]:
        """Do it; ``(done, what happened)``. Never raises for a hook that fails."""
        out = await self.outcome(launched, err=err, ask=ask, **values)
        return out.done, out.note

    async def outcome(self, launched: Launched | None, *, err: TextIO | None = None,
                      ask: TextIO | None = None, **values: Any) -> "HookOutcome":
        """Do it, and say whether it ran at all: a shell command that ran and exited non-zero
        (a start the peer refused, its reason on its last line of output) ran, but was not done."""
        spec = self.spec
        if not spec:
            return HookOutcome(False, False, f"no hook given to {self.what}")
        for key, value in values.items():
            spec = spec.replace("{" + key + "}", str(value))
        what = self.what
        for key, value in values.items():
            what = what.replace("{" + key + "}", str(value))
        if spec.startswith("stdin:"):
            text = spec[len("stdin:"):].strip()
            if launched is None:
                return HookOutcome(False, False, f"{spec!r} writes to a launched program's stdin: give --launch")
            if not await launched.send_line(text):
                return HookOutcome(False, False, f"could not write {text!r} to the launched program (it ended?)")
            return HookOutcome(True, True, f"wrote {text!r} to the launched program")
        if spec.strip() == "prompt":
            err = err or sys.stderr
            print(f"fieldbox conform: please {what} now, then press Enter", file=err, flush=True)
            line = await asyncio.to_thread((ask or sys.stdin).readline)
            if not line:
                return HookOutcome(False, False, "no answer (end of input)")
            return HookOutcome(True, True, f"a person was asked to {what}")
        try:
            proc = await asyncio.create_subprocess_shell(spec, stdin=asyncio.subprocess.DEVNULL,
                                                         stdout=asyncio.subprocess.PIPE,
                                                         stderr=asyncio.subprocess.STDOUT,
                                                         start_new_session=True, env=child_env())
        except OSError as exc:
            return HookOutcome(False, False, f"cannot run {spec!r}: {exc}")
        # its output is read as it comes (a full pipe would stall it), the tail kept: the
        # last line says why a command failed ("match cannot start: B3 not connected")
        tail = bytearray()
        reader = asyncio.get_running_loop().create_task(_keep_tail(proc.stdout, tail))
        try:
            code = await asyncio.wait_for(proc.wait(), HOOK_TIMEOUT)
        except asyncio.TimeoutError:
            try:
                os.killpg(proc.pid, signal.SIGKILL)
            except (ProcessLookupError, PermissionError):
                pass
            await proc.wait()
            reader.cancel()
            await asyncio.gather(reader, return_exceptions=True)
            return HookOutcome(False, False, f"{spec!r} did not end within {HOOK_TIMEOUT:g} s")
        # a child it left in the background may hold the pipe open: the output is not waited for
        try:
            await asyncio.wait_for(asyncio.shield(reader), HOOK_OUTPUT_WAIT)
        except asyncio.TimeoutError:
            reader.cancel()
            await asyncio.gather(reader, return_exceptions=True)
        lines = [ln.strip() for ln in tail.decode("utf-8", "replace").splitlines() if ln.strip()]
        said = f": {lines[-1][:HOOK_REASON]}" if code != 0 and lines else ""
        return HookOutcome(code == 0, True, f"ran {spec!r} (exit {code}{said})")


#: How long a hook command's output is waited for once it has ended.
HOOK_OUTPUT_WAIT = 1.0
#: Output kept of a hook command, and characters of its last line put in the report.
HOOK_TAIL = 4096
HOOK_REASON = 200


async def _keep_tail(stream: asyncio.StreamReader | None, tail: bytearray) -> None:
    if stream is None:
        return
    while True:
        chunk = await stream.read(HOOK_TAIL)
        if not chunk:
            return
        tail += chunk
        del tail[:-HOOK_TAIL]


@dataclass(frozen=True)
class HookOutcome:
    done: bool  # it did what it asks (a shell command: exit 0)
    ran: bool  # it ran at all (a shell command that ended, whatever its exit code)
    note: str


# -- what a robot program reports ------------------------------------------------------------
@dataclass(frozen=True)
class Report:
    """One line a conformance robot program printed: what its robot code sees."""

    at: float  # time.monotonic() when the line reached us
    line: str
    state: dict[str, Any]
    source: str = ""  # where it came from: the DS console, a launched program's stdout

    def stick(self, slot: int) -> dict[str, Any]:
        sticks = self.state.get("sticks")
        if isinstance(sticks, list) and 0 <= slot < len(sticks) and isinstance(sticks[slot], dict):
            return sticks[slot]
        return {}


class Readback:
    """Report lines from wherever the robot program's output reaches us: the DS console on
    TCP 1740 (fieldbox's fake roboRIO) or the launched program's stdout (WPILib's simulator,
    which sends nothing on TCP 1740). Any other text is kept too, as console lines."""

    def __init__(self) -> None:
        self.reports: deque[Report] = deque(maxlen=MAX_LINES)
        self.lines: deque[tuple[float, str]] = deque(maxlen=MAX_LINES)
        self.bad_reports = 0

    def add_text(self, at: float, text: str, source: str = "") -> None:
        for line in text.splitlines():
            if len(line) > MAX_LINE:
                continue
            self.lines.append((at, line))
            start = line.find(REPORT_PREFIX)
            if start < 0:
                continue
            try:
                state = json.loads(line[start + len(REPORT_PREFIX):])
            except (ValueError, RecursionError):
                self.bad_reports += 1
                continue
            if isinstance(state, dict):
                self.reports.append(Report(at, line[start:], state, source))
            else:
                self.bad_reports += 1

    def since(self, t: float) -> list[Report]:
        return [r for r in self.reports if r.at >= t]

    @property
    def last(self) -> Report | None:
        return self.reports[-1] if self.reports else None
