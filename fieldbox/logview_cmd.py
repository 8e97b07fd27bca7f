"""``fieldbox logs [FOLDER|FILE]``: the NI log files of a folder or one run, in the log viewer
(fieldbox/logview.py), or printed (``--print``). A file that cannot be read is one line on
stderr and exit status 1, never a traceback; a run with a torn end opens, and says so."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import TextIO

from .dslog_read import RECORD_PERIOD
from .logview_runs import LoadedRun, Run, find_runs, load, run_for


def add_parser(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    logs = sub.add_parser(
        "logs", help="the NI Driver Station log files (.dslog/.dsevents): pick a run, see its charts and events",
        description="Open the .dslog/.dsevents files fieldbox's Driver Stations wrote (in ds-TEAM-dslog/ of each "
                    "run's log folder) or a real NI Driver Station's, version 3 or 4: a list of runs, newest first, "
                    "then a run's battery, trip time, lost packets, CPU, modes and events on one time axis.")
    logs.add_argument("path", metavar="FOLDER|FILE", nargs="?", default=None,
                      help="a folder to list runs from (default: fieldbox's log folder, every run in it), or "
                           "one .dslog or .dsevents file")
    logs.add_argument("--print", action="store_true", dest="print_only",
                      help="print the runs (a folder) or the run's summary and events (a file) instead of "
                           "opening the viewer")


def _err(line: str) -> None:
    print(f"fieldbox logs: {line}", file=sys.stderr)


def _run_line(run: Run) -> str:
    from .logview import length_text, when_text

    parts = [when_text(run.start), length_text(run.duration),
             "team —" if run.team is None else f"team {run.team}", run.match or "no match", str(run.stem)]
    if run.problem:
        parts.append(f"⚠ {run.problem}")
    return "  ".join(parts)


def print_run(loaded: LoadedRun, out: TextIO) -> None:
    from .logview import Timeline, clock

    print(_run_line(loaded.run), file=out)
    log = loaded.log
    if log is not None and log.records:
        rec = log.records
        volts = [r.battery for r in rec if r.comms]
        print(f"version {log.version}, {len(rec)} records ({len(rec) * RECORD_PERIOD:.1f} s)"
              + (f", battery {min(volts):.2f}-{max(volts):.2f} V" if volts else ", no robot comms")
              + f", trip time up to {max(r.trip_ms for r in rec):.1f} ms"
              + f", lost packets up to {max(r.lost for r in rec) * 100:.0f} %"
              + f", brownout {sum(r.brownout for r in rec) * RECORD_PERIOD:.1f} s", file=out)
    tl = Timeline(loaded)
    for t, e in zip(tl.event_times, tl.events):
        print(f"{clock(t):>9}  {e.text}", file=out)


def run_logs(path: str | None, print_only: bool = False, theme: str | None = None) -> int:
    if path is None:
        from roles.runtime.logfiles import default_log_dir

        target = default_log_dir()
    else:
        target = Path(path).expanduser()
    if target.is_dir():
        runs = find_runs(target)
        if not runs:
            _err(f"no .dslog or .dsevents files in {target} (fieldbox writes them in ds-TEAM-dslog/ inside each "
                 "run's log folder)")
            return 1
        if print_only:
            for run in runs:
                print(_run_line(run))
            return 0
        from .logview import LogViewerApp

        LogViewerApp(folder=target, runs=runs, theme_name=theme).run()
        return 0
    run = run_for(target)
    if not run.has_log and not run.has_events:
        _err(f"no such file or folder: {target}")
        return 1
    loaded = load(run)
    for problem in loaded.problems:
        _err(problem)
    if loaded.log is None and loaded.events is None:
        return 1
    if print_only:
        print_run(loaded, sys.stdout)
        return 0
    from .logview import LogViewerApp

    LogViewerApp(loaded=loaded, theme_name=theme).run()
    return 0


__all__ = ["add_parser", "print_run", "run_logs"]
