"""Where the fake roboRIO's robot program runs, and the narrow channel it is reached through.

On a real roboRIO the network daemon (which answers the DS, feeds the FPGA watchdog and
latches an e-stop) never waits for user code: the user program is a process of its own that
reads the newest DS data and writes its outputs. The fake roboRIO is built the same way.
Its core (roles/cores/rio_program.py) never runs, reads or waits for the program: it asks
(check this program, start it, call it with this state, stop it) and :class:`CodeHost`, one
per roboRIO, does it here; what a process sends later the shell (roles/runtime/shell.py)
hands to the core with ``Rio.program_events`` before the core's next event. Reading and
running program files (:func:`load_program`, :func:`check_program`) is this module's too.

* :class:`ProcessHost` runs a program file in a child process (``python -c`` :data:`CHILD_CODE`).
  The wire sends it the newest :class:`~roles.cores.robot_program.ControlState` whenever the last
  call has returned, never waits for it, and reads back what it did (console lines as they
  come, then one result per call) without blocking. Nothing the program does reaches the
  wire's process: an exception of any kind (KeyboardInterrupt, SystemExit, a BaseException
  of its own) is a result; an endless loop is a call that never returns (reported as stuck
  by the core); ``os._exit`` or a crash ends the code, seen by the process's own end (not by
  the end of its channel, which a process it forked may hold); memory is limited
  (:data:`MEMORY_LIMIT`). The child runs at a lower priority than the wire, as user code
  runs below the roboRIO's network daemon. It leads a session of its own, so a restart or
  the field's end kills it with every process it forked (its process group), none left
  behind.
* :class:`InlineHost` calls a program in the wire's own thread: for the built-in program
  (ours, bounded), programs given as Python callables, and the fake-clock tests.

Either way, what the program wrote (outputs, rumble, the 2010 DS's digital outputs and LCD)
crosses :func:`sanitize_outputs` before the wire uses it: a NaN, a None or an out-of-range
value is clamped or refused (turned off) and reported once, never sent.

The child speaks length-prefixed frames on a socket pair: the parent sends pickles (the
child trusts its parent), the child sends JSON objects (the parent does not run what a
program could forge), each field checked on arrival.
"""

from __future__ import annotations

import inspect
import json
import math
import os
import pickle
import signal
import socket
import struct
import subprocess
import sys
import threading
import time
import traceback
import types
from typing import Any, Callable

from ..cores.rio_program import (NO_OUTPUTS, CallProgram, CheckProgram, Ended,  # noqa: F401 - re-exported
                                  LoadFailed, Loaded, Loading, Message, ProgramEvent, ProgramOutputs,
                                  ProgramRequest, ProgramSource, Result, StartProgram, StopProgram)
from ..cores.robot_program import (MAX_TEXT, SLOTS, BuiltinProgram, ControlState, Program, ProgramError,
                                   RobotApi, describe_exception)

#: The robot program's period; a call that takes longer is an overrun.
PERIOD = 0.020
#: Address space a program's process may take (a program that allocates without end gets a
#: MemoryError, not the machine's memory).
MEMORY_LIMIT = 1 << 30
#: Console messages a program may send in one 20 ms window; the rest are counted and dropped.
MAX_MESSAGES_PER_WINDOW = 50
#: The largest frame either side accepts (a console line is at most MAX_TEXT characters).
MAX_FRAME = 256 * 1024
#: What the wire reads from a child in one go (the rest waits for the next beat).
READ_BUDGET = 256 * 1024
#: Calls the wire has not yet written to the child's socket, at most (the child stopped reading).
MAX_UNSENT = 64 * 1024

KINDS = ("stdout", "warning", "error")
_LEN = struct.Struct(">I")

#: How the child starts; ``sys.argv``: the socket's fd, the program's path, the memory limit.
CHILD_CODE = ("import sys; sys.modules['ssl'] = None; from roles.runtime.program_host import child_main; "
              "sys.exit(child_main(int(sys.argv[1]), sys.argv[2], int(sys.argv[3])))")
