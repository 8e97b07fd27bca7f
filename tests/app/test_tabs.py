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


def _styles_of(panel) -> list:
    """Every widget of ``panel`` with the rules its styles hold now."""
    return [(node, dict(node._css_styles.get_rules())) for node in panel.walk_children(with_self=True)]


async def test_a_panels_focus_restyles_what_textual_would():
    # A panel restyles itself and its FOCUS_STYLED widgets when it gains or loses the focus,
    # not its whole tab (Panel.watch_has_focus). Here every panel's widgets, after a focus and
    # after a blur, hold the styles Textual's full restyle of the tab gives them: a CSS rule
    # that follows a panel's focus and is not in FOCUS_STYLED fails this test.
    app, _ = make_app(one_team(roles=frozenset({"ds", "rio", "fms"})))
    async with app.run_test(size=SIZE) as pilot:
        await step(pilot, 1.0)
        checked = 0
        for cls in panel_classes():
            app.action_show_tab(cls.ID)
            await pilot.pause()
            panel = next(p for p in app.query("Panel") if p.ID == cls.ID)
            if not panel.can_focus:
                continue
            for focused in (True, False):
                app.screen.set_focus(panel if focused else None)
                await pilot.pause()
                assert panel.has_focus is focused
                ours = _styles_of(panel)
                app.update_styles(panel)  # Textual's own: the panel and everything in it
                assert _styles_of(panel) == ours, cls.ID
            checked += 1
        assert checked >= 4


async def test_the_timer_refreshes_a_panel_of_counters_every_other_tick_and_a_switch_at_once():
    # A panel of tables and lists (REFRESH_TICKS 2) redraws five times a second from the
    # app's timer; the DS, every tick. A tab switch refreshes the new tab at once.
    app, _ = make_app(one_team(roles=frozenset({"ds", "rio", "fms"})))
    async with app.run_test(size=SIZE) as pilot:
        await step(pilot, 1.0)
        panels = {p.ID: p for p in app.query("Panel")}
        calls: dict[str, int] = {"ds": 0, "fms": 0}
        for name in calls:
            original = panels[name].refresh_view

            def counted(engine, now, name=name, original=original):
                calls[name] += 1
                return original(engine, now)

            panels[name].refresh_view = counted
        assert panels["fms"].REFRESH_TICKS == 2 and panels["ds"].REFRESH_TICKS == 1
        for tick in (1, 2, 3, 4):
            app.refresh_views(tick)
        assert calls["ds"] == 4 and calls["fms"] == 0  # the FMS tab is not shown
        app.action_show_tab("fms")
        assert calls["fms"] == 1
        for tick in (5, 6, 7, 8):
            app.refresh_views(tick)
        assert calls["fms"] == 3
