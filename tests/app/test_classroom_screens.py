"""A classroom seat's screen (issue 31, item 4): a seat sees only what it may do, the title
names a driver's own team, and every tab reads an event's time on the field's clock.

The apps here join a real classroom field (roles/runtime/classroom.py) as a served tab's app
does, each with the seat it asks for."""

from __future__ import annotations

import pytest

from roles.runtime.classroom import ClassroomProcess, JoinedEngine, Seat
from roles.runtime.field import FieldConfig

from fieldbox.app import FieldboxApp
from fieldbox.panels.joysticks import JoysticksPanel

from .helpers import PC, until

pytestmark = pytest.mark.usefixtures("no_real_joysticks")

TEAMS = [254, 1114]


@pytest.fixture
def classroom():
    host = ClassroomProcess(FieldConfig(teams=list(TEAMS), plan="ephemeral", log_files=False))
    host.start()
    try:
        yield host
    finally:
        host.stop()


def seat_app(host: ClassroomProcess, want) -> FieldboxApp:
    """An app in a seat of ``host``'s classroom, as ``fieldbox --join`` makes it (fieldbox/launch.py)."""

    def joined(config: FieldConfig) -> JoinedEngine:
        engine = JoinedEngine(host.path, want, config)
        engine.start()
        return engine

    return FieldboxApp(joined, FieldConfig(plan="ephemeral", log_files=False), panel="ds", animate=False,
                       pc_status=lambda: PC)


def screen_text(app) -> str:
    return "\n".join(strip.text for strip in app.screen._compositor.render_strips())


def footer_text(app) -> str:
    return screen_text(app).split("\n")[-1]


@pytest.mark.parametrize("size", [(80, 24), (160, 50)])
async def test_an_observer_sees_no_button_or_key_it_may_not_use_and_a_driver_does(classroom, size):
    observer, driver = seat_app(classroom, "observer"), seat_app(classroom, "driver")
    async with observer.run_test(size=size) as watching, driver.run_test(size=size) as driving:
        for pilot in (watching, driving):
            assert await until(pilot, lambda app=pilot.app: app.seat is not None and app.engine.field.stations)
            pilot.app.refresh_views()
            await pilot.pause()
        seen, drives = screen_text(observer), screen_text(driver)
        for word in ("E-STOP", "Enable e e", "Restart", "Reboot"):
            assert word not in seen, word
            assert word in drives, word
        assert "E-stop" not in footer_text(observer) and "Disable" not in footer_text(observer)
        assert "E-stop" in footer_text(driver) and "Disable" in footer_text(driver)
        assert "Roles" not in footer_text(driver)  # F8: the field's roles are the classroom's
        assert "Communications" in seen and "Robot code" in seen  # the field itself still shows
        assert "classroom: you watch" in seen
        # the title names the driver's own team, not the field's first or the joining defaults
        assert driver.seat == Seat("driver", 254)
        assert driver.sub_title.startswith("team 254 · classroom") and "team 1 " not in driver.sub_title
        assert observer.sub_title.startswith("watching · classroom")


async def test_a_second_drivers_tab_shows_the_team_it_drives(classroom):
    """The second student drove team 1114 while its DS tab showed team 254 (the field's first)."""
    first, second = seat_app(classroom, "driver"), seat_app(classroom, "driver")
    async with first.run_test(size=(160, 50)) as p1:
        assert await until(p1, lambda: first.seat == Seat("driver", 254))
        async with second.run_test(size=(160, 50)) as p2:
            assert await until(p2, lambda: second.seat == Seat("driver", 1114))
            second.refresh_views()
            await p2.pause()
            assert "Team 1114" in screen_text(second) and "Team 254 " not in screen_text(second)
            assert second.sub_title.startswith("team 1114 · classroom")


