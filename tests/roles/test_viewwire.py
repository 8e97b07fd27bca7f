"""Views across a process boundary (roles/runtime/viewwire.py), both sides in one process."""

from __future__ import annotations

import collections
import gc
import pickle
from dataclasses import dataclass
from types import SimpleNamespace
from typing import Any

from hypothesis import given, settings
from hypothesis import strategies as st

from roles.runtime.viewwire import ViewReceiver, ViewSender


@dataclass(frozen=True)
class View:
    at: float
    enabled: bool
    history: Any


class Core:
    """A stand-in for a DS or a roboRIO: it makes a frozen view of itself."""

    def __init__(self) -> None:
        self.enabled = False
        self.history: collections.deque = collections.deque(maxlen=5)

    def view(self, now: float) -> View:
        return View(now, self.enabled, self.history)


def _field():
    station = SimpleNamespace(ds=Core(), rio=Core())
    return SimpleNamespace(stations=[station], fms=Core(), faults=Core(), clock=lambda: 7.0)


def _round(sender: ViewSender, receiver: ViewReceiver, keys=(("station", 0),)):
    """One payload through pickle, as the pipe carries it; returns the payload and what it showed."""
    payload = pickle.loads(pickle.dumps(sender.payload(list(keys))))
    return payload, receiver.apply(payload)


def _bytes_of(payload, path):
    return next(data for unit in payload[2].values() for p, data in unit if p == path)


def test_a_view_arrives_frozen_with_its_time():
    field = _field()
    field.stations[0].ds.enabled = True
    _, shown = _round(ViewSender(field), ViewReceiver())
    view = shown[("station", 0)]["s0.ds"]
    assert isinstance(view, View) and view.enabled and view.at == 7.0


def test_a_stream_sends_its_new_items_only():
    field = _field()
    sender, receiver = ViewSender(field), ViewReceiver()
    history = field.stations[0].ds.history
    history.extend([1.5, 2.5, 3.5])
    _, first = _round(sender, receiver)
    history.append(4.5)
    payload, shown = _round(sender, receiver)
    data = _bytes_of(payload, "s0.ds")
    assert b"_stream_more" in data and pickle.dumps(1.5)[2:-1] not in data
    copy = shown[("station", 0)]["s0.ds"].history
    assert list(copy) == [1.5, 2.5, 3.5, 4.5] and copy.maxlen == 5
    assert first[("station", 0)]["s0.ds"].history is copy  # one copy, grown in place


# A deque as the roles use it (appended on the right, bounded), and as they might (cleared,
# popped on the left, the same object appended twice): the copy always equals the original.
_ops = st.lists(st.one_of(st.tuples(st.just("append"), st.integers(0, 3)),
                          st.tuples(st.just("extend"), st.lists(st.integers(0, 3), max_size=8)),
                          st.tuples(st.just("popleft"), st.none()),
                          st.tuples(st.just("clear"), st.none()),
                          st.tuples(st.just("same"), st.none())), max_size=30)


@settings(max_examples=150, deadline=None)
@given(_ops, st.sampled_from([None, 4]))
def test_the_copy_of_a_stream_always_equals_it(ops, maxlen):
    field = _field()
    history = field.stations[0].ds.history = collections.deque(maxlen=maxlen)
    sender, receiver = ViewSender(field), ViewReceiver()
    for op, arg in ops:
        if op == "append":
            history.append([arg])  # a new object each time, as samples are
        elif op == "extend":
            history.extend([value] for value in arg)
        elif op == "popleft" and history:
            history.popleft()
        elif op == "clear":
            history.clear()
        elif op == "same" and history:
            history.append(history[-1])  # the same object twice: its identity alone misleads
        _, shown = _round(sender, receiver)
        assert list(shown[("station", 0)]["s0.ds"].history) == list(history)


def test_a_stream_in_two_views_is_one_copy():
    """A DS's and its roboRIO's views may hold the same stream."""
    field = _field()
    shared = collections.deque(maxlen=5)
    field.stations[0].ds.history = field.stations[0].rio.history = shared
    sender, receiver = ViewSender(field), ViewReceiver()
    for n in range(3):
        shared.append((n, "log"))
        _, shown = _round(sender, receiver)
    unit = shown[("station", 0)]
    assert list(unit["s0.ds"].history) == [(0, "log"), (1, "log"), (2, "log")]
    assert unit["s0.ds"].history is unit["s0.rio"].history


def test_a_stream_sent_whole_again_leaves_no_old_copy_behind():
    """A fault's TCP line pops its deque on the left at every due write."""
    field = _field()
    line = field.stations[0].ds.history = collections.deque()
    sender, receiver = ViewSender(field), ViewReceiver()
    for n in range(200):
        line.append([n])
        if n % 3 == 0:
            line.popleft()
        _, shown = _round(sender, receiver)
        assert list(shown[("station", 0)]["s0.ds"].history) == list(line)
    assert len(receiver._streams) == 2  # the DS's and the roboRIO's


def test_a_dead_stream_is_forgotten_on_both_sides():
    field = _field()
    sender, receiver = ViewSender(field), ViewReceiver()
    _round(sender, receiver)
    assert len(receiver._streams) == 2
    field.stations[0].ds.history = collections.deque([9.0])  # the old one dies
    gc.collect()
    payload, shown = _round(sender, receiver)
    assert len(payload[1]) == 1  # its token, gone
    assert len(receiver._streams) == 2 and list(shown[("station", 0)]["s0.ds"].history) == [9.0]


def test_a_lost_payload_is_made_good_by_a_resync():
    field = _field()
    sender, receiver = ViewSender(field), ViewReceiver()
    history = field.stations[0].ds.history
    _round(sender, receiver)
    history.append(1.0)
    field.stations[0].ds.enabled = True
    sender.payload([("station", 0)])  # made, never delivered
    sender.resync()
    payload, shown = _round(sender, receiver)
    assert payload[0] is True  # reset: the app forgets its copies
    ds = shown[("station", 0)]["s0.ds"]
    assert ds.enabled and list(ds.history) == [1.0]


def test_an_unknown_stream_is_an_error_the_engine_can_resync_from():
    field = _field()
    sender, receiver = ViewSender(field), ViewReceiver()
    _round(sender, receiver)
    receiver._streams.clear()  # the two sides disagree
    field.stations[0].ds.history.append(1.0)
    try:
        _round(sender, receiver)
    except pickle.UnpicklingError:
        pass
    else:
        raise AssertionError("an unknown stream went unnoticed")
    sender.resync()
    _, shown = _round(sender, receiver)
    assert list(shown[("station", 0)]["s0.ds"].history) == [1.0]


def test_a_role_that_goes_away_shows_as_none():
    field = _field()
    sender, receiver = ViewSender(field), ViewReceiver()
    _round(sender, receiver)
    field.stations[0].rio = None
    _, shown = _round(sender, receiver)
    assert shown[("station", 0)]["s0.rio"] is None


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
        assert shown[("station", 0)]["s0.rio"].snapshot()["code_state"] == engine.field.stations[0].rio.code_state
        assert shown["fms"]["fms"].snapshot(engine.now()) == engine.field.fms.snapshot(engine.now())
        assert shown["faults"]["faults"].snapshot() == engine.field.faults.snapshot()
    finally:
        engine.stop()
