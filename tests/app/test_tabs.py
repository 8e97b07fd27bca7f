"""Changing tabs: the tab picked is the one shown, and its panel has the keys.

Textual makes the tab of a widget that receives the focus the active one, and focus moves
are queued. Before FieldboxTabs (fieldbox/widgets.py) and the app's ``_focus_tab``, a
focus asked for in the tab being left arrived after the new tab was shown and took the user
back: F6 then F7 a frame or two apart ended on the inspector (37 of the 126 ordered pairs of
tabs, picked 10-30 ms apart, ended on the first tab).
"""

from __future__ import annotations

import asyncio
import itertools

from textual import events
from textual.widgets import TabbedContent

from fieldbox.app import panel_classes

from .helpers import SIZE, make_app, one_team, step


def shown(app):
    active = app.query_one(TabbedContent).active
    return active, next(p for p in app.query("Panel") if p.ID == active)


async def test_two_tab_keys_a_frame_apart_end_on_the_second():
    # The keys go in as a terminal delivers them, 10 ms apart, without waiting for the app
    # to settle in between (pilot.press waits, which lets the late focus land first).
    app, _ = make_app(one_team(roles=frozenset({"ds", "rio", "fms"})), "ds")
    tabs = [cls.ID for cls in panel_classes()]
    async with app.run_test(size=SIZE) as pilot:
        await step(pilot, 0.5)
        for first, second in itertools.permutations(tabs, 2):
            app.post_message(events.Key(f"f{tabs.index(first) + 1}", None))
            await asyncio.sleep(0.01)
            app.post_message(events.Key(f"f{tabs.index(second) + 1}", None))
            await asyncio.sleep(0.12)
            await pilot.pause()
            active, panel = shown(app)
            assert (first, active) == (first, second)
            assert panel.focus_is_inside()  # its keys work at once


async def test_a_focus_arriving_from_a_tab_left_neither_changes_tab_nor_keeps_the_keys():
    # What the race comes down to: the inspector's list is focused after the user has
    # already moved on to the Legacy tab.
    app, _ = make_app(one_team(), "ds")
    async with app.run_test(size=SIZE) as pilot:
        await step(pilot, 0.5)
        app.action_show_tab("legacy")
        await pilot.pause()
        app.query_one("#inspector-packets").focus()  # asked for before the switch, arriving now
        await pilot.pause()
        await pilot.pause()
        active, panel = shown(app)
        assert active == "legacy"
        assert app.focused is panel  # the Legacy tab's keys work
        await pilot.press("f6")
        await pilot.pause()
        assert shown(app)[0] == "inspector" and app.focused is app.query_one("#inspector-packets")
