"""Views across a process boundary (roles/runtime/viewwire.py), both sides in one process."""

from __future__ import annotations

import pickle
from dataclasses import dataclass
from types import SimpleNamespace
from typing import Any

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from roles.cores.core import Stream
from roles.cores.views import StreamView
from roles.runtime.viewwire import ViewError, ViewReceiver, ViewSender


@dataclass(frozen=True, slots=True)
class Inner:
    samples: StreamView[Any]


@dataclass(frozen=True, slots=True)
class View:
    at: float
    enabled: bool
    history: StreamView[Any]
    inner: Inner  # a stream deeper in the view


class Core:
    """A stand-in for a DS or a roboRIO: it makes a frozen view of itself."""

    def __init__(self) -> None:
        self.enabled = False
        self.history: Stream[Any] = Stream(5)
        self.samples: Stream[Any] = Stream(3)

    def view(self, now: float) -> View:
        return View(now, self.enabled, self.history.view(), Inner(self.samples.view()))


def _field():
    station = SimpleNamespace(ds=Core(), rio=Core())
    return SimpleNamespace(stations=[station], fms=Core(), faults=Core(), clock=lambda: 7.0)


def _round(sender: ViewSender, receiver: ViewReceiver, keys=(("station", 0),)):
    """One payload through pickle, as the pipe carries it; returns its bytes and what it showed."""
    data = pickle.dumps(sender.payload(list(keys)))
    return data, receiver.apply(pickle.loads(data))


def _same(shown: StreamView, stream: Stream) -> bool:
    made = stream.view()
    return (shown.first_seq, shown.items) == (made.first_seq, made.items)


def test_a_view_arrives_frozen_with_its_time():
    field = _field()
    field.stations[0].ds.enabled = True
    _, shown = _round(ViewSender(field), ViewReceiver())
    view = shown[("station", 0)]["s0.ds"]
    assert isinstance(view, View) and view.enabled and view.at == 7.0


def test_a_stream_sends_its_new_items_only_and_arrives_whole_with_its_numbers():
    field = _field()
    sender, receiver = ViewSender(field), ViewReceiver()
    history = field.stations[0].ds.history
    history.extend(["first-item", "second-item", "third-item"])
    _, before = _round(sender, receiver)
    history.extend(["fourth-item", "fifth-item", "sixth-item"])  # the first falls out (5 kept)
    data, shown = _round(sender, receiver)
    assert b"fourth-item" in data and b"second-item" not in data and b"third-item" not in data
    copy = shown[("station", 0)]["s0.ds"].history
    assert isinstance(copy, StreamView) and _same(copy, history) and copy.first_seq == 1
    # the items the app already had are the same objects: a reader that follows by identity
    # (fieldbox/console_feed.py) finds its place
    assert copy[0] is before[("station", 0)]["s0.ds"].history[1]


def test_a_stream_deep_in_a_view_crosses_the_same_way():
    field = _field()
    sender, receiver = ViewSender(field), ViewReceiver()
    samples = field.stations[0].rio.samples
    for n in range(10):
        samples.append(f"sample-{n}")
        data, shown = _round(sender, receiver)
        assert _same(shown[("station", 0)]["s0.rio"].inner.samples, samples)
        assert n == 0 or f"sample-{n - 1}".encode() not in data


def test_a_reader_following_by_number_sees_every_item_once():
    from fieldbox.widgets import StreamCursor

    field = _field()
    sender, receiver = ViewSender(field), ViewReceiver()
    history, cursor, seen = field.stations[0].ds.history, StreamCursor(), []
    for n in range(40):
        history.extend(range(history.total, history.total + n % 4))  # 0 to 3 new items a payload
        _, shown = _round(sender, receiver)
        new, _ = cursor.take(shown[("station", 0)]["s0.ds"].history, "ds")
        seen += new
    assert seen == list(range(history.total))  # each item is its own number


