"""A reader's place in a view's stream (fieldbox/widgets.py StreamCursor): the match log,
NetConsole and event logs show each line once, found by its number."""

from __future__ import annotations

import threading

from fieldbox.widgets import StreamCursor
from roles.cores.core import Stream
from roles.cores.views import StreamView
from roles.runtime.engine import ThreadEngine
from roles.runtime.field import FieldConfig


def test_each_item_is_taken_once_as_the_stream_grows_between_looks():
    stream: Stream[tuple[float, str]] = Stream(5)  # a core's events, five kept
    cursor = StreamCursor()
    stream.extend([(0.0, "a"), (1.0, "b")])
    assert cursor.take(stream.view()) == ([(0.0, "a"), (1.0, "b")], True)
    assert cursor.take(stream.view()) == ([], False)  # a new view of the same items
    stream.extend([(2.0, "c"), (3.0, "d")])
    new, fresh = cursor.take(stream.view())
    assert [text for _, text in new] == ["c", "d"] and not fresh
    for i in range(4):  # the oldest fall out; the place is found by number, not by a count kept
        stream.append((4.0 + i, f"e{i}"))
    assert [text for _, text in cursor.take(stream.view())[0]] == ["e0", "e1", "e2", "e3"]


def test_another_source_a_new_stream_or_one_that_scrolled_past_starts_over():
    cursor = StreamCursor()
    first: Stream[tuple[float, str]] = Stream(5)
    first.append((0.0, "a"))
    cursor.take(first.view(), source=254)
    assert cursor.take(first.view(), source=1114) == ([(0.0, "a")], True)  # another DS's events
    fast: Stream[tuple[float, str]] = Stream(1)
    fast.append((5.0, "x"))
    cursor.take(fast.view(), source=1)  # "x" is number 0 of a new stream
    fast.append((6.0, "y"))
    fast.append((7.0, "z"))  # "y" scrolled out before the look: what is there is shown afresh
    assert cursor.take(fast.view(), source=1) == ([(7.0, "z")], True)
    restarted = StreamView(0, ((8.0, "new"),))  # numbered from 0 again: a new stream at this place
    assert cursor.take(restarted, source=1) == ([(8.0, "new")], True)


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
