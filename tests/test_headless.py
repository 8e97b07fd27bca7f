"""``fieldbox --headless``: commands on stdin, status lines on stdout, clean exits."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time

import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def start(*args: str) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-m", "fieldbox", "--headless", *args],
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
