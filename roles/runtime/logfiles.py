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
"""

from __future__ import annotations

import datetime as _dt
import os
import re
import shutil
import time
from pathlib import Path
from typing import Any, Callable, TextIO

from .dslog import VERSION_NI, VERSIONS, DsNiLog

#: How often :meth:`FieldLog.poll` should run (seconds): a console batch is at most this old.
POLL_PERIOD = 0.1
#: Run folders kept in the log directory (the oldest beyond this are deleted).
KEEP_RUNS = 50
#: Failed writes are reported at once, then at most this often while they go on failing.
REPORT_EVERY = 10.0
_RUN_NAME = re.compile(r"^\d{8}-\d{6}-\d+$")


def default_log_dir() -> Path:
    """``platformdirs.user_log_dir("fieldbox")`` (e.g. ``~/.local/state/fieldbox/log``)."""
    import platformdirs

    return Path(platformdirs.user_log_dir("fieldbox"))


class _ConsoleWatch:
    """New lines of one console deque since the last look."""

    def __init__(self, name: str, core: Any, attr: str, total_attr: str | None) -> None:
        self.name = name
        self.core = core
        self.attr = attr
        self.total_attr = total_attr
        lines = getattr(core, attr)
        # what the deque holds already counts as new: a log attached late still gets it
        self.seen_total = getattr(core, total_attr) - len(lines) if total_attr else 0
        self.last = None  # identity marker of the newest entry seen, for a deque without a counter

    def new_lines(self) -> tuple[list, int]:
        """(new entries, entries missed because the deque turned over before we looked)."""
        lines = getattr(self.core, self.attr)
        if self.total_attr:
            total = getattr(self.core, self.total_attr)
            new = total - self.seen_total
            self.seen_total = total
            if new <= 0:
                return [], 0
            take = min(new, len(lines))
            return list(lines)[-take:], new - take
        if not lines or lines[-1] is self.last:
            return [], 0
        out = []
        for entry in reversed(lines):
            if entry is self.last:
                break
            out.append(entry)
        missed = 0
        if self.last is not None and len(out) == len(lines) and len(lines) == lines.maxlen:
            missed = 1  # the marker fell out of a full deque: some went unseen (at least one)
        self.last = lines[-1]
        out.reverse()
        return out, missed


class FieldLog:
    """Log files for one field. ``attach()`` (on the wire's side, after the field started),
    then ``poll()`` every :data:`POLL_PERIOD`, ``close()`` at the end.

    Plain attributes: ``folder`` (this run's folder), ``paths`` (file name -> path),
    ``lines_written``, ``missed`` (console lines a deque dropped before a poll saw them),
    ``errors`` (writes that failed), ``last_error``, ``ni_logs`` (team -> the DS's NI-format
    log, :class:`~roles.runtime.dslog.DsNiLog`, whose ``paths`` are its newest files).
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

    # -- set-up --------------------------------------------------------------------------
    def attach(self) -> "FieldLog":
        """Start watching the field's cores (call where the cores run: the wire's thread)."""
        if self._attached:
            return self
        self._attached = True
        field = self.field
        for st in getattr(field, "stations", ()):
            if st.ds is not None:
                self._watches.append(_ConsoleWatch(f"ds-{st.team}-console.log", st.ds, "console", "console_total"))
                self._listen(st.ds, f"ds-{st.team}-events.log")
                self._attach_ni(st.team, st.ds)
            if st.rio is not None:
                if st.ds is None:  # no DS here shows this robot's console: keep the robot's own
                    self._watches.append(_ConsoleWatch(f"rio-{st.team}-console.log", st.rio, "console", None))
                self._listen(st.rio, f"rio-{st.team}-events.log")
        fms = getattr(field, "fms", None)
        if fms is not None:  # its match log keeps the last 10 000 entries (its events the last 500)
            backlog = getattr(fms, "match_log", None)
            missed = getattr(fms, "match_log_total", 0) - len(backlog) if backlog is not None else 0
            if missed > 0:
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
                     on_error=self._error)
        self.ni_logs[team] = ni
        self._ni_watches.append((ni, _ConsoleWatch(f"ds-{team}-dslog", ds, "console", "console_total")))

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

    def take_problem(self) -> str | None:
        """What to tell a person about writes that failed since the last report (None: nothing
        new, or the last report was less than :data:`REPORT_EVERY` seconds ago)."""
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
                if problem is not None:
                    on_problem(problem)
                handle = loop.call_later(POLL_PERIOD, tick)
                self._cancel = handle.cancel
            tick()
        runtime.call(begin).result(timeout=5)

    # -- the work ----------------------------------------------------------------------------
    def poll(self) -> int:
        """Copy new console lines to their files and flush; returns how many were written."""
        if self._closed:
            return 0
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

    def close(self) -> None:
        """Write what is left, stop listening, close the files."""
        if self._closed:
            return
        self.poll()
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
        if name in self._files or self._closed:
            return
        path = self.folder / name
        try:
            self._files[name] = open(path, "a", encoding="utf-8", errors="replace")
        except OSError as exc:
            self._error(exc)
            return
        self.paths[name] = path

    def _line(self, name: str, t: float | None, level: str, text: str) -> None:
        f = self._files.get(name)
        if f is None:
            return
        stamp = self._stamp(t)
        text = str(text).rstrip("\r\n").replace("\r\n", "\n").replace("\r", "\n")
        body = text.replace("\n", "\n    ")  # a call stack's lines stay with their error
        try:
            f.write(f"{stamp} {level + ' ' if level else ''}{body}\n")
        except (OSError, ValueError) as exc:
            self._error(exc)
            return
        self.lines_written += 1

    def _flush(self, name: str) -> None:
        f = self._files.get(name)
        if f is None:
            return
        try:
            f.flush()
        except (OSError, ValueError) as exc:
            self._error(exc)

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


def _prune(base: Path, keep: int, current: Path) -> None:
    """Delete the oldest run folders beyond ``keep`` (only folders this module names)."""
    try:
        runs = sorted(p for p in base.iterdir() if p.is_dir() and _RUN_NAME.match(p.name) and p != current)
    except OSError:
        return
    for old in runs[:max(0, len(runs) - (keep - 1))]:
        shutil.rmtree(old, ignore_errors=True)


__all__ = ["FieldLog", "KEEP_RUNS", "POLL_PERIOD", "default_log_dir"]
