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

The server is the wire process's own (roles/runtime/wireproc.py :class:`WireServer`): its
child serves one seat, the app that started it; this process serves many, on a Unix socket.

Who may connect is who may open the socket: the user that started the server (its folder is
0700, the socket 0600). Messages are pickled, as on the wire process's own pipe: a joined
app is fieldbox's code, started by the server; the seats' rules stand between a person at a
tab and the field, not between processes of the same user.
"""

from __future__ import annotations

import logging
import os
import pickle
import secrets
import signal
import socket
import subprocess
import sys
import tempfile
import threading
from pathlib import Path
from multiprocessing.connection import Connection

from .engine import ThreadEngine
from .field import FieldConfig
from .process_tuning import quiet_collector, tune_wire_thread
from .program_host import ROOT, child_environment
from .wireproc import CALL_TIMEOUT, PROTOCOL, Join, ProcessEngine, Seat, SeatWant, TakeBack, WireServer

__all__ = ["ClassroomProcess", "JoinedEngine", "Seat", "TakeBack", "WireServer", "classroom_main", "wanted_seat"]

log = logging.getLogger("fieldbox.classroom")

#: Packets a driver's or an observer's inspector keeps: about 15 s of a full field's traffic
#: (the teacher's and every other app's keep 50,000).
TAB_CAPTURE = 20_000
#: How the host process starts (``sys.argv[1]``: the socket's path; the configuration and the
#: teacher's key come pickled on stdin, out of ``ps``'s sight).
HOST_CODE = ("import sys; sys.modules['ssl'] = None; from roles.runtime.classroom import classroom_main; "
             "sys.exit(classroom_main(sys.argv[1]))")
#: Where ``--join-as teacher`` finds the teacher's key (``fieldbox serve --classroom`` sets it).
KEY_ENV = "FIELDBOX_CLASSROOM_KEY"


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
    host = WireServer(engine, teacher_key)
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
def wanted_seat(text: str) -> SeatWant:
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

    def __init__(self, path: str, want: SeatWant, config: FieldConfig | None = None) -> None:
        super().__init__(config or FieldConfig(plan="ephemeral", log_files=False))
        self.path = path
        self.want = want
        self.seat: Seat | None = None

    NAME = "the classroom's field"
    STOPPED = "this app left the classroom's field"

    def _open(self, timeout: float) -> object:
        sock = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
        sock.settimeout(timeout)
        try:
            sock.connect(self.path)
        except OSError as exc:
            sock.close()
            raise OSError(f"cannot join the classroom's field at {self.path}: {exc.strerror or exc}") from None
        sock.settimeout(None)
        self.conn = Connection(sock.detach())
        return Join(self.want)

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

    def _end_child(self) -> None:
        """This app leaves; the field goes on for the others."""
        self._close_conn()
