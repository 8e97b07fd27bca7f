"""A virtual SDL joystick, made with SDL_JoystickAttachVirtualEx on the very SDL library pygame
loaded (ctypes), goes through fieldbox.joystick_input and the DS core to the wire: its axis,
button and hat show in the DS's control packets; unplugging it clears the slot; a locked
slot waits for it and takes it back; and the robot's rumble comes back to the device.

No hardware and no display: SDL runs with the dummy video driver. SDL 2.0.14 added virtual
joysticks (2.24 the Ex form with a rumble callback); older SDLs skip with the reason.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import glob
import os
import re
from dataclasses import replace

import pytest

from protocol import ds_to_rio
from roles.runtime.engine import SimEngine

from fieldbox.joystick_input import JoystickHub, import_pygame

from .helpers import SIZE, Wire, make_app, one_team

SDL_JOYSTICK_TYPE_GAMECONTROLLER = 1
SDL_HAT_RIGHT = 0x02
SDL_VIRTUAL_JOYSTICK_DESC_VERSION = 1
_SDL_NAME = re.compile(r"(^|/)(lib)?SDL2(-2\.0|-2-[0-9a-f]+\.0)?(\.so[.0-9]*|\.dylib|\.dll)$")

RumbleFn = ctypes.CFUNCTYPE(ctypes.c_int, ctypes.c_void_p, ctypes.c_uint16, ctypes.c_uint16)


class VirtualJoystickDesc(ctypes.Structure):
    """SDL_VirtualJoystickDesc, version 1 (SDL 2.24+, SDL_joystick.h)."""

    _fields_ = [("version", ctypes.c_uint16), ("type", ctypes.c_uint16), ("naxes", ctypes.c_uint16),
                ("nbuttons", ctypes.c_uint16), ("nhats", ctypes.c_uint16), ("vendor_id", ctypes.c_uint16),
                ("product_id", ctypes.c_uint16), ("padding", ctypes.c_uint16),
                ("button_mask", ctypes.c_uint32), ("axis_mask", ctypes.c_uint32),
                ("name", ctypes.c_char_p), ("userdata", ctypes.c_void_p),
                ("Update", ctypes.c_void_p), ("SetPlayerIndex", ctypes.c_void_p), ("Rumble", RumbleFn),
                ("RumbleTriggers", ctypes.c_void_p), ("SetLED", ctypes.c_void_p), ("SendEffect", ctypes.c_void_p)]


def sdl_library(pygame) -> ctypes.CDLL:
    """The SDL2 library pygame itself loaded: the process's own mapping first (Linux), then
    the copy bundled with the wheel, then the system's."""
    candidates: list[str] = []
    try:
        with open("/proc/self/maps") as maps:
            candidates += [line.split()[-1] for line in maps if "SDL2" in line]
    except OSError:
        pass
    base = os.path.dirname(pygame.__file__)
    # auditwheel names the folder after the distribution: pygame-ce's is pygame_ce.libs
    site = os.path.dirname(base)
    for pattern in (site + "/pygame_ce.libs/*SDL2*", base + ".libs/*SDL2*", base + "/.dylibs/*SDL2*",
                    base + "/SDL2*.dll"):
        candidates += sorted(glob.glob(pattern))
    system = ctypes.util.find_library("SDL2")
    if system:
        candidates.append(system)
    for path in dict.fromkeys(candidates):
        if _SDL_NAME.search(path) or path == system:
            return ctypes.CDLL(path)
    pytest.skip(f"cannot find the SDL2 library pygame loaded (looked at {candidates})")