async def test_a_driver_taken_back_loses_the_buttons_and_keys_and_title_of_a_driver(classroom):
    teacher = seat_app(classroom, ("teacher", classroom.teacher_key))
    driver = seat_app(classroom, "driver")
    async with teacher.run_test(size=(80, 24)) as t, driver.run_test(size=(80, 24)) as d:
        assert await until(d, lambda: driver.seat == Seat("driver", 254))
        assert await until(t, lambda: teacher.seat is not None)
        driver.refresh_views()
        await d.pause()
        assert "E-STOP" in screen_text(driver)
        teacher.take_back(254)

        def watches() -> bool:
            driver.refresh_views()
            return driver.seat == Seat("observer")

        assert await until(d, watches)
        driver.refresh_views()
        await d.pause()
        await d.pause()
        assert "E-STOP" not in screen_text(driver) and "E-stop" not in footer_text(driver)
        assert driver.sub_title.startswith("watching · classroom")


async def test_every_tab_reads_an_event_at_the_same_time_on_the_fields_clock(classroom):
    """Each tab counted from its own start: the same event read 144.462 in one tab and 158.517
    in another, and one from before a tab joined read 0.000 there."""
    first = seat_app(classroom, "driver")
    async with first.run_test(size=(200, 50)) as p1:
        assert await until(p1, lambda: first.seat is not None)
        await p1.pause(1.5)  # the event comes well after the field started and this tab joined
        first.run_command("estop")

        def estop_lines(app) -> list[str]:
            app.refresh_views()
            return [line for line in app.query_one("#ds-messages").lines if "E-STOP" in line]

        assert await until(p1, lambda: estop_lines(first), timeout=30)
        await p1.pause(1.5)  # the second tab joins well after the event
        second = seat_app(classroom, "observer")
        async with second.run_test(size=(200, 50)) as p2:
            assert await until(p2, lambda: second.seat is not None and estop_lines(second), timeout=30)
            one, two = estop_lines(first)[0], estop_lines(second)[0]
            assert one == two, (one, two)
            assert float(two.split()[0]) >= 1.5  # seconds since the field started


def tab_bar(app) -> str:
    return screen_text(app).split("\n")[2]


def said(app) -> list[str]:
    return [note.message for note in app._notifications]


#: What the teacher's keys say in a footer, and their key help on screen: never a student's.
TEACHERS_FOOTER = ("Bypass", "E-stop station", "A-stop", "Start match", "Abort match", "Next match", "Replay",
                   "Match type", "Durations", "Type a fault")
TEACHERS_HELP = ("b bypass", "s start", "s starts the match", "period lengths", "LINK:SETTINGS",
                 "Pull robot", "Faults on purpose (f")