#: The project's root: a child process runs this fieldbox, installed or not.
ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


def child_environment() -> dict[str, str]:
    """This process's environment with :data:`ROOT` first on PYTHONPATH, for a child of ours."""
    env = dict(os.environ)
    env["PYTHONPATH"] = ROOT + (os.pathsep + env["PYTHONPATH"] if env.get("PYTHONPATH") else "")
    return env


# -- what crosses the channel --------------------------------------------------------------
# The requests and answers themselves are the core's (roles/cores/rio_program.py): the
# core says what it wants done, this module does it.
Event = ProgramEvent


def _check_int(value: Any, top: int, what: str, problems: list[str]) -> int:
    if isinstance(value, bool) or not isinstance(value, int):
        problems.append(f"{what} = {_show(value)} is not a whole number 0..{top:#x}: sent as 0")
        return 0
    if not 0 <= value <= top:
        clamped = min(max(value, 0), top)
        problems.append(f"{what} = {_show(value)} is out of range 0..{top:#x}: sent as {clamped:#x}")
        return clamped
    return value


def _check_fraction(value: Any, what: str, problems: list[str]) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        problems.append(f"{what} = {_show(value)} is not a number 0.0..1.0: sent as 0.0")
        return 0.0
    if not 0.0 <= value <= 1.0:
        clamped = min(max(float(value), 0.0), 1.0)
        problems.append(f"{what} = {_show(value)} is out of range 0.0..1.0: sent as {clamped:g}")
        return clamped
    return float(value)


def _slots(value: Any, what: str, problems: list[str], off: int | float) -> list:
    if not isinstance(value, (list, tuple)) or len(value) != SLOTS:
        problems.append(f"{what} = {_show(value)} is not a list of {SLOTS}: all sent as 0")
        return [off] * SLOTS  # said once above, not once more per slot
    return list(value)


def _show(value: Any) -> str:
    try:
        text = repr(value)
    except Exception:  # noqa: BLE001 - a program's object with a broken __repr__
        text = f"<{type(value).__name__}>"
    return text if len(text) <= 60 else text[:57] + "..."


def sanitize_outputs(outputs: Any, left: Any, right: Any, digital_out: Any = 0,
                     lcd: Any = None) -> tuple[ProgramOutputs, tuple[str, ...]]:
    """The program's raw outputs, made valid: ``(outputs, problems)``. A value of the wrong
    type (None, NaN, a string) is refused and sent as off; a number out of range is clamped.
    Each is a problem naming the output (a None too: the README promises it is said)."""
    problems: list[str] = []
    outs = tuple(_check_int(v, 0xFFFFFFFF, f"robot.outputs[{i}]", problems)
                 for i, v in enumerate(_slots(outputs, "robot.outputs", problems, 0)))
    lefts = tuple(_check_fraction(v, f"robot.left_rumble[{i}]", problems)
                  for i, v in enumerate(_slots(left, "robot.left_rumble", problems, 0.0)))
    rights = tuple(_check_fraction(v, f"robot.right_rumble[{i}]", problems)
                   for i, v in enumerate(_slots(right, "robot.right_rumble", problems, 0.0)))
    dout = _check_int(digital_out, 0xFF, "robot.ds_digital_out", problems)
    lines = None
    if lcd is not None:
        if isinstance(lcd, (list, tuple)) and len(lcd) == 6 and all(isinstance(s, str) for s in lcd):
            lines = tuple("".join(c if " " <= c <= "~" else "?" for c in s[:21]) for s in lcd)
        else:
            problems.append(f"robot.lcd = {_show(lcd)} is not six lines of text: not shown")
    return ProgramOutputs(outs, lefts, rights, dout, lines), tuple(problems)


