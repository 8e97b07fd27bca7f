"""The Console panel and the console log file, driven through the app with a SimEngine."""

from __future__ import annotations

import gc
import sys
from collections import deque
from types import SimpleNamespace

from roles.runtime.field import FieldConfig

from fieldbox.panels.console import CAPACITY, ConsolePanel, ConsoleView

from .helpers import Wire, layouts_asked, make_app, one_team, step, text_of

# A robot program that warns and errs once each time it is enabled, besides printing.
NOISY_PROGRAM = '''
was_enabled = False

def robot_periodic(state, robot):
    global was_enabled
    if state.enabled and not was_enabled:
        robot.print("hello from the robot")
        robot.warning("battery is low-ish")
        robot.error("Unhandled thing in Drive")
    if was_enabled and not state.enabled:
        robot.print("Robot disabled")
    was_enabled = state.enabled
'''


def noisy_robot(tmp_path) -> FieldConfig:
    program = tmp_path / "noisy.py"
    program.write_text(NOISY_PROGRAM)
    return one_team(program=str(program))


def texts(view: ConsoleView) -> list[str]:
    return [e.text for e in view.shown_entries()]


def say(engine, ds, *texts: str, level: str = "stdout") -> None:
    """Lines on a DS core's console as the core adds them (a test shortcut for a chatty robot)."""
    for text in texts:
        ds.tcp.console.append((engine.now(), level, text))  # numbered: its total moves too

async def test_robot_stdout_arrives_and_filters_hide_and_show_it(tmp_path):
    app, engines = make_app(noisy_robot(tmp_path), "console")
    async with app.run_test(size=(120, 40)) as pilot:
        engine = engines[0]
        wire = Wire(engine)
        await step(pilot, 1.0)
        panel = app.query_one(ConsolePanel)
        view = panel.view
        assert app.focused is view  # keys work at once on this tab

        await pilot.press("e", "e")
        await step(pilot, 0.5)
        # the wire: the DS asked for enable, and the robot's lines crossed TCP 1740
        assert any(p.enabled for p in wire.ds_control())
        assert "hello from the robot" in wire.stdout_texts()
        # the panel: every level arrived, with its level
        levels = {e.text: e.level for e in view.shown_entries()}
        assert levels["hello from the robot"] == "stdout"
        # warnings and errors as the DS words them: [code] details (where)
        assert levels["battery is low-ish (noisy.py:8)"] == "warning"
        assert levels["[1] Unhandled thing in Drive (noisy.py:9)"] == "error"

        # 1 hides stdout: only the warning and the error remain
        await pilot.press("1")
        assert {e.level for e in view.shown_entries()} == {"warning", "error"}
        assert "hiding stdout" in text_of(app, "#console-status")
        await pilot.press("2")
        assert {e.level for e in view.shown_entries()} == {"error"}
        await pilot.press("3")
        assert view.shown == 0
        await pilot.press("1", "2", "3")
        assert view.shown == view.total


async def test_text_filter_and_new_lines_that_pass_it(tmp_path):
    app, engines = make_app(noisy_robot(tmp_path), "console")
    async with app.run_test(size=(120, 40)) as pilot:
        engine = engines[0]
        wire = Wire(engine)
        await step(pilot, 1.0)
        view = app.query_one(ConsoleView)
        await pilot.press("e", "e")
        await step(pilot, 0.5)

        # text filter: case-insensitive substring, typed into the filter box after /
        await pilot.press("slash")
        assert app.focused.id == "console-filter"
        await pilot.press("R", "O")
        assert texts(view) == ["hello from the robot"]
        # a new line that passes the filter shows up at once
        await pilot.press("enter")  # the app's disable key (it works from the filter box too)
        await step(pilot, 0.5)
        assert texts(view) == ["hello from the robot", "Robot disabled"]
        assert not any(p.enabled for p in wire.ds_control()[-5:])
        # Enter also submitted the filter, which hands focus back to the view; typing in the
        # filter does not toggle levels: "1" goes into the box
        assert app.focused is view
        await pilot.press("slash", "ctrl+u", "1")
        assert app.query_one("#console-filter").value == "1"
        assert "stdout" in view.levels and view.shown == 1  # [1] Unhandled thing...
        await pilot.press("escape")
        assert app.focused is view
        assert "Robot disabled" in wire.stdout_texts()


