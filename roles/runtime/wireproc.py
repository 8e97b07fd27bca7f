"""The wire in a process of its own: :class:`ProcessEngine` and its child.

Under the app, a wire thread shares one GIL with the drawing, and the 20 ms beat wavers;
the same field in a process of its own beside a busy app keeps it (docs/figures.md,
"Why"). So the app runs its field in a child
process (:data:`CHILD_CODE`, or ``python -m roles.runtime.wireproc FD``) and reads *views* of it.

The child runs a :class:`~roles.runtime.engine.ThreadEngine` (real sockets, log files, the same
switch interval) and serves one socket pair (``multiprocessing.connection`` framing: a 4-byte
length, then one pickled message). The messages are the frozen dataclasses below, the same
for a classroom's seats (roles/runtime/classroom.py):

* to the wire: :class:`Configure` first (a classroom's seat: :class:`Join`); then
  :class:`Call` (a :class:`~roles.cores.commands.Command`: nothing else changes the field),
  :class:`Tapping`, :class:`Resync`, :class:`Stop`;
* from the wire: :class:`Started` or :class:`Failed`; :class:`Views`; :class:`Taps`;
  :class:`Answer`; :class:`LogLine`, :class:`Problem`, :class:`LogErrors` and
  :class:`LogFolder` (a new one after the first was deleted); a classroom's :class:`SeatChanged`.

``units`` is a :meth:`roles.runtime.viewwire.ViewSender.payload`: per *unit* (a station's DS and
roboRIO together, the FMS, the faults), the frozen views of its cores (roles/cores/views.py)
with only the new items of their streams. Views are made **on the wire thread**, one unit
every :data:`SNAPSHOT_TICK`, so each is consistent and none holds the loop long (a
six-station field: a full round in 160 ms). A reply to a call carries the views of the unit
it touched, made on the wire thread after the call (so in order with the others): the app
shows the change at once. A payload the child had to drop (the parent not reading) or one
the parent could not apply starts every stream over whole (``resync``). Taps are recorded
only while the parent has some, and sent every :data:`TAP_PERIOD`: the parent's taps see the
child's receive times (the same ``time.monotonic`` on Linux).

The app reads :attr:`ProcessEngine.field`, the latest :class:`~roles.runtime.engine.FieldView`
(each view in it says when it was made: ``at``), replaced whole as views arrive: changes go
through :meth:`ProcessEngine.execute` and :meth:`ProcessEngine.submit_command`
with a typed command (roles/cores/commands.py).

Taps run on the reader's thread (``fieldbox-views``), as they ran on the wire thread
before: a tap must not call the engine (it would wait for the reply its own thread reads,
and time out after :data:`CALL_TIMEOUT`).

Its figures (``benchmarks/outside.py``, ``field.py --app``, ``memory.py``): docs/figures.md.
"""

from __future__ import annotations

import collections
import functools
import gc
import itertools
import logging
import os
import pickle
import queue
import signal
import socket
import subprocess
import sys
import threading
import time
from concurrent.futures import Future, TimeoutError as FutureTimeout
from dataclasses import dataclass, replace
from multiprocessing.connection import Connection
from typing import Any

from ..cores.commands import Command
from ..cores.core import CommandError
from .engine import RESTART_KEY, Engine, FieldView, StationView, ThreadEngine
from .field import Field, FieldConfig
from .viewwire import NOTHING, Payload, ViewReceiver, ViewSender, unit_keys
from .process_tuning import GC_PERIOD, full_collection, quiet_collector, tune_wire_thread
from .program_host import ROOT, child_environment
from .shell import Tap, TapRecord

log = logging.getLogger("fieldbox.wireproc")

#: How often the child sends views, and how many units each time (a station's changes
#: take the wire's loop about 0.5 ms to find and pickle; one unit per beat: each unit is
#: at most 160 ms old in the app, whose panels redraw every 100 ms).
SNAPSHOT_TICK = 0.020
UNITS_PER_TICK = 1
#: Messages queued for the parent at most before views and taps are dropped (a parent
#: that stopped reading must not grow the child).
OUT_BACKLOG = 500
#: How often recorded tap batches go to the parent (only while it has taps).
TAP_PERIOD = 0.050
#: Taps cross the pipe in batches of plain tuples, in :class:`~roles.runtime.shell.TapRecord`'s
#: field order, and become records again on the app's side: a batch of records pickles ten
#: times slower than one of tuples (4.8 against 0.36 us a packet, and unpickles 4.1 against 0.3).
#: Taps recorded but not yet sent, at most (a parent that stopped reading loses the oldest).
TAP_BACKLOG = 50_000
#: How many (role, link, direction, kind, remote, local) the app's side keeps one copy of
#: (roles are few; addresses are bounded by this, the cache starting over when full).
SHARED_NAMES = 4096
CALL_TIMEOUT = 5.0
START_TIMEOUT = 20.0
STOP_TIMEOUT = 3.0
PROTOCOL = pickle.HIGHEST_PROTOCOL

