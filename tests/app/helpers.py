"""What the app tests share: the app on SimEngines, the clock step, and a tap on the wire.

* :func:`make_app` builds the app with an engine factory that keeps every SimEngine it made
  (a role change in the picker makes a new one);
* :func:`step` runs the fake clock and copies the cores into the panels, as the app's 10 Hz
  timer would;
* :class:`Wire` keeps every packet a tap sees and decodes the ones a test asks for;
* :func:`layouts_asked` records the refreshes a widget asks for, and which lay the screen out;
* :func:`left_to_the_collector` keeps what some code leaves to Python's cyclic collector;
* :func:`ui_modules_after` says which UI libraries some code pulls in (in a fresh process);
* :class:`Harness` is the app, its engines, a :class:`Wire` on the newest engine, and every
  notification with its severity.

The ``no_real_joysticks`` fixture (conftest.py) keeps the test machine's joysticks and the
user's own themes out of a test.
"""

from __future__ import annotations

import gc
import subprocess
import sys
import time
from pathlib import Path
from typing import Any, Awaitable, Callable

from protocol import ds_to_rio, rio_to_ds
from protocol.fms_to_ds import decode_control as decode_fms_control
from protocol.legacy import decode_legacy_control
from roles.runtime.engine import SimEngine
from roles.runtime.field import FieldConfig
from roles.runtime.shell import TapRecord

from fieldbox.app import FieldboxApp
from fieldbox.pcstatus import PcReading

SIZE = (120, 40)
ROOT = Path(__file__).resolve().parents[2]
#: The PC's figures the app shows in tests (the test machine's own would change every run).
PC = PcReading(cpu=12.0, battery=80.0, charging=False)


async def left_to_the_collector(action: Callable[[], Awaitable[Any]]) -> list:
    """What ``await action()`` leaves to the cyclic collector, kept (``gc.DEBUG_SAVEALL``)
    instead of freed."""
    gc.collect()
    gc.set_debug(gc.DEBUG_SAVEALL)
    try:
        await action()
        gc.collect()
        return list(gc.garbage)
    finally:
        gc.set_debug(0)
        gc.garbage.clear()


def one_team(**kw: Any) -> FieldConfig:
    """Team 254's Driver Station and fake roboRIO (no FMS), unless ``kw`` says otherwise."""
    kw.setdefault("roles", frozenset({"ds", "rio"}))
    return FieldConfig(team=254, **kw)


def recording_factory(engines: list[SimEngine],
                      on_new: Callable[[SimEngine], None] | None = None) -> Callable[[FieldConfig], SimEngine]:
    """An engine factory for the app that appends each SimEngine it makes to ``engines``."""

    def factory(cfg: FieldConfig) -> SimEngine:
        engine = SimEngine(cfg)
        engines.append(engine)
        if on_new is not None:
            on_new(engine)
        return engine

    return factory


def make_app(config: FieldConfig, panel: str | None = None, **kw: Any) -> tuple[FieldboxApp, list[SimEngine]]:
    """The app on SimEngines (animations off), and the list of the engines it starts."""
    engines: list[SimEngine] = []
    kw.setdefault("pc_status", lambda: PC)
    return FieldboxApp(recording_factory(engines), config, panel=panel, animate=False, **kw), engines


async def step(pilot, seconds: float) -> None:
    """Run the app's engine ``seconds`` on its fake clock, copy the cores into the panels (as
    the 10 Hz timer would), and let the screen catch up."""
    app = pilot.app
    app.engine.advance(seconds)
    app.refresh_views()
    await pilot.pause()


def layouts_asked(widget) -> list[bool]:
    """Every refresh ``widget`` asks for from now on: True for one that lays out the screen."""
    asked: list[bool] = []
    original = widget.refresh

    def refresh(*regions, repaint=True, layout=False, recompose=False):
        asked.append(layout)
        return original(*regions, repaint=repaint, layout=layout, recompose=recompose)

    widget.refresh = refresh
    return asked


def ui_modules_after(code: str) -> list[str]:
    """Run ``code`` in a fresh interpreter in the project folder; the UI libraries (textual,
    rich, pygame) it loaded. A module that must work without the app is checked with it."""
    probe = code + "\nimport sys; print(','.join(m for m in ('textual', 'rich', 'pygame') if m in sys.modules))"
    done = subprocess.run([sys.executable, "-c", probe], cwd=ROOT, capture_output=True, text=True, timeout=30)
    assert done.returncode == 0, done.stderr
    return [m for m in done.stdout.strip().split(",") if m]


