"""The app with its wire in a child process (roles/runtime/wireproc.py), as ``fieldbox`` runs by
default: real loopback sockets, ephemeral ports, the panels reading the views it sends."""

from __future__ import annotations

import os
import signal

from roles.cores.match import Phase
from roles.runtime.field import FieldConfig
from roles.runtime.wireproc import ProcessEngine

from fieldbox.app import FieldboxApp, engine_factory, wire_kind

from .helpers import text_of, until


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
        assert await until(pilot, lambda: engine.field.stations[0].ds.robot_comms)
        inspector = app.query_one("#panel-inspector")
        assert await until(pilot, lambda: any(k for k in inspector.ring.links))  # taps from the child
        await pilot.press("d", "1", "5", "escape")  # a period length: a CoreCall to the child
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
        assert await until(pilot, lambda: engine.field.stations[0].ds.robot_comms)
        panel = app.query_one("#panel-faults")
        assert await until(pilot, lambda: (panel.value("ds254-control", "out") or 0) > 0)
        first = {(row, column): panel.value(row, column) or 0 for row, column in
                 (("ds254-control", "out"), ("rio254-control", "in"), ("rio254-status", "out"))}
        assert await until(pilot, lambda: all((panel.value(r, c) or 0) > first[(r, c)] + 50 for r, c in first))
