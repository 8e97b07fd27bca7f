"""Views across a process boundary: the wire process's side (:class:`ViewSender`) and the
app's (:class:`ViewReceiver`). See roles/runtime/wireproc.py and roles/cores/views.py.

A field is sent in *units* (each station's DS and roboRIO together, the FMS, the fault
injector), each unit as the frozen views of its cores, made on the wire thread at one
moment. A view goes whole, pickled on its own, except its streams: a ``collections.deque``
in a view (console lines, events, battery history, round-trip times, the match log) goes
whole once, then only as the items appended since. The sender finds them after the last
item it sent (by identity) and checks that the app's copy extended by them equals the
deque; anything else (a deque cleared, or popped on the left) sends it whole again under a
new token, and the app drops the old copy. The app's copy of a stream is extended in
place, so every view that holds it sees the new items; a reader copies it with ``list()``.

A payload lost on the way would leave the app's streams behind for good:
:meth:`ViewSender.resync` starts every stream over whole (``reset`` in the next payload
tells the app to forget its copies).
"""

from __future__ import annotations

import collections
import io
import itertools
import pickle
import time
import weakref
from typing import Any, Callable

PROTOCOL = pickle.HIGHEST_PROTOCOL


def unit_keys(field) -> list:
    """The field's units, in the order they are sent: each station (its DS and roboRIO
    together), the FMS, the fault injector."""
    keys: list = [("station", i) for i in range(len(field.stations))]
    if field.fms is not None:
        keys.append("fms")
    keys.append("faults")
    return keys


def unit_cores(field, key) -> list[tuple[str, Any]]:
    """``(path, core)`` of one unit (``None`` for a station without a DS or roboRIO)."""
    if key == "fms":
        return [("fms", field.fms)]
    if key == "faults":
        return [("faults", field.faults)]
    i = key[1]
    st = field.stations[i]
    return [(f"s{i}.ds", st.ds), (f"s{i}.rio", st.rio)]


# -- the wire process's side -----------------------------------------------------------------
class _Pickler(pickle.Pickler):
    def __init__(self, file, sender: "ViewSender") -> None:
        super().__init__(file, PROTOCOL)
        self._file = file
        self.sender = sender

    def bytes_of(self, value: Any) -> bytes:
        buf = self._file
        buf.seek(0)
        buf.truncate()
        self.clear_memo()
        self.dump(value)
        return buf.getvalue()

    def reducer_override(self, obj):
        if type(obj) is collections.deque:
            return self.sender.stream(obj)
        return NotImplemented


class ViewSender:
    """What the app was sent of each stream (wire thread only)."""

    def __init__(self, field, clock: Callable[[], float] | None = None) -> None:
        self.field = field
        self.clock = clock or field.clock or time.monotonic
        self._streams: dict[int, list] = {}  # id -> [weakref, token, the items sent]
        self._tokens = itertools.count(1)
        # tokens of streams that died (their weakrefs' callbacks may run on any thread)
        self._gone: collections.deque[int] = collections.deque()
        self._reset = False
        self._buffer = io.BytesIO()

    def resync(self) -> None:
        """A payload was lost: every stream goes whole again, and the app forgets its copies."""
        self._streams.clear()
        self._gone.clear()
        self._reset = True

    def payload(self, keys) -> tuple[bool, list[int], dict]:
        """``(reset, gone, {unit key: [(path, pickled view or None)]})`` for the units ``keys``."""
        now = self.clock()
        pickler = _Pickler(self._buffer, self)
        units = {}
        for key in keys:
            units[key] = [(path, None if core is None else pickler.bytes_of(core.view(now)))
                          for path, core in unit_cores(self.field, key)]
        reset, self._reset = self._reset, False
        gone = [self._gone.popleft() for _ in range(len(self._gone))]
        return reset, gone, units

    def stream(self, d: collections.deque) -> tuple:
        """The reduction of ``d``: its new items if the app has it, else the whole of it."""
        entry = self._streams.get(id(d))
        if entry is not None and entry[0]() is d:
            items = tuple(d)
            new = _appended(items, entry[2], d.maxlen)
            if new is not None:
                if new:
                    entry[2] = items
                return _stream_more, (entry[1], new)
        if entry is not None:  # sent whole again under a new token: the app drops the old copy
            self._gone.append(entry[1])
        token = next(self._tokens)
        key = id(d)

        def forget(_ref, key=key, token=token) -> None:
            entry = self._streams.get(key)
            if entry is not None and entry[1] == token:
                self._streams.pop(key, None)
                self._gone.append(token)

        items = tuple(d)
        self._streams[key] = [weakref.ref(d, forget), token, items]
        return _stream_full, (token, d.maxlen, items)


def _appended(items: tuple, sent: tuple, maxlen: int | None) -> tuple | None:
    """The items appended to a deque that now holds ``items`` since it held ``sent``, or None
    when it changed otherwise (cleared, popped on the left). The answer is checked: the app's
    copy, ``sent`` extended by it (and cut to ``maxlen``), equals ``items``."""
    n = len(items)
    if sent:
        last, k = sent[-1], 0
        while k < n and items[n - 1 - k] is not last:  # usually a few new items: found at once
            k += 1
        if k == n:
            return None
    else:
        k = n
    new = items[n - k:]
    expected = sent + new
    if maxlen is not None and len(expected) > maxlen:
        expected = expected[len(expected) - maxlen:]
    return new if expected == items else None


# The reductions' callables, by name: only :class:`ViewReceiver`'s unpickler resolves them.
def _stream_full(token: int, maxlen: int | None, items: tuple) -> Any:
    raise pickle.UnpicklingError("a view's stream outside a view receiver")


def _stream_more(token: int, items: tuple) -> Any:
    raise pickle.UnpicklingError("a view's stream outside a view receiver")


# -- the app's side ---------------------------------------------------------------------------
class _Unpickler(pickle.Unpickler):
    def __init__(self, data: bytes, receiver: "ViewReceiver") -> None:
        super().__init__(io.BytesIO(data))
        self._resolve: dict[str, Callable] = {"_stream_full": receiver.stream_full,
                                              "_stream_more": receiver.stream_more}

    def find_class(self, module: str, name: str):
        if module == __name__ and name in self._resolve:
            return self._resolve[name]
        return super().find_class(module, name)


class ViewReceiver:
    """The app's copies of the streams (one thread applies; others only read views)."""

    def __init__(self) -> None:
        self._streams: dict[int, collections.deque] = {}

    def apply(self, payload: tuple[bool, list[int], dict]) -> dict:
        """A :meth:`ViewSender.payload` as ``{key: {path: view or None}}``."""
        reset, gone, units = payload
        if reset:
            self._streams.clear()
        for token in gone:
            self._streams.pop(token, None)
        return {key: {path: None if data is None else _Unpickler(data, self).load() for path, data in unit}
                for key, unit in units.items()}

    def stream_full(self, token: int, maxlen: int | None, items: tuple) -> collections.deque:
        d = collections.deque(items, maxlen)
        self._streams[token] = d
        return d

    def stream_more(self, token: int, items: tuple) -> collections.deque:
        old = self._streams.get(token)
        if old is None:  # cannot happen while the two sides agree
            raise pickle.UnpicklingError(f"view stream {token} unknown")
        old.extend(items)  # in place: every view holding it sees them
        return old
