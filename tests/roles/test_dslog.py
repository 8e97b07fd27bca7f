"""Each DS's run in the NI Driver Station's own format (roles/runtime/dslog.py), read back by an
independent reader: dslogparser (PyPI, version 3), and for version 4 the layout AdvantageScope
and DSLOG-Reader read, decoded here from their documented offsets."""

from __future__ import annotations

import calendar
import datetime as dt
import math
import struct
from pathlib import Path

import pytest

from protocol.rio_to_ds import PDP_AMPS_PER_UNIT, PdpLog, StatusPacket
from roles.runtime.dslog import (BROWNOUT, DS_AUTO, DS_DISABLED, DS_TELEOP, IDLE_CLOSE, RECORD_PERIOD, LV_EPOCH_OFFSET, RETRY_AFTER, ROBOT_AUTO, DsLogRecord, DsNiLog,
                                 console_event, event_record, file_header, file_stem, match_events, pdp_bytes,
                                 record_size)
from roles.runtime.field import Field, FieldConfig
from roles.runtime.logfiles import POLL_PERIOD, FieldLog
from roles.sim.simnet import SimNetwork

from fieldbox.language import parse

dslogparser = pytest.importorskip("dslogparser")

# A whole second, so dslogparser's fraction (it divides by 2**63 - 1, not 2**64) does not matter.
WALL0 = 1_700_000_000.0

# -- test vectors ----------------------------------------------------------------------------
# Header: i32 version, i64 seconds since 1904-01-01 UTC, u64 fraction / 2**64 (FRCture's
# logging page; AdvantageScope's DSUtil.convertLVTime; DSLOG-Reader's Reader.ReadMetadata). The
# date is the start of DSLOG-Reader's test file "2022_02_25 21_25_39 Fri.dslog" (its
# ReaderTests: 2022-02-26 02:25:39 UTC), with half a second: 0x8000... exactly.
HEADER_V4 = bytes.fromhex("00000004" "00000000de3f4023" "8000000000000000")
HEADER_UNIX = calendar.timegm((2022, 2, 26, 2, 25, 39)) + 0.5

# One record, packed by hand from the readers' offsets (dslogparser.parse_data_v3 and
# parse_pdp_v3; AdvantageScope's DSLogReader.ts; DSLOG-Reader's DSLOGReader.ReadEntryV4):
# trip 12.5 ms (x2: 0x19), lost 8 % (/4: 0x02), battery 12.5 V (x256: 0x0c80), CPU 27 %
# (x2: 0x36), flags DS auto + robot auto (0x12, inverted: 0xed), CAN 12 % (x2: 0x18), Wi-Fi
# dB 0, bandwidth 0; then the PDP: id 0, channel 0 = 8 (1 A) and channel 5 = 16 (2 A) in the
# first big-endian u64 (bits 54 and 4), the second u64 empty, channel 15 = 0x3ff in the five
# bytes, three bytes 0.
RECORD_HEAD = "19020c8036ed18000000"
PDP_25 = "00" "0200000000000100" "0000000000000000" "00000003ff" "000000"
RECORD_V3 = bytes.fromhex(RECORD_HEAD + PDP_25)
# Version 4 puts the PD type (25: CTRE PDP) in a u32 before it: byte 13 of the record is the
# type both AdvantageScope (getPDType) and DSLOG-Reader (ParsePDPType) read, byte 14 the CAN id.
RECORD_V4 = bytes.fromhex(RECORD_HEAD + "00000019" + PDP_25)
RECORD_VALUES = DsLogRecord(trip_ms=12.5, lost=0.08, battery=12.5, cpu=27.0, flags=DS_AUTO | ROBOT_AUTO, can=12.0,
                            pdp=pdp_bytes((8, 0, 0, 0, 0, 16) + (0,) * 9 + (0x3FF,)))

# The first event of DSLOG-Reader's test file "2022_02_25 21_25_39 Fri.dsevents", written by
# the NI DS 2022 (its ReaderTests.TestReadEvents): a robot print.
NI_PRINT = "<TagVersion>1 <time> 04.803 <message> ********** Robot program starting ********** "


