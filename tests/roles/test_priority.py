"""The wire thread's real-time priority (roles/priority.py), in the wire's own process."""

from __future__ import annotations

import os
import resource
import threading

import pytest

from roles import priority
from roles.field import FieldConfig
from roles.wireproc import ProcessEngine

pytestmark = pytest.mark.skipif(not hasattr(os, "sched_getscheduler"), reason="Linux scheduling")


def _in_a_thread(fn):
    out = {}

    def run():
        out["said"] = fn()
        out["policy"] = os.sched_getscheduler(0)

    t = threading.Thread(target=run)
    t.start()
    t.join()
    return out


def _may_be_realtime() -> bool:
    """Root, or a real-time limit of 1 or more (CAP_SYS_NICE alone is not looked for)."""
    soft, _ = resource.getrlimit(resource.RLIMIT_RTPRIO)
    return os.geteuid() == 0 or soft == resource.RLIM_INFINITY or soft >= 1


def test_off_when_asked(monkeypatch):
    monkeypatch.setenv(priority.ENV, "0")
    out = _in_a_thread(priority.raise_wire_thread)
    assert out["said"] == "normal priority (FIELDBOX_REALTIME=0)"
    assert out["policy"] == os.SCHED_OTHER


def test_only_the_calling_thread_is_raised(monkeypatch):
    monkeypatch.delenv(priority.ENV, raising=False)
    out = _in_a_thread(priority.raise_wire_thread)
    if out["said"].startswith("real-time"):
        assert out["policy"] == os.SCHED_RR
    else:  # not allowed here: it says why, and nothing changed
        assert "real-time needs" in out["said"] or out["said"].startswith("normal")
        assert out["policy"] == os.SCHED_OTHER
    assert os.sched_getscheduler(0) == os.SCHED_OTHER  # this thread, untouched


def test_the_wire_process_raises_its_wire_thread_only(tmp_path, monkeypatch):
    monkeypatch.delenv(priority.ENV, raising=False)
    engine = ProcessEngine(FieldConfig(team=254, plan="ephemeral", log_dir=str(tmp_path),
                                       roles=frozenset({"ds", "rio"})))
    engine.start()
    try:
        said, tid = engine.priority
        wire_policy = os.sched_getscheduler(tid)
        others = {int(t) for t in os.listdir(f"/proc/{engine.proc.pid}/task")} - {tid}
        if _may_be_realtime():
            assert said == "real-time priority (SCHED_RR 1)" and wire_policy == os.SCHED_RR
            assert os.sched_getparam(tid).sched_priority == 1
        else:
            assert said.startswith("normal priority") and wire_policy == os.SCHED_OTHER
        assert others and all(os.sched_getscheduler(t) == os.SCHED_OTHER for t in others)
        assert os.sched_getscheduler(0) == os.SCHED_OTHER  # the app's process keeps its own
    finally:
        engine.stop()
