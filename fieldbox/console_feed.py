"""The robot console as the Console panel reads it: new lines only, never a rebuild.

The panel reads the Driver Station core's
``console`` deque of ``(time, level, text)`` (what crossed the wire from the robot), or, where
no DS runs, the fake roboRIO's own ``console`` of :class:`~roles.cores.rio.ConsoleLine`. Those are
plain attributes written by the wire's thread; :class:`ConsoleFollower` copies out only the
lines that are new since it last looked, without locking anything:

* ``console_total`` (lines ever added) is the cheap "anything new?" check;
* the lines themselves are found by identity: the follower remembers the last entry it took
  and takes everything after it. Copying the deque is one C call (``list(islice(reversed(d),
  n))``), so it never sees the deque half-changed, and a line appended between reading the
  total and copying is neither lost nor taken twice.

The console is saved to files as it arrives by :class:`roles.runtime.logfiles.FieldLog` (with the
events and the match log), for the app and headless mode alike.
"""

from __future__ import annotations

import functools
import itertools
from collections import deque
from dataclasses import dataclass
from typing import Any, Callable

#: Levels as they appear in the file and on screen ("radio" is the roboRIO's radio events).
LEVELS = ("stdout", "warning", "error", "radio")


@dataclass(frozen=True, slots=True)
class ConsoleEntry:
    """One console line, whichever core it came from."""

    time: float   # the engine's clock
    team: int
    level: str    # stdout / warning / error / radio
    text: str


def _level_of(kind: str) -> str:
    return kind if kind in LEVELS else "stdout"


class ConsoleFollower:
    """New console lines of one core since the last call (see the module docstring)."""

    __slots__ = ("core", "team", "_last", "_total", "missed")

    def __init__(self, core: Callable[[], Any], team: int) -> None:
        self.core = core       # the DS's or roboRIO's view (or core) now: a new view comes every few beats
        self.team = team
        self._last: Any = None  # the last raw entry taken (compared by identity)
        self._total: int | None = None
        self.missed = 0         # lines that scrolled out of the core's deque before we looked

    @property
    def source(self) -> Any:
        return self.core()

    def _console(self) -> deque:
        return self.source.console

    def new_entries(self) -> list[ConsoleEntry]:
        src = self.source
        total = getattr(src, "console_total", None)
        if total is not None and total == self._total:
            return []
        console = self._console()
        fresh: list[Any] | None = None
        if total is not None and self._total is not None and self._last is not None:
            # Usually only a few lines are new: copy those (plus a little, since a line may be
            # in the deque before the counter moves) and find our marker among them.
            fresh = _after(list(itertools.islice(reversed(console), total - self._total + 2)), self._last)
        if fresh is None:
            fresh = _after(list(reversed(console)), self._last)
        if fresh is None and total is not None and self._total is not None and self._last is not None:
            # Our marker is not there: it scrolled out before we looked, or the source is a
            # view from another process whose stream was sent whole again (roles/runtime/viewwire.py),
            # every entry a new object. A view's counter and stream agree: the counter says how
            # many are new.
            new = total - self._total
            fresh = list(itertools.islice(reversed(console), max(0, new)))
            self.missed += max(0, new - len(fresh))
        if fresh is None:
            # Our marker scrolled out before we looked: all that is there is new, and what
            # fell out of the deque in between is lost.
            fresh = list(reversed(console))
            if total is not None and self._total is not None:
                self.missed += max(0, total - self._total - len(fresh))
        elif self._total is None and total is not None:
            # The first look: what the core dropped before anyone looked is lost too.
            self.missed += max(0, total - len(console))
        if total is not None:
            self._total = total
        if not fresh:
            return []
        self._last = fresh[0]
        fresh.reverse()
        return [self._entry(raw) for raw in fresh]

    def skip_to_end(self) -> None:
        """Forget what is in the core's console now (a log opened mid-run starts here)."""
        console = self._console()
        self._total = getattr(self.source, "console_total", None)
        self._last = console[-1] if console else None

    def _entry(self, raw: Any) -> ConsoleEntry:
        if isinstance(raw, tuple):  # the DS: (time, level, text)
            t, level, text = raw
        else:  # the fake roboRIO: ConsoleLine(time, kind, text, sequence)
            t, level, text = raw.time, raw.kind, raw.text
        return ConsoleEntry(t, self.team, _level_of(level), text)


def _after(newest_first: list[Any], marker: Any) -> list[Any] | None:
    """The entries newer than ``marker`` (newest first), or None if it is not among them.
    No marker yet: everything is newer."""
    if marker is None:
        return newest_first
    for i, raw in enumerate(newest_first):
        if raw is marker:
            return newest_first[:i]
    return None


def station_role(engine: Any, i: int, role: str) -> Any:
    """Station ``i``'s DS or roboRIO (``role``: "ds" or "rio") as the engine shows it when
    asked: read through the engine each time, as its views are a new FieldView each refresh."""
    return getattr(engine.field.stations[i], role)


def ds_console_of(engine: Any, i: int) -> Any:
    """Where station ``i``'s DS keeps its console now (its robot TCP part, or that part's
    fragment of its view: ``console`` and ``console_total``)."""
    return engine.field.stations[i].ds.tcp


def console_sources(engine: Any) -> list[tuple[int, Callable[[], Any]]]:
    """(team, the core now) whose console the panel and the log show: each station's DS (what
    crossed the wire), or its fake roboRIO where no DS runs here."""
    out: list[tuple[int, Callable[[], Any]]] = []
    for i, st in enumerate(engine.field.stations):
        if st.ds is not None:
            out.append((st.team, functools.partial(ds_console_of, engine, i)))
        elif st.rio is not None:
            out.append((st.team, functools.partial(station_role, engine, i, "rio")))
    return out


class ConsoleReader:
    """New lines of every console on a field, across engine restarts."""

    def __init__(self) -> None:
        self._engine: Any = None
        self.followers: list[ConsoleFollower] = []

    def follow(self, engine: Any) -> bool:
        """Point at ``engine`` (True if it is a new one: the followers start afresh)."""
        if engine is self._engine:
            return False
        self._engine = engine
        self.followers = [ConsoleFollower(core, team) for team, core in console_sources(engine)] \
            if engine is not None else []
        return True

    def read(self, engine: Any) -> list[ConsoleEntry]:
        self.follow(engine)
        out: list[ConsoleEntry] = []
        for f in self.followers:
            out += f.new_entries()
        if len(self.followers) > 1:
            out.sort(key=lambda e: e.time)  # stable: each team's own order is kept
        return out

    @property
    def missed(self) -> int:
        return sum(f.missed for f in self.followers)
