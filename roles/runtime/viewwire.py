"""Views across a process boundary: the wire process's side (:class:`ViewSender`) and the
app's (:class:`ViewReceiver`). See roles/runtime/wireproc.py and roles/cores/views.py.

A field is sent in *units* (each station's DS and roboRIO together, the FMS, the fault
injector), each unit as the frozen views of its cores, made on the wire thread at one
moment. A view is a plain frozen value and goes as it is, except its streams: each
:class:`~roles.cores.views.StreamView` in it, at any depth of its dataclass fields (console
lines, events, round-trip times...), goes as a :class:`StreamPart`, the items numbered from
the end of the last part sent for that stream's *path* (``"s0.rio:console"``,
``"s0.ds:events.items"``). The app keeps its own copy of each stream by path, as long as the
sender's, and puts back a whole :class:`StreamView` with the same numbering, so a panel that
follows a stream by number (fieldbox/widgets.py StreamCursor) sees every new item once.

A stream whose numbering went back (a new stream at the same path) goes whole; so does every
stream after :meth:`ViewSender.resync` (a payload was lost: ``reset`` in the next payload
tells the app to forget its copies), and a part the app cannot join to its copy is an error
the engine answers with a resync.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, fields, is_dataclass, replace
from typing import Any, Callable

from roles.cores.views import StreamView

UnitKey = tuple[str, int] | str  # ("station", i), "fms" or "faults"


def unit_keys(field: Any) -> list[UnitKey]:
    """The field's units, in the order they are sent: each station (its DS and roboRIO
    together), the FMS, the fault injector."""
    keys: list[UnitKey] = [("station", i) for i in range(len(field.stations))]
    if field.fms is not None:
        keys.append("fms")
    keys.append("faults")
    return keys


def unit_cores(field: Any, key: UnitKey) -> list[tuple[str, Any]]:
    """``(path, core)`` of one unit (``None`` for a station without a DS or roboRIO)."""
    if key == "fms":
        return [("fms", field.fms)]
    if key == "faults":
        return [("faults", field.faults)]
    assert isinstance(key, tuple)
    i = key[1]
    st = field.stations[i]
    return [(f"s{i}.ds", st.ds), (f"s{i}.rio", st.rio)]


# -- what crosses ---------------------------------------------------------------------------
@dataclass(frozen=True, slots=True)
class StreamPart:
    """A stream of a view on its way, in the view's place: the items numbered ``start`` on,
    of a stream that now keeps those from ``first_seq``. ``whole``: the app forgets what it
    had of this path (``start == first_seq`` then)."""

    first_seq: int
    start: int
    items: tuple[object, ...]
    whole: bool


@dataclass(frozen=True, slots=True)
class CoreView:
    """One core's view (its streams as :class:`StreamPart`), or None for no core there."""

    path: str
    view: object


@dataclass(frozen=True, slots=True)
class Payload:
    """Views of some units. ``reset``: the app forgets every stream it holds first."""

    reset: bool
    units: dict[UnitKey, tuple[CoreView, ...]]


NOTHING = Payload(False, {})

_FIELDS: dict[type, tuple[str, ...]] = {}
# What a value of each type is to the walk (found once per type: the walk runs on every view)
_SKIP, _STREAM, _DATACLASS = range(3)
_KINDS: dict[type, int] = {StreamView: _STREAM, StreamPart: _STREAM, type(None): _SKIP, bool: _SKIP,
                           int: _SKIP, float: _SKIP, str: _SKIP, tuple: _SKIP, dict: _SKIP}


def _kind(cls: type) -> int:
    kind = _DATACLASS if is_dataclass(cls) else _SKIP  # a view holds frozen values only
    _KINDS[cls] = kind
    return kind


