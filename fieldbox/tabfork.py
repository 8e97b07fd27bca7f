"""Tabs forked from one warm interpreter (``fieldbox serve --classroom`` and ``--replay``).

Each browser tab is an app process. Started afresh, each one imports Python, Textual and
fieldbox on its own: 53 MB of private memory per tab, 30 tabs on a laptop. Forked from a
process that imported all of that once (and froze it out of the collector's way), the tabs
share those pages until they write them: the observer's bar of 60 MB a tab (docs/figures.md).

The fork server is a process of its own, started before any thread: it reads one request per
connection on a private Unix socket (the tab's stdin, stdout and stderr as file descriptors,
its command line, environment and folder), forks, answers the child's pid, and in the child
runs ``fieldbox`` as the command line says, with the environment textual-serve built for it.
A tab it cannot fork is started the usual way, and the server's console says why.

Every process the server starts ends when the server does, even killed (SIGKILL, a crash):
left alone, a tab drew and drove its field into a dead pipe for an hour. Each one watches the
process that started it (:func:`end_with_parent`): on Linux the kernel sends it SIGTERM when
that process dies (``PR_SET_PDEATHSIG``), and anywhere a thread sees its parent pid change.
SIGTERM is what a tab's app takes as "quit" (textual's web driver); one that has not ended
5 s later ends anyway. The fork server also ends when its stdin, the server's pipe, reads EOF.
Tabs that are not forked (a field's own, or any when the fork server failed) are started by
:func:`tab_argv`, which does the same before it runs ``fieldbox``.
"""

from __future__ import annotations

import array
import functools
import importlib
import logging
import os
import pickle
import select
import shlex
import signal
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path
from typing import Any

from roles.runtime.process_tuning import freeze_for_forks

log = logging.getLogger("fieldbox.serve")

#: The largest request (command line and environment, pickled), bytes.
REQUEST_MAX = 1 << 20
#: How long one request may take to arrive whole, seconds (one client at a time is served).
REQUEST_SECONDS = 5.0
#: The modules a tab needs, imported once by the fork server.
WARM = ("fieldbox.launch", "fieldbox.app", "fieldbox.cli", "roles.runtime.classroom", "textual.drivers.web_driver",
        "fieldbox.replay", "fieldbox.panels.inspector", "fieldbox.panels.timeline")
#: In the environment of a process the server starts: the server's pid, the parent it watches
#: (read before anything else, so a server that died first is noticed too).
PARENT_ENV = "FIELDBOX_SERVE_PID"
#: How often a process looks whether its parent is still there, seconds (where the kernel does
#: not tell it: not Linux), and how long an app told to quit then has before it ends anyway.
PARENT_PERIOD, PARENT_GRACE = 0.5, 5.0
#: A tab that is not forked: ``python -c TAB_CODE ARGS`` watches its server, then runs fieldbox ARGS.
TAB_CODE = "import sys; from fieldbox.tabfork import run_tab; sys.exit(run_tab(sys.argv[1:]))"


def _parent_death_signal(sig: int) -> None:
    """Ask Linux to send ``sig`` to this process when the thread that started it ends."""
    if sys.platform.startswith("linux"):
        try:
            import ctypes

            ctypes.CDLL(None, use_errno=True).prctl(1, int(sig), 0, 0, 0)  # PR_SET_PDEATHSIG
        except (OSError, AttributeError):
            pass


def parent_from_environment() -> int | None:
    """The pid the server put in :data:`PARENT_ENV` (taken out of the environment: the
    process's own children have another parent), or None."""
    try:
        return int(os.environ.pop(PARENT_ENV, ""))
    except ValueError:
        return None


