"""A Driver Station's run in the NI Driver Station's own log format: ``.dslog`` (a record every
20 ms) and ``.dsevents`` (timestamped text), the pair AdvantageScope and DSLOG-Reader open.

The layout, as the independent readers agree on it (AdvantageScope's DSLogReader.ts and
DSEventsReader.ts, DSLOG-Reader 2's DSLOGReader.cs and DSEVENTSReader.cs, ligerbots'
dslogparser; FRCture's logging page for the older fields). Everything is big-endian.

* Both files start with ``i32 version``, then a LabVIEW timestamp: ``i64`` seconds since
  1904-01-01 00:00 UTC and ``u64`` fractions of a second (/2**64). In a ``.dslog`` that is the
  time of the first record; records carry no time of their own, each is 20 ms after the last.
* A ``.dslog`` record: ``u8`` trip time (ms x 2), ``i8`` lost packets (percent / 4), ``u16``
  battery (V x 256), ``u8`` roboRIO CPU (percent x 2), ``u8`` status flags, ``u8`` CAN
  utilisation (percent x 2), ``u8`` Wi-Fi dB (x 2), ``u16`` bandwidth (Mb/s x 256); then the
  power distribution. The status flags are *inverted* (a 0 bit is set), high bit first:
  brownout, watchdog, DS teleop, DS auto, DS disabled, robot teleop, robot auto, robot disabled.
* Version 3 (2016 to 2021): the 25 bytes of the roboRIO's PDP tag (0x08) follow, as the
  status packet carries them: an id byte, sixteen 10-bit currents (1/8 A) packed in 21 bytes,
  3 more bytes. A record is 35 bytes. dslogparser reads only this version.
* Version 4 (the NI DS since 2022, when it learnt the REV PDH; what it writes today):
  4 bytes whose last is the PD type (25 CTRE PDP, 33 REV PDH), then for a CTRE PDP the CAN id
  and the same 24 bytes as version 3: a record is 39 bytes. AdvantageScope and DSLOG-Reader
  read only this version. The 24 bytes are the PDP's three CAN status frames as WPILib's
  CTREPDP.cpp decodes them, most-significant bit first, the last three bytes resistance, bus
  voltage and temperature (docs/dslog.md; AdvantageScope reads the currents' bits otherwise).
* A ``.dsevents`` record: a LabVIEW timestamp, ``i32`` length, that many bytes of text. Robot
  prints are ``<TagVersion>1 <time> SS.mmm <message> TEXT``, errors ``<TagVersion>1 <time>
  SS.mmm <count> 1 <flags> F <Code> N <details> TEXT <location> WHERE <stack> ``; a match shows
  as ``FMS Connected:   Qualification - 12:1, Field Time: 26/3/29 13:35:4`` and
  ``Info FMS Event Name: NAME`` (the lines DSLOG-Reader and dslogparser look for). No two
  events share a time (:data:`EVENT_STEP`): AdvantageScope keeps one event per timestamp.

What fieldbox's DS knows goes in; what it does not is written as nothing: Wi-Fi dB and
bandwidth 0 (no radio here), the watchdog flag clear (a DS cannot see the robot's watchdog; the
FMS log-data tag says the same), PD currents 0 until the robot sends a PDP tag. fieldbox's
robot speaks the CTRE PDP tag only, so every version-4 record says "CTRE PDP", whose layout a
reader takes from the file's first record: a file never changes its record size.

A pair starts when the DS first has robot comms or an FMS, and ends after :data:`IDLE_CLOSE`
seconds with neither (so an idle DS writes nothing), when the FMS loads another match (one
pair per match, as the readers list them), after :data:`MAX_RECORDS` records (an hour), or
after a write fails (so a file never holds a torn record mid-way; the next pair, tried
:data:`RETRY_AFTER` seconds on, first says what was lost meanwhile, and so does the DS's console
log), or when its files are deleted (:meth:`DsNiLog.relocate`). Files are named as the NI
DS names them, ``YYYY_MM_DD HH_MM_SS Ddd``, local time: DSLOG-Reader lists a folder by those
names. Values other than the battery are read when :meth:`DsNiLog.catch_up` runs (every
100 ms from :class:`~roles.runtime.logfiles.FieldLog`) and written as the 20 ms records since; the
battery comes from the DS's per-packet history; only records whose 20 ms have ended are
written (the one under way when the log closes); a DS event (enabled, disabled, comms lost,
brownout, e-stop) first writes the records that ended before it with the state from before,
so a change shows in the record it happened in. The DS flags are what the last control packet
sent (``ds.arbiter.sent_enabled``), not the command, and a brownout's end, which fires no event, shows
in the record its status packet came in (``ds.telemetry.brownout_changed``).
"""