# A stream as a core writes it (appended, bounded, cleared, or a new one in its place), with
# payloads lost on the way (made, never applied, then a resync): the app's copy always
# equals the stream, numbers and items.
_ops = st.lists(st.one_of(st.tuples(st.just("append"), st.integers(0, 3)),
                          st.tuples(st.just("extend"), st.lists(st.integers(0, 3), max_size=8)),
                          st.tuples(st.just("clear"), st.none()),
                          st.tuples(st.just("new"), st.none()),
                          st.tuples(st.just("lost"), st.none())), max_size=30)


@settings(max_examples=150, deadline=None)
@given(_ops)
def test_the_copy_of_a_stream_always_equals_it(ops):
    field = _field()
    core = field.stations[0].ds
    sender, receiver = ViewSender(field), ViewReceiver()
    for op, arg in ops:
        if op == "append":
            core.history.append([arg])
        elif op == "extend":
            core.history.extend([value] for value in arg)
        elif op == "clear":
            core.history.clear()
        elif op == "new":
            core.history = Stream(5)  # its numbers start again
        elif op == "lost":
            sender.payload([("station", 0)])  # made, never delivered
            sender.resync()
            continue
        _, shown = _round(sender, receiver)
        assert _same(shown[("station", 0)]["s0.ds"].history, core.history)


def test_a_lost_payload_is_made_good_by_a_resync():
    field = _field()
    sender, receiver = ViewSender(field), ViewReceiver()
    history = field.stations[0].ds.history
    _round(sender, receiver)
    history.append(1.0)
    field.stations[0].ds.enabled = True
    sender.payload([("station", 0)])  # made, never delivered
    sender.resync()
    data, shown = _round(sender, receiver)
    assert pickle.loads(data).reset  # the app forgets its copies
    ds = shown[("station", 0)]["s0.ds"]
    assert ds.enabled and list(ds.history) == [1.0]


def test_a_payload_that_does_not_join_is_an_error_the_engine_can_resync_from():
    field = _field()
    sender, receiver = ViewSender(field), ViewReceiver()
    history = field.stations[0].ds.history
    history.append(1.0)
    _round(sender, receiver)
    history.append(2.0)
    sender.payload([("station", 0)])  # lost on the way, and nobody noticed
    history.append(3.0)
    with pytest.raises(ViewError):
        _round(sender, receiver)
    sender.resync()
    _, shown = _round(sender, receiver)
    assert list(shown[("station", 0)]["s0.ds"].history) == [1.0, 2.0, 3.0]


def test_a_role_that_goes_away_shows_as_none():
    field = _field()
    sender, receiver = ViewSender(field), ViewReceiver()
    _round(sender, receiver)
    field.stations[0].rio = None
    _, shown = _round(sender, receiver)
    assert shown[("station", 0)]["s0.rio"] is None
    field.stations[0].rio = Core()  # a new one in its place: its streams start whole
    field.stations[0].rio.history.append("again")
    _, shown = _round(sender, receiver)
    assert list(shown[("station", 0)]["s0.rio"].history) == ["again"]


def test_the_real_cores_views_cross_a_pipe(tmp_path):
    """Every view a full field makes pickles and arrives with the fields panels read."""
    from roles.runtime.engine import SimEngine
    from roles.runtime.field import FieldConfig, parse_teams
    from roles.runtime.viewwire import unit_keys

    engine = SimEngine(FieldConfig(teams=parse_teams("254,1114"), log_files=False, log_dir=str(tmp_path)))
    try:
        engine.advance(2.0)
        sender, receiver = ViewSender(engine.field, engine.now), ViewReceiver()
        _, shown = _round(sender, receiver, unit_keys(engine.field))
        ds = shown[("station", 0)]["s0.ds"]
        assert ds.team == 254 and ds.link.robot_comms and ds.snapshot() == engine.field.stations[0].ds.snapshot()
        rio, shown_rio = engine.field.stations[0].rio, shown[("station", 0)]["s0.rio"]
        assert shown_rio.snapshot() == rio.snapshot() and shown_rio.console.end == rio.tcp.console.total
        assert shown["fms"]["fms"].snapshot(engine.now()) == engine.field.fms.snapshot(engine.now())
        assert shown["faults"]["faults"].snapshot() == engine.field.faults.snapshot()
    finally:
        engine.stop()
