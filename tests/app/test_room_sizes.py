"""Screens that read right at every size (issue 31, item 4): toasts that leave the Driver
Station's lights alone on a small screen, key hints that never part a key from what it does,
F8's network list whole, the Console tab's level boxes ticked without colour.

Each is a snapshot at 80x24 (an SSH window) and 160x50 (a demo screen), and asserts the text
a user reads there. Update with ``pytest tests/app/test_room_sizes.py --snapshot-update``
and look at the SVGs under tests/app/__snapshots__/test_room_sizes/ first.
"""

from __future__ import annotations

import pytest
from textual.widgets._toast import Toast

from fieldbox.widgets import key_hints

from roles.runtime.field import FieldConfig

from .helpers import make_app, one_team, step
from .test_snapshots_sizes import the_same_world  # noqa: F401 - a fixture: the console's clock

pytestmark = pytest.mark.usefixtures("no_real_joysticks", "the_same_world")

SIZES = {"80x24": (80, 24), "160x50": (160, 50)}


def screen_text(app) -> str:
    return "\n".join(strip.text for strip in app.screen._compositor.render_strips())


@pytest.mark.parametrize("size", list(SIZES))
def test_toasts_on_a_small_screen_are_few_and_leave_the_lights_alone(snap_compare, size):
    """At 80x24 three toasts stacked over the charts and the middle column's Communications
    and Robot code lights. Now a small screen shows the newest two (a big one three), the
    newest saying how many went before it, and a toast keeps to the right third."""
    app, _ = make_app(one_team(), "ds")
    seen: dict[str, object] = {}

    async def run_before(pilot) -> None:
        await step(pilot, 2.0)
        app.notify("first warning: the joystick went", severity="warning")
        app.notify("second: the robot asked for the date")
        app.notify("third: restart robot code requested")
        app.notify("fourth: E-STOP: restart robot code to clear it", severity="error")
        await pilot.pause()
        await pilot.pause()
        seen["text"] = screen_text(app)
        seen["toasts"] = len(app.screen.query(Toast))

    assert snap_compare(app, terminal_size=SIZES[size], run_before=run_before)
    text = str(seen["text"])
    small = size == "80x24"
    assert seen["toasts"] == (2 if small else 3)
    assert "fourth: E-STOP" in text and "third: restart" in text  # the newest, whole in reach
    assert ("second: the robot" in text) is (not small)
    assert "first warning" not in text  # the oldest went
    assert "+1 earlier" in text
    # the DS's lights read whole: no toast over the middle column
    for light in ("██ Communications", "██ Robot code", "██ Joysticks"):
        assert light in text, light
    # and its key hints, over the footer, read whole: toasts stay above them (a toast covered
    # "B  reboot   F1  more" at 80x24)
    lines = text.split("\n")
    hints = (["e e  enable   t a s  mode   p  practice   R  restart   B  reboot   F1  more"] if small else
             ["F1  again: Diagnostics, Setup, Charts", "R  restart code    B  reboot roboRIO"])
    for hint, line in zip(hints, lines[-1 - len(hints):-1]):
        assert hint in line, (hint, line)


@pytest.mark.parametrize("tab, hints", [
    ("ds", ["e e  enable   t a s  mode   p  practice   R  restart", "B  reboot   F1  more   [ ]  team"]),
    ("setup", ["This tab  g  game data    p  practice times    d  dashboard    Tab  next box",
               "Enter  apply    Esc  leave the box    ctrl+space  types a space"]),
])
async def test_toasts_never_cover_a_tabs_key_hints_at_80x24(tab, hints):
    """Two rows of hints on the DS tab of a field of two (and on the Setup tab), toasts up,
    and a switch of tab while they are: every hint row reads whole, each line of it on the
    screen as the tab writes it."""
    # no FMS: the DS tab's hints are its longest (an FMS takes e e, t a s and p off them)
    app, _ = make_app(FieldConfig(teams=[254, 1114], roles=frozenset({"ds", "rio"}), plan="ephemeral",
                                  log_files=False), "ds")
    async with app.run_test(size=(80, 24), notifications=True) as pilot:
        await step(pilot, 2.0)
        app.notify("first: restart robot code requested", timeout=60)
        app.notify("second: E-STOP: restart robot code to clear it", severity="error", timeout=60)
        await pilot.pause()
        if tab != "ds":
            app.action_show_tab(tab)
        await step(pilot, 1.0)
        await pilot.pause()
        text = screen_text(app)
        assert "second: E-STOP" in text  # the toasts are up
        lines = text.split("\n")
        for hint in hints:
            assert any(hint in line for line in lines), (hint, lines[-5:])


@pytest.mark.parametrize("width", [72, 80, 102, 160])
async def test_the_ds_tabs_key_hints_never_part_a_key_from_what_it_does(width):
    """Between 80 and 100 columns "F1" ended a line and "more" began the next, and from 100
    to about 125 "F1" ended one and "again: Diagnostics, Setup, Charts" began the next."""
    app, _ = make_app(one_team(), "ds")
    async with app.run_test(size=(width, 40)) as pilot:
        await step(pilot, 1.0)
        lines = screen_text(app).split("\n")
        hint = "F1  more" if width < 100 else "F1  again: Diagnostics, Setup, Charts"
        assert any(hint in line for line in lines), "\n".join(lines[-6:])
        assert not any(line.rstrip(" │").endswith(" F1 ") for line in lines)


@pytest.mark.parametrize("size", [(102, 30)])
def test_the_ds_tabs_key_hints_at_a_width_that_parted_them(snap_compare, size):
    app, _ = make_app(one_team(), "ds")

    async def run_before(pilot) -> None:
        await step(pilot, 1.0)
        app.clear_notifications()
        await pilot.pause()

    assert snap_compare(app, terminal_size=size, run_before=run_before)