from __future__ import annotations

import datetime as _dt
import errno
import math
import os
import re
import struct
from collections import deque
from dataclasses import dataclass
from pathlib import Path
from typing import Any, BinaryIO, Callable

from protocol.enums import Mode

RECORD_PERIOD = 0.020
#: The version the NI Driver Station writes now (since 2022), and the one dslogparser reads.
VERSION_NI = 4
VERSION_DSLOGPARSER = 3
VERSIONS = (VERSION_DSLOGPARSER, VERSION_NI)
PD_TYPE_CTRE = 25
PD_TYPE_REV = 33  # a REV PDH: never written, fieldbox's robot has no PDH tag
#: Seconds with neither robot comms nor an FMS before a pair is closed.
IDLE_CLOSE = 10.0
#: Records in one .dslog before the next pair begins (an hour: about 7 MB).
MAX_RECORDS = 180_000
#: A gap longer than this between two catch-ups (a stopped process) starts a new pair rather
#: than filling the file with guesses.
MAX_CATCH_UP = 500
#: Bytes of one event's text (a call stack is a few KiB).
MAX_EVENT_BYTES = 8192
#: After a failed write, seconds before the next pair is tried (a full disk gets no new file
#: ten times a second).
RETRY_AFTER = 5.0
#: The step between two .dsevents records that would share a time, in LabVIEW's 2**-64 s units:
#: 2**-20 s (about a microsecond). AdvantageScope keeps one event per timestamp and turns the
#: time into a double of Unix seconds (DSUtil.convertLVTime), whose resolution is 2**-22 s now
#: and 2**-21 s after 2038: a smaller step would give the same double, and lose the event.
EVENT_STEP = 2**44
#: File paths remembered in :attr:`DsNiLog.paths` (the newest).
MAX_PATHS = 100
LOSS_WINDOW = 1.0  # seconds over which the lost-packet share is counted

#: Seconds from 1904-01-01 (LabVIEW's epoch) to 1970-01-01, both UTC.
LV_EPOCH_OFFSET = 2_082_844_800
_DAYS = ("Mon", "Tue", "Wed", "Thu", "Fri", "Sat", "Sun")  # %a would follow the locale
_MATCH_TYPES = {0: "None", 1: "Practice", 2: "Qualification", 3: "Elimination"}
_HEAD = struct.Struct(">iqQ")
_EVENT_HEAD = struct.Struct(">qQi")
_RECORD = struct.Struct(">BbHBBBBH")
_ERROR_CODE = re.compile(r"^\[(-?\d+)\] ")

# status flag bits (before inversion), high bit first
BROWNOUT, WATCHDOG, DS_TELEOP, DS_AUTO, DS_DISABLED = 0x80, 0x40, 0x20, 0x10, 0x08
ROBOT_TELEOP, ROBOT_AUTO, ROBOT_DISABLED = 0x04, 0x02, 0x01


# -- encoding (pure) ------------------------------------------------------------------------
def lv_timestamp(unix: float) -> tuple[int, int]:
    """(seconds since 1904-01-01 UTC, fraction as u64) of a Unix time."""
    whole = math.floor(unix)
    frac = min(int((unix - whole) * 2**64), 2**64 - 1)
    return whole + LV_EPOCH_OFFSET, frac


def file_header(version: int, unix: float) -> bytes:
    return _HEAD.pack(version, *lv_timestamp(unix))


def lv_stamp(unix: float) -> int:
    """A Unix time as one LabVIEW number: seconds since 1904 times 2**64 plus the fraction."""
    whole, frac = lv_timestamp(unix)
    return whole << 64 | frac


def event_record(unix: float, text: str, stamp: int | None = None) -> bytes:
    """One .dsevents record at ``unix``, or at the LabVIEW number ``stamp`` if given."""
    data = text.encode("utf-8", "replace")[:MAX_EVENT_BYTES]
    if stamp is None:
        stamp = lv_stamp(unix)
    return _EVENT_HEAD.pack(stamp >> 64, stamp & (2**64 - 1), len(data)) + data


