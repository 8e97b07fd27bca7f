"""A field and the wire that carries it, behind one small interface the app uses.

:class:`ThreadEngine` runs the field on real sockets, on a thread of its own (the wire never
waits for drawing). :class:`LoopEngine` runs it on the caller's own running loop (headless
and ``fieldbox run``: nothing else shares that loop). :class:`SimEngine` runs it on the
in-memory network and a fake clock that the caller advances: deterministic, for tests and
stable screenshots.

Either way the app reads a :class:`FieldView` (frozen views of the cores, made on the wire's
side: :meth:`Engine.views`) and asks for changes only with typed commands
(roles/cores/commands.py) through :meth:`Engine.submit_command`, which runs on the wire's
side, polls the role at once, and returns a future the app never waits on
(:meth:`Engine.execute` waits, for scripts and tests; :meth:`Engine.submit` and
:meth:`Engine.call` run a plain callable there, for tests on a field in this process).
:meth:`Engine.age` says how long ago the wire last showed it is alive: past
:data:`STALE_AFTER` a screen no longer vouches for what it shows.
"""

from __future__ import annotations

import abc
import asyncio
import sys
import threading
from concurrent.futures import Future, TimeoutError as FutureTimeout
from dataclasses import dataclass, field as default
from typing import Any, Callable, Mapping

from protocol.enums import AllianceStation

from ..cores.commands import Command
from ..cores.core import Address, CommandError
from ..cores.views import DsView, FaultsView, FmsView, RioView, view_of
from ..sim.simnet import SimNetwork
from .field import Field, FieldConfig, StationRoles, station_for
from .logfiles import FieldLog
from .process_tuning import quick_gil_handover
from .shell import Runtime, Tap

#: How long the wire may stay silent before the app says its screens are out of date.
STALE_AFTER = 0.3
#: How long :meth:`Engine.call` and :meth:`Engine.execute` wait for the wire's answer.
CALL_TIMEOUT = 5.0
#: The app's key that starts a field whose wire ended again (fieldbox/app.py).
RESTART_KEY = "F9"


@dataclass(frozen=True, slots=True)
class StationView:
    """One alliance station as the app reads it: where it plays, its team, its roles' names,
    and the views of its DS and roboRIO (None: that role does not run here)."""

    station: AllianceStation
    team: int
    ds_name: str
    rio_name: str
    ds: DsView | None = None
    rio: RioView | None = None


@dataclass(frozen=True, slots=True)
class FieldView:
    """The whole field as the app, the headless mode and a classroom's seats read it: frozen
    views of every core (roles/cores/views.py), never a core. ``at``: when it was put
    together (each core's view says when it was made in its own ``at``)."""

    config: FieldConfig
    stations: tuple[StationView, ...]
    fms: FmsView | None
    faults: FaultsView | None
    at: float
    fms_name: str = "fms"
    fms_note: str | None = None
    bound: Mapping[str, Mapping[str, Address]] = default(default_factory=dict)

    def station_for(self, team: int | None) -> StationView:
        return station_for(self.stations, team)


def field_view(field: Field, now: float) -> FieldView:
    """The views of a live field, made now (on the wire's side: only it reads the cores)."""
    return _field_view(field, tuple(station_view(st, now) for st in field.stations), now)


def station_view(st: StationRoles, now: float) -> StationView:
    """One station's views, made now."""
    return StationView(st.station, st.team, st.ds_name, st.rio_name, view_of(st.ds, now), view_of(st.rio, now))


def _field_view(field: Field, stations: tuple[StationView, ...], now: float) -> FieldView:
    return FieldView(field.config, stations, view_of(field.fms, now), field.faults.view(now), now, field.fms_name,
                     field.fms_note, field.bound)


