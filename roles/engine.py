"""A field and the wire that carries it, behind one small interface the app uses.

:class:`ThreadEngine` runs the field on real sockets, on a thread of its own (the wire never
waits for drawing). :class:`SimEngine` runs it on the in-memory network and a fake clock
that the caller advances: deterministic, for tests and stable screenshots.

Either way the app reads the cores' plain attributes and asks for changes only through
:meth:`Engine.execute` / :meth:`Engine.call`, which run on the wire's side and poll the
role at once.
"""

from __future__ import annotations

import abc
import functools
import sys
from concurrent.futures import Future
from dataclasses import dataclass, field as _field
from typing import Any, Callable

from .commands import Command
from .core import CommandError
from .field import Field, FieldConfig
from .logfiles import FieldLog
from .shell import Runtime, Tap
from .simnet import SimNetwork

#: While the app draws on another thread, the wire thread must get the GIL back quickly
#: when a socket or timer wakes it: CPython's default hand-over is 5 ms. Measured under the
#: app (benchmarks/field.py --app), 0.5 ms -> 0.1 ms took the DS's round trip p99 from
#: 3.5 ms to 0.8-1.3 ms and its late sends (p99) from 4.1 to 3.1 ms, for 1-2 % more CPU.
WIRE_SWITCH_INTERVAL = 0.0001


@dataclass(frozen=True)
class CoreCall:
    """A call on one core, named by its role's host name (``"fms"``, ``"ds 254"``,
    ``"rio 254"``), to run on the wire's side. Unlike a closure it can be pickled, so it
    also crosses to a wire in another process (:class:`roles.wireproc.ProcessEngine`).

    ``method`` is the name of a method of the core (or of its attribute ``part``, e.g. a
    2010 DS's ``"legacy"`` codec), or a picklable callable (a module-level function, a
    bound method of a picklable object) called as ``method(core, *args, **kwargs)``.
    Arguments are taken as they are: pass ``engine.now()`` for a time.
    """

    role: str
    method: Any
    args: tuple = ()
    kwargs: dict = _field(default_factory=dict)
    part: str | None = None

    def run(self, field: Field) -> Any:
        target = field.core_named(self.role)
        if self.part is not None:
            target = getattr(target, self.part, None)
            if target is None:
                raise CommandError(f"{self.role} has no {self.part}")
        if isinstance(self.method, str):
            return getattr(target, self.method)(*self.args, **self.kwargs)
        return self.method(target, *self.args, **self.kwargs)


class Engine(abc.ABC):
    field: Field

    def _runnable(self, fn: Any) -> Callable[[], Any]:
        """A :class:`CoreCall` bound to this engine's field; a plain callable as it is."""
        if isinstance(fn, CoreCall):
            return functools.partial(fn.run, self.field)
        return fn

    @abc.abstractmethod
    def now(self) -> float:
        ...

    @abc.abstractmethod
    def call(self, fn: Callable[[], Any], host: str | None = None) -> Any:
        """Run ``fn`` on the wire's side, poll ``host`` after it, return its result (or raise).

        ``fn`` is a :class:`CoreCall` or (not with a wire in another process) any callable."""

    @abc.abstractmethod
    def add_tap(self, tap: Tap) -> None:
        ...

    @abc.abstractmethod
    def remove_tap(self, tap: Tap) -> None:
        ...

    @abc.abstractmethod
    def stop(self) -> None:
        ...

    def execute(self, command: Command) -> None:
        """Carry out a headless-language command; raises CommandError (nothing changed)."""
        host = self.field.host_for(command)
        self.call(lambda: self.field.execute(command, self.now()), host)


class ThreadEngine(Engine):
    def __init__(self, config: FieldConfig) -> None:
        self.field = Field(config)
        self.runtime = Runtime()
        self._old_interval = sys.getswitchinterval()
        self.log: FieldLog | None = None
        #: Things that went wrong but did not stop the field (shown by the app).
        self.problems: list[str] = []

    def start(self) -> None:
        """Bind and start; raises OSError/ValueError with a clear message if it cannot.

        Then the log files (console, events, match log: roles/logfiles.py), unless the config
        turns them off; a log folder that cannot be written is reported in ``problems``,
        the field runs anyway."""
        sys.setswitchinterval(min(self._old_interval, WIRE_SWITCH_INTERVAL))
        try:
            self.runtime.start_thread(self.field.start)
        except BaseException:
            sys.setswitchinterval(self._old_interval)
            self.runtime.stop_thread()
            raise
        config = self.field.config
        if config.log_files:
            try:
                self.log = FieldLog(self.field, config.log_dir)
                self.log.start_on(self.runtime)
            except OSError as exc:
                self.log = None
                self.problems.append(f"cannot write log files: {exc.strerror or exc}")

    def now(self) -> float:
        return self.runtime.clock()

    def call(self, fn, host=None):
        return self.runtime.call(self._runnable(fn), host).result(timeout=5)

    def add_tap(self, tap: Tap) -> None:
        self.runtime.taps.append(tap)

    def remove_tap(self, tap: Tap) -> None:
        if tap in self.runtime.taps:
            self.runtime.taps.remove(tap)

    def stop(self) -> None:
        if self.log is not None:
            try:
                self.runtime.call(self.log.close).result(timeout=5)
            except Exception:  # the wire thread is gone already: close from here
                self.log.close()
            self.log = None
        self.runtime.stop_thread()
        sys.setswitchinterval(self._old_interval)


class SimEngine(Engine):
    """The field on a fake clock. ``advance(seconds)`` moves time (and the traffic) on."""

    def __init__(self, config: FieldConfig, start: float = 1000.0) -> None:
        config.plan = "ephemeral"
        self.net = SimNetwork(start)
        self.field = Field(config)
        self.field.start_sim(self.net)

    def now(self) -> float:
        return self.net.now

    def advance(self, seconds: float) -> None:
        self.net.run_for(seconds)

    def call(self, fn, host=None):
        fn = self._runnable(fn)
        if host is None:
            return fn()
        return self.net.command(host, fn)

    def add_tap(self, tap: Tap) -> None:
        self.net.taps.append(tap)

    def remove_tap(self, tap: Tap) -> None:
        if tap in self.net.taps:
            self.net.taps.remove(tap)

    def stop(self) -> None:
        pass


__all__ = ["CoreCall", "Engine", "SimEngine", "ThreadEngine", "Future"]