def end_with_parent(parent: int, period: float = PARENT_PERIOD, grace: float = PARENT_GRACE) -> None:
    """End this process when ``parent`` (the pid that started it) is gone: SIGTERM to itself,
    at once on Linux (the kernel's), else within ``period`` (a thread that watches the parent
    pid; it also catches a parent that died before this was called); ``grace`` seconds later,
    if it is still here, it ends with code 1. Quietly: the server that would show a word is gone."""
    _parent_death_signal(signal.SIGTERM)

    def watch() -> None:
        while os.getppid() == parent:
            time.sleep(period)
        log.info("the server (pid %d) is gone: this process ends", parent)
        try:
            os.kill(os.getpid(), signal.SIGTERM)  # as the kernel's signal: the app quits
        except OSError:
            pass
        time.sleep(grace)
        os._exit(1)  # it did not: ending it hung (a dead pipe, a stuck field)

    threading.Thread(target=watch, name="fieldbox-parent", daemon=True).start()


def tab_argv(argv: list[str]) -> list[str]:
    """The command line of a tab that is not forked: fieldbox ``argv``, run by :func:`run_tab`."""
    return [sys.executable, "-c", TAB_CODE, *argv]


def run_tab(argv: list[str]) -> int:
    """A tab's process, started by the server: it watches the server (:data:`PARENT_ENV`), then
    runs ``fieldbox argv``."""
    parent = parent_from_environment()
    if parent is not None:
        end_with_parent(parent)
    from fieldbox.cli import main

    sys.argv = [sys.argv[0], *argv]
    return main(argv) or 0


def fieldbox_argv(command: str) -> list[str] | None:
    """The arguments of ``python -m fieldbox ARGS`` (a tab's command), or None if it is not one."""
    argv = shlex.split(command)
    if len(argv) >= 3 and argv[1:3] == ["-m", "fieldbox"]:
        return argv[3:]
    return None


def _name(argv: list[str]) -> bytes:
    """What ``ps`` and /proc/PID/comm show for a tab: its seat, or replay (15 bytes at most)."""
    seat = argv[argv.index("--join-as") + 1] if "--join-as" in argv[:-1] else "replay" if "replay" in argv else "app"
    return f"fb-tab-{seat.split('-')[0]}".encode()[:15]


def _set_name(name: bytes) -> None:
    try:
        import ctypes

        ctypes.CDLL(None, use_errno=True).prctl(15, ctypes.c_char_p(name), 0, 0, 0)  # PR_SET_NAME
    except (OSError, AttributeError):
        pass


def _child(fds: list[int], argv: list[str], env: dict[str, str], cwd: str, parent: int) -> None:
    """In the forked tab: its pipes as 0, 1 and 2, its environment, then fieldbox; it ends when
    ``parent`` (the fork server) does. Never returns."""
    code = 1
    try:
        end_with_parent(parent)  # first: its fork server may be gone already
        signal.signal(signal.SIGINT, signal.default_int_handler)  # as any Python starts
        signal.signal(signal.SIGPIPE, signal.SIG_IGN)
        for sig in (signal.SIGTERM, signal.SIGCHLD):
            signal.signal(sig, signal.SIG_DFL)
        for target, fd in enumerate(fds):
            os.dup2(fd, target)
            os.close(fd)
        os.environ.clear()
        os.environ.update(env)
        os.environ.pop(PARENT_ENV, None)  # its parent is the fork server, watched above
        os.chdir(cwd)
        import random

        from .textual_fixes import reread_environment

        random.seed()
        reread_environment()  # this tab's, not the fork server's
        _set_name(_name(argv))
        sys.argv = [sys.argv[0], *argv]
        from fieldbox.cli import main

        code = main(argv) or 0
    except SystemExit as exc:
        code = exc.code if isinstance(exc.code, int) else (0 if exc.code is None else 1)
    except BaseException:  # noqa: BLE001 - said on the tab's stderr, which the server prints
        import traceback

        traceback.print_exc()
    finally:
        try:
            sys.stdout.flush()
            sys.stderr.flush()
        finally:
            os._exit(code)


