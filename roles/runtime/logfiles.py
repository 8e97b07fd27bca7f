"""Nothing lost: a field's console lines, errors and match events, written to files as they
arrive, so they survive a crash or a ``kill -9``.

:class:`FieldLog` watches a running :class:`~roles.runtime.field.Field` and appends, with a
wall-clock timestamp, to one folder per run (``<log dir>/<YYYYmmdd-HHMMSS>-<pid>/``):

* ``ds-TEAM-console.log``: what each Driver Station's console received (robot stdout,
  warnings and errors, radio events; NetConsole in 2010 mode);
* ``ds-TEAM-events.log``, ``rio-TEAM-events.log``: each core's events (comms lost, e-stop...);
* ``rio-TEAM-console.log``: a fake roboRIO's own console, where no DS of this field shows it;
* ``fms-match.log``: the FMS's match events (logins, phases, e-stops, refusals...);
* ``ds-TEAM-dslog/YYYY_MM_DD HH_MM_SS Ddd.dslog`` and ``.dsevents``: each DS's run in the NI
  Driver Station's own format (trip time, lost packets, battery, CPU, CAN, modes, PD
  currents; events, match info and console), for AdvantageScope and DSLOG-Reader
  (roles/runtime/dslog.py). Version 4, as the NI DS writes now, or 3 (``dslog_version``) for readers
  of the older layout such as dslogparser.

Events are written and flushed the moment a core adds them (its ``Events`` listeners).
Console lines, which the cores keep in bounded deques, are copied by :meth:`FieldLog.poll`:
call it every 100 ms or so **on the wire's side** (the thread or loop the cores run on), so a
batch is at most that old when flushed. Writes go to the OS at once (``flush``), so a killed
process loses nothing it flushed; a full disk is counted in ``errors``, never raised into a
core, and :meth:`FieldLog.take_problem` gives the sentence a person must see (the app's
notification, a line on headless stderr), at most every :data:`REPORT_EVERY` seconds: the
run goes on, and nobody believes logs that are not there. No UI, no asyncio: the caller
schedules it (see :meth:`FieldLog.start_on` for a :class:`~roles.runtime.shell.Runtime`).

Once every :data:`CHECK_EVERY` seconds :meth:`FieldLog.poll` also looks whether the files are
still there (an ``fstat`` of each open file, a ``stat`` of the folder: a few microseconds).
A file deleted under us still takes writes, into nothing: so a deleted run folder (or a file
in it) is said (:meth:`FieldLog.take_problem`, and the first line of each file from then on)
and the run writes on in a new folder beside it, named as the first with a ``-N`` suffix
(never in the old one, which the person deleting it may still be emptying), with a fresh
``.dslog`` pair (its header). A file whose write failed (a full disk) is closed and tried again at each check; the lines meant
for it meanwhile are counted, and the first line it gets when writing works again says how
many were lost and when ("12 lines lost from 14:02:11 to 14:02:19: disk full").
"""

from __future__ import annotations

import datetime as _dt
import errno
import functools
import logging
import os
import re
import shutil
import time
from collections import deque
from pathlib import Path
from typing import Any, Callable, TextIO

from ..cores.core import Stream
from .dslog import VERSION_NI, VERSIONS, DsNiLog, hms, unlinked, write_problem

log = logging.getLogger("fieldbox.logfiles")

#: How often :meth:`FieldLog.poll` should run (seconds): a console batch is at most this old.
POLL_PERIOD = 0.1
#: Run folders kept in the log directory (the oldest beyond this are deleted).
KEEP_RUNS = 50
#: Failed writes are reported at once, then at most this often while they go on failing.
REPORT_EVERY = 10.0
#: Seconds between two looks at whether the files are still there (and between two tries of a
#: file whose write failed).
CHECK_EVERY = 1.0
# a run folder: stamp and pid, and "-N" for the folder a run writes on in after its first was
# deleted
_RUN_NAME = re.compile(r"^\d{8}-\d{6}-\d+(-\d+)?$")


