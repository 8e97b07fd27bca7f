"""A reader's place in a view's stream (fieldbox/widgets.py StreamCursor): the match log,
NetConsole and event logs show each line once, whatever the view's counters say."""

from __future__ import annotations

import collections
import threading

from fieldbox.widgets import StreamCursor
from roles.runtime.engine import ThreadEngine
from roles.runtime.field import FieldConfig


def test_each_item_is_taken_once_as_the_stream_grows_between_looks():
    stream: collections.deque = collections.deque(maxlen=5)
    cursor = StreamCursor()
    stream.extend([(0.0, "a"), (1.0, "b")])
    assert cursor.take(stream) == ([(0.0, "a"), (1.0, "b")], True)
    assert cursor.take(stream) == ([], False)
    stream.extend([(2.0, "c"), (3.0, "d")])  # appended after the view that counted them was made
    new, fresh = cursor.take(stream)
    assert [text for _, text in new] == ["c", "d"] and not fresh
    for i in range(4):  # the oldest fall out; the place is found by identity, not by a count
        stream.append((4.0 + i, f"e{i}"))
    assert [text for _, text in cursor.take(stream)[0]] == ["e0", "e1", "e2", "e3"]


def test_another_stream_or_one_sent_whole_again_starts_over():
    cursor = StreamCursor()
    first = collections.deque([(0.0, "a")])
    cursor.take(first)
    again = collections.deque([(0.0, "a"), (1.0, "b")])  # the same lines as new objects: a resync
    assert cursor.take(again) == ([(0.0, "a"), (1.0, "b")], True)
    lost = collections.deque([(5.0, "x")], maxlen=1)
    cursor.take(lost)
    lost.append((6.0, "y"))
    lost.append((7.0, "z"))  # "y" scrolled out before the look: what is there is shown afresh
    assert cursor.take(lost) == ([(7.0, "z")], True)


def test_a_wire_on_a_thread_makes_its_views_on_that_thread(tmp_path, monkeypatch):
    # A view reads properties that keep caches the wire relies on (the roboRIO's sticks): only
    # the wire's own thread may make it.
    import roles.runtime.engine as E

    threads = []
    made = E.field_view

    def watched(field, now):
        threads.append(threading.current_thread())
        return made(field, now)

    monkeypatch.setattr(E, "field_view", watched)
    engine = ThreadEngine(FieldConfig(team=254, plan="ephemeral", log_files=False, log_dir=str(tmp_path)))
    engine.start()
    try:
        field = engine.views(engine.now())
        assert field.stations[0].ds.team == 254 and field.stations[0].rio is not None
        assert threads and all(t is not threading.current_thread() for t in threads)
    finally:
        engine.stop()
