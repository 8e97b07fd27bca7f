"""The wire in a process of its own: :class:`ProcessEngine` and its child.

Under the app, a wire thread shares one GIL with the drawing, and the 20 ms beat wavers;
the same field in a process of its own beside a busy app keeps it (docs/figures.md,
"Why"). So the app runs its field in a child
process (:data:`CHILD_CODE`, or ``python -m roles.runtime.wireproc FD``) and reads *views* of it.

The child runs a :class:`~roles.runtime.engine.ThreadEngine` (real sockets, log files, the same
switch interval) and a :class:`WireServer` on the wire's own loop, which serves *seats*: here
one, the app that started it (the "owner"), on a socket pair; a classroom's field
(roles/runtime/classroom.py) many, on a Unix socket. Each message is a 4-byte length, then one
pickled frozen dataclass (``multiprocessing.connection``'s framing, which the app reads with):

* to the wire: :class:`Configure` first (a classroom's seat: :class:`Join`); then
  :class:`Call` (a :class:`~roles.cores.commands.Command`: nothing else changes the field),
  :class:`Tapping`, :class:`Resync`, :class:`Stop`;
* from the wire: :class:`Started` or :class:`Failed`; :class:`Views`; :class:`Taps`;
  :class:`Answer`; :class:`LogLine`, :class:`Problem`, :class:`LogState` (its folder: a
  new one after the first was deleted); a classroom's :class:`SeatChanged`.

:class:`Views` carry a :meth:`roles.runtime.viewwire.ViewSender.payload`: per *unit* (a station's DS and
roboRIO together, the FMS, the faults), the frozen views of its cores (roles/cores/views.py)
with only the new items of their streams. Views are made **on the wire thread**, one unit
every :data:`SNAPSHOT_TICK`, so each is consistent and none holds the loop long (a
six-station field: a full round in 160 ms). The views of the unit a call touched go to every
seat right after the call, before its :class:`Answer`: the app shows the change at once. A
payload the owner's app did not read in time (it is dropped) or could not apply
(:class:`Resync`) starts every stream over whole. Taps are recorded
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

import asyncio
import collections
import dataclasses
import gc
import hmac
import itertools
import logging
import os
import pickle
import queue
import signal
import socket
import struct
import subprocess
import sys
import threading
import time
from concurrent.futures import Future, TimeoutError as FutureTimeout
from dataclasses import dataclass, replace
from multiprocessing.connection import Connection
from typing import Any

from ..cores.commands import FMS_COMMANDS, Command, Disable, Fault
from ..cores.core import CommandError
from .engine import RESTART_KEY, Engine, FieldView, StationView, ThreadEngine
from .field import Field, FieldConfig
from .viewwire import NOTHING, Payload, ViewReceiver, ViewSender, unit_keys
from .process_tuning import GC_PERIOD, full_collection, quiet_collector, tune_wire_thread
from .program_host import ROOT, child_environment
from .shell import Tap, TapRecord

log = logging.getLogger("fieldbox.wireproc")
seat_log = logging.getLogger("fieldbox.classroom")  # who joins and leaves a classroom's field

#: How often the child sends views, and how many units each time (a station's changes
#: take the wire's loop about 0.5 ms to find and pickle; one unit per beat: each unit is
#: at most 160 ms old in the app, whose panels redraw every 100 ms).
SNAPSHOT_TICK = 0.020
UNITS_PER_TICK = 1
#: How often recorded tap batches go to the parent (only while it has taps).
TAP_PERIOD = 0.050
#: Taps cross the pipe in batches of plain tuples, in :class:`~roles.runtime.shell.TapRecord`'s
#: field order, and become records again on the app's side: a batch of records pickles ten
#: times slower than one of tuples (4.8 against 0.36 us a packet, and unpickles 4.1 against 0.3).
#: Taps recorded but not yet sent, at most.
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


#: The app whose wire process it is: every command is its own.
OWNER = Seat("owner")


@dataclass(frozen=True)
class TakeBack:
    """A classroom's teacher takes a station back from its driver (who then watches)."""

    team: int


