"""SVG snapshot of the FMS panel: a full field of six teams, 5.3 s into auto.

The field runs on a SimEngine (a fake clock), so every number on screen is the same on every
run. Update with ``pytest tests/app/test_snapshots_fms.py --snapshot-update`` after a change
that is meant to show.
"""

from __future__ import annotations

from roles.runtime.field import FieldConfig

from .helpers import SIZE, make_app, step

TEAMS = [254, 1114, 2056, 118, 148, 1678]


def test_fms_panel_full_field_in_auto(snap_compare):
    app, engines = make_app(FieldConfig(teams=TEAMS), "fms")

    async def run_before(pilot) -> None:
        engine = engines[0]
        await step(pilot, 2.0)  # every DS logged in, every robot linked
        await pilot.press("4", "b")  # bypass B1: shown on its row
        await pilot.press("s")
        engine.advance(5.3)  # 5.3 s into auto: 15 s left
        app.refresh_views()
        await pilot.press("2", "x")  # e-stop R2
        await step(pilot, 0.1)

    assert snap_compare(app, terminal_size=SIZE, run_before=run_before)


def test_fms_panel_refused_start(snap_compare):
    app, engines = make_app(FieldConfig(teams=TEAMS), "fms")

    async def run_before(pilot) -> None:
        engine = engines[0]
        await step(pilot, 2.0)
        await pilot.press("2", "x")  # an e-stopped station refuses the start...
        engine.net.remove("ds 148")  # ...and so does a DS that went away
        engine.advance(2.0)
        app.refresh_views()
        await pilot.press("s")
        app.refresh_views()
        await pilot.pause()

    assert snap_compare(app, terminal_size=SIZE, run_before=run_before)