class Engine(abc.ABC):
    """A running field as the app, the headless mode, scripts and a classroom's seats use it,
    wherever its wire runs (a thread, a process, the fake clock, a classroom's server): views
    out (:meth:`views`), typed commands in (:meth:`submit_command`), taps on its packets."""

    #: The live field where its cores run in this process (:class:`LocalEngine`), else the
    #: latest views of it; the app's panels read :meth:`views` only.
    field: Field | FieldView

    @abc.abstractmethod
    def now(self) -> float:
        ...

    def age(self) -> float:
        """Seconds since the wire last showed it runs (its views of the field are that old)."""
        return 0.0

    @abc.abstractmethod
    def views(self, now: float) -> FieldView:
        """The field as the app reads it, made (or last heard) now."""

    def station_view(self, team: int | None, now: float) -> StationView:
        """The views of ``team``'s station (None: the first) as :meth:`views` shows it
        (CommandError: no such team here)."""
        return self.views(now).station_for(team)

    #: Writes to the log files that failed (a full disk, a folder gone).
    log_errors = 0
    #: Where this run's log files go (None: no log files).
    log_folder: str | None = None
    #: Why the wire ended by itself, in words ("the wire process ended (killed by SIGKILL)"):
    #: the field no longer runs and nothing will answer. None while it runs, and once stopped
    #: on purpose.
    end_reason: str | None = None

    @abc.abstractmethod
    def submit_command(self, command: Command) -> Future:
        """Carry out a command (roles/cores/commands.py) on the wire's side; a future of its
        reply (CommandError: refused, nothing changed). Never waits for the wire."""

    @abc.abstractmethod
    def add_tap(self, tap: Tap) -> None:
        ...

    @abc.abstractmethod
    def remove_tap(self, tap: Tap) -> None:
        ...

    @abc.abstractmethod
    def stop(self) -> None:
        ...

    def execute(self, command: Command) -> str | None:
        """Carry out a command and wait; its reply (a line to print, or None), or CommandError
        (nothing changed). On a :class:`LoopEngine`, from its loop, it is done on return."""
        return self._wait(self.submit_command(command))

    def _wait(self, future: Future) -> Any:
        try:
            return future.result(timeout=CALL_TIMEOUT)
        except FutureTimeout:
            raise CommandError(f"the wire did not answer within {CALL_TIMEOUT:g} s") from None


#: How long the app waits for views from a wire on a thread of its own before it shows the last.
VIEWS_WAIT = 0.1


class LocalEngine(Engine):
    """A field whose cores live in this process (:attr:`field`): on a thread, or on the fake
    clock. Tests and benchmarks may also run a plain callable on the wire's side."""

    field: Field

    @property
    @abc.abstractmethod
    def taps(self) -> list[Tap]:
        """The taps the wire calls: the runtime's or the network's own list."""

    def views(self, now: float) -> FieldView:
        return field_view(self.field, now)

    def station_view(self, team: int | None, now: float) -> StationView:
        """Only that station's views are made (a step watching one DS every 20 ms)."""
        return station_view(station_for(self.field.stations, team), now)

    def add_tap(self, tap: Tap) -> None:
        self.taps.append(tap)

    def remove_tap(self, tap: Tap) -> None:
        if tap in self.taps:
            self.taps.remove(tap)

    @abc.abstractmethod
    def submit(self, fn: Callable[[], Any], host: str | None = None) -> Future:
        """Run ``fn`` on the wire's side, poll ``host`` after it; a future of its result. Never
        waits for the wire. For tests and benchmarks on a field in this process: the app and
        a classroom change a field only with commands (:meth:`submit_command`)."""

    def submit_command(self, command: Command) -> Future:
        field = self.field
        return self.submit(lambda: field.execute(command, self.now()), field.host_for(command))

    def call(self, fn: Callable[[], Any], host: str | None = None) -> Any:
        """:meth:`submit`, then wait for the result (or raise it)."""
        return self._wait(self.submit(fn, host))


class ThreadEngine(LocalEngine):
    def __init__(self, config: FieldConfig) -> None:
        self.field = Field(config)
        self.runtime = Runtime()
        self._old_interval = sys.getswitchinterval()
        self.log: FieldLog | None = None
        #: Things that went wrong but did not stop the field (shown by the app).
        self.problems: list[str] = []
        self._shown: FieldView | None = None  # the last views made

    def start(self) -> None:
        """Bind and start; raises OSError/ValueError with a clear message if it cannot.

        Then the log files (console, events, match log: roles/runtime/logfiles.py), unless the config
        turns them off; a log folder that cannot be written is reported in ``problems``,
        the field runs anyway."""
        self._old_interval = quick_gil_handover()
        try:
            self.runtime.start_thread(self.field.start)
        except BaseException:
            sys.setswitchinterval(self._old_interval)
            self.runtime.stop_thread()
            raise
        if self.field.ds_ip_note:  # another program has the dashboards' port: the field runs on
            self.problems.append(self.field.ds_ip_note)
        config = self.field.config
        if config.log_files:
            try:
                self.log = FieldLog(self.field, config.log_dir)
                self.log.start_on(self.runtime, self.problems.append)
            except OSError as exc:
                self.log = None
                self.problems.append(f"cannot write log files: {exc.strerror or exc}")

    def now(self) -> float:
        return self.runtime.clock()

    @property
    def taps(self) -> list[Tap]:
        return self.runtime.taps

    # Engine's is a plain attribute, which other engines set: here it is read from the log files
    @property
    def log_errors(self) -> int:  # type: ignore[override]
        """Writes to the log files that failed (a full disk, a folder gone)."""
        return self.log.errors if self.log is not None else 0

    @property
    def log_folder(self) -> str | None:  # type: ignore[override]  # as log_errors
        return str(self.log.folder) if self.log is not None else None

    def age(self) -> float:
        return max(0.0, self.runtime.clock() - self.runtime.alive_at)

    def views(self, now: float) -> FieldView:
        """Made on the wire's own thread: only it reads the cores (a property may keep a cache
        the wire relies on). A wire that does not answer within :data:`VIEWS_WAIT` leaves the
        last views (the app says the wire is silent)."""
        try:
            self._shown = self.runtime.call(lambda: field_view(self.field, now)).result(timeout=VIEWS_WAIT)
        except FutureTimeout:
            if self._shown is None:  # none yet: an empty field until the wire answers
                return FieldView(self.field.config, (), None, None, now)
        return self._shown

    def submit(self, fn, host=None) -> Future:
        return self.runtime.call(fn, host)

    def stop(self) -> None:
        if self.log is not None:
            try:
                self.runtime.call(self.log.close).result(timeout=5)
            except Exception:  # the wire thread is gone already: close from here
                self.log.close()
            self.log = None
        self.runtime.stop_thread()
        sys.setswitchinterval(self._old_interval)


