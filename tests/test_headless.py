"""``fieldbox --headless``: commands on stdin, status lines on stdout, clean exits."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import threading
import time

import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def start(*args: str) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-m", "fieldbox", "--headless", "--roles", "ds,rio,fms", *args],
                            cwd=ROOT, stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, bufsize=1)


def read_until(proc: subprocess.Popen, predicate, timeout: float = 15.0) -> list:
    """JSON lines from stdout until ``predicate(obj)``; fails with what was seen."""
    seen = []
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        line = proc.stdout.readline()
        if not line:
            break
        obj = json.loads(line)
        seen.append(obj)
        if predicate(obj):
            return seen
    raise AssertionError(f"not seen; got {seen[-8:]}")


def ds_status(obj, **want) -> bool:
    return obj.get("type") == "status" and obj.get("role") == "ds" and all(obj.get(k) == v for k, v in want.items())


def test_json_session_enable_axis_estop_and_quit():
    proc = start("--roles", "ds,rio", "--team", "254", "--net", "ephemeral", "--json")
    try:
        bound = json.loads(proc.stdout.readline())
        assert bound["type"] == "bound"
        assert set(bound["roles"]) == {"rio 254", "ds 254"}
        assert bound["roles"]["ds 254"]["robot"].startswith("127.0.0.1:")
        read_until(proc, lambda o: ds_status(o, robot_comms=True, robot_code=True))
        proc.stdin.write("mode auto\nenable\n")
        proc.stdin.flush()
        read_until(proc, lambda o: ds_status(o, enabled=True, mode="auto"))
        read_until(proc, lambda o: o.get("role") == "rio" and o.get("enabled") is True and o["mode"] == "auto")
        proc.stdin.write("axis 0 1 -0.5\nestop\n")
        proc.stdin.flush()
        read_until(proc, lambda o: ds_status(o, estopped=True, enabled=False))
        read_until(proc, lambda o: o.get("role") == "rio" and o.get("estopped") is True)
        # A refused command says why on stderr and changes nothing.
        proc.stdin.write("enable\nfly away\nquit\n")
        proc.stdin.flush()
        assert proc.wait(10) == 0
        err = proc.stderr.read()
        assert "error: enable:" in err and "e-stop" in err.lower()
        assert "unknown command 'fly away'" in err
    finally:
        proc.kill()


@pytest.mark.parametrize("how", ["eof", "sigint", "sigterm"])
def test_clean_exit(how):
    proc = start("--net", "ephemeral", "--team", "118")
    try:
        first = proc.stdout.readline()
        assert first.startswith("bound ")
        if how == "eof":
            proc.stdin.close()
        else:
            proc.send_signal(signal.SIGINT if how == "sigint" else signal.SIGTERM)
        assert proc.wait(10) == 0
        assert "Traceback" not in proc.stderr.read()
    finally:
        proc.kill()


def test_text_status_lines_and_bad_arguments():
    proc = start("--roles", "ds,rio", "--team", "1114", "--net", "ephemeral")
    try:
        out = []
        deadline = time.monotonic() + 15
        while time.monotonic() < deadline:
            line = proc.stdout.readline()
            out.append(line)
            if line.startswith("ds 1114 R1:") and "comms ok" in line:
                break
        assert any(l.startswith("ds 1114 R1: teleop disabled | comms ok | code ok") for l in out), out
        proc.stdin.write("quit\n")
        proc.stdin.flush()
        assert proc.wait(10) == 0
    finally:
        proc.kill()
    bad = subprocess.run([sys.executable, "-m", "fieldbox", "--headless", "--team", "99999"], cwd=ROOT,
                         capture_output=True, text=True, timeout=20)
    assert bad.returncode != 0 and "team must be 1..25599" in bad.stderr


def test_text_lines_name_the_station_the_fms_assigned():
    """Issue 29: configured at R1, placed at B1 by the FMS's match, the text line said R1
    (``--json`` already said B1)."""
    proc = start("--roles", "ds,rio,fms", "--team", "254", "--station", "R1", "--net", "ephemeral",
                 "--teams", "118,148,1678,254,1114,2056")
    out: list[str] = []
    threading.Thread(target=lambda: out.extend(proc.stdout), daemon=True).start()  # never blocks the test
    try:
        deadline = time.monotonic() + 20
        while time.monotonic() < deadline and not any(l.startswith("ds 254 B1:") for l in out):
            time.sleep(0.05)
        assert any(l.startswith("ds 254 B1:") for l in out), out
        proc.stdin.write("quit\n")
        proc.stdin.flush()
        assert proc.wait(10) == 0
    finally:
        proc.kill()


def test_fms_alone_names_six_teams():
    proc = start("--roles", "fms", "--teams", "254,1114,2056,118,148,1678", "--net", "ephemeral", "--json")
    try:
        json.loads(proc.stdout.readline())
        status = read_until(proc, lambda o: o.get("role") == "fms")[-1]
        assert [s["team"] for s in status["stations"]] == [254, 1114, 2056, 118, 148, 1678]
        proc.stdin.write("match start\n")
        proc.stdin.flush()
        proc.stdin.close()
        assert proc.wait(10) == 0
        err = proc.stderr.read()
        # Nobody is connected: the refusal lists every station.
        assert err.count("not connected") == 6, err
    finally:
        proc.kill()


def test_full_field_runs_a_match():
    proc = subprocess.Popen([sys.executable, "-m", "fieldbox", "field", "--teams", "254,1114,2056,118,148,1678",
                             "--headless", "--net", "ephemeral", "--json"], cwd=ROOT, stdin=subprocess.PIPE,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, bufsize=1)
    try:
        bound = json.loads(proc.stdout.readline())
        assert len(bound["roles"]) == 13
        read_until(proc, lambda o: o.get("role") == "fms" and all(s["ds_link"] for s in o["stations"]), 30)
        proc.stdin.write("match start\n")
        proc.stdin.flush()
        read_until(proc, lambda o: o.get("role") == "fms" and o["phase"] == "auto")
        enabled = set()
        read_until(proc, lambda o: ds_status(o, enabled=True, mode="auto") and enabled.add(o["team"]) is None
                   and len(enabled) == 6, 20)
        proc.stdin.write("estop B2\n")
        proc.stdin.flush()
        read_until(proc, lambda o: ds_status(o, team=148, estopped=True, enabled=False))
        proc.stdin.write("match abort\nquit\n")
        proc.stdin.flush()
        assert proc.wait(15) == 0
    finally:
        proc.kill()


# -- a reader that went away or never reads: the commands are still obeyed (issue 27) ---------------
class Lines:
    """A stream's lines, read on a thread: a test never blocks on a process that stopped
    writing (a held loop must fail the test, not hang it)."""

    def __init__(self, proc: subprocess.Popen, stream) -> None:
        self.proc = proc
        self.lines: list[str] = []
        self._thread = threading.Thread(target=self._read, args=(stream,), daemon=True)
        self._thread.start()

    def _read(self, stream) -> None:
        for line in stream:
            self.lines.append(line.rstrip("\n"))

    def until(self, predicate, start: int = 0, timeout: float = 30.0) -> tuple[int, str]:
        """The index and text of the first line from ``start`` with ``predicate(line)``."""
        deadline = time.monotonic() + timeout
        while True:
            for i in range(start, len(self.lines)):
                if predicate(self.lines[i]):
                    return i, self.lines[i]
            assert time.monotonic() < deadline and self.proc.poll() is None, \
                f"not seen (fieldbox {'ended' if self.proc.poll() is not None else 'runs'}); got {self.lines[-8:]}"
            time.sleep(0.02)

    def text(self) -> str:
        """Everything, once the process has ended."""
        self._thread.join(10)
        return "".join(line + "\n" for line in self.lines)


def send(proc: subprocess.Popen, *lines: str) -> None:
    proc.stdin.write("".join(line + "\n" for line in lines))
    proc.stdin.flush()


def wait_file(folder, name: str, text: str, proc: subprocess.Popen, count: int = 1, timeout: float = 30.0) -> None:
    """Wait until ``name`` in the run's log folder holds ``text`` ``count`` times: what the
    robot did, seen from outside the process, whatever its stdout does."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        seen = "".join(p.read_text() for p in folder.glob(f"*/{name}"))
        if seen.count(text) >= count:
            return
        assert proc.poll() is None, f"fieldbox ended ({proc.returncode}) before {name} said {text!r}"
        time.sleep(0.02)
    raise AssertionError(f"{name} never said {text!r} {count} time(s); it says {seen[-600:]!r}")