class _Outage:
    """Lines meant for a file while its writes failed: how many, since when, why."""

    __slots__ = ("since", "lines", "why")

    def __init__(self, since: float, why: str) -> None:
        self.since, self.lines, self.why = since, 0, why


def default_log_dir() -> Path:
    """``platformdirs.user_log_dir("fieldbox")`` (e.g. ``~/.local/state/fieldbox/log``)."""
    import platformdirs

    return Path(platformdirs.user_log_dir("fieldbox"))


class _ConsoleWatch:
    """New lines of one console stream (roles/cores/core.py Stream) since the last look."""

    def __init__(self, name: str, stream: Stream[Any]) -> None:
        self.name = name
        self.stream = stream
        # what the stream holds already counts as new: a log attached late still gets it
        self.seen_total = stream.total - len(stream)

    def new_lines(self) -> tuple[list, int]:
        """(new entries, entries missed because the stream turned over before we looked)."""
        view = self.stream.view()
        new, missed = view.since(self.seen_total), max(0, view.first_seq - self.seen_total)
        self.seen_total = view.end
        return list(new), missed


class FieldLog:
    """Log files for one field. ``attach()`` (on the wire's side, after the field started),
    then ``poll()`` every :data:`POLL_PERIOD`, ``close()`` at the end.

    Plain attributes: ``folder`` (this run's folder), ``paths`` (file name -> path),
    ``lines_written``, ``missed`` (console lines a deque dropped before a poll saw them),
    ``errors`` (writes that failed), ``last_error``, ``ni_logs`` (team -> the DS's NI-format
    log, :class:`~roles.runtime.dslog.DsNiLog`, whose ``paths`` are its newest files),
    ``moves`` (times the folder was deleted and the run went on in a new one).
    ``dslog_version`` (3 or 4) defaults to the field config's, else 4.
    """

    def __init__(self, field: Any, log_dir: str | os.PathLike | None = None, *,
                 wall_clock: Callable[[], float] = time.time, run_folder: bool = True,
                 keep_runs: int = KEEP_RUNS, dslog_version: int | None = None) -> None:
        self.field = field
        if dslog_version is None:
            dslog_version = getattr(getattr(field, "config", None), "dslog_version", None) or VERSION_NI
        if dslog_version not in VERSIONS:
            raise ValueError(f"a .dslog version fieldbox writes: {VERSIONS}, not {dslog_version!r}")
        self.dslog_version = dslog_version
        self.wall_clock = wall_clock
        base = Path(log_dir) if log_dir is not None else default_log_dir()
        self.run_folder = run_folder
        if run_folder:
            stamp = _dt.datetime.fromtimestamp(wall_clock()).strftime("%Y%m%d-%H%M%S")
            self.folder = base / f"{stamp}-{os.getpid()}"
        else:
            self.folder = base
        self.folder.mkdir(parents=True, exist_ok=True)  # OSError: the caller says why
        if run_folder:
            _prune(base, keep_runs, self.folder)
        self.paths: dict[str, Path] = {}
        self.lines_written = 0
        self.missed = 0
        self.errors = 0
        self.last_error = ""
        self._files: dict[str, TextIO] = {}
        self._watches: list[_ConsoleWatch] = []
        self.ni_logs: dict[int, DsNiLog] = {}
        self._ni_watches: list[tuple[DsNiLog, _ConsoleWatch]] = []
        self._listeners: list[tuple[Any, Callable]] = []
        self._attached = False
        self._closed = False
        self._cancel: Callable[[], Any] | None = None
        self._reported = 0  # errors already reported by take_problem
        self._reported_at = float("-inf")
        self.moves = 0
        self._folder_id = _identity(self.folder)
        self._failing: dict[str, _Outage] = {}  # files whose writes failed, closed till the next check
        self._unflushed: dict[str, int] = {}  # lines written to a file since its last flush
        self._notices: deque[str] = deque(maxlen=20)  # what take_problem says before the errors
        self._cant_move_said = False
        self._check_at = time.monotonic() + CHECK_EVERY

    # -- set-up --------------------------------------------------------------------------
    def attach(self) -> "FieldLog":
        """Start watching the field's cores (call where the cores run: the wire's thread)."""
        if self._attached:
            return self
        self._attached = True
        field = self.field
        for st in getattr(field, "stations", ()):
            if st.ds is not None:
                self._watches.append(_ConsoleWatch(f"ds-{st.team}-console.log", st.ds.tcp.console))
                self._listen(st.ds, f"ds-{st.team}-events.log")
                self._attach_ni(st.team, st.ds)
            if st.rio is not None:
                if st.ds is None:  # no DS here shows this robot's console: keep the robot's own
                    self._watches.append(_ConsoleWatch(f"rio-{st.team}-console.log", st.rio.tcp.console))
                self._listen(st.rio, f"rio-{st.team}-events.log")
        fms = getattr(field, "fms", None)
        if fms is not None:  # its match log keeps the last 10 000 entries (its events the last 500)
            backlog = getattr(fms, "match_log", None)
            missed = getattr(fms, "match_log_total", 0) - len(backlog) if backlog is not None else 0
            if missed > 0 and backlog is not None:  # (missed > 0: there is a backlog)
                self._open("fms-match.log")
                self._line("fms-match.log", None, "fieldbox", f"{missed} earlier match log entries not "
                                                               "logged: the FMS keeps the last "
                                                               f"{len(backlog)}")
            self._listen(fms, "fms-match.log", backlog)
        self.poll()  # console lines that arrived before the attach
        return self

    def _listen(self, core: Any, name: str, backlog: Any = None) -> None:
        """Write what ``core.events`` (or ``backlog``) already holds, then each new event."""
        events = getattr(core, "events", None)
        if events is None:
            return
        self._open(name)
        for t, text in list(backlog if backlog is not None else events.items):
            self._line(name, t, "", text)
        self._flush(name)

        def on_event(t: float, text: str, name=name) -> None:
            if not self._closed:
                self._line(name, t, "", text)
                self._flush(name)
        events.listeners.append(on_event)
        self._listeners.append((events, on_event))

    def _attach_ni(self, team: int, ds: Any) -> None:
        """The DS's .dslog/.dsevents (roles/runtime/dslog.py): fed by its events as they fire, its
        console and its 20 ms records on each poll."""
        events = getattr(ds, "events", None)
        if events is None or getattr(self.field, "clock", None) is None or team in self.ni_logs:
            return
        ni = DsNiLog(ds, self.folder / f"ds-{team}-dslog", self._to_unix, version=self.dslog_version,
                     on_error=self._error, on_lost=functools.partial(self._said_lost, team))
        self.ni_logs[team] = ni
        self._ni_watches.append((ni, _ConsoleWatch(f"ds-{team}-dslog", ds.tcp.console)))

        def on_event(t: float, text: str, ni=ni) -> None:
            if not self._closed:
                ni.event(t, text)
        events.listeners.append(on_event)
        self._listeners.append((events, on_event))

    def _poll_ni(self) -> None:
        if not self._ni_watches:
            return
        try:
            now = self.field.clock()
        except Exception as exc:  # noqa: BLE001 - a clock is never worth a crash
            self._error(exc)
            return
        for ni, watch in self._ni_watches:
            try:
                entries, _ = watch.new_lines()  # a dropped line is said in the console log already
                ni.console(entries, now)
                ni.catch_up(now)
                ni.flush()
            except RuntimeError:  # mutated while we looked: the caller is on the wrong thread
                continue
            except Exception as exc:  # noqa: BLE001 - never raised into the wire's loop
                self._error(exc)

    def _to_unix(self, t: float) -> float:
        """The wall-clock time of core time ``t``, in seconds since 1970."""
        wall = self.wall_clock()
        try:
            return wall - max(0.0, self.field.clock() - t)
        except Exception:  # noqa: BLE001
            return wall

    def _said_lost(self, team: int, text: str) -> None:
        """A DS's NI log writes again after failed writes: its console log says what was lost."""
        name = f"ds-{team}-console.log"
        self._open(name)
        self._line(name, None, "fieldbox", text)
        self._flush(name)
        self._notice(f"log files in {self.folder}: the NI log of DS {team} writes again; {text}")

    def _core_now(self) -> float:
        try:
            return self.field.clock()
        except Exception:  # noqa: BLE001 - a clock is never worth a crash
            return 0.0

    def _notice(self, text: str) -> None:
        log.info("%s", text)  # the fieldbox log keeps it; a person sees it by take_problem
        self._notices.append(text)

    def take_problem(self) -> str | None:
        """What to tell a person: a folder deleted, files writing again (each at once), or
        writes that failed since the last report (None: nothing new, or the last report was
        less than :data:`REPORT_EVERY` seconds ago)."""
        if self._notices:
            return self._notices.popleft()
        new = self.errors - self._reported
        now = time.monotonic()
        if new <= 0 or (self._reported and now - self._reported_at < REPORT_EVERY):
            return None
        self._reported, self._reported_at = self.errors, now
        writes = "a write" if new == 1 else f"{new} writes"
        return (f"log files in {self.folder}: {writes} failed ({self.last_error}); the field runs on, "
                "but its logs miss what could not be written")

    def start_on(self, runtime: Any, on_problem: Callable[[str], Any] | None = None) -> None:
        """Attach and poll every :data:`POLL_PERIOD` on a :class:`~roles.runtime.shell.Runtime`'s loop
        (from any thread; returns once attached); ``on_problem`` gets :meth:`take_problem`'s
        sentences."""
        def begin() -> None:
            self.attach()
            loop = runtime.loop

            def tick() -> None:
                if self._closed:
                    return
                self.poll()
                problem = self.take_problem() if on_problem is not None else None
                if problem is not None and on_problem is not None:
                    on_problem(problem)
                handle = loop.call_later(POLL_PERIOD, tick)
                self._cancel = handle.cancel
            tick()
        runtime.call(begin).result(timeout=5)

    # -- the work ----------------------------------------------------------------------------
    def poll(self) -> int:
        """Copy new console lines to their files and flush; returns how many were written.
        Every :data:`CHECK_EVERY` seconds, :meth:`check` first."""
        if self._closed:
            return 0
        if time.monotonic() >= self._check_at:
            self.check()
        written = 0
        for watch in self._watches:
            try:
                entries, missed = watch.new_lines()
            except RuntimeError:  # mutated while we looked: the caller is on the wrong thread
                continue
            if missed:
                self.missed += missed
                self._open(watch.name)
                self._line(watch.name, None, "fieldbox", f"{missed} console line(s) not logged: "
                                                          "the console overflowed between two polls")
            if not entries:
                continue
            self._open(watch.name)
            for entry in entries:
                t, level, text = _console_entry(entry)
                self._line(watch.name, t, level, text)
                written += 1
            self._flush(watch.name)
        self._poll_ni()
        return written

    def check(self) -> None:
        """Whether the files are still there, and whether the failed ones write again. A folder
        or file deleted: said, and the run goes on in a new folder. Cheap (an ``fstat`` per
        open file, a ``stat`` of the folder): :meth:`poll` runs it every :data:`CHECK_EVERY`
        seconds on the wire's side."""
        self._check_at = time.monotonic() + CHECK_EVERY
        if self._closed:
            return
        if self._gone():
            self._move_on()
        recovered = []
        for name in list(self._failing):
            text = self._reopen(name)
            if text is not None:
                recovered.append(f"{name}: {text}")
        if recovered:
            self._notice(f"log files in {self.folder} write again; " + "; ".join(recovered))

    def _gone(self) -> bool:
        """The folder deleted (or another put in its place), or one of the open files."""
        try:
            st = os.stat(self.folder)
        except FileNotFoundError:
            return True
        except OSError:  # cannot look (a permission): the writes say what is wrong
            return False
        if self._folder_id is not None and (st.st_dev, st.st_ino) != self._folder_id:
            return True
        return any(unlinked(f) for f in self._files.values()) or any(ni.deleted() for ni in self.ni_logs.values())

    def _move_on(self) -> None:
        """The folder (or a file in it) was deleted: what was written to it since the last check
        is gone with it. Say so, and go on in a new folder named as the first (a ``-N``
        suffix), each file starting with that sentence, each DS with a new NI pair."""
        old, wall = self.folder, self.wall_clock()
        try:
            new = self._new_folder(wall)
        except OSError as exc:
            self._error(exc)
            for name in list(self._files):  # they write into nothing: counted as lost from now
                self._fail(name, exc)
            if not self._cant_move_said:
                self._cant_move_said = True
                self._notice(f"log files: {old} was deleted, and no new folder can be made "
                             f"({write_problem(exc)}): the field runs on, its logs are lost until one can")
            return
        self._cant_move_said = False
        self.folder, self._folder_id = new, _identity(new)
        self.moves += 1
        note = (f"the log folder {old} or a file in it was deleted (noticed at {hms(wall)}; what was written "
                f"there in the {CHECK_EVERY:g} s before is gone with it): the logs go on in {new}")
        for name in list(self.paths):  # every file this run has written
            f = self._files.pop(name, None)
            self._unflushed.pop(name, None)
            if f is not None:
                try:
                    f.close()
                except (OSError, ValueError):
                    pass
            if name not in self._failing:
                self._open(name)
            self._line(name, None, "fieldbox", note)
            self._flush(name)
        now = self._core_now()
        for team, ni in self.ni_logs.items():
            try:
                ni.relocate(new / f"ds-{team}-dslog", now, note)
            except Exception as exc:  # noqa: BLE001 - never raised into the wire's loop
                self._error(exc)
        self._notice(f"log files: {note}")

    def _new_folder(self, wall: float) -> Path:
        if not self.run_folder:  # the caller's own folder: made again where it was
            self.folder.mkdir(parents=True, exist_ok=True)
            return self.folder
        stamp = _dt.datetime.fromtimestamp(wall).strftime("%Y%m%d-%H%M%S")
        for n in range(2, 1000):
            path = self.folder.parent / f"{stamp}-{os.getpid()}-{n}"
            try:
                path.mkdir(parents=True)
            except FileExistsError:
                continue
            return path
        raise FileExistsError(errno.EEXIST, "no free folder name", str(self.folder.parent))

    def close(self) -> None:
        """Write what is left, stop listening, close the files."""
        if self._closed:
            return
        self.poll()
        if self._failing:
            self.check()  # lines lost to a disk that has room again are said before the end
        for ni in self.ni_logs.values():
            try:
                ni.close(self.field.clock())
            except Exception as exc:  # noqa: BLE001 - what is left is written, or counted
                self._error(exc)
        self._closed = True
        if self._cancel is not None:
            self._cancel()
        for events, listener in self._listeners:
            if listener in events.listeners:
                events.listeners.remove(listener)
        self._listeners.clear()
        for f in self._files.values():
            try:
                f.close()
            except OSError:
                pass
        self._files.clear()

    # -- files -------------------------------------------------------------------------------
    def _open(self, name: str) -> None:
        """Open a file to append to (a file whose writes failed waits for :meth:`check`)."""
        if name in self._files or name in self._failing or self._closed:
            return
        path = self.folder / name
        self.paths[name] = path
        try:
            self._files[name] = open(path, "a", encoding="utf-8", errors="replace")
        except OSError as exc:
            self._fail(name, exc)
            return
        self._unflushed[name] = 0

    def _reopen(self, name: str) -> str | None:
        """Try a file whose writes failed again: its first line says what was lost (returned;
        None while it still fails)."""
        outage = self._failing.pop(name)
        path = self.folder / name
        wall = self.wall_clock()
        lost = outage.lines
        text = f"{lost} line{'' if lost == 1 else 's'} lost from {hms(outage.since)} to {hms(wall)}: {outage.why}"
        try:
            torn = _ends_mid_line(path)
            f = open(path, "a", encoding="utf-8", errors="replace")
        except OSError as exc:
            self._failing[name] = outage
            self._error(exc)
            return None
        self._files[name], self.paths[name], self._unflushed[name] = f, path, 0
        try:  # a line torn by the failure is ended first, so this one stands on its own
            f.write(f"{chr(10) if torn else ''}{self._stamp(None)} fieldbox {text}\n")
            f.flush()
        except (OSError, ValueError) as exc:
            self._failing[name] = outage
            self._fail(name, exc)
            return None
        self.lines_written += 1
        return text

    def _line(self, name: str, t: float | None, level: str, text: str) -> None:
        f = self._files.get(name)
        if f is None:
            outage = self._failing.get(name)
            if outage is not None:  # said once the file writes again
                outage.lines += 1
            return
        stamp = self._stamp(t)
        text = str(text).rstrip("\r\n").replace("\r\n", "\n").replace("\r", "\n")
        body = text.replace("\n", "\n    ")  # a call stack's lines stay with their error
        try:
            f.write(f"{stamp} {level + ' ' if level else ''}{body}\n")
        except (OSError, ValueError) as exc:
            self._fail(name, exc, 1)
            return
        self._unflushed[name] = self._unflushed.get(name, 0) + 1
        self.lines_written += 1

    def _flush(self, name: str) -> None:
        f = self._files.get(name)
        if f is None:
            return
        try:
            f.flush()
        except (OSError, ValueError) as exc:
            self._fail(name, exc)
            return
        self._unflushed[name] = 0

    def _fail(self, name: str, exc: Exception, lines: int = 0) -> None:
        """A write, flush or open of ``name`` failed: counted; the file is closed (what it had
        not flushed is lost: counted too) and tried again at the next :meth:`check`."""
        self._error(exc)
        unflushed = self._unflushed.pop(name, 0)
        self.lines_written -= unflushed
        outage = self._failing.get(name)
        if outage is None:
            outage = self._failing[name] = _Outage(self.wall_clock(), write_problem(exc))
        outage.lines += lines + unflushed
        f = self._files.pop(name, None)
        if f is not None:
            try:
                f.close()  # its buffer cannot be written either: dropped with the descriptor
            except (OSError, ValueError):
                pass

    def _error(self, exc: Exception) -> None:
        self.errors += 1
        self.last_error = str(exc)

    def _stamp(self, t: float | None) -> str:
        """The wall-clock time of core time ``t`` (the field's clock), to the millisecond."""
        wall = self.wall_clock()
        clock = getattr(self.field, "clock", None)
        if t is not None and clock is not None:
            try:
                wall -= max(0.0, clock() - t)
            except Exception:  # noqa: BLE001 - a stamp is never worth a crash
                pass
        return _dt.datetime.fromtimestamp(wall).isoformat(sep=" ", timespec="milliseconds")


