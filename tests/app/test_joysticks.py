"""Joystick input: the keyboard joystick, the slots (hot-plug, locking, the keyboard's place),
and the Joysticks panel driven through the app, checking the DS's control packets.

Real SDL devices are in test_virtual_joystick.py; here a fake device backend stands in for
pygame, so these run anywhere.
"""

from __future__ import annotations

import subprocess
import sys
from dataclasses import replace

import pytest

from protocol import ds_to_rio
from roles.cores.commands import ClearJoystick, DeclareJoystick, SetAxis, SetButton, SetPov
from roles.runtime.engine import SimEngine
from roles.runtime.field import FieldConfig

from fieldbox.joystick_input import (KEYBOARD_NAME, Descriptor, Device, DeviceError, JoystickHub,
                                     KeyboardJoystick, PygameDevices, Reading, describe_device)
from fieldbox.joystick_input import hub as hub_module
from fieldbox.panels.joysticks import JoysticksPanel

from .helpers import ROOT, SIZE, Harness, one_team, ui_modules_after


pytestmark = pytest.mark.usefixtures("no_real_joysticks")


# -- a device backend without SDL -------------------------------------------------------------
class FakeDevices:
    """What PygameDevices offers the hub, driven by the test."""

    def __init__(self) -> None:
        self.devices: dict[int, Device] = {}
        self.pending: list[tuple[str, Device]] = []
        self.values: dict[int, Reading] = {}
        self.rumbled: list[tuple[str, float, float]] = []
        self._ids = iter(range(100, 1000))

    def plug(self, name: str = "Gamepad F310", guid: str = "0300-f310", axes: int = 6, buttons: int = 10,
             hats: int = 1, *, at_start: bool = False) -> Device:
        dev = Device(next(self._ids), name, guid, describe_device(name, axes, buttons, hats))
        self.devices[dev.instance_id] = dev
        if not at_start:
            self.pending.append(("added", dev))
        return dev

    def unplug(self, dev: Device) -> None:
        del self.devices[dev.instance_id]
        self.pending.append(("removed", dev))

    def move(self, dev: Device, axes=None, buttons: int = 0, povs=None) -> None:
        d = dev.descriptor
        self.values[dev.instance_id] = Reading(tuple(axes or (0.0,) * d.axes), buttons,
                                               tuple(povs or (-1,) * d.povs))

    def open_all(self) -> list[Device]:
        return list(self.devices.values())

    def events(self):
        out, self.pending = self.pending, []
        return out

    def read(self, dev: Device) -> Reading:
        return self.values.get(dev.instance_id) or dev.descriptor.neutral()

    def set_rumble(self, dev: Device, left: float, right: float) -> None:
        if (left, right) != dev.rumble:
            dev.rumble = (left, right)
            self.rumbled.append((dev.name, left, right))

    def rescan(self) -> list[Device]:
        old = list(self.devices.values())
        self.devices.clear()
        self.pending.clear()
        return [self.plug(d.name, d.guid, d.descriptor.axes, d.descriptor.buttons, d.descriptor.povs,
                          at_start=True) for d in old]

    def close(self) -> None:
        pass


def declare(slot: int, d: Descriptor) -> DeclareJoystick:
    """What the hub sends the DS for a joystick plugged into ``slot``."""
    return DeclareJoystick(slot, d.name, d.axes, d.buttons, d.povs, d.is_xbox, d.joystick_type)


def names(hub: JoystickHub) -> list[str | None]:
    return [None if e is None else e.descriptor.name for e in hub.slots]


# -- the keyboard joystick --------------------------------------------------------------------
def test_spring_axis_holds_through_the_key_repeat_delay_then_returns():
    kb = KeyboardJoystick()
    assert kb.press("d", 0.0) and kb.axes[0] == 1.0
    assert not kb.tick(0.5)  # a single press holds past a terminal's ~0.5 s repeat delay
    kb.press("d", 0.5)  # repeats keep it
    kb.press("d", 0.53)
    assert not kb.tick(0.6) and kb.axes[0] == 1.0
    assert kb.tick(0.68) and kb.axes[0] == 0.0  # 0.15 s after the last repeat: back to 0
    assert kb.next_change() is None
    kb.press("w", 1.0)
    assert kb.axes[1] == -1.0  # w pushes forward: negative Y, as WPILib reads a stick
    kb.press("s", 1.1)
    assert kb.axes[1] == 1.0  # the other way at once
    assert kb.next_change() == pytest.approx(1.1 + kb.first_hold)


