"""Safety under stress, end to end: a fake roboRIO in its own ``fieldbox --headless --roles rio``
process, misbehaving robot programs, a stalled process, a DS that falls silent, closed input,
a full disk (issue 16's "done when").

The DS here is a script: a UDP socket that sends real control packets every 20 ms and keeps
every reply, so a test can say which reply answered which packet. Nothing here measures how
fast: each assertion is about what the replies and status lines say (the figures are
``python benchmarks/stress.py``'s), and each wait is generous for a loaded 2-core machine.
"""

from __future__ import annotations

import json
import os
import resource
import select
import signal
import socket
import subprocess
import sys
import threading
import time

import pytest

from protocol.ds_to_rio import ControlPacket
from protocol.rio_to_ds import decode_status

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
PATIENCE = 30.0

pytestmark = pytest.mark.skipif(not sys.platform.startswith("linux"), reason="signals and rlimits of Linux")


class Headless:
    """``fieldbox --headless --json`` in a process of its own; its JSON lines read on a thread."""

    def __init__(self, *args: str, preexec=None) -> None:
        self.proc = subprocess.Popen([sys.executable, "-m", "fieldbox", "--headless", "--json", "--net", "ephemeral", "--roles", "ds,rio,fms",
                                      *args], cwd=ROOT, stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                                     stderr=subprocess.PIPE, text=True, bufsize=1, preexec_fn=preexec)
        self.lines: list[dict] = []
        self.err: list[str] = []
        self._lock = threading.Lock()
        threading.Thread(target=self._read, args=(self.proc.stdout, True), daemon=True).start()
        threading.Thread(target=self._read, args=(self.proc.stderr, False), daemon=True).start()
        self.bound = self.wait_for(lambda o: o.get("type") == "bound")["roles"]

    def _read(self, stream, is_json: bool) -> None:
        for line in stream:
            with self._lock:
                if is_json:
                    self.lines.append(json.loads(line))
                else:
                    self.err.append(line)

    def address(self, role: str, link: str) -> tuple[str, int]:
        host, port = self.bound[role][link].rsplit(":", 1)
        return host, int(port)

    def wait_for(self, predicate, start: int = 0) -> dict:
        end = time.monotonic() + PATIENCE
        while time.monotonic() < end:
            with self._lock:
                for obj in self.lines[start:]:
                    if predicate(obj):
                        return obj
            time.sleep(0.01)
        raise AssertionError(f"not seen; last lines {self.lines[-5:]}; stderr {self.err[-5:]}")

    def send(self, text: str) -> None:
        self.proc.stdin.write(text + "\n")
        self.proc.stdin.flush()

    def quit(self) -> int:
        self.send("quit")
        return self.proc.wait(PATIENCE)

    def close(self) -> None:
        if self.proc.poll() is None:
            self.proc.kill()
            self.proc.wait()


class ScriptedDS:
    """A Driver Station in a test: control packets every 20 ms on a thread, every reply kept
    as (reply, the state the DS was sending when it came)."""

    def __init__(self, robot: tuple[str, int]) -> None:
        self.robot = robot
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.bind(("127.0.0.1", 0))
        self.enabled = False
        self.estop = False
        self.sending = True
        self.seq = 0
        self.sent: dict[int, tuple[bool, bool]] = {}  # sequence -> (enabled, estop) it carried
        self.replies: list[tuple[float, object]] = []
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()

    def _run(self) -> None:
        next_at = time.monotonic()
        while not self._stop.is_set():
            now = time.monotonic()
            if now >= next_at:
                next_at += 0.020
                if self.sending:
                    self.seq = (self.seq + 1) & 0xFFFF
                    self.sent[self.seq] = (self.enabled, self.estop)
                    self.sock.sendto(ControlPacket(sequence=self.seq, enabled=self.enabled, estop=self.estop).encode(),
                                     self.robot)
            ready, _, _ = select.select([self.sock], [], [], max(0.0, next_at - time.monotonic()))
            if ready:
                try:
                    data = self.sock.recv(2048)
                except OSError:
                    continue
                self.replies.append((time.monotonic(), decode_status(data)))

    def wait_reply(self, predicate, after: int = 0):
        end = time.monotonic() + PATIENCE
        while time.monotonic() < end:
            for _, reply in self.replies[after:]:
                if predicate(reply):
                    return reply
            time.sleep(0.01)
        raise AssertionError(f"no such reply; last {[r for _, r in self.replies[-3:]]}")

    def close(self) -> None:
        self._stop.set()
        self._thread.join(2)
        self.sock.close()


