"""Reading the NI Driver Station's ``.dslog`` and ``.dsevents`` files: bytes in, frozen records out.

Pure: no file is opened here (:mod:`fieldbox.logview_runs` reads the files, bounded in size,
and hands the bytes over), so a test gives it any bytes it likes. A file that is not a log,
or of a version this does not know, raises :class:`LogFileError` with one line that says so;
a file cut short (a DS that lost power mid-write, a copy interrupted) gives every whole record
and says in :attr:`DsLog.problem` how many bytes of a last record were missing.

The layout is the one ``roles/runtime/dslog.py`` writes and docs/dslog.md describes, as
AdvantageScope's ``DSLogReader.ts``/``DSEventsReader.ts``, DSLOG-Reader 2's ``DSLOGReader.cs``
and dslogparser read it (all big-endian):

* header: ``i32`` version (3 or 4), then a LabVIEW time, ``i64`` seconds since 1904-01-01 UTC
  and ``u64`` fraction (/2**64), the time of the first record (a ``.dsevents``: of the file);
* a ``.dslog`` record, one every 20 ms (records carry no time of their own): ``u8`` trip time
  (ms x 2), ``i8`` lost packets (percent / 4; AdvantageScope and DSLOG-Reader read it signed,
  and AdvantageScope clamps it to 0..100 %: so does this), ``u16`` battery (V x 256), ``u8``
  roboRIO CPU (percent x 2), ``u8`` status flags *inverted* (a 0 bit is set; high bit first:
  brownout, watchdog, DS teleop, DS auto, DS disabled, robot teleop, robot auto, robot
  disabled), ``u8`` CAN (percent x 2), ``u8`` Wi-Fi dB (x 2), ``u16`` bandwidth (Mb/s x 256);
* then the power distribution. Version 3: 25 bytes (a CTRE PDP), 35 a record. Version 4:
  4 bytes whose last is the PD type, then 25 bytes for a CTRE PDP (type 25: 39 a record),
  33 for a REV PDH (type 33: 47 a record), nothing for another type (14 a record): as
  AdvantageScope, the type is read record by record (DSLOG-Reader takes the first record's);
* a ``.dsevents`` record: a LabVIEW time, ``i32`` length, that many bytes of UTF-8 text.

What a reader derives (the files do not say it): *enabled* is "the DS disabled bit clear";
the DS sends *test* when it is enabled in neither teleop nor auto; *robot comms* are taken to
be there while the robot reports a mode (without comms a DS has no robot status to log, and
fieldbox's DS, like the NI DS, writes none of the three robot bits then); an *e-stop* is an
event (``E-STOP`` in its text), held from then to the end of the file, as the robot is
e-stopped until it reboots. The power distribution currents are not decoded here: the viewer
does not show them (docs/dslog.md tells why their layout is disputed).
"""

from __future__ import annotations

import re
import struct
from dataclasses import dataclass

#: Seconds from 1904-01-01 (LabVIEW's epoch) to 1970-01-01, both UTC.
LV_EPOCH_OFFSET = 2_082_844_800
RECORD_PERIOD = 0.020
VERSIONS = (3, 4)
HEADER_SIZE = 20
PD_CTRE, PD_REV = 25, 33
#: Bytes of power distribution data after the 4-byte type in a version-4 record, by type.
_PD_BYTES = {PD_CTRE: 25, PD_REV: 33}
#: The most records decoded from one .dslog (two hours, about 100 MB decoded), and events from one
#: .dsevents: past them the rest is left out and said, never a memory exhausted.
MAX_RECORDS = 360_000
MAX_EVENTS = 100_000
#: The longest event text kept (a call stack is a few KiB; a longer length field is a file
#: that is not a .dsevents, or a torn one).
MAX_EVENT_BYTES = 1 << 20

_HEAD = struct.Struct(">iqQ")
_EVENT_HEAD = struct.Struct(">qQi")
_RECORD = struct.Struct(">BbHBBBBH")

# status flag bits (after inversion: set means the state holds)
BROWNOUT, WATCHDOG, DS_TELEOP, DS_AUTO, DS_DISABLED = 0x80, 0x40, 0x20, 0x10, 0x08
ROBOT_TELEOP, ROBOT_AUTO, ROBOT_DISABLED = 0x04, 0x02, 0x01


class LogFileError(ValueError):
    """A file that cannot be read as a log; its text is one line for a person."""