class VirtualPad:
    """One virtual SDL joystick: 6 axes, 12 buttons, 1 hat; rumble calls are recorded."""

    def __init__(self, sdl: ctypes.CDLL, name: bytes = b"fieldbox virtual pad") -> None:
        self.sdl = sdl
        self.rumbles: list[tuple[int, int]] = []
        self._rumble_cb = RumbleFn(self._on_rumble)  # kept alive as long as the device
        self.desc = VirtualJoystickDesc(version=SDL_VIRTUAL_JOYSTICK_DESC_VERSION,
                                        type=SDL_JOYSTICK_TYPE_GAMECONTROLLER, naxes=6, nbuttons=12, nhats=1,
                                        name=name, Rumble=self._rumble_cb)
        self.index = sdl.SDL_JoystickAttachVirtualEx(ctypes.byref(self.desc))
        if self.index < 0:
            raise RuntimeError(f"SDL_JoystickAttachVirtualEx: {sdl.SDL_GetError().decode()}")
        self.handle = sdl.SDL_JoystickOpen(self.index)  # values can be set only on an open joystick
        if not self.handle:
            raise RuntimeError(f"SDL_JoystickOpen: {sdl.SDL_GetError().decode()}")

    def _on_rumble(self, userdata, low: int, high: int) -> int:
        self.rumbles.append((low, high))
        return 0

    def axis(self, axis: int, value: int) -> None:
        assert self.sdl.SDL_JoystickSetVirtualAxis(self.handle, axis, value) == 0

    def button(self, button: int, down: bool) -> None:
        assert self.sdl.SDL_JoystickSetVirtualButton(self.handle, button, int(down)) == 0

    def hat(self, hat: int, value: int) -> None:
        assert self.sdl.SDL_JoystickSetVirtualHat(self.handle, hat, value) == 0

    def unplug(self) -> None:
        if self.handle:
            self.sdl.SDL_JoystickClose(self.handle)
            self.handle = None
        # the device index of a virtual joystick can move as others come and go: find ours
        for index in range(self.sdl.SDL_NumJoysticks()):
            if self.sdl.SDL_JoystickIsVirtual(index):
                self.sdl.SDL_JoystickDetachVirtual(index)
                return


@pytest.fixture
def sdl():
    pygame = import_pygame()
    major, minor, patch = pygame.get_sdl_version()
    if (major, minor, patch) < (2, 24, 0):
        pytest.skip(f"SDL {major}.{minor}.{patch} has no SDL_JoystickAttachVirtualEx (2.24+)")
    lib = sdl_library(pygame)
    lib.SDL_JoystickAttachVirtualEx.argtypes = [ctypes.POINTER(VirtualJoystickDesc)]
    lib.SDL_JoystickAttachVirtualEx.restype = ctypes.c_int
    lib.SDL_JoystickOpen.argtypes = [ctypes.c_int]
    lib.SDL_JoystickOpen.restype = ctypes.c_void_p
    lib.SDL_JoystickClose.argtypes = [ctypes.c_void_p]
    lib.SDL_JoystickSetVirtualAxis.argtypes = [ctypes.c_void_p, ctypes.c_int, ctypes.c_int16]
    lib.SDL_JoystickSetVirtualButton.argtypes = [ctypes.c_void_p, ctypes.c_int, ctypes.c_uint8]
    lib.SDL_JoystickSetVirtualHat.argtypes = [ctypes.c_void_p, ctypes.c_int, ctypes.c_uint8]
    lib.SDL_JoystickIsVirtual.argtypes = [ctypes.c_int]
    lib.SDL_JoystickIsVirtual.restype = ctypes.c_int
    lib.SDL_JoystickDetachVirtual.argtypes = [ctypes.c_int]
    lib.SDL_GetError.restype = ctypes.c_char_p
    yield lib
    pygame.quit()


class Bench:
    """A DS and fake roboRIO on a fake clock, the hub feeding the DS, a tap on the wire."""

    def __init__(self) -> None:
        self.engine = SimEngine(one_team())
        self.station = self.engine.field.stations[0]
        self.ds = self.station.ds
        self.wire = Wire(self.engine)
        self.engine.advance(1.0)  # robot comms up
        self.hub = JoystickHub(keyboard=False)
        self.now = 0.0

    def step(self, seconds: float = 0.1) -> list[str]:
        """One input poll (hot-plug, values), the batch to the DS, then the wire runs on."""
        self.now += 0.02
        messages = self.hub.poll(self.now)
        update = self.hub.take_update()
        if update:
            self.engine.execute(replace(update, team=self.station.team))
        self.engine.advance(seconds)
        return messages

    def joystick(self, slot: int = 0) -> ds_to_rio.Joystick:
        """Slot ``slot`` as the last control packet carried it."""
        joysticks = self.wire.last_control().joysticks
        return joysticks[slot] if slot < len(joysticks) else ds_to_rio.EMPTY_JOYSTICK


def test_virtual_joystick_reaches_the_wire(sdl):
    bench = Bench()
    assert bench.hub.start_devices() == []  # SDL started, nothing plugged in yet
    assert bench.hub.devices_status == "no joystick found: plug one in (hot-plug is on)"
    pad = VirtualPad(sdl)
    try:
        messages = bench.step()
        assert any("fieldbox virtual pad plugged in: slot 0" in m for m in messages), messages
        joy = bench.ds.sticks.slots[0]
        assert joy is not None and joy.name == "fieldbox virtual pad"
        assert (len(joy.axes), joy.button_count, len(joy.povs)) == (6, 12, 1)

        pad.axis(1, -32768)  # left stick pushed fully forward
        pad.axis(0, 16384)  # half right
        pad.button(2, True)  # SDL button 2 is WPILib button 3
        pad.hat(0, SDL_HAT_RIGHT)
        bench.step()
        wire = bench.joystick(0)
        assert wire.axes[:2] == (64, -128)
        assert wire.pressed(3) and not wire.pressed(1)
        assert wire.povs == (90,)

        pad.axis(1, 0)
        pad.button(2, False)
        pad.hat(0, 0)
        bench.step()
        wire = bench.joystick(0)
        assert wire.axes[1] == 0 and wire.buttons == 0 and wire.povs == (-1,)
    finally:
        pad.unplug()
    messages = bench.step()
    assert any("unplugged: slot 0 is free" in m for m in messages), messages
    assert bench.ds.sticks.slots[0] is None
    assert bench.joystick(0).is_empty


