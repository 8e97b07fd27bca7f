"""Layouts that fit (issue 20, item 3): at 80x24, a small SSH window, every tab keeps what a
diagnosis needs on screen; on a big one, panels take the rows they are given. What a person
would see, measured on the widgets' regions (the snapshots in test_snapshots_sizes.py show it).
"""

from __future__ import annotations

import pytest
from textual.widgets import Button, DataTable, Footer
from textual.widgets._footer import FooterKey

from roles.runtime.field import FieldConfig

from fieldbox.app import panel_classes

from .helpers import Harness, make_app, step

pytestmark = pytest.mark.usefixtures("no_real_joysticks")

SMALL = (80, 24)
FIELD = [254, 1114, 2056, 118, 148, 1678]


def on_screen(widget, width: int) -> bool:
    region = widget.region
    return region.width > 0 and region.height > 0 and region.right <= width


async def test_at_80x24_every_tabs_footer_keeps_space_enter_and_ctrl_q():
    app, _ = make_app(FieldConfig(team=254), "ds")
    async with app.run_test(size=SMALL) as pilot:
        await step(pilot, 1.0)
        for cls in panel_classes():
            app.action_show_tab(cls.ID)
            await pilot.pause()
            await pilot.pause()
            keys = {key.key for key in app.query_one(Footer).query(FooterKey)
                    if key.display and on_screen(key, SMALL[0])}
            assert {"space", "enter", "ctrl+q"} <= keys, cls.ID


async def test_at_80x24_the_field_shows_six_teams_and_the_buttons_keep_their_keys():
    app, _ = make_app(FieldConfig(teams=FIELD, roles=frozenset({"ds", "rio"})), "ds")
    async with app.run_test(size=SMALL) as pilot:
        await step(pilot, 1.0)
        teams = list(app.query("#ds-teams Button").results(Button))
        assert [str(b.label) for b in teams][-1] == "B3 1678"
        assert all(on_screen(b, SMALL[0]) and b.region.width >= len(str(b.label)) for b in teams)
        keys = {"ds-mode-teleop": "t", "ds-mode-auto": "a", "ds-mode-test": "s", "ds-enable-btn": "e e",
                "ds-disable-btn": "⏎", "ds-estop-btn": "Space", "ds-restart-btn": "R", "ds-reboot-btn": "B"}
        for ident, key in keys.items():
            button = app.query_one(f"#{ident}", Button)
            label = str(button.label)
            assert label.endswith(key) and button.region.width >= len(label), (ident, label, button.region)
            assert button.region.bottom <= SMALL[1] - 1  # above the footer: nothing to scroll to


async def test_at_80x24_the_faults_table_shows_its_rows():
    # issue 20: the table shrank to no row at all under the help and the fault injector
    app, _ = make_app(FieldConfig(teams=FIELD), "faults")
    async with app.run_test(size=SMALL) as pilot:
        await step(pilot, 1.0)
        table = app.query_one("#faults-table", DataTable)
        assert table.region.height >= 8 and on_screen(table, SMALL[0])  # its header and seven rows or more
        assert app.query_one("#fault-spec").region.bottom <= SMALL[1] - 1  # the injector's input too
        assert not app.query_one("#fault-table").display  # no fault on: its table gives its rows


async def test_at_80_columns_the_fms_table_keeps_its_stops_and_status():
    app, _ = make_app(FieldConfig(teams=FIELD), "fms")
    async with app.run_test(size=SMALL) as pilot:
        await step(pilot, 2.0)
        await pilot.press("2", "x")  # e-stop R2
        await step(pilot, 0.2)
        table = app.query_one("#fms-stations", DataTable)
        keys = [c.key.value for c in table.ordered_columns]
        assert {"estop", "astop", "status", "bypass", "team"} <= set(keys)
        widths = sum(c.get_render_width(table) for c in table.ordered_columns)
        assert widths <= table.region.width  # every column on screen, none scrolled off
        assert str(table.get_cell("R2", "estop")) == "E-STOP"
        assert str(table.get_cell("R2", "status")) == "FMS e-stop"  # issue 29: it read "ready"
        await pilot.resize_terminal(160, 50)  # wide again: every column back
        await step(pilot, 0.2)
        assert {"trip", "lost", "radio", "rio", "field"} <= {c.key.value for c in table.ordered_columns}
        assert str(table.get_cell("R2", "estop")) == "E-STOP"


async def test_a_fault_is_shown_whole_in_the_injectors_table():
    # issue 20: "loss=50%" was shown as "loss=5"
    h = Harness(FieldConfig(team=254), "faults")
    async with h.app.run_test(size=(160, 50)) as pilot:
        h.run(1.0)
        h.app.run_command("fault ds-rio:loss=50%,delay=30ms~10ms")
        h.run(0.5)
        await pilot.pause()
        table = h.app.query_one("#fault-table", DataTable)
        text = str(table.get_cell("ds-rio", "fault"))
        assert "loss=50%" in text and table.columns["fault"].content_width >= len(text)


async def test_a_big_screen_gives_its_rows_to_the_charts_and_the_lists():
    app, _ = make_app(FieldConfig(team=254), "ds")
    async with app.run_test(size=(200, 60)) as pilot:
        await step(pilot, 1.0)
        assert app.query_one("#ds-chart").region.height >= 12  # the battery chart, 6 rows at 120x40 before
        assert app.query_one("#ds-messages").region.height >= 12
        app.action_show_tab("fms")
        await step(pilot, 0.5)
        assert app.query_one("#fms-log").region.height >= 20  # the match log takes what is left
        app.action_show_tab("charts")
        await step(pilot, 0.5)
        assert all(app.query_one(f"#{c}").region.height >= 20 for c in ("chart-trip", "chart-battery"))
        app.action_show_tab("timeline")
        await step(pilot, 2.0)
        assert len(app.query_one("#timeline-view").hops) >= 40  # more packets of each link
