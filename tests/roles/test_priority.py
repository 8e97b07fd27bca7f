"""The wire thread's real-time priority (roles/runtime/priority.py), in the wire's own process."""

from __future__ import annotations

import os
import threading

import pytest

from roles.runtime import priority
from roles.runtime.field import FieldConfig
from roles.runtime.wireproc import ProcessEngine

pytestmark = pytest.mark.skipif(not hasattr(os, "sched_getscheduler"), reason="Linux scheduling")

RESET = getattr(os, "SCHED_RESET_ON_FORK", 0)


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


def test_off_when_asked(monkeypatch):
    monkeypatch.setenv(priority.ENV, "0")
    out = _in_a_thread(priority.raise_wire_thread)
    assert out["said"] == "normal priority (FIELDBOX_REALTIME=0)"
    assert out["policy"] == os.SCHED_OTHER


def test_only_the_calling_thread_is_raised(monkeypatch):
    monkeypatch.delenv(priority.ENV, raising=False)
    out = _in_a_thread(priority.raise_wire_thread)
    if _may_be_realtime():
        assert out["said"] == "real-time priority (SCHED_RR 1)" and out["policy"] == os.SCHED_RR
    else:  # not allowed here: it says why, and nothing changed
        assert out["said"].startswith("normal priority (real-time needs CAP_SYS_NICE")
        assert out["policy"] == os.SCHED_OTHER
    assert out["its_thread"] == os.SCHED_OTHER  # threads it starts are not real-time
    assert _policy() == os.SCHED_OTHER  # this thread, untouched


def test_the_wire_process_raises_its_wire_thread_only(tmp_path, monkeypatch):
    monkeypatch.delenv(priority.ENV, raising=False)
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