async def test_clear_and_auto_scroll_pauses_when_scrolled_up():
    app, engines = make_app(one_team(), "console")
    async with app.run_test(size=(100, 20)) as pilot:
        engine = engines[0]
        await step(pilot, 1.0)
        view = app.query_one(ConsoleView)
        ds = engine.field.stations[0].ds
        say(engine, ds, *(f"line {i}" for i in range(200)))
        await step(pilot, 0.1)
        assert view.following and view.scroll_y == view.max_scroll_y > 0

        await pilot.press("pageup")
        assert not view.following
        top = view.scroll_y
        say(engine, ds, "line 200")
        await step(pilot, 0.1)
        assert view.scroll_y == top and view.unseen == 1  # did not jump to the end
        assert "PAUSED" in text_of(app, "#console-status")

        await pilot.press("end")
        assert view.following and view.scroll_y == view.max_scroll_y

        await pilot.press("c")
        assert view.total == 0 and view.shown == 0
        say(engine, ds, "after the clear")
        await step(pilot, 0.1)
        assert texts(view) == ["after the clear"]  # old lines do not come back


async def test_new_lines_scroll_without_laying_the_screen_out():
    # Each batch of lines set virtual_size, and that laid the whole screen out; only a wider
    # line (the horizontal scroll) or a scrollbar appearing needs it (fieldbox/textual_fixes.py).
    app, engines = make_app(one_team(), "console")
    async with app.run_test(size=(100, 20)) as pilot:
        engine = engines[0]
        await step(pilot, 1.0)
        view = app.query_one(ConsoleView)
        ds = engine.field.stations[0].ds
        say(engine, ds, *(f"line {i}" for i in range(100)))
        await step(pilot, 0.1)
        assert view.show_vertical_scrollbar and view.scroll_y == view.max_scroll_y > 0
        before = view.max_scroll_y
        asked = layouts_asked(view)
        say(engine, ds, *(f"line {i}" for i in range(10)))
        await step(pilot, 0.1)
        assert asked and not any(asked)
        assert view.max_scroll_y == before + 10 and view.scroll_y == view.max_scroll_y  # followed
        assert texts(view)[-1] == "line 9"
        say(engine, ds, "a line far wider than the console's panel, " * 4)  # the width changes: laid out
        await step(pilot, 0.1)
        assert any(asked) and view.virtual_size.width > view.size.width


async def test_a_reader_scrolled_up_stays_put_while_hidden_lines_push_shown_ones_out():
    # A full ring, stdout hidden, the reader two lines above the bottom: chatter on stdout
    # pushes out warnings they can see. The view keeps their lines and does not jump back to
    # following (a review found it did, once a new size clamped the scroll before the view
    # moved up by the lines that left).
    app, engines = make_app(one_team(), "console")
    async with app.run_test(size=(100, 20)) as pilot:
        engine = engines[0]
        await step(pilot, 1.0)
        view = app.query_one(ConsoleView)
        view.clear()
        view.capacity, view._ring = 60, deque(maxlen=60)  # a small ring, to fill it quickly
        ds = engine.field.stations[0].ds
        say(engine, ds, *(f"warn {i}" for i in range(60)), level="warning")
        await step(pilot, 0.1)
        view.set_filters(levels={"warning", "error"})
        await pilot.pause()
        view.scroll_to(y=view.max_scroll_y - 2, animate=False, immediate=True)
        await pilot.pause()
        top = view.shown_entries()[int(view.scroll_y)].text
        assert not view.following and top == f"warn {60 - 2 - view.scrollable_content_region.height}"
        say(engine, ds, *(f"chatter {i}" for i in range(5)))  # hidden; five warnings leave the ring
        await step(pilot, 0.1)
        assert view.shown_entries()[int(view.scroll_y)].text == top
        assert not view.following
        say(engine, ds, "new 0", "new 1", "new 2", level="warning")
        await step(pilot, 0.1)
        assert view.shown_entries()[int(view.scroll_y)].text == top and view.unseen == 3