def serve_forks(path: str) -> int:
    """The fork server's loop (its own process; see the module's docstring)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # the server decides when it ends
    signal.signal(signal.SIGCHLD, signal.SIG_IGN)  # tabs that end are reaped by the kernel
    # Gone with the server, even killed: the kernel's SIGTERM (Linux), else the loop below sees
    # stdin's EOF or another parent pid. Its tabs then see it gone (their own end_with_parent).
    # No thread here: a fork copies only the thread that forks.
    parent = parent_from_environment() or os.getppid()
    _parent_death_signal(signal.SIGTERM)
    for name in WARM:
        importlib.import_module(name)
    listener = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    old = os.umask(0o177)
    try:
        listener.bind(path)
    finally:
        os.umask(old)
    listener.listen(64)
    freeze_for_forks()  # the tabs share the imports' pages
    print("ready", flush=True)
    stdin = sys.stdin.fileno()
    while True:
        ready, _, _ = select.select([listener, stdin], [], [], PARENT_PERIOD)
        if (stdin in ready and not os.read(stdin, 4096)) or os.getppid() != parent:
            return 0  # the server is gone
        if listener not in ready:
            continue
        conn, _ = listener.accept()
        with conn:
            fds: list[int] = []
            try:
                request = _receive(conn, fds)
                me = os.getpid()
                pid = os.fork()
            except Exception as exc:  # noqa: BLE001 - one bad request or a failed fork: said, the next is served
                for fd in fds:
                    os.close(fd)
                print(f"fieldbox serve: a tab's request was refused: {exc}", file=sys.stderr, flush=True)
                continue
            if pid == 0:
                listener.close()
                conn.close()
                _child(fds, *request, parent=me)
            for fd in fds:
                os.close(fd)
            try:
                conn.sendall(str(pid).encode())
            except OSError:
                pass


def _receive(conn: socket.socket, fds: list[int]) -> tuple[list[str], dict[str, str], str]:
    """One request, within :data:`REQUEST_SECONDS` in all; the descriptors it carried go into
    ``fds`` as they come (the caller closes them whatever happens)."""
    deadline = time.monotonic() + REQUEST_SECONDS

    def wait() -> None:
        left = deadline - time.monotonic()
        if left <= 0:
            raise TimeoutError(f"no whole request within {REQUEST_SECONDS:g} s")
        conn.settimeout(left)

    wait()
    received = array.array("i")
    data, ancillary, _, _ = conn.recvmsg(REQUEST_MAX, socket.CMSG_SPACE(3 * received.itemsize))
    for level, kind, payload in ancillary:
        if level == socket.SOL_SOCKET and kind == socket.SCM_RIGHTS:
            received.frombytes(payload[:len(payload) - len(payload) % received.itemsize])
    fds.extend(received)
    if len(fds) != 3:
        raise ValueError(f"{len(fds)} file descriptors, not 3")
    while len(data) < 4 or len(data) < int.from_bytes(data[:4], "big") + 4:
        if len(data) > REQUEST_MAX + 4:
            break
        wait()
        more = conn.recv(REQUEST_MAX)
        if not more:
            break
        data += more
    size = int.from_bytes(data[:4], "big") if len(data) >= 4 else 0
    if not 0 < size <= REQUEST_MAX or len(data) != size + 4:
        raise ValueError("a request of the wrong length")
    request = pickle.loads(data[4:])
    if not (isinstance(request, tuple) and len(request) == 3 and isinstance(request[0], list)
            and all(isinstance(a, str) for a in request[0]) and isinstance(request[1], dict)
            and isinstance(request[2], str)):
        raise ValueError("a request that is not a command line, an environment and a folder")
    return request


class ForkServer:
    """The fork server, from the side that starts it and asks it for tabs."""

    def __init__(self, folder: str | Path) -> None:
        self.path = str(Path(folder) / "tabs.sock")
        self.process: subprocess.Popen | None = None

    def start(self, timeout: float = 60.0) -> bool:
        """Start it; False (and the reason logged) if it did not come up."""
        from roles.runtime.program_host import ROOT, child_environment

        code = "import sys; from fieldbox.tabfork import serve_forks; sys.exit(serve_forks(sys.argv[1]))"
        env = child_environment()
        env[PARENT_ENV] = str(os.getpid())
        self.process = subprocess.Popen([sys.executable, "-c", code, self.path], stdin=subprocess.PIPE,
                                        stdout=subprocess.PIPE, env=env, cwd=ROOT)
        out = self.process.stdout
        assert out is not None  # a pipe
        ready, _, _ = select.select([out], [], [], timeout)
        if not ready or out.readline().strip() != b"ready":
            log.warning("the tabs' fork server did not start: each tab starts on its own")
            self.stop()
            return False
        return True

    def fork(self, command: str, env: dict[str, str], fds: tuple[int, int, int]) -> int | None:
        """A tab running ``command`` on ``fds`` (its stdin, stdout, stderr): its pid, or None
        when this command is not fieldbox's or the fork server cannot make it."""
        argv = fieldbox_argv(command)
        if argv is None or self.process is None or self.process.poll() is not None:
            return None
        data = pickle.dumps((argv, env, os.getcwd()))
        try:
            with socket.socket(socket.AF_UNIX, socket.SOCK_STREAM) as sock:
                sock.settimeout(10.0)
                sock.connect(self.path)
                message = len(data).to_bytes(4, "big") + data
                sent = sock.sendmsg([message], [(socket.SOL_SOCKET, socket.SCM_RIGHTS, array.array("i", fds).tobytes())])
                sock.sendall(message[sent:])
                answer = sock.recv(64)
            return int(answer)
        except (OSError, ValueError) as exc:
            log.warning("the tabs' fork server failed (%s): this tab starts on its own", exc)
            return None

    def stop(self) -> None:
        if self.process is None:
            return
        try:
            assert self.process.stdin is not None  # a pipe
            self.process.stdin.close()
        except OSError:
            pass
        try:
            self.process.wait(5)
        except subprocess.TimeoutExpired:
            self.process.kill()
            self.process.wait()
        if self.process.stdout is not None:
            self.process.stdout.close()
        try:
            os.unlink(self.path)
        except OSError:
            pass


