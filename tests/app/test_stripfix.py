"""fieldbox/stripfix.py: a line drawn whole is freed when it is dropped, not by the collector."""

from __future__ import annotations

import gc
import sys

from rich.segment import Segment
from rich.style import Style
from textual.strip import Strip

from fieldbox import stripfix

from .helpers import make_app, one_team, step


def a_strip() -> Strip:
    return Strip([Segment("ds 254 ", Style(bold=True)), Segment("robot out", None), Segment(" 20.0 ms")], 24)


def test_textual_keeps_a_strip_cut_at_its_own_width_in_its_own_cache():
    # Why the fix exists: with Textual's divide the strip refers to itself. If Textual stops
    # doing that, this fails and fieldbox/stripfix.py can go.
    strip = a_strip()
    before = sys.getrefcount(strip)
    assert stripfix._textual_divide(strip, [24]) == [strip]
    assert sys.getrefcount(strip) == before + 1  # the cached [strip]


def test_a_strip_cut_at_its_own_width_refers_to_nothing_after():
    strip = a_strip()  # fieldbox.app installed the fix when the helpers imported it
    before = sys.getrefcount(strip)
    parts = strip.divide([24])
    assert parts == [strip] and parts[0] is strip
    del parts
    assert sys.getrefcount(strip) == before
    assert strip.divide(iter([24, 30])) == [strip]  # cuts past the end are dropped, as Textual does


def test_a_strip_cropped_whole_refers_to_nothing_after():
    strip = a_strip()
    before = sys.getrefcount(strip)
    assert stripfix._textual_crop_extend(a_strip(), 0, 24, None) is not None
    assert strip.crop_extend(0, 24, None) is strip
    assert strip.crop_extend(-3, 24, Style(bold=True)) is strip
    assert sys.getrefcount(strip) == before
    textuals = a_strip()
    stripfix._textual_crop_extend(textuals, 0, 24, None)
    assert sys.getrefcount(textuals) == before + 1  # Textual's keeps it in its own cache


def test_every_other_crop_is_textuals_own():
    def shape(s):
        return (s.text, s.cell_length, list(s))

    for start, end in ((0, 24), (-2, 24), (0, 30), (3, 24), (0, 10), (5, 40), (24, 24), (30, 40)):
        for style in (None, Style(italic=True)):
            assert shape(a_strip().crop_extend(start, end, style)) == \
                shape(stripfix._textual_crop_extend(a_strip(), start, end, style)), (start, end, style)


def test_every_other_cut_is_textuals_own():
    def shape(strips):
        return [(s.text, s.cell_length, list(s)) for s in strips]

    for cuts in ([24], [8, 24], [3, 10, 24], [7], [0, 24], [5, 24, 40], [], [30]):
        assert shape(a_strip().divide(iter(cuts))) == shape(stripfix._textual_divide(a_strip(), cuts)), cuts
    empty = Strip([], 0)
    assert shape(empty.divide([0])) == shape(stripfix._textual_divide(Strip([], 0), [0]))


async def test_the_inspector_draws_without_leaving_strips_to_the_collector():
    # Before the fix, every line the compositor drew whole was a reference cycle: with the
    # inspector shown, 4 400 strips (and 26 000 segments, 31 000 caches) every 10 s waited
    # for the collector's full collections, 100-300 ms with the app stopped.
    app, _ = make_app(one_team(), "inspector")
    async with app.run_test(size=(120, 40)) as pilot:
        await step(pilot, 0.5)
        gc.collect()
        gc.set_debug(gc.DEBUG_SAVEALL)
        try:
            for _ in range(10):
                await step(pilot, 0.1)  # the list grows: every row is drawn again
            gc.collect()
            strips = sum(1 for o in gc.garbage if isinstance(o, Strip))
        finally:
            gc.set_debug(0)
            gc.garbage.clear()
        assert app.screen.is_current and strips == 0