def test_header_vector():
    assert file_header(4, HEADER_UNIX) == HEADER_V4
    version, secs, frac = struct.unpack(">iqQ", HEADER_V4)
    assert secs - LV_EPOCH_OFFSET + frac / 2**64 == HEADER_UNIX


def test_record_vectors_and_dslogparser_reads_them(tmp_path):
    assert RECORD_VALUES.encode(3) == RECORD_V3 and len(RECORD_V3) == record_size(3) == 35
    assert RECORD_VALUES.encode(4) == RECORD_V4 and len(RECORD_V4) == record_size(4) == 39
    path = tmp_path / "v3.dslog"
    path.write_bytes(file_header(3, WALL0) + RECORD_V3)
    (rec,) = dslogparser.DSLogParser(str(path)).read_records()
    assert rec["round_trip_time"] == 12.5 and rec["packet_loss"] == pytest.approx(0.08)
    assert rec["voltage"] == 12.5 and rec["rio_cpu"] == pytest.approx(0.27) and rec["can_usage"] == pytest.approx(0.12)
    assert rec["ds_auto"] and rec["robot_auto"] and not rec["ds_disabled"] and not rec["robot_disabled"]
    assert not rec["brownout"] and not rec["watchdog"] and not rec["ds_tele"] and not rec["robot_tele"]
    # dslogparser 1.0.3 lists the channels 15 first ("values are 15 through 0, so reverse the
    # list ... DSLog-Reader did not reverse these. Don't know who to believe"); DSLOG-Reader and
    # fieldbox's wire codec (protocol/rio_to_ds.py, PdpLog) put channel 0 in the top bits.
    assert rec["pdp_currents"][::-1] == [1.0, 0, 0, 0, 0, 2.0] + [0] * 9 + [127.875]
    assert rec["time"] == dt.datetime.fromtimestamp(WALL0, dt.timezone.utc)


def test_the_pdp_bytes_are_the_robots_pdp_tag():
    """The NI DS logs the PDP tag (0x08) of the status packet as it came: the same 25 bytes."""
    pdp = PdpLog(currents=tuple(range(0, 1024, 64)), unknown_head=7, unknown_tail=b"\x01\x02\x03")
    wire = StatusPacket(tags=(pdp,)).encode()
    assert wire[8:10] == bytes((26, 0x08))
    assert pdp_bytes(pdp.currents, pdp.unknown_head, pdp.unknown_tail) == wire[10:]


def wpilib_pdp(frames: bytes) -> tuple[list[int], float]:
    """The 24 bytes after the PDP's id read as WPILib's CTREPDP.cpp reads its three CAN status
    frames (PdpStatus1..3; GCC fills each byte's bit-fields from its lowest bit): the sixteen
    raw currents and the bus voltage (busVoltage * 0.05 + 4.0)."""
    def field(byte: int, lo: int, width: int) -> int:
        return (byte >> lo) & ((1 << width) - 1)
    raw = []
    for f in range(3):
        d = frames[8 * f:8 * f + 8]
        chans = [field(d[0], 0, 8) << 2 | field(d[1], 6, 2), field(d[1], 0, 6) << 4 | field(d[2], 4, 4),
                 field(d[2], 0, 4) << 6 | field(d[3], 2, 6), field(d[3], 0, 2) << 8 | d[4]]
        if f < 2:
            chans += [d[5] << 2 | field(d[6], 6, 2), field(d[6], 0, 6) << 4 | field(d[7], 4, 4)]
        raw += chans
    return raw, frames[22] * 0.05 + 4.0


