"""How each of our processes sets CPython's cyclic collector, the GIL's hand-over and the
scheduler: the whole policy, applied by explicit calls where a process starts, never by an
import.

Who calls what:

* **the app** (fieldbox/app.py, when its main asks for it): :func:`hold_collector` while its
  wire runs, :func:`release_collector` when the wire stops;
* **a wire thread beside other threads** (``ThreadEngine``): :func:`quick_gil_handover`;
* **the wire's own process** (roles/runtime/wireproc.py) and **the classroom's field**
  (roles/runtime/classroom.py): :func:`quiet_collector` as it starts, :func:`tune_wire_thread`
  on the wire thread once the field is bound, then :func:`full_collection` every
  :data:`GC_PERIOD` from the wire's loop;
* **headless** (fieldbox/headless.py): :func:`raise_wire_thread` on its loop's thread;
* **a robot program's host process** (roles/runtime/program_host.py): :func:`below_the_wire`;
* **the classroom's fork server** (fieldbox/tabfork.py): :func:`freeze_for_forks`;
* **the app's rings of plain data** (the inspector's packets, the console's lines):
  :func:`untrack_plain` on each item.

Why each rule exists and what it bought: docs/figures.md, "Why". Nothing here imports a
role core or a UI library: every process may import it.
"""

from __future__ import annotations

import gc
import itertools
import logging
import os
import sys
import threading
import time
from typing import Callable

log = logging.getLogger("fieldbox.tuning")

# -- the collector beside the app ------------------------------------------------------------
#: The oldest generation's threshold while the app holds the collector (CPython's is 10). Rare
#: long pauses beat frequent short ones: each pause costs every DS about one late interval,
#: whatever its length.
THRESHOLD2 = 30

_hold_lock = threading.Lock()
_holds = 0  # wires running beside the app's heap
_saved_threshold: tuple[int, ...] | None = None


def hold_collector() -> None:
    """A wire starts beside the app's heap (Textual's widgets, styles and caches): what exists
    now is frozen (``gc.freeze``: out of the collector's sight, still freed by reference
    counting), and full collections wait for :data:`THRESHOLD2` young ones. A full collection
    walks every tracked object holding the GIL, so the wire (a thread) or the views' reader
    (the wire in a process of its own) stops meanwhile. Calls nest; the last
    :func:`release_collector` undoes the first hold."""
    global _holds, _saved_threshold
    with _hold_lock:
        _holds += 1
        if _holds == 1:
            _saved_threshold = gc.get_threshold()
            gc.freeze()
            t0, t1, t2 = _saved_threshold
            gc.set_threshold(t0, t1, max(t2, THRESHOLD2))


def release_collector() -> None:
    """A wire beside the app stopped: after the last one, the collector is as it was."""
    global _holds, _saved_threshold
    with _hold_lock:
        if _holds == 0:
            return
        _holds -= 1
        if _holds == 0:
            if _saved_threshold is not None:
                gc.set_threshold(*_saved_threshold)
                _saved_threshold = None
            gc.unfreeze()


# -- the collector in the wire's own process --------------------------------------------------
#: How often the wire's process runs its one full collection (from its loop, between two
#: callbacks): the automatic ones paused the loop for tens of milliseconds every few seconds.
GC_PERIOD = 10.0
#: Every this many full collections, everything is unfrozen first, so cycles that died after
#: they were frozen (a closed connection's transport, a restarted robot program) are freed too.
GC_UNFREEZE_EVERY = 6

_collections = itertools.count(1)


def quiet_collector() -> None:
    """Where a process that is only the wire starts: what the imports made is frozen, young
    collections stay automatic (cheap), and full ones happen only through
    :func:`full_collection`."""
    gc.freeze()
    t0, t1, _ = gc.get_threshold()
    gc.set_threshold(t0, t1, 1_000_000_000)


def full_collection() -> None:
    """The wire process's full collection, then a freeze: the next one walks only what is new."""
    t0 = time.perf_counter()
    if next(_collections) % GC_UNFREEZE_EVERY == 0:
        gc.unfreeze()
    gc.collect()
    gc.freeze()
    took = time.perf_counter() - t0
    if took > 0.005:
        log.debug("wire process: a full collection took %.1f ms", took * 1e3)


def freeze_for_forks() -> None:
    """In the fork server, once the tabs' modules are imported: what they made is frozen, so the
    forked tabs' collections never write to (and so never copy) the pages they share."""
    gc.collect()
    gc.freeze()