def pdp_bytes(currents: tuple[int, ...] = (0,) * 16, can_id: int = 0, tail: bytes = b"\0\0\0") -> bytes:
    """The 25 bytes of a CTRE PDP in a log record: the id, sixteen 10-bit currents (raw 1/8 A,
    channel 0 in the top bits of a big-endian u64 holding 0-5, the next u64 6-11, then five
    bytes 12-15), the 3 bytes after. The roboRIO's PDP tag carries the same bytes."""
    c = [min(max(int(x), 0), 0x3FF) for x in tuple(currents)[:16]] + [0] * (16 - len(currents))
    g0 = c[0] << 54 | c[1] << 44 | c[2] << 34 | c[3] << 24 | c[4] << 14 | c[5] << 4
    g1 = c[6] << 54 | c[7] << 44 | c[8] << 34 | c[9] << 24 | c[10] << 14 | c[11] << 4
    g2 = c[12] << 30 | c[13] << 20 | c[14] << 10 | c[15]
    tail = bytes(tail[:3]).ljust(3, b"\0")
    return bytes((can_id & 0xFF,)) + g0.to_bytes(8, "big") + g1.to_bytes(8, "big") + g2.to_bytes(5, "big") + tail


def _byte(value: float, scale: float, hi: int = 255, lo: int = 0) -> int:
    if not math.isfinite(value):
        return lo
    return min(max(round(value * scale), lo), hi)


@dataclass(frozen=True, slots=True)
class DsLogRecord:
    """One 20 ms record: values in the units a person reads (ms, a share 0..1, volts, percent)."""

    trip_ms: float = 0.0
    lost: float = 0.0  # share of packets lost, 0..1
    battery: float = 0.0
    cpu: float = 0.0  # roboRIO CPU, percent
    flags: int = 0  # BROWNOUT | ... (set bits; inverted on the way out)
    can: float = 0.0  # CAN utilisation, percent
    wifi_db: float = 0.0
    bandwidth: float = 0.0  # Mb/s
    pdp: bytes = pdp_bytes()  # 25 bytes (pdp_bytes)

    def encode(self, version: int = VERSION_NI) -> bytes:
        head = _RECORD.pack(_byte(self.trip_ms, 2), _byte(self.lost, 25, 25), _byte(self.battery, 256, 0xFFFF),
                            _byte(self.cpu, 2), ~self.flags & 0xFF, _byte(self.can, 2), _byte(self.wifi_db, 2),
                            _byte(self.bandwidth, 256, 0xFFFF))
        if version == VERSION_DSLOGPARSER:
            return head + self.pdp
        return head + PD_TYPE_CTRE.to_bytes(4, "big") + self.pdp


def record_size(version: int) -> int:
    return 35 if version == VERSION_DSLOGPARSER else 39


def console_event(level: str, text: str, seconds: float) -> str:
    """A console line as the NI DS writes it in .dsevents (``seconds``: since the log began)."""
    when = f"<TagVersion>1 <time> {max(seconds, 0.0):06.3f} "
    if level not in ("error", "warning"):
        return f"{when}<message> {text} "
    code = 0
    m = _ERROR_CODE.match(text)
    if m:  # the DS console keeps an error as "[code] details (location)"
        code, text = int(m.group(1)), text[m.end():]
    return (f"{when}<count> 1 <flags> {1 if level == 'error' else 0} <Code> {code} <details> {text} "
            f"<location>  <stack> ")


def match_events(info: Any, wall: float) -> list[str]:
    """The lines that mark a match: "FMS Connected: ..." (field time in the DS's local time)
    and, with a competition name, "Info FMS Event Name: ..."."""
    kind = _MATCH_TYPES.get(int(getattr(info, "match_type", 0) or 0), "None")
    t = _dt.datetime.fromtimestamp(wall)
    field_time = f"{t.year % 100}/{t.month}/{t.day} {t.hour}:{t.minute}:{t.second}"
    out = [f"FMS Connected:   {kind} - {int(getattr(info, 'match_number', 0))}:{int(getattr(info, 'replay', 0))}, "
           f"Field Time: {field_time}\n -- fieldbox Driver Station"]
    name = str(getattr(info, "competition", "") or "")
    if name:
        out.append(f"Info FMS Event Name: {name}")
    return out