@dataclass(frozen=True, slots=True)
class LogRecord:
    """One 20 ms record, in the units a person reads."""

    t: float  # seconds since the file's first record
    trip_ms: float
    lost: float  # share of packets lost, 0..1
    battery: float  # volts
    cpu: float  # roboRIO CPU, percent
    flags: int  # BROWNOUT | DS_TELEOP | ... (set bits)
    can: float  # CAN utilisation, percent
    wifi_db: float
    bandwidth: float  # Mb/s
    pd_type: int  # 25 CTRE PDP, 33 REV PDH (version 3: always 25)

    @property
    def enabled(self) -> bool:
        return not self.flags & DS_DISABLED

    @property
    def ds_mode(self) -> str:
        """What the DS sent: "disabled", "auto", "teleop" or "test" (enabled in neither)."""
        if not self.enabled:
            return "disabled"
        if self.flags & DS_AUTO:
            return "auto"
        if self.flags & DS_TELEOP:
            return "teleop"
        return "test"

    @property
    def robot_mode(self) -> str | None:
        """What the robot's code said it runs ("disabled", "auto", "teleop"), None: no comms."""
        if self.flags & ROBOT_AUTO:
            return "auto"
        if self.flags & ROBOT_TELEOP:
            return "teleop"
        if self.flags & ROBOT_DISABLED:
            return "disabled"
        return None

    @property
    def comms(self) -> bool:
        return self.robot_mode is not None

    @property
    def brownout(self) -> bool:
        return bool(self.flags & BROWNOUT)

    @property
    def watchdog(self) -> bool:
        return bool(self.flags & WATCHDOG)


@dataclass(frozen=True, slots=True)
class DsLog:
    """A decoded ``.dslog``: its version, the Unix time of its first record, its records, and
    what was wrong at its end (a torn last record, records past :data:`MAX_RECORDS`), if anything."""

    version: int
    start: float
    records: tuple[LogRecord, ...]
    problem: str = ""

    @property
    def duration(self) -> float:
        return len(self.records) * RECORD_PERIOD


@dataclass(frozen=True, slots=True)
class LogEvent:
    """One ``.dsevents`` line: its time (seconds since the file began; may be negative for an
    event stamped before the header), its raw text and the text a person reads."""

    t: float
    raw: str
    text: str
    kind: str  # "estop", "error", "warning", "comms", "mode", "fms", "print", "info"


@dataclass(frozen=True, slots=True)
class DsEvents:
    version: int
    start: float
    events: tuple[LogEvent, ...]
    problem: str = ""


def lv_to_unix(seconds: int, fraction: int) -> float:
    """A LabVIEW time (seconds since 1904-01-01 UTC, fraction / 2**64) as Unix seconds."""
    return seconds - LV_EPOCH_OFFSET + fraction / 2**64


def _header(data: bytes, what: str) -> tuple[int, float]:
    if len(data) < HEADER_SIZE:
        raise LogFileError(f"not a {what} file: {len(data)} bytes, shorter than the {HEADER_SIZE}-byte header")
    version, seconds, fraction = _HEAD.unpack_from(data, 0)
    if version not in VERSIONS:
        if 0 < version < 100:  # a log, of a version from before 2016 or after today
            raise LogFileError(f"a {what} file of version {version}, which this does not read (it reads 3 and 4)")
        raise LogFileError(f"not a {what} file: it does not begin with a version number (3 or 4)")
    start = lv_to_unix(seconds, fraction)
    # 1990 to 2200: a header outside is not a Driver Station's (a text file, a wrong file)
    if not 631_152_000 <= start <= 7_258_118_400:
        raise LogFileError(f"not a {what} file: its header's time is not a date a DS could write")
    return version, start


def _shown(n: int, what: str) -> str:
    """"the 3 whole records before it are shown", in good English for 0 and 1 too."""
    if n == 0:
        return f"no {what} comes before it"
    return f"the {what} before it is shown" if n == 1 else f"the {n} {what}s before it are shown"


def decode_dslog(data: bytes) -> DsLog:
    """Every whole record of a ``.dslog``'s bytes (see the module docstring)."""
    version, start = _header(data, ".dslog")
    records: list[LogRecord] = []
    at, end = HEADER_SIZE, len(data)
    problem = ""
    unpack = _RECORD.unpack_from
    add = records.append
    while at < end:
        if len(records) >= MAX_RECORDS:
            problem = (f"only the first {len(records)} records ({len(records) * RECORD_PERIOD / 3600:.1f} h) "
                       f"are shown: the file goes on for {end - at} bytes more")
            break
        if version == 3:
            size, pd_type = 35, PD_CTRE
        else:
            if end - at < 14:
                size, pd_type = 14, PD_CTRE
            else:
                pd_type = data[at + 13]
                size = 14 + _PD_BYTES.get(pd_type, 0)
        if end - at < size:
            problem = (f"the last record is cut short ({end - at} of its {size} bytes): "
                       f"{_shown(len(records), 'whole record')}")
            break
        trip, lost, battery, cpu, status, can, wifi, bandwidth = unpack(data, at)
        # positional: an hour is 180,000 of these, and keywords cost a third more
        add(LogRecord(len(records) * RECORD_PERIOD, trip / 2, min(max(lost * 4, 0), 100) / 100, battery / 256,
                      cpu / 2, ~status & 0xFF, can / 2, wifi / 2, bandwidth / 256, pd_type))
        at += size
    return DsLog(version, start, tuple(records), problem)


