"""Real joysticks through pygame (SDL), with hot-plug. pygame is imported only when
:class:`PygameDevices` is made, with SDL's environment set first, and only the parts
joysticks need (:func:`import_pygame`)."""

from __future__ import annotations

import importlib
import importlib.util
import logging
import os
import sys
import types
from dataclasses import dataclass, field
from typing import Any

from .descriptor import (MAX_AXES, MAX_BUTTONS, MAX_POVS, TYPE_HID_GAMEPAD, TYPE_HID_JOYSTICK, TYPE_XINPUT_GAMEPAD,
                         Descriptor, Reading)

log = logging.getLogger("fieldbox.joysticks")

#: SDL reads these when it starts; set before pygame is imported.
SDL_ENVIRONMENT = {
    "SDL_VIDEODRIVER": "dummy",
    "SDL_JOYSTICK_ALLOW_BACKGROUND_EVENTS": "1",
    "SDL_NO_SIGNAL_HANDLERS": "1",
    "PYGAME_HIDE_SUPPORT_PROMPT": "1",  # its banner on stdout would scribble over the TUI
}


class DeviceError(Exception):
    """Real joysticks are unavailable; the message says why (for the screen)."""


HAT_TO_POV = {(0, 1): 0, (1, 1): 45, (1, 0): 90, (1, -1): 135, (0, -1): 180, (-1, -1): 225,
              (-1, 0): 270, (-1, 1): 315}


#: The parts of pygame joysticks need (``pygame.base`` brings ``error``, ``quit`` and
#: ``get_sdl_version``; ``pygame.constants`` the event types).
PYGAME_PARTS = ("pygame.base", "pygame.constants", "pygame.display", "pygame.event", "pygame.joystick")


def import_pygame() -> Any:
    """pygame, imported with SDL's environment set first (values the user set win).

    Only the parts joysticks need: ``import pygame`` itself loads every module and library
    pygame has (fonts, images, sound, ...), 22.5 MB of resident memory and about 0.2 s;
    :data:`PYGAME_PARTS` alone take 2.5 MB with SDL's joysticks started (measured with
    /proc/self/statm, pygame 2.6.1). pygame-ce 2.5.8, the kept community edition, installs as
    the same ``pygame`` package: 9.2 MB whole and 2.7 MB for the parts, both with SDL's
    joysticks started (/proc/self/statm before and after).
    The package's ``__init__`` is skipped: ``pygame`` is
    a plain package object holding those parts and the names of ``pygame.base`` and
    ``pygame.constants``. If pygame was imported whole already, or the parts cannot be
    loaded alone, it is the whole ``pygame``. Afterwards, ``import pygame`` elsewhere in the
    app's process gets this package: nothing else there uses pygame (a robot program that
    does should run in the wire's own process, the default, or import pygame first)."""
    for name, value in SDL_ENVIRONMENT.items():
        os.environ.setdefault(name, value)
    loaded = sys.modules.get("pygame", False)
    if loaded is None:  # imports of pygame blocked (a test, a user's choice)
        raise ImportError("import of pygame halted; None in sys.modules")
    if loaded is not False:
        return loaded
    spec = importlib.util.find_spec("pygame")
    if spec is None or not spec.submodule_search_locations:
        raise ImportError("No module named 'pygame'")
    package = types.ModuleType("pygame")
    package.__file__ = spec.origin
    package.__path__ = list(spec.submodule_search_locations)
    package.__spec__ = spec
    sys.modules["pygame"] = package
    try:
        for part in PYGAME_PARTS:
            module = importlib.import_module(part)
            if part in ("pygame.base", "pygame.constants"):
                package.__dict__.update({k: v for k, v in vars(module).items() if not k.startswith("_")})
    except Exception as exc:  # an unusual pygame build: the whole of it
        log.info("pygame's joystick parts would not load alone (%s): importing all of pygame", exc)
        for name in [m for m in sys.modules if m == "pygame" or m.startswith("pygame.")]:
            del sys.modules[name]
        import pygame  # noqa: PLC0415 - lazy on purpose

        return pygame
    return package


@dataclass(eq=False)
class Device:
    """One open SDL joystick."""

    instance_id: int
    name: str
    guid: str
    descriptor: Descriptor
    handle: Any = field(repr=False, default=None)
    rumble: tuple[float, float] = (0.0, 0.0)
    key: tuple[str, str, int] | None = None  # set by the hub: (GUID, name, n-th of its kind)


