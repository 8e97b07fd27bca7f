"""Space e-stops and Enter disables wherever the focus is, as on the NI Driver Station (issue 31):
in a tab's text box, the roles dialog (F8), a path prompt, the command palette. Each place is
tested with a robot enabled, on the wire: the DS's control packets carry the e-stop bit, or
stop carrying the enabled bit. The dialogs' own controls have keys of their own (x, ctrl+s),
and a text box types a space with ctrl+space."""

from __future__ import annotations

import pytest
from textual.widgets import Input

from protocol.enums import AllianceStation
from roles.runtime.field import FieldConfig

from fieldbox.picker import RolePicker
from fieldbox.widgets import Palette, PathPrompt

from .helpers import SIZE, Harness, one_team, until

#: How to get there, from the tab the app starts on: (tab, keys, what must then hold).
PLACES = {
    # a tab's text boxes, each reached with its own key
    "console filter": ("console", ("slash",), lambda app: app.focused.id == "console-filter"),
    "setup game data": ("setup", ("g",), lambda app: app.focused.id == "setup-game-data"),
    "FMS period lengths": ("fms", ("d",), lambda app: app.focused.id == "fms-auto"),
    # the dialogs
    "roles dialog": ("ds", ("f8",), lambda app: isinstance(app.screen, RolePicker)),
    "roles dialog, team box": ("ds", ("f8", "tab", "tab", "tab"),
                               lambda app: isinstance(app.screen, RolePicker) and app.focused.id == "team"),
    "roles dialog, open list": ("ds", ("f8", "tab", "tab", "tab", "tab", "down"),
                                lambda app: isinstance(app.screen, RolePicker)
                                and app.screen.query_one("#station").expanded),
    "path prompt": ("inspector", ("R",), lambda app: isinstance(app.screen, PathPrompt)),
    "command palette": ("ds", ("ctrl+p", "t", "h", "e"),
                        lambda app: isinstance(app.screen, Palette) and app.focused.value == "the"),
}


async def enabled_at(pilot, h: Harness, place: str):
    """The robot enabled (by an FMS's match: its period boxes show only with one), then the
    focus at ``place``. The DS."""
    tab, keys, there = PLACES[place]
    h.run(1.0)
    ds = h.engine.field.stations[0].ds
    if h.engine.field.fms is not None:
        assert h.app.run_command("match start")
    else:
        await pilot.press("e", "e")
    h.run(0.5)
    assert ds.enabled and h.wire.last_control().enabled
    if tab != "ds":
        h.app.action_show_tab(tab)
        await pilot.pause()
    await pilot.press(*keys)
    await pilot.pause()
    assert there(h.app), place
    return ds


def field_for(place: str) -> FieldConfig:
    return FieldConfig(team=254) if place.startswith("FMS") else one_team()


@pytest.mark.parametrize("place", list(PLACES))
async def test_space_estops_the_robot_wherever_the_focus_is(place):
    h = Harness(field_for(place))
    async with h.app.run_test(size=SIZE) as pilot:
        ds = await enabled_at(pilot, h, place)
        screen, mark = h.app.screen, h.wire.mark()
        await pilot.press("space")
        h.run(0.2)
        sent = h.wire.ds_control(mark)
        assert sent and all(p.estop for p in sent[1:]) and not sent[-1].enabled, place
        assert ds.arbiter.estopped
        assert h.app.screen is screen  # the dialog stays open: its own keys are other keys
        if isinstance(h.app.focused, Input):
            assert " " not in h.app.focused.value  # the space went to the robot, not the box


@pytest.mark.parametrize("place", list(PLACES))
async def test_enter_disables_the_robot_wherever_the_focus_is(place):
    h = Harness(field_for(place))
    async with h.app.run_test(size=SIZE) as pilot:
        ds = await enabled_at(pilot, h, place)
        screen, theme, mark = h.app.screen, h.app.theme, h.wire.mark()
        await pilot.press("enter")
        h.run(0.2)
        sent = h.wire.ds_control(mark)
        assert sent and not any(p.enabled for p in sent[1:]) and not sent[-1].estop, place
        assert not ds.enabled and not ds.arbiter.estopped
        # Enter is neither a dialog's Apply nor the palette's Run: the dialog stays open, the
        # field and the theme as they were
        assert h.app.screen is screen and len(h.engines) == 1 and h.app.theme == theme


@pytest.mark.parametrize("place", ["console filter", "setup game data", "FMS period lengths"])
async def test_a_text_box_with_the_focus_leaves_space_e_stop_in_the_footer(place):
    # Textual leaves out of the footer every key the focused widget takes, and a text box
    # took Space: the footer said "Disable" but not "E-stop" while Space still e-stopped.
    h = Harness(field_for(place))
    async with h.app.run_test(size=SIZE) as pilot:
        await enabled_at(pilot, h, place)
        await pilot.pause()
        footer = [strip.text for strip in h.app.screen._compositor.render_strips()][-1]
        assert "space E-stop" in footer and "⏎ Disable" in footer, (place, footer)


async def test_in_a_text_box_ctrl_space_types_a_space_and_space_estops():
    """In the console's filter: ctrl+space (NUL from a terminal, "ctrl+@"; "ctrl+space" from
    the kitty protocol) types a space over the selection or at the cursor; Space e-stops and
    types nothing; Enter disables and still applies the box."""
    h = Harness(one_team(), "console")
    async with h.app.run_test(size=SIZE) as pilot:
        ds = await enabled_at(pilot, h, "console filter")
        await pilot.press("a", "ctrl+@", "b", "ctrl+space", "c")
        box = h.app.query_one("#console-filter", Input)
        assert box.value == "a b c" and ds.enabled and not ds.arbiter.estopped
        h.run(0.1)  # and the console's status line says how a space is typed there
        assert str(h.app.query_one("#console-status").render()).startswith("ctrl+space types a space")
        await pilot.press("enter")  # disables, and applies the filter (the focus goes to the lines)
        h.run(0.2)
        assert not ds.enabled and not h.wire.last_control().enabled
        assert h.app.focused is not box and box.value == "a b c"
        await pilot.press("slash", "space")
        h.run(0.2)
        assert ds.arbiter.estopped and h.wire.last_control().estop and box.value == "a b c"