def test_step_axes_pulse_and_toggle_buttons_pov_and_centre():
    kb = KeyboardJoystick()
    kb.press("v", 0.0)
    assert kb.axis_mode == "step"
    for _ in range(3):
        kb.press("l", 0.0)
    kb.press("j", 0.0)
    assert kb.axes[4] == 0.5 and not kb.tick(100.0)  # steps stay
    for _ in range(9):
        kb.press("i", 0.0)
    assert kb.axes[5] == -1.0  # clamped
    kb.press("up", 0.0)
    assert kb.pov == 0 and not kb.tick(100.0)
    kb.press("c", 0.0)
    assert kb.axes == [0.0] * 6 and kb.pov == -1

    kb.press("1", 10.0)
    kb.press("=", 10.0)
    assert kb.buttons == 1 | 1 << 11
    assert kb.tick(10.25) and kb.buttons == 0  # a pulse is 0.2 s
    kb.press("b", 11.0)
    assert kb.button_mode == "toggle"
    kb.press("0", 11.0)
    assert kb.buttons == 1 << 9 and not kb.tick(50.0)
    kb.press("0", 51.0)
    assert kb.buttons == 0
    assert not kb.press("e", 0.0) and not kb.press("L", 0.0) and not kb.press("enter", 0.0)
    assert kb.reading() == Reading((0.0,) * 6, 0, (-1,))


def test_the_key_map_says_what_each_mode_does():
    kb = KeyboardJoystick()
    text = " ".join(f"{k} {v}" for k, v in kb.key_map())
    assert "w a s d" in text and "spring back" in text and "pulse" in text
    kb.press("v", 0.0)
    kb.press("b", 0.0)
    text = " ".join(f"{k} {v}" for k, v in kb.key_map())
    assert "step ±0.25" in text and "toggle per press" in text


# -- slots -------------------------------------------------------------------------------------
def test_first_device_takes_slot_0_from_the_keyboard_and_replug_keeps_slots():
    fake = FakeDevices()
    hub = JoystickHub(devices_factory=lambda: fake)
    assert names(hub)[0] == KEYBOARD_NAME
    assert hub.start_devices() == []
    assert hub.devices_status == "no joystick found: plug one in (hot-plug is on)"
    a = fake.plug()
    b = fake.plug()  # an identical second pad
    messages = hub.poll(0.0)
    assert messages == ["Gamepad F310 plugged in: slot 0", "Gamepad F310 plugged in: slot 2"]
    assert names(hub)[:3] == ["Gamepad F310", KEYBOARD_NAME, "Gamepad F310"]
    assert hub.devices_status == "2 joysticks found; hot-plug is on"
    fake.unplug(a)
    assert hub.poll(0.0) == ["Gamepad F310 unplugged: slot 0 is free"]
    fake.unplug(b)
    hub.poll(0.0)
    assert names(hub)[:3] == [None, KEYBOARD_NAME, None]
    # back in the other order: each n-th pad of its kind finds the slot it had
    b2 = fake.plug()
    a2 = fake.plug()
    hub.poll(0.0)
    assert hub.slots[0].device is b2 and hub.slots[2].device is a2  # the first one back is "n=0"


def test_a_placed_keyboard_stays_and_a_seventh_device_waits():
    fake = FakeDevices()
    hub = JoystickHub(devices_factory=lambda: fake)
    hub.start_devices()
    assert hub.move_keyboard(0) == "the keyboard joystick is already in slot 0"  # now placed by the user
    devs = [fake.plug(f"pad {i}", f"guid{i}") for i in range(6)]
    messages = hub.poll(0.0)
    assert names(hub) == [KEYBOARD_NAME, "pad 0", "pad 1", "pad 2", "pad 3", "pad 4"]
    assert messages[-1] == "pad 5 plugged in, but all six slots are taken"
    assert hub.toggle_keyboard().startswith("keyboard joystick off (slot 0 is free)")
    assert names(hub)[0] == "pad 5"  # the waiting device gets the freed slot
    assert hub.toggle_keyboard() == "all six slots are taken: free one for the keyboard joystick"
    fake.unplug(devs[2])
    hub.poll(0.0)
    assert hub.toggle_keyboard() == "keyboard joystick on: slot 3"