async def test_a_full_ring_of_lines_is_appended_not_rebuilt():
    app, engines = make_app(one_team(roles=frozenset({"ds"})), "console")
    async with app.run_test(size=(120, 40)) as pilot:
        engine = engines[0]
        app.refresh_views()
        await pilot.pause()
        view = app.query_one(ConsoleView)
        ds = engine.field.stations[0].ds
        rebuilds = view.rebuilds
        # CAPACITY + 500 lines in batches of 500 (the DS keeps 2000): one panel refresh per batch
        batches = CAPACITY // 500 + 1
        n = 0
        for _ in range(batches):
            for _ in range(500):
                ds.tcp.console.append((1000.0 + n / 1000, "warning" if n % 10 == 0 else "stdout", f"line {n}"))
                n += 1
            app.refresh_views()
        await pilot.pause()
        last = CAPACITY + 499
        assert view.total == CAPACITY  # the ring dropped the oldest 500
        assert texts(view)[0] == "line 500" and texts(view)[-1] == f"line {last}"
        assert view.rebuilds == rebuilds  # appended batch by batch, never rebuilt
        # only what was on screen was ever rendered (a screenful per batch at most)
        assert view.strips_rendered <= batches * view.size.height
        # the newest line is on screen
        assert view.scroll_y == view.max_scroll_y
        line = "".join(s.text for s in view.render_line(view.size.height - 1))
        assert f"line {last}" in line

        await pilot.press("2")  # hide warnings: one rebuild over the ring
        assert view.rebuilds == rebuilds + 1
        assert view.shown == CAPACITY * 9 // 10
        await pilot.press("slash", *"1999")
        assert texts(view) == [f"line {i}" for i in range(500, last + 1) if i % 10 and "1999" in str(i)]
        assert view.rebuilds == rebuilds + 5  # one per key
        # scrolling back over cached lines renders nothing new
        rendered = view.strips_rendered
        view.refresh()
        await pilot.pause()
        assert view.strips_rendered == rendered


async def test_full_field_has_a_team_column_and_a_team_filter():
    teams = [254, 1114, 2056, 118, 148, 1678]
    app, engines = make_app(FieldConfig(teams=teams, roles=frozenset({"ds", "rio"})), "console")
    async with app.run_test(size=(120, 40)) as pilot:
        engine = engines[0]
        await step(pilot, 1.0)
        view = app.query_one(ConsoleView)
        assert view.show_team
        assert {e.team for e in view.shown_entries()} == set(teams)
        await pilot.press("t")  # all -> 254
        assert {e.team for e in view.shown_entries()} == {254}
        assert "team: 254" in text_of(app, "#console-team")
        line = "".join(s.text for s in view.render_line(0))
        assert "254" in line
        for _ in teams:
            await pilot.press("t")
        assert view.team_filter is None and {e.team for e in view.shown_entries()} == set(teams)


def test_follower_takes_each_line_once_and_counts_what_scrolled_out():
    from roles.cores.core import Stream

    from fieldbox.console_feed import ConsoleFollower

    stream: Stream[tuple[float, str, str]] = Stream(4)  # a DS's console, four lines kept
    follower = ConsoleFollower(lambda: SimpleNamespace(console=stream.view()), 254)
    for i in range(3):
        stream.append((float(i), "stdout", f"a{i}"))
    assert [e.text for e in follower.new_entries()] == ["a0", "a1", "a2"]
    assert follower.new_entries() == []  # a new view of the same lines: nothing is new
    stream.append((3.0, "error", "c"))
    assert [(e.level, e.text) for e in follower.new_entries()] == [("error", "c")]
    assert follower.missed == 0
    for i in range(6):  # six more: two scroll out before the follower looks
        stream.append((4.0 + i, "stdout", f"b{i}"))
    assert [e.text for e in follower.new_entries()] == [f"b{i}" for i in range(2, 6)]
    assert follower.missed == 2


async def test_the_lines_kept_are_out_of_the_collectors_sight():
    # A full ring is 40 000 objects that every full collection of the app's process would walk
    # (the app's drawing stops meanwhile); a line can never be in a reference cycle.
    app, engines = make_app(one_team(), "console")
    async with app.run_test(size=(120, 40)) as pilot:
        await step(pilot, 0.5)
        engine = engines[0]
        say(engine, engine.field.stations[0].ds, "Teleop: left=0.250 right=0.250", "Teleop: left=0.5")
        await step(pilot, 0.2)
        view = app.query_one(ConsoleView)
        rows = [row for row in view._ring if row.entry.text.startswith("Teleop")]
        assert len(rows) == 2
        if sys.implementation.name == "cpython":  # elsewhere they stay tracked
            assert not any(gc.is_tracked(row) or gc.is_tracked(row.entry) for row in rows)
        await pilot.press("slash", *"LEFT=0.5")  # the search folds each line as it runs
        assert texts(view) == ["Teleop: left=0.5"]
