"""Changing tabs: the tab picked is the one shown, and its panel has the keys.

Textual makes the tab of a widget that receives the focus the active one, and focus moves
are queued. Before FieldboxTabs (fieldbox/textual_fixes.py) and the app's ``_focus_tab``, a
focus asked for in the tab being left arrived after the new tab was shown and took the user
back: F6 then F7 a frame or two apart ended on the inspector (37 of the 126 ordered pairs of
tabs, picked 10-30 ms apart, ended on the first tab).
"""

from __future__ import annotations

import asyncio
import itertools

from textual import events
from textual.widgets import TabbedContent

from fieldbox.app import TAB_KEYS, panel_classes, tab_key_text

from .helpers import SIZE, make_app, one_team, step


def shown(app):
    active = app.query_one(TabbedContent).active
    return active, next(p for p in app.query("Panel") if p.ID == active)


async def test_two_tab_keys_a_frame_apart_end_on_the_second():
    # The keys go in as a terminal delivers them, 10 ms apart, without waiting for the app
    # to settle in between (pilot.press waits, which lets the late focus land first).
    app, _ = make_app(one_team(roles=frozenset({"ds", "rio", "fms"})), "ds")
    first_tabs = {tabs[0]: key for key, tabs in TAB_KEYS}  # what each function key shows first
    async with app.run_test(size=SIZE) as pilot:
        await step(pilot, 0.5)
        for first, second in itertools.permutations(first_tabs, 2):
            app.post_message(events.Key(first_tabs[first], None))
            await asyncio.sleep(0.01)
            app.post_message(events.Key(first_tabs[second], None))
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


async def test_a_function_key_pressed_again_shows_the_next_tab_of_its_group():
    # F1 holds the Driver Station's places as the NI Driver Station does: Operation,
    # Diagnostics, Setup, Charts; F6 the inspector and the timeline. Every tab has a key.
    app, _ = make_app(one_team(roles=frozenset({"ds", "rio", "fms"})), "console")
    async with app.run_test(size=SIZE) as pilot:
        await step(pilot, 0.5)
        seen = []
        for _ in range(5):
            await pilot.press("f1")
            await pilot.pause()
            seen.append(shown(app)[0])
            assert shown(app)[1].focus_is_inside()  # its keys work at once
        assert seen == ["ds", "diagnostics", "setup", "charts", "ds"]
        await pilot.press("f6", "f6")
        await pilot.pause()
        assert shown(app)[0] == "timeline"
        await pilot.press("f3", "f6")  # from another group, a key starts at its first tab
        await pilot.pause()
        assert shown(app)[0] == "inspector"
    grouped = [tab for _, tabs in TAB_KEYS for tab in tabs]
    assert sorted(grouped) == sorted(cls.ID for cls in panel_classes())  # no tab without a key
    assert tab_key_text("setup") == "F1 F1 F1" and tab_key_text("timeline") == "F6 F6"
