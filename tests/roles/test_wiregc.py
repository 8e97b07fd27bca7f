"""The collector while a wire thread runs beside the app (roles/runtime/wiregc.py): what exists is
frozen and full collections are rarer while any wire thread runs; all undone after the last."""

from __future__ import annotations

import gc
import sys

from roles.runtime import wiregc
from roles.runtime.engine import WIRE_SWITCH_INTERVAL, ThreadEngine
from roles.runtime.field import FieldConfig


def test_nested_wires_undo_after_the_last():
    before = gc.get_threshold()
    gc.unfreeze()  # CPython 3.12.1 starts with objects frozen (get_freeze_count() is 375)
    assert gc.get_freeze_count() == 0
    wiregc.wire_started()
    wiregc.wire_started()
    assert gc.get_freeze_count() > 0
    assert gc.get_threshold()[2] == max(before[2], wiregc.THRESHOLD2)
    wiregc.wire_stopped()
    assert gc.get_threshold()[2] == max(before[2], wiregc.THRESHOLD2)  # one wire still runs
    wiregc.wire_stopped()
    assert gc.get_threshold() == before and gc.get_freeze_count() == 0
    wiregc.wire_stopped()  # one stop too many changes nothing
    assert gc.get_threshold() == before


def test_a_thread_engine_sets_and_restores_the_collector_and_switch_interval():
    before, interval = gc.get_threshold(), sys.getswitchinterval()
    engine = ThreadEngine(FieldConfig(team=254, roles=frozenset({"ds", "rio"}), plan="ephemeral",
                                      log_files=False))
    engine.start()
    try:
        assert gc.get_freeze_count() > 0
        assert abs(sys.getswitchinterval() - min(interval, WIRE_SWITCH_INTERVAL)) < 1e-9  # stored in µs
    finally:
        engine.stop()
    assert gc.get_threshold() == before and gc.get_freeze_count() == 0
    assert sys.getswitchinterval() == interval