@pytest.mark.parametrize("reader,end", [("closed at once", "quit"), ("head -3", "eof"), ("never read", "quit"),
                                        ("never read", "eof")])
def test_commands_are_obeyed_whatever_stdout_does(tmp_path, reader, end):
    r, w = os.pipe()
    proc = subprocess.Popen([sys.executable, "-m", "fieldbox", "--headless", "--json", "--roles", "ds,rio",
                             "--team", "254", "--net", "ephemeral", "--log-dir", str(tmp_path)],
                            cwd=ROOT, stdin=subprocess.PIPE, stdout=w, stderr=subprocess.PIPE, text=True, bufsize=1)
    os.close(w)
    try:
        err = Lines(proc, proc.stderr)
        if reader == "closed at once":
            os.close(r)
        elif reader == "head -3":
            with os.fdopen(r) as first:
                assert json.loads(first.readline())["type"] == "bound"
                first.readline(), first.readline()
        wait_file(tmp_path, "ds-254-events.log", "robot code running", proc)
        if reader == "never read":  # megabytes of status lines: the pipe is full, and then the backlog
            send(proc, *["status"] * 3000)
            err.until(lambda l: l.startswith("fieldbox: stdout is not being read"))
        rio = "rio-254-events.log"
        for i, (command, said) in enumerate([("enable", "robot enabled in teleop"), ("disable", "robot disabled"),
                                             ("enable", "robot enabled in teleop"), ("estop", "E-STOP: latched")]):
            send(proc, command)
            wait_file(tmp_path, rio, said, proc, count=2 if i == 2 else 1)
        if end == "quit":
            send(proc, "quit")
        else:
            proc.stdin.close()
        assert proc.wait(10) == 0  # a hang guard: the promise is 1.5 s
        text = err.text()
        gone = "fieldbox: stdout is not being read" if reader == "never read" else "fieldbox: stdout is closed"
        assert text.count(gone) == 1, text
        assert "Traceback" not in text and "error:" not in text, text
    finally:
        proc.kill()
        if reader == "never read":
            os.close(r)