def outputs_of(robot: RobotApi) -> tuple[ProgramOutputs, tuple[str, ...]]:
    return sanitize_outputs(robot.outputs, robot.left_rumble, robot.right_rumble, robot.ds_digital_out,
                            robot.lcd)


def _raw_key(robot: RobotApi) -> tuple | None:
    """What the program left in ``robot``, as a comparable value (None: not plain lists)."""
    try:
        lcd = robot.lcd
        return (tuple(robot.outputs), tuple(robot.left_rumble), tuple(robot.right_rumble), robot.ds_digital_out,
                None if lcd is None else tuple(lcd))
    except TypeError:
        return None


# -- reading and running a program file --------------------------------------------------------
def compile_program(path: str, flags: int = 0) -> Any:
    """The program file at ``path``, read and compiled (``flags``: ``ast.PyCF_ONLY_AST`` for its
    tree), without running it. Raises :class:`ProgramError` naming the file and line."""
    try:
        with open(path, "rb") as f:
            source = f.read()
    except OSError as exc:
        raise ProgramError(f"cannot read robot program {path}: {exc.strerror or exc}") from None
    try:
        return compile(source, path, "exec", flags)
    except SyntaxError as exc:
        where = f"{path}, line {exc.lineno}" if exc.lineno else path
        raise ProgramError(f"{where}: {type(exc).__name__}: {exc.msg}") from None
    except (ValueError, RecursionError, MemoryError) as exc:  # null bytes, absurd nesting
        raise ProgramError(f"{path}: not Python source: {exc}") from None


def load_program(path: str | os.PathLike[str], console: Callable[..., None] | None = None) -> Program:
    """Load ``robot_periodic(state, robot)`` from the file at ``path``.

    The file runs in a fresh namespace each call (a restart of the code reloads it). With
    ``console``, the file's ``print`` is that function. Raises :class:`ProgramError` naming
    the file and line for a missing file, a syntax error, an exception at load time, or a
    missing or wrongly shaped ``robot_periodic``.
    """
    path = os.fspath(path)
    code = compile_program(path)
    module = types.ModuleType(os.path.splitext(os.path.basename(path))[0] or "robot_program")
    module.__file__ = path
    if console is not None:
        module.print = console  # type: ignore[attr-defined]
    try:
        exec(code, module.__dict__)  # noqa: S102 - the user's own robot program, on purpose
    except (Exception, SystemExit) as exc:
        raise ProgramError(f"{path}, line {_program_line(exc, path)}: error while loading: "
                           f"{type(exc).__name__}: {exc}") from None
    hook = module.__dict__.get("robot_periodic")
    if hook is None:
        raise ProgramError(f"{path}: defines no robot_periodic(state, robot) function")
    if not callable(hook):
        raise ProgramError(f"{path}: robot_periodic is a {type(hook).__name__}, not a function")
    try:
        inspect.signature(hook).bind(None, None)
    except TypeError:
        raise ProgramError(f"{path}: robot_periodic must take two arguments (state, robot)") from None
    except ValueError:
        pass  # no signature to check (a builtin): let it run
    periodic: Callable[[ControlState, RobotApi], Any] = hook  # checked callable with two arguments above
    return periodic


def _program_line(exc: BaseException, path: str) -> str:
    frames = traceback.extract_tb(exc.__traceback__)
    for fr in reversed(frames):
        if fr.filename == path:
            return str(fr.lineno)
    return "?"



