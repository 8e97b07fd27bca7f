"""Finding and reading the NI log files a log viewer shows: the I/O beside the pure
:mod:`fieldbox.dslog_read`.

A *run* is a ``.dslog`` and its ``.dsevents`` (the same name beside it; either may be missing).
fieldbox writes them in ``ds-TEAM-dslog/`` inside each run's log folder (the user's log
folder by default: ``fieldbox logs`` with no argument lists every run there); the NI Driver
Station writes them, without a team, in ``C:\\Users\\Public\\Documents\\FRC\\Log Files``. Reads
are bounded: a folder is walked a few levels deep and at most :data:`MAX_RUNS` runs are
listed (the newest), a file over :data:`MAX_FILE_BYTES` is refused with a line that says so.
"""

from __future__ import annotations

import os
import re
from dataclasses import dataclass
from pathlib import Path

from .dslog_read import (HEADER_SIZE, RECORD_PERIOD, DsEvents, DsLog, LogFileError, decode_dsevents, decode_dslog,
                         match_name)

#: Bytes of one log file read at most: a DS writes about 7 MB an hour, so this is hours of
#: records; a bigger file is not a Driver Station's log (or not one to open here).
MAX_FILE_BYTES = 64 << 20
#: Runs listed from one folder (the newest), folders walked below it.
MAX_RUNS = 500
MAX_DEPTH = 4
#: Bytes of a .dsevents read to find the match a run was in, when listing.
LIST_EVENT_BYTES = 256 << 10

_TEAM_FOLDER = re.compile(r"^ds-(\d+)-dslog$")


@dataclass(frozen=True, slots=True)
class Run:
    """One pair of files as the list of runs shows it."""

    stem: Path  # the path without its suffix
    has_log: bool
    has_events: bool
    start: float  # Unix time (the header's; the file's modification time if it has none)
    duration: float | None  # seconds of records, None: no .dslog
    team: int | None  # from fieldbox's ds-TEAM-dslog folder; the NI DS does not say
    match: str
    problem: str = ""  # why a file of it cannot be read, or ""

    @property
    def dslog(self) -> Path:
        return self.stem.with_name(self.stem.name + ".dslog")

    @property
    def dsevents(self) -> Path:
        return self.stem.with_name(self.stem.name + ".dsevents")


@dataclass(frozen=True, slots=True)
class LoadedRun:
    run: Run
    log: DsLog | None
    events: DsEvents | None
    problems: tuple[str, ...]  # one line each, for the screen (and stderr)


def read_bounded(path: Path, limit: int = MAX_FILE_BYTES) -> bytes:
    """A file's bytes, or :class:`LogFileError` with a line saying why not."""
    try:
        with open(path, "rb") as f:
            size = os.fstat(f.fileno()).st_size
            if size > limit:
                raise LogFileError(f"{path.name} is {size / 2**20:.0f} MiB, more than the {limit >> 20} MiB "
                                   "a log viewer reads: not a Driver Station log")
            return f.read(limit + 1)[:limit]
    except OSError as exc:
        raise LogFileError(f"cannot read {path}: {exc.strerror or exc}") from None


def team_of(path: Path) -> int | None:
    m = _TEAM_FOLDER.match(path.parent.name)
    return int(m.group(1)) if m else None


def describe(stem: Path) -> Run:
    """A pair of files as the list shows it: reads the .dslog's first record and the start of
    the .dsevents, never the whole of either."""
    log, events = stem.with_name(stem.name + ".dslog"), stem.with_name(stem.name + ".dsevents")
    has_log, has_events = log.is_file(), events.is_file()
    start: float | None = None
    duration: float | None = None
    match, problem = "", ""
    if has_log:
        try:
            with open(log, "rb") as f:
                head = f.read(HEADER_SIZE + 14)
                size = os.fstat(f.fileno()).st_size
            decoded = decode_dslog(head[:HEADER_SIZE])
            start = decoded.start
            record = 35 if decoded.version == 3 else 14 + {25: 25, 33: 33}.get(head[HEADER_SIZE + 13], 0) \
                if len(head) >= HEADER_SIZE + 14 else 39
            duration = (size - HEADER_SIZE) // record * RECORD_PERIOD
        except (OSError, LogFileError) as exc:
            problem = str(exc) if isinstance(exc, LogFileError) else f"cannot read {log.name}: {exc.strerror}"
    if has_events:
        try:
            with open(events, "rb") as f:
                data = f.read(LIST_EVENT_BYTES)
            decoded_events = decode_dsevents(data)
            match = match_name(decoded_events)
            if start is None:
                start = decoded_events.start
        except (OSError, LogFileError) as exc:
            problem = problem or (str(exc) if isinstance(exc, LogFileError) else
                                  f"cannot read {events.name}: {exc.strerror}")
    if start is None:
        try:
            start = (log if has_log else events).stat().st_mtime
        except OSError:
            start = 0.0
    return Run(stem, has_log, has_events, start, duration, team_of(log), match, problem)


def find_runs(folder: Path, limit: int = MAX_RUNS) -> list[Run]:
    """Every run in ``folder`` and the folders below it (a few levels), newest first."""
    stems: dict[Path, float] = {}
    root_depth = len(folder.parts)
    for here, dirs, files in os.walk(folder):
        if len(Path(here).parts) - root_depth >= MAX_DEPTH:
            dirs[:] = []
        dirs.sort()
        for name in files:
            if name.endswith((".dslog", ".dsevents")):
                path = Path(here) / name
                stem = path.with_suffix("")
                try:
                    mtime = path.stat().st_mtime
                except OSError:
                    continue
                stems[stem] = max(stems.get(stem, 0.0), mtime)
    newest = sorted(stems, key=lambda s: stems[s], reverse=True)[:limit]
    runs = [describe(stem) for stem in newest]
    runs.sort(key=lambda r: (r.start, str(r.stem)), reverse=True)
    return runs


def run_for(path: Path) -> Run:
    """The run of a file given by name (either of the pair, or the name without a suffix)."""
    stem = path.with_suffix("") if path.suffix in (".dslog", ".dsevents") else path
    return describe(stem)


def load(run: Run) -> LoadedRun:
    """Both files of a run, decoded; what cannot be read is said in ``problems``, never raised."""
    problems: list[str] = []
    log: DsLog | None = None
    events: DsEvents | None = None
    if run.has_log:
        try:
            log = decode_dslog(read_bounded(run.dslog))
            if log.problem:
                problems.append(f"{run.dslog.name}: {log.problem}")
        except LogFileError as exc:
            problems.append(f"{run.dslog.name}: {exc}")
    if run.has_events:
        try:
            events = decode_dsevents(read_bounded(run.dsevents))
            if events.problem:
                problems.append(f"{run.dsevents.name}: {events.problem}")
        except LogFileError as exc:
            problems.append(f"{run.dsevents.name}: {exc}")
    if not run.has_log and not run.has_events:
        problems.append(f"{run.stem}: no .dslog or .dsevents file of that name")
    return LoadedRun(run, log, events, tuple(problems))


__all__ = ["LoadedRun", "MAX_FILE_BYTES", "Run", "describe", "find_runs", "load", "read_bounded", "run_for",
           "team_of"]