def test_move_keyboard_swaps_with_the_device_there():
    fake = FakeDevices()
    hub = JoystickHub(devices_factory=lambda: fake)
    hub.start_devices()
    fake.plug()
    hub.poll(0.0)
    assert names(hub)[:2] == ["Gamepad F310", KEYBOARD_NAME]
    assert hub.move_keyboard(0) == "keyboard joystick: slot 0"
    assert names(hub)[:2] == [KEYBOARD_NAME, "Gamepad F310"]


def test_lock_keeps_the_slot_through_unplug_and_rescan():
    fake = FakeDevices()
    hub = JoystickHub(keyboard=False, devices_factory=lambda: fake)
    fake.plug("Extreme 3D Pro", "046d-c215", 4, 12, 1, at_start=True)
    assert hub.start_devices() == ["Extreme 3D Pro plugged in: slot 0"]
    assert hub.slots[0].descriptor.joystick_type == 20  # a HID joystick by its name
    assert hub.toggle_lock(1) == "slot 1 is empty: nothing to lock"
    assert hub.toggle_lock(0) == "slot 0 locked to Extreme 3D Pro"
    fake.unplug(hub.slots[0].device)
    assert hub.poll(0.0) == ["Extreme 3D Pro unplugged: slot 0 stays locked to it (neutral until it returns)"]
    other = fake.plug("Gamepad F310")
    hub.poll(0.0)
    assert names(hub)[:2] == ["Extreme 3D Pro", "Gamepad F310"]  # slot 0 waits for its own device
    assert hub.wanted()[0] == (hub.slots[0].descriptor, Reading((0.0,) * 4, 0, (-1,)))
    fake.plug("Extreme 3D Pro", "046d-c215", 4, 12, 1)
    assert hub.poll(0.0) == ["Extreme 3D Pro is back in its locked slot 0"]
    messages = hub.rescan()  # new SDL instance ids, same slots
    assert names(hub)[:2] == ["Extreme 3D Pro", "Gamepad F310"] and hub.slots[0].locked
    assert "Gamepad F310 plugged in: slot 1" in messages and other not in hub.devices.devices.values()
    assert hub.toggle_lock(0) == "slot 0 unlocked from Extreme 3D Pro"


def test_updates_are_one_batch_of_what_changed():
    fake = FakeDevices()
    hub = JoystickHub(devices_factory=lambda: fake)
    first = hub.take_update()
    # the first update declares the keyboard and clears the other five slots
    assert first.changes == (declare(0, KeyboardJoystick.DESCRIPTOR),) + tuple(ClearJoystick(s) for s in range(1, 6))
    assert first.team is None  # the joystick tab says which DS
    assert hub.take_update() is None
    hub.start_devices()
    pad = fake.plug()
    hub.poll(0.0)
    # the pad takes slot 0 and the keyboard moves to slot 1: two declarations, values neutral
    assert hub.take_update().changes == (declare(0, pad.descriptor), declare(1, KeyboardJoystick.DESCRIPTOR))
    fake.move(pad, axes=(0.5, -1.0, 0, 0, 0, 0), buttons=0b101, povs=(270,))
    hub.keyboard.press("d", 0.0)
    hub.poll(0.0)
    ops = hub.take_update().changes
    assert ops == (SetAxis(0, 0, 0.5), SetAxis(0, 1, -1.0), SetButton(0, 1, True), SetButton(0, 3, True),
                   SetPov(0, 0, 270), SetAxis(1, 0, 1.0))
    fake.move(pad, axes=(0.502, -1.0, 0, 0, 0, 0), buttons=0b101, povs=(270,))  # jitter under one step
    hub.poll(0.0)
    assert hub.take_update() is None

    # the DS takes it as one command: the pad declared as it is, then its values
    engine = SimEngine(one_team())
    hub.forget_pushed()
    engine.execute(replace(hub.take_update(), team=254))
    pad_slot = engine.field.stations[0].ds.sticks.slots[0]
    assert (pad_slot.name, len(pad_slot.axes), pad_slot.button_count, pad_slot.is_xbox, pad_slot.joystick_type) \
        == ("Gamepad F310", 6, 10, False, 21)
    assert pad_slot.axes[1] == -1.0 and pad_slot.povs == [270] and pad_slot.buttons == 0b101


