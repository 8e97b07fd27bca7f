"""The roles dialog (F8) as a keyboard form (issue 20): Tab moves, x ticks or opens, ctrl+s picks
or applies, Esc cancels. Space and Enter stay the robot's e-stop and disable while it is open
(issue 31: tests/app/test_robot_keys.py)."""

from __future__ import annotations

from protocol.enums import AllianceStation
from roles.runtime.field import FieldConfig

from fieldbox.picker import RolePicker

from .helpers import make_app, step


async def test_the_roles_dialog_works_from_the_keyboard_alone_and_its_keys_never_drive_the_robot():
    app, engines = make_app(FieldConfig(team=254, roles=frozenset({"ds", "rio"})))
    async with app.run_test(size=(160, 50)) as pilot:
        await step(pilot, 0.5)
        ds = engines[0].field.stations[0].ds
        app.run_command("enable")
        await step(pilot, 0.1)
        assert ds.enabled
        await pilot.press("f8")
        assert isinstance(app.screen, RolePicker)
        assert app.focused.id == "role-ds"
        # every field of the form is on screen, the station beside the team
        dialog = app.screen.query_one("Vertical").region
        for wid in ("#team", "#station", "#plan", "#legacy", "#apply", "#cancel"):
            region = app.screen.query_one(wid).region
            assert region.width > 0 and dialog.contains_region(region), wid
        await pilot.press("tab", "tab")  # to FMS
        assert app.focused.id == "role-fms"
        await pilot.press("x")  # ticks the box, and the robot is not e-stopped
        await step(pilot, 0.1)
        assert app.screen.query_one("#role-fms").value and not ds.arbiter.estopped and ds.enabled
        await pilot.press("tab")
        assert app.focused.id == "team"
        await pilot.press("end", "backspace", "backspace", "backspace", "1", "1", "1", "4")
        await pilot.press("tab", "x")  # the station list opens with x ...
        await pilot.press("down", "down", "down", "ctrl+s")  # ... and ctrl+s picks B1, not Apply
        assert isinstance(app.screen, RolePicker)
        assert app.screen.query_one("#station").value == AllianceStation.BLUE1
        assert ds.enabled  # nothing of the form's drove the robot
        await pilot.press("ctrl+s")  # from anywhere in the form: Apply
        await pilot.pause()
        assert len(engines) == 2
        config = engines[1].field.config
        assert config.roles == frozenset({"ds", "rio", "fms"}) and config.team == 1114
        assert config.station == AllianceStation.BLUE1
        assert not isinstance(app.screen, RolePicker)


async def test_escape_and_x_on_cancel_change_nothing_and_a_bad_team_says_why():
    app, engines = make_app(FieldConfig(team=254, roles=frozenset({"ds", "rio"})))
    async with app.run_test(size=(80, 24)) as pilot:
        await step(pilot, 0.2)
        await pilot.press("f8", "x", "escape")  # untick the DS, then cancel
        await pilot.pause()
        assert not isinstance(app.screen, RolePicker) and len(engines) == 1
        await pilot.press("f8")
        app.screen.query_one("#cancel").focus()
        await pilot.press("x")
        await pilot.pause()
        assert not isinstance(app.screen, RolePicker) and len(engines) == 1
        await pilot.press("f8", "tab", "tab", "tab", "end", "backspace", "backspace", "backspace", "0", "ctrl+s")
        await pilot.pause()
        assert isinstance(app.screen, RolePicker) and len(engines) == 1
        assert "team" in str(app.screen.query_one("#picker-error").render()).lower()
        assert app.focused.id == "team"


async def test_a_ticked_box_and_an_unticked_one_differ_without_colour():
    """Textual's Checkbox draws the same "X" ticked or not, in another colour: no use without colour."""
    app, engines = make_app(FieldConfig(team=254, roles=frozenset({"ds", "rio"})))
    async with app.run_test(size=(80, 24)) as pilot:
        await step(pilot, 0.2)
        await pilot.press("f8")
        picker = app.screen

        def mark(wid: str) -> str:
            return picker.query_one(wid).render().plain.split(" ", 1)[0]  # the text, styles left out

        assert picker.query_one("#role-ds").value and not picker.query_one("#role-fms").value
        ticked, unticked = mark("#role-ds"), mark("#role-fms")
        assert ticked != unticked and "X" in ticked and "X" not in unticked
        await pilot.press("x")  # untick the DS: its mark becomes the unticked one
        await pilot.pause()
        assert not picker.query_one("#role-ds").value and mark("#role-ds") == unticked
        await pilot.press("escape")