@dataclass(frozen=True, slots=True)
class Configure:
    """The wire process's first message: the field to run."""

    config: FieldConfig


#: What a seat asks for when it joins: "driver", "observer" or ("teacher", key).
SeatWant = str | tuple[str, str]


@dataclass(frozen=True, slots=True)
class Join:
    """A classroom seat's first message: "driver", "observer" or ("teacher", key)."""

    want: SeatWant


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
    seat: Seat = OWNER
    config: FieldConfig | None = None  # what a classroom's field runs
    #: The field's clock when it started: every seat counts its event times from it, so the
    #: same event reads the same in each tab.
    field_started: float | None = None


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
class LogState:
    """The log files' failed writes, and the folder they go to (None: none)."""

    errors: int
    folder: str | None


@dataclass(frozen=True, slots=True)
class SeatChanged:
    seat: Seat


# -- the server ---------------------------------------------------------------------------------
#: The largest message a seat may send (a command, a joystick update: a few hundred bytes);
#: a longer length closes the seat.
SEAT_MESSAGE_MAX = 1 << 20
#: Bytes waiting to go to one seat before it is closed as not reading (a few seconds of
#: everything, taps included).
SEAT_BUFFER_MAX = 32 << 20
#: Seats written to per turn of the wire's loop (WireServer.queue).
WRITES_PER_TURN = 4
_LENGTH = struct.Struct("!i")  # multiprocessing.Connection's framing, the joined app's side


class _Seat(asyncio.Protocol):
    """One joined app, on the wire's loop: its messages framed as multiprocessing's
    Connection frames them, its writes buffered by the loop's transport (never waited for)."""

    def __init__(self, host: "WireServer") -> None:
        self.host = host
        self.transport: asyncio.Transport | None = None
        self.seat: Seat | None = None  # None until it said "join"
        self.tapping = False
        self.closed = False
        self.queued = 0  # bytes in the host's queue for this seat
        self._buffer = bytearray()

    def connection_made(self, transport) -> None:
        self.transport = transport

    def data_received(self, data: bytes) -> None:
        buffer = self._buffer
        buffer += data
        while len(buffer) >= 4 and not self.closed:
            (size,) = _LENGTH.unpack_from(buffer)
            if not 0 <= size <= SEAT_MESSAGE_MAX:
                self.host.dropped("a message of a length no seat sends", self)
                return
            if len(buffer) < 4 + size:
                return
            body = bytes(buffer[4:4 + size])
            del buffer[:4 + size]
            try:
                msg = pickle.loads(body)
                self.host.received(self, msg)
            except Exception as exc:  # noqa: BLE001 - said; this seat goes, the others play on
                self.host.dropped(f"a message that cannot be used ({type(exc).__name__}: {exc})", self)
                return

    def put(self, data: bytes, droppable: bool = False) -> None:
        """Send ``data`` in turn (the host's queue: see :meth:`WireServer.queue`). The owner's
        app that does not read loses views and taps (``droppable``; its views then go whole
        again), never its answers: the wire is its own, closing it would end the field."""
        if self.closed:
            return
        if droppable and self.seat == OWNER and self.queued + len(data) > SEAT_BUFFER_MAX // 2:
            self.host.drops += 1
            self.host.views.resync()
            return
        self.queued += len(data)
        if self.queued > SEAT_BUFFER_MAX:
            self.too_slow()
            return
        self.host.queue(self, data)

    def too_slow(self) -> None:
        # not reading: its backlog would only grow; it must not cost the field memory
        seat_log.warning("classroom: closing a seat (%s) that does not read", self.label())
        self.close()

    def write(self, data: bytes) -> None:
        self.queued -= len(data)
        if self.closed or self.transport is None:
            return
        self.transport.write(_LENGTH.pack(len(data)) + data)
        if self.transport.get_write_buffer_size() + self.queued > SEAT_BUFFER_MAX:
            self.too_slow()

    def label(self) -> str:
        return self.seat.label() if self.seat is not None else "an app that has not joined"

    def close(self) -> None:
        if not self.closed:
            self.closed = True
            if self.transport is not None:
                self.transport.close()
            self.host.left(self)

    def connection_lost(self, exc) -> None:
        self.close()


