"""The app with its wire in a child process (roles/runtime/wireproc.py), as ``fieldbox`` runs by
default: real loopback sockets, ephemeral ports, the panels reading the views it sends."""

from __future__ import annotations

import os
import signal

import pytest

from roles.cores.match import Phase
from roles.runtime.engine import STALE_AFTER, SimEngine
from roles.runtime.field import FieldConfig
from roles.runtime.wireproc import ProcessEngine, exit_words

from fieldbox.app import FieldboxApp, engine_factory, stale_check_in, wire_kind

from .helpers import one_team, text_of, until


def test_the_wire_runs_in_a_process_unless_asked_otherwise(monkeypatch):
    monkeypatch.delenv("FIELDBOX_WIRE", raising=False)
    assert wire_kind(None) == "process"
    monkeypatch.setenv("FIELDBOX_WIRE", "thread")
    assert wire_kind(None) == "thread"

    class Args:
        wire = "process"

    assert wire_kind(Args()) == "process"  # the option wins over the environment


async def test_the_app_drives_a_field_in_another_process(tmp_path):
    config = FieldConfig(team=254, plan="ephemeral", log_dir=str(tmp_path))
    app = FieldboxApp(engine_factory("process"), config, panel="fms", animate=False)
    async with app.run_test(size=(120, 40)) as pilot:
        engine = app.engine
        assert isinstance(engine, ProcessEngine)
        assert await until(pilot, lambda: engine.field.stations[0].ds.link.robot_comms)
        inspector = app.query_one("#panel-inspector")
        assert await until(pilot, lambda: any(k for k in inspector.ring.links))  # taps from the child
        await pilot.press("d", "1", "5", "escape")  # a period length: a typed command to the child
        # views are values: the field's FMS is a newer view each time the wire sends one
        assert await until(pilot, lambda: engine.field.fms.match.timing.auto == 15)
        assert await until(pilot, lambda: "auto period is now 15 s" in text_of(app, "#fms-timing-note"))
        await pilot.press("t")  # practice -> qualification, same number
        await pilot.pause(0.2)
        assert text_of(app, "#fms-match").startswith("Qualification match 1")
        assert app.run_command("enable")  # sent without waiting; the child's CommandError comes back
        assert await until(pilot, lambda: any("an FMS is attached" in str(n.message)
                                               for n in app._notifications))
        await pilot.press("s")  # the match starts: the DS is enabled in auto
        assert await until(pilot, lambda: engine.field.stations[0].ds.enabled)
        assert engine.field.fms.match.phase == Phase.AUTO
        await pilot.press("ctrl+a")  # abort
        assert await until(pilot, lambda: not engine.field.stations[0].ds.enabled)

        pid = engine.proc.pid
        os.kill(pid, signal.SIGKILL)
        assert await until(pilot, lambda: any("wire process ended" in str(n.message)
                                               for n in app._notifications))
        assert not app.run_command("disable")  # refused with a notification, no hang
        assert await until(pilot, lambda: any("wire process has ended" in str(n.message)
                                               for n in app._notifications))
    assert engine.proc.poll() is not None


async def test_the_faults_tab_counts_move_with_the_wire_in_another_process(tmp_path):
    # issue 20: the DS and roboRIO counters froze at the values of the first snapshot (the
    # rows kept the stats dicts of a core the wire later sent anew)
    config = FieldConfig(team=254, plan="ephemeral", log_dir=str(tmp_path))
    app = FieldboxApp(engine_factory("process"), config, panel="faults", animate=False)
    async with app.run_test(size=(160, 50)) as pilot:
        engine = app.engine
        assert await until(pilot, lambda: engine.field.stations[0].ds.link.robot_comms)
        panel = app.query_one("#panel-faults")
        assert await until(pilot, lambda: (panel.value("ds254-control", "out") or 0) > 0)
        first = {(row, column): panel.value(row, column) or 0 for row, column in
                 (("ds254-control", "out"), ("rio254-control", "in"), ("rio254-status", "out"))}
        assert await until(pilot, lambda: all((panel.value(r, c) or 0) > first[(r, c)] + 50 for r, c in first))