# -- the core's host: what it asks, done here ----------------------------------------------
class CodeHost:
    """The runtime side of one fake roboRIO's robot code (the core's ``ProgramHost``).

    The core asks (a ``ProgramRequest``): check a program, start it, call it with this
    state, stop it. A file that runs apart starts a :class:`ProcessHost`; anything else an
    :class:`InlineHost`, whose answers come back at once. What a process sends later the
    shell reads with :meth:`collect` before each of the core's events, and hands to the
    core's ``program_events``: the core never touches the channel.
    """

    def __init__(self) -> None:
        #: Where what a process sent goes (the core's ``program_events``), set by who hosts both.
        self.deliver: Callable[[list[ProgramEvent], float], object] | None = None
        self.robot = RobotApi(self._message)  # what an inline program writes to
        self._host: InlineHost | ProcessHost | None = None
        self._kept: tuple[str, Program] | None = None  # a file whose top level ran at its check
        self._answers: list[ProgramEvent] = []

    @property
    def host(self) -> InlineHost | ProcessHost | None:
        """Where the program runs now (None: no code)."""
        return self._host

    def __call__(self, request: ProgramRequest, now: float) -> list[ProgramEvent]:
        kind = type(request)
        if kind is CallProgram:
            assert isinstance(request, CallProgram)
            host = self._host
            if host is not None and host.offer(request.state, request.inputs, now) and not host.isolated:
                self._answers.extend(host.collect(now))  # an inline program has run
        elif kind is StartProgram:
            assert isinstance(request, StartProgram)
            self._start(request.source, now)
        elif kind is StopProgram:
            self._stop()
        elif kind is CheckProgram:
            assert isinstance(request, CheckProgram)
            self._check(request.source, request.keep)
        answers, self._answers = self._answers, []
        return answers

    def collect(self, now: float) -> list[ProgramEvent]:
        """What a program's process sent since the last look (never waits)."""
        host = self._host
        return host.collect(now) if host is not None and host.isolated else []

    def pump(self, now: float) -> None:
        """Hand what a process sent to the core (the shell calls this before each of its events)."""
        if self._host is not None and self._host.isolated and self.deliver is not None:
            events = self._host.collect(now)
            if events:
                self.deliver(events, now)

    def shutdown(self) -> None:
        self._stop()

    def _message(self, kind: str, text: str, code: int = 0, location: str = "", call_stack: str = "") -> None:
        self._answers.append(Message(kind, text, code, location, call_stack))

    def _check(self, source: ProgramSource, keep: bool) -> None:
        self._kept = None
        if source.path is None:
            return
        try:
            if source.isolate:  # its top level runs in its own process, never here
                check_program(source.path)
            else:
                program = load_program(source.path, console=self.robot.print)
                if keep:
                    self._kept = (source.path, program)
        except ProgramError as exc:
            self._answers.append(LoadFailed(str(exc)))

    def _start(self, source: ProgramSource, now: float) -> None:
        self._stop()
        if source.apart:
            assert source.path is not None  # apart: a file, in a process of its own
            try:
                self._host = ProcessHost(source.path, now)
            except OSError as exc:
                self._answers.append(LoadFailed(f"cannot start its process: {exc.strerror or exc}"))
                return
            self._answers.append(Loading())  # until its top level has run (Loaded)
            return
        self._host = InlineHost(lambda: self._make(source), self.robot)
        self._answers.extend(self._host.collect(now))  # Loaded or LoadFailed, at once

    def _make(self, source: ProgramSource) -> Program:
        kept, self._kept = self._kept, None
        if source.path is not None:
            if kept is not None and kept[0] == source.path:
                return kept[1]
            return load_program(source.path, console=self.robot.print)
        if isinstance(source.program, type):
            fresh: Program = source.program()  # a class: a fresh instance each time the code starts
            return fresh
        if source.program is not None:
            return source.program
        return BuiltinProgram()

    def _stop(self) -> None:
        """The program stops where it is (a process is killed); its outputs go off."""
        if self._host is not None:
            self._host.stop()
            self._host = None
        self.robot.reset()


