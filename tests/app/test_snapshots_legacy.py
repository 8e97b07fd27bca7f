"""SVG snapshot of the Legacy 2010 panel: a 2010 Driver Station and fake cRIO on a SimEngine
(a fake clock), so every byte on screen is the same on every run.

Update with ``pytest tests/app/test_snapshots_legacy.py --snapshot-update`` after a change that
is meant to show, and look at the SVG under tests/app/__snapshots__/ first.
"""

from __future__ import annotations

import pytest

from roles.runtime.field import FieldConfig

from .helpers import SIZE, make_app, step

pytestmark = pytest.mark.usefixtures("no_real_joysticks")  # no real joystick or user theme in the picture


def test_legacy_panel_enabled_with_inputs_set(snap_compare):
    """Team 294 in 2010 mode, enabled 1.5 s: DS digital inputs 1 and 3 on, analog input 2
    moved from the keyboard; the control byte, the robot's BCD battery and echo, its LCD, the
    dashboard counter and the NetConsole as they stand 2.5 s after the start."""
    app, _ = make_app(FieldConfig(team=294, legacy=True, roles=frozenset({"ds", "rio"})), "legacy")

    async def run_before(pilot) -> None:
        await step(pilot, 1.0)
        await pilot.press("1", "3")
        app.query_one("#legacy-analog-2").focus()
        await pilot.press("pageup", "pageup", "right")
        await pilot.press("e", "e")
        app.clear_notifications()  # a toast would cover a corner
        await step(pilot, 1.5)

    assert snap_compare(app, terminal_size=SIZE, run_before=run_before)