@pytest.mark.parametrize("size", [(80, 24), (160, 50)])
async def test_a_students_footer_and_tab_bar_offer_only_what_it_may_use(classroom, size):
    """A driver's and an observer's FMS tab and Faults tab offered the teacher's keys (Start
    match, Bypass, Type a fault...), each refused when pressed, and the tab bar a 2010 tab that
    only said "press F8", which a seat may not. Now each tab shows its table without them, says
    who runs it, and a key pressed anyway is still refused, with the classroom's words."""
    driver, observer = seat_app(classroom, "driver"), seat_app(classroom, "observer")
    async with driver.run_test(size=size) as driving, observer.run_test(size=size) as watching:
        for pilot in (driving, watching):
            assert await until(pilot, lambda app=pilot.app: app.seat is not None and app.engine.field.stations)
        driver.refresh_views()
        await driving.pause()
        if size[0] >= 100:  # the DS tab's wide key help counts the function keys a student has
            assert "F1…F6  tabs" in screen_text(driver) and "F1…F7" not in screen_text(driver)
        for pilot, app in ((driving, driver), (watching, observer)):
            assert "2010" not in tab_bar(app) and "Legacy" not in tab_bar(app), tab_bar(app)
            assert "FMS" in tab_bar(app) and "Faults" in tab_bar(app)  # the match and the counters show
            app.action_show_tab("fms")
            await pilot.pause()
            await pilot.pause()
            seen, footer = screen_text(app), footer_text(app)
            assert "R1" in seen and "254" in seen and "Match log" in seen  # the match and its stations
            assert "The match is the teacher's" in seen and "the teacher starts the match" in seen
            assert "Match log" in footer  # a look at the log is every seat's
            app.action_show_tab("faults")
            await pilot.pause()
            await pilot.pause()
            faults, faults_footer = screen_text(app), footer_text(app)
            assert "control → robot" in faults and "Faults on purpose are the teacher's" in faults
            app.action_show_tab("setup")  # the team is the teacher's: no key to type one
            await pilot.pause()
            await pilot.pause()
            assert "t Team" not in footer_text(app) and "t  team" not in screen_text(app)
            assert "g Game data" in footer_text(app) and "g  game data" in screen_text(app)
            for word in TEACHERS_FOOTER:
                assert word not in footer and word not in faults_footer, (word, footer, faults_footer)
            for words in TEACHERS_HELP:
                assert words not in seen and words not in faults, words
        # an observer's joysticks drive nothing: its Joysticks tab offers no key to place them
        observer.action_show_tab("joysticks")
        driver.action_show_tab("joysticks")
        for pilot in (watching, driving):
            await pilot.pause()
            await pilot.pause()
        assert "You watch: no joystick drives from this tab" in screen_text(observer)
        assert "Keyboard here" not in footer_text(observer) and not observer.query_one("#js-keys").display
        assert "Keyboard here" in footer_text(driver) and driver.query_one("#js-keys").display
        assert "Rescan" not in footer_text(driver)  # the server's joysticks are not a seat's
        # nor do an observer's keyboard-joystick keys move a stick on its screen, as if they drove
        await watching.press("d", "d", "1")
        hub = observer.query_one(JoysticksPanel).hub
        assert all(v == 0 for v in hub.keyboard.axes) and not hub.keyboard.buttons
        # the driver still drives from every tab; the observer does not
        assert "E-stop" in footer_text(driver) and "E-stop" not in footer_text(observer)
        # a key not offered, pressed anyway: refused, and said so (the match does not start)
        driver.action_show_tab("fms")
        await driving.pause()
        await driving.press("s")
        assert "the FMS and the faults are the teacher's: you watch them here" in said(driver)
        driver.action_show_tab("setup")
        await driving.pause()
        await driving.press("t")
        assert "this app shares the classroom's field: its teams are the teacher's" in said(driver)
        driver.action_show_tab("fms")
        await driving.pause()
        await driving.press("f7")
        assert any("not a 2010 one" in note for note in said(driver))
        assert driver.query_one("#tabs").active == "fms"
        await watching.press("space")
        await watching.press("e")
        assert "you watch this field: ask the teacher for a station" in said(observer)
        driver.refresh_views()
        assert driver.engine.field.fms.match.phase == "pre-match"
        assert not any(st.ds.arbiter.estopped for st in driver.engine.field.stations)


async def test_the_teachers_tab_keeps_every_key_a_student_does_not_see(classroom):
    """The other side of the test above: the same screens, the teacher's, offer them all."""
    teacher = seat_app(classroom, ("teacher", classroom.teacher_key))
    async with teacher.run_test(size=(160, 50)) as pilot:
        assert await until(pilot, lambda: teacher.seat is not None and teacher.engine.field.stations)
        assert "2010" in tab_bar(teacher)
        teacher.action_show_tab("fms")
        await pilot.pause()
        await pilot.pause()
        assert "Start match" in footer_text(teacher) and "b bypass" in screen_text(teacher)
        assert "The match is the teacher's" not in screen_text(teacher)
        teacher.action_show_tab("faults")
        await pilot.pause()
        await pilot.pause()
        assert "Type a fault" in footer_text(teacher) and "LINK:SETTINGS" in screen_text(teacher)
