"""Nothing lost (roles/runtime/logfiles.py): console lines, errors, events and the FMS's match log
go to files as they arrive, flushed, so a ``kill -9`` loses nothing that arrived."""

from __future__ import annotations

import datetime
import errno
import os
import re
import shutil
import signal
import struct
import subprocess
import sys
import time
from pathlib import Path

import pytest

from roles.runtime.field import Field, FieldConfig
from roles.runtime.logfiles import FieldLog, POLL_PERIOD
from roles.sim.simnet import SimNetwork

from fieldbox.language import parse

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
    from roles.cores.core import Stream

    net, field = sim_field(roles=("fms",))
    field.fms.match_log = Stream(3)  # the FMS keeps 10 000; three here
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
    for i in range(ds.tcp.console.capacity + 100):
        ds.add_console_line(net.now, "stdout", f"line {i}")
    assert log.poll() == ds.tcp.console.capacity
    assert log.missed == 100
    lines = read(log, "ds-254-console.log")
    assert "100 console line(s) not logged" in lines[0] and lines[-1].endswith(f"line {ds.tcp.console.capacity + 99}")
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
    assert field.stations[0].ds.link.robot_comms
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
    proc = subprocess.Popen([sys.executable, "-m", "fieldbox", "--headless", "--net", "ephemeral", "--team", "254", "--roles", "ds,rio,fms",
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


# -- a folder deleted, a disk full: said, and the logs go on --------------------------------------
class Full:
    """A file on a full disk: ``write`` puts ``keep`` bytes of the text where it should go (a
    write cut off mid-line), then fails as the OS does."""

    def __init__(self, real=None, keep: int = 0) -> None:
        self.real, self.keep = real, keep

    def write(self, text):
        if self.real is not None and self.keep:
            self.real.write(text[:self.keep])
            self.real.flush()
            self.keep = 0
        raise OSError(errno.ENOSPC, "No space left on device")

    def flush(self):
        raise OSError(errno.ENOSPC, "No space left on device")

    def close(self):
        if self.real is not None:
            self.real.close()


def hms(wall: float) -> str:
    return datetime.datetime.fromtimestamp(wall).strftime("%H:%M:%S")


def test_a_deleted_log_folder_is_said_and_the_run_writes_on_in_a_new_one(tmp_path):
    """``rm -r`` of the run's folder mid-run: the next check (within a second) notices, says so,
    and every file goes on in a new folder beside it, the DS's NI log with a new pair (its
    header first); nothing more goes into the deleted files."""
    net, field = sim_field()
    ds = field.stations[0].ds
    log = FieldLog(field, tmp_path).attach()
    for _ in range(10):
        net.run_for(POLL_PERIOD)
        log.poll()
    first = log.folder
    assert (first / "ds-254-dslog").is_dir() and log.ni_logs[254].open
    shutil.rmtree(first)
    deadline = time.monotonic() + 10  # a hang guard: the check runs every CHECK_EVERY (1 s)
    while log.folder == first and time.monotonic() < deadline:
        net.run_for(POLL_PERIOD)
        log.poll()
        time.sleep(0.02)
    new = log.folder
    assert new != first and new.parent == tmp_path and new.name.startswith(first.name[:9])
    assert re.fullmatch(r"\d{8}-\d{6}-\d+-2", new.name) and not first.exists()
    problem = log.take_problem()
    assert problem is not None and f"{first}" in problem and "deleted" in problem and f"{new}" in problem
    ds.add_console_line(net.now, "stdout", "after the move")
    net.command(field.fms_name, lambda: field.execute(parse("match start"), net.now))
    for _ in range(10):
        net.run_for(POLL_PERIOD)
        log.poll()
    console = read(log, "ds-254-console.log")
    assert "deleted" in console[0] and f"the logs go on in {new}" in console[0]
    assert any(line.endswith("stdout after the move") for line in console)
    assert "deleted" in read(log, "ds-254-events.log")[0] and "deleted" in read(log, "rio-254-events.log")[0]
    assert read(log, "fms-match.log")[-1].endswith("auto started")
    (dslog,) = (new / "ds-254-dslog").glob("*.dslog")
    data = dslog.read_bytes()
    version, secs, _ = struct.unpack_from(">iqQ", data)
    assert version == 4 and abs(secs - 2_082_844_800 - time.time()) < 3600
    assert len(data) > 20 and (len(data) - 20) % 39 == 0  # whole records after the header
    events = dslog.with_suffix(".dsevents").read_bytes()
    assert struct.unpack_from(">i", events)[0] == 4 and b"Info fieldbox: the log folder" in events
    assert log.errors == 0
    log.close()


def test_lines_lost_to_a_full_disk_are_said_once_it_has_room(tmp_path, monkeypatch):
    """A full disk: the console file's writes fail (one cut off mid-line), it is tried again
    each second; once the disk has room, the file's next line says how many were lost and
    from when to when, on a line of its own."""
    import roles.runtime.logfiles as logfiles

    net, field = sim_field(roles=("ds",))
    ds = field.stations[0].ds
    start = net.now
    wall0 = 1_700_000_000.0
    log = FieldLog(field, tmp_path, wall_clock=lambda: wall0 + (net.now - start)).attach()
    name = "ds-254-console.log"
    ds.add_console_line(net.now, "stdout", "before")
    log.poll()
    log._files[name] = Full(log._files[name], keep=20)  # the disk fills up
    net.run_for(1.0)
    full_at = wall0 + (net.now - start)
    for i in range(3):
        ds.add_console_line(net.now, "stdout", f"lost {i}")
    log.poll()
    assert log.errors == 1 and "No space left" in log.last_error
    assert "No space left" in log.take_problem()

    def still_full(path, mode="r", *args, **kwargs):
        return Full() if "a" in mode else open(path, mode, *args, **kwargs)
    monkeypatch.setattr(logfiles, "open", still_full, raising=False)
    net.run_for(1.0)
    log.check()  # still full: tried, failed, counted
    ds.add_console_line(net.now, "stdout", "lost 3")
    ds.add_console_line(net.now, "stdout", "lost 4")
    log.poll()
    assert log.errors == 2
    monkeypatch.undo()  # room again
    net.run_for(1.0)
    back_at = wall0 + (net.now - start)
    log.check()
    ds.add_console_line(net.now, "stdout", "after")
    log.poll()
    lines = read(log, name)
    assert lines[0].endswith("stdout before") and "lost" not in lines[0]
    assert len(lines[1]) == 20 and " stdout lost 0" not in lines[1]  # the torn line, ended
    assert re.fullmatch(STAMP + f" fieldbox 5 lines lost from {hms(full_at)} to {hms(back_at)}: disk full",
                        lines[2]), lines
    assert lines[3].endswith("stdout after") and len(lines) == 4
    assert any("5 lines lost" in (log.take_problem() or "") for _ in range(3))
    log.close()


def test_ni_log_records_lost_to_a_full_disk_are_said_in_the_next_pair_and_the_console(tmp_path):
    """The .dslog's write fails: its pair ends; the next (5 s on) starts with a valid header, and
    its first event and the DS's console log say how many records and events were lost."""
    from roles.runtime.dslog import RETRY_AFTER

    net, field = sim_field(roles=("ds", "rio"))
    start = net.now
    wall0 = 1_700_000_000.0
    log = FieldLog(field, tmp_path, wall_clock=lambda: wall0 + (net.now - start)).attach()
    for _ in range(10):
        net.run_for(POLL_PERIOD)
        log.poll()
    ni = log.ni_logs[254]
    first_pair = ni._log
    ni._log = Full()
    first_pair.close()
    net.run_for(POLL_PERIOD)
    log.poll()  # this poll's records fail: the pair ends
    assert not ni.open and log.errors >= 1
    failed_at = net.now
    while net.now - failed_at < RETRY_AFTER + 1.0:
        net.run_for(POLL_PERIOD)
        log.poll()
    assert ni.open
    logs = sorted(p for p in ni.paths if p.suffix == ".dslog")
    assert len(logs) == 2
    second = logs[-1].with_suffix(".dsevents").read_bytes()
    assert struct.unpack_from(">i", logs[-1].read_bytes())[0] == 4 and (logs[-1].stat().st_size - 20) % 39 == 0
    m = re.search(rb"Info fieldbox: (\d+) records and (\d+) events? of the NI log lost from [\d:]{8} to [\d:]{8}: "
                  rb"disk full", second)
    assert m is not None, second
    # the poll that failed and the 5 s before the retry, at one record per 20 ms
    assert (RETRY_AFTER) / 0.02 <= int(m.group(1)) <= (RETRY_AFTER + 0.3) / 0.02
    console = read(log, "ds-254-console.log")
    assert any(re.search(r" fieldbox \d+ records and \d+ events? of the NI log lost from .*: disk full$", line)
               for line in console), console
    log.close()


def test_headless_says_a_deleted_log_folder_and_writes_on(tmp_path):
    """``fieldbox --headless``: the run's folder deleted under it; stderr says so and names the
    new folder, where the console, the match log and the NI log go on."""
    import threading

    err_path = tmp_path / "stderr.txt"
    with open(err_path, "w") as err:
        proc = subprocess.Popen([sys.executable, "-m", "fieldbox", "--headless", "--net", "ephemeral", "--roles", "ds,rio,fms", "--team",
                                 "254", "--log-dir", str(tmp_path / "logs")], cwd=ROOT, stdin=subprocess.PIPE,
                                stdout=subprocess.PIPE, stderr=err, text=True, bufsize=1)
    lines: list[str] = []
    threading.Thread(target=lambda: lines.extend(iter(proc.stdout.readline, "")), daemon=True).start()

    def wait_for(check) -> bool:
        deadline = time.monotonic() + 20  # a hang guard
        while time.monotonic() < deadline and proc.poll() is None:
            if check():
                return True
            time.sleep(0.05)
        return False
    try:
        assert wait_for(lambda: any(line.startswith("fms:") and "R1:254+" in line for line in list(lines)))
        (folder,) = [Path(line[5:].strip()) for line in list(lines) if line.startswith("logs ")]
        assert (folder / "ds-254-console.log").exists()
        shutil.rmtree(folder)
        assert wait_for(lambda: "deleted" in err_path.read_text()), err_path.read_text()
        new = [p for p in (tmp_path / "logs").iterdir() if p.is_dir()]
        assert len(new) == 1 and new[0] != folder
        proc.stdin.write("match start\n")
        proc.stdin.flush()
        console = new[0] / "ds-254-console.log"
        assert wait_for(lambda: "Robot enabled in auto" in console.read_text())
        proc.stdin.write("quit\n")
        proc.stdin.flush()
        proc.wait(20)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait(10)
    err = err_path.read_text()
    assert re.search(rf"fieldbox: log files: the log folder {re.escape(str(folder))} .*deleted.* the logs go on in "
                     rf"{re.escape(str(new[0]))}", err), err
    assert "auto started" in (new[0] / "fms-match.log").read_text()
    assert list((new[0] / "ds-254-dslog").glob("*.dslog")) and not folder.exists()
    assert proc.returncode == 0
