"""Nothing lost (roles/runtime/logfiles.py): console lines, errors, events and the FMS's match log
go to files as they arrive, flushed, so a ``kill -9`` loses nothing that arrived."""

from __future__ import annotations

import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from roles.cores.commands import parse
from roles.runtime.field import Field, FieldConfig
from roles.runtime.logfiles import FieldLog, POLL_PERIOD
from roles.sim.simnet import SimNetwork

ROOT = Path(__file__).resolve().parents[1]
STAMP = r"\d{4}-\d\d-\d\d \d\d:\d\d:\d\d\.\d{3}"


def sim_field(roles=("ds", "rio", "fms"), program=None):
    net = SimNetwork()
    field = Field(FieldConfig(roles=frozenset(roles), team=254, plan="ephemeral", program=program))
    field.start_sim(net)
    return net, field


def read(log: FieldLog, name: str) -> list[str]:
    path = log.folder / name
    return path.read_text(encoding="utf-8").splitlines() if path.exists() else []


def test_console_events_and_match_log_reach_their_files(tmp_path):
    program = tmp_path / "robot.py"
    program.write_text(
        "n = 0\n"
        "def robot_periodic(state, robot):\n"
        "    global n\n"
        "    n += 1\n"
        "    if n == 10:\n"
        "        robot.warning('low pressure')\n"
        "    if n == 12:\n"
        "        raise RuntimeError('arm jammed')\n")
    net, field = sim_field(program=str(program))
    net.run_for(0.5)  # some of it happens before the log is attached: it is written too
    log = FieldLog(field, tmp_path / "logs").attach()
    assert log.folder.parent == tmp_path / "logs" and re.fullmatch(r"\d{8}-\d{6}-\d+", log.folder.name)
    for _ in range(30):
        net.run_for(POLL_PERIOD)
        log.poll()
    net.command(field.fms_name, lambda: field.execute(parse("match start"), net.now))
    net.run_for(0.5)
    log.poll()
    console = read(log, "ds-254-console.log")
    assert any(re.fullmatch(STAMP + r" warning low pressure.*", line) for line in console), console
    assert any(" error " in line and "arm jammed" in line for line in console), console
    events = read(log, "ds-254-events.log")
    assert any("robot comms established" in line for line in events)
    match = read(log, "fms-match.log")
    assert any("DS logged in" in line for line in match), match  # before the attach
    assert any(line.endswith("auto started") for line in match)
    assert all(re.match(STAMP + " ", line) for line in match)
    assert read(log, "rio-254-events.log") and not (log.folder / "rio-254-console.log").exists()
    assert log.errors == 0 and log.missed == 0 and log.lines_written > 10
    log.close()
    assert field.fms.events.listeners == [] and field.stations[0].ds.events.listeners == []


def test_a_match_log_that_scrolled_before_the_attach_says_how_much_is_missing(tmp_path):
    from collections import deque

    net, field = sim_field(roles=("fms",))
    field.fms.match_log = deque(maxlen=3)  # the FMS keeps 10 000; three here
    for _ in range(5):
        net.command(field.fms_name, lambda: field.execute(parse("match next"), net.now))
    assert field.fms.match_log_total - len(field.fms.match_log) >= 2
    log = FieldLog(field, tmp_path).attach()
    match = read(log, "fms-match.log")
    missed = field.fms.match_log_total - 3
    assert match[0].endswith(f"fieldbox {missed} earlier match log entries not logged: the FMS keeps the last 3")
    assert [line.split(" ", 2)[2] for line in match[1:]] == [text for _, text in field.fms.match_log]
    log.close()


def test_a_robot_without_a_ds_logs_its_own_console(tmp_path):
    net, field = sim_field(roles=("rio",))
    log = FieldLog(field, tmp_path).attach()
    net.run_for(0.2)
    log.poll()
    assert any("Robot program started" in line for line in read(log, "rio-254-console.log"))
    log.close()