def _mapped(value: object, path: str, each: Callable[[str, Any], object]) -> object:
    """``value`` (a dataclass) with each stream in its fields, at any depth, replaced by what
    ``each(path, stream)`` makes of it: a new value where anything changed."""
    cls = type(value)
    names = _FIELDS.get(cls)
    if names is None:
        names = _FIELDS[cls] = tuple(f.name for f in fields(cls))  # type: ignore[arg-type]
    changes: dict[str, object] = {}
    for name in names:
        item = getattr(value, name)
        kind = _KINDS.get(type(item))
        if kind is None:
            kind = _kind(type(item))
        if kind == _SKIP:
            continue
        where = f"{path}.{name}" if path else name
        new = each(where, item) if kind == _STREAM else _mapped(item, where, each)
        if new is not item:
            changes[name] = new
    return replace(value, **changes) if changes else value  # type: ignore[type-var]


# -- the wire process's side -----------------------------------------------------------------
class ViewSender:
    """Where each stream the app holds ends (wire thread only)."""

    def __init__(self, field: Any, clock: Callable[[], float] | None = None) -> None:
        self.field = field
        self.clock = clock or field.clock or time.monotonic
        self._sent: dict[str, dict[str, int]] = {}  # core path -> {stream path: end sent}
        self._reset = False

    def resync(self) -> None:
        """A payload was lost: every stream goes whole again, and the app forgets its copies."""
        self._sent.clear()
        self._reset = True

    def payload(self, keys: list[UnitKey]) -> Payload:
        """The views of the units ``keys``, each stream as its items not yet sent."""
        now = self.clock()
        units = {key: tuple(CoreView(path, self._outgoing(path, None if core is None else core.view(now)))
                            for path, core in unit_cores(self.field, key))
                 for key in keys}
        reset, self._reset = self._reset, False
        return Payload(reset, units)

    def _outgoing(self, core_path: str, view: object) -> object:
        if view is None or not is_dataclass(view):
            self._sent.pop(core_path, None)  # as the app forgets its copies
            return view
        sent = self._sent.get(core_path, {})
        now_sent: dict[str, int] = {}  # streams no longer in the view are forgotten, as the app does

        def part(path: str, stream: StreamView[Any]) -> object:
            end = sent.get(path)
            now_sent[path] = stream.end
            if end is None or end > stream.end:  # new to the app, or a new stream here
                return StreamPart(stream.first_seq, stream.first_seq, stream.items, True)
            start = max(end, stream.first_seq)
            return StreamPart(stream.first_seq, start, stream.since(start), False)

        out = _mapped(view, "", part)
        self._sent[core_path] = now_sent
        return out


# -- the app's side ---------------------------------------------------------------------------
class ViewError(Exception):
    """A payload the app cannot join to what it holds (a payload before it was lost)."""


class ViewReceiver:
    """The app's copy of each stream (one thread applies; others only read views)."""

    def __init__(self) -> None:
        self._streams: dict[str, dict[str, StreamView[Any]]] = {}  # core path -> {stream path: copy}

    def apply(self, payload: Payload) -> dict[UnitKey, dict[str, Any]]:
        """A :meth:`ViewSender.payload` as ``{key: {path: view or None}}``."""
        if payload.reset:
            self._streams.clear()
        return {key: {cv.path: self._incoming(cv.path, cv.view) for cv in unit}
                for key, unit in payload.units.items()}

    def _incoming(self, core_path: str, view: object) -> object:
        if view is None or not is_dataclass(view):
            self._streams.pop(core_path, None)
            return view
        held = self._streams.get(core_path, {})
        now_held: dict[str, StreamView[Any]] = {}

        def whole(path: str, part: StreamPart) -> object:
            copy = held.get(path)
            if part.whole:
                stream: StreamView[Any] = StreamView(part.first_seq, part.items)
            elif copy is None or not copy.first_seq <= part.start <= copy.end and part.start > part.first_seq:
                raise ViewError(f"{core_path}: stream {path} from {part.start}, held to "
                                f"{'nothing' if copy is None else copy.end}")
            else:
                kept = copy.since(part.first_seq)[:max(0, part.start - max(part.first_seq, copy.first_seq))]
                stream = StreamView(part.start - len(kept), kept + part.items)
            now_held[path] = stream
            return stream

        out = _mapped(view, "", whole)
        self._streams[core_path] = now_held
        return out