def test_rumble_goes_to_the_device_in_the_slot():
    fake = FakeDevices()
    hub = JoystickHub(devices_factory=lambda: fake)
    hub.start_devices()
    fake.plug()
    hub.poll(0.0)
    from protocol.rio_to_ds import JoystickOutput
    hub.set_rumble([JoystickOutput(0b1, 0, 0xFFFF), JoystickOutput(0, 0xFFFF, 0xFFFF)])
    assert fake.rumbled == [("Gamepad F310", 1.0, 0.0)]  # slot 1 is the keyboard: no motors
    hub.set_rumble([None] * 6)
    assert fake.rumbled[-1] == ("Gamepad F310", 0.0, 0.0)


def test_no_pygame_is_a_message(monkeypatch):
    monkeypatch.setitem(sys.modules, "pygame", None)  # import pygame raises ImportError
    with pytest.raises(DeviceError, match="pygame is not installed"):
        PygameDevices()
    hub = JoystickHub()
    [message] = hub.start_devices()
    assert message.startswith("pygame is not installed") and hub.devices_status == message
    assert not hub.started and hub.wanted()[0][0].name == KEYBOARD_NAME  # the keyboard still works


def test_only_the_joystick_parts_of_pygame_are_loaded():
    """``import pygame`` loads fonts, images and sound too (22.5 MB resident); joysticks need
    five of its modules (fieldbox/joystick_input/devices.py)."""
    pytest.importorskip("pygame")
    code = ("import sys\n"
            "from fieldbox.joystick_input.devices import PygameDevices\n"
            "d = PygameDevices()\n"
            "print(len(d.open_all()), sorted(m for m in sys.modules if m.startswith('pygame')))\n"
            "d.pg.joystick.quit(); d.pg.quit()")
    done = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, timeout=30)
    assert done.returncode == 0, done.stderr
    count, modules = done.stdout.split(" ", 1)
    assert int(count) >= 0
    assert "'pygame.joystick'" in modules and "'pygame.event'" in modules
    assert "'pygame.mixer'" not in modules and "'pygame.font'" not in modules and "'pygame.image'" not in modules


def test_describe_device_clips_to_the_protocol():
    d = describe_device("Xbox Wireless Controller", 20, 40, 13)
    assert d == Descriptor("Xbox Wireless Controller", 12, 32, 12, True, 1)


def test_joystick_input_imports_neither_textual_nor_pygame():
    assert ui_modules_after("import fieldbox.joystick_input as j; j.JoystickHub().take_update()") == []


# -- the panel, through the app ---------------------------------------------------------------
class JoystickHarness(Harness):
    """The app on the Joysticks tab, with the keyboard's springs on a clock of the test's own."""

    def __init__(self, config: FieldConfig | None = None, panel: str = "joysticks") -> None:
        super().__init__(config or one_team(), panel)
        self.t = 0.0

    @property
    def panel(self) -> JoysticksPanel:
        return self.app.query_one(JoysticksPanel)

    def start(self) -> None:
        self.panel.clock = lambda: self.t  # the keyboard's springs on a clock of our own

    def step(self, seconds: float = 0.06) -> None:
        """Time passes for the keys' springs and for the wire; one input poll; a redraw."""
        self.t += seconds
        self.panel.poll()
        self.engine.advance(seconds)
        self.app.refresh_views()

    def joystick(self, slot: int = 0, role: str = "ds 254") -> ds_to_rio.Joystick:
        """Slot ``slot`` as the newest control packet of ``role`` carried it."""
        joysticks = self.wire.last_control(role).joysticks
        return joysticks[slot] if slot < len(joysticks) else ds_to_rio.EMPTY_JOYSTICK

    def slot_text(self, slot: int) -> str:
        return str(self.app.query_one(f"#js-slot-{slot}").content)


