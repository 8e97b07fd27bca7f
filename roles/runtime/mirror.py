"""Snapshots of a field that carry only what changed: the wire process's side
(:class:`Snapshots`) and the app's (:class:`Mirror`). See roles/runtime/wireproc.py.

A *root* is a core the mirror keeps as one object for the life of the field (a DS, a fake
roboRIO, the FMS, the fault injector, and a DS's robot codec): the app's copy is updated in
place, so a panel holding it sees it move. A root is sent attribute by attribute (its
``__getstate__``), each attribute pickled on its own, and an attribute goes only when its
pickle differs from the one sent last. Inside a pickle:

* a reference to a root is a reference (``_mirror_ref``), never a copy: a DS's FMS link
  points back at its DS, a robot's ``_emit`` at its roboRIO;
* a ``collections.deque`` goes whole once, then only the items appended since
  (``_mirror_deque_more``): a DS's 300 battery samples, its 256 round-trip times and its
  console. The child finds them after the last item it sent (by identity), and checks that
  the app's copy extended by them equals the deque; anything else (a deque cleared, popped
  on the left) sends it whole again, under a new token (the app drops the old copy). The
  app extends its copy in place, so every reference to it (the FMS reaches a station's
  deques through its stations and its connections) sees the new items, and it is mutated
  while the drawing thread may read it, exactly as the wire thread mutates the real one
  under ``--wire thread``: a panel copies a deque with ``list()`` before it iterates. Items
  are not sent again if they change in place: the roles append immutable items (tuples,
  floats, frozen dataclasses);
* a ``random.Random`` is a fresh one: its 2.5 KB of state means nothing to a panel.

Whole cores were a third of the app process's busy time; their changes alone are a
fraction of that.

A message lost on the way (the child drops snapshots while the app does not read) would leave
the app's copy behind for good: :meth:`Snapshots.resync` starts every unit over from whole
(``reset`` in the next payload tells the app to forget its deques).
"""

from __future__ import annotations

import collections
import enum
import io
import itertools
import pickle
import random
import weakref
from typing import Any, Callable

PROTOCOL = pickle.HIGHEST_PROTOCOL

#: Attributes of a root that are roots too (their identity matters: the legacy panel starts
#: its NetConsole over when a DS's codec changes).
NESTED = ("_codec",)



def unit_keys(field) -> list:
    """The field's units, in the order the child sends them: each station (its DS and
    roboRIO together), the FMS, the fault injector."""
    keys: list = [("station", i) for i in range(len(field.stations))]
    if field.fms is not None:
        keys.append("fms")
    keys.append("faults")
    return keys


def unit_roots(field, key) -> list[tuple[str, Any]]:
    """``(path, object)`` of the roots of one unit (``None`` for a station without a DS or
    roboRIO), nested ones after their owner."""
    if key == "fms":
        roots: list[tuple[str, Any]] = [("fms", field.fms)]
    elif key == "faults":
        roots = [("faults", field.faults)]
    else:
        i = key[1]
        st = field.stations[i]
        roots = [(f"s{i}.ds", st.ds), (f"s{i}.rio", st.rio)]
    for path, obj in list(roots):
        inner = getattr(obj, "__dict__", None)
        if inner is None:
            continue
        for name in NESTED:
            value = inner.get(name)
            if value is not None and hasattr(value, "__dict__"):
                roots.append((f"{path}.{name}", value))
    return roots


_SCALARS = {int, float, complex, str, bytes, bool, type(None)}
_immutable_types: dict[type, bool] = {}


def _immutable(value: Any, depth: int = 3) -> bool:
    """Whether ``value`` cannot change while the same object (so an attribute still holding
    it need not be pickled again): scalars, enum members, and tuples and frozen dataclasses
    of those."""
    kind = type(value)
    known = _immutable_types.get(kind)
    if known is None:
        known = kind in _SCALARS or issubclass(kind, enum.Enum)
        _immutable_types[kind] = known
    if known:
        return True
    if depth <= 0:
        return False
    if isinstance(value, tuple):
        return all(_immutable(item, depth - 1) for item in value)
    params = getattr(kind, "__dataclass_params__", None)
    if params is not None and params.frozen:
        return all(_immutable(getattr(value, name), depth - 1) for name in kind.__dataclass_fields__)
    return False