# -- in the wire's thread --------------------------------------------------------------------
class InlineHost:
    """A program called in the wire's own thread (the built-in one, callables, fake clocks).

    ``make`` builds the program (raising ProgramError if it cannot); ``robot`` is the API it
    writes to, whose messages go straight to the core's ``emit``."""

    isolated = False

    def __init__(self, make: Callable[[], Program], robot: RobotApi) -> None:
        self.robot = robot
        self._events: list[Event] = []
        self._last_key: tuple | None = None
        self._last: tuple[ProgramOutputs, tuple[str, ...]] = (NO_OUTPUTS, ())
        try:
            self.program: Program | None = make()
        except ProgramError as exc:
            self.program = None
            self._events.append(LoadFailed(str(exc)))
        else:
            self._events.append(Loaded())

    @property
    def busy_since(self) -> float | None:
        return None  # a call here has always returned by the time anyone asks

    @property
    def idle(self) -> bool:
        return self.program is not None

    def offer(self, state: ControlState, inputs: tuple[int, tuple[int, ...]], now: float) -> bool:
        if self.program is None:
            return False
        robot = self.robot
        robot.ds_digital_in, robot.ds_analog_in = inputs
        error = None
        t0 = time.perf_counter()
        try:
            self.program(state, robot)
        except BaseException as exc:  # noqa: BLE001 - the user's code must never stop the wire
            error = describe_exception(exc)
        took = time.perf_counter() - t0
        key = _raw_key(robot)
        if key is None or key != self._last_key:  # the same outputs as last beat: checked already
            self._last = outputs_of(robot)
            self._last_key = key
        outputs, problems = self._last
        self._events.append(Result(took, outputs, problems, error))
        return True

    def collect(self, now: float) -> list[Event]:
        events, self._events = self._events, []
        return events

    def stop(self) -> None:
        self.program = None

    def fileno(self) -> int | None:
        return None