class LoopEngine(LocalEngine):
    """The field on the running asyncio loop, the caller's: ``fieldbox --headless`` and
    ``fieldbox run``, whose main loop is the wire's (at real-time priority where allowed,
    roles/runtime/process_tuning.py) and reads views and runs steps between its beats.
    :meth:`start` and :meth:`close` on that loop."""

    def __init__(self, config: FieldConfig) -> None:
        self.field = Field(config)
        self.runtime = Runtime()
        self._loop_thread: int | None = None
        self._closing: Future[None] | None = None

    async def start(self) -> None:
        """Bind, then begin polling (OSError/ValueError saying why the field cannot be)."""
        self._loop_thread = threading.get_ident()
        try:
            await self.field.start(self.runtime)
        except BaseException:
            await self.runtime.close()
            raise
        self.runtime.start()

    def now(self) -> float:
        return self.runtime.clock()

    async def views_between_beats(self) -> FieldView:
        """:meth:`views`, made a station at a time with the loop let go in between: this loop
        is the wire's, and a whole field's views at once (0.4-1 ms) every status tick made
        headless's beat p99 three times longer (docs/figures.md, section 11). Each view says
        when it was made (its ``at``)."""
        stations = []
        for st in self.field.stations:
            stations.append(station_view(st, self.now()))
            await asyncio.sleep(0)  # a beat due now goes first
        return _field_view(self.field, tuple(stations), self.now())

    @property
    def taps(self) -> list[Tap]:
        return self.runtime.taps

    def submit(self, fn, host=None) -> Future:
        """From the loop's own thread, ``fn`` runs at once and the future is done on return:
        an e-stop typed goes before anything else the loop has to do. From another thread,
        on the loop, soon."""
        if threading.get_ident() == self._loop_thread:
            return self.runtime.call(fn, host)

        async def on_loop() -> Any:
            return self.runtime.call(fn, host).result()
        return asyncio.run_coroutine_threadsafe(on_loop(), self.runtime.loop)

    async def close(self) -> None:
        await self.runtime.close()

    def stop(self) -> None:
        """Close soon, from any thread (headless awaits :meth:`close` on its loop)."""
        self._closing = asyncio.run_coroutine_threadsafe(self.close(), self.runtime.loop)


class SimEngine(LocalEngine):
    """The field on a fake clock. ``advance(seconds)`` moves time (and the traffic) on."""

    def __init__(self, config: FieldConfig, start: float = 1000.0) -> None:
        config.plan = "ephemeral"
        self.net = SimNetwork(start)
        self.field = Field(config)
        self.field.start_sim(self.net)

    def now(self) -> float:
        return self.net.now

    @property
    def taps(self) -> list[Tap]:
        return self.net.taps

    def advance(self, seconds: float) -> None:
        self.net.run_for(seconds)

    def submit(self, fn, host=None) -> Future:
        """Runs at once, on the fake clock: the future is done when it returns."""
        future: Future = Future()
        try:
            value = fn() if host is None else self.net.command(host, fn)
        except Exception as exc:  # noqa: BLE001 - handed to the caller
            future.set_exception(exc)
        else:
            future.set_result(value)
        return future

    def stop(self) -> None:
        pass


__all__ = ["Engine", "FieldView", "LocalEngine", "LoopEngine", "SimEngine", "StationView", "ThreadEngine", "Future"]