def test_the_pdp_bytes_are_wpilibs_ctre_frames():
    """docs/dslog.md: the log's CTRE PDP field is the PDP's three CAN frames, most-significant
    bit first, then resistance, bus voltage and temperature, as WPILib decodes them."""
    currents = tuple(range(1, 1024, 64))  # 1, 65, 129, ...: every bit position differs
    volts = round((12.3 - 4.0) / 0.05)
    data = pdp_bytes(currents, 3, bytes((20, volts, 90)))
    raw, bus = wpilib_pdp(data[1:])
    assert raw == list(currents) and bus == pytest.approx(12.3)
    # AdvantageScope's DSLogReader.ts: from bit floor(i/6)*64 + (i%6)*10, each byte from its
    # lowest bit, eight bits: not the currents
    bits = [(byte >> k) & 1 for byte in data[1:22] for k in range(8)]
    scope = [sum(bits[(i // 6) * 64 + (i % 6) * 10 + k] << k for k in range(8)) for i in range(16)]
    assert scope[0] == currents[0] >> 2 and scope != list(currents)


def test_console_lines_as_the_ni_ds_writes_them():
    assert console_event("stdout", "********** Robot program starting **********", 4.803) == NI_PRINT
    assert console_event("error", "[-1029] Loop time overrun", 12.5) == (
        "<TagVersion>1 <time> 12.500 <count> 1 <flags> 1 <Code> -1029 <details> Loop time overrun "
        "<location>  <stack> ")


def test_match_lines_are_the_ones_readers_look_for(tmp_path):
    class Info:
        competition, match_type, match_number, replay = "NCPEM", 2, 52, 1
    lines = match_events(Info, WALL0)
    assert lines[0].startswith("FMS Connected:   Qualification - 52:1, Field Time: ")
    assert lines[1] == "Info FMS Event Name: NCPEM"
    path = tmp_path / "m.dsevents"
    path.write_bytes(file_header(3, WALL0) + b"".join(event_record(WALL0, text) for text in lines))
    found = dslogparser.DSEventParser.find_match_info(str(path))
    assert found["match_name"] == "Qualification - 52:1"
    assert found["field_time"] == dt.datetime.fromtimestamp(WALL0).replace(microsecond=0)


def test_bad_values_are_clipped_never_raised():
    rec = DsLogRecord(trip_ms=float("nan"), lost=7.0, battery=1e9, cpu=-5.0, can=float("inf"), flags=0x1FF,
                      pdp=pdp_bytes((5000, -3)))
    data = rec.encode(4)
    assert len(data) == 39 and data[:10] == bytes.fromhex("00 19 ffff 00 00 00 00 0000")
    assert file_stem(WALL0) == dt.datetime.fromtimestamp(WALL0).strftime("%Y_%m_%d %H_%M_%S ") + \
        ("Mon", "Tue", "Wed", "Thu", "Fri", "Sat", "Sun")[dt.datetime.fromtimestamp(WALL0).weekday()]


# -- a version-4 reader from the documented offsets -------------------------------------------
def read_v4(path: Path) -> tuple[float, list[dict]]:
    data = path.read_bytes()
    version, secs, frac = struct.unpack_from(">iqQ", data)
    assert version == 4
    records = []
    for at in range(20, len(data), 39):
        trip, lost, volts, cpu, mask, can = struct.unpack_from(">BbHBBB", data, at)
        pd_type, can_id = data[at + 13], data[at + 14]
        groups = data[at + 15:at + 36]
        g0, g1 = struct.unpack_from(">QQ", groups)
        g2 = int.from_bytes(groups[16:21], "big")
        raw = [(g0 >> (54 - 10 * i)) & 0x3FF for i in range(6)] + [(g1 >> (54 - 10 * i)) & 0x3FF for i in range(6)] \
            + [(g2 >> (30 - 10 * i)) & 0x3FF for i in range(4)]
        records.append({"trip": trip / 2, "lost": lost * 4 / 100, "battery": volts / 256, "cpu": cpu / 2,
                        "flags": ~mask & 0xFF, "can": can / 2, "pd_type": pd_type, "can_id": can_id,
                        "amps": [r * PDP_AMPS_PER_UNIT for r in raw]})
    return secs - LV_EPOCH_OFFSET + frac / 2**64, records


def read_events(path: Path) -> list[tuple[float, str]]:
    data, at, out = path.read_bytes(), 20, []
    while at < len(data):
        secs, frac, n = struct.unpack_from(">qQi", data, at)
        out.append((secs - LV_EPOCH_OFFSET + frac / 2**64, data[at + 20:at + 20 + n].decode("utf-8")))
        at += 20 + n
    return out


# -- a field's DS, end to end -------------------------------------------------------------------
def run_match(tmp_path, version: int, roles=("ds", "rio", "fms")):
    net = SimNetwork()
    field = Field(FieldConfig(roles=frozenset(roles), team=254, plan="ephemeral", dslog_version=version))
    field.start_sim(net)
    start = net.now
    log = FieldLog(field, tmp_path, wall_clock=lambda: WALL0 + (net.now - start)).attach()
    samples = []  # (core time, battery, pdp amps, robot mode) as the DS saw them at each poll
    for i in range(60):
        if i == 20 and "fms" in roles:
            net.command(field.fms_name, lambda: field.execute(parse("match start"), net.now))
        net.run_for(POLL_PERIOD)
        ds = field.stations[0].ds
        samples.append((net.now - start, ds.link.battery, ds.telemetry.pdp.amps if ds.telemetry.pdp else None, ds.link.program_mode))
        log.poll()
    return net, field, log, samples


def ni_files(log: FieldLog, suffix: str) -> list[Path]:
    return [p for p in log.ni_logs[254].paths if p.parent.name == "ds-254-dslog" and p.suffix == suffix]


def test_a_match_in_version_3_as_dslogparser_reads_it(tmp_path):
    net, field, log, samples = run_match(tmp_path, 3)
    ds = field.stations[0].ds
    ds.add_console_line(net.now, "stdout", "shooter at speed")
    ds.add_console_line(net.now, "error", "[44004] The robot is out of memory")
    log.close()
    assert log.errors == 0, log.last_error
    (dslog,), (dsevents,) = ni_files(log, ".dslog"), ni_files(log, ".dsevents")
    assert dslog.stem == dsevents.stem and dslog.parent.name == "ds-254-dslog"
    parser = dslogparser.DSLogParser(str(dslog))
    records = list(parser.read_records())
    # a record every 20 ms from the first robot status (the pair opens with robot comms)
    assert 280 <= len(records) <= 300
    first, last = records[0], records[-1]
    assert first["time"].timestamp() == pytest.approx(WALL0, abs=0.1)
    assert (last["time"] - first["time"]).total_seconds() == pytest.approx((len(records) - 1) * 0.020, abs=0.02)
    # the robot, disabled before the match and in auto after, as its status said
    assert first["robot_disabled"] and first["ds_disabled"] and not first["robot_auto"]
    assert last["robot_auto"] and last["ds_auto"] and not last["ds_disabled"] and not last["brownout"]
    assert last["voltage"] == pytest.approx(samples[-1][1], abs=1 / 256)
    assert last["pdp_currents"][::-1] == pytest.approx(list(samples[-1][2]))  # 15 first, see above
    cpus = ds.telemetry.cpu.cpus
    assert last["rio_cpu"] == pytest.approx(
        round(sum(c.time_critical + c.above_normal + c.normal + c.low for c in cpus) / len(cpus) * 2) / 200)
    assert last["can_usage"] == pytest.approx(round(ds.telemetry.can.utilization * 2) / 200)
    assert last["round_trip_time"] == pytest.approx(ds.link.echoes.trip.last_ms, abs=0.5)
    assert all(r["packet_loss"] == 0 for r in records)
    events = [r["message"] for r in dslogparser.DSEventParser(str(dsevents)).read_records()]
    assert dslogparser.DSEventParser.find_match_info(str(dsevents))["match_name"].endswith(" - 1:1")
    assert "Info robot comms established" in events and "Info robot enabled (auto)" in events
    assert any(e.endswith("<message> shooter at speed ") for e in events)
    assert any("<Code> 44004 <details> The robot is out of memory" in e for e in events)


def test_a_match_in_version_4_as_advantagescope_reads_it(tmp_path):
    net, field, log, samples = run_match(tmp_path, 4)
    log.close()
    (dslog,), (dsevents,) = ni_files(log, ".dslog"), ni_files(log, ".dsevents")
    assert (dslog.stat().st_size - 20) % 39 == 0
    start, records = read_v4(dslog)
    assert start == pytest.approx(WALL0, abs=0.1)
    assert all(r["pd_type"] == 25 and r["can_id"] == 0 for r in records)
    assert records[0]["flags"] & ROBOT_AUTO == 0
    assert records[-1]["flags"] & (DS_AUTO | ROBOT_AUTO) == DS_AUTO | ROBOT_AUTO
    assert records[-1]["battery"] == pytest.approx(samples[-1][1], abs=1 / 256)
    assert records[-1]["amps"] == pytest.approx(list(samples[-1][2]))
    events = read_events(dsevents)
    assert any(text.startswith("FMS Connected:   ") for _, text in events)
    assert all(WALL0 - 1 <= t <= WALL0 + 7 for t, _ in events)


def test_an_idle_ds_writes_nothing_and_a_lost_robot_ends_the_pair(tmp_path):
    net = SimNetwork()
    field = Field(FieldConfig(roles=frozenset({"ds", "rio"}), team=254, plan="ephemeral"))
    field.start_sim(net)
    log = FieldLog(field, tmp_path, wall_clock=lambda: WALL0 + net.now).attach()
    for _ in range(10):
        net.run_for(POLL_PERIOD)
        log.poll()
    ni = log.ni_logs[254]
    assert ni.open and ni.records > 0
    field.execute(parse("fault ds-rio:cut"), net.now)  # the robot is gone
    for _ in range(int((IDLE_CLOSE + 3) / POLL_PERIOD)):
        net.run_for(POLL_PERIOD)
        log.poll()
    assert not field.stations[0].ds.link.robot_comms
    assert not ni.open
    log.close()
    assert len(ni_files(log, ".dslog")) == 1


def test_a_ds_with_no_robot_and_no_fms_writes_no_pair(tmp_path):
    net = SimNetwork()
    field = Field(FieldConfig(roles=frozenset({"ds"}), team=254, plan="ephemeral"))
    field.start_sim(net)
    log = FieldLog(field, tmp_path, wall_clock=lambda: WALL0 + net.now).attach()
    for _ in range(20):
        net.run_for(POLL_PERIOD)
        log.poll()
    log.close()
    assert not (log.folder / "ds-254-dslog").exists() and log.errors == 0


class FakeDs:
    """Just what roles/runtime/dslog.py reads of a DS core: its parts' few attributes."""

    def __init__(self) -> None:
        from types import SimpleNamespace

        from roles.cores.core import Events, TripTimer
        from protocol.enums import Mode

        self.enabled, self.mode, self.events = False, Mode.TELEOP, Events()
        self.link = SimpleNamespace(robot_comms=True, status=None, battery=None,
                                    echoes=SimpleNamespace(trip=TripTimer(), lost_packets=0, sent_packets=0))
        # when the brownout bit last changed
        self.telemetry = SimpleNamespace(brownout=False, brownout_changed=None, cpu=None, can=None, pdp=None,
                                         battery_history=[])
        # what the last control packet said
        self.arbiter = SimpleNamespace(sent_enabled=False, sent_mode=Mode.TELEOP)
        self.fms = SimpleNamespace(attached=False)
        self.tcp = SimpleNamespace(match_info=None)


def test_an_enable_shows_at_its_record_not_at_the_next_poll(tmp_path):
    """The DS's event marks the change: records before it keep the state from before."""
    from protocol.enums import Mode

    ds = FakeDs()
    ni = DsNiLog(ds, tmp_path, lambda t: WALL0 + t, version=3)
    ds.events.listeners.append(ni.event)
    ni.catch_up(0.0)
    ni.catch_up(0.4)  # polled: disabled
    ds.enabled = ds.arbiter.sent_enabled = True
    ds.events.add(0.5, "robot enabled (teleop)")  # as the core says it, at the packet
    ni.catch_up(0.9)  # the next poll
    ni.close(0.9)
    (dslog,) = [p for p in ni.paths if p.suffix == ".dslog"]
    records = list(dslogparser.DSLogParser(str(dslog)).read_records())
    assert len(records) == 46
    assert [r["ds_tele"] for r in records] == [False] * 25 + [True] * 21  # the change at 0.5 s
    assert all(r["ds_disabled"] for r in records[:25]) and not any(r["ds_disabled"] for r in records[25:])


def test_each_match_the_fms_loads_gets_a_pair_of_its_own(tmp_path):
    class Info:
        competition, match_type, replay = "", 2, 1

        def __init__(self, n):
            self.match_number = n
    ds = FakeDs()
    ni = DsNiLog(ds, tmp_path, lambda t: WALL0 + t, version=3)
    ni.catch_up(0.0)
    ds.fms.attached, ds.tcp.match_info = True, Info(1)
    ni.catch_up(1.0)
    ds.tcp.match_info = Info(2)
    ni.catch_up(2.5)  # a second later the name would differ anyway: this one gets "(2)"
    ni.close(3.0)
    logs = sorted(p for p in ni.paths if p.suffix == ".dsevents")
    assert len(logs) == 2
    names = [dslogparser.DSEventParser.find_match_info(str(p))["match_name"] for p in logs]
    assert sorted(names) == ["Qualification - 1:1", "Qualification - 2:1"]
    for p in ni.paths:
        if p.suffix == ".dslog":
            assert all(r["voltage"] == 0 for r in dslogparser.DSLogParser(str(p)).read_records())


def test_a_failing_disk_is_counted_and_the_next_pair_starts_clean(tmp_path):
    errors: list[Exception] = []
    ds = FakeDs()
    ni = DsNiLog(ds, tmp_path, lambda t: WALL0 + t, version=3, on_error=errors.append)
    ni.catch_up(0.0)
    ni.catch_up(0.5)

    class Full:
        def write(self, data):
            raise OSError(28, "No space left on device")

        def flush(self):
            raise OSError(28, "No space left on device")

        def close(self):
            pass
    real = ni._log
    ni._log = Full()
    ds.events.listeners.append(ni.event)
    ni.catch_up(1.0)  # fails: counted, the pair ends
    real.close()
    ds.events.add(1.1, "robot comms lost")  # inside a core's event: nothing may escape
    assert errors and "No space left" in str(errors[0])
    ni.catch_up(3.0)  # a full disk gets no new file at each poll
    assert not ni.open and len(ni.paths) == 2
    ni.catch_up(1.0 + RETRY_AFTER)
    ni.close(7.0)
    logs = [p for p in ni.paths if p.suffix == ".dslog"]
    assert len(logs) == 2  # the first ended at the failure, the next began whole
    for p in logs:
        assert (p.stat().st_size - 20) % 35 == 0
        assert list(dslogparser.DSLogParser(str(p)).read_records())


def test_the_apps_wire_thread_writes_them(tmp_path):
    """The app's wire (a ThreadEngine, real loopback sockets) leaves a .dslog dslogparser reads."""
    import time

    from roles.runtime.engine import ThreadEngine

    engine = ThreadEngine(FieldConfig(roles=frozenset({"ds", "rio"}), team=254, plan="ephemeral",
                                      log_dir=str(tmp_path), dslog_version=3))
    engine.start()
    try:
        deadline = time.monotonic() + 10
        while time.monotonic() < deadline and not (engine.log and engine.log.ni_logs[254].records > 25):
            time.sleep(0.05)
    finally:
        log = engine.log
        engine.stop()
    (dslog,) = ni_files(log, ".dslog")
    records = list(dslogparser.DSLogParser(str(dslog)).read_records())
    assert len(records) > 25 and records[-1]["voltage"] > 10 and records[-1]["robot_disabled"]


def test_fieldbox_headless_dslog_version_3(tmp_path):
    """As a mentor runs it: ``fieldbox --headless --dslog-version 3``, a match, ``quit``; the
    folder it names holds a pair dslogparser reads, with the match in it."""
    import subprocess
    import sys
    import time

    root = Path(__file__).resolve().parents[2]
    proc = subprocess.Popen([sys.executable, "-m", "fieldbox", "--headless", "--net", "ephemeral", "--team", "254", "--roles", "ds,rio,fms",
                             "--log-dir", str(tmp_path), "--dslog-version", "3"], cwd=root, stdin=subprocess.PIPE,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, bufsize=1)
    try:
        folder, deadline = None, time.monotonic() + 30
        while time.monotonic() < deadline:
            line = proc.stdout.readline()
            if line.startswith("logs "):
                folder = Path(line[5:].strip())
            if line.startswith("fms:") and "R1:254+" in line:
                break
        proc.stdin.write("match start\n")
        proc.stdin.flush()
        while time.monotonic() < deadline:
            line = proc.stdout.readline()
            if line.startswith("rio ") and "enabled" in line and "disabled" not in line:
                break
        else:
            pytest.fail("the robot never enabled")
        time.sleep(0.5)
        proc.stdin.write("quit\n")
        proc.stdin.flush()
        proc.wait(20)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait(10)
    assert proc.returncode == 0
    (dslog,) = (folder / "ds-254-dslog").glob("*.dslog")
    records = list(dslogparser.DSLogParser(str(dslog)).read_records())
    assert records[0]["robot_disabled"] and records[-1]["robot_auto"] and records[-1]["voltage"] > 10
    info = dslogparser.DSEventParser.find_match_info(str(dslog.with_suffix(".dsevents")))
    assert info is not None and info["match_name"].endswith(":1")


def test_a_failed_ni_write_is_said_by_take_problem(tmp_path):
    """FieldLog counts a failed .dslog write as its own, and take_problem says it."""
    net, field, log, _ = run_match(tmp_path, 4, roles=("ds", "rio"))
    ni = log.ni_logs[254]

    class Full:
        def write(self, data):
            raise OSError(28, "No space left on device")

        def flush(self):
            raise OSError(28, "No space left on device")

        def close(self):
            pass
    real, ni._log = ni._log, Full()
    real.close()
    net.run_for(POLL_PERIOD)
    log.poll()
    problem = log.take_problem()
    assert log.errors >= 1 and problem is not None and "No space left" in problem
    assert field.stations[0].ds.link.robot_comms  # the field runs on
    log.close()


def test_the_2010_protocol_logs_too(tmp_path):
    net = SimNetwork()
    field = Field(FieldConfig(roles=frozenset({"ds", "rio"}), team=254, plan="ephemeral", legacy=True,
                              dslog_version=3))
    field.start_sim(net)
    log = FieldLog(field, tmp_path, wall_clock=lambda: WALL0 + net.now).attach()
    for _ in range(20):
        net.run_for(POLL_PERIOD)
        log.poll()
    log.close()
    (dslog,) = ni_files(log, ".dslog")
    records = list(dslogparser.DSLogParser(str(dslog)).read_records())
    assert log.errors == 0 and records and records[-1]["voltage"] > 10


# -- AdvantageScope's view ----------------------------------------------------------------------
def advantagescope_times(path: Path) -> list[float]:
    """Each event's time as AdvantageScope's DSEventsReader makes it: DSUtil.convertLVTime's
    double of Unix seconds (its epoch 1904-01-01 05:00 UTC, summed in this order), less the
    header's. Its log keeps one value per timestamp: two events at one time are one event."""
    def convert(secs: int, frac: int) -> float:
        t = -2082826800.0
        t += float(secs)
        t += float(frac) / 2**64
        return t
    data = path.read_bytes()
    start = convert(*struct.unpack_from(">qQ", data, 4))
    at, out = 20, []
    while at < len(data):
        secs, frac, n = struct.unpack_from(">qQi", data, at)
        out.append(convert(secs, frac) - start)
        at += 20 + n
    return out


def test_no_two_events_of_a_match_share_a_time_as_advantagescope_reads_them(tmp_path):
    """The match line, the event name and the date request come at one moment: AdvantageScope
    would keep only the last of them (real NI files: no two events share a time)."""
    net, field, log, _ = run_match(tmp_path, 4)
    log.close()
    (dsevents,) = ni_files(log, ".dsevents")
    times, texts = advantagescope_times(dsevents), [text for _, text in read_events(dsevents)]
    assert any(text.startswith("FMS Connected:   ") for text in texts)
    assert len(times) == len(texts) > 5
    assert len(set(times)) == len(times)
    assert times == sorted(times)  # in the order written, as the NI DS writes them
    # and each still at its moment: a bump is a microsecond, nowhere near a record's 20 ms
    raw = [t for t, _ in read_events(dsevents)]
    assert all(abs(b - a) < 0.001 or b > a for a, b in zip(raw, raw[1:]))


def test_an_enable_shows_from_the_record_its_first_control_packet_went_out_in(tmp_path):
    """Enabled between two control packets and the log polled at once: the records before the
    packet that tells the robot still say disabled."""
    net = SimNetwork()
    field = Field(FieldConfig(roles=frozenset({"ds", "rio"}), team=254, plan="ephemeral", dslog_version=4))
    field.start_sim(net)
    log = FieldLog(field, tmp_path, wall_clock=lambda: WALL0 + net.now).attach()
    ds, deadline = field.stations[0].ds, net.now + 10
    while not (ds.link.robot_comms and ds.link.robot_code):
        net.run_for(POLL_PERIOD)
        log.poll()
        assert net.now < deadline, "the robot never came up"
    ni = log.ni_logs[254]
    # a control packet goes out at p; the next record boundary after it is b (<= p + 20 ms)
    sent = ds.link.echoes.sent_packets
    while ds.link.echoes.sent_packets == sent:
        net.run_for(0.0005)
    p = net.now
    b = ni._start + math.ceil((p - ni._start) / RECORD_PERIOD + 1e-9) * RECORD_PERIOD
    net.run_for((b - p) / 2)  # between p and b: the next packet is in the record after b
    commanded = net.now
    field.execute(parse("enable"), net.now)
    log.poll()  # at once: the robot has not been told
    for _ in range(5):
        net.run_for(POLL_PERIOD)
        log.poll()
    log.close()
    (dslog,), (dsevents,) = ni_files(log, ".dslog"), ni_files(log, ".dsevents")
    start, records = read_v4(dslog)
    (told,) = [t for t, text in read_events(dsevents) if text.startswith("Info robot enabled")]
    assert told - start > commanded - ni._start  # the packet went after the command
    first = next(i for i, r in enumerate(records) if not r["flags"] & DS_DISABLED)
    assert first == int((told - start) / RECORD_PERIOD + 1e-6)
    assert all(r["flags"] & DS_DISABLED for r in records[:first])
    assert all(r["flags"] & DS_TELEOP for r in records[first:])


def test_a_brownout_ends_at_its_record_not_at_the_next_poll(tmp_path):
    """No event marks a brownout's end: the records up to the status packet that ended it
    still show it, and the one it came in shows it over."""
    from types import SimpleNamespace

    ds = FakeDs()
    ds.link.status = SimpleNamespace(user_teleop=False, user_auto=False, user_disabled=True)
    ni = DsNiLog(ds, tmp_path, lambda t: WALL0 + t, version=4)
    ds.events.listeners.append(ni.event)
    ni.catch_up(0.0)
    ni.catch_up(0.2)
    ds.events.add(0.3, "robot brownout (6.10 V)")  # as the core fires it: the bit not yet set
    ds.telemetry.brownout, ds.telemetry.brownout_changed = True, 0.3
    ni.catch_up(0.4)
    ds.telemetry.brownout, ds.telemetry.brownout_changed = False, 0.47  # over, in the record of 0.46 to 0.48
    ni.catch_up(0.5)
    ni.close(0.6)
    (dslog,) = [p for p in ni.paths if p.suffix == ".dslog"]
    _, records = read_v4(dslog)
    assert len(records) == 31
    assert [bool(r["flags"] & BROWNOUT) for r in records] == [False] * 15 + [True] * 8 + [False] * 8
