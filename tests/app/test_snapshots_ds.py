"""SVG snapshots of the Driver Station and Joysticks panels, on a SimEngine advanced to a fixed
time so every figure (battery, trip time, countdown, packet counts) is the same each run.

Update with ``pytest tests/app/test_snapshots_ds.py --snapshot-update`` and look at the SVGs
under tests/app/__snapshots__/ before committing them.
"""

from __future__ import annotations

import pytest

from roles.runtime.field import FieldConfig

from .helpers import SIZE, make_app, one_team, step

pytestmark = pytest.mark.usefixtures("no_real_joysticks")  # no real joystick or user theme in the picture


def test_ds_panel_battery_history(snap_compare):
    """Disabled, robot code up; the battery sagged to 10.5 V, browned out at 6.5 V, recovered."""
    app, _ = make_app(one_team(), "ds")

    async def run_before(pilot) -> None:
        for volts, seconds in (("12.4", 10.0), ("10.5", 6.0), ("6.5", 2.0), ("12.2", 10.0)):
            app.run_command(f"battery {volts}")
            app.engine.advance(seconds)
        await step(pilot, 0.0)

    assert snap_compare(app, terminal_size=SIZE, run_before=run_before)


def test_ds_panel_practice_auto(snap_compare):
    """A practice run 5 s in: autonomous, enabled by the run, the countdown on the right."""
    app, _ = make_app(one_team(), "ds")

    async def run_before(pilot) -> None:
        await step(pilot, 1.0)
        await pilot.press("p")
        await step(pilot, 5.0)

    assert snap_compare(app, terminal_size=SIZE, run_before=run_before)


def test_ds_panel_field_selected_team(snap_compare):
    """Three stations of a field; the second team selected with ], e-stopped."""
    app, _ = make_app(FieldConfig(teams=[254, 1114, None, 118, None, None], roles=frozenset({"ds", "rio"})), "ds")

    async def run_before(pilot) -> None:
        await step(pilot, 1.0)
        await pilot.press("right_square_bracket", "space")
        app.clear_notifications()  # the e-stop toast would cover a corner
        await step(pilot, 1.0)

    assert snap_compare(app, terminal_size=SIZE, run_before=run_before)


def test_joysticks_panel_keyboard(snap_compare):
    """The keyboard joystick in step and toggle modes (nothing depends on real time): sticks
    moved, buttons 1 and 3 held, the POV right; the robot echoes them as rumble and outputs."""
    app, _ = make_app(one_team(), "joysticks")

    async def run_before(pilot) -> None:
        await step(pilot, 1.0)
        await pilot.press("v", "b", "d", "d", "d", "w", "i", "i", "j", "r", "1", "3", "0", "right")
        await step(pilot, 0.5)

    assert snap_compare(app, terminal_size=SIZE, run_before=run_before)