def test_key_hints_break_between_keys_at_every_width():
    hints = key_hints([("Everywhere", [("e e", "enable"), ("Enter", "disable"), ("F1", "again: Diagnostics")]),
                       ("This tab", [("t a s", "teleop / auto / test"), ("R", "restart code")])], title_width=11)
    whole = [" e e  enable", " Enter  disable", " F1  again: Diagnostics", " t a s  teleop / auto / test",
             " R  restart code"]
    assert hints.plain.split("\n")[0].startswith("Everywhere")  # as text: a row a line
    for width in range(41, 120):  # from the widest key and its title on
        text = hints.laid_out(width).plain
        assert all(piece in text for piece in whole), (width, text)
        assert all(len(line) <= width for line in text.split("\n")), (width, text)


@pytest.mark.parametrize("size", list(SIZES))
def test_the_network_list_of_f8_shows_ephemeral_whole(snap_compare, size):
    """The network plan's list was 16 cells wide: "ephemera" over "l"."""
    app, _ = make_app(one_team(plan="ephemeral"), "ds")
    seen: dict[str, str] = {}

    async def run_before(pilot) -> None:
        await step(pilot, 1.0)
        app.clear_notifications()
        await pilot.press("f8")
        await pilot.pause()
        seen["text"] = screen_text(app)

    assert snap_compare(app, terminal_size=SIZES[size], run_before=run_before)
    network = next(line for line in seen["text"].split("\n") if " Network " in line)
    assert "ephemeral " in network, network


@pytest.mark.parametrize("size", list(SIZES))
def test_the_console_tabs_level_boxes_read_ticked_without_colour(snap_compare, size):
    """The level boxes were Textual's Checkbox: the same "X" ticked or not, in two colours."""
    app, _ = make_app(one_team(), "console")
    seen: dict[str, str] = {}

    async def run_before(pilot) -> None:
        await step(pilot, 1.0)
        app.clear_notifications()
        await pilot.click("#console-show-warning")  # hide the warnings
        await step(pilot, 0.1)
        seen["text"] = screen_text(app)

    assert snap_compare(app, terminal_size=SIZES[size], run_before=run_before)
    bar = next(line for line in seen["text"].split("\n") if "1 " in line and "2 warn" in line)
    assert "▐X▌ 1 " in bar and "▐ ▌ 2 warn" in bar and "▐X▌ 3 err" in bar, bar


@pytest.mark.parametrize("size", list(SIZES))
def test_a_browser_tabs_joysticks_tab_offers_the_keyboard_joystick(snap_compare, monkeypatch, size):
    """A served tab's Joysticks tab said "no joystick found: plug one in" (and read the
    server's own joysticks): a student's gamepad is in the browser's machine, it cannot reach
    the server. It says so, and that the keyboard joystick drives."""
    import fieldbox.app
    import fieldbox.joystick_input.hub as hub_module

    monkeypatch.setenv("FIELDBOX_JOYSTICKS", "auto")  # as a served tab is started: real joysticks would start

    def server_devices():
        raise AssertionError("a browser tab opened the server's joysticks")

    monkeypatch.setattr(hub_module, "PygameDevices", server_devices)
    monkeypatch.setattr(fieldbox.app.FieldboxApp, "is_web", property(lambda self: True))
    monkeypatch.setattr(fieldbox.app, "screen_reader_gone", lambda fd=None: False)  # its server is there
    app, _ = make_app(one_team(), "joysticks")
    seen: dict[str, str] = {}

    async def run_before(pilot) -> None:
        await step(pilot, 1.0)
        await pilot.press("N")  # a rescan, too, leaves the server's joysticks alone
        seen["said"] = " ".join(note.message for note in app._notifications)
        seen["offered"] = " ".join(active.binding.action for active in app.screen.active_bindings.values())
        app.clear_notifications()
        await step(pilot, 0.5)
        seen["text"] = screen_text(app)
        seen["started"] = str(app.query_one("#panel-joysticks").hub.started)

    assert snap_compare(app, terminal_size=SIZES[size], run_before=run_before)
    text = " ".join(seen["text"].split())
    assert "plug one in" not in text and "no joystick found" not in text
    assert "your gamepad cannot reach the field" in text and "keyboard joystick" in text
    assert seen["started"] == "False"
    # a browser's seat cannot rescan the server's joysticks: the key is not offered, on the
    # footer nor in the key help; pressed anyway, it says why
    footer = seen["text"].split("\n")[-1]
    assert "Rescan" not in footer and "rescan devices" not in text
    assert "rescan" not in seen["offered"].split() and "toggle_keyboard" in seen["offered"].split()
    assert "Keyboard on/off" in footer or size == "80x24"  # (80 columns cut the footer's end)
    assert "your gamepad cannot reach the field" in seen["said"]


async def test_a_terminals_joysticks_tab_offers_a_rescan(monkeypatch):
    """The other side of the browser's: in a terminal, N rescans this machine's joysticks."""
    import fieldbox.joystick_input.hub as hub_module

    from .test_joysticks import FakeDevices

    monkeypatch.setenv("FIELDBOX_JOYSTICKS", "auto")
    rescans = []

    class Devices(FakeDevices):
        def rescan(self):
            rescans.append(True)
            return super().rescan()

    monkeypatch.setattr(hub_module, "PygameDevices", Devices)
    app, _ = make_app(one_team(), "joysticks")
    async with app.run_test(size=(160, 50)) as pilot:
        await step(pilot, 1.0)
        footer = screen_text(app).split("\n")[-1]
        assert "N Rescan" in footer and "rescan devices" in screen_text(app)
        await pilot.press("N")
        await pilot.pause()
        assert rescans
