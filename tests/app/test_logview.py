"""The log viewer (``fieldbox logs``) as a person sees it, at 80x24 (an SSH window) and 160x50,
on a match built byte by byte (so every figure is the same each run): disabled, 15 s of auto,
teleop with a battery sag and a brownout, an e-stop, then the robot gone.

Update the pictures with ``pytest tests/app/test_logview.py --snapshot-update`` and look at the
SVGs under tests/app/__snapshots__/test_logview/ first. Each test also reads the screen's text:
a battery figure, a mode label, an event line, the state at the cursor."""

from __future__ import annotations

import re

import struct
import subprocess
import sys
from pathlib import Path

import pytest

from fieldbox.dslog_read import (BROWNOUT, DS_AUTO, DS_DISABLED, DS_TELEOP, ROBOT_AUTO, ROBOT_DISABLED,
                                 ROBOT_TELEOP)
from fieldbox.logview import LogViewerApp, RunsScreen
from fieldbox.logview_runs import find_runs, load, run_for
from roles.runtime.dslog import LV_EPOCH_OFFSET

pytestmark = pytest.mark.usefixtures("no_real_joysticks", "utc")  # no user theme; dates in UTC

START = 1_795_000_000.0  # 2026-11-18 11:06:40 UTC
SIZES = {"80x24": (80, 24), "160x50": (160, 50)}
ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture
def utc(monkeypatch):
    import time

    monkeypatch.setenv("TZ", "UTC")
    time.tzset()
    yield
    monkeypatch.undo()
    time.tzset()


