"""The log viewer's reader (fieldbox/dslog_read.py): version 3 and 4, fieldbox's own files read
record for record as dslogparser reads them, files laid out as the NI DS writes them, and
hostile bytes that give one line, never a traceback."""

from __future__ import annotations

import calendar
import struct

import pytest

from fieldbox.dslog_read import (DS_AUTO, DS_DISABLED, DS_TELEOP, MAX_RECORDS, ROBOT_AUTO, ROBOT_DISABLED,
                                 ROBOT_TELEOP, LogFileError, decode_dsevents, decode_dslog, estop_at,
                                 event_text, match_name)
from fieldbox.logview_runs import find_runs, load, read_bounded
from fieldbox.language import parse
from roles.runtime.dslog import LV_EPOCH_OFFSET
from roles.runtime.field import Field, FieldConfig
from roles.runtime.logfiles import POLL_PERIOD, FieldLog
from roles.sim.simnet import SimNetwork

dslogparser = pytest.importorskip("dslogparser")

WALL0 = 1_700_000_000.0  # a whole second: dslogparser's fraction (/ 2**63 - 1) does not matter

# A header by hand: version, seconds since 1904-01-01 UTC, fraction / 2**64. The time is the
# start of DSLOG-Reader's real version-4 test file "2022_02_25 21_25_39 Fri.dslog" (its
# ReaderTests say 2022-02-26 02:25:39.855 UTC); .5 s here, exactly 0x8000...
NI_START = calendar.timegm((2022, 2, 26, 2, 25, 39)) + 0.5


