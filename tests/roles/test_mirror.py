"""Snapshots that carry only what changed (roles/runtime/mirror.py), both sides in one process."""

from __future__ import annotations

import collections
import gc
import pickle
import random
from types import SimpleNamespace

from hypothesis import given, settings
from hypothesis import strategies as st

from roles.runtime.mirror import Mirror, Snapshots


class Core:
    """A stand-in for a DS or a roboRIO: attributes in a __dict__."""


class Link:
    """A DS's FMS link: it points back at its DS."""


def _field():
    ds, rio, fms, faults = Core(), Core(), Core(), Core()
    ds.enabled, ds.history, ds.name = False, collections.deque(maxlen=5), "ds 254"
    ds.link = Link()
    ds.link.ds, ds.link.port = ds, 1160
    rio.rng, rio.volts = random.Random(7), 12.5
    fms.match = 1
    faults.links = {}
    station = SimpleNamespace(ds=ds, rio=rio)
    return SimpleNamespace(stations=[station], fms=fms, faults=faults)


def _round(snaps: Snapshots, mirror: Mirror, keys=(("station", 0),)):
    """One payload through pickle, as the pipe carries it; returns the payload and what it showed."""
    payload = pickle.loads(pickle.dumps(snaps.payload(list(keys))))
    return payload, mirror.apply(payload)


def _changed(payload, path):
    for patch in payload[2].values():
        for p, kind, changed, removed, whole in patch:
            if p == path:
                return set(changed)
    return None


def test_first_whole_then_only_what_changed():
    field = _field()
    snaps, mirror = Snapshots(field), Mirror()
    _, shown = _round(snaps, mirror)
    ds = shown[("station", 0)]["s0.ds"]
    assert (ds.enabled, ds.name, ds.link.port) == (False, "ds 254", 1160)
    assert ds.link.ds is ds  # a back-reference is a reference, not a second DS

    payload, _ = _round(snaps, mirror)
    assert _changed(payload, "s0.ds") == set()  # nothing moved: nothing sent
    field.stations[0].ds.enabled = True
    payload, shown = _round(snaps, mirror)
    assert _changed(payload, "s0.ds") == {"enabled"}
    assert shown[("station", 0)]["s0.ds"] is ds and ds.enabled  # the same object, moved


def test_a_mutated_container_is_sent_again():
    field = _field()
    snaps, mirror = Snapshots(field), Mirror()
    _round(snaps, mirror, ["faults"])
    field.faults.links["ds-rio"] = "drop 10%"
    payload, shown = _round(snaps, mirror, ["faults"])
    assert _changed(payload, "faults") == {"links"}
    assert shown["faults"]["faults"].links == {"ds-rio": "drop 10%"}


def test_a_random_generator_arrives_fresh_not_with_its_state():
    field = _field()
    payload, shown = _round(Snapshots(field), Mirror())
    data = [p for p in payload[2][("station", 0)] if p[0] == "s0.rio"][0][2]["rng"]
    assert len(data) < 100  # the Mersenne state is 2.5 KB
    assert isinstance(shown[("station", 0)]["s0.rio"].rng, random.Random)


def test_a_deque_sends_its_new_items_only():
    field = _field()
    snaps, mirror = Snapshots(field), Mirror()
    history = field.stations[0].ds.history
    history.extend([1.5, 2.5, 3.5])
    _round(snaps, mirror)
    history.append(4.5)
    payload, shown = _round(snaps, mirror)
    data = [p for p in payload[2][("station", 0)] if p[0] == "s0.ds"][0][2]["history"]
    assert b"_mirror_deque_more" in data and pickle.dumps(1.5)[2:-1] not in data
    copy = shown[("station", 0)]["s0.ds"].history
    assert list(copy) == [1.5, 2.5, 3.5, 4.5] and copy.maxlen == 5


# A deque as the roles use it (appended on the right, bounded), and as they might (cleared,
# popped on the left, the same object appended twice): the copy always equals the original.
_ops = st.lists(st.one_of(st.tuples(st.just("append"), st.integers(0, 3)),
                          st.tuples(st.just("extend"), st.lists(st.integers(0, 3), max_size=8)),
                          st.tuples(st.just("popleft"), st.none()),
                          st.tuples(st.just("clear"), st.none()),
                          st.tuples(st.just("same"), st.none())), max_size=30)


