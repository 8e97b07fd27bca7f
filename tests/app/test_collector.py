"""The app's process and the collector (roles/runtime/process_tuning.py): when the app's main
asks, the collector is held out of the wire's way while a wire runs, once however many times
the field restarts, and let go when the app ends; an app made without asking leaves it alone."""

from __future__ import annotations

import argparse
import gc

from roles.runtime import process_tuning

from fieldbox import app as app_module
from fieldbox.app import FieldboxApp, run_app

from .helpers import SIZE, make_app, one_team


def _held() -> bool:
    return gc.get_freeze_count() > 0 and gc.get_threshold()[2] >= process_tuning.THRESHOLD2


async def test_the_collector_is_held_while_the_wire_runs_and_let_go_at_the_end():
    gc.unfreeze()
    before = gc.get_threshold()
    app, engines = make_app(one_team(), hold_collector=True)
    async with app.run_test(size=SIZE) as pilot:
        await pilot.pause()
        assert _held()
        app.start_engine(one_team(roles=frozenset({"ds"})))  # the picker's restart
        await pilot.pause()
        assert len(engines) == 2 and _held() and process_tuning._holds == 1  # once, for the app
    assert gc.get_threshold() == before and gc.get_freeze_count() == 0


async def test_an_app_that_was_not_asked_leaves_the_collector_alone():
    gc.unfreeze()
    before = gc.get_threshold()
    app, _ = make_app(one_team())
    async with app.run_test(size=SIZE) as pilot:
        await pilot.pause()
        assert gc.get_threshold() == before and gc.get_freeze_count() == 0


def test_the_apps_main_asks(monkeypatch):
    asked = []
    monkeypatch.setattr(FieldboxApp, "run", lambda self: asked.append(self.hold_collector))
    monkeypatch.setattr(app_module, "engine_factory", lambda kind: None)
    assert run_app(one_team(), argparse.Namespace(theme=None, wire="thread")) == 0
    assert asked == [True]
