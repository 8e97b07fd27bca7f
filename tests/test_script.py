"""``fieldbox run SCRIPT``: the headless language as a test harness (issue 22, part 2). A script
plays against a real field on loopback; each step's result comes out as TAP, JSON or JUnit;
the first failed step ends the run with exit code 1."""

from __future__ import annotations

import asyncio
import json
import os
import signal
import subprocess
import sys
import threading
import time
import xml.etree.ElementTree as ET

import pytest

from fieldbox.language import (CommandSyntaxError, ExpectBattery, ExpectConsole, ExpectRobotMode, Sleep, Wait,
                               parse)
from fieldbox.script import MAX_SCRIPT_BYTES, Console, ConsoleMatcher, ScriptError, load_script

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def run(*args: str, timeout: float = 120) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "fieldbox", "run", *args], cwd=ROOT, capture_output=True,
                          text=True, timeout=timeout)


def test_the_test_steps_parse_and_refuse_what_is_not_one():
    assert parse("expect console Auto (started|begun) within 5") == ExpectConsole("Auto (started|begun)", 5.0)
    assert parse("@254 expect robot mode auto within 3") == ExpectRobotMode("auto", 3.0, team=254)
    assert parse("expect battery >= 11.5") == ExpectBattery(">=", 11.5, 0.0)
    assert parse("wait comms") == Wait("comms", 10.0) and parse("wait enabled 3") == Wait("enabled", 3.0)
    assert parse("sleep 1.5") == Sleep(1.5)
    for bad, words in [("expect console ( within 2", "not a regular expression"), ("wait foo", "usage: wait"),
                       ("expect robot mode fly within 1", "usage: expect robot mode"),
                       ("sleep -1", "0..3600"), ("expect battery ~ 3", "usage: expect battery"),
                       ("expect nothing", "cannot expect")]:
        with pytest.raises(CommandSyntaxError, match=words):
            parse(bad)


def test_a_script_that_cannot_be_played_names_its_line(tmp_path):
    path = tmp_path / "bad.fbx"
    path.write_text("# a comment\nenable\nwait forever\n")
    with pytest.raises(ScriptError, match=r"bad.fbx, line 3: usage: wait"):
        load_script(str(path))
    path.write_text("quit\n")
    with pytest.raises(ScriptError, match="line 1: quit has no place"):
        load_script(str(path))
    assert run(str(tmp_path / "nope.fbx"), "--net", "ephemeral").returncode == 2


def test_console_expectations_move_on_past_each_match():
    async def looks() -> list:
        console = Console()
        for line in ("Robot disabled", "Robot enabled in auto", "Robot disabled"):
            console.add(line)
        seen = []
        for pattern in ("enabled", "disabled", "disabled"):
            matcher = ConsoleMatcher(pattern)
            try:
                seen.append((await console.match(matcher))[0])
            finally:
                await matcher.close()
        return seen

    # the one after the last match, not the first; then none
    assert asyncio.run(looks()) == ["Robot enabled in auto", "Robot disabled", None]


SCRIPT = """\
# our own fake roboRIO and its built-in program
wait code 30
mode auto
enable
expect robot mode auto within 5
expect console Robot enabled in auto within 5
expect battery > 11 within 2
disable
expect console Robot disabled within 5
"""


def test_a_script_passes_against_our_fake_roborio_with_tap_and_junit(tmp_path):
    path = tmp_path / "auto.fbx"
    path.write_text(SCRIPT)
    report = tmp_path / "auto.xml"
    done = run(str(path), "--roles", "ds,rio", "--net", "ephemeral", "--no-log-files", "--junit", str(report))
    assert done.returncode == 0, done.stdout + done.stderr
    lines = done.stdout.splitlines()
    assert lines[:2] == ["TAP version 13", "1..8"]
    assert [line.split(" - ")[0] for line in lines[2:]] == [f"ok {n}" for n in range(1, 9)]
    suite = ET.parse(report).getroot()
    assert suite.get("tests") == "8" and suite.get("failures") == "0"


def test_the_first_failed_step_ends_the_run_and_says_why(tmp_path):
    path = tmp_path / "fails.fbx"
    path.write_text("wait code 30\nexpect console no robot prints this within 0.5\nenable\n")
    report = tmp_path / "fails.xml"
    done = run(str(path), "--roles", "ds,rio", "--net", "ephemeral", "--no-log-files", "--json",
               "--junit", str(report))
    assert done.returncode == 1
    steps = [json.loads(line) for line in done.stdout.splitlines()]
    assert [(s["n"], s["ok"], s["skipped"]) for s in steps] == [(1, True, False), (2, False, False), (3, False, True)]
    assert steps[1]["line"] == 2 and "not within 0.5 s" in steps[1]["detail"]
    assert "Robot program started" in steps[1]["detail"]  # the last lines, to see what came instead
    case = ET.parse(report).getroot().findall("testcase")[1]
    assert case.find("failure") is not None and "not within 0.5 s" in case.find("failure").get("message")