class ForkedProcess:
    """What textual-serve's AppService reads of a process: its stdin (a StreamWriter), its
    stdout and stderr (StreamReaders), and its pid."""

    def __init__(self, pid: int, stdin: Any, stdout: Any, stderr: Any) -> None:
        self.pid, self.stdin, self.stdout, self.stderr = pid, stdin, stdout, stderr
        self.returncode = None


async def open_forked(server: ForkServer, command: str, env: dict[str, str]) -> ForkedProcess | None:
    """A forked tab with asyncio streams on its pipes, or None (then start it the usual way)."""
    import asyncio

    loop = asyncio.get_running_loop()
    pipes = [os.pipe() for _ in range(3)]  # (read, write) each: stdin, stdout, stderr
    theirs = (pipes[0][0], pipes[1][1], pipes[2][1])
    mine = (pipes[0][1], pipes[1][0], pipes[2][0])
    def fork() -> int | None:  # in a worker thread; the child's ends are closed there, after
        try:
            return server.fork(command, env, theirs)
        finally:
            for fd in theirs:
                os.close(fd)

    future = loop.run_in_executor(None, fork)
    try:
        pid = await asyncio.shield(future)
    except BaseException:  # the tab went before its app came: its pipes close, and so it ends
        def close_mine(_: Any) -> None:
            for fd in mine:
                os.close(fd)
        future.add_done_callback(close_mine)
        raise
    if pid is None:
        for fd in mine:
            os.close(fd)
        return None
    files = [os.fdopen(mine[0], "wb", buffering=0), os.fdopen(mine[1], "rb", buffering=0),
             os.fdopen(mine[2], "rb", buffering=0)]
    transports: list[Any] = []
    try:
        readers = []
        for file in files[1:]:
            reader = asyncio.StreamReader(limit=2 ** 16, loop=loop)
            transport, _ = await loop.connect_read_pipe(
                functools.partial(asyncio.StreamReaderProtocol, reader, loop=loop), file)
            transports.append(transport)
            readers.append(reader)
        write_transport, protocol = await loop.connect_write_pipe(asyncio.streams.FlowControlMixin, files[0])
        transports.append(write_transport)
    except BaseException:
        for transport in transports:
            transport.close()
        for file in files:
            file.close()
        raise
    writer = asyncio.StreamWriter(write_transport, protocol, None, loop)
    return ForkedProcess(pid, writer, *readers)
