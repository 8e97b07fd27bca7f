"""The classroom's fork server (fieldbox/tabfork.py): tabs forked from a warm interpreter run
fieldbox as their command line says, on the pipes they were given; bad requests are refused
and harm no one; the fork server ends with its server."""

from __future__ import annotations

import array
import os
import pickle
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest

from fieldbox.tabfork import ForkServer, _name, fieldbox_argv

from .test_serve import alive, cpu_seconds

pytestmark = pytest.mark.skipif(not hasattr(os, "fork"), reason="forks")

ROOT = Path(__file__).resolve().parents[2]

# a control packet as seed ds_to_rio.rst lays it out: sequence 1, comm version 0x01, control
# 0x00 (teleop, disabled), request 0x00, station 0 (Red 1)
CONTROL = "000101000000"


def test_a_tab_command_is_fieldbox_or_left_alone():
    assert fieldbox_argv(f"{sys.executable} -m fieldbox --join /tmp/x/field.sock --join-as observer") == \
        ["--join", "/tmp/x/field.sock", "--join-as", "observer"]
    assert fieldbox_argv("sh -c 'rm -rf /'") is None
    assert _name(["--join", "s", "--join-as", "teacher-0123"]) == b"fb-tab-teacher"
    assert _name(["--join", "s", "--join-as", "observer"]) == b"fb-tab-observer"
    assert _name(["--theme", "alliance", "replay", "/srv/class/match.pcapng"]) == b"fb-tab-replay"


def open_fds(pid: int) -> int:
    return len(os.listdir(f"/proc/{pid}/fd"))


def run_forked(forks: ForkServer, command: str) -> tuple[int | None, bytes, bytes]:
    """Fork ``command`` on fresh pipes; what it wrote to stdout and stderr."""
    pipes = [os.pipe() for _ in range(3)]
    pid = forks.fork(command, dict(os.environ), (pipes[0][0], pipes[1][1], pipes[2][1]))
    for fd in (pipes[0][0], pipes[1][1], pipes[2][1]):
        os.close(fd)
    os.close(pipes[0][1])  # its stdin: nothing
    out = b"".join(iter(lambda: os.read(pipes[1][0], 65536), b""))
    err = b"".join(iter(lambda: os.read(pipes[2][0], 65536), b""))
    os.close(pipes[1][0])
    os.close(pipes[2][0])
    return pid, out, err


def test_a_forked_tab_runs_fieldbox_on_its_pipes_and_bad_requests_harm_no_one(tmp_path):
    forks = ForkServer(tmp_path)
    assert forks.start()
    try:
        pid, out, err = run_forked(forks, f"{sys.executable} -m fieldbox decode --as ds-to-rio {CONTROL}")
        assert pid is not None and pid != os.getpid()
        assert b"sequence" in out, err
        # garbage, a request without its three descriptors, a huge length, three descriptors
        # with a body that is no request: each refused, said, and its descriptors closed
        fds_before = open_fds(forks.process.pid)
        body = pickle.dumps(5)
        for junk, fds in ((b"\x00\x00\x00\x05hello", []), (b"\xff\xff\xff\xffxx", []),
                          (b"not even a length", []), (len(body).to_bytes(4, "big") + body, [0, 1, 2]),
                          (b"\x00\x00\x00\x05hello", [0, 1, 2])):
            with socket.socket(socket.AF_UNIX, socket.SOCK_STREAM) as s:
                s.settimeout(30)
                s.connect(forks.path)
                s.sendmsg([junk], [(socket.SOL_SOCKET, socket.SCM_RIGHTS, array.array("i", fds).tobytes())] if fds else [])
                s.shutdown(socket.SHUT_WR)
                assert s.recv(64) == b""  # no pid: nothing was forked
        assert forks.process.poll() is None
        assert open_fds(forks.process.pid) == fds_before
        # and the next tab is served as the first was
        pid, out, _ = run_forked(forks, f"{sys.executable} -m fieldbox decode --as ds-to-rio {CONTROL}")
        assert pid is not None and b"sequence" in out
        # not fieldbox: not forked (the caller starts it the usual way)
        assert forks.fork("sh -c true", dict(os.environ), (0, 1, 2)) is None
    finally:
        forks.stop()
    assert forks.process.returncode == 0 and not os.path.exists(forks.path)