def describe_device(name: str, n_axes: int, n_buttons: int, n_hats: int) -> Descriptor:
    """The DS descriptor for a device: counts clipped to what the protocol carries, and a type
    guessed from the name (Xbox pads are XInput gamepads; sticks are HID joysticks)."""
    lowered = name.lower()
    is_xbox = any(word in lowered for word in ("xbox", "x-box", "xinput"))
    if is_xbox:
        kind = TYPE_XINPUT_GAMEPAD
    elif any(word in lowered for word in ("stick", "flight", "attack", "extreme 3d")):
        kind = TYPE_HID_JOYSTICK
    else:
        kind = TYPE_HID_GAMEPAD
    clipped = name.encode("utf-8", "replace")[:60].decode("utf-8", "ignore")
    return Descriptor(clipped, min(n_axes, MAX_AXES), min(n_buttons, MAX_BUTTONS), min(n_hats, MAX_POVS),
                      is_xbox, kind)


class PygameDevices:
    """SDL joysticks through pygame. Constructing it starts SDL's joystick subsystem; it
    raises :class:`DeviceError` with the reason when pygame or SDL cannot."""

    def __init__(self) -> None:
        try:
            pg = import_pygame()
        except ImportError as exc:
            raise DeviceError(f"pygame is not installed ({exc}): real joysticks are off") from None
        self.pg = pg
        try:
            pg.display.init()  # SDL delivers joystick events through its video/event loop
            pg.joystick.init()
        except Exception as exc:  # pygame.error, or SDL missing a backend
            raise DeviceError(f"SDL could not start joysticks: {exc}") from None
        self.devices: dict[int, Device] = {}

    def open_all(self) -> list[Device]:
        """Open every joystick SDL knows now (already open ones are returned as they are)."""
        self.pg.event.pump()
        found = []
        for index in range(self.pg.joystick.get_count()):
            dev = self._open(index)
            if dev is not None:
                found.append(dev)
        self._drain()  # their "added" events are already handled
        return found

    def _open(self, index: int) -> Device | None:
        try:
            js = self.pg.joystick.Joystick(index)
            iid = js.get_instance_id()
            if iid in self.devices:
                return self.devices[iid]
            desc = describe_device(js.get_name() or f"joystick {index}", js.get_numaxes(), js.get_numbuttons(),
                                   js.get_numhats())
            dev = Device(iid, desc.name, js.get_guid(), desc, js)
        except Exception as exc:  # a device that vanished between the event and the open
            log.info("cannot open joystick %s: %s", index, exc)
            return None
        self.devices[iid] = dev
        return dev

    def _drain(self) -> None:
        self.pg.event.get()

    def events(self) -> list[tuple[str, Any]]:
        """Hot-plug since the last call: ``("added", Device)`` and ``("removed", Device)``.
        Every other event is dropped (values are read as state, see :meth:`read`)."""
        pg = self.pg
        out: list[tuple[str, Any]] = []
        for event in pg.event.get():
            if event.type == pg.JOYDEVICEADDED:
                before = set(self.devices)
                dev = self._open(event.device_index)
                if dev is not None and dev.instance_id not in before:
                    out.append(("added", dev))
            elif event.type == pg.JOYDEVICEREMOVED:
                dev = self.devices.pop(event.instance_id, None)
                if dev is not None:
                    self._close(dev)
                    out.append(("removed", dev))
        return out

    def read(self, dev: Device) -> Reading:
        js, d = dev.handle, dev.descriptor
        try:
            axes = tuple(js.get_axis(i) for i in range(d.axes))
            buttons = 0
            for i in range(d.buttons):
                if js.get_button(i):
                    buttons |= 1 << i
            povs = tuple(HAT_TO_POV.get(tuple(js.get_hat(i)), -1) for i in range(d.povs))
        except Exception:  # unplugged this instant: the removed event follows
            return d.neutral()
        return Reading(axes, buttons, povs)

    def set_rumble(self, dev: Device, left: float, right: float) -> None:
        """The robot's rumble on the device (left is the heavy, low-frequency motor)."""
        if (left, right) == dev.rumble:
            return
        dev.rumble = (left, right)
        try:
            if left or right:
                dev.handle.rumble(left, right, 0)
            else:
                dev.handle.stop_rumble()
        except Exception as exc:  # no rumble motors, or unplugged
            log.debug("rumble on %s: %s", dev.name, exc)

    def rescan(self) -> list[Device]:
        """Restart SDL's joystick subsystem and open everything again (new instance ids)."""
        for dev in list(self.devices.values()):
            self._close(dev)
        self.devices.clear()
        self.pg.joystick.quit()
        self.pg.joystick.init()
        return self.open_all()

    def _close(self, dev: Device) -> None:
        try:
            dev.handle.quit()
        except Exception:
            pass

    def close(self) -> None:
        for dev in list(self.devices.values()):
            self._close(dev)
        self.devices.clear()
        try:
            self.pg.joystick.quit()
        except Exception:
            pass