def file_stem(wall: float) -> str:
    """The NI DS's file name for a log begun at ``wall`` (local time)."""
    t = _dt.datetime.fromtimestamp(wall)
    return t.strftime("%Y_%m_%d %H_%M_%S ") + _DAYS[t.weekday()]


# -- what a DS knows -------------------------------------------------------------------------
def sample(ds: Any) -> DsLogRecord:
    """A record of the DS's state now (the battery, lost packets and the brownout's end are
    filled in per slot). The DS flags are what its last control packet told the robot, not
    the command: an enable typed between two packets shows from the record its packet went
    out in."""
    comms = bool(ds.link.robot_comms)
    status = ds.link.status if comms else None
    enabled, mode = bool(ds.arbiter.sent_enabled), ds.arbiter.sent_mode
    flags = 0 if enabled else DS_DISABLED
    if enabled and mode == Mode.TELEOP:
        flags |= DS_TELEOP
    elif enabled and mode == Mode.AUTONOMOUS:
        flags |= DS_AUTO
    if status is not None:
        flags |= ROBOT_TELEOP if status.user_teleop else 0
        flags |= ROBOT_AUTO if status.user_auto else 0
        flags |= ROBOT_DISABLED if status.user_disabled else 0
        flags |= BROWNOUT if ds.telemetry.brownout else 0
    cpu = can = 0.0
    pdp = pdp_bytes()
    tel = ds.telemetry
    if comms:
        cpus = getattr(tel.cpu, "cpus", ()) or ()
        if cpus:
            cpu = sum(c.time_critical + c.above_normal + c.normal + c.low for c in cpus) / len(cpus)
        if tel.can is not None:
            can = tel.can.utilization
        if tel.pdp is not None:
            pdp = pdp_bytes(tel.pdp.currents, tel.pdp.unknown_head, tel.pdp.unknown_tail)
    last_trip = ds.link.echoes.trip.last_ms
    trip = last_trip if comms and last_trip is not None else 0.0
    return DsLogRecord(trip_ms=trip, cpu=min(max(cpu, 0.0), 100.0), flags=flags, can=can, pdp=pdp)


