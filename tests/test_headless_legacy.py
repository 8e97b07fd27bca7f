"""``fieldbox --headless --legacy-2010``: the same stdin commands drive a 2010 DS and robot."""

from __future__ import annotations

import json
import os
import queue
import subprocess
import sys
import threading
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def start(tmp_path, *args: str) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-m", "fieldbox", "--headless", "--legacy-2010", "--net", "ephemeral",
                             "--log-file", str(tmp_path / "fieldbox.log"), *args],
                            cwd=ROOT, stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, bufsize=1)


def send(proc: subprocess.Popen, *lines: str) -> None:
    proc.stdin.write("".join(f"{line}\n" for line in lines))
    proc.stdin.flush()


class Session:
    """Reads the JSON lines on a thread: a test waits on the latest DS and robot status lines,
    with a timeout (no line may ever come: status lines are printed on change only)."""

    def __init__(self, proc: subprocess.Popen) -> None:
        self.proc = proc
        self.lines: queue.Queue = queue.Queue()
        self.latest: dict[str, dict] = {"ds": {}, "rio": {}}
        self.seen: list[dict] = []
        threading.Thread(target=self._read, daemon=True).start()

    def _read(self) -> None:
        for line in self.proc.stdout:
            self.lines.put(json.loads(line))
        self.lines.put(None)

    def next(self, timeout: float = 15.0) -> dict:
        obj = self.lines.get(timeout=timeout)
        assert obj is not None, "fieldbox ended"
        self.seen.append(obj)
        if obj.get("type") == "status" and obj.get("role") in self.latest:
            self.latest[obj["role"]] = obj
        return obj

    def until(self, role: str, timeout: float = 15.0, **want) -> dict:
        """Wait until the latest ``role`` status line has every field of ``want``."""
        deadline = time.monotonic() + timeout
        while True:
            latest = self.latest[role]
            if latest and all(latest.get(k) == v for k, v in want.items()):
                return latest
            left = deadline - time.monotonic()
            try:
                assert left > 0
                self.next(left)
            except (AssertionError, queue.Empty):
                raise AssertionError(f"{role} {want} not seen; last lines {self.seen[-6:]}") from None


def test_headless_legacy_session(tmp_path):
    proc = start(tmp_path, "--roles", "ds,rio,fms", "--team", "294", "--json")  # every role asked: no FMS in 2010
    try:
        io = Session(proc)
        bound = io.next()
        assert bound["type"] == "bound"
        assert set(bound["roles"]) == {"rio 294", "ds 294"}  # no FMS
        assert set(bound["roles"]["ds 294"]) == {"robot", "netconsole", "dashboard"}
        assert set(bound["roles"]["rio 294"]) == {"ds", "netconsole"}  # no TCP in 2010
        first = io.until("ds", robot_comms=True, robot_code=True)
        assert 10.0 < first["battery"] < 14.0 and first["robot_tcp"] is False  # decoded from BCD
        send(proc, "mode auto", "enable")
        io.until("ds", enabled=True, mode="auto")
        io.until("rio", enabled=True, mode="auto")
        send(proc, "mode test", "axis 0 1 -0.5", "button 0 3 1", "pov 0 0 90", "disable")
        io.until("ds", enabled=False, mode="auto")
        io.until("rio", enabled=False)
        send(proc, "mode teleop", "enable")
        io.until("rio", enabled=True, mode="teleop")
        send(proc, "estop")
        io.until("ds", estopped=True, enabled=False)
        io.until("rio", estopped=True, enabled=False)
        # 2010 has no "restart code": the request goes out as the reset bit and the cRIO reboots,
        # which is also what clears a 2010 e-stop.
        send(proc, "enable", "match start", "restart")
        io.until("rio", code_state="rebooting")
        io.until("ds", estopped=False)
        io.until("rio", code_state="running", estopped=False, timeout=20)
        io.until("ds", robot_comms=True, robot_code=True)
        send(proc, "enable")
        io.until("rio", enabled=True)
        send(proc, "reboot")
        io.until("rio", code_state="rebooting")
        send(proc, "quit")
        assert proc.wait(15) == 0
        err = proc.stderr.read()
        assert ("the 2010 field protocol is not documented; the FMS role does not run in --legacy-2010 mode"
                in err)
        assert "error: mode test: the 2010 protocol has no test mode" in err
        assert "error: enable:" in err and "e-stop" in err.lower()
        assert "error: match start: the 2010 field protocol is not documented" in err
        assert "Traceback" not in err
    finally:
        proc.kill()


def test_headless_legacy_text_lines_and_a_bad_dashboard(tmp_path):
    proc = start(tmp_path, "--roles", "ds,rio", "--team", "1114", "--dashboard", "127.0.0.1:0")
    try:
        out = proc.communicate(timeout=20)
    finally:
        proc.kill()
    assert proc.returncode == 1 and "bad --dashboard port 0" in out[1]
    proc = start(tmp_path, "--roles", "ds,rio", "--team", "1114", "--dashboard", "off")
    try:
        lines = []
        deadline = time.monotonic() + 15
        while time.monotonic() < deadline:
            line = proc.stdout.readline()
            lines.append(line)
            if line.startswith("ds 1114 R1:") and "comms ok" in line:
                break
        assert any(l.startswith("ds 1114 R1: teleop disabled | comms ok | code ok") for l in lines), lines
        assert any(l.startswith("bound ds 1114: robot 127.0.0.1:") and "netconsole" in l for l in lines), lines
        send(proc, "quit")
        assert proc.wait(10) == 0
        assert "not documented" not in proc.stderr.read()  # no FMS asked, nothing to say
    finally:
        proc.kill()