def test_a_console_line_is_matched_once_however_often_the_steps_look(tmp_path):
    """Each look of a step reads a new view of the DS: the console lines it already took are
    not taken again, so a robot that printed a line once does not pass two expectations."""
    path = tmp_path / "twice.fbx"
    path.write_text("wait code 30\nmode auto\nenable\nexpect console Robot enabled in auto within 5\n"
                    "expect console Robot enabled in auto within 1\n")
    done = run(str(path), "--roles", "ds,rio", "--net", "ephemeral", "--no-log-files", "--json")
    steps = [json.loads(line) for line in done.stdout.splitlines()]
    assert [s["ok"] for s in steps] == [True, True, True, True, False], done.stdout + done.stderr
    assert done.returncode == 1 and "not within 1 s" in steps[4]["detail"]


def test_a_refused_command_fails_its_step(tmp_path):
    path = tmp_path / "refused.fbx"
    path.write_text("enable\n")  # no robot comms yet: the DS refuses
    done = run(str(path), "--roles", "ds", "--robot", "127.0.0.1", "--net", "ephemeral", "--no-log-files")
    assert done.returncode == 1 and "not ok 1 - enable" in done.stdout and "no robot comms" in done.stdout


def test_the_launched_programs_output_counts_as_console_lines_and_it_is_stopped(tmp_path):
    path = tmp_path / "launch.fbx"
    path.write_text("expect console hello from the robot within 20\nexpect console tick 3 within 20\n")
    pidfile = tmp_path / "pid"
    program = tmp_path / "chatty.py"
    program.write_text("import os, time\n"
                       f"open({str(pidfile)!r}, 'w').write(str(os.getpid()))\n"
                       "print('hello from the robot', flush=True)\n"
                       "for n in range(1000):\n    print('tick', n, flush=True)\n    time.sleep(0.05)\n")
    done = run(str(path), "--roles", "rio", "--net", "ephemeral", "--no-log-files",
               "--launch", f"{sys.executable} {program}")
    # a test step watches a DS: with no DS here, expect refuses (said), and the program stops
    assert done.returncode == 1 and "no Driver Station runs here" in done.stdout
    done = run(str(path), "--roles", "ds,rio", "--net", "ephemeral", "--no-log-files",
               "--launch", f"{sys.executable} {program}")
    assert done.returncode == 0, done.stdout + done.stderr
    pid = int(pidfile.read_text())
    assert not os.path.exists(f"/proc/{pid}") or open(f"/proc/{pid}/stat").read().split(")")[-1].split()[0] == "Z"