async def until(pilot, predicate, timeout: float = 20.0) -> bool:
    """Let the app run until ``predicate()`` holds (True), or ``timeout`` passed (its last
    value): a wait for a real wire on a busy machine, never a timing assertion."""
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if predicate():
            return True
        await pilot.pause(0.05)
    return predicate()


def text_of(app: FieldboxApp, selector: str) -> str:
    """What a widget shows, as plain text."""
    return str(app.query_one(selector).render())


class Wire:
    """A tap that keeps every packet: ``(role, direction, kind, data, time)``. Given an
    engine, it taps that engine at once."""

    def __init__(self, engine: SimEngine | None = None) -> None:
        self.packets: list[tuple[str, str, str, bytes, float]] = []
        if engine is not None:
            engine.add_tap(self)

    def __call__(self, r: TapRecord) -> None:
        self.packets.append((r.role, r.direction, r.kind, bytes(r.data), r.time))

    def mark(self) -> int:
        """Where the wire is now: pass it as ``since`` to see only what comes after."""
        return len(self.packets)

    def _data(self, since: int, direction: str, kind: str, role: str | None) -> list[bytes]:
        return [d for r, dr, k, d, _ in self.packets[since:]
                if k == kind and dr == direction and (role is None or r == role)]

    # -- the DS's control packets ----------------------------------------------------------
    def ds_control(self, since: int = 0, role: str = "ds 254") -> list[ds_to_rio.ControlPacket]:
        """The control packets ``role`` sent to its robot, decoded, from mark ``since`` on."""
        return [ds_to_rio.decode_control(d) for d in self._data(since, "out", "ds-to-rio", role)]

    def last_control(self, role: str = "ds 254") -> ds_to_rio.ControlPacket:
        """The newest control packet ``role`` sent."""
        for r, direction, kind, d, _ in reversed(self.packets):
            if r == role and direction == "out" and kind == "ds-to-rio":
                return ds_to_rio.decode_control(d)
        raise AssertionError(f"{role} sent no control packet")

    def legacy_control(self, since: int = 0) -> list:
        """The 2010 DS's 1024-byte control packets, decoded, from mark ``since`` on."""
        return [decode_legacy_control(d) for d in self._data(since, "out", "legacy-ds-to-robot", None)]

    def fms_control(self, since: int = 0) -> list:
        """The FMS's control packets, decoded, from mark ``since`` on."""
        return [decode_fms_control(d) for d in self._data(since, "out", "fms-to-ds", "fms")]

    # -- what the robot sent the DS ----------------------------------------------------------
    def robot_status(self, role: str = "ds 254") -> list[rio_to_ds.StatusPacket]:
        """The robot's status packets ``role`` received (the ones that decode)."""
        out = []
        for d in self._data(0, "in", "rio-to-ds", role):
            try:
                out.append(rio_to_ds.decode_status(d))
            except ValueError:
                pass
        return out

    def robot_tcp(self, role: str = "ds 254") -> list:
        """The robot's TCP frames ``role`` received, decoded."""
        return [rio_to_ds.decode_tcp(d) for d in self._data(0, "in", "rio-to-ds-tcp", role)]

    def stdout_texts(self, role: str = "ds 254") -> list[str]:
        """The robot's console lines (TCP stdout frames) ``role`` received."""
        return [m.text.rstrip("\n") for m in self.robot_tcp(role) if isinstance(m, rio_to_ds.StdoutMessage)]


class Harness:
    """The app on SimEngines, a :class:`Wire` on the newest engine, and every notification
    as ``(message, severity)``."""

    def __init__(self, config: FieldConfig, panel: str = "ds") -> None:
        self.engines: list[SimEngine] = []
        self.wire: Wire | None = None
        self.app = FieldboxApp(recording_factory(self.engines, self._new_engine), config, panel=panel,
                               animate=False, pc_status=lambda: PC)
        self.notes: list[tuple[str, str]] = []
        notify = self.app.notify

        def record(message, *args, **kwargs):
            self.notes.append((str(message), kwargs.get("severity", "information")))
            return notify(message, *args, **kwargs)

        self.app.notify = record

    def _new_engine(self, engine: SimEngine) -> None:
        self.wire = Wire(engine)

    @property
    def engine(self) -> SimEngine:
        return self.engines[-1]

    @property
    def messages(self) -> list[str]:
        """The notifications' messages."""
        return [message for message, _ in self.notes]

    def run(self, seconds: float = 0.1) -> None:
        """Let the wire run, then copy the state to the widgets (as the app's 10 Hz timer
        would; widget contents change at once, no need to wait for a repaint)."""
        self.engine.advance(seconds)
        self.app.refresh_views()
