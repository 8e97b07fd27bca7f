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
process's one stream of snapshots (roles/mirror.py), pickled once and written to every
seat: an observer costs the bytes of a view stream, not a field. A seat that joins makes
every unit go whole again (the stream is shared: the newcomer's start is everyone's); the
replies' own snapshots go to every seat before the reply, so no seat misses a change. A
seat that does not read is closed (its queue is bounded): it cannot slow the others.

The wire's own rules (its thread at real-time priority, the collector's policy, the
snapshot tick) are those of roles/wireproc.py, whose child serves a single app.
"""

from __future__ import annotations

import dataclasses
import functools
import hmac
import itertools
import logging
import os
import pickle
import queue
import secrets
import signal
import socket
import subprocess
import sys
import tempfile
import threading
import time
from dataclasses import dataclass
from pathlib import Path
from multiprocessing.connection import Connection
from typing import Any

from .commands import FMS_COMMANDS, Command, Disable, Fault
from .core import CommandError
from .engine import CoreCall, ThreadEngine
from .field import FieldConfig
from .mirror import Snapshots, unit_keys
from .wireproc import (CALL_TIMEOUT, GC_PERIOD, PROTOCOL, SNAPSHOT_TICK, TAP_BACKLOG, TAP_PERIOD, UNITS_PER_TICK,
                       ProcessEngine, _execute, _full_collection, _portable, _quiet_collector, _raise_priority)

log = logging.getLogger("fieldbox.classroom")

#: Messages a seat may have waiting before it is closed as not reading.
SEAT_BACKLOG = 2000
#: How the host process starts (``sys.argv[1]``: the socket's path; the configuration and the
#: teacher's key come pickled on stdin, out of ``ps``'s sight).
HOST_CODE = ("import sys; sys.modules['ssl'] = None; from roles.classroom import classroom_main; "
             "sys.exit(classroom_main(sys.argv[1]))")
#: Where ``--join-as teacher`` finds the teacher's key (``fieldbox serve --classroom`` sets it).
KEY_ENV = "FIELDBOX_CLASSROOM_KEY"


@dataclass(frozen=True)
class Seat:
    """Who a joined app is: ``kind`` "driver" (of ``team``), "observer" or "teacher"."""

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
    """The teacher takes a station back from its driver (who then watches)."""

    team: int


class _Conn:
    """One joined app: its connection, a bounded queue of messages and the thread writing them."""

    def __init__(self, host: "ClassroomHost", conn: Connection, seat: Seat) -> None:
        self.host = host
        self.conn = conn
        self.seat = seat
        self.tapping = False
        self.outq: queue.Queue = queue.Queue(SEAT_BACKLOG)
        self.closed = threading.Event()
        self.writer = threading.Thread(target=self._write, name="fieldbox-seat-out", daemon=True)
        self.reader = threading.Thread(target=self._read, name="fieldbox-seat-in", daemon=True)

    def put(self, data: bytes) -> None:
        try:
            self.outq.put_nowait(data)
        except queue.Full:  # not reading: it would hold everyone's stream back
            log.warning("classroom: closing a seat (%s) that does not read", self.seat.label())
            self.close()

    def _write(self) -> None:
        try:
            while not self.closed.is_set():
                data = self.outq.get()
                if data is None:
                    return
                self.conn.send_bytes(data)
        except (OSError, EOFError, ValueError):
            pass
        self.close()

    def _read(self) -> None:
        try:
            while not self.closed.is_set():
                msg = pickle.loads(self.conn.recv_bytes())
                kind = msg[0]
                if kind == "call":
                    try:
                        self.host.answer(self, msg)
                    except Exception:  # noqa: BLE001 - said; this seat goes, the others play on
                        log.exception("classroom: a %s sent a request that cannot be answered", self.seat.label())
                        break
                elif kind == "taps":
                    self.tapping = bool(msg[1])
                elif kind == "stop":
                    break
        except (OSError, EOFError, pickle.UnpicklingError, ValueError, IndexError, TypeError):
            pass
        self.close()

    def close(self) -> None:
        if self.closed.is_set():
            return
        self.closed.set()
        try:
            self.outq.put_nowait(None)
        except queue.Full:
            pass
        try:
            self.conn.close()
        except OSError:
            pass
        self.host.left(self)


class ClassroomHost:
    """The shared field and its seats (the host process)."""

    def __init__(self, engine: ThreadEngine, teacher_key: str) -> None:
        self.engine = engine
        self.teacher_key = teacher_key
        self.snapshots = Snapshots(engine.field)
        self.seats: list[_Conn] = []
        # Re-entrant: a seat closed for not reading is closed from the tick's broadcast.
        self.lock = threading.RLock()
        self.taps: list = []
        self.tapping = False
        self.stopping = threading.Event()
        self.priority: tuple[str, int] = ("", 0)

    # -- seats ------------------------------------------------------------------------------
    def seat_for(self, want: Any) -> Seat:
        if isinstance(want, tuple) and want[:1] == ("teacher",):
            if len(want) == 2 and hmac.compare_digest(str(want[1]).encode(), self.teacher_key.encode()):
                return Seat("teacher")
            return Seat("observer")  # a wrong key watches, as anyone may
        if want == "driver":
            taken = {c.seat.team for c in self.seats if c.seat.kind == "driver"}
            for st in self.engine.field.stations:
                if st.ds is not None and st.team not in taken:
                    return Seat("driver", st.team)
        return Seat("observer")

    def join(self, conn: Connection) -> None:
        """A new app: its seat, the field whole (for everyone: the stream is shared), then on."""
        try:
            kind, want = pickle.loads(conn.recv_bytes())
        except (OSError, EOFError, pickle.UnpicklingError, ValueError, TypeError):
            conn.close()
            return
        if kind != "join":
            conn.close()
            return
        engine = self.engine
        field = engine.field

        def seated() -> _Conn:
            # On the wire's loop, as the snapshot tick: the newcomer's whole field and the
            # tick's units go out in one order, and no thread holding the seats' lock ever
            # waits for the loop (which takes that lock at every tick).
            self.snapshots.resync()
            units = self.snapshots.payload(unit_keys(field))
            layout = [(st.station, st.team, st.ds_name, st.rio_name) for st in field.stations]
            with self.lock:
                joined = _Conn(self, conn, self.seat_for(want))
                self.broadcast(("units", units))
                joined.put(pickle.dumps(("started", layout, field.bound, field.fms_name, field.fms_note,
                                         list(engine.problems), units, self.priority,
                                         str(engine.log.folder) if engine.log is not None else None,
                                         joined.seat), PROTOCOL))
                self.seats.append(joined)
            return joined

        try:
            joined = engine.runtime.call(seated).result(timeout=CALL_TIMEOUT)
        except Exception:  # noqa: BLE001 - the field is stopping, or its loop is held
            log.exception("classroom: could not seat an app")
            conn.close()
            return
        seat = joined.seat
        log.info("classroom: joined: %s (%d seats)", seat.label(), len(self.seats))
        joined.writer.start()
        joined.reader.start()

    def left(self, gone: _Conn) -> None:
        with self.lock:
            if gone not in self.seats:
                return
            self.seats.remove(gone)
        log.info("classroom: left: %s (%d seats)", gone.seat.label(), len(self.seats))
        if gone.seat.kind == "driver" and not self.stopping.is_set():
            self._disable(gone.seat.team)

    def _disable(self, team: int) -> None:
        """A station whose driver went: its DS disabled, as a DS that lost its operator."""
        field = self.engine.field
        command = Disable(team=team)

        def said(done) -> None:
            if done.exception() is not None:  # the field may be stopping
                log.warning("classroom: could not disable team %s: %s", team, done.exception())

        try:  # never waits: this may run on the wire's loop itself (a seat closed by the tick)
            self.engine.submit(functools.partial(_execute, field, command, self.engine),
                               field.host_for(command)).add_done_callback(said)
        except Exception:  # noqa: BLE001 - the field is stopping
            log.exception("classroom: could not disable team %s", team)

    def broadcast(self, msg: tuple) -> None:
        data = pickle.dumps(msg, PROTOCOL)
        for seat in list(self.seats):
            seat.put(data)

    # -- requests --------------------------------------------------------------------------
    def refusal(self, seat: Seat, what: str, payload: Any) -> str | None:
        """Why ``seat`` may not send this, or None."""
        if seat.kind == "teacher":
            return None
        if seat.kind == "observer":
            return "you watch this field: ask the teacher for a station"
        if isinstance(payload, TakeBack):
            return "only the teacher hands stations out"
        if what == "execute":
            if not isinstance(payload, Command):
                return "that is not a command"
            if isinstance(payload, FMS_COMMANDS) or isinstance(payload, Fault):
                return "the FMS and the faults are the teacher's"
            if getattr(payload, "team", None) not in (None, seat.team):
                return f"you drive team {seat.team}, not {payload.team}"
            return None
        if isinstance(payload, CoreCall) and payload.role == f"ds {seat.team}":
            return None
        return f"you drive team {seat.team}: that is not yours to change"

    def answer(self, seat_conn: _Conn, msg: tuple) -> None:
        _, ident, what, payload, host = msg
        engine = self.engine
        field = engine.field
        seat = seat_conn.seat
        why = self.refusal(seat, what, payload)
        if why is not None:
            seat_conn.put(pickle.dumps(("reply", ident, False, CommandError(why), (False, [], {})), PROTOCOL))
            return
        try:
            if isinstance(payload, TakeBack):
                value = self.take_back(payload.team)
            elif what == "execute":
                if seat.kind == "driver" and hasattr(payload, "team"):
                    payload = dataclasses.replace(payload, team=seat.team)
                host = field.host_for(payload)
                value = engine.call(functools.partial(_execute, field, payload, engine), host)
            else:
                value = engine.call(payload, host or getattr(payload, "role", None))
            ok = True
        except BaseException as exc:  # noqa: BLE001 - handed to the app
            ok, value = False, _portable(exc)
        keys = _unit_of(field, host)

        def publish() -> None:  # on the wire's loop, in the stream's order (see join)
            units = self.snapshots.payload(keys)
            with self.lock:
                self.broadcast(("units", units))  # every seat sees the change, before the reply
                seat_conn.put(pickle.dumps(("reply", ident, ok, value, (False, [], {})), PROTOCOL))

        try:
            engine.runtime.call(publish).result(timeout=CALL_TIMEOUT)
        except Exception:  # noqa: BLE001 - the field is stopping: the app's call fails on its own
            log.exception("classroom: could not answer a seat")

    def take_back(self, team: int) -> str:
        with self.lock:
            drivers = [c for c in self.seats if c.seat == Seat("driver", team)]
            for conn in drivers:
                conn.seat = Seat("observer")
                conn.put(pickle.dumps(("seat", conn.seat), PROTOCOL))
        if not drivers:
            raise CommandError(f"nobody drives team {team}")
        self._disable(team)
        return f"team {team} is free"

    # -- the stream ------------------------------------------------------------------------
    def record(self, role, link, direction, kind, data, peer, now) -> None:  # a tap, wire thread
        if len(self.taps) < TAP_BACKLOG:
            self.taps.append((role, link, direction, kind, data, peer, now))

    def start_pump(self) -> None:
        """Snapshots and tap batches on the wire's own loop, as roles/wireproc.py's child."""
        engine = self.engine
        keys = unit_keys(engine.field)
        turn = itertools.cycle(keys)
        per_tick = min(UNITS_PER_TICK, len(keys))
        loop = engine.runtime.loop
        state = {"next": time.monotonic(), "taps": time.monotonic(), "gc": time.monotonic() + GC_PERIOD}

        def tick() -> None:
            if self.stopping.is_set():
                return
            try:
                now = time.monotonic()
                with self.lock:
                    self.broadcast(("units", self.snapshots.payload([next(turn) for _ in range(per_tick)])))
                    wants = any(c.tapping for c in self.seats)
                    if wants != self.tapping:
                        self.tapping = wants
                        engine.add_tap(self.record) if wants else engine.remove_tap(self.record)
                        self.taps.clear()
                    if now - state["taps"] >= TAP_PERIOD:
                        state["taps"] = now
                        if self.taps:
                            data = pickle.dumps(("taps", self.taps), PROTOCOL)
                            self.taps = []
                            for seat in list(self.seats):
                                if seat.tapping:
                                    seat.put(data)
                if now >= state["gc"]:
                    state["gc"] = now + GC_PERIOD
                    _full_collection()
            except Exception:  # noqa: BLE001 - said, and the stream goes on at the next tick
                log.exception("classroom: a snapshot failed; everything goes whole again")
                self.snapshots.resync()
            state["next"] += SNAPSHOT_TICK
            if state["next"] < time.monotonic() - SNAPSHOT_TICK:
                state["next"] = time.monotonic()
            loop.call_at(state["next"], tick)

        loop.call_soon_threadsafe(tick)


def _unit_of(field, host: str | None) -> list:
    if host is None:
        return ["faults"]
    if host == field.fms_name:
        return ["fms"]
    for i, st in enumerate(field.stations):
        if host in (st.ds_name, st.rio_name):
            return [("station", i)]
    return []


def classroom_main(path: str) -> int:
    """The host process: the field from the configuration on stdin, seats on ``path``."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # the server decides when the field stops
    # The server's console says who joins and leaves, and what went wrong; the field's own
    # story goes to its log files, as every field's.
    logging.basicConfig(level=logging.WARNING, stream=sys.stderr, format="%(asctime)s %(message)s", datefmt="%H:%M:%S")
    log.setLevel(logging.INFO)
    config, teacher_key = pickle.loads(sys.stdin.buffer.read())
    engine = ThreadEngine(config)
    try:
        engine.start()
    except (OSError, ValueError) as exc:
        print(f"fieldbox classroom: {exc}", file=sys.stderr, flush=True)
        return 1
    host = ClassroomHost(engine, teacher_key)
    engine.runtime.call(_quiet_collector).result(timeout=CALL_TIMEOUT)
    host.priority = engine.runtime.call(_raise_priority).result(timeout=CALL_TIMEOUT)
    log.info("classroom: the wire thread runs at %s", host.priority[0])
    listener = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    old = os.umask(0o177)  # only this user may join (the folder is the user's own as well)
    try:
        listener.bind(path)
    finally:
        os.umask(old)
    listener.listen(64)
    host.start_pump()
    signal.signal(signal.SIGTERM, lambda *_: host.stopping.set())
    print("ready", flush=True)
    listener.settimeout(0.2)
    try:
        while not host.stopping.is_set():
            try:
                sock, _ = listener.accept()
            except socket.timeout:
                continue
            sock.settimeout(None)
            threading.Thread(target=host.join, args=(Connection(sock.detach()),), name="fieldbox-join",
                             daemon=True).start()
    finally:
        host.stopping.set()
        for seat in list(host.seats):
            seat.close()
        listener.close()
        try:
            os.unlink(path)
        except OSError:
            pass
        engine.stop()
    return 0


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
        root = str(Path(__file__).resolve().parent.parent)
        env = dict(os.environ)
        env["PYTHONPATH"] = root + (os.pathsep + env["PYTHONPATH"] if env.get("PYTHONPATH") else "")
        self.process = subprocess.Popen([sys.executable, "-c", HOST_CODE, self.path], stdin=subprocess.PIPE,
                                        stdout=subprocess.PIPE, env=env, cwd=root)
        self.process.stdin.write(pickle.dumps((self.config, self.teacher_key), PROTOCOL))
        self.process.stdin.close()
        said: list[bytes] = []
        reader = threading.Thread(target=lambda: said.append(self.process.stdout.readline()), daemon=True)
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
    """The app's engine in a classroom: the shared field's mirror, a seat, no process of its own."""

    def __init__(self, path: str, want: Any, config: FieldConfig | None = None) -> None:
        super().__init__(config or FieldConfig(plan="ephemeral", log_files=False))
        self.path = path
        self.want = want
        self.seat: Seat | None = None

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
        self._send(("join", self.want))
        if not self.conn.poll(timeout):
            self.conn.close()
            raise OSError(f"the classroom's field did not answer within {timeout:g} s")
        try:
            msg = pickle.loads(self.conn.recv_bytes())
            while msg[0] != "started":
                msg = pickle.loads(self.conn.recv_bytes())
        except (EOFError, OSError):
            raise OSError("the classroom's field closed the connection") from None
        self.seat = msg[9]
        self._started(msg[1:])
        self._begin_threads()

    def _message(self, msg: tuple) -> None:
        if msg[0] == "seat":
            self.seat = msg[1]

    def stop(self) -> None:
        """This app leaves; the field goes on for the others."""
        self._stopping = True
        if self.conn is None:
            return
        self._outq.put(pickle.dumps(("stop",), PROTOCOL))
        self._outq.put(None)
        if self._writer is not None:
            self._writer.join(0.5)
        self._close_conn()
        if self._reader is not None and self._reader is not threading.current_thread():
            self._reader.join(2.0)
        self._fail_pending("this app left the classroom's field")
        self._release_collector()

    def _exit_code(self) -> int | None:
        return None
