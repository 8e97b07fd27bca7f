"""One field for a whole classroom: a wire process that many apps join.

``fieldbox serve --classroom`` runs one field (the FMS, six DS and six fake roboRIOs) in a
process of its own, :func:`classroom_main`, listening on a Unix socket that only this user
can open. Every browser tab's app joins it (:class:`JoinedEngine`, ``fieldbox --join``)
instead of starting a field of its own, and takes a *seat*:

* **driver**: a free station's DS, driven with that tab's keys and keyboard joystick; its
  commands act on that team only, never on the FMS. When the tab goes, its DS is disabled
  (a DS that loses its driver must not go on enabled) and the station is free again;
* **observer**: everything on screen, the inspector's packets included; no command;
* **teacher** (with the key the server printed): every command, the FMS's included, and
  :class:`TakeBack` a station from its driver (who then watches).

A tab asking to drive gets a free station, else watches. What the apps see is the wire
process's one stream of views (roles/runtime/viewwire.py), pickled once and written to every
seat: an observer costs the bytes of a view stream, not a field. A seat that joins makes
every stream go whole again (the payloads are shared: the newcomer's start is everyone's); the
replies' own views go to every seat before the reply, so no seat misses a change. A
seat that does not read is closed (its queue is bounded): it cannot slow the others.

The wire's own rules (its thread at real-time priority, the collector's policy, the
view tick) are those of roles/runtime/wireproc.py, whose child serves a single app.

Who may connect is who may open the socket: the user that started the server (its folder is
0700, the socket 0600). Messages are pickled, as on the wire process's own pipe: a joined
app is fieldbox's code, started by the server; the seats' rules stand between a person at a
tab and the field, not between processes of the same user.
"""

from __future__ import annotations

import asyncio
import collections
import dataclasses
import hmac
import itertools
import logging
import os
import pickle
import secrets
import signal
import socket
import struct
import subprocess
import sys
import tempfile
import threading
import time
from concurrent.futures import Future
from dataclasses import dataclass
from pathlib import Path
from multiprocessing.connection import Connection
from typing import Any

from ..cores.commands import FMS_COMMANDS, Command, Disable, Fault
from ..cores.core import CommandError
from .engine import ThreadEngine
from .field import FieldConfig
from .viewwire import NOTHING, ViewSender, unit_keys
from .process_tuning import GC_PERIOD, full_collection, quiet_collector, tune_wire_thread
from .program_host import ROOT, child_environment
from .shell import TapRecord
from .wireproc import (CALL_TIMEOUT, PROTOCOL, SNAPSHOT_TICK, TAP_BACKLOG, TAP_PERIOD, UNITS_PER_TICK, Answer,
                       Call, Join, ProcessEngine, Resync, Seat, SeatChanged, Started, Stop, TakeBack, Tapping, Taps,
                       Views, _execute, _portable, started_message, unit_of)

log = logging.getLogger("fieldbox.classroom")

#: Messages a seat may have waiting before it is closed as not reading.
SEAT_BACKLOG = 2000
#: Packets a driver's or an observer's inspector keeps: about 15 s of a full field's traffic
#: (the teacher's and every other app's keep 50,000).
TAB_CAPTURE = 20_000
#: How the host process starts (``sys.argv[1]``: the socket's path; the configuration and the
#: teacher's key come pickled on stdin, out of ``ps``'s sight).
HOST_CODE = ("import sys; sys.modules['ssl'] = None; from roles.runtime.classroom import classroom_main; "
             "sys.exit(classroom_main(sys.argv[1]))")
#: Where ``--join-as teacher`` finds the teacher's key (``fieldbox serve --classroom`` sets it).
KEY_ENV = "FIELDBOX_CLASSROOM_KEY"


#: The largest message a seat may send (a command, a joystick update: a few hundred bytes);
#: a longer length closes the seat.
SEAT_MESSAGE_MAX = 1 << 20
#: Bytes waiting to go to one seat before it is closed as not reading (a few seconds of
#: everything, taps included).
SEAT_BUFFER_MAX = 32 << 20
#: Seats written to per turn of the wire's loop (ClassroomHost.queue).
WRITES_PER_TURN = 4
_LENGTH = struct.Struct("!i")  # multiprocessing.Connection's framing, the joined app's side