def _console_entry(entry: Any) -> tuple[float | None, str, str]:
    """(time, level, text) of a DS console tuple or a roboRIO ConsoleLine."""
    if isinstance(entry, tuple) and len(entry) == 3:
        return entry[0], str(entry[1]), str(entry[2])
    return getattr(entry, "time", None), str(getattr(entry, "kind", "")), str(getattr(entry, "text", entry))


def _identity(folder: Path) -> tuple[int, int] | None:
    try:
        st = os.stat(folder)
    except OSError:
        return None
    return st.st_dev, st.st_ino


def _ends_mid_line(path: Path) -> bool:
    """Whether a file's last byte is not a newline (a write cut off by a full disk)."""
    try:
        with open(path, "rb") as f:
            f.seek(0, os.SEEK_END)
            if f.tell() == 0:
                return False
            f.seek(-1, os.SEEK_END)
            return f.read(1) != b"\n"
    except FileNotFoundError:
        return False


def _prune(base: Path, keep: int, current: Path) -> None:
    """Delete the oldest run folders beyond ``keep`` (only folders this module names)."""
    try:
        runs = sorted(p for p in base.iterdir() if p.is_dir() and _RUN_NAME.match(p.name) and p != current)
    except OSError:
        return
    for old in runs[:max(0, len(runs) - (keep - 1))]:
        shutil.rmtree(old, ignore_errors=True)


__all__ = ["CHECK_EVERY", "FieldLog", "KEEP_RUNS", "POLL_PERIOD", "default_log_dir"]