#: How the child starts (``python -m roles.runtime.wireproc FD`` does the same, with ssl). The wire
#: never speaks TLS, and asyncio imports ssl only if it can: without it the child is a few MB
#: smaller (libssl and OpenSSL's start-up).
CHILD_CODE = ("import sys; sys.modules['ssl'] = None; "
              "from roles.runtime.wireproc import child_main; sys.exit(child_main(int(sys.argv[1])))")



# -- what crosses ----------------------------------------------------------------------------
@dataclass(frozen=True)
class Seat:
    """Who an app is to the wire: ``kind`` "owner" (the app whose wire process it is), or a
    classroom's "driver" (of ``team``), "observer" or "teacher"."""

    kind: str
    team: int | None = None

    def label(self) -> str:
        """For the host's log: "driver of team 254", "observer", "teacher"."""
        return f"driver of team {self.team}" if self.kind == "driver" else self.kind

    def describe(self) -> str:
        if self.kind == "driver":
            return f"you drive team {self.team}"
        return "you are the teacher" if self.kind == "teacher" else "you watch"


@dataclass(frozen=True)
class TakeBack:
    """A classroom's teacher takes a station back from its driver (who then watches)."""

    team: int


@dataclass(frozen=True, slots=True)
class Configure:
    """The wire process's first message: the field to run."""

    config: FieldConfig


@dataclass(frozen=True, slots=True)
class Join:
    """A classroom seat's first message: "driver", "observer" or ("teacher", key)."""

    want: object


@dataclass(frozen=True, slots=True)
class Call:
    """A request, answered by an :class:`Answer` with the same ``ident``: a command (a
    classroom's teacher also sends a :class:`TakeBack`). Whatever arrives is checked."""

    ident: int
    request: object


@dataclass(frozen=True, slots=True)
class Tapping:
    """Send :class:`Taps` (``on``) or stop."""

    on: bool


@dataclass(frozen=True, slots=True)
class Resync:
    """The app could not apply views: every stream goes whole again."""


@dataclass(frozen=True, slots=True)
class Stop:
    """The app is done: the wire process's field stops; a classroom's seat leaves."""


@dataclass(frozen=True, slots=True)
class Started:
    """The field runs: its stations ``(station, team, ds name, rio name)``, addresses, first views."""

    layout: tuple
    bound: dict
    fms_name: str
    fms_note: str | None
    problems: tuple[str, ...]
    views: Payload
    priority: tuple[str, int]
    log_folder: str | None
    seat: Seat = Seat("owner")
    config: FieldConfig | None = None  # what a classroom's field runs


@dataclass(frozen=True, slots=True)
class Failed:
    """The field could not start: ``error`` "OSError" or "ValueError", and why."""

    error: str
    message: str


@dataclass(frozen=True, slots=True)
class Views:
    payload: Payload


@dataclass(frozen=True, slots=True)
class Taps:
    """Packets tapped, as tuples in :class:`~roles.runtime.shell.TapRecord`'s field order."""

    records: list


@dataclass(frozen=True, slots=True)
class Answer:
    """The outcome of the :class:`Call` ``ident``: its value, or (``ok`` False) the exception."""

    ident: int
    ok: bool
    value: object
    views: Payload  # of what it changed (NOTHING where they went to every seat first)


@dataclass(frozen=True, slots=True)
class LogLine:
    level: int
    name: str
    text: str


@dataclass(frozen=True, slots=True)
class Problem:
    text: str


@dataclass(frozen=True, slots=True)
class LogErrors:
    count: int


@dataclass(frozen=True, slots=True)
class LogFolder:
    path: str | None


@dataclass(frozen=True, slots=True)
class SeatChanged:
    seat: Seat


