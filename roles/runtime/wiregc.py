"""The garbage collector while a wire thread shares the interpreter with the app.

Thread mode runs the wire next to Textual, whose heap is large (a few hundred thousand
tracked objects: widgets, styles, render caches). CPython's cyclic collector walks every
tracked object on a full collection, holding the GIL, and the wire stops meanwhile (with
CPython's defaults, 100-300 ms every second or two: docs/figures.md, "Why").

While any wire thread runs:

* everything that exists when the first one starts (modules, classes, the app's widget
  tree) is frozen (``gc.freeze``: out of the collector's sight, still freed by reference
  counting);
* full collections wait for :data:`THRESHOLD2` young-generation collections (CPython's
  default is 10).

Rare long pauses beat frequent short ones here: each pause costs every DS about one late
interval whatever its length, so what counts for the 99th percentile is how many there are.

The real cure is the wire in a process of its own (``benchmarks/field.py --beside-app``):
see docs/figures.md.

When the last wire thread stops, the collector is as it was.
"""

from __future__ import annotations

import gc
import threading

#: The third generation threshold while a wire thread runs.
THRESHOLD2 = 30

_lock = threading.Lock()
_wires = 0  # wire threads running
_saved: tuple[int, ...] | None = None


def wire_started() -> None:
    global _wires, _saved
    with _lock:
        _wires += 1
        if _wires == 1:
            _saved = gc.get_threshold()
            gc.freeze()
            t0, t1, t2 = _saved
            gc.set_threshold(t0, t1, max(t2, THRESHOLD2))


def wire_stopped() -> None:
    global _wires, _saved
    with _lock:
        if _wires == 0:
            return
        _wires -= 1
        if _wires == 0:
            if _saved is not None:
                gc.set_threshold(*_saved)
                _saved = None
            gc.unfreeze()