# -- in a process of its own -----------------------------------------------------------------
class ProcessHost:
    """A program file in a child process, reached without ever waiting for it."""

    isolated = True

    def __init__(self, path: str, now: float, *, memory_limit: int = MEMORY_LIMIT) -> None:
        ours, theirs = socket.socketpair()
        env = child_environment()
        folder = os.path.dirname(os.path.abspath(path)) or None
        try:
            self.proc: subprocess.Popen | None = subprocess.Popen(
                [sys.executable, "-c", CHILD_CODE, str(theirs.fileno()), os.path.abspath(path), str(memory_limit)],
                pass_fds=[theirs.fileno()], stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
                stderr=subprocess.DEVNULL, env=env, cwd=folder if folder and os.path.isdir(folder) else None,
                start_new_session=True)  # a group of its own: stop() kills what the program forked too
        except OSError:
            ours.close()
            raise
        finally:
            theirs.close()
        ours.setblocking(False)
        self.sock: socket.socket | None = ours
        self._inbuf = bytearray()
        self._outbuf = bytearray()
        self._loaded = False
        self._sent = 0  # calls sent
        self._returned = 0  # results read
        self._busy_since: float | None = now  # the top level runs first
        self._ended = False

    @property
    def busy_since(self) -> float | None:
        return self._busy_since

    @property
    def idle(self) -> bool:
        return self._loaded and not self._ended and self._sent == self._returned

    def fileno(self) -> int | None:
        return self.sock.fileno() if self.sock is not None else None

    def offer(self, state: ControlState, inputs: tuple[int, tuple[int, ...]], now: float) -> bool:
        """Send the newest state if the last call returned; never waits."""
        if not self.idle:
            return False
        data = pickle.dumps(("call", self._sent + 1, state, inputs), pickle.HIGHEST_PROTOCOL)
        if len(self._outbuf) + len(data) > MAX_UNSENT:
            return False
        self._outbuf += _LEN.pack(len(data)) + data
        self._sent += 1
        self._busy_since = now
        self._flush()
        return True

    def _flush(self) -> None:
        while self._outbuf and self.sock is not None:
            try:
                n = self.sock.send(self._outbuf)
            except (BlockingIOError, InterruptedError):
                return
            except OSError:
                return  # the child is gone: collect() reads the end of file
            del self._outbuf[:n]

    def collect(self, now: float) -> list[Event]:
        """What the child sent since the last look (at most READ_BUDGET bytes of it)."""
        if self.sock is None:
            return []
        # Looked at before the reading: a process that had ended has sent all it will, so
        # once the channel is drained it is over, even if a process it forked holds the
        # channel open (no end of file would come).
        exited = self._exited()
        self._flush()
        events: list[Event] = []
        budget = READ_BUDGET
        eof = False
        while budget > 0:
            try:
                chunk = self.sock.recv(min(65536, budget))
            except (BlockingIOError, InterruptedError):
                eof = exited  # drained
                break
            except OSError:
                eof = True
                break
            if not chunk:
                eof = True
                break
            budget -= len(chunk)
            self._inbuf += chunk
        while len(self._inbuf) >= 4:
            size = _LEN.unpack_from(self._inbuf)[0]
            if size > MAX_FRAME:
                events.append(self._end("the robot program's process sent a frame that is too large"))
                return events
            if len(self._inbuf) < 4 + size:
                break
            body = bytes(self._inbuf[4:4 + size])
            del self._inbuf[:4 + size]
            try:
                event = self._event(json.loads(body))
            except (ValueError, TypeError, KeyError, IndexError, RecursionError) as exc:
                events.append(self._end(f"the robot program's process sent a malformed message ({exc})"))
                return events
            if event is not None:
                events.append(event)
        if eof:
            events.append(self._end(self._exit_text()))
        return events

    def _event(self, msg: Any) -> Event | None:
        kind = msg["t"]
        if kind == "msg":
            text_kind = msg["k"]
            if text_kind not in KINDS:
                raise ValueError(f"unknown message kind {text_kind!r}")
            return Message(text_kind, _text(msg["x"]), _int32(msg.get("c", 0)), _text(msg.get("l", "")),
                           _text(msg.get("s", "")))
        if kind == "loaded":
            self._loaded = True
            self._busy_since = None
            return Loaded()
        if kind == "load_failed":
            self._busy_since = None
            return LoadFailed(_text(msg["x"]))
        if kind == "result":
            if self._returned >= self._sent:
                raise ValueError("a result for no call")
            self._returned += 1
            self._busy_since = None
            took = msg["took"]
            if isinstance(took, bool) or not isinstance(took, (int, float)) or not math.isfinite(took) or took < 0:
                raise ValueError(f"bad call time {took!r}")
            outputs, problems = sanitize_outputs(msg.get("out"), msg.get("left"), msg.get("right"),
                                                 msg.get("dout", 0), msg.get("lcd"))
            error = msg.get("err")
            if error is not None:
                error = tuple(_text(part) for part in error[:3]) + ("",) * (3 - len(error[:3]))
            dropped = msg.get("dropped", 0)
            dropped = dropped if isinstance(dropped, int) and not isinstance(dropped, bool) and dropped >= 0 else 0
            return Result(float(took), outputs, problems, error, dropped)
        raise ValueError(f"unknown message {kind!r}")

    def _exited(self) -> bool:
        """Whether the program's process has ended, left unreaped (a zombie keeps its pid, so
        its process group cannot be another's when stop() kills it)."""
        return self._exit_code() is not None

    def _exit_code(self) -> int | None:
        """The ended process's code (minus the signal that killed it), None while it runs."""
        proc = self.proc
        if proc is None:
            return None
        if proc.returncode is not None:
            return proc.returncode
        try:
            info = os.waitid(os.P_PID, proc.pid, os.WEXITED | os.WNOHANG | os.WNOWAIT)
        except ChildProcessError:  # reaped elsewhere
            return proc.poll()
        except (AttributeError, OSError):  # no waitid here
            return proc.poll()
        if info is None:
            return None
        return info.si_status if info.si_code == os.CLD_EXITED else -info.si_status

    def _exit_text(self) -> str:
        code = self._exit_code()
        if code is None:
            return "the robot program's process closed its channel"
        if code < 0:
            try:
                name = signal.Signals(-code).name
            except ValueError:
                name = f"signal {-code}"
            return f"the robot program's process was killed by {name}"
        return f"the robot program's process exited with code {code}"

    def _end(self, text: str) -> Ended:
        self._ended = True
        self._busy_since = None
        self.stop()
        return Ended(text)

    def stop(self) -> None:
        """Kill the child and every process it forked (its process group: a robot program is
        not asked, it may be stuck) and reap it aside."""
        if self.sock is not None:
            try:
                self.sock.close()
            except OSError:
                pass
            self.sock = None
        proc, self.proc = self.proc, None
        if proc is not None:
            # The group is the child's pid; the child is not reaped yet (a zombie at most), so
            # that pid is no other's. What it forked dies even after the child itself ended.
            try:
                os.killpg(proc.pid, signal.SIGKILL)
            except (ProcessLookupError, PermissionError):  # the group is gone already
                pass
            except OSError:
                try:
                    proc.kill()
                except OSError:
                    pass
            if proc.returncode is None:
                threading.Thread(target=proc.wait, name="fieldbox-reap", daemon=True).start()

    def __del__(self) -> None:
        try:
            self.stop()
        except Exception:  # noqa: BLE001 - at interpreter exit
            pass


