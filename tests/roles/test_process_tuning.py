"""How our processes set the collector, the GIL's hand-over and the scheduler
(roles/runtime/process_tuning.py): the app's hold on the collector nests and is undone after
the last; a ThreadEngine shortens the hand-over while it runs; the wire thread, and only it,
runs at real-time priority where allowed; a robot program's process runs below it."""

from __future__ import annotations

import gc
import os
import subprocess
import sys
import threading
from pathlib import Path

import pytest

from roles.runtime import process_tuning
from roles.runtime.engine import ThreadEngine
from roles.runtime.field import FieldConfig
from roles.runtime.wireproc import ProcessEngine

ROOT = Path(__file__).resolve().parents[2]
RESET = getattr(os, "SCHED_RESET_ON_FORK", 0)
linux_scheduling = pytest.mark.skipif(not hasattr(os, "sched_getscheduler"), reason="Linux scheduling")


# -- the collector ------------------------------------------------------------------------------
def test_nested_holds_undo_after_the_last():
    before = gc.get_threshold()
    gc.unfreeze()  # CPython 3.12.1 starts with objects frozen (get_freeze_count() is 375)
    assert gc.get_freeze_count() == 0
    process_tuning.hold_collector()
    process_tuning.hold_collector()
    assert gc.get_freeze_count() > 0
    assert gc.get_threshold()[2] == max(before[2], process_tuning.THRESHOLD2)
    process_tuning.release_collector()
    assert gc.get_threshold()[2] == max(before[2], process_tuning.THRESHOLD2)  # one wire still runs
    process_tuning.release_collector()
    assert gc.get_threshold() == before and gc.get_freeze_count() == 0
    process_tuning.release_collector()  # one release too many changes nothing
    assert gc.get_threshold() == before


def test_a_thread_engine_sets_and_restores_the_switch_interval_and_leaves_the_collector_alone():
    before, interval = gc.get_threshold(), sys.getswitchinterval()
    gc.unfreeze()
    engine = ThreadEngine(FieldConfig(team=254, roles=frozenset({"ds", "rio"}), plan="ephemeral",
                                      log_files=False))
    engine.start()
    try:
        # stored in µs
        assert abs(sys.getswitchinterval() - min(interval, process_tuning.WIRE_SWITCH_INTERVAL)) < 1e-9
        assert gc.get_freeze_count() == 0 and gc.get_threshold() == before  # the app's to hold
    finally:
        engine.stop()
    assert sys.getswitchinterval() == interval


def _in_a_process(code: str) -> str:
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60, cwd=ROOT)
    assert out.returncode == 0, out.stderr
    return out.stdout


def test_the_wire_process_has_no_automatic_full_collection_and_runs_its_own():
    code = ("import gc; from roles.runtime import process_tuning as t; t.quiet_collector(); "
            "assert gc.get_threshold()[2] == 1_000_000_000 and gc.get_freeze_count() > 0; "
            "said, tid = t.tune_wire_thread(); assert said.endswith(')') and tid > 0; "
            "[t.full_collection() for _ in range(t.GC_UNFREEZE_EVERY)]; "
            "assert gc.get_freeze_count() > 0; print('ok')")
    assert _in_a_process(code).strip() == "ok"


def test_plain_data_leaves_the_collectors_sight():
    class Packet(tuple):  # tracked, as a named tuple is
        pass

    packet = Packet((1, "ds 254", b"\x00"))
    assert gc.is_tracked(packet)
    process_tuning.untrack_plain(packet)
    if sys.implementation.name == "cpython":
        assert not gc.is_tracked(packet)


# -- the scheduler --------------------------------------------------------------------------------
def _policy(tid: int = 0) -> int:
    return os.sched_getscheduler(tid) & ~RESET


def _in_a_thread(fn):
    out = {}

    def run():
        out["said"] = fn()
        out["policy"] = _policy()
        child = threading.Thread(target=lambda: out.setdefault("its_thread", _policy()))
        child.start()
        child.join()

    t = threading.Thread(target=run)
    t.start()
    t.join()
    return out


def _may_be_realtime() -> bool:
    """Tried, in a thread of its own: root in a container may lack CAP_SYS_NICE."""
    out = {}

    def run():
        try:
            os.sched_setscheduler(0, os.SCHED_RR | RESET, os.sched_param(1))
            out["ok"] = True
        except OSError:
            out["ok"] = False

    t = threading.Thread(target=run)
    t.start()
    t.join()
    return out["ok"]


@linux_scheduling
def test_off_when_asked(monkeypatch):
    monkeypatch.setenv(process_tuning.REALTIME_ENV, "0")
    out = _in_a_thread(process_tuning.raise_wire_thread)
    assert out["said"] == "normal priority (FIELDBOX_REALTIME=0)"
    assert out["policy"] == os.SCHED_OTHER


@linux_scheduling
def test_only_the_calling_thread_is_raised(monkeypatch):
    monkeypatch.delenv(process_tuning.REALTIME_ENV, raising=False)
    out = _in_a_thread(process_tuning.raise_wire_thread)
    if _may_be_realtime():
        assert out["said"] == "real-time priority (SCHED_RR 1)" and out["policy"] == os.SCHED_RR
    else:  # not allowed here: it says why, and nothing changed
        assert out["said"].startswith("normal priority (real-time needs CAP_SYS_NICE")
        assert out["policy"] == os.SCHED_OTHER
    assert out["its_thread"] == os.SCHED_OTHER  # threads it starts are not real-time
    assert _policy() == os.SCHED_OTHER  # this thread, untouched


@linux_scheduling
def test_the_wire_process_raises_its_wire_thread_only(tmp_path, monkeypatch):
    monkeypatch.delenv(process_tuning.REALTIME_ENV, raising=False)
    engine = ProcessEngine(FieldConfig(team=254, plan="ephemeral", log_dir=str(tmp_path),
                                       roles=frozenset({"ds", "rio"})))
    engine.start()
    try:
        said, tid = engine.priority
        others = {int(t) for t in os.listdir(f"/proc/{engine.proc.pid}/task")} - {tid}
        if _may_be_realtime():
            assert said == "real-time priority (SCHED_RR 1)" and _policy(tid) == os.SCHED_RR
            assert os.sched_getparam(tid).sched_priority == 1
        else:
            assert said.startswith("normal priority") and _policy(tid) == os.SCHED_OTHER
        assert others and all(_policy(t) == os.SCHED_OTHER for t in others)
        assert _policy() == os.SCHED_OTHER  # the app's process keeps its own
    finally:
        engine.stop()


@linux_scheduling
def test_a_robot_programs_process_runs_below_the_wire():
    code = ("import os; from roles.runtime import process_tuning as t; before = os.nice(0); "
            "t.below_the_wire(); print(os.nice(0) - before, os.sched_getscheduler(0) == os.SCHED_BATCH)")
    raised, batch = _in_a_process(code).split()
    assert int(raised) == min(process_tuning.PROGRAM_NICE, 19 - os.nice(0)) and batch == "True"