# -- the files ---------------------------------------------------------------------------------
class DsNiLog:
    """The .dslog/.dsevents pairs of one DS core, in ``folder``.

    ``to_unix(t)`` turns the core's clock into wall-clock seconds; ``on_error(exc)`` counts a
    failed write (nothing raises out of here: events arrive inside the core); ``on_lost(text)``
    gets the sentence saying what was lost, once a pair begins again after one. Call
    :meth:`event` from the core's events, :meth:`console` with new console lines and
    :meth:`catch_up` about every 100 ms, all on the wire's side; :meth:`flush`, :meth:`close`.
    """

    def __init__(self, ds: Any, folder: Path, to_unix: Callable[[float], float], *,
                 version: int = VERSION_NI, on_error: Callable[[Exception], Any] = lambda exc: None,
                 on_lost: Callable[[str], Any] = lambda text: None) -> None:
        if version not in VERSIONS:
            raise ValueError(f"a .dslog version fieldbox writes: {VERSIONS}, not {version!r}")
        self.ds = ds
        self.folder = Path(folder)
        self.to_unix = to_unix
        self.version = version
        self.on_error = on_error
        self.paths: deque[Path] = deque(maxlen=MAX_PATHS)  # the newest .dslog and .dsevents, in order
        self.records = 0  # in the open .dslog
        self._log: BinaryIO | None = None
        self._events: BinaryIO | None = None
        self._start = 0.0  # core time of the open pair's first record
        self._idle_since: float | None = None
        self._match: tuple | None = None  # (type, number, replay) the open pair has said
        self._fms = False
        self._loss: deque[tuple[float, int, int]] = deque(maxlen=128)
        self._now = 0.0
        self._last: DsLogRecord | None = None  # the state the last catch-up saw
        self._last_robot = False  # whether the robot was reporting at that catch-up
        self._event_stamp = -1  # the open .dsevents' last time (LabVIEW units): each is later
        self._retry_at = -math.inf
        self._closed = False
        self.on_lost = on_lost
        # after a failed write: since when (core time), why, the records and events not written
        self._lost_from: float | None = None
        self._lost_why = ""
        self._lost_live = 0.0  # seconds the DS was live (a pair would have been open) meanwhile
        self._lost_seen = 0.0
        self._lost_events = 0

    @property
    def open(self) -> bool:
        return self._log is not None

    def deleted(self) -> bool:
        """Whether the open pair's files were deleted (writes to them would go into nothing)."""
        return any(f is not None and unlinked(f) for f in (self._log, self._events))

    def relocate(self, folder: Path, now: float, why: str) -> None:
        """Go on in ``folder`` (the files were deleted): the open pair ends, a new one (its own
        header) begins there at once if the DS is live, its first event ``why``."""
        if self._closed:
            return
        self._now = now
        self._end(None)
        self.folder = Path(folder)
        self._retry_at = -math.inf
        self._keep_open(now)
        self._event(now, f"Info fieldbox: {why}")

    # -- feeding ------------------------------------------------------------------------------
    def event(self, t: float, text: str) -> None:
        """One of the core's events: "Info TEXT" in the open pair (opened if the DS is live)."""
        if self._closed:
            return
        self._now = t
        try:
            if self._log is not None and self._last is not None:
                # an event marks a change (enabled, comms lost, brownout...): the records up to
                # it keep the state from before, so the change shows to the 20 ms, not the poll
                self._records_until(t, self._last, self._last_robot)
            self._keep_open(t)
            if self._events is not None:
                self._event(t, f"Info {text}")
            elif self._lost_from is not None:
                self._lost_events += 1
        except Exception as exc:  # noqa: BLE001 - never into the core that fired the event
            self._failed(exc)

    def console(self, entries: list[tuple[float, str, str]], now: float) -> None:
        if self._closed or not entries:
            return
        self._now = now
        self._keep_open(now)
        if self._events is None:
            if self._lost_from is not None:
                self._lost_events += len(entries)
            return
        for t, level, text in entries:
            seconds = (t if t is not None else now) - self._start
            self._event(t if t is not None else now, console_event(level, text, seconds))

    def catch_up(self, now: float) -> None:
        """Write the 20 ms records due by ``now``; open, split or close pairs as the DS goes."""
        if self._closed:
            return
        self._now = now
        self._keep_open(now)
        if self._log is None:
            return
        self._last, self._last_robot = sample(self.ds), bool(self.ds.link.robot_comms)
        self._records_until(now, self._last, self._last_robot)

    def _records_until(self, now: float, base: DsLogRecord, robot: bool, final: bool = False) -> None:
        """The records whose 20 ms have ended by ``now`` (``final``: the one under way too)
        with ``base``'s state (battery, losses and a brownout's end per slot; ``robot``: the
        robot was reporting, so the brownout bit is its). A change at ``now`` (an event) thus
        shows in the record it happened in, as the records before it are written first."""
        slots = (now - self._start) / RECORD_PERIOD
        due = int(slots + 1e-9) + (1 if final else 0)
        if due - self.records > MAX_CATCH_UP:
            self._end(f"{(due - self.records) * RECORD_PERIOD:.1f} s not logged: the log was not polled")
            self._keep_open(now)
            return
        if due <= self.records:
            return
        first = self._start + self.records * RECORD_PERIOD
        volts = _battery_at(self.ds, first)
        # a brownout's end fires no event: the records before the status packet that ended it
        # still show it (its start fires one, so at most this one change is unwritten)
        brownout, changed = bool(self.ds.telemetry.brownout), self.ds.telemetry.brownout_changed
        out = bytearray()
        for k in range(self.records, min(due, MAX_RECORDS)):
            t = self._start + k * RECORD_PERIOD
            flags = base.flags & ~BROWNOUT
            if robot and (brownout != (changed is not None and t + RECORD_PERIOD <= changed + 1e-9)):
                flags |= BROWNOUT
            record = DsLogRecord(base.trip_ms, self._lost_share(t), volts(t), base.cpu, flags, base.can,
                                 base.wifi_db, base.bandwidth, base.pdp)
            out += record.encode(self.version)
        assert self._log is not None  # records are due only while the pair is open
        self._write(self._log, bytes(out))
        if self._log is not None:
            self.records = min(due, MAX_RECORDS)
            if self.records >= MAX_RECORDS:
                self._end(None)
                self._keep_open(now)

    def flush(self) -> None:
        for f in (self._log, self._events):
            if f is not None:
                try:
                    f.flush()
                except (OSError, ValueError) as exc:
                    self._failed(exc)
                    return

    def close(self, now: float | None = None) -> None:
        if self._closed:
            return
        if now is not None and self._log is not None:
            self.catch_up(now)
            if self._log is not None and self._last is not None:
                self._records_until(now, self._last, self._last_robot, final=True)  # the one under way
        self._end(None)
        self._closed = True

    # -- pairs ------------------------------------------------------------------------------
    def _keep_open(self, now: float) -> None:
        ds = self.ds
        live = bool(ds.link.robot_comms) or bool(ds.fms.attached)
        if self._lost_from is not None and self._log is None:
            if live:  # a pair would be open: its records are lost
                self._lost_live += max(0.0, now - self._lost_seen)
            self._lost_seen = now
        if self._log is not None:
            if live:
                self._idle_since = None
            elif self._idle_since is None:
                self._idle_since = now
            elif now - self._idle_since >= IDLE_CLOSE:
                self._end(None)
                return
            self._follow_fms(now)
            return
        if live and now >= self._retry_at:
            self._begin(now)

    def _follow_fms(self, now: float) -> None:
        ds = self.ds
        attached = bool(ds.fms.attached)
        info = ds.tcp.match_info if attached else None
        key = None if info is None else (int(info.match_type), info.match_number, info.replay)
        if attached and key is not None and key != self._match:
            if self._match is not None:  # the FMS loaded another match: a pair of its own
                self._end(None)
                self._begin(now)
                return
            self._match = key
            for line in match_events(info, self.to_unix(now)):
                self._event(now, line)
        if self._fms and not attached:
            self._event(now, "FMS Disconnect")
            self._match = None
        self._fms = attached

    def _begin(self, now: float) -> None:
        wall = self.to_unix(now)
        try:
            # not its parents: a run folder deleted under us is not made again here (the
            # caller notices it and moves on to a new one, saying so)
            self.folder.mkdir(exist_ok=True)
            stem = file_stem(wall)
            for n in range(1, 100):  # two pairs begun within a second: "(2)", as a browser names
                name = stem if n == 1 else f"{stem} ({n})"
                if not (self.folder / f"{name}.dslog").exists():
                    break
            log = open(self.folder / f"{name}.dslog", "xb")
        except OSError as exc:
            self._failed(exc)
            return
        try:
            events = open(self.folder / f"{name}.dsevents", "xb")
        except OSError as exc:
            log.close()
            self._failed(exc)
            return
        self._log, self._events = log, events
        self.paths += [self.folder / f"{name}.dslog", self.folder / f"{name}.dsevents"]
        self._start, self.records, self._idle_since, self._last = now, 0, None, None
        self._event_stamp = -1
        self._match, self._fms = None, False
        self._write(log, file_header(self.version, wall))
        self._write(events, file_header(self.version, wall))
        if self._log is not None and self._lost_from is not None:
            self._say_lost(now, wall)
        if self._log is not None:
            self._follow_fms(now)

    def _say_lost(self, now: float, wall: float) -> None:
        """The first event of a pair after failed writes: what was lost, from when to when."""
        records = int(self._lost_live / RECORD_PERIOD + 0.5)
        events = self._lost_events
        assert self._lost_from is not None  # the caller checked
        since, why = self.to_unix(self._lost_from), self._lost_why
        self._lost_from, self._lost_live, self._lost_events = None, 0.0, 0
        if not records and not events:
            return
        text = (f"{_count(records, 'record')} and {_count(events, 'event')} of the NI log lost from "
                f"{hms(since)} to {hms(wall)}: {why}")
        self._event(now, f"Info fieldbox: {text}")
        try:
            self.on_lost(text)
        except Exception as exc:  # noqa: BLE001 - never into the core
            self.on_error(exc)

    def _end(self, why: str | None) -> None:
        if why is not None and self._events is not None:
            self._event(self._start + self.records * RECORD_PERIOD, f"Info fieldbox: {why}")
        for f in (self._log, self._events):
            if f is not None:
                try:
                    f.close()
                except (OSError, ValueError) as exc:
                    self.on_error(exc)
        self._log = self._events = None
        self._idle_since = None

    # -- writing ----------------------------------------------------------------------------
    def _event(self, t: float, text: str) -> None:
        if self._events is not None:
            # no two events share a time: AdvantageScope keeps one event per timestamp (a
            # match's "FMS Connected" and its event name come at the same moment)
            stamp = max(lv_stamp(self.to_unix(t)), self._event_stamp + EVENT_STEP)
            self._event_stamp = stamp
            self._write(self._events, event_record(0.0, text, stamp))

    def _write(self, f: BinaryIO, data: bytes) -> None:
        try:
            f.write(data)
        except (OSError, ValueError) as exc:
            if f is self._events and self._log is not None:
                self._lost_events += 1  # this event; a record's loss is counted by its time
            self._failed(exc)

    def _failed(self, exc: Exception) -> None:
        """Counted; the pair ends, so no file goes on past a torn record (the next begins anew,
        :data:`RETRY_AFTER` seconds on, and says what was lost meanwhile)."""
        self.on_error(exc)
        if self._lost_from is None:
            # the records lost begin with the first one not written
            first = self._start + self.records * RECORD_PERIOD if self._log is not None else self._now
            self._lost_from, self._lost_seen, self._lost_why = first, first, write_problem(exc)
            self._lost_live = 0.0
        self._retry_at = self._now + RETRY_AFTER
        self._end(None)

    def _lost_share(self, t: float) -> float:
        ds = self.ds
        window = self._loss
        window.append((t, ds.link.echoes.lost_packets, ds.link.echoes.sent_packets))
        while len(window) > 1 and t - window[0][0] > LOSS_WINDOW:
            window.popleft()
        _, lost0, sent0 = window[0]
        sent = ds.link.echoes.sent_packets - sent0
        return min(max((ds.link.echoes.lost_packets - lost0) / sent, 0.0), 1.0) if sent > 0 else 0.0