def _text(value: Any) -> str:
    if not isinstance(value, str):
        raise TypeError(f"text expected, not {type(value).__name__}")
    return value[:MAX_TEXT]


def _int32(value: Any) -> int:
    if isinstance(value, bool) or not isinstance(value, int):
        return 0
    return max(-0x80000000, min(0x7FFFFFFF, value))


def check_program(path: str | os.PathLike) -> None:
    """What can be known of a program file without running it: it reads, it compiles, and its
    top level defines ``robot_periodic``. Raises ProgramError naming the file and line."""
    import ast

    path = os.fspath(path)
    tree = compile_program(path, ast.PyCF_ONLY_AST)
    names = set()
    for node in tree.body:
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
            names.add(node.name)
        elif isinstance(node, (ast.Import, ast.ImportFrom)):
            names.update((alias.asname or alias.name).split(".")[0] for alias in node.names)
        elif isinstance(node, (ast.Assign, ast.AnnAssign)):
            targets = node.targets if isinstance(node, ast.Assign) else [node.target]
            names.update(t.id for t in targets if isinstance(t, ast.Name))
    if "robot_periodic" not in names and not any(isinstance(node, ast.ImportFrom) and
                                                 any(a.name == "*" for a in node.names) for node in tree.body):
        raise ProgramError(f"{path}: defines no robot_periodic(state, robot) function")


# -- the child ---------------------------------------------------------------------------------
class _Channel:
    """The child's end: blocking, one frame at a time."""

    def __init__(self, sock: socket.socket) -> None:
        self.sock = sock
        self.lock = threading.Lock()  # a program's own threads may print too
        self.window_start = 0.0
        self.window_count = 0
        self.dropped = 0

    def send(self, msg: dict) -> None:
        try:
            data = json.dumps(msg, default=_show).encode()
        except (ValueError, TypeError, RecursionError):  # a circular list in the outputs
            for key in ("out", "left", "right", "lcd"):
                msg.pop(key, None)
            data = json.dumps(msg, default=_show).encode()
        with self.lock:
            self.sock.sendall(_LEN.pack(len(data)) + data)

    def message(self, kind: str, text: str, code: int = 0, location: str = "", call_stack: str = "") -> None:
        now = time.monotonic()
        with self.lock:
            if now - self.window_start >= PERIOD:
                self.window_start, self.window_count = now, 0
            self.window_count += 1
            if self.window_count > MAX_MESSAGES_PER_WINDOW:
                self.dropped += 1
                return
        self.send({"t": "msg", "k": kind, "x": str(text)[:MAX_TEXT], "c": _int32(code),
                   "l": str(location)[:MAX_TEXT], "s": str(call_stack)[-MAX_TEXT:]})

    def receive(self) -> Any:
        head = self._exactly(4)
        if head is None:
            return None
        size = _LEN.unpack(head)[0]
        body = self._exactly(size)
        return None if body is None else pickle.loads(body)

    def _exactly(self, n: int) -> bytes | None:
        parts = []
        while n:
            chunk = self.sock.recv(n)
            if not chunk:
                return None
            parts.append(chunk)
            n -= len(chunk)
        return b"".join(parts)