def test_the_fork_server_ends_when_its_server_is_gone(tmp_path):
    forks = ForkServer(tmp_path)
    assert forks.start()
    forks.process.stdin.close()  # as when the server dies: its end of the pipe closes
    deadline = time.monotonic() + 30
    while forks.process.poll() is None and time.monotonic() < deadline:
        time.sleep(0.05)
    assert forks.process.poll() == 0
    forks.stop()


def test_a_served_app_sees_its_screen_reader_go():
    """What fieldbox/app.py's served tab checks each second: the pipe its screen goes to has
    no reader any more (its server died)."""
    from fieldbox.app import screen_reader_gone

    read, write = os.pipe()
    try:
        assert not screen_reader_gone(write)
        os.close(read)
        assert screen_reader_gone(write)
    finally:
        os.close(write)


# -- a tab ends with its server, even a killed one ------------------------------------------------
#: Stands for ``fieldbox serve``: starts a tab as the server does (forked by a fork server, or
#: started by tab_argv), holds the tab's pipes, says the pids, and waits to be killed.
SERVER = """
import os, subprocess, sys, time
from fieldbox.tabfork import ForkServer
how, folder, capture = sys.argv[1:]
env = dict(os.environ, TEXTUAL_DRIVER="textual.drivers.headless_driver:HeadlessDriver")
argv = ["replay", capture]
pipes = [os.pipe() for _ in range(3)]
theirs = (pipes[0][0], pipes[1][1], pipes[2][1])
if how == "forked":
    forks = ForkServer(folder)
    assert forks.start()
    pids = [forks.process.pid, forks.fork(" ".join([sys.executable, "-m", "fieldbox", *argv]), env, theirs)]
else:
    from fieldbox.tabfork import PARENT_ENV, tab_argv

    env[PARENT_ENV] = str(os.getpid())
    pids = [subprocess.Popen(tab_argv(argv), env=env, stdin=theirs[0], stdout=theirs[1], stderr=theirs[2]).pid]
print(*pids, flush=True)
time.sleep(600)
"""


@pytest.mark.skipif(not os.path.isdir("/proc"), reason="reads /proc")
@pytest.mark.parametrize("how", ["forked", "started"])
def test_a_tab_that_never_looks_at_its_server_still_ends_when_the_server_is_killed(tmp_path, how):
    """A tab's app sees its server go by its screen's pipe (fieldbox/app.py), but only a served
    app looks, and only while its loop runs: here a replay drawing to no screen at all (Textual's
    headless driver), which left alone plays on for ever after its server is SIGKILLed. Every
    process the server started ends anyway: the fork server, and the tab (forked from it, or
    started by tab_argv)."""
    from .test_replay import recording

    capture, _ = recording(tmp_path)
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    server = subprocess.Popen([sys.executable, "-c", SERVER, how, str(tmp_path), str(capture)], cwd=ROOT,
                              env=env, stdout=subprocess.PIPE, text=True, start_new_session=True)
    pids: list[int] = []
    try:
        pids = [int(p) for p in server.stdout.readline().split()]
        assert pids and all(alive(p) for p in pids), pids
        time.sleep(2.0)  # the tab is up: a replay playing, with no one to show it to
        assert all(alive(p) for p in pids), pids
        os.kill(server.pid, signal.SIGKILL)
        server.wait()
        deadline = time.monotonic() + 15  # a hang guard: the kernel's signal is at once
        while any(alive(p) for p in pids) and time.monotonic() < deadline:
            time.sleep(0.1)
        left = {p: f"{cpu_seconds(p):.2f} s of CPU" for p in pids if alive(p)}
        assert not left, f"still running after their server was killed: {left}"
    finally:
        for pid in pids:
            try:
                os.kill(pid, signal.SIGKILL)
            except OSError:
                pass
        if server.poll() is None:
            server.kill()
            server.wait()