def _untracker() -> Callable[[object], None]:
    """CPython's ``PyObject_GC_UnTrack``; elsewhere (no ``ctypes.pythonapi``), nothing."""
    try:
        import ctypes

        untrack = ctypes.pythonapi.PyObject_GC_UnTrack
    except (ImportError, AttributeError, OSError):  # pragma: no cover - not CPython
        return lambda obj: None
    untrack.argtypes = (ctypes.py_object,)
    untrack.restype = None
    return untrack


#: ``untrack_plain(obj)``: the collector stops looking at an object that holds only numbers,
#: strings, bytes and plain tuples of them (the inspector's packets, the console's lines). Such
#: an object can never be in a reference cycle, and tens of thousands of them made every full
#: collection longer. CPython untracks plain tuples like it by itself, but not named tuples.
untrack_plain: Callable[[object], None] = _untracker()


# -- the GIL ------------------------------------------------------------------------------------
#: While the app draws on another thread, the wire thread must get the GIL back quickly when a
#: socket or timer wakes it: CPython's default hand-over is 5 ms.
WIRE_SWITCH_INTERVAL = 0.0001


def quick_gil_handover() -> float:
    """A wire thread starts beside other threads: the switch interval at most
    :data:`WIRE_SWITCH_INTERVAL`. Returns the interval to put back when it stops."""
    old = sys.getswitchinterval()
    sys.setswitchinterval(min(old, WIRE_SWITCH_INTERVAL))
    return old


# -- the scheduler ------------------------------------------------------------------------------
#: The environment variable that keeps the wire at normal priority (``0``, ``off``, ``no``).
REALTIME_ENV = "FIELDBOX_REALTIME"
#: The wire thread's real-time priority: the lowest (SCHED_RR 1).
REALTIME_PRIORITY = 1
#: A robot program's niceness: below the wire, as user code runs below the roboRIO's network
#: daemon.
PROGRAM_NICE = 10


def raise_wire_thread() -> str:
    """Run on the wire thread: SCHED_RR at :data:`REALTIME_PRIORITY` where allowed. Returns
    what happened, in words for the log.

    A woken thread at normal priority may wait for the running one's time slice (a kernel
    tick); a real-time one preempts it. Only the calling thread is raised: threads and
    processes it starts begin at normal priority (``SCHED_RESET_ON_FORK``), and the kernel
    keeps 5 % of each CPU for normal threads whatever real-time ones do. Allowed with
    CAP_SYS_NICE or a ``ulimit -r`` of 1 or more; otherwise nothing changes and the words say
    why."""
    if os.environ.get(REALTIME_ENV, "").strip().lower() in ("0", "off", "no", "false"):
        return f"normal priority ({REALTIME_ENV}={os.environ[REALTIME_ENV]})"
    setter = getattr(os, "sched_setscheduler", None)
    if setter is None or not hasattr(os, "SCHED_RR"):
        return "normal priority (no real-time scheduling on this system)"
    # 0: this thread (Linux schedules threads). Threads it starts (asyncio's executor for name
    # lookups, a robot program's own) and processes start at normal priority.
    policy = os.SCHED_RR | getattr(os, "SCHED_RESET_ON_FORK", 0)
    try:
        setter(0, policy, os.sched_param(REALTIME_PRIORITY))
    except PermissionError:
        return ("normal priority (real-time needs CAP_SYS_NICE, which root has unless a container "
                f"took it away, or `ulimit -r` of 1 or more; set {REALTIME_ENV}=0 to stop trying)")
    except OSError as exc:
        return f"normal priority ({exc.strerror or exc})"
    return f"real-time priority (SCHED_RR {REALTIME_PRIORITY})"


def tune_wire_thread() -> tuple[str, int]:
    """Run on the wire thread of a process that is only the wire (after :func:`quiet_collector`),
    once its field is bound: what the field made is collected and frozen, then
    :func:`raise_wire_thread`. Returns the priority in words and the thread's id (a test reads
    its policy)."""
    gc.collect()
    gc.freeze()
    return raise_wire_thread(), threading.get_native_id()


def below_the_wire() -> None:
    """In a robot program's process: niceness :data:`PROGRAM_NICE` and, where there is one,
    the batch policy, so the program never delays the wire's beat."""
    try:
        os.nice(PROGRAM_NICE)
    except OSError:
        pass
    if hasattr(os, "sched_setscheduler") and hasattr(os, "SCHED_BATCH"):
        try:
            os.sched_setscheduler(0, os.SCHED_BATCH, os.sched_param(0))
        except OSError:
            pass