class WireServer:
    """A running field's seats: the app whose wire process it is (one "owner" seat), or a
    classroom's many. Everything here runs on the wire's loop: a seat's request is answered
    between two beats, views and taps are made and pickled there once for every seat, and a
    seat is never waited for. (Threads serving the seats were tried first: with thirty busy
    apps on the machine, a seat's thread preempted while holding the interpreter's lock held
    the wire thread back, p99 of the beat 1.7 ms; a second thread pickling for the single app
    fought the wire for the GIL, p99 22.7 ms under the app.)"""

    def __init__(self, engine: ThreadEngine, teacher_key: str = "") -> None:
        self.engine = engine
        self.started_at = engine.now()  # the field's clock as the server starts with it
        self.teacher_key = teacher_key  # "": no seat may be the teacher
        self.views = ViewSender(engine.field, engine.now)
        #: The wire process's own log lines (_ForwardLog), for its owner: a classroom's go to stderr.
        self.logs: collections.deque[LogLine] = collections.deque(maxlen=1000)
        self.problems_sent = len(engine.problems)
        self.log_state_sent = LogState(0, engine.log_folder)
        #: Set when the owner's seat has gone: the wire process ends.
        self.owner_gone = threading.Event()
        self.seats: list[_Seat] = []
        self.taps: list = []
        self._out: collections.deque = collections.deque()  # (seat, bytes) to write, in turn
        self._draining = False
        self.tapping = False
        self.stopping = False
        self.priority: tuple[str, int] = ("", 0)
        self.drops = 0

    # -- seats ------------------------------------------------------------------------------
    def seat_for(self, want: object) -> Seat:
        if isinstance(want, tuple) and want[:1] == ("teacher",):
            if len(want) == 2 and self.teacher_key and \
                    hmac.compare_digest(str(want[1]).encode(), self.teacher_key.encode()):
                return Seat("teacher")
            return Seat("observer")  # a wrong key watches, as anyone may
        if want == "driver":
            taken = {c.seat.team for c in self.seats if c.seat is not None and c.seat.kind == "driver"}
            for st in self.engine.field.stations:
                if st.ds is not None and st.team not in taken:
                    return Seat("driver", st.team)
        return Seat("observer")

    def received(self, conn: _Seat, msg: object) -> None:
        if conn.seat is None:
            if not isinstance(msg, Join):
                raise ValueError("the first message must be a Join")
            self.join(conn, self.seat_for(msg.want))
        elif isinstance(msg, Call):
            self.answer(conn, msg)
        elif isinstance(msg, Tapping):
            conn.tapping = msg.on
        elif isinstance(msg, Resync):  # the stream is shared: everyone's goes whole
            self.views.resync()
        elif isinstance(msg, Stop):
            conn.close()
        else:
            raise ValueError(f"no such message: {type(msg).__name__}")

    def dropped(self, what: str, conn: _Seat) -> None:
        self.drops += 1
        seat_log.warning("classroom: %s sent %s: closed (%d so far)", conn.label(), what, self.drops)
        conn.close()

    def join(self, conn: _Seat, seat: Seat) -> None:
        """A new app: its seat, the field whole (for everyone: the stream is shared), then on."""
        engine = self.engine
        field = engine.field
        conn.seat = seat
        self.views.resync()
        units = self.views.payload(unit_keys(field))
        self.broadcast(Views(units))
        layout = tuple((st.station, st.team, st.ds_name, st.rio_name) for st in field.stations)
        conn.put(pickle.dumps(Started(layout, field.bound, field.fms_name, field.fms_note, tuple(engine.problems),
                                      units, self.priority, engine.log_folder, seat, field.config,
                                      self.started_at), PROTOCOL))
        self.seats.append(conn)
        if seat != OWNER:
            seat_log.info("classroom: joined: %s (%d seats)", seat.label(), len(self.seats))

    def left(self, gone: _Seat) -> None:
        if gone not in self.seats:
            return
        self.seats.remove(gone)
        seat = gone.seat
        assert seat is not None  # it was in self.seats: joined
        if seat == OWNER:  # the app whose wire process this is: the field ends with it
            self.owner_gone.set()
            return
        seat_log.info("classroom: left: %s (%d seats)", seat.label(), len(self.seats))
        if seat.kind == "driver" and seat.team is not None and not self.stopping:  # (a driver has a team)
            self._disable(seat.team)

    def _disable(self, team: int) -> None:
        """A station whose driver went: its DS disabled, as a DS that lost its operator."""
        try:
            _execute(self.engine.field, Disable(team=team), self.engine)
        except Exception:  # noqa: BLE001 - the field may be stopping
            seat_log.exception("classroom: could not disable team %s", team)

    def queue(self, seat: _Seat, data: bytes) -> None:
        """Every seat's writes in one queue, a few per turn of the wire's loop: thirty seats'
        writes at once held a DS's beat up to a millisecond; between two turns the beat's own
        timer runs. One queue keeps each seat's messages in order (units before a reply)."""
        self._out.append((seat, data))
        if not self._draining:
            self._draining = True
            self.engine.runtime.loop.call_soon(self._drain)

    def _drain(self) -> None:
        out = self._out
        for _ in range(WRITES_PER_TURN):
            if not out:
                break
            seat, data = out.popleft()
            seat.write(data)
        if out:
            self.engine.runtime.loop.call_soon(self._drain)
        else:
            self._draining = False

    def broadcast(self, msg: object, droppable: bool = False) -> None:
        data = pickle.dumps(msg, PROTOCOL)
        for seat in list(self.seats):
            seat.put(data, droppable)

    def send_news(self) -> None:
        """To the owner's app: the wire process's log lines, its problems (log files that
        fail), the log's failed writes and its folder (a new one after the first was deleted)."""
        owners = [seat for seat in self.seats if seat.seat == OWNER]
        if not owners:
            return
        engine, news = self.engine, list[object]()
        while self.logs:
            news.append(self.logs.popleft())
        news += [Problem(text) for text in engine.problems[self.problems_sent:]]
        self.problems_sent = len(engine.problems)
        state = LogState(engine.log_errors, engine.log_folder)
        if state != self.log_state_sent:
            self.log_state_sent = state
            news.append(state)
        for msg in news:
            data = pickle.dumps(msg, PROTOCOL)
            for seat in owners:
                seat.put(data)

    # -- requests --------------------------------------------------------------------------
    def refusal(self, seat: Seat, payload: object) -> str | None:
        """Why ``seat`` may not send this, or None. A seat sends commands (and the teacher
        a :class:`TakeBack`), nothing else: a driver's act on its own station only."""
        if isinstance(payload, TakeBack):
            return None if seat.kind == "teacher" else "only the teacher hands stations out"
        if not isinstance(payload, Command):
            return f"the wire takes commands only, not {type(payload).__name__}"
        if seat.kind in ("teacher", "owner"):
            return None
        if seat.kind == "observer":
            return "you watch this field: ask the teacher for a station"
        if isinstance(payload, FMS_COMMANDS) or isinstance(payload, Fault):
            return "the FMS and the faults are the teacher's"
        if payload.team not in (None, seat.team):
            return f"you drive team {seat.team}, not {payload.team}"
        return None

    def answer(self, conn: _Seat, msg: Call) -> None:
        ident, payload, host = msg.ident, msg.request, None
        engine = self.engine
        field = engine.field
        seat = conn.seat
        assert seat is not None  # received() answers a joined seat only
        why = self.refusal(seat, payload)
        if why is not None:
            conn.put(pickle.dumps(Answer(ident, False, CommandError(why), NOTHING), PROTOCOL))
            return
        value: Any
        try:
            if isinstance(payload, TakeBack):
                value = self.take_back(payload.team)
            else:
                assert isinstance(payload, Command)  # refusal() let a command or a TakeBack by
                if seat.kind == "driver":
                    payload = dataclasses.replace(payload, team=seat.team)
                host = field.host_for(payload)
                value = _execute(field, payload, engine)
            ok = True
        except BaseException as exc:  # noqa: BLE001 - handed to the app
            ok, value = False, _portable(exc)
        if host is not None and host in engine.runtime.hosts:
            engine.runtime.hosts[host].kick()
        self.broadcast(Views(self.views.payload(unit_of(field, host))))  # everyone sees it, first
        conn.put(pickle.dumps(Answer(ident, ok, value, NOTHING), PROTOCOL))

    def take_back(self, team: int) -> str:
        drivers = [c for c in self.seats if c.seat == Seat("driver", team)]
        if not drivers:
            raise CommandError(f"nobody drives team {team}")
        for conn in drivers:
            conn.seat = Seat("observer")
            conn.put(pickle.dumps(SeatChanged(conn.seat), PROTOCOL))
        self._disable(team)
        return f"team {team} is free"

    # -- the stream ------------------------------------------------------------------------
    def record(self, r: TapRecord) -> None:  # a tap, wire thread (tuples: wireproc.TAP_BACKLOG)
        if len(self.taps) < TAP_BACKLOG:
            self.taps.append((r.role, r.link, r.direction, r.kind, r.data, r.remote, r.local, r.time))

    def start_pump(self) -> None:
        """Views and tap batches on the wire's own loop, as roles/runtime/wireproc.py's child."""
        engine = self.engine
        keys = unit_keys(engine.field)
        turn = itertools.cycle(keys)
        per_tick = min(UNITS_PER_TICK, len(keys))
        loop = engine.runtime.loop
        state = {"next": time.monotonic(), "taps": time.monotonic(), "gc": time.monotonic() + GC_PERIOD}

        def tick() -> None:
            if self.stopping:
                return
            try:
                now = time.monotonic()
                if self.seats:
                    self.broadcast(Views(self.views.payload([next(turn) for _ in range(per_tick)])), True)
                self.send_news()
                wants = any(c.tapping for c in self.seats)
                if wants != self.tapping:
                    self.tapping = wants
                    engine.add_tap(self.record) if wants else engine.remove_tap(self.record)
                    self.taps.clear()
                if now - state["taps"] >= TAP_PERIOD:
                    state["taps"] = now
                    if self.taps:
                        data = pickle.dumps(Taps(self.taps), PROTOCOL)
                        self.taps = []
                        for seat in list(self.seats):
                            if seat.tapping:
                                seat.put(data, True)
                if now >= state["gc"]:
                    state["gc"] = now + GC_PERIOD
                    full_collection()
            except Exception:  # noqa: BLE001 - said, and the stream goes on at the next tick
                owners = [seat for seat in self.seats if seat.seat == OWNER]
                if owners:  # the app's own wire: it must see the wire end, not a frozen field
                    log.exception("wire process: views stopped")
                    self.send_news()
                    for seat in owners:
                        seat.close()
                    return
                seat_log.exception("classroom: views failed; every stream goes whole again")
                self.views.resync()
            state["next"] += SNAPSHOT_TICK
            if state["next"] < time.monotonic() - SNAPSHOT_TICK:
                state["next"] = time.monotonic()
            loop.call_at(state["next"], tick)

        loop.call_soon_threadsafe(tick)

    def serve(self, listener: socket.socket) -> None:
        """Take seats on ``listener`` (bound and listening), on the wire's loop."""
        loop = self.engine.runtime.loop
        asyncio.run_coroutine_threadsafe(loop.create_unix_server(lambda: _Seat(self), sock=listener), loop) \
            .result(timeout=CALL_TIMEOUT)

    def serve_owner(self, sock: socket.socket) -> None:
        """The wire process's app, on the socket pair it started the process with (on the
        wire's loop): told :class:`Started` first, like any seat."""
        loop = self.engine.runtime.loop

        async def connect() -> None:
            _, conn = await loop.connect_accepted_socket(lambda: _Seat(self), sock=sock)
            self.join(conn, OWNER)

        asyncio.run_coroutine_threadsafe(connect(), loop).result(timeout=CALL_TIMEOUT)

    def close_all(self) -> None:
        """The field stops: every seat's connection closes (on the wire's loop)."""
        self.stopping = True
        for seat in list(self.seats):
            seat.close()



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
    """The child's log records, kept for the parent's logging (the child has no terminal):
    the server sends them on the wire's loop (:meth:`WireServer.send_news`), before it runs
    the child's main thread."""

    def __init__(self) -> None:
        super().__init__(logging.INFO)
        self.logs: collections.deque[LogLine] = collections.deque(maxlen=1000)

    def emit(self, record: logging.LogRecord) -> None:
        try:
            self.logs.append(LogLine(record.levelno, record.name, self.format(record)))
        except Exception:
            pass


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
    # field stops (it says Stop, or its end closes the socket pair).
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    conn = Connection(fd)
    forward = _ForwardLog()
    root = logging.getLogger()
    root.handlers[:] = [forward]
    root.setLevel(logging.INFO)

    def say(*msgs: object) -> None:  # before the server runs: on the pipe, waiting
        for msg in (*forward.logs, *msgs):
            conn.send_bytes(pickle.dumps(msg, PROTOCOL))
        forward.logs.clear()

    try:
        first = pickle.loads(conn.recv_bytes())
        if not isinstance(first, Configure):
            say(Failed("ValueError", f"the wire process starts with a Configure, not {type(first).__name__}"))
            return 1
        quiet_collector()
        engine = ThreadEngine(first.config)
        try:
            engine.start()
        except (OSError, ValueError) as exc:
            say(Failed("OSError" if isinstance(exc, OSError) else "ValueError", str(exc)))
            return 1
    except (EOFError, OSError):  # the parent went away
        return 1
    server = WireServer(engine)
    server.logs = forward.logs
    server.priority = engine.runtime.call(tune_wire_thread).result(timeout=CALL_TIMEOUT)
    log.info("wire process: the wire thread runs at %s", server.priority[0])
    if os.environ.get("FIELDBOX_WIREPROC_DEBUG"):
        _debug(engine, os.environ["FIELDBOX_WIREPROC_DEBUG"])
    try:
        sock = socket.socket(fileno=os.dup(conn.fileno()))  # the loop's own from now on
        conn.close()
        server.serve_owner(sock)
        server.start_pump()
        server.owner_gone.wait()
    finally:
        try:
            engine.runtime.call(server.close_all).result(timeout=CALL_TIMEOUT)
        except Exception:  # noqa: BLE001 - the loop is gone already
            pass
        engine.stop()
    return 0