def write(tmp_path, name: str, source: str) -> str:
    path = tmp_path / name
    path.write_text(source)
    return str(path)


@pytest.fixture
def made():
    things = []
    yield things
    for thing in reversed(things):
        thing.close()


def rio_status(**want):
    return lambda o: o.get("type") == "status" and o.get("role") == "rio" and all(o.get(k) == v for k, v in want.items())


def enabled_robot(made, *args: str) -> tuple[Headless, ScriptedDS]:
    """``fieldbox --headless --roles rio ARGS`` and a scripted DS that has enabled it."""
    rio = Headless("--roles", "rio", "--no-log-files", *args)
    made.append(rio)
    ds = ScriptedDS(rio.address("rio 1", "ds"))
    made.append(ds)
    rio.wait_for(rio_status(code_state="running"))
    ds.enabled = True
    ds.wait_reply(lambda r: r.enabled)
    return rio, ds


def test_a_30ms_program_in_its_own_rio_process_obeys_an_estop_at_once_and_silence_disables(tmp_path, made):
    rio, ds = enabled_robot(made, "--robot-program", write(tmp_path, "slow.py", "import time\n"
                                                           "def robot_periodic(state, robot):\n    time.sleep(0.030)\n"))
    # the DS falls silent: the robot's status says disabled (its watchdog, on arrival time)
    mark = len(rio.lines)
    ds.sending = False
    rio.wait_for(rio_status(enabled=False), mark)
    ds.sending = True
    ds.wait_reply(lambda r: r.enabled, len(ds.replies))  # a fresh enabled packet enables again
    # the DS's first e-stop packet: the reply to that very packet says e-stopped
    ds.estop = True
    end = time.monotonic() + PATIENCE
    while time.monotonic() < end and not any(estop for _, estop in list(ds.sent.values())):
        time.sleep(0.005)
    first = min(seq for seq, (_, estop) in list(ds.sent.items()) if estop)
    reply = ds.wait_reply(lambda r: r.sequence == first)
    assert reply.estop and not reply.enabled
    ds.estop = False  # the DS clears its bit and keeps asking to enable: the robot does not
    time.sleep(0.5)
    after = [r for _, r in list(ds.replies) if r.sequence >= first]
    assert len(after) > 10 and not any(r.enabled for r in after)
    rio.wait_for(rio_status(estopped=True))
    assert rio.quit() == 0


def test_after_a_2s_stall_of_the_robots_process_no_reply_says_enabled(tmp_path, made):
    rio, ds = enabled_robot(made)
    os.kill(rio.proc.pid, signal.SIGSTOP)  # a loaded laptop
    try:
        time.sleep(1.0)
        ds.enabled = False  # the DS disables while the robot's process is stopped
        time.sleep(1.0)
    finally:
        os.kill(rio.proc.pid, signal.SIGCONT)
    resumed = len(ds.replies)
    stalled_from = ds.seq - 100  # about 2 s of packets queued in the robot's socket
    time.sleep(1.0)
    late = ds.replies[resumed:]
    assert len(late) > 40  # the backlog was answered, and the packets after it
    assert not any(r.enabled for _, r in late), [r.sequence for _, r in late if r.enabled]
    assert any(r.sequence < stalled_from + 50 for _, r in late)  # old packets among them: answered, not obeyed
    assert rio.quit() == 0


