"""SVG snapshots of the Driver Station and Joysticks panels, on a SimEngine advanced to a fixed
time so every figure (battery, trip time, countdown, packet counts) is the same each run.

Update with ``pytest tests/app/test_snapshots_ds.py --snapshot-update`` and look at the SVGs
under tests/app/__snapshots__/ before committing them.
"""

from __future__ import annotations

import pytest

from roles.engine import SimEngine
from roles.field import FieldConfig

from fieldbox.app import FieldboxApp

SIZE = (120, 40)


@pytest.fixture(autouse=True)
def fixed_environment(monkeypatch, tmp_path):
    monkeypatch.setenv("FIELDBOX_JOYSTICKS", "off")  # no real joystick in the picture
    monkeypatch.setenv("XDG_CONFIG_HOME", str(tmp_path))  # no user theme either


def make_app(config: FieldConfig, panel: str) -> FieldboxApp:
    return FieldboxApp(SimEngine, config, panel=panel, animate=False)


async def settle(pilot, app: FieldboxApp, seconds: float) -> None:
    app.engine.advance(seconds)
    app.refresh_views()
    await pilot.pause()


def test_ds_panel_battery_history(snap_compare):
    """Disabled, robot code up; the battery sagged to 10.5 V, browned out at 6.5 V, recovered."""
    app = make_app(FieldConfig(team=254, roles=frozenset({"ds", "rio"})), "ds")

    async def run_before(pilot) -> None:
        for volts, seconds in (("12.4", 10.0), ("10.5", 6.0), ("6.5", 2.0), ("12.2", 10.0)):
            app.run_command(f"battery {volts}")
            app.engine.advance(seconds)
        await settle(pilot, app, 0.0)

    assert snap_compare(app, terminal_size=SIZE, run_before=run_before)


def test_ds_panel_practice_auto(snap_compare):
    """A practice run 5 s in: autonomous, enabled by the run, the countdown on the right."""
    app = make_app(FieldConfig(team=254, roles=frozenset({"ds", "rio"})), "ds")

    async def run_before(pilot) -> None:
        await settle(pilot, app, 1.0)
        await pilot.press("p")
        await settle(pilot, app, 5.0)

    assert snap_compare(app, terminal_size=SIZE, run_before=run_before)


def test_ds_panel_field_selected_team(snap_compare):
    """Three stations of a field; the second team selected with ], e-stopped."""
    app = make_app(FieldConfig(teams=[254, 1114, None, 118, None, None], roles=frozenset({"ds", "rio"})), "ds")

    async def run_before(pilot) -> None:
        await settle(pilot, app, 1.0)
        await pilot.press("right_square_bracket", "space")
        app.clear_notifications()  # the e-stop toast would cover a corner
        await settle(pilot, app, 1.0)

    assert snap_compare(app, terminal_size=SIZE, run_before=run_before)


def test_joysticks_panel_keyboard(snap_compare):
    """The keyboard joystick in step and toggle modes (nothing depends on real time): sticks
    moved, buttons 1 and 3 held, the POV right; the robot echoes them as rumble and outputs."""
    app = make_app(FieldConfig(team=254, roles=frozenset({"ds", "rio"})), "joysticks")

    async def run_before(pilot) -> None:
        await settle(pilot, app, 1.0)
        await pilot.press("v", "b", "d", "d", "d", "w", "i", "i", "j", "r", "1", "3", "0", "right")
        await settle(pilot, app, 0.5)

    assert snap_compare(app, terminal_size=SIZE, run_before=run_before)