async def test_keyboard_joystick_keys_reach_the_wire():
    h = JoystickHarness()
    async with h.app.run_test(size=SIZE) as pilot:
        h.start()
        h.step(1.0)
        ds = h.engine.field.stations[0].ds
        assert ds.sticks.slots[0].name == KEYBOARD_NAME  # declared as the DS starts
        wire = h.joystick(0)
        assert (len(wire.axes), wire.button_count, len(wire.povs)) == (6, 12, 1)
        assert h.app.focused is h.panel  # the tab takes focus so its keys work

        await pilot.press("d", "w", "1", "up")
        h.step()
        wire = h.joystick(0)
        assert wire.axes[:2] == (127, -128) and wire.pressed(1) and wire.povs == (0,)
        text = h.slot_text(0)
        assert "fieldbox keyboard" in text and "+1.00" in text and "-1.00" in text and "↑ 0°" in text
        h.step(0.1)  # the robot program echoes button 1: output 1 and left rumble
        assert "outputs 1" in h.slot_text(0) and "█" in h.slot_text(0).split("rumble L")[1][:8]

        h.step(0.2)  # the button's 0.2 s pulse is over; the stick is still held
        assert not h.joystick(0).pressed(1) and h.joystick(0).axes[0] == 127
        h.step(0.4)  # no key repeat came: the springs return
        wire = h.joystick(0)
        assert wire.axes[:2] == (0, 0) and wire.povs == (-1,)
        assert "outputs —" in h.slot_text(0)


async def test_keyboard_step_mode_and_centre():
    h = JoystickHarness()
    async with h.app.run_test(size=SIZE) as pilot:
        h.start()
        h.step(1.0)
        await pilot.press("v", "l", "l", "k")  # step mode: 0.25 per press, and it stays
        h.step(2.0)
        assert h.joystick(0).axes[4:6] == (64, 32)
        assert "step ±0.25" in str(h.app.query_one("#js-keys").content)
        await pilot.press("c")
        h.step()
        assert h.joystick(0).axes == (0,) * 6


async def test_app_keys_still_work_on_the_joysticks_tab():
    h = JoystickHarness()
    async with h.app.run_test(size=SIZE) as pilot:
        h.start()
        h.step(1.0)
        ds = h.engine.field.stations[0].ds
        await pilot.press("e", "e")  # e is the app's: not a joystick key
        h.step()
        assert ds.enabled and h.wire.last_control().enabled
        await pilot.press("space")
        h.step()
        assert ds.arbiter.estopped and h.wire.last_control().estop


async def test_joystick_keys_work_only_on_the_joysticks_tab():
    h = JoystickHarness(panel="ds")
    async with h.app.run_test(size=SIZE) as pilot:
        h.start()
        h.step(1.0)
        await pilot.press("d", "w")  # on the Driver Station tab these are nothing
        h.step()
        assert h.joystick(0).axes == (0,) * 6
        await pilot.press("f2", "d")
        h.step()
        assert h.joystick(0).axes[0] == 127


async def test_slot_keys_move_and_switch_off_the_keyboard():
    h = JoystickHarness()
    async with h.app.run_test(size=SIZE) as pilot:
        h.start()
        h.step(1.0)
        await pilot.press("full_stop", "m")
        h.step()
        assert h.joystick(0).is_empty and h.joystick(1).axes == (0,) * 6
        assert h.slot_text(0).endswith("— empty —") and h.slot_text(1).startswith("▶ 1 fieldbox keyboard")
        assert "keyboard joystick: slot 1" in h.messages
        await pilot.press("d")
        h.step()
        assert h.joystick(1).axes[0] == 127
        await pilot.press("K")
        h.step()
        ds = h.engine.field.stations[0].ds
        assert ds.sticks.slots == [None] * 6 and all(j.is_empty for j in h.wire.last_control().joysticks)
        assert "is off (K turns it on)" in str(h.app.query_one("#js-keys").content)
        await pilot.press("d")  # off: the key is not the joystick's any more
        h.step()
        assert ds.sticks.slots[1] is None