async def test_the_roles_dialog_ticks_opens_picks_and_applies_with_its_own_keys():
    h = Harness(one_team())
    async with h.app.run_test(size=SIZE) as pilot:
        ds = await enabled_at(pilot, h, "roles dialog")
        await pilot.press("tab", "tab", "x")  # FMS ticked with x
        assert h.app.focused.id == "role-fms" and h.app.screen.query_one("#role-fms").value
        await pilot.press("tab", "end", "backspace", "backspace", "backspace", *"1114")
        await pilot.press("tab", "x")  # the station list opens with x ...
        station = h.app.screen.query_one("#station")
        assert station.expanded
        await pilot.press("down", "down", "down", "ctrl+s")  # ... and ctrl+s picks B1, not Apply
        assert not station.expanded and station.value == AllianceStation.BLUE1
        h.run(0.2)
        assert ds.enabled and not ds.arbiter.estopped and len(h.engines) == 1  # nothing of that drove the robot
        await pilot.press("ctrl+s")  # apply, from anywhere in the form
        await pilot.pause()
        assert not isinstance(h.app.screen, RolePicker) and len(h.engines) == 2
        config = h.engine.field.config
        assert config.roles == frozenset({"ds", "rio", "fms"}) and config.team == 1114
        assert config.station == AllianceStation.BLUE1
        # and the dialog says so: its keys line and its buttons
        await pilot.press("f8")
        keys = str(h.app.screen.query_one("#picker-keys").render())
        assert "x ticks" in keys and "ctrl+s picks/applies" in keys
        assert "Space e-stops" in str(h.app.screen.query_one("#picker-title").render())
        assert "ctrl+s" in str(h.app.screen.query_one("#apply").label)


async def test_the_palette_runs_a_command_with_ctrl_s_and_types_a_space_with_ctrl_space():
    h = Harness(one_team())
    async with h.app.run_test(size=(100, 30)) as pilot:
        ds = await enabled_at(pilot, h, "command palette")
        palette = h.app.screen
        search = palette.query_one(Input)
        assert "ctrl+s runs" in search.placeholder and "Space e-stops" in search.placeholder
        await pilot.press(*"me", "ctrl+@", *"alli")
        assert search.value == "theme alli"
        await pilot.pause(0.3)  # the search runs
        await pilot.press("ctrl+s", "ctrl+s")  # the first match highlighted, then run
        await pilot.pause(0.2)
        assert h.app.theme == "alliance" and not isinstance(h.app.screen, Palette)
        h.run(0.2)
        assert ds.enabled and not ds.arbiter.estopped


async def test_the_path_prompt_writes_with_ctrl_s_and_takes_a_space_with_ctrl_space(tmp_path):
    h = Harness(one_team(), "inspector")
    async with h.app.run_test(size=SIZE) as pilot:
        ds = await enabled_at(pilot, h, "path prompt")
        box = h.app.screen.query_one(Input)
        box.value = str(tmp_path / "my")
        box.action_end()
        await pilot.press("ctrl+@", *"wire.pcap")
        assert box.value == str(tmp_path / "my wire.pcap")
        await pilot.press("ctrl+s")
        await pilot.pause()
        assert not isinstance(h.app.screen, PathPrompt)
        h.run(0.3)
        assert (tmp_path / "my wire.pcap").stat().st_size > 24 and ds.enabled


async def test_in_a_classroom_space_in_the_palette_estops_a_drivers_robot_and_an_observer_is_refused():
    """A served tab is the same app with the same keys; the classroom's rules stay: an
    observer's Space e-stops nothing (the field refuses and the tab says why), a driver's
    e-stops its own robot, from the command palette too. (The classroom's FMS decides enable:
    the robot is disabled here, and an e-stop holds all the same.)"""
    from fieldbox.app import FieldboxApp
    from roles.runtime.classroom import ClassroomProcess, JoinedEngine

    host = ClassroomProcess(FieldConfig(teams=[254], plan="ephemeral", log_files=False))
    host.start()
    try:
        for seat in ("observer", "driver"):
            def joined(cfg, seat=seat):
                engine = JoinedEngine(host.path, seat, cfg)
                engine.start()
                return engine

            app = FieldboxApp(joined, FieldConfig(plan="ephemeral", log_files=False), animate=False)
            notes: list[str] = []
            notify = app.notify
            app.notify = lambda message, *a, **kw: (notes.append(str(message)), notify(message, *a, **kw))[1]
            async with app.run_test(size=SIZE) as pilot:
                def ds():
                    return app.engine.field.stations[0].ds

                assert await until(pilot, lambda: ds() is not None and ds().link.robot_comms)
                await pilot.press("ctrl+p")
                assert await until(pilot, lambda: isinstance(app.screen, Palette))
                await pilot.press("space")
                if seat == "observer":
                    assert await until(pilot, lambda: any("you watch this field" in n for n in notes))
                    await pilot.pause(0.5)
                    assert not ds().arbiter.estopped
                else:
                    assert await until(pilot, lambda: ds().arbiter.estopped)
                assert isinstance(app.screen, Palette)
    finally:
        host.stop()