def test_an_endless_loop_is_said_stuck_the_robot_answers_and_quit_ends_fieldbox(tmp_path, made):
    rio = Headless("--roles", "ds,rio", "--no-log-files", "--robot-program",
                   write(tmp_path, "spin.py", "def robot_periodic(state, robot):\n"
                                              "    if state.enabled:\n        while True:\n            pass\n"))
    made.append(rio)
    rio.wait_for(lambda o: o.get("role") == "ds" and o.get("robot_code"))
    rio.send("enable")
    rio.wait_for(rio_status(code_state="stuck"))
    mark = len(rio.lines)
    time.sleep(1.5)
    # the DS still hears its robot: no comms loss while the program spins
    with rio._lock:
        assert not any(o.get("role") == "ds" and o.get("robot_comms") is False for o in rio.lines[mark:])
    assert rio.quit() == 0
    assert not any("Traceback" in line for line in rio.err)


@pytest.mark.parametrize("name,source", [
    ("kbi.py", "def robot_periodic(state, robot):\n    raise KeyboardInterrupt\n"),
    ("nan.py", "def robot_periodic(state, robot):\n    robot.left_rumble[0] = float('nan')\n"),
    ("none.py", "def robot_periodic(state, robot):\n    robot.outputs = None\n"),
    ("minus5.py", "def robot_periodic(state, robot):\n    robot.right_rumble[1] = -5\n"),
])
def test_a_misbehaving_program_leaves_fieldbox_up_the_ds_with_comms_and_stderr_quiet(tmp_path, made, name, source):
    run = Headless("--roles", "ds,rio", "--no-log-files", "--robot-program", write(tmp_path, name, source))
    made.append(run)
    run.wait_for(lambda o: o.get("role") == "ds" and o.get("robot_comms"))
    run.send("enable")
    time.sleep(2.0)
    mark = len(run.lines)
    run.send("status")
    status = run.wait_for(lambda o: o.get("role") == "ds" and o.get("type") == "status", mark)
    assert status["robot_comms"] is True
    assert run.quit() == 0
    time.sleep(0.2)
    assert all(line.startswith("error: ") for line in run.err), run.err  # a refusal says why; no traceback


@pytest.mark.parametrize("how", ["closed", "eof"])
def test_closed_stdin_and_end_of_input_end_headless(how):
    proc = subprocess.Popen([sys.executable, "-m", "fieldbox", "--headless", "--roles", "ds,rio", "--net",
                             "ephemeral", "--no-log-files"], cwd=ROOT,
                            stdin=subprocess.DEVNULL if how == "eof" else None, stdout=subprocess.DEVNULL,
                            stderr=subprocess.PIPE, pass_fds=(), close_fds=True,
                            preexec_fn=(lambda: os.close(0)) if how == "closed" else None)
    try:
        assert proc.wait(PATIENCE) == 0
        assert b"Traceback" not in proc.stderr.read()
    finally:
        if proc.poll() is None:
            proc.kill()


def test_a_full_log_disk_is_said_and_the_run_goes_on(tmp_path, made):
    limit = 600  # bytes a file may grow to: a disk that fills up at once

    def small_files() -> None:
        resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))

    run = Headless("--roles", "ds,rio", "--log-dir", str(tmp_path), preexec=small_files)
    made.append(run)
    run.wait_for(lambda o: o.get("role") == "ds" and o.get("robot_comms"))
    end = time.monotonic() + PATIENCE
    while time.monotonic() < end and not any("log files in" in line for line in run.err):
        run.send("mode auto")
        run.send("mode teleop")
        time.sleep(0.1)
    said = [line for line in run.err if "log files in" in line]
    assert said and "failed" in said[0] and "the field runs on" in said[0]
    run.send("status")
    assert run.quit() == 0


def test_the_exit_guard_ends_a_process_whose_loop_is_held():
    # what SIGTERM, quit and end of input arm in `fieldbox --headless`: if the field does not
    # stop (its loop held), the process ends anyway, saying so
    code = ("import sys, time\nfrom fieldbox.headless import ExitGuard\n"
            "ExitGuard(True, sys.stderr).arm()\ntime.sleep(60)\n")
    done = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, timeout=PATIENCE)
    assert done.returncode == 0 and "did not stop within" in done.stderr