def _state(obj) -> dict:
    state = obj.__getstate__()
    if state is None:  # an instance with nothing in its __dict__ yet
        return {}
    if not isinstance(state, dict):
        raise TypeError(f"{type(obj).__name__}: a mirrored core keeps its state in a __dict__")
    return state


# -- the wire process's side -----------------------------------------------------------------
class _Pickler(pickle.Pickler):
    def __init__(self, file, snapshots: "Snapshots", roots: dict[int, tuple[str, Any]]) -> None:
        super().__init__(file, PROTOCOL)
        self._file = file
        self.snapshots = snapshots
        self.roots = roots
        self.moved = False  # a deque sent items: the attribute goes even if its bytes repeat

    def bytes_of(self, value: Any) -> bytes:
        """``value`` pickled on its own (``moved`` says whether a deque sent items)."""
        buf = self._file
        buf.seek(0)
        buf.truncate()
        self.clear_memo()
        self.moved = False
        self.dump(value)
        return buf.getvalue()

    def reducer_override(self, obj):
        kind = type(obj)
        if kind is collections.deque:
            reduced, moved = self.snapshots.deque(obj)
            self.moved = self.moved or moved
            return reduced
        if kind is random.Random:
            return random.Random, ()
        root = self.roots.get(id(obj))
        if root is not None and root[1] is obj:
            return _mirror_ref, (root[0], kind)
        return NotImplemented


class Snapshots:
    """What the app was sent last, per root attribute and per deque (wire thread only)."""

    def __init__(self, field) -> None:
        self.field = field
        self._sent: dict[str, tuple[type, dict[str, bytes]]] = {}
        self._values: dict[str, dict[str, Any]] = {}  # the immutable values sent, by root
        self._deques: dict[int, list] = {}  # id -> [weakref, token, the items sent]
        self._tokens = itertools.count(1)
        # tokens of deques that died (their weakrefs' callbacks may run on any thread)
        self._gone: collections.deque[int] = collections.deque()
        self._reset = False
        self._buffer = io.BytesIO()

    def resync(self) -> None:
        """A payload was lost: everything goes whole again, and the app forgets its deques."""
        self._sent.clear()
        self._values.clear()
        self._deques.clear()
        self._gone.clear()
        self._reset = True

    def payload(self, keys) -> tuple[bool, list[int], dict]:
        """``(reset, gone, {unit key: patch})`` for the units ``keys``; a patch is a list of
        ``(path, class or None, {attribute: pickle}, [attributes gone], whole)``."""
        roots_by_id: dict[int, tuple[str, Any]] = {}
        units = {}
        for key in unit_keys(self.field):
            for path, obj in unit_roots(self.field, key):
                if obj is not None:
                    roots_by_id[id(obj)] = (path, obj)
        pickler = _Pickler(self._buffer, self, roots_by_id)
        for key in keys:
            units[key] = [self._patch(path, obj, pickler) for path, obj in unit_roots(self.field, key)]
        reset, self._reset = self._reset, False
        gone = [self._gone.popleft() for _ in range(len(self._gone))]
        return reset, gone, units

    def _patch(self, path: str, obj: Any, pickler: _Pickler) -> tuple:
        if obj is None:
            self._sent.pop(path, None)
            self._values.pop(path, None)
            return path, None, {}, [], True
        kind = type(obj)
        last = self._sent.get(path)
        before: dict[str, bytes] = last[1] if last is not None and last[0] is kind else {}
        kept: dict[str, Any] = self._values.get(path, {}) if before else {}
        now: dict[str, bytes] = {}
        values: dict[str, Any] = {}  # immutable values, whose pickle need not be made again
        changed: dict[str, bytes] = {}
        for name, value in _state(obj).items():
            if name in kept and kept[name] is value:  # the same immutable object: sent already
                now[name] = before[name]
                values[name] = value
                continue
            data = pickler.bytes_of(value)
            if pickler.moved:  # deques sent items: kept is the pickle once they have not
                changed[name] = data
                data = pickler.bytes_of(value)
            elif before.get(name) != data:
                changed[name] = data
            now[name] = data
            if _immutable(value):
                values[name] = value
        self._sent[path] = (kind, now)
        self._values[path] = values
        # whole: the app starts this root's state afresh (first time, after a resync, a new
        # class), so nothing it held before (an attribute since deleted) survives
        return path, kind, changed, [name for name in before if name not in now], not before

    def deque(self, d: collections.deque) -> tuple[tuple, bool]:
        """The reduction of ``d``: its new items if the app has it, else the whole of it."""
        entry = self._deques.get(id(d))
        if entry is not None and entry[0]() is d:
            items = tuple(d)
            new = _appended(items, entry[2], d.maxlen)
            if new is not None:
                if new:
                    entry[2] = items
                return (_mirror_deque_more, (entry[1], new)), bool(new)
        if entry is not None:  # sent whole again under a new token: the app drops the old copy
            self._gone.append(entry[1])
        token = next(self._tokens)
        key = id(d)

        def forget(_ref, key=key, token=token) -> None:
            entry = self._deques.get(key)
            if entry is not None and entry[1] == token:
                self._deques.pop(key, None)
                self._gone.append(token)

        items = tuple(d)
        self._deques[key] = [weakref.ref(d, forget), token, items]
        return (_mirror_deque_full, (token, d.maxlen, items)), True


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