def test_locked_slot_waits_for_its_device(sdl):
    bench = Bench()
    bench.hub.start_devices()
    pad = VirtualPad(sdl)
    try:
        bench.step()
        bench.hub.move_keyboard(1)  # something else in the slots: the pad must come back to 0 all the same
        assert "locked" in bench.hub.toggle_lock(0)
        pad.axis(0, 32767)
        bench.step()
        assert bench.joystick(0).axes[0] == 127
    finally:
        pad.unplug()
    messages = bench.step()
    assert any("stays locked" in m for m in messages), messages
    # the slot is still declared, neutral: robot code sees the stick centred, not gone
    assert bench.ds.sticks.slots[0] is not None and bench.ds.sticks.slots[0].name == "fieldbox virtual pad"
    assert bench.joystick(0).axes[0] == 0 and not bench.joystick(0).is_empty
    assert bench.hub.toggle_keyboard().startswith("keyboard joystick off")  # free slot 1
    pad = VirtualPad(sdl)
    try:
        messages = bench.step()
        assert any("back in its locked slot 0" in m for m in messages), messages
        pad.axis(0, -32768)
        bench.step()
        assert bench.joystick(0).axes[0] == -128
    finally:
        pad.unplug()


def test_robot_rumble_reaches_the_device(sdl):
    """Button 1 -> the fake roboRIO's built-in program sets left rumble -> the status packet's
    joystick output tag -> the DS -> the hub -> SDL's rumble on the device."""
    bench = Bench()
    assert bench.ds.enabled is False  # the built-in program echoes buttons even disabled
    bench.hub.start_devices()
    pad = VirtualPad(sdl)
    try:
        bench.step()
        pad.button(0, True)
        bench.step(0.2)
        out = bench.ds.sticks.outputs[0]
        assert out is not None and out.left_rumble == 0xFFFF and out.output(1)
        bench.hub.set_rumble(bench.ds.sticks.outputs)
        assert pad.rumbles and pad.rumbles[-1] == (0xFFFF, 0)
        pad.button(0, False)
        bench.step(0.2)
        bench.hub.set_rumble(bench.ds.sticks.outputs)
        assert pad.rumbles[-1] == (0, 0)
    finally:
        pad.unplug()
        bench.hub.close()


async def test_the_joysticks_panel_finds_a_virtual_joystick(sdl, monkeypatch, tmp_path):
    """The whole path in the app: the tab starts SDL when first shown, its 50 Hz poll finds
    the device plugged in afterwards, and the stick's moves reach the control packets."""
    from fieldbox.panels.joysticks import JoysticksPanel

    monkeypatch.setenv("FIELDBOX_JOYSTICKS", "auto")
    monkeypatch.setenv("XDG_CONFIG_HOME", str(tmp_path))
    app, _ = make_app(one_team(), "joysticks")
    async with app.run_test(size=SIZE) as pilot:
        wire = Wire(app.engine)
        app.engine.advance(1.0)
        await pilot.pause()
        panel = app.query_one(JoysticksPanel)
        assert panel.hub.started, panel.hub.devices_status
        pad = VirtualPad(sdl)
        try:
            pad.axis(3, -16384)
            await pilot.pause(0.1)  # a few real 50 Hz polls
            app.engine.advance(0.1)
            ds = app.engine.field.stations[0].ds
            assert ds.sticks.slots[0].name == "fieldbox virtual pad"
            assert ds.sticks.slots[1].name == "fieldbox keyboard"  # it gave slot 0 to the real pad
            assert wire.last_control().joysticks[0].axes[3] == -64
            app.refresh_views()
            assert "fieldbox virtual pad" in str(app.query_one("#js-slot-0").content)
        finally:
            pad.unplug()
        await pilot.pause(0.1)
        app.engine.advance(0.1)
        assert app.engine.field.stations[0].ds.sticks.slots[0] is None
