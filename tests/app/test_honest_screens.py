"""Honest screens (issue 16): when the wire stops answering, every screen says it no longer
knows instead of showing the last state it saw, and a key pressed meanwhile waits, shown as
pending, then reaches the wire when it answers. The UI thread never waits for the wire.

Real wires on loopback: the default one in a child process (stopped with SIGSTOP, as a
loaded laptop stops it), and ``--wire thread`` (its loop held by a long call)."""

from __future__ import annotations

import os
import signal
import sys
import time

import pytest

from roles.runtime.field import FieldConfig

from fieldbox.app import FieldboxApp, engine_factory

from .helpers import text_of, until

PATIENCE = 20.0


def config(tmp_path) -> FieldConfig:
    return FieldConfig(roles=frozenset({"ds", "rio"}), team=254, plan="ephemeral", log_dir=str(tmp_path))


def assert_unknown(app) -> None:
    """What every screen shows while the wire is silent."""
    banner = app.query_one("#stale-banner")
    assert banner.display and "NO ANSWER FROM THE WIRE" in text_of(app, "#stale-banner")
    status = text_of(app, "#status-line")
    assert "ENABLE STATE UNKNOWN" in status and "ENABLED" not in status and "comms ?" in status
    assert text_of(app, "#ds-state").startswith("STATE UNKNOWN")
    for light in ("#ds-light-comms", "#ds-light-code", "#ds-light-joysticks"):
        assert app.query_one(light).state == "idle"


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="stops the wire's process with SIGSTOP")
async def test_a_stopped_wire_process_is_shown_and_a_key_waits_for_it(tmp_path):
    app = FieldboxApp(engine_factory("process"), config(tmp_path), animate=False)
    async with app.run_test(size=(120, 40)) as pilot:
        engine = app.engine
        ds = lambda: engine.field.stations[0].ds  # noqa: E731 - the latest view from the wire process
        assert await until(pilot, lambda: ds().link.robot_comms and ds().link.robot_code)
        assert app.run_command("enable")
        assert await until(pilot, lambda: ds().enabled and "ENABLED" in text_of(app, "#status-line"))
        assert not app.query_one("#stale-banner").display
        pid = engine.proc.pid
        os.kill(pid, signal.SIGSTOP)
        try:
            assert await until(pilot, lambda: app.wire_stale)
            await pilot.pause(0.2)
            assert_unknown(app)
            assert ds().enabled  # the last state the wire sent, which the screens no longer vouch for
            await pilot.press("enter")  # disable, while the wire cannot hear it: the UI does not wait
            assert await until(pilot, lambda: "waiting for the wire: disable" in text_of(app, "#status-line"))
        finally:
            os.kill(pid, signal.SIGCONT)
        assert await until(pilot, lambda: not app.wire_stale and not ds().enabled)
        assert await until(pilot, lambda: "waiting for the wire" not in text_of(app, "#status-line"))
        assert not app.query_one("#stale-banner").display
        assert text_of(app, "#ds-state").startswith("DISABLED")


async def test_a_held_wire_thread_is_shown_and_enter_neither_blocks_nor_crashes(tmp_path):
    # issue 16: with --wire thread, Enter during a stall crashed the app
    app = FieldboxApp(engine_factory("thread"), config(tmp_path), animate=False)
    async with app.run_test(size=(120, 40)) as pilot:
        engine = app.engine
        ds = engine.field.stations[0].ds
        assert await until(pilot, lambda: ds.link.robot_comms and ds.link.robot_code)
        assert app.run_command("enable")
        assert await until(pilot, lambda: ds.enabled)
        held = engine.runtime.call(lambda: time.sleep(5.0))  # the wire's loop does nothing else
        assert await until(pilot, lambda: app.wire_stale)
        await pilot.pause(0.2)
        assert_unknown(app)
        await pilot.press("enter")
        assert not held.done()  # the key came back while the wire was still held: the UI did not wait
        assert await until(pilot, lambda: "waiting for the wire: disable" in text_of(app, "#status-line"))
        assert await until(pilot, lambda: held.done() and not ds.enabled and not app.wire_stale)
        assert await until(pilot, lambda: "waiting for the wire" not in text_of(app, "#status-line"))


async def test_an_enable_pressed_while_the_wire_was_silent_is_refused_when_it_arrives_late(tmp_path):
    app = FieldboxApp(engine_factory("thread"), config(tmp_path), animate=False)
    notes: list[str] = []
    notify = app.notify
    app.notify = lambda message, *a, **k: (notes.append(str(message)), notify(message, *a, **k))[1]
    async with app.run_test(size=(120, 40)) as pilot:
        engine = app.engine
        ds = engine.field.stations[0].ds
        assert await until(pilot, lambda: ds.link.robot_comms and ds.link.robot_code)
        held = engine.runtime.call(lambda: time.sleep(4.0))
        assert await until(pilot, lambda: app.wire_stale)
        assert app.run_command("enable")  # pressed now, carried out seconds late: refused
        assert await until(pilot, lambda: held.done() and any("press it again" in n for n in notes))
        await pilot.pause(0.3)
        assert not ds.enabled


@pytest.mark.skipif(not hasattr(__import__("resource"), "prlimit"), reason="needs resource.prlimit (Linux)")
async def test_a_full_log_disk_in_the_wire_process_is_a_notification_and_a_line_on_the_faults_tab(tmp_path):
    import resource

    app = FieldboxApp(engine_factory("process"), config(tmp_path), panel="faults", animate=False)
    notes: list[str] = []
    notify = app.notify
    app.notify = lambda message, *a, **k: (notes.append(str(message)), notify(message, *a, **k))[1]
    async with app.run_test(size=(120, 40)) as pilot:
        engine = app.engine
        assert await until(pilot, lambda: engine.field.stations[0].ds.link.robot_comms)
        # the wire's files may not grow past 600 bytes from now on: a disk that just filled up
        resource.prlimit(engine.proc.pid, resource.RLIMIT_FSIZE, (600, 600))
        end = time.monotonic() + PATIENCE
        while time.monotonic() < end and not any("log files in" in n for n in notes):
            app.run_command("mode auto")
            app.run_command("mode teleop")
            await pilot.pause(0.1)
        [said] = [n for n in notes if "log files in" in n][:1]
        assert "failed" in said and "the field runs on" in said
        assert await until(pilot, lambda: "Log files:" in text_of(app, "#faults-other"))
        assert "writes failed" in text_of(app, "#faults-other")
        assert not engine.ended and engine.field.stations[0].ds.link.robot_comms


async def test_the_app_shows_a_stuck_robot_program_and_restart_code_ends_it(tmp_path):
    program = tmp_path / "spin.py"
    program.write_text("def robot_periodic(state, robot):\n    if state.enabled:\n        while True:\n"
                       "            pass\n")
    cfg = config(tmp_path)
    cfg.program = str(program)
    app = FieldboxApp(engine_factory("process"), cfg, animate=False)
    async with app.run_test(size=(120, 40)) as pilot:
        engine = app.engine
        st = engine.field.stations[0]
        assert await until(pilot, lambda: st.ds.link.robot_comms and st.ds.link.robot_code)
        assert app.run_command("enable")
        assert await until(pilot, lambda: "STUCK" in text_of(app, "#ds-program"))
        assert st.ds.link.robot_comms and not app.wire_stale  # the robot and the wire answer throughout
        await pilot.press("R")  # restart code (the DS tab's key)
        assert await until(pilot, lambda: "STUCK" not in text_of(app, "#ds-program")
                           and engine.field.stations[0].rio.code_state == "running")