def test_an_overflow_between_polls_is_counted_and_said(tmp_path):
    net, field = sim_field(roles=("ds",))
    ds = field.stations[0].ds
    log = FieldLog(field, tmp_path).attach()
    for i in range(ds.console.maxlen + 100):
        ds.add_console_line(net.now, "stdout", f"line {i}")
    assert log.poll() == ds.console.maxlen
    assert log.missed == 100
    lines = read(log, "ds-254-console.log")
    assert "100 console line(s) not logged" in lines[0] and lines[-1].endswith(f"line {ds.console.maxlen + 99}")
    # a multi-line text (a call stack) stays together: its next lines indented
    ds.add_console_line(net.now, "error", "Traceback:\n  File robot.py, line 8\nRuntimeError: arm jammed")
    log.poll()
    last = read(log, "ds-254-console.log")[-3:]
    assert re.fullmatch(STAMP + " error Traceback:", last[0])
    assert last[1:] == ["      File robot.py, line 8", "    RuntimeError: arm jammed"]


def test_a_failing_disk_is_counted_never_raised_into_a_core(tmp_path):
    net, field = sim_field(roles=("ds", "rio"))
    log = FieldLog(field, tmp_path).attach()

    class Broken:
        def write(self, text):
            raise OSError(28, "No space left on device")

        def flush(self):
            raise OSError(28, "No space left on device")

        def close(self):
            pass

    for name in list(log._files):
        log._files[name] = Broken()
    net.run_for(2.0)  # events fire inside the cores: nothing may escape into them
    log.poll()
    assert field.stations[0].ds.robot_comms
    assert log.errors > 0 and "No space left" in log.last_error
    log.close()


def test_old_runs_are_pruned(tmp_path):
    for i in range(5):
        (tmp_path / f"20240101-00000{i}-1").mkdir()
    (tmp_path / "keep-me").mkdir()
    net, field = sim_field(roles=("ds",))
    log = FieldLog(field, tmp_path, keep_runs=3)
    runs = sorted(p.name for p in tmp_path.iterdir())
    assert runs == ["20240101-000003-1", "20240101-000004-1", log.folder.name, "keep-me"]


def test_killed_headless_run_keeps_what_arrived(tmp_path):
    """``fieldbox --headless`` killed with SIGKILL: every line that arrived before is in the files."""
    proc = subprocess.Popen([sys.executable, "-m", "fieldbox", "--headless", "--net", "ephemeral", "--team", "254",
                             "--log-dir", str(tmp_path)], cwd=ROOT, stdin=subprocess.PIPE,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, bufsize=1)
    try:
        folder = None
        deadline = time.monotonic() + 20
        while time.monotonic() < deadline:
            line = proc.stdout.readline()
            if line.startswith("logs "):
                folder = Path(line[5:].strip())
            if line.startswith("fms:") and "R1:254+" in line:
                break
        assert folder is not None and folder.parent == tmp_path
        proc.stdin.write("match start\n")
        proc.stdin.flush()
        while time.monotonic() < deadline:
            line = proc.stdout.readline()
            if line.startswith("rio ") and "enabled" in line and "disabled" not in line:
                break
        else:
            pytest.fail("the robot never enabled")
        time.sleep(2 * POLL_PERIOD + 0.1)  # the console line's batch is at most one poll old
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait(10)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait(10)
    console = (folder / "ds-254-console.log").read_text()
    assert "Robot program started" in console and "Robot enabled in auto" in console, console
    assert "auto started" in (folder / "fms-match.log").read_text()
    assert "robot comms established" in (folder / "ds-254-events.log").read_text()
    assert proc.returncode == -signal.SIGKILL


def test_start_on_a_wire_thread_as_the_app_runs_it(tmp_path):
    """The app's way: the field on its own thread (ThreadEngine), whose log attaches and
    polls there; stopping the engine closes it and leaves no listener behind."""
    from roles.runtime.engine import ThreadEngine

    engine = ThreadEngine(FieldConfig(roles=frozenset({"ds", "rio"}), team=254, plan="ephemeral",
                                      log_dir=str(tmp_path)))
    engine.start()
    ds = engine.field.stations[0].ds
    try:
        log = engine.log
        assert log is not None and log.folder.parent == tmp_path
        path = log.folder / "ds-254-console.log"
        deadline = time.monotonic() + 10
        while time.monotonic() < deadline and "Robot program started" not in (
                path.read_text() if path.exists() else ""):
            time.sleep(0.05)
        assert "Robot program started" in path.read_text()
    finally:
        engine.stop()
    assert ds.events.listeners == [] and engine.log is None