def test_an_overlong_command_line_is_refused_unkept_and_the_next_command_obeyed():
    proc = start("--roles", "ds,rio", "--team", "254", "--net", "ephemeral", "--json", "--no-log-files")
    try:
        out, err = Lines(proc, proc.stdout), Lines(proc, proc.stderr)
        out.until(lambda l: ds_status(json.loads(l), robot_comms=True, robot_code=True))
        send(proc, "enable")
        mark, _ = out.until(lambda l: json.loads(l).get("role") == "rio" and json.loads(l)["enabled"] is True)
        send(proc, "disable " * 375_000, "estop")  # a 3 MB line, then the e-stop
        end, _ = out.until(lambda l: json.loads(l).get("role") == "rio" and json.loads(l)["estopped"] is True, mark)
        # nothing of the long line was obeyed: the robot went from enabled to e-stopped
        between = [json.loads(l) for l in out.lines[mark:end]]
        assert not any(o.get("role") == "rio" and o["enabled"] is False and o["estopped"] is False
                       for o in between), between
        send(proc, "quit")
        assert proc.wait(10) == 0
        text = err.text()
        assert text == "error: line over 4096 characters refused (3000000 characters): nothing changed\n", text[:300]
    finally:
        proc.kill()


# -- the DS line says what the robot reports (issue 27) ---------------------------------------------
SPIN = "def robot_periodic(state, robot):\n    if state.enabled:\n        while True:\n            pass\n"
DIE = "import os\ndef robot_periodic(state, robot):\n    if state.enabled:\n        os._exit(3)\n"


def ds_says(**want):
    return lambda line: ds_status(json.loads(line), **want)


@pytest.mark.parametrize("as_json", [False, True])
def test_the_ds_line_says_the_robot_program_is_stuck(tmp_path, as_json):
    program = tmp_path / "spin.py"
    program.write_text(SPIN)
    proc = start("--roles", "ds,rio", "--team", "254", "--net", "ephemeral", "--no-log-files",
                 "--robot-program", str(program), *(["--json"] if as_json else []))
    try:
        out = Lines(proc, proc.stdout)
        if as_json:
            out.until(ds_says(code="ok", robot_enabled=False))
            send(proc, "enable")
            out.until(ds_says(code="stuck", robot_code=True, enabled=True, robot_enabled=True))
        else:
            mark, _ = out.until(lambda l: l.startswith("ds ") and "| code ok |" in l)
            send(proc, "enable")
            _, line = out.until(lambda l: l.startswith("ds ") and "code stuck" in l, mark)
            assert line.startswith("ds 254 R1: teleop enabled | comms ok | code stuck |"), line
        send(proc, "quit")
        assert proc.wait(10) == 0
    finally:
        proc.kill()


@pytest.mark.parametrize("as_json", [False, True])
def test_the_ds_line_says_the_robot_is_disabled_after_its_code_died(tmp_path, as_json):
    program = tmp_path / "die.py"
    program.write_text(DIE)
    proc = start("--roles", "ds,rio", "--team", "254", "--net", "ephemeral", "--no-log-files",
                 "--robot-program", str(program), *(["--json"] if as_json else []))
    try:
        out = Lines(proc, proc.stdout)
        if as_json:
            out.until(ds_says(code="ok"))
            send(proc, "enable")
            # the DS still asks to enable; the robot says it is disabled, without code
            out.until(ds_says(code="none", robot_code=False, enabled=True, robot_enabled=False, robot_estopped=False,
                              robot_comms=True))
        else:
            mark, _ = out.until(lambda l: l.startswith("ds ") and "| code ok |" in l)
            send(proc, "enable")
            _, line = out.until(lambda l: l.startswith("ds ") and "code NO" in l, mark)
            assert line.startswith("ds 254 R1: teleop disabled (DS: enabled) | comms ok | code NO |"), line
        send(proc, "quit")
        assert proc.wait(10) == 0
    finally:
        proc.kill()
