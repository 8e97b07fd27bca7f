"""The robot console as the Console panel reads it: new lines only, never a rebuild.

The panel reads the Driver Station's ``console`` stream of ``(time, level, text)`` (what
crossed the wire from the robot), or, where no DS runs, the fake roboRIO's own ``console`` of
:class:`~roles.cores.views.ConsoleLine`, each a numbered stream in the latest view
(roles/cores/views.py StreamView): :class:`ConsoleFollower` takes the lines numbered after
the last it took, and counts the ones that scrolled out before it looked.

The console is saved to files as it arrives by :class:`roles.runtime.logfiles.FieldLog` (with the
events and the match log), for the app and headless mode alike.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from typing import Any, Callable

from roles.cores.views import StreamView

from .widgets import StreamCursor

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
    """New console lines of one core since the last call, followed by their numbers (a
    console is a numbered stream: roles/cores/views.py StreamView)."""

    __slots__ = ("core", "team", "_cursor", "missed")

    def __init__(self, core: Callable[[], Any], team: int) -> None:
        self.core = core       # the DS's or roboRIO's view now: a new view comes every few beats
        self.team = team
        self._cursor = StreamCursor()
        self.missed = 0         # lines that scrolled out of the stream before we looked

    def _console(self) -> StreamView[Any]:
        console: StreamView[Any] = self.core().console
        return console

    def new_entries(self) -> list[ConsoleEntry]:
        console = self._console()
        seen = self._cursor.seq
        new, _ = self._cursor.take(console)
        # what the stream dropped before we looked (the first look: before anyone looked)
        self.missed += max(0, console.first_seq - max(seen, 0))
        return [self._entry(raw) for raw in new]

    def _entry(self, raw: Any) -> ConsoleEntry:
        if isinstance(raw, tuple):  # the DS: (time, level, text)
            t, level, text = raw
        else:  # the fake roboRIO: ConsoleLine(time, kind, text, sequence)
            t, level, text = raw.time, raw.kind, raw.text
        return ConsoleEntry(t, self.team, _level_of(level), text)


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