@settings(max_examples=150, deadline=None)
@given(_ops, st.sampled_from([None, 4]))
def test_the_copy_of_a_deque_always_equals_it(ops, maxlen):
    field = _field()
    history = field.stations[0].ds.history = collections.deque(maxlen=maxlen)
    snaps, mirror = Snapshots(field), Mirror()
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
        _, shown = _round(snaps, mirror)
        assert list(shown[("station", 0)]["s0.ds"].history) == list(history)


def test_a_deque_reached_from_two_places_moves_in_both():
    """The FMS reaches a station's deques through its stations and its connections."""
    field = _field()
    shared = collections.deque(maxlen=5)
    field.fms.stations, field.fms.connections = [shared], {"tcp#1": shared}
    snaps, mirror = Snapshots(field), Mirror()
    _round(snaps, mirror, ["fms"])
    for n in range(3):
        shared.append((n, "log"))
        _, shown = _round(snaps, mirror, ["fms"])
    fms = shown["fms"]["fms"]
    assert list(fms.stations[0]) == list(fms.connections["tcp#1"]) == [(0, "log"), (1, "log"), (2, "log")]
    assert fms.stations[0] is fms.connections["tcp#1"]  # still one deque, as in the child


def test_a_deque_sent_whole_again_leaves_no_old_copy_behind():
    """A fault's TCP line pops its deque on the left at every due write."""
    field = _field()
    line = field.stations[0].ds.history = collections.deque()
    snaps, mirror = Snapshots(field), Mirror()
    for n in range(200):
        line.append([n])
        if n % 3 == 0:
            line.popleft()
        _, shown = _round(snaps, mirror)
        assert list(shown[("station", 0)]["s0.ds"].history) == list(line)
    assert len(mirror._deques) == 1


def test_an_attribute_deleted_while_a_payload_was_lost_is_gone_after_the_resync():
    field = _field()
    snaps, mirror = Snapshots(field), Mirror()
    _round(snaps, mirror)
    del field.stations[0].ds.name
    snaps.payload([("station", 0)])  # made, never delivered
    snaps.resync()
    _, shown = _round(snaps, mirror)
    assert not hasattr(shown[("station", 0)]["s0.ds"], "name")


def test_a_dead_deque_is_forgotten_on_both_sides():
    field = _field()
    snaps, mirror = Snapshots(field), Mirror()
    _round(snaps, mirror)
    assert len(mirror._deques) == 1
    field.stations[0].ds.history = collections.deque([9.0])  # the old one dies
    gc.collect()
    payload, shown = _round(snaps, mirror)
    assert len(payload[1]) == 1  # its token, gone
    assert len(mirror._deques) == 1 and list(shown[("station", 0)]["s0.ds"].history) == [9.0]


def test_a_lost_payload_is_made_good_by_a_resync():
    field = _field()
    snaps, mirror = Snapshots(field), Mirror()
    history = field.stations[0].ds.history
    _round(snaps, mirror)
    history.append(1.0)
    field.stations[0].ds.enabled = True
    snaps.payload([("station", 0)])  # made, never delivered
    snaps.resync()
    payload, shown = _round(snaps, mirror)
    assert payload[0] is True  # reset: the app forgets its deques
    ds = shown[("station", 0)]["s0.ds"]
    assert ds.enabled and list(ds.history) == [1.0]


def test_an_unknown_deque_is_an_error_the_engine_can_resync_from():
    field = _field()
    snaps, mirror = Snapshots(field), Mirror()
    _round(snaps, mirror)
    mirror._deques.clear()  # the two sides disagree
    field.stations[0].ds.history.append(1.0)
    try:
        _round(snaps, mirror)
    except pickle.UnpicklingError:
        pass
    else:
        raise AssertionError("an unknown deque went unnoticed")
    snaps.resync()
    _, shown = _round(snaps, mirror)
    assert list(shown[("station", 0)]["s0.ds"].history) == [1.0]


def test_a_role_that_goes_away_shows_as_none():
    field = _field()
    snaps, mirror = Snapshots(field), Mirror()
    _round(snaps, mirror)
    field.stations[0].rio = None
    _, shown = _round(snaps, mirror)
    assert shown[("station", 0)]["s0.rio"] is None
