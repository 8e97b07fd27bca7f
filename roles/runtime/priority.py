"""The wire thread's scheduling priority, raised where the system allows it.

The wire's loop sleeps between beats and must run the moment its timer fires. On a busy
machine a woken thread at normal priority waits for the running one's time slice (up to a
kernel tick, 4 ms here); a real-time thread preempts it at once. The difference, under the
app and under six busy robot programs: docs/figures.md, "Why".

Only the wire thread is raised, to the lowest real-time priority (1): the pipe's and the
requests' threads stay normal, as does the app, and so do threads the wire thread starts
(``SCHED_RESET_ON_FORK``). The kernel keeps 5 % of each CPU for normal threads whatever
real-time ones do (``/proc/sys/kernel/sched_rt_runtime_us``), and the wire thread itself
is bounded by its inputs' bounds. Allowed to a process with CAP_SYS_NICE (root, unless a
container took it away) or where ``ulimit -r`` is 1 or more; otherwise the thread keeps
normal priority and the log says why. ``FIELDBOX_REALTIME=0`` turns it off.
"""

from __future__ import annotations

import os

#: The environment variable that turns it off (``0``, ``off``, ``no``).
ENV = "FIELDBOX_REALTIME"
PRIORITY = 1


def raise_wire_thread() -> str:
    """Run on the wire thread: give it SCHED_RR at :data:`PRIORITY` if allowed. Returns what
    happened, in words for the log."""
    if os.environ.get(ENV, "").strip().lower() in ("0", "off", "no", "false"):
        return f"normal priority ({ENV}={os.environ[ENV]})"
    setter = getattr(os, "sched_setscheduler", None)
    if setter is None or not hasattr(os, "SCHED_RR"):
        return "normal priority (no real-time scheduling on this system)"
    # 0: this thread (Linux: per thread). SCHED_RESET_ON_FORK: threads it starts (asyncio's
    # executor for name lookups, a robot program's own) and processes start at normal priority
    policy = os.SCHED_RR | getattr(os, "SCHED_RESET_ON_FORK", 0)
    try:
        setter(0, policy, os.sched_param(PRIORITY))
    except PermissionError:
        return ("normal priority (real-time needs CAP_SYS_NICE, which root has unless a container "
                f"took it away, or `ulimit -r` of 1 or more; set {ENV}=0 to stop trying)")
    except OSError as exc:
        return f"normal priority ({exc.strerror or exc})"
    return f"real-time priority (SCHED_RR {PRIORITY})"