# -- the child ---------------------------------------------------------------------------------

def unit_of(field, host: str | None) -> list:
    """The unit a command to ``host`` changes (sent with its answer)."""
    if host is None:
        return ["faults"]
    if host == field.fms_name:
        return ["fms"]
    for i, st in enumerate(field.stations):
        if host in (st.ds_name, st.rio_name):
            return [("station", i)]
    return []

class _ForwardLog(logging.Handler):
    """The child's log records, sent to the parent's logging (the child has no terminal) by
    the writer thread: the wire thread never waits on the pipe."""

    def __init__(self, child: "_Child") -> None:
        super().__init__(logging.INFO)
        self.child = child

    def emit(self, record: logging.LogRecord) -> None:
        try:
            self.child.logs.append(LogLine(record.levelno, record.name, self.format(record)))
        except Exception:
            pass


class _Child:
    def __init__(self, conn: Connection) -> None:
        self.conn = conn
        # engine and views: None until wire_main sets them, before the first message is read
        self.engine: ThreadEngine = None  # type: ignore[assignment]
        self.taps: collections.deque = collections.deque(maxlen=TAP_BACKLOG)
        self.tapping = False
        self.logs: collections.deque = collections.deque(maxlen=1000)
        self.stopping = threading.Event()
        self.outq: queue.SimpleQueue = queue.SimpleQueue()
        self.dropped = 0
        self.writer: threading.Thread | None = None
        self.views: ViewSender = None  # type: ignore[assignment]
        self.problems_sent = 0
        self.log_errors_sent = 0
        self.log_folder_sent: str | None = None

    def send(self, msg: object, *, droppable: bool = False) -> bool:
        """Queue a message for the writer thread (any thread may call this; it never waits on
        the pipe). A parent that stops reading loses views and taps (``droppable``),
        counted in ``dropped``, never replies; the queue stays bounded. False if dropped."""
        if droppable and self.outq.qsize() >= OUT_BACKLOG:
            self.dropped += 1
            return False
        self.outq.put(pickle.dumps(msg, PROTOCOL))
        return True

    def write(self) -> None:
        """The writer thread: sends what ``send`` queued. It holds the GIL only to take
        bytes off the queue: the pipe's system calls let it go."""
        try:
            while True:
                data = self.outq.get()
                if data is None:
                    return
                self.conn.send_bytes(data)
        except (OSError, EOFError, ValueError):  # the parent went away
            self.hang_up()

    # -- views (made on the wire thread: roles/runtime/viewwire.py) ------------------------------
    def payload(self, keys) -> Payload:
        """What changed in ``keys``' units since they were last sent (wire thread only)."""
        return self.views.payload(keys)

    def dump(self, keys) -> Payload:
        return self.engine.runtime.call(functools.partial(self.payload, keys)).result(timeout=CALL_TIMEOUT)

    def record(self, r: TapRecord) -> None:  # a tap, wire thread
        # Batched as plain tuples: see TAP_BACKLOG.
        self.taps.append((r.role, r.link, r.direction, r.kind, r.data, r.remote, r.local, r.time))

    # -- the loops ----------------------------------------------------------------------------
    def start_pump(self) -> None:
        """Views every tick and tap batches every TAP_PERIOD, run as callbacks of the
        wire's own loop: the child's hot path stays on one thread (a second thread pickling
        and sending fought the wire for the GIL: p99 22.7 ms under the app)."""
        keys = unit_keys(self.engine.field)
        turn = itertools.cycle(keys)
        per_tick = min(UNITS_PER_TICK, len(keys))
        loop = self.engine.runtime.loop
        state = {"next": time.monotonic(), "taps": time.monotonic(), "gc": time.monotonic() + GC_PERIOD}

        def tick() -> None:
            if self.stopping.is_set():
                return
            try:
                now = time.monotonic()
                if not self.send(Views(self.payload([next(turn) for _ in range(per_tick)])),
                                 droppable=True):
                    self.views.resync()  # the parent missed changes: all go whole again
                self.send_logs()
                self.send_problems()
                if now - state["taps"] >= TAP_PERIOD:
                    state["taps"] = now
                    n = len(self.taps)
                    if n:
                        self.send(Taps([self.taps.popleft() for _ in range(n)]), droppable=True)
                if now >= state["gc"]:
                    state["gc"] = now + GC_PERIOD
                    full_collection()
            except Exception:  # views failed: say so, and let the parent see the wire end
                log.exception("wire process: views stopped")
                try:
                    self.send_logs()
                except Exception:
                    pass
                self.hang_up()
                return
            state["next"] += SNAPSHOT_TICK
            if state["next"] < time.monotonic() - SNAPSHOT_TICK:  # far behind: no burst
                state["next"] = time.monotonic()
            loop.call_at(state["next"], tick)

        loop.call_soon_threadsafe(tick)

    def hang_up(self) -> None:
        """End the service: wakes the request loop (blocked reading) with an end of file."""
        self.stopping.set()
        try:
            sock = socket.socket(fileno=os.dup(self.conn.fileno()))
        except (OSError, ValueError):
            return
        try:
            sock.shutdown(socket.SHUT_RDWR)
        except OSError:
            pass
        finally:
            sock.close()

    def send_logs(self) -> None:
        while self.logs:
            self.send(self.logs.popleft())

    def send_problems(self) -> None:
        """What went wrong since start (log files that fail), and the log's failed writes."""
        engine = self.engine
        problems = engine.problems
        while self.problems_sent < len(problems):
            self.send(Problem(problems[self.problems_sent]))
            self.problems_sent += 1
        if engine.log_errors != self.log_errors_sent:
            self.log_errors_sent = engine.log_errors
            self.send(LogErrors(self.log_errors_sent))
        folder = engine.log_folder
        if folder != self.log_folder_sent:  # the first was deleted: the logs go on in another
            self.log_folder_sent = folder
            self.send(LogFolder(folder))

    def answer(self, msg: Call) -> None:
        ident, payload, host = msg.ident, msg.request, None
        engine = self.engine
        field = engine.field
        try:
            if not isinstance(payload, Command):
                raise CommandError(f"the wire process takes commands only, not {type(payload).__name__}")
            host = field.host_for(payload)
            value = engine.call(functools.partial(_execute, field, payload, engine), host)
            ok = True
        except BaseException as exc:  # noqa: BLE001 - handed to the parent
            ok, value = False, _portable(exc)
        reply = functools.partial(self.reply, ident, ok, value, unit_of(self.engine.field, host))
        try:  # on the wire thread: in order with the other views
            engine.runtime.call(reply).result(timeout=CALL_TIMEOUT)
        except Exception:  # the wire's loop has ended: the answer goes without views
            self.send_reply(ident, ok, value, NOTHING)

    def reply(self, ident: int, ok: bool, value: Any, keys: list) -> None:
        """A reply with fresh views of the units the call touched (wire thread)."""
        try:
            units = self.payload(keys)
        except Exception:
            log.exception("wire process: views failed")
            units = NOTHING
            self.views.resync()  # what it had taken as sent was not: all whole again
        self.send_reply(ident, ok, value, units)

    def send_reply(self, ident: int, ok: bool, value: Any, units: Payload) -> None:
        """Queue a reply that will pickle: a value that will not becomes a RuntimeError saying
        so; views that will not are left out (and the next ones go whole)."""
        try:
            self.send(Answer(ident, ok, value, units))
            return
        except Exception:
            pass
        self.views.resync()  # the views sent nothing this time: all whole again
        try:
            self.send(Answer(ident, ok, value, NOTHING))
            log.exception("wire process: views failed")  # the value went: the views were at fault
            return
        except Exception as exc:
            ok, value = False, RuntimeError(f"cannot return the result: {exc}")
        self.send(Answer(ident, ok, value, NOTHING))

    def start_writer(self) -> None:
        self.writer = threading.Thread(target=self.write, name="fieldbox-pipe", daemon=True)
        self.writer.start()

    def end_writer(self) -> None:
        """Send what is queued, then stop the writer."""
        self.outq.put(None)
        if self.writer is not None:
            self.writer.join(2.0)

    def serve(self) -> None:
        self.start_pump()
        try:
            while not self.stopping.is_set():
                try:
                    msg = pickle.loads(self.conn.recv_bytes())
                except (EOFError, OSError):
                    break
                if isinstance(msg, Stop):
                    break
                if isinstance(msg, Tapping):
                    if msg.on and not self.tapping:
                        self.engine.add_tap(self.record)
                    elif not msg.on and self.tapping:
                        self.engine.remove_tap(self.record)
                        self.taps.clear()
                    self.tapping = msg.on
                elif isinstance(msg, Call):
                    self.answer(msg)
                elif isinstance(msg, Resync):  # the parent could not apply views
                    self.engine.runtime.call(self.views.resync)
        finally:
            self.stopping.set()
            self.end_writer()