class _ConsoleStream:
    """``sys.stdout`` / ``sys.stderr`` of the program's process: whole lines to the console."""

    def __init__(self, channel: _Channel) -> None:
        self.channel = channel
        self.partial = ""

    def write(self, text: Any) -> int:
        text = str(text)
        self.partial += text
        if "\n" in self.partial:
            *lines, self.partial = self.partial.split("\n")
            for line in lines:
                self.channel.message("stdout", line + "\n")
        if len(self.partial) > MAX_TEXT:
            self.flush()
        return len(text)

    def flush(self) -> None:
        if self.partial:
            text, self.partial = self.partial, ""
            self.channel.message("stdout", text)

    def isatty(self) -> bool:
        return False

    def writable(self) -> bool:
        return True


def _die_with_parent() -> None:
    """Gone with the process that started it, even if that one is killed."""
    if sys.platform.startswith("linux"):
        try:
            import ctypes

            ctypes.CDLL(None, use_errno=True).prctl(1, signal.SIGKILL)  # PR_SET_PDEATHSIG
        except (OSError, AttributeError):
            pass


def child_main(fd: int, path: str, memory_limit: int) -> int:
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl+C reaches the group: the wire decides
    # Imported here, in the program's own process: the wire's process needs this module, and no more.
    from .process_tuning import below_the_wire

    below_the_wire()
    _die_with_parent()
    if memory_limit > 0:
        try:
            import resource

            resource.setrlimit(resource.RLIMIT_AS, (memory_limit, memory_limit))
        except (ImportError, ValueError, OSError):
            pass
    channel = _Channel(socket.socket(fileno=fd))
    sys.stdout = sys.stderr = _ConsoleStream(channel)  # type: ignore[assignment]
    folder = os.path.dirname(path)
    if folder not in sys.path:
        sys.path.insert(0, folder)  # helpers beside the program import as they would on a robot
    robot = RobotApi(channel.message)
    try:
        try:
            program = load_program(path, console=robot.print)
        except ProgramError as exc:
            channel.send({"t": "load_failed", "x": str(exc)[:MAX_TEXT]})
            return 1
        except BaseException as exc:  # noqa: BLE001 - KeyboardInterrupt at the top level, say
            channel.send({"t": "load_failed", "x": f"{path}: error while loading: {type(exc).__name__}: {exc}"[:MAX_TEXT]})
            return 1
        channel.send({"t": "loaded"})
        while True:
            msg = channel.receive()
            if msg is None:
                return 0
            _, _, state, (robot.ds_digital_in, robot.ds_analog_in) = msg
            error = None
            t0 = time.perf_counter()
            try:
                program(state, robot)
            except BaseException as exc:  # noqa: BLE001 - every exception is a result
                error = list(describe_exception(exc))
            took = time.perf_counter() - t0
            sys.stdout.flush()
            dropped, channel.dropped = channel.dropped, 0
            channel.send({"t": "result", "took": took, "out": robot.outputs, "left": robot.left_rumble,
                          "right": robot.right_rumble, "dout": robot.ds_digital_out, "lcd": robot.lcd,
                          "err": error, "dropped": dropped})
    except (OSError, EOFError):
        return 0  # the wire is gone
