"""A classroom seat's screen (issue 31, item 4): a seat sees only what it may do, the title
names a driver's own team, and every tab reads an event's time on the field's clock.

The apps here join a real classroom field (roles/runtime/classroom.py) as a served tab's app
does, each with the seat it asks for."""

from __future__ import annotations

import pytest

from roles.runtime.classroom import ClassroomProcess, JoinedEngine, Seat
from roles.runtime.field import FieldConfig

from fieldbox.app import FieldboxApp

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