def lv(unix: float) -> bytes:
    whole = int(unix // 1)
    return struct.pack(">qQ", whole + LV_EPOCH_OFFSET, int((unix - whole) * 2**64))


def state_at(t: float) -> tuple[int, float, float, int, int]:
    """(flags, battery, trip ms, lost %, CPU %) of the made-up match at ``t`` seconds."""
    battery, trip, lost, cpu = 12.5 - t * 0.01, 3.0 + (t % 7) * 0.5, 0, 30 + int(t) % 20
    if t < 5:
        flags = DS_DISABLED | ROBOT_DISABLED
    elif t < 20:
        flags = DS_AUTO | ROBOT_AUTO
    elif t < 23:
        flags = DS_DISABLED | ROBOT_DISABLED
    elif t < 45:
        flags = DS_TELEOP | ROBOT_TELEOP
        if 30 <= t < 32:  # the sag: a brownout
            battery, flags = 6.75, flags | BROWNOUT
        if 38 <= t < 40:
            lost, trip = 48, 40.0
    elif t < 55:
        flags = DS_DISABLED | ROBOT_DISABLED  # e-stopped
    else:
        flags, battery, trip, cpu = DS_DISABLED, 0.0, 0.0, 0  # no robot comms
    return flags, battery, trip, lost, cpu


def write_match(folder: Path, version: int = 4) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    stem = folder / "2026_11_18 11_06_40 Wed"
    records = []
    for k in range(3000):  # 60 s
        flags, battery, trip, lost, cpu = state_at(k * 0.02)
        head = struct.pack(">BbHBBBBH", round(trip * 2), lost // 4, round(battery * 256), cpu * 2, ~flags & 0xFF,
                           10, 0, 0)
        records.append(head + (b"" if version == 3 else b"\0\0\0\x19") + bytes(25))
    Path(f"{stem}.dslog").write_bytes(struct.pack(">i", version) + lv(START) + b"".join(records))
    events = [(0.0, "Info robot comms established"),
              (0.5, "FMS Connected:   Qualification - 12:1, Field Time: 26/11/18 11:6:40\n -- FRC Driver Station"),
              (5.0, "Info robot enabled (auto)"),
              (6.5, "<TagVersion>1 <time> 06.500 <message> shooter at speed "),
              (20.0, "Info robot disabled"),
              (23.0, "Info robot enabled (teleop)"),
              (30.0, "Info robot brownout (6.75 V)"),
              (33.0, "<TagVersion>1 <time> 33.000 <count> 1 <flags> 1 <Code> 44004 <details> The robot is out "
                     "of memory <location> robot.py:3 <stack> "),
              (45.0, "Info E-STOP (operator): latched"),
              (55.0, "Info robot comms lost")]
    data = b"".join(lv(START + t) + struct.pack(">i", len(text.encode())) + text.encode() for t, text in events)
    Path(f"{stem}.dsevents").write_bytes(struct.pack(">i", version) + lv(START) + data)
    return stem


def screen_text(app) -> str:
    return "\n".join(strip.text for strip in app.screen._compositor.render_strips())


def viewer(tmp_path: Path) -> LogViewerApp:
    stem = write_match(tmp_path / "ds-254-dslog")
    return LogViewerApp(loaded=load(run_for(stem)))


@pytest.mark.parametrize("size", list(SIZES))
def test_a_match_at_two_sizes(snap_compare, tmp_path, size):
    app = viewer(tmp_path)
    seen: dict[str, str] = {}

    async def run_before(pilot) -> None:
        await pilot.pause()
        seen["start"] = screen_text(pilot.app)
        await pilot.press("tab", *["down"] * 8)  # the event list: down to the e-stop
        await pilot.pause()
        seen["estop"] = screen_text(pilot.app)

    assert snap_compare(app, terminal_size=SIZES[size], run_before=run_before)
    start, estop = seen["start"], seen["estop"]
    # the run's title, a battery figure at the cursor, the modes, an event line
    assert "2026-11-18 11:06:40 · 1:00 · team 254 · Qualification 12 · v4" in start
    assert "Battery  12.50 V" in start and "low 6.75 V" in start
    # the window's "high" is its highest sample: never below a value the cursor shows
    high = float(re.search(r"Battery .*high ([\d.]+) V", start).group(1))
    assert high >= 12.50, start
    assert "Trip time" in start and "Lost packets" in start and "roboRIO CPU" in start
    ds_row = next(line for line in start.splitlines() if line.startswith("DS "))
    assert "auto" in ds_row and "teleop" in ds_row and "disabled" in ds_row
    alert_row = next(line for line in start.splitlines() if line.startswith("Alert"))
    assert "e-stop" in alert_row
    robot_row = next(line for line in start.splitlines() if line.startswith("Robot"))
    assert "no com" in robot_row  # the last 5 s: "no comms", or "no com" where it does not fit
    assert "0:00.00  robot comms established" in start
    assert "▸ 0:00.00  DS disabled · robot disabled" in start
    # picking the e-stop in the list moves the cursor to it: the charts and the state say 0:45
    assert "▸ 0:45.00  DS disabled · robot disabled · E-STOPPED" in estop
    assert "Battery  12.05 V" in estop


async def test_the_cursor_keys_and_the_next_event(tmp_path):
    app = viewer(tmp_path)
    async with app.run_test(size=(80, 24)) as pilot:
        await pilot.pause()
        await pilot.press("n", "n", "n", "n", "n", "n")  # 0:00.5, 0:05, 0:06.5, 0:20, 0:23, the brownout at 0:30
        await pilot.pause()
        text = screen_text(app)
        assert "▸ 0:30.00  DS teleop enabled · robot teleop · BROWNOUT" in text
        assert "Battery  6.75 V" in text
        await pilot.press("n", "n", "n", "n")  # past the e-stop to the comms lost
        await pilot.press("right")
        await pilot.pause()
        text = screen_text(app)
        assert "no robot comms · E-STOPPED" in text
        assert "0:55." in text.split("▸")[1].split("\n")[0]
        await pilot.press("plus", "plus")  # zoomed around the cursor: a window of 15 s
        await pilot.pause()
        assert "0:45–1:00" in screen_text(app)  # the window: 15 s, the end of the run


async def test_the_list_of_runs_newest_first_opens_one(tmp_path):
    write_match(tmp_path / "20261118-110640-1" / "ds-254-dslog")
    older = write_match(tmp_path / "old" / "Log Files", version=3)  # an NI DS's: no team
    data = bytearray(Path(f"{older}.dslog").read_bytes())
    data[4:12] = struct.pack(">q", struct.unpack(">q", bytes(data[4:12]))[0] - 86_400)  # a day earlier
    Path(f"{older}.dslog").write_bytes(bytes(data))
    (tmp_path / "junk.dslog").write_bytes(b"junk")  # no date of its own: listed by its file's time, now
    runs = find_runs(tmp_path)
    assert [r.team for r in runs] == [None, 254, None]
    app = LogViewerApp(folder=tmp_path, runs=runs)
    async with app.run_test(size=(120, 24)) as pilot:
        await pilot.pause()
        text = screen_text(app)
        assert "junk  ⚠ not a .dslog file: 4 bytes, shorter than the 20" in text
        lines = [line for line in text.splitlines() if "Qualification 12" in line]
        assert lines[0].split()[:4] == ["2026-11-18", "11:06:40", "1:00", "254"]
        assert lines[1].split()[:4] == ["2026-11-17", "11:06:40", "1:00", "—"]
        await pilot.press("enter")  # the junk: it stays in the list, and a toast says why
        await pilot.pause()
        assert isinstance(app.screen, RunsScreen)
        assert any("shorter than the 20-byte header" in n.message for n in app._notifications)
        await pilot.press("down", "down", "enter")  # the older one, version 3
        await pilot.pause()
        text = screen_text(app)
        assert "2026-11-17 11:06:40 · 1:00 · Qualification 12 · v3" in text
        await pilot.press("escape")
        await pilot.pause()
        assert "3 runs in" in screen_text(app)


# -- the command line ---------------------------------------------------------------------------
def fieldbox(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "fieldbox", "logs", *args], capture_output=True, text=True,
                          cwd=ROOT, timeout=60)