async def test_a_killed_wire_says_it_ended_and_f9_starts_a_field_with_the_robot_disabled(tmp_path):
    config = FieldConfig(roles=frozenset({"ds", "rio"}), team=254, plan="ephemeral", log_dir=str(tmp_path))
    app = FieldboxApp(engine_factory("process"), config, animate=False)
    async with app.run_test(size=(120, 40)) as pilot:
        engine = app.engine
        ds = lambda: app.engine.field.stations[0].ds  # noqa: E731 - the latest view from the wire process
        assert await until(pilot, lambda: ds().link.robot_comms and ds().link.robot_code)
        assert app.run_command("enable")
        assert await until(pilot, lambda: ds().enabled)
        os.kill(engine.proc.pid, signal.SIGKILL)
        assert await until(pilot, lambda: "THE FIELD STOPPED" in text_of(app, "#stale-banner"))
        banner = text_of(app, "#stale-banner")
        assert app.query_one("#stale-banner").display
        assert "the wire process ended (killed by SIGKILL)" in banner
        assert "F9 starts the field again (every robot disabled)" in banner and "ctrl+q" in banner
        assert "Keys wait and go when it answers" not in banner  # nothing will answer
        assert "ENABLED" not in text_of(app, "#status-line")
        await pilot.press("f9")  # a fresh wire: the robot comes back disabled, not enabled again
        assert await until(pilot, lambda: app.engine is not engine and ds().link.robot_comms and ds().link.robot_code)
        assert not ds().enabled and not app.engine.field.stations[0].rio.enabled
        assert await until(pilot, lambda: not app.query_one("#stale-banner").display)
        assert any("the field started again after the wire process ended (killed by SIGKILL): every robot is "
                   "disabled" in str(n.message) for n in app._notifications)
        await pilot.press("f9")  # while it runs: refused, the field goes on
        assert any("the field runs: nothing to start again" in str(n.message) for n in app._notifications)
        assert app.engine.end_reason is None
    assert engine.proc.poll() is not None


def test_a_wire_process_end_is_said_as_a_user_reads_it():
    assert exit_words(-signal.SIGKILL) == "killed by SIGKILL" and exit_words(3) == "exit code 3"
    assert exit_words(None) == "exit code unknown" and exit_words(-200) == "killed by signal 200"


class _QuietSim(SimEngine):
    """A field on a fake clock whose wire last answered at ``heard_at`` (the engine's clock)."""

    heard_at = 1000.0

    def age(self) -> float:
        return max(0.0, self.now() - self.heard_at)


async def test_the_banner_is_due_the_moment_the_wires_last_answer_is_300_ms_old():
    # issue 27: checked by the 10 Hz refresh alone, the banner came ~440 ms after the last answer
    app = FieldboxApp(_QuietSim, one_team(), animate=False)
    async with app.run_test(size=(120, 40)) as pilot:
        engine, banner = app.engine, app.query_one("#stale-banner")
        engine.heard_at = last = engine.now()
        engine.advance(0.1)
        app._watch_wire()  # as its timer fires: it sets itself for the last answer + STALE_AFTER
        assert app.banner_due_at == pytest.approx(last + STALE_AFTER)
        engine.advance(STALE_AFTER - 0.1 - 0.001)  # a millisecond before: no banner
        app._watch_wire()
        assert not banner.display and not app.wire_stale
        assert app.banner_due_at == pytest.approx(last + STALE_AFTER)
        engine.advance(0.002)  # a millisecond after: the banner, at once, from this timer
        app._watch_wire()
        assert banner.display and app.wire_stale
        assert "NO ANSWER FROM THE WIRE for 0.3 s" in text_of(app, "#stale-banner")
        engine.heard_at = engine.now()  # it answers again: gone at the next look
        app._watch_wire()
        app.refresh_views()
        await pilot.pause()
        assert not banner.display and app.banner_due_at == pytest.approx(engine.now() + STALE_AFTER)


def test_the_banners_timer_is_set_for_the_moment_it_is_due_and_never_spins():
    assert stale_check_in(0.0) == STALE_AFTER
    assert stale_check_in(0.25) == pytest.approx(STALE_AFTER - 0.25)
    # once stale, a look every STALE_AFTER: the 10 Hz refresh keeps the banner's count
    assert stale_check_in(STALE_AFTER) == STALE_AFTER and stale_check_in(60.0) == STALE_AFTER