def _debug(engine: ThreadEngine, path: str) -> None:
    """Diagnosis: the loop's slow callbacks (asyncio debug mode) and long collections, logged to ``path``."""
    root = logging.getLogger()
    handler = logging.FileHandler(path)
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
    #: What a shared wire's field runs (its configuration, from the field itself).
    shared_config: FieldConfig | None = None
    #: A shared wire's field's clock when it started (event times count from it).
    field_started: float | None = None

    def __init__(self, config: FieldConfig, stderr: Any = subprocess.DEVNULL) -> None:
        self.config = config
        #: The latest views of the field (empty until it starts), replaced whole by the reader.
        self.field = FieldView(config, (), None, None, time.monotonic())
        #: Things that went wrong (shown by the app): log files, the child's end.
        self.problems: list[str] = []
        self.proc: subprocess.Popen | None = None
        self.conn: Connection | None = None
        self._stderr = stderr
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
    #: The wire's side as the app's messages name it.
    NAME = "the wire process"
    #: Why a call still waiting fails when the app stops.
    STOPPED = "the field was stopped"

    def start(self, timeout: float = START_TIMEOUT) -> None:
        """Start (or join) the wire and wait for its :class:`Started`; raises OSError/ValueError
        with the wire's message if it cannot start."""
        first = self._open(timeout)
        assert self.conn is not None  # _open connected it
        try:
            self._send(first)
            if not self.conn.poll(timeout):
                raise OSError(f"{self.NAME} did not answer within {timeout:g} s")
            try:
                msg = pickle.loads(self.conn.recv_bytes())
                while isinstance(msg, LogLine):
                    self._log(msg)
                    msg = pickle.loads(self.conn.recv_bytes())
            except (EOFError, OSError):
                raise OSError(f"{self.NAME} ended while starting ({exit_words(self._exit_code())})") from None
            if isinstance(msg, Failed):
                raise (OSError if msg.error == "OSError" else ValueError)(msg.message)
            if not isinstance(msg, Started):
                raise OSError(f"{self.NAME} said {type(msg).__name__} before it started")
        except BaseException:
            self._stopping = True
            self._end_child()
            raise
        self._started(msg)
        self._begin_threads()

    def _open(self, timeout: float) -> object:
        """Start the child on a socket pair; the first message for it."""
        ours, theirs = socket.socketpair()
        env = child_environment()
        try:
            self.proc = subprocess.Popen([sys.executable, "-c", CHILD_CODE, str(theirs.fileno())],
                                         pass_fds=[theirs.fileno()], stdin=subprocess.DEVNULL,
                                         stdout=subprocess.DEVNULL, stderr=self._stderr, env=env, cwd=ROOT)
        finally:
            theirs.close()
        self.conn = Connection(ours.detach())
        return Configure(self.config)

    def _started(self, msg: Started) -> None:
        """The field the wire runs and its first views; then read on."""
        self.priority, self.log_folder = msg.priority, msg.log_folder
        if msg.seat != OWNER:  # a classroom's: what its field runs, not what joining said
            self.seat, self.shared_config, self.field_started = msg.seat, msg.config, msg.field_started
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
        if self.conn is None:
            return
        self._outq.put(pickle.dumps(Stop(), PROTOCOL))
        self._outq.put(None)  # the sender thread ends after Stop
        if self._writer is not None:
            self._writer.join(0.5)
        self._end_child()
        if self._reader is not None and self._reader is not threading.current_thread():
            self._reader.join(2.0)
        self._fail_pending(self.STOPPED)

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
                    elif isinstance(msg, LogState):
                        self.log_errors, self.log_folder = msg.errors, msg.folder
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
        """Only a command crosses to the wire (as :meth:`submit_command`; a classroom's
        teacher also sends a :class:`TakeBack`)."""
        if isinstance(fn, (Command, TakeBack)):
            return self._request(fn)
        raise TypeError(f"cannot send {fn!r} to the wire process: only a command goes "
                        "(roles/cores/commands.py)")

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
            try:  # the only writer once started (_send writes before this thread starts)
                self.conn.send_bytes(data)  # type: ignore[union-attr]  # None once stopped: caught below
            except (OSError, ValueError, AttributeError):
                self._fail_pending(f"the wire process has ended: start the field again ({RESTART_KEY})")

    def _fail_pending(self, why: str) -> None:
        for ident in list(self._pending):
            future = self._pending.pop(ident, None)
            if future is not None and not future.done():
                future.set_exception(CommandError(why))

    def _send(self, msg: object) -> None:
        data = pickle.dumps(msg, PROTOCOL)
        assert self.conn is not None  # opened; the writer thread has not started yet
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