def started_message(engine: ThreadEngine, views: Payload, priority: tuple[str, int], seat: Seat = Seat("owner"),
                    config: FieldConfig | None = None) -> Started:
    """What an app is told first: the field's stations and addresses, its first views."""
    field = engine.field
    return Started(tuple((st.station, st.team, st.ds_name, st.rio_name) for st in field.stations), field.bound,
                   field.fms_name, field.fms_note, tuple(engine.problems), views, priority,
                   str(engine.log.folder) if engine.log is not None else None, seat, config)


def _execute(field: "Field", command, engine: Engine):
    return field.execute(command, engine.now())


def _portable(exc: BaseException) -> BaseException:
    """The exception itself if it survives pickling as itself, else a RuntimeError saying it."""
    try:
        copy = pickle.loads(pickle.dumps(exc, PROTOCOL))
        if type(copy) is type(exc) and str(copy) == str(exc):
            return exc
    except Exception:
        pass
    if isinstance(exc, CommandError):
        return CommandError(str(exc))
    return RuntimeError(f"{type(exc).__name__}: {exc}")


def child_main(fd: int) -> int:
    # Ctrl+C in the terminal reaches the whole process group: the parent decides when the
    # field stops (it says "stop", or its end closes the socket pair).
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    conn = Connection(fd)
    child = _Child(conn)
    child.start_writer()
    root = logging.getLogger()
    root.handlers[:] = [_ForwardLog(child)]
    root.setLevel(logging.INFO)
    try:
        first = pickle.loads(conn.recv_bytes())
    except (EOFError, OSError):
        child.end_writer()
        return 1
    if not isinstance(first, Configure):
        child.send(Failed("ValueError", f"the wire process starts with a Configure, not {type(first).__name__}"))
        child.end_writer()
        return 1
    config = first.config
    quiet_collector()
    engine = ThreadEngine(config)
    try:
        engine.start()
    except (OSError, ValueError) as exc:
        child.send_logs()
        child.send(Failed("OSError" if isinstance(exc, OSError) else "ValueError", str(exc)))
        child.end_writer()
        return 1
    child.engine = engine
    child.views = ViewSender(engine.field, engine.now)
    priority = engine.runtime.call(tune_wire_thread).result(timeout=CALL_TIMEOUT)
    log.info("wire process: the wire thread runs at %s", priority[0])
    debug = os.environ.get("FIELDBOX_WIREPROC_DEBUG")
    if debug:  # diagnosis: the loop's slow callbacks (asyncio debug mode) logged to this file
        handler = logging.FileHandler(debug)
        handler.setFormatter(logging.Formatter("%(asctime)s %(threadName)s %(name)s %(message)s"))
        root.addHandler(handler)
        root.setLevel(logging.DEBUG)
        loop = engine.runtime.loop
        loop.slow_callback_duration = 0.005
        loop.call_soon_threadsafe(loop.set_debug, True)
        started: list = []

        def gc_watch(phase: str, info: dict) -> None:
            if phase == "start":
                started[:] = [time.perf_counter(), time.process_time()]
            elif started:
                wall, cpu = time.perf_counter() - started[0], time.process_time() - started[1]
                if wall > 0.003:
                    log.warning("gc gen %d: %.1f ms (cpu %.1f ms), %d collected, %d tracked", info["generation"],
                                wall * 1e3, cpu * 1e3, info["collected"], len(gc.get_objects()))

        gc.callbacks.append(gc_watch)
    try:
        field = engine.field
        child.problems_sent = len(engine.problems)
        child.send(started_message(engine, child.dump(unit_keys(field)), priority))
        child.serve()
    except (OSError, EOFError):
        pass
    except Exception:  # said to the parent's log if it still listens
        log.exception("wire process failed")
        try:
            child.send_logs()
        except Exception:
            pass
        return 1
    finally:
        child.end_writer()  # what is queued (a last log line) goes before the pipe closes
        engine.stop()
        try:
            conn.close()
        except OSError:
            pass
    return 0