def test_headless_takes_the_test_steps_too():
    proc = subprocess.run([sys.executable, "-m", "fieldbox", "--headless", "--roles", "ds,rio", "--net", "ephemeral",
                           "--no-log-files"], cwd=ROOT, input="wait code 30\nenable\nexpect console Robot enabled "
                                                                "within 5\nexpect battery < 5\nquit\n",
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0
    assert "ok: wait code 30" in proc.stdout and "ok: expect console Robot enabled within 5" in proc.stdout
    assert "error: expect battery < 5: not within 0 s: battery" in proc.stderr


# -- bounded: a script's size and kind, a pattern's time (issue 27) -----------------------------
def test_a_script_over_its_size_is_refused_whole_never_cut(tmp_path):
    # a passing first step, then padding, then a failing last step past the first megabyte
    path = tmp_path / "big.fbx"
    path.write_text("sleep 0\n" + "# padding padding padding padding padding padding padding\n" * 20_000
                    + "expect battery < 0\n")
    assert path.stat().st_size > MAX_SCRIPT_BYTES
    with pytest.raises(ScriptError, match=f"big.fbx: {path.stat().st_size} bytes, more than a script's "
                                          f"{MAX_SCRIPT_BYTES} at most"):
        load_script(str(path))
    done = run(str(path), "--roles", "ds", "--net", "ephemeral", "--no-log-files")
    assert done.returncode == 2 and "more than a script's" in done.stderr and "ok 1" not in done.stdout
    # a script of the most bytes allowed is read to its last line
    padding = "# padding\n" * ((MAX_SCRIPT_BYTES - 30) // 10)
    path.write_text("sleep 0\n" + padding + "expect battery < 0".ljust(MAX_SCRIPT_BYTES - 8 - len(padding) - 1) + "\n")
    assert path.stat().st_size == MAX_SCRIPT_BYTES
    assert load_script(str(path))[-1].text == "expect battery < 0"


def test_a_fifo_or_a_folder_is_refused_at_once(tmp_path):
    fifo = tmp_path / "script.fifo"
    os.mkfifo(fifo)
    # no writer ever comes: without a look at what the file is, open() would wait for ever
    done = run(str(fifo), "--roles", "ds", "--net", "ephemeral", "--no-log-files", timeout=60)
    assert done.returncode == 2 and f"{fifo}: not a regular file" in done.stderr
    done = run(str(tmp_path), "--roles", "ds", "--net", "ephemeral", "--no-log-files", timeout=60)
    assert done.returncode == 2 and "not a regular file" in done.stderr


#: A robot program that prints, every 20 ms, a line on which ``(a+)+$`` backtracks for days.
CATASTROPHIC_LINE = "def robot_periodic(state, robot):\n    print('a' * 40 + '!')\n"
CATASTROPHIC = "expect console (a+)+$ within 2"
#: How long fieldbox may take to fail that step or end (the promise: some 2 s).
HANG_GUARD = 10.0


def test_a_pattern_that_backtracks_fails_its_step_in_a_script(tmp_path):
    program = tmp_path / "aaa.py"
    program.write_text(CATASTROPHIC_LINE)
    path = tmp_path / "slow.fbx"
    path.write_text(f"wait code 30\nexpect console a!$ within 10\n{CATASTROPHIC}\nenable\n")
    done = run(str(path), "--roles", "ds,rio", "--net", "ephemeral", "--no-log-files", "--json",
               "--robot-program", str(program), timeout=60)
    assert done.returncode == 1, done.stdout + done.stderr
    steps = [json.loads(line) for line in done.stdout.splitlines()]
    assert [(s["n"], s["ok"], s["skipped"]) for s in steps] == [(1, True, False), (2, True, False), (3, False, False),
                                                                 (4, False, True)]
    assert steps[2]["detail"].startswith("the pattern took longer than 2 s to match ")
    assert "console line" in steps[2]["detail"] and "it may backtrack catastrophically" in steps[2]["detail"]


def _matchers(pid: int) -> list[int]:
    """The console matcher children of process ``pid`` (python -I -S -c ...)."""
    found = []
    for task in os.listdir(f"/proc/{pid}/task"):
        try:
            children = open(f"/proc/{pid}/task/{task}/children").read().split()
        except OSError:
            continue
        for child in children:
            try:
                if b"\0-I\0-S\0-c\0" in open(f"/proc/{child}/cmdline", "rb").read():
                    found.append(int(child))
            except OSError:
                continue
    return found


def _running(pid: int) -> bool:
    try:
        return open(f"/proc/{pid}/stat").read().rsplit(")", 1)[-1].split()[0] != "Z"
    except OSError:
        return False


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="/proc and signals of Linux")
def test_a_pattern_that_backtracks_fails_its_step_while_the_ds_keeps_its_robot_and_sigterm_ends_it(tmp_path):
    program = tmp_path / "aaa.py"
    program.write_text(CATASTROPHIC_LINE)
    proc = subprocess.Popen([sys.executable, "-m", "fieldbox", "--headless", "--json", "--roles", "ds,rio", "--net",
                             "ephemeral", "--no-log-files", "--robot-program", str(program)], cwd=ROOT,
                            stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            bufsize=1)
    lines: list[dict] = []
    threading.Thread(target=lambda: lines.extend(json.loads(line) for line in proc.stdout), daemon=True).start()

    def send(text: str) -> None:
        proc.stdin.write(text + "\n")
        proc.stdin.flush()

    def seen(predicate, start: int = 0, within: float = 60.0) -> dict:
        end = time.monotonic() + within
        while time.monotonic() < end:
            for obj in lines[start:]:
                if predicate(obj):
                    return obj
            time.sleep(0.01)
        raise AssertionError(f"not seen within {within:g} s; last lines {lines[-3:]}")

    def ds_status(start: int) -> dict:
        send("status")
        return seen(lambda o: o.get("type") == "status" and o.get("role") == "ds", start)

    try:
        seen(lambda o: o.get("role") == "ds" and o.get("robot_code"))
        send("enable")
        seen(lambda o: o.get("type") == "status" and o.get("role") == "rio" and o.get("enabled"))
        send("expect console a!$ within 10")  # the robot's lines come (a pattern that does not backtrack)
        assert seen(lambda o: o.get("type") == "step")["ok"]
        mark = len(lines)
        before = ds_status(mark)
        assert before["enabled"] and before["robot_comms"]
        mark = len(lines)
        send(CATASTROPHIC)
        step = seen(lambda o: o.get("type") == "step", mark, within=HANG_GUARD)
        assert not step["ok"] and step["detail"].startswith("the pattern took longer than 2 s to match ")
        assert "it may backtrack catastrophically" in step["detail"]
        after = ds_status(len(lines))
        # the DS kept sending all along (some 50 packets a second), its robot never lost it nor
        # disabled on its watchdog (a DS that loses comms disables)
        assert after["sent_packets"] - before["sent_packets"] >= 25 * step["seconds"], (before, after)
        assert after["enabled"] and after["robot_comms"]
        assert not any(o.get("type") == "status" and (o.get("enabled") is False or o.get("robot_comms") is False)
                       for o in lines[mark:])
        # SIGTERM while a pattern is being matched: fieldbox ends at once, and so does its matcher
        send("expect console (a+)+$ within 60")
        end = time.monotonic() + HANG_GUARD
        while time.monotonic() < end and not _matchers(proc.pid):
            time.sleep(0.01)
        matchers = _matchers(proc.pid)
        assert matchers
        time.sleep(0.3)
        proc.send_signal(signal.SIGTERM)
        assert proc.wait(HANG_GUARD) == 0
        end = time.monotonic() + HANG_GUARD
        while time.monotonic() < end and any(_running(pid) for pid in matchers):
            time.sleep(0.05)
        assert not any(_running(pid) for pid in matchers)
        assert "Traceback" not in proc.stderr.read()
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()

def test_a_run_whose_reader_went_away_plays_on_and_says_so_once(tmp_path):
    path = tmp_path / "headless.fbx"
    path.write_text("wait code 30\nenable\nwait enabled 10\nestop\nwait disabled 10\n")
    report = tmp_path / "run.xml"
    r, w = os.pipe()
    os.close(r)  # `fieldbox run ... | head -0`
    try:
        done = subprocess.run([sys.executable, "-m", "fieldbox", "run", str(path), "--roles", "ds,rio", "--net",
                               "ephemeral", "--no-log-files", "--junit", str(report)], cwd=ROOT, stdout=w,
                              stderr=subprocess.PIPE, text=True, timeout=120)
    finally:
        os.close(w)
    assert done.returncode == 0, done.stderr
    suite = ET.parse(report).getroot()
    assert suite.get("tests") == "5" and suite.get("failures") == "0"  # every step played and passed
    assert done.stderr.count("fieldbox: stdout is closed (its reader went away)") == 1, done.stderr
    assert "Traceback" not in done.stderr


def test_a_launched_command_names_this_install_without_an_activated_venv(tmp_path):
    """README's ``--launch "python -m ..."`` and ``--launch "fieldbox ..."`` name this install's
    interpreter and commands when fieldbox runs as .venv/bin/fieldbox, nothing activated."""
    path = tmp_path / "which.fbx"
    path.write_text("expect console launched-by-this-python within 20\n")
    program = tmp_path / "which.py"
    program.write_text("import sys\n"  # this install's interpreter: the same environment (sys.prefix)
                       f"print('launched-by-this-python' if sys.prefix == {sys.prefix!r} else sys.prefix, flush=True)\n")
    bare = dict(os.environ, PATH=os.pathsep.join(p for p in ("/usr/bin", "/bin") if os.path.isdir(p)))
    done = subprocess.run([sys.executable, "-m", "fieldbox", "run", str(path), "--roles", "ds,rio", "--net",
                           "ephemeral", "--no-log-files", "--launch", f"python {program}"],
                          cwd=ROOT, capture_output=True, text=True, timeout=120, env=bare)
    assert done.returncode == 0, done.stdout + done.stderr
    assert "ok 1 - expect console" in done.stdout


def test_a_script_with_the_default_roles_enables(tmp_path):
    """``fieldbox run SCRIPT`` with no --roles: one team's DS and robot, which the script
    enables (an FMS by default decided enable, and the enable step failed: issue 31)."""
    path = tmp_path / "auto.fbx"
    path.write_text(SCRIPT)
    done = run(str(path), "--net", "ephemeral", "--no-log-files")
    assert done.returncode == 0, done.stdout + done.stderr
    assert "not ok" not in done.stdout and "ok 3 - enable" in done.stdout