class _Seat(asyncio.Protocol):
    """One joined app, on the wire's loop: its messages framed as multiprocessing's
    Connection frames them, its writes buffered by the loop's transport (never waited for)."""

    def __init__(self, host: "ClassroomHost") -> None:
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

    def put(self, data: bytes) -> None:
        """Send ``data`` in turn (the host's queue: see :meth:`ClassroomHost.queue`)."""
        if self.closed:
            return
        self.queued += len(data)
        if self.queued > SEAT_BUFFER_MAX:
            self.too_slow()
            return
        self.host.queue(self, data)

    def too_slow(self) -> None:
        # not reading: its backlog would only grow; it must not cost the field memory
        log.warning("classroom: closing a seat (%s) that does not read", self.label())
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


class ClassroomHost:
    """The shared field and its seats (the host process). Everything here runs on the wire's
    loop: a seat's request is answered between two beats, as the single app's requests of
    roles/runtime/wireproc.py's child are, and a seat is never waited for. (Threads serving the seats
    were tried first: with thirty busy apps on the machine, a seat's thread preempted while
    holding the interpreter's lock held the wire thread back, p99 of the beat 1.7 ms.)"""

    def __init__(self, engine: ThreadEngine, teacher_key: str) -> None:
        self.engine = engine
        self.teacher_key = teacher_key
        self.views = ViewSender(engine.field, engine.now)
        self.seats: list[_Seat] = []
        self.taps: list = []
        self._out: collections.deque = collections.deque()  # (seat, bytes) to write, in turn
        self._draining = False
        self.tapping = False
        self.stopping = False
        self.priority: tuple[str, int] = ("", 0)
        self.drops = 0

    # -- seats ------------------------------------------------------------------------------
    def seat_for(self, want: Any) -> Seat:
        if isinstance(want, tuple) and want[:1] == ("teacher",):
            if len(want) == 2 and hmac.compare_digest(str(want[1]).encode(), self.teacher_key.encode()):
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
            self.join(conn, msg.want)
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
        log.warning("classroom: %s sent %s: closed (%d so far)", conn.label(), what, self.drops)
        conn.close()

    def join(self, conn: _Seat, want: Any) -> None:
        """A new app: its seat, the field whole (for everyone: the stream is shared), then on."""
        engine = self.engine
        field = engine.field
        conn.seat = self.seat_for(want)
        self.views.resync()
        units = self.views.payload(unit_keys(field))
        self.broadcast(Views(units))
        conn.put(pickle.dumps(started_message(engine, units, self.priority, conn.seat, field.config), PROTOCOL))
        self.seats.append(conn)
        log.info("classroom: joined: %s (%d seats)", conn.seat.label(), len(self.seats))

    def left(self, gone: _Seat) -> None:
        if gone not in self.seats:
            return
        self.seats.remove(gone)
        seat = gone.seat
        assert seat is not None  # it was in self.seats: joined
        log.info("classroom: left: %s (%d seats)", seat.label(), len(self.seats))
        if seat.kind == "driver" and seat.team is not None and not self.stopping:  # (a driver has a team)
            self._disable(seat.team)

    def _disable(self, team: int) -> None:
        """A station whose driver went: its DS disabled, as a DS that lost its operator."""
        try:
            _execute(self.engine.field, Disable(team=team), self.engine)
        except Exception:  # noqa: BLE001 - the field may be stopping
            log.exception("classroom: could not disable team %s", team)

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

    def broadcast(self, msg: object) -> None:
        data = pickle.dumps(msg, PROTOCOL)
        for seat in list(self.seats):
            seat.put(data)

    # -- requests --------------------------------------------------------------------------
    def refusal(self, seat: Seat, payload: object) -> str | None:
        """Why ``seat`` may not send this, or None. A seat sends commands (and the teacher
        a :class:`TakeBack`), nothing else: a driver's act on its own station only."""
        if isinstance(payload, TakeBack):
            return None if seat.kind == "teacher" else "only the teacher hands stations out"
        if not isinstance(payload, Command):
            return "that is not a command"
        if seat.kind == "teacher":
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
                    self.broadcast(Views(self.views.payload([next(turn) for _ in range(per_tick)])))
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
                                seat.put(data)
                if now >= state["gc"]:
                    state["gc"] = now + GC_PERIOD
                    full_collection()
            except Exception:  # noqa: BLE001 - said, and the stream goes on at the next tick
                log.exception("classroom: views failed; every stream goes whole again")
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

    def close_all(self) -> None:
        """The field stops: every seat's connection closes (on the wire's loop)."""
        self.stopping = True
        for seat in list(self.seats):
            seat.close()