# The reductions' callables, by name: only :class:`Mirror`'s unpickler resolves them.
def _mirror_ref(path: str, kind: type) -> Any:
    raise pickle.UnpicklingError("a mirror reference outside the mirror")


def _mirror_deque_full(token: int, maxlen: int | None, items: tuple) -> Any:
    raise pickle.UnpicklingError("a mirror deque outside the mirror")


def _mirror_deque_more(token: int, items: tuple) -> Any:
    raise pickle.UnpicklingError("a mirror deque outside the mirror")


# -- the app's side ---------------------------------------------------------------------------
class _Unpickler(pickle.Unpickler):
    def __init__(self, data: bytes, mirror: "Mirror") -> None:
        super().__init__(io.BytesIO(data))
        self._resolve: dict[str, Callable] = {"_mirror_ref": mirror.ref,
                                              "_mirror_deque_full": mirror.deque_full,
                                              "_mirror_deque_more": mirror.deque_more}

    def find_class(self, module: str, name: str):
        if module == __name__ and name in self._resolve:
            return self._resolve[name]
        return super().find_class(module, name)


class Mirror:
    """The app's copies of the roots, by path (one thread applies; others only read)."""

    def __init__(self) -> None:
        self.objects: dict[str, Any] = {}
        self._deques: dict[int, collections.deque] = {}

    def apply(self, payload: tuple[bool, list[int], dict]) -> dict:
        """Apply a :meth:`Snapshots.payload`; returns its units ``{key: {path: object}}``.
        Each root's new state is swapped in at once (a reader never sees half of it)."""
        reset, gone, units = payload
        if reset:
            self._deques.clear()
        for token in gone:
            self._deques.pop(token, None)
        shown = {}
        for key, patch in units.items():
            roots = {}
            for path, kind, changed, removed, whole in patch:
                if kind is None:
                    self.objects.pop(path, None)
                    roots[path] = None
                    continue
                obj = self.ref(path, kind)
                state = {} if whole else dict(obj.__dict__)
                for name, data in changed.items():
                    state[name] = _Unpickler(data, self).load()
                for name in removed:
                    state.pop(name, None)
                obj.__dict__ = state
                roots[path] = obj
            shown[key] = roots
        return shown

    def ref(self, path: str, kind: type) -> Any:
        obj = self.objects.get(path)
        if obj is None or type(obj) is not kind:
            obj = kind.__new__(kind)
            self.objects[path] = obj
        return obj

    def deque_full(self, token: int, maxlen: int | None, items: tuple) -> collections.deque:
        d = collections.deque(items, maxlen)
        self._deques[token] = d
        return d

    def deque_more(self, token: int, items: tuple) -> collections.deque:
        old = self._deques.get(token)
        if old is None:  # cannot happen while the two sides agree; show what came
            raise pickle.UnpicklingError(f"mirror deque {token} unknown")
        old.extend(items)  # in place: every reference to it sees them (see the module's notes)
        return old