def test_the_command_line_prints_a_run_and_refuses_a_bad_file(tmp_path):
    stem = write_match(tmp_path / "ds-254-dslog")
    out = fieldbox(f"{stem}.dslog", "--print")
    assert out.returncode == 0 and out.stderr == ""
    assert "version 4, 3000 records (60.0 s), battery 0.00-12.50 V" not in out.stdout  # no comms is no battery
    assert "battery 6.75-12.50 V" in out.stdout and "brownout 2.0 s" in out.stdout
    assert "\n  0:45.00  E-STOP (operator): latched\n" in out.stdout
    listed = fieldbox(str(tmp_path), "--print")
    assert listed.returncode == 0 and "team 254  Qualification 12" in listed.stdout

    (tmp_path / "notes.dslog").write_text("my notes, not a log\n")
    bad = fieldbox(str(tmp_path / "notes.dslog"))
    assert bad.returncode == 1 and bad.stdout == ""
    assert bad.stderr.strip().splitlines() == [
        "fieldbox logs: notes.dslog: not a .dslog file: it does not begin with a version number (3 or 4)"]
    missing = fieldbox(str(tmp_path / "nothing.dslog"))
    assert missing.returncode == 1 and missing.stderr.startswith("fieldbox logs: no such file or folder:")
    assert "Traceback" not in bad.stderr + missing.stderr

    # a torn last record: the rest opens, and the problem is said once, on stderr
    data = Path(f"{stem}.dslog").read_bytes()
    Path(f"{stem}.dslog").write_bytes(data[:-20])
    torn = fieldbox(f"{stem}.dslog", "--print")
    assert torn.returncode == 0 and "2999 records" in torn.stdout
    assert "the last record is cut short (19 of its 39 bytes)" in torn.stderr

    empty = tmp_path / "empty"
    empty.mkdir()
    none = fieldbox(str(empty))
    assert none.returncode == 1 and "no .dslog or .dsevents files in" in none.stderr


# -- from the app -------------------------------------------------------------------------------
async def test_the_apps_palette_opens_the_viewer_and_space_still_estops(tmp_path, monkeypatch):
    """The command palette's "Logs: the NI log viewer" lists the runs of the log folder over the
    app; o opens one (Enter stays the robot's Disable); Space e-stops the robot from the viewer
    too; q closes the viewer, back to the app's tab."""
    from textual.command import CommandPalette

    from fieldbox.logview import LogScreen

    from .helpers import SIZE, Harness, one_team

    write_match(tmp_path / "20261118-110640-1" / "ds-254-dslog")
    h = Harness(one_team())
    async with h.app.run_test(size=SIZE) as pilot:
        h.run(1.0)
        # this run's folder, beside the older run's: the viewer lists the log folder they are in
        monkeypatch.setattr(h.engine, "log_folder", str(tmp_path / "20261118-120000-2"), raising=False)
        ds = h.engine.field.stations[0].ds
        await pilot.press("e", "e")
        h.run(0.5)
        assert ds.enabled
        main = h.app.screen
        await pilot.press("ctrl+p", *"logviewer")  # a search needs no spaces (Space e-stops)
        await pilot.pause(0.3)
        assert isinstance(h.app.screen, CommandPalette) and ds.enabled
        await pilot.press("ctrl+s", "ctrl+s")  # the palette's Run (Enter is Disable): highlight, run
        await pilot.pause()
        assert isinstance(h.app.screen, RunsScreen) and ds.enabled
        assert "1 run in" in screen_text(h.app) and "o opens one" in screen_text(h.app)
        await pilot.press("o")
        await pilot.pause()
        assert isinstance(h.app.screen, LogScreen) and "Battery  12.50 V" in screen_text(h.app)
        await pilot.press("space")
        h.run(0.2)
        assert ds.arbiter.estopped
        await pilot.press("q")
        await pilot.pause()
        assert h.app.screen is main


def test_an_event_hours_off_does_not_squash_the_charts(tmp_path):
    """A DS whose clock jumped writes an event hours after its records: it is listed, but the
    time axis stays on the records (a minute past them at most)."""
    from fieldbox.logview import Timeline

    stem = write_match(tmp_path)
    with open(f"{stem}.dsevents", "ab") as f:
        text = b"Info robot comms lost"
        f.write(lv(START + 5 * 3600) + struct.pack(">i", len(text)) + text)
    timeline = Timeline(load(run_for(stem)))
    assert timeline.event_times[-1] == pytest.approx(5 * 3600)
    assert timeline.begin == 0.0 and timeline.end == pytest.approx(120.0)