async def test_devices_hot_plug_and_lock_in_the_panel(monkeypatch):
    monkeypatch.setenv("FIELDBOX_JOYSTICKS", "auto")
    fake = FakeDevices()
    # the hub's devices before the app runs: it starts them after the tab's first refresh,
    # which may come before the test's first line inside run_test
    monkeypatch.setattr(hub_module, "PygameDevices", lambda: fake)
    h = JoystickHarness()
    async with h.app.run_test(size=SIZE) as pilot:
        h.start()
        await pilot.pause()
        h.step(1.0)
        assert h.panel.hub.started  # started because the tab was shown
        pad = fake.plug("Logitech Dual Action", "046d-c216", 4, 12, 1)
        h.step()
        assert "Logitech Dual Action plugged in: slot 0" in h.messages
        fake.move(pad, axes=(0.0, 0.0, -0.5, 0.0), buttons=1 << 11)
        h.step()
        assert h.joystick(0).axes == (0, 0, -64, 0) and h.joystick(0).pressed(12)
        assert h.joystick(1).axes == (0,) * 6  # the keyboard moved over for the real pad
        await pilot.press("L")
        fake.unplug(pad)
        h.step()
        assert "[locked]" in h.slot_text(0) and "unplugged" in h.slot_text(0)
        assert h.joystick(0).axes == (0, 0, 0, 0) and not h.joystick(0).pressed(12)  # neutral, still declared
        head = str(h.app.query_one("#js-head").content)
        assert "Joysticks drive team 254" in head and "no joystick found" in head


async def test_no_sdl_is_a_message_not_a_crash(monkeypatch):
    monkeypatch.setenv("FIELDBOX_JOYSTICKS", "auto")

    def broken():
        raise DeviceError("SDL could not start joysticks: no joystick backend")

    monkeypatch.setattr(hub_module, "PygameDevices", broken)  # before the hub starts them
    h = JoystickHarness()
    async with h.app.run_test(size=SIZE) as pilot:
        await pilot.press("N")
        h.step(0.5)
        assert "SDL could not start joysticks: no joystick backend" in h.messages
        assert "no joystick backend" in str(h.app.query_one("#js-head").content)
        assert h.joystick(0).axes == (0,) * 6  # the keyboard joystick carries on


async def test_joysticks_follow_the_selected_team():
    h = JoystickHarness(FieldConfig(teams=[254, 1114], roles=frozenset({"ds", "rio"})))
    async with h.app.run_test(size=SIZE) as pilot:
        h.start()
        h.step(1.0)
        await pilot.press("d")
        h.step()
        assert h.joystick(0, "ds 254").axes[0] == 127 and h.joystick(0, "ds 1114").is_empty
        h.app.selected_team = 1114
        h.step()
        assert h.joystick(0, "ds 254").is_empty and h.joystick(0, "ds 1114").axes[0] == 127
        assert "Joysticks drive team 1114" in str(h.app.query_one("#js-head").content)


def test_axis_level_and_pov_pictures():
    from fieldbox.widgets import axis_bar, level_bar, pov_arrow

    assert axis_bar(0.0, 9).plain == "····│····"
    assert axis_bar(1.0, 9).plain == "····│████"
    assert axis_bar(-1.0, 9).plain == "████│····"
    assert axis_bar(0.75, 9).plain == "····│███·"
    assert axis_bar(-0.125, 9).plain == "···▐│····"  # half cells next to the centre
    assert axis_bar(float("nan"), 9).plain == "····│····"
    assert level_bar(0.0, 4).plain == "····" and level_bar(1.0, 4).plain == "████"
    assert level_bar(0.5 + 1 / 32, 4).plain == "██▏·"  # eighths
    assert [pov_arrow(d) for d in (-1, 0, 45, 90, 180, 270, 315)] == ["·", "↑", "↗", "→", "↓", "←", "↖"]