# -- the parent ----------------------------------------------------------------------------------
def exit_words(code: int | None) -> str:
    """A process's end as a user reads it: "exit code 3", "killed by SIGKILL"."""
    if code is None:
        return "exit code unknown"
    if code < 0:
        try:
            return f"killed by {signal.Signals(-code).name}"
        except ValueError:
            return f"killed by signal {-code}"
    return f"exit code {code}"


class ProcessEngine(Engine):
    """A field whose wire runs in a child process; ``field`` is the latest views of it."""

    field: FieldView
    #: Who this app is to a shared wire (a classroom's :class:`JoinedEngine`); None: its own.
    seat: Seat | None = None

    def __init__(self, config: FieldConfig, stderr: Any = subprocess.DEVNULL) -> None:
        self.config = config
        #: The latest views of the field (empty until it starts), replaced whole by the reader.
        self.field = FieldView(config, (), None, None, time.monotonic())
        #: Things that went wrong (shown by the app): log files, the child's end.
        self.problems: list[str] = []
        self.proc: subprocess.Popen | None = None
        self.conn: Connection | None = None
        self._stderr = stderr
        self._send_lock = threading.Lock()
        self._ids = itertools.count(1)
        self._pending: dict[int, Future] = {}
        self._taps: list[Tap] = []
        self._shared_names: dict[tuple, tuple] = {}
        self._reader: threading.Thread | None = None
        self._stopping = False
        self.ended = False
        self.end_reason: str | None = None
        self._views = ViewReceiver()
        #: The wire thread's priority in words (roles/runtime/process_tuning.py), and its thread id.
        self.priority: tuple[str, int] = ("", 0)
        #: Payloads of views applied (a test waits on this).
        self.updates = 0
        #: Writes to the child's log files that failed, and the folder they go to (None: none).
        self.log_errors = 0
        self.log_folder: str | None = None
        #: When the child last sent anything (it sends every 20 ms while its wire runs).
        self.heard_at = time.monotonic()
        self._outq: queue.SimpleQueue = queue.SimpleQueue()
        self._writer: threading.Thread | None = None

    # -- start and stop --------------------------------------------------------------------
    def start(self, timeout: float = START_TIMEOUT) -> None:
        """Start the child and wait until its field is bound; raises OSError/ValueError
        with the child's message if it cannot start."""
        ours, theirs = socket.socketpair()
        env = child_environment()
        try:
            self.proc = subprocess.Popen([sys.executable, "-c", CHILD_CODE, str(theirs.fileno())],
                                         pass_fds=[theirs.fileno()], stdin=subprocess.DEVNULL,
                                         stdout=subprocess.DEVNULL, stderr=self._stderr, env=env, cwd=ROOT)
        finally:
            theirs.close()
        self.conn = Connection(ours.detach())
        try:
            self._send(Configure(self.config))
            if not self.conn.poll(timeout):
                raise OSError(f"the wire process did not start within {timeout:g} s")
            try:
                msg = pickle.loads(self.conn.recv_bytes())
            except (EOFError, OSError):
                raise OSError(f"the wire process ended while starting ({exit_words(self._exit_code())})") from None
            while isinstance(msg, LogLine):
                self._log(msg)
                msg = pickle.loads(self.conn.recv_bytes())
            if isinstance(msg, Failed):
                raise (OSError if msg.error == "OSError" else ValueError)(msg.message)
            if not isinstance(msg, Started):
                raise OSError(f"the wire process said {type(msg).__name__} before it started")
        except BaseException:
            self._stopping = True
            self._end_child()
            raise
        self._started(msg)
        self._begin_threads()

    def _started(self, msg: Started) -> None:
        """The field the wire runs and its first views; then read on."""
        self.priority, self.log_folder = msg.priority, msg.log_folder
        self.field = FieldView(self.config, tuple(StationView(*item) for item in msg.layout), None, None,
                               time.monotonic(), msg.fms_name, msg.fms_note, msg.bound)
        self.problems.extend(msg.problems)
        self._apply(msg.views)

    def _begin_threads(self) -> None:
        """The views' reader and the requests' writer, once the field is known."""
        self.heard_at = time.monotonic()
        self._reader = threading.Thread(target=self._read, name="fieldbox-views", daemon=True)
        self._reader.start()
        self._writer = threading.Thread(target=self._write, name="fieldbox-requests", daemon=True)
        self._writer.start()

    def stop(self) -> None:
        self._stopping = True
        if self.proc is None:
            return
        self._outq.put(pickle.dumps(Stop(), PROTOCOL))
        self._outq.put(None)  # the sender thread ends after Stop
        if self._writer is not None:
            self._writer.join(0.5)
        self._end_child()
        if self._reader is not None and self._reader is not threading.current_thread():
            self._reader.join(2.0)
        self._fail_pending("the field was stopped")

    def _end_child(self) -> None:
        proc = self.proc
        if proc is not None:
            try:
                proc.wait(STOP_TIMEOUT)
            except subprocess.TimeoutExpired:
                proc.terminate()
                try:
                    proc.wait(1.0)
                except subprocess.TimeoutExpired:
                    proc.kill()
                    proc.wait()
        if self.conn is not None and (self._reader is None or not self._reader.is_alive()):
            self._close_conn()

    def _close_conn(self) -> None:
        if self.conn is not None:
            try:
                self.conn.close()
            except OSError:
                pass

    def _exit_code(self) -> int | None:
        if self.proc is None:
            return None
        try:
            return self.proc.wait(0.5)
        except subprocess.TimeoutExpired:
            return None

    # -- the views ----------------------------------------------------------------------------
    def _read(self) -> None:
        conn = self.conn
        assert conn is not None  # read once started
        try:
            while True:
                try:
                    msg = pickle.loads(conn.recv_bytes())
                except (EOFError, OSError, TypeError):  # TypeError: closed under the read (stop)
                    break
                self.heard_at = time.monotonic()
                try:
                    if isinstance(msg, Views):
                        self._apply(msg.payload)
                    elif isinstance(msg, Taps):
                        self._tap(msg.records)
                    elif isinstance(msg, Answer):
                        self._apply(msg.views)
                        future = self._pending.pop(msg.ident, None)
                        if future is not None:
                            if msg.ok:
                                future.set_result(msg.value)
                            else:  # the child sends an exception (_portable)
                                future.set_exception(msg.value if isinstance(msg.value, BaseException)
                                                     else RuntimeError(str(msg.value)))
                    elif isinstance(msg, LogLine):
                        self._log(msg)
                    elif isinstance(msg, Problem):
                        self.problems.append(msg.text)
                    elif isinstance(msg, LogErrors):
                        self.log_errors = msg.count
                    elif isinstance(msg, LogFolder):
                        self.log_folder = msg.path
                    elif isinstance(msg, SeatChanged):
                        self.seat = msg.seat
                    else:
                        raise TypeError(f"no such message: {type(msg).__name__}")
                except Exception:  # a bad message must not end the reader
                    log.exception("wire process: cannot use a %s message", type(msg).__name__)
        finally:
            self.ended = True
            if not self._stopping:
                how = exit_words(self._exit_code()) if self.proc is not None else "its connection closed"
                self.end_reason = f"the wire process ended ({how})"
                problem = f"{self.end_reason}: the field no longer runs; start it again ({RESTART_KEY})"
                log.error("%s", problem)
                self._show_ended(self.end_reason)
                self.problems.append(problem)
            self._fail_pending("the wire process has ended")
            self._close_conn()

    def _show_ended(self, why: str) -> None:
        """The views must not go on showing the last comms of a field that no longer runs:
        each DS's view loses its robot (no comms, no enable), as the robot lost its DS; each
        roboRIO's and the FMS's show nothing enabled or linked."""
        now, field = self.now(), self.field
        stations = tuple(replace(st, ds=st.ds and st.ds.wire_ended(now, why), rio=st.rio and st.rio.wire_ended())
                         for st in field.stations)
        self.field = replace(field, stations=stations, fms=field.fms and field.fms.wire_ended(), at=now)

    def _apply(self, payload: Payload) -> None:
        """A payload of views into the field (the reader's thread; start before it runs)."""
        try:
            shown = self._views.apply(payload)
        except Exception:
            # the two sides no longer agree on what the app has: everything whole again
            log.exception("wire process: views could not be applied; asking for all of it")
            self._send_quietly(Resync())
            return
        field = self.field
        stations, changes = list(field.stations), {}
        for key, roots in shown.items():
            if key in ("fms", "faults"):
                changes[key] = roots[key]
            else:
                i = int(key[1])
                stations[i] = replace(stations[i], ds=roots[f"s{i}.ds"], rio=roots[f"s{i}.rio"])
        # one new FieldView, swapped in whole: the app's thread never sees half of a payload
        self.field = replace(field, stations=tuple(stations), at=time.monotonic(), **changes)
        self.updates += 1

    def _tap(self, records: list) -> None:
        taps = list(self._taps)
        shared = self._shared_names
        for record in records:
            # Each batch comes unpickled with strings and addresses of its own: the names
            # and both addresses are made the ones already held, so that a packet kept (the
            # inspector keeps 50,000) costs its bytes, not seven new objects.
            names = record[:4] + record[5:7]
            known = shared.get(names)
            if known is None:
                if len(shared) >= SHARED_NAMES:
                    shared.clear()
                known = shared[names] = names
            role, link, direction, kind, remote, local = known
            tapped = TapRecord(role, link, direction, kind, record[4], remote, local, record[7])
            for tap in taps:
                try:
                    tap(tapped)
                except Exception:
                    log.exception("tap failed")

    @staticmethod
    def _log(msg: LogLine) -> None:
        logging.getLogger(msg.name).log(msg.level, "%s", msg.text)

    # -- the Engine interface ---------------------------------------------------------------
    def now(self) -> float:
        return time.monotonic()

    def age(self) -> float:
        return max(0.0, time.monotonic() - self.heard_at)

    def views(self, now: float) -> FieldView:
        return self.field  # the views the child sent

    def submit_command(self, command: Command) -> Future:
        return self._request(command)

    def submit(self, fn, host=None) -> Future:
        """Only a command crosses to the wire process (as :meth:`submit_command`)."""
        if isinstance(fn, Command):
            return self.submit_command(fn)
        raise TypeError(f"cannot send {fn!r} to the wire process: only a command goes "
                        "(roles/cores/commands.py)")

    def execute(self, command) -> None:
        self._wait(self.submit_command(command))

    def call(self, fn, host=None):
        return self._wait(self.submit(fn, host))

    def _wait(self, future: Future) -> Any:
        try:
            return future.result(timeout=CALL_TIMEOUT)
        except FutureTimeout:
            for ident, pending in list(self._pending.items()):
                if pending is future:
                    self._pending.pop(ident, None)
            raise CommandError(f"the wire process did not answer within {CALL_TIMEOUT:g} s") from None

    def _request(self, payload: object) -> Future:
        """Queue a request for the child; the future is its answer. Never waits: the bytes go
        out on the sender thread, so a child that stopped reading holds nothing here."""
        future: Future = Future()
        if self.ended or self.conn is None:
            future.set_exception(CommandError(f"the wire process has ended: start the field again ({RESTART_KEY})"))
            return future
        ident = next(self._ids)
        try:
            data = pickle.dumps(Call(ident, payload), PROTOCOL)
        except (pickle.PicklingError, TypeError, AttributeError) as exc:
            raise TypeError(f"cannot send {payload!r} to the wire process ({exc})") from None
        self._pending[ident] = future
        self._outq.put(data)
        return future

    def _write(self) -> None:
        """The sender thread: requests to the child, in order."""
        while True:
            data = self._outq.get()
            if data is None:
                return
            try:
                with self._send_lock:
                    # None once stopped: the AttributeError is caught below
                    self.conn.send_bytes(data)  # type: ignore[union-attr]
            except (OSError, ValueError, AttributeError):
                self._fail_pending(f"the wire process has ended: start the field again ({RESTART_KEY})")

    def _fail_pending(self, why: str) -> None:
        for ident in list(self._pending):
            future = self._pending.pop(ident, None)
            if future is not None and not future.done():
                future.set_exception(CommandError(why))

    def _send(self, msg: object) -> None:
        data = pickle.dumps(msg, PROTOCOL)
        assert self.conn is not None  # sent once started
        with self._send_lock:
            self.conn.send_bytes(data)

    def add_tap(self, tap: Tap) -> None:
        self._taps.append(tap)
        if len(self._taps) == 1:
            self._send_quietly(Tapping(True))

    def remove_tap(self, tap: Tap) -> None:
        if tap in self._taps:
            self._taps.remove(tap)
            if not self._taps:
                self._send_quietly(Tapping(False))

    def _send_quietly(self, msg: object) -> None:
        if self.ended or self.conn is None:
            return
        self._outq.put(pickle.dumps(msg, PROTOCOL))


if __name__ == "__main__":
    sys.exit(child_main(int(sys.argv[1])))