def classroom_main(path: str) -> int:
    """The host process: the field from the configuration on stdin, seats on ``path``."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # the server decides when the field stops
    # The server's console says who joins and leaves, and what went wrong; the field's own
    # story goes to its log files, as every field's.
    logging.basicConfig(level=logging.WARNING, stream=sys.stderr, format="%(asctime)s %(message)s", datefmt="%H:%M:%S")
    log.setLevel(logging.INFO)
    head = sys.stdin.buffer.read(4)
    size = int.from_bytes(head, "big") if len(head) == 4 else 0
    if not 0 < size <= CONFIG_MAX:
        print("fieldbox classroom: no configuration on stdin", file=sys.stderr, flush=True)
        return 2
    config, teacher_key = pickle.loads(sys.stdin.buffer.read(size))
    quiet_collector()
    engine = ThreadEngine(config)
    try:
        engine.start()
    except (OSError, ValueError) as exc:
        print(f"fieldbox classroom: {exc}", file=sys.stderr, flush=True)
        return 1
    host = ClassroomHost(engine, teacher_key)
    host.priority = engine.runtime.call(tune_wire_thread).result(timeout=CALL_TIMEOUT)
    log.info("classroom: the wire thread runs at %s", host.priority[0])
    listener = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    old = os.umask(0o177)  # only this user may join (the folder is the user's own as well)
    try:
        listener.bind(path)
    finally:
        os.umask(old)
    listener.listen(64)
    stop = threading.Event()
    signal.signal(signal.SIGTERM, lambda *_: stop.set())

    stdin = sys.stdin.fileno()

    def orphaned() -> None:  # the server keeps stdin open: its end means the server is gone
        # os.read on the descriptor, not sys.stdin's buffered reader: a daemon thread still
        # inside that reader when the process ends (the server's SIGTERM right after it
        # closed our stdin) holds its lock, and the interpreter's shutdown then aborted
        # ("could not acquire lock for <stdin> at interpreter shutdown", exit -6).
        while True:
            try:
                if not os.read(stdin, 65536):
                    break
            except InterruptedError:
                continue
            except OSError:
                break
        log.warning("classroom: the server is gone; the field stops")
        stop.set()

    threading.Thread(target=orphaned, name="classroom-server", daemon=True).start()
    try:
        host.serve(listener)
        host.start_pump()
        print("ready", flush=True)
        while not stop.wait(0.5):
            pass
    finally:
        try:
            engine.runtime.call(host.close_all).result(timeout=CALL_TIMEOUT)
        except Exception:  # noqa: BLE001 - the loop is gone already
            pass
        listener.close()
        try:
            os.unlink(path)
        except OSError:
            pass
        engine.stop()
    return 0


#: The largest configuration the host process takes on its stdin, bytes.
CONFIG_MAX = 1 << 20


class ClassroomProcess:
    """The host process, from the side that starts it (``fieldbox serve --classroom``, tests):
    a private folder for its socket, the configuration and the key on its stdin, "ready"."""

    def __init__(self, config: FieldConfig, teacher_key: str | None = None) -> None:
        self.config = config
        self.teacher_key = teacher_key or secrets.token_hex(16)
        self.folder = Path(tempfile.mkdtemp(prefix="fieldbox-classroom-"))  # 0700: this user's
        self.path = str(self.folder / "field.sock")
        self.process: subprocess.Popen | None = None

    def start(self, timeout: float = 60.0) -> None:
        """Start it and wait for its "ready" (OSError saying why it did not come)."""
        self.process = subprocess.Popen([sys.executable, "-c", HOST_CODE, self.path], stdin=subprocess.PIPE,
                                        stdout=subprocess.PIPE, env=child_environment(), cwd=ROOT)
        data = pickle.dumps((self.config, self.teacher_key), PROTOCOL)
        # stdin stays open while this side lives: if it dies (even by SIGKILL), the field ends
        stdin, stdout = self.process.stdin, self.process.stdout
        assert stdin is not None and stdout is not None  # pipes
        stdin.write(len(data).to_bytes(4, "big") + data)
        stdin.flush()
        said: list[bytes] = []
        reader = threading.Thread(target=lambda: said.append(stdout.readline()), daemon=True)
        reader.start()
        reader.join(timeout)
        if not said or said[0].strip() != b"ready":
            self.stop()
            raise OSError("the classroom's field did not start (its reasons are above)" if said else
                          f"the classroom's field did not start within {timeout:g} s")

    def stop(self, timeout: float = 10.0) -> int | None:
        """End it (its field stops, every seat's connection closes); its exit code."""
        code = None
        if self.process is not None:
            try:
                assert self.process.stdin is not None  # a pipe
                self.process.stdin.close()
            except OSError:
                pass
            if self.process.poll() is None:
                self.process.terminate()
            try:
                code = self.process.wait(timeout)
            except subprocess.TimeoutExpired:
                self.process.kill()
                code = self.process.wait()
            if self.process.stdout is not None:
                self.process.stdout.close()
        for leftover in self.folder.glob("*"):
            leftover.unlink(missing_ok=True)
        try:
            self.folder.rmdir()
        except OSError:
            pass
        return code


# -- an app that joins ------------------------------------------------------------------------
def wanted_seat(text: str) -> Any:
    """``--join-as``: "driver", "observer", "teacher:KEY", or "teacher" (the key from
    :data:`KEY_ENV`); ValueError for anything else."""
    if text in ("driver", "observer"):
        return text
    if text == "teacher" or text.startswith("teacher:"):
        key = text[8:] if text.startswith("teacher:") else os.environ.get(KEY_ENV, "")
        if not key:
            raise ValueError(f"--join-as teacher needs the teacher's key: teacher:KEY, or {KEY_ENV} set")
        return ("teacher", key)
    raise ValueError(f"--join-as {text!r}: driver, observer or teacher:KEY")


class JoinedEngine(ProcessEngine):
    """The app's engine in a classroom: the shared field's views, a seat, no process of its own."""

    def __init__(self, path: str, want: Any, config: FieldConfig | None = None) -> None:
        super().__init__(config or FieldConfig(plan="ephemeral", log_files=False))
        self.path = path
        self.want = want
        self.seat: Seat | None = None
        #: What the classroom's field runs (its configuration, from the field itself): what
        #: the app's title says, not the joining command line's defaults ("team 1 loopback").
        self.shared_config: FieldConfig | None = None

    def start(self, timeout: float = 20.0) -> None:
        sock = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
        sock.settimeout(timeout)
        try:
            sock.connect(self.path)
        except OSError as exc:
            sock.close()
            raise OSError(f"cannot join the classroom's field at {self.path}: {exc.strerror or exc}") from None
        sock.settimeout(None)
        self.conn = Connection(sock.detach())
        self._send(Join(self.want))
        if not self.conn.poll(timeout):
            self.conn.close()
            raise OSError(f"the classroom's field did not answer within {timeout:g} s")
        try:
            msg = pickle.loads(self.conn.recv_bytes())
            while not isinstance(msg, Started):
                msg = pickle.loads(self.conn.recv_bytes())
        except (EOFError, OSError):
            raise OSError("the classroom's field closed the connection") from None
        self.seat, self.shared_config = msg.seat, msg.config
        self._started(msg)
        self._begin_threads()

    @property
    def capture_total(self) -> int | None:
        """How many packets this app's inspector keeps: the teacher's as any app's; a driver's
        or an observer's :data:`TAB_CAPTURE` (at 50,000 a full ring was 18 MB of a tab's
        memory, the target for an observer's tab being 60 MB in all)."""
        return None if self.seat is not None and self.seat.kind == "teacher" else TAB_CAPTURE

    @property
    def capture_when_shown(self) -> bool:
        """A driver's or an observer's inspector captures only while it is shown (or recording):
        thirty tabs each unpickling every packet of the field, all the time, cost the machine
        more CPU than it has to spare for the field's beat."""
        return not (self.seat is not None and self.seat.kind == "teacher")

    def submit(self, fn, host=None) -> Future:
        """A command, or the teacher's :class:`TakeBack` (the classroom's own request)."""
        if isinstance(fn, TakeBack):
            return self._request(fn)
        return super().submit(fn, host)

    def stop(self) -> None:
        """This app leaves; the field goes on for the others."""
        self._stopping = True
        if self.conn is None:
            return
        self._outq.put(pickle.dumps(Stop(), PROTOCOL))
        self._outq.put(None)
        if self._writer is not None:
            self._writer.join(0.5)
        self._close_conn()
        if self._reader is not None and self._reader is not threading.current_thread():
            self._reader.join(2.0)
        self._fail_pending("this app left the classroom's field")

    def _exit_code(self) -> int | None:
        return None