# -- events ----------------------------------------------------------------------------------
_TAG = re.compile(r"<(TagVersion|time|count|flags|Code|details|location|stack|message)>\s?")


def event_text(raw: str) -> tuple[str, str]:
    """(what a person reads, kind) of a ``.dsevents`` line: a robot print's ``<message>``, an
    error's code and details, and other lines as written, on one line."""
    if "<TagVersion>" in raw or "<message>" in raw or "<details>" in raw:
        parts: dict[str, str] = {}
        matches = list(_TAG.finditer(raw))
        for i, m in enumerate(matches):
            stop = matches[i + 1].start() if i + 1 < len(matches) else len(raw)
            parts[m.group(1)] = raw[m.end():stop].strip()
        if "details" in parts:
            error = parts.get("flags", "1").strip() != "0"
            code = parts.get("Code", "0")
            head = ("Error" if error else "Warning") + (f" {code}" if code not in ("", "0") else "")
            where = parts.get("location", "")
            text = f"{head}: {parts['details']}" + (f" ({where})" if where else "")
            return _one_line(text), "error" if error else "warning"
        if "message" in parts:
            return _one_line(parts["message"]), "print"
    text = _one_line(raw)
    if text.startswith("Info "):
        text = text[5:]
    low = text.lower()
    if "e-stop" in low:
        kind = "estop"
    elif low.startswith("fms") or "fms event name" in low:
        kind = "fms"
    elif "comms" in low or "code start" in low or "no robot code" in low:
        kind = "comms"
    elif "enabled" in low or "disabled" in low:
        kind = "mode"
    elif low.startswith("error") or low.startswith("warning"):
        kind = "error" if low.startswith("error") else "warning"
    else:
        kind = "info"
    return text, kind


def _one_line(text: str) -> str:
    return " ".join(text.split())


def decode_dsevents(data: bytes) -> DsEvents:
    """Every whole event of a ``.dsevents``'s bytes, in the file's order."""
    version, start = _header(data, ".dsevents")
    events: list[LogEvent] = []
    at, end = HEADER_SIZE, len(data)
    problem = ""
    while at < end:
        if len(events) >= MAX_EVENTS:
            problem = f"only the first {len(events)} events are shown: the file goes on for {end - at} bytes more"
            break
        if end - at < _EVENT_HEAD.size:
            problem = (f"the last event is cut short ({end - at} bytes of its header): "
                       f"{_shown(len(events), 'whole event')}")
            break
        seconds, fraction, length = _EVENT_HEAD.unpack_from(data, at)
        if not 0 <= length <= MAX_EVENT_BYTES:
            problem = (f"event {len(events) + 1} says it is {length} bytes long, which no event is: "
                       f"{_shown(len(events), 'event')}")
            break
        body = data[at + _EVENT_HEAD.size:at + _EVENT_HEAD.size + length]
        if len(body) < length:
            problem = (f"the last event is cut short ({len(body)} of its {length} bytes of text): "
                       f"{_shown(len(events), 'whole event')}")
            break
        raw = body.decode("utf-8", "replace")
        text, kind = event_text(raw)
        events.append(LogEvent(lv_to_unix(seconds, fraction) - start, raw, text, kind))
        at += _EVENT_HEAD.size + length
    return DsEvents(version, start, tuple(events), problem)


_MATCH = re.compile(r"FMS Connected:\s+(\w+) - (\d+):(\d+)")


def match_name(events: DsEvents | tuple[LogEvent, ...]) -> str:
    """The match a ``.dsevents`` was written in ("Qualification 12", "Practice 3 (replay 2)"),
    from its ``FMS Connected:`` line, or "" (no FMS; "None - 0" is a DS on an FMS with no match)."""
    items = events.events if isinstance(events, DsEvents) else events
    for e in items:
        m = _MATCH.search(e.raw)
        if m:
            kind, number, replay = m.group(1), int(m.group(2)), int(m.group(3))
            if kind == "None" and number == 0:
                return ""
            return f"{kind} {number}" + (f" (replay {replay})" if replay > 1 else "")
    return ""


def estop_at(events: DsEvents | tuple[LogEvent, ...]) -> float | None:
    """When the first e-stop of a file happened (seconds since its start), None: never."""
    items = events.events if isinstance(events, DsEvents) else events
    return next((e.t for e in items if e.kind == "estop"), None)


__all__ = ["BROWNOUT", "DS_AUTO", "DS_DISABLED", "DS_TELEOP", "DsEvents", "DsLog", "LogEvent",
           "LogFileError", "LogRecord", "MAX_EVENTS", "MAX_RECORDS", "RECORD_PERIOD", "ROBOT_AUTO",
           "ROBOT_DISABLED", "ROBOT_TELEOP", "WATCHDOG", "decode_dsevents", "decode_dslog", "estop_at",
           "event_text", "lv_to_unix", "match_name"]
