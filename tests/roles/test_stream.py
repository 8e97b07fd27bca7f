"""A core's stream and its view number their items, so a reader takes only what is new."""

from roles.cores.core import Stream


def test_view_numbers_the_items_kept():
    stream: Stream[str] = Stream(3)
    for word in "abcde":
        stream.append(word)
    view = stream.view()
    assert (view.first_seq, view.items, view.end) == (2, ("c", "d", "e"), 5)
    assert view.since(4) == ("e",)
    assert view.since(0) == ("c", "d", "e")  # older than kept: all that is kept
    assert view.since(5) == ()


def test_a_view_never_changes_and_clear_keeps_the_numbering():
    stream: Stream[int] = Stream(10)
    stream.extend([1, 2])
    before = stream.view()
    stream.append(3)
    stream.clear()
    assert before.items == (1, 2)
    after = stream.view()
    assert (after.first_seq, after.items) == (3, ())
    stream.append(4)
    assert stream.view().since(after.end) == (4,)
