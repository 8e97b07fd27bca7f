"""``fieldbox run SCRIPT``: the headless language as a test harness (issue 22, part 2). A script
plays against a real field on loopback; each step's result comes out as TAP, JSON or JUnit;
the first failed step ends the run with exit code 1."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import xml.etree.ElementTree as ET

import pytest

from roles.cores.commands import (CommandSyntaxError, ExpectBattery, ExpectConsole, ExpectRobotMode, Sleep, Wait,
                                  parse)

from fieldbox.script import Console, ScriptError, load_script

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
    console = Console()
    for line in ("Robot disabled", "Robot enabled in auto", "Robot disabled"):
        console.add(line)
    import re

    assert console.match(re.compile("enabled")) == "Robot enabled in auto"
    assert console.match(re.compile("disabled")) == "Robot disabled"  # the one after, not the first
    assert console.match(re.compile("disabled")) is None


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