def header(version: int, unix: float = NI_START) -> bytes:
    whole = int(unix // 1)
    return struct.pack(">iqQ", version, whole + LV_EPOCH_OFFSET, int((unix - whole) * 2**64))


def head(trip: int, lost: int, volts: int, cpu: int, flags: int, can: int = 0) -> bytes:
    """The 10 bytes every version starts a record with, the flags inverted as written."""
    return struct.pack(">BbHBBBBH", trip, lost, volts, cpu, ~flags & 0xFF, can, 0, 0)


CTRE = bytes(25)  # a CTRE PDP's id, 21 bytes of currents, 3 bytes: zeros here
REV = b"\x01" + bytes(32)  # a REV PDH's CAN id (1), 27 bytes of currents, 4 extra channels, 1 byte


def event(unix: float, text: str) -> bytes:
    whole = int(unix // 1)
    data = text.encode()
    return struct.pack(">qQi", whole + LV_EPOCH_OFFSET, int((unix - whole) * 2**64), len(data)) + data


# -- version 3, by hand ---------------------------------------------------------------------------
def test_a_version_3_file_by_hand():
    data = (header(3) + head(0x19, 2, 0x0C80, 0x36, DS_AUTO | ROBOT_AUTO, 0x18) + CTRE
            + head(10, 0, 0x0B66, 20, DS_DISABLED | ROBOT_DISABLED) + CTRE)
    log = decode_dslog(data)
    assert log.version == 3 and log.start == NI_START and log.problem == ""
    first, second = log.records
    assert (first.trip_ms, first.lost, first.battery, first.cpu, first.can) == (12.5, 0.08, 12.5, 27.0, 12.0)
    assert first.ds_mode == "auto" and first.robot_mode == "auto" and first.enabled and first.comms
    assert second.t == pytest.approx(0.020) and second.battery == pytest.approx(0x0B66 / 256)
    assert second.ds_mode == "disabled" and not second.enabled and second.robot_mode == "disabled"
    assert log.duration == pytest.approx(0.040)


# -- version 4, laid out as the NI DS writes it ---------------------------------------------------
def test_a_version_4_file_as_the_ni_ds_writes_it_rev_and_ctre():
    """DSLOG-Reader's real test files are version 4, one with a CTRE PDP and one with a REV PDH
    (its ReaderTests); they are binary, not to be had here, so this one is built from the layout
    both AdvantageScope and DSLOG-Reader read: the PD type in the last of 4 bytes after the 10
    (DSLOG-Reader's note: "rev code is 0, 0, 33, 1", those bytes and the PDH's CAN id after them),
    then 25 bytes for a CTRE PDP (39 a record) or 33 for a REV PDH (47 a record)."""
    rev = [head(8, 0, 0x0C40, 40, DS_TELEOP | ROBOT_TELEOP) + b"\0\0\0\x21" + REV for _ in range(3)]
    ctre = head(9, 1, 0x0C00, 41, DS_TELEOP | ROBOT_TELEOP) + b"\0\0\x00\x19" + CTRE
    log = decode_dslog(header(4) + b"".join(rev) + ctre)
    assert [r.pd_type for r in log.records] == [33, 33, 33, 25]
    assert [r.battery for r in log.records] == [12.25, 12.25, 12.25, 12.0]
    assert log.records[-1].t == pytest.approx(0.060) and log.records[-1].lost == 0.04
    assert all(r.ds_mode == "teleop" and r.robot_mode == "teleop" for r in log.records)
    # a DS enabled in neither teleop nor auto sends test; no robot bit: no comms
    test = decode_dslog(header(4) + head(0, 0, 0, 0, 0) + b"\0\0\0\x19" + CTRE).records[0]
    assert test.ds_mode == "test" and test.enabled and test.robot_mode is None and not test.comms


def test_the_ni_ds_event_lines_read_as_a_person_reads_them():
    data = header(4) + b"".join([
        # the first event of DSLOG-Reader's "2022_02_25 21_25_39 Fri.dsevents" (its ReaderTests)
        event(NI_START + 4.803, "<TagVersion>1 <time> 04.803 <message> ********** Robot program starting ********** "),
        event(NI_START + 5, "FMS Connected:   Qualification - 12:1, Field Time: 22/2/25 21:25:44\n -- FRC Driver Station"),
        event(NI_START + 6, "<TagVersion>1 <time> 06.000 <count> 1 <flags> 1 <Code> 44004 <details> The robot is "
                            "out of memory <location> robot.py:3 <stack> "),
        event(NI_START + 7, "Info E-STOP (Space): latched"),
    ])
    events = decode_dsevents(data)
    assert [e.text for e in events.events] == [
        "********** Robot program starting **********",
        "FMS Connected: Qualification - 12:1, Field Time: 22/2/25 21:25:44 -- FRC Driver Station",
        "Error 44004: The robot is out of memory (robot.py:3)",
        "E-STOP (Space): latched"]
    assert [e.kind for e in events.events] == ["print", "fms", "error", "estop"]
    assert events.events[0].t == pytest.approx(4.803, abs=1e-6)
    assert match_name(events) == "Qualification 12" and estop_at(events) == pytest.approx(7.0)
    assert event_text("Info robot comms established") == ("robot comms established", "comms")


# -- fieldbox's own files, record for record as dslogparser reads them ----------------------------
def run_match(tmp_path, version: int):
    net = SimNetwork()
    field = Field(FieldConfig(roles=frozenset({"ds", "rio", "fms"}), team=254, plan="ephemeral",
                              dslog_version=version))
    field.start_sim(net)
    start = net.now
    log = FieldLog(field, tmp_path, wall_clock=lambda: WALL0 + (net.now - start)).attach()
    for i in range(60):
        if i == 20:
            net.command(field.fms_name, lambda: field.execute(parse("match start"), net.now))
        if i == 40:
            net.command(field.stations[0].ds_name, lambda: field.execute(parse("battery 11.2"), net.now))
        net.run_for(POLL_PERIOD)
        log.poll()
    log.close()
    assert log.errors == 0, log.last_error
    paths = list(log.ni_logs[254].paths)
    return [p for p in paths if p.suffix == ".dslog"], [p for p in paths if p.suffix == ".dsevents"]


def test_fieldbox_version_3_files_read_as_dslogparser_reads_them(tmp_path):
    (dslog,), (dsevents,) = run_match(tmp_path, 3)
    ours = decode_dslog(dslog.read_bytes())
    theirs = list(dslogparser.DSLogParser(str(dslog)).read_records())
    assert ours.problem == "" and len(ours.records) == len(theirs) > 250
    assert ours.start == pytest.approx(theirs[0]["time"].timestamp(), abs=1e-3)
    for mine, their in zip(ours.records, theirs, strict=True):
        assert mine.trip_ms == their["round_trip_time"]
        assert mine.lost == pytest.approx(their["packet_loss"])
        assert mine.battery == their["voltage"]
        assert mine.cpu == pytest.approx(their["rio_cpu"] * 100)
        assert mine.can == pytest.approx(their["can_usage"] * 100)
        assert mine.wifi_db == their["wifi_db"] and mine.bandwidth == their["bandwidth"]
        assert (mine.brownout, mine.watchdog) == (their["brownout"], their["watchdog"])
        assert (mine.ds_mode == "auto", mine.ds_mode == "teleop", not mine.enabled) == \
            (their["ds_auto"], their["ds_tele"], their["ds_disabled"])
        assert (mine.robot_mode == "auto", mine.robot_mode == "teleop", mine.robot_mode == "disabled") == \
            (their["robot_auto"], their["robot_tele"], their["robot_disabled"])
    # the run as a person sees it: disabled, then auto; the battery dropped to 11.2 V
    assert ours.records[0].ds_mode == "disabled" and ours.records[-1].ds_mode == "auto"
    assert ours.records[-1].battery == pytest.approx(11.2, abs=0.05)
    events = decode_dsevents(dsevents.read_bytes())
    theirs_events = [r["message"] for r in dslogparser.DSEventParser(str(dsevents)).read_records()]
    assert [e.raw for e in events.events] == theirs_events
    assert "robot enabled (auto)" in [e.text for e in events.events]
    assert match_name(events) == "Practice 1"


def test_fieldbox_version_4_files_and_the_list_of_runs(tmp_path):
    (dslog,), (dsevents,) = run_match(tmp_path, 4)
    log = decode_dslog(dslog.read_bytes())
    assert log.version == 4 and log.start == pytest.approx(WALL0, abs=0.1) and log.problem == ""
    assert len(log.records) == (dslog.stat().st_size - 20) // 39
    assert log.records[-1].ds_mode == "auto" and log.records[-1].robot_mode == "auto"
    (run,) = find_runs(tmp_path)
    assert run.team == 254 and run.match == "Practice 1" and run.problem == ""
    assert run.duration == pytest.approx(log.duration)
    loaded = load(run)
    assert loaded.problems == () and loaded.log == log


# -- hostile files --------------------------------------------------------------------------------
@pytest.mark.parametrize("data,says", [
    (b"", "shorter than the 20-byte header"),
    (b"hello, this is a text file and not a log\n", "does not begin with a version number (3 or 4)"),
    (struct.pack(">iqQ", 4, 0, 0), "not a date a DS could write"),
    (struct.pack(">iqQ", 7, 3_700_000_000, 0), "of version 7, which this does not read (it reads 3 and 4)"),
    (b"\x89PNG\r\n\x1a\n" + bytes(40), "does not begin with a version number"),
])
def test_a_file_that_is_no_log_gives_one_line(data, says):
    for decode in (decode_dslog, decode_dsevents):
        with pytest.raises(LogFileError) as err:
            decode(data)
        assert says in str(err.value) and "\n" not in str(err.value)


def test_a_truncated_last_record_is_said_and_the_rest_shown():
    record = head(8, 0, 0x0C40, 40, DS_TELEOP | ROBOT_TELEOP) + b"\0\0\0\x19" + CTRE
    log = decode_dslog(header(4) + record * 5 + record[:17])
    assert len(log.records) == 5 and "cut short (17 of its 39 bytes): the 5 whole records before it are shown" in log.problem
    events = decode_dsevents(header(4) + event(NI_START, "Info one") + event(NI_START + 1, "Info two")[:-2])
    assert [e.text for e in events.events] == ["one"] and "cut short (6 of its 8 bytes of text): the whole event before it is shown" in events.problem
    # a length no event has: the events before it, and a line (never a 2 GiB allocation)
    bad = header(4) + event(NI_START, "Info one") + struct.pack(">qQi", 0, 0, 2**31 - 1) + b"xx"
    events = decode_dsevents(bad)
    assert len(events.events) == 1 and "2147483647 bytes long" in events.problem


def test_a_huge_file_is_bounded(tmp_path):
    record = head(8, 0, 0x0C40, 40, DS_TELEOP | ROBOT_TELEOP) + b"\0\0\0\x19" + CTRE
    log = decode_dslog(header(4) + record * (MAX_RECORDS + 3))
    assert len(log.records) == MAX_RECORDS and "only the first" in log.problem
    big = tmp_path / "big.dslog"
    with open(big, "wb") as f:
        f.truncate(65 << 20)  # sparse: no disk used
    with pytest.raises(LogFileError, match="more than the 64 MiB"):
        read_bounded(big)