def write_problem(exc: BaseException) -> str:
    """Why a write failed, in a few words ("disk full")."""
    code = getattr(exc, "errno", None)
    if code == errno.ENOSPC:
        return "disk full"
    if code == errno.EDQUOT:
        return "disk quota full"
    return getattr(exc, "strerror", None) or str(exc) or type(exc).__name__


def unlinked(f: Any) -> bool:
    """Whether an open file was deleted (its link count 0): what is written to it is lost."""
    try:
        return os.fstat(f.fileno()).st_nlink == 0
    except (OSError, ValueError, AttributeError):  # closed, or not a real file
        return False


def hms(wall: float) -> str:
    """A wall-clock time as HH:MM:SS, local time."""
    return _dt.datetime.fromtimestamp(wall).strftime("%H:%M:%S")


def _count(n: int, what: str) -> str:
    return f"{n} {what}" if n == 1 else f"{n} {what}s"


def _battery_at(ds: Any, since: float) -> Callable[[float], float]:
    """The battery at a slot time: the newest sample at or before it, from the DS's history;
    0 where the newest is over a second old (no robot comms: the NI DS shows no battery)."""
    recent: list[tuple[float, float]] = []
    for t, v in reversed(ds.telemetry.battery_history):
        recent.append((t, v))
        if t < since:
            break
    recent.reverse()
    i = 0

    def at(t: float) -> float:
        nonlocal i
        while i + 1 < len(recent) and recent[i + 1][0] <= t:
            i += 1
        if recent and t - 1.0 < recent[i][0] <= t:
            return recent[i][1]
        return 0.0
    return at


__all__ = ["BROWNOUT", "DS_AUTO", "DS_DISABLED", "DS_TELEOP", "DsLogRecord", "DsNiLog",
           "EVENT_STEP", "IDLE_CLOSE", "MAX_PATHS", "MAX_RECORDS", "PD_TYPE_CTRE", "RECORD_PERIOD",
           "RETRY_AFTER", "ROBOT_AUTO", "ROBOT_DISABLED", "ROBOT_TELEOP", "VERSIONS",
           "VERSION_DSLOGPARSER", "VERSION_NI", "WATCHDOG", "console_event", "event_record",
           "file_header", "file_stem", "hms", "lv_stamp", "lv_timestamp", "match_events", "pdp_bytes", "record_size",
           "sample", "unlinked", "write_problem"]
