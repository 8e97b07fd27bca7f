"""fieldbox/cycles.py: what Textual throws away is freed when it is dropped, not by the collector,
and what it would throw away is kept when it can be."""

from __future__ import annotations

import gc
import sys
import weakref

from rich.segment import Segment
from rich.style import Style
from textual.app import App, ComposeResult
from textual.cache import LRUCache
from textual.dom import DOMNode
import pytest
from textual.strip import Strip
from textual.widgets import DataTable

from fieldbox import cycles

from .helpers import left_to_the_collector, make_app, one_team, step


@pytest.fixture(autouse=True)
def fixes_in() -> None:
    """What the app does when it is made (FieldboxApp.__init__)."""
    assert cycles.install()


def test_the_fixes_stay_out_of_another_textual_series(monkeypatch):
    import textual

    monkeypatch.setattr(textual, "__version__", "9.0.0")
    assert not cycles.install()


def a_strip() -> Strip:
    return Strip([Segment("ds 254 ", Style(bold=True)), Segment("robot out", None), Segment(" 20.0 ms")], 24)


def test_textual_keeps_a_strip_cut_at_its_own_width_in_its_own_cache():
    # Why the fix exists: with Textual's divide the strip refers to itself. If Textual stops
    # doing that, this fails and fieldbox/cycles.py can go.
    strip = a_strip()
    before = sys.getrefcount(strip)
    assert cycles._textual_divide(strip, [24]) == [strip]
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
    assert cycles._textual_crop_extend(a_strip(), 0, 24, None) is not None
    assert strip.crop_extend(0, 24, None) is strip
    assert strip.crop_extend(-3, 24, Style(bold=True)) is strip
    assert sys.getrefcount(strip) == before
    textuals = a_strip()
    cycles._textual_crop_extend(textuals, 0, 24, None)
    assert sys.getrefcount(textuals) == before + 1  # Textual's keeps it in its own cache


def test_every_other_crop_is_textuals_own():
    def shape(s):
        return (s.text, s.cell_length, list(s))

    for start, end in ((0, 24), (-2, 24), (0, 30), (3, 24), (0, 10), (5, 40), (24, 24), (30, 40)):
        for style in (None, Style(italic=True)):
            assert shape(a_strip().crop_extend(start, end, style)) == \
                shape(cycles._textual_crop_extend(a_strip(), start, end, style)), (start, end, style)


def test_every_other_cut_is_textuals_own():
    def shape(strips):
        return [(s.text, s.cell_length, list(s)) for s in strips]

    for cuts in ([24], [8, 24], [3, 10, 24], [7], [0, 24], [5, 24, 40], [], [30]):
        assert shape(a_strip().divide(iter(cuts))) == shape(cycles._textual_divide(a_strip(), cuts)), cuts
    empty = Strip([], 0)
    assert shape(empty.divide([0])) == shape(cycles._textual_divide(Strip([], 0), [0]))


async def test_the_inspector_draws_without_leaving_strips_to_the_collector():
    # Before the fix, every line the compositor drew whole was a reference cycle: with the
    # inspector shown, 4 400 strips (and 26 000 segments, 31 000 caches) every 10 s waited
    # for the collector's full collections, 100-300 ms with the app stopped.
    app, _ = make_app(one_team(), "inspector")
    async with app.run_test(size=(120, 40)) as pilot:
        await step(pilot, 0.5)

        async def refresh_ten_times() -> None:
            for _ in range(10):
                await step(pilot, 0.1)  # the list grows: every row is drawn again

        garbage = await left_to_the_collector(refresh_ten_times)
        assert app.screen.is_current and not any(isinstance(o, Strip) for o in garbage)


class Value:
    """A cached value whose death can be watched (a weak reference)."""


def filled_cache(n: int = 5) -> tuple[LRUCache, list[weakref.ref]]:
    cache: LRUCache = LRUCache(3)  # n > 3: some evicted on the way, as a table's caches are
    refs = []
    for i in range(n):
        value = Value()
        refs.append(weakref.ref(value))
        cache[("cell", i)] = value
    cache.get(("cell", n - 2))  # one moved to the head of the ring
    return cache, refs


def alive(refs: list[weakref.ref]) -> int:
    return sum(ref() is not None for ref in refs)


def test_textual_leaves_a_cleared_lru_cache_in_a_cycle():
    # Why lru_clear exists: Textual's clear drops the ring of entries whole, and only the
    # collector frees its values. If Textual stops doing that, this fails and lru_clear can go.
    cache, refs = filled_cache()
    gc.disable()  # no collection between the clear and the count
    try:
        cycles._textual_lru_clear(cache)
        assert alive(refs) == 3  # the three the ring still held
    finally:
        gc.enable()
    gc.collect()
    assert alive(refs) == 0


def test_a_cleared_lru_cache_frees_its_values_at_once():
    cache, refs = filled_cache()
    assert alive(refs) == 3  # the two oldest were evicted, and freed at once
    gc.disable()
    try:
        cache.clear()
        assert alive(refs) == 0 and len(cache) == 0
    finally:
        gc.enable()


def test_an_lru_cache_works_as_before_after_a_clear():
    cache, _ = filled_cache()
    cache.clear()
    assert cache.get("gone") is None and not cache
    for i in range(5):
        cache[i] = str(i)
    assert cache.get(3) == "3"  # 3 is now the most recently used, then 4, 2
    cache[5] = "5"  # evicts the least recently used: 2
    assert sorted(cache.keys()) == [3, 4, 5] and cache[4] == "4"
    cache.discard(4)
    assert sorted(cache.keys()) == [3, 5] and cache.get(5) == "5"
    cache.clear()
    cache["x"] = "only"  # the first entry of an empty ring links to itself
    assert cache.get("x") == "only" and len(cache) == 1


class TwoTables(App):
    """Two tables of stations, trading the focus: each trade restyles both."""

    def __init__(self, stations: tuple[str, ...]) -> None:
        super().__init__()
        self.stations = stations

    def compose(self) -> ComposeResult:
        yield DataTable(id="stations")
        yield DataTable(id="faults")

    def on_mount(self) -> None:
        for table in self.query(DataTable):
            table.add_columns("station", "trip ms")
            for station in self.stations:
                table.add_row(station, "0.4", key=station)

    async def trade_focus(self, pilot, turns: int = 10) -> None:
        tables = list(self.query(DataTable))
        for turn in range(turns):
            tables[turn % 2].focus()  # the focus moves: both restyled and drawn again
            await pilot.pause()


async def test_a_table_restyled_leaves_no_cache_entries_to_the_collector():
    # A DataTable clears its caches (cells, rows, lines drawn) whenever its style may have
    # changed: when it gains or loses the focus, when its tab is shown. Before lru_clear each
    # clear left a ring of [prev, next, key, value] lists, with what they held, to the
    # collector: a quarter of the app's cyclic garbage with the tabs cycling.
    app = TwoTables(("R1", "R2", "R3", "B1", "B2", "B3"))
    async with app.run_test(size=(80, 20)) as pilot:
        await pilot.pause()
        garbage = await left_to_the_collector(lambda: app.trade_focus(pilot))
        links = sum(1 for o in garbage if type(o) is list and len(o) == 4
                    and type(o[0]) is list and type(o[1]) is list)
        faults = app.query_one("#faults", DataTable)
        assert app.focused is faults and faults.get_cell("B3", faults.ordered_columns[1].key) == "0.4"
        assert links == 0


async def test_a_table_restyled_keeps_its_virtual_style_nodes_and_their_styles_follow():
    # Each restyle (the focus gained or lost, a tab shown) made a fresh virtual style node
    # per component class, the old ones left to the collector: forty objects each, the
    # largest part of the app's cyclic garbage with the tabs cycling.
    app = TwoTables(("R1",))
    async with app.run_test(size=(80, 20)) as pilot:
        await pilot.pause()
        tables = list(app.query(DataTable))
        table = tables[0]

        def cursor_rules() -> tuple:
            styles = table._component_styles["datatable--cursor"]
            return styles.base.get_rules(), styles.inline.get_rules()

        rules = {}
        for focused in tables:
            focused.focus()
            await pilot.pause()
            rules[focused is table] = cursor_rules()
            ours = table._component_styles["datatable--cursor"]
            cycles._textual_component_classes(app.stylesheet, table)  # Textual's, afresh
            assert cursor_rules() == rules[focused is table]
            table._component_styles["datatable--cursor"] = ours
        assert rules[True] != rules[False]  # the cursor looks different when the table has the focus

        garbage = await left_to_the_collector(lambda: app.trade_focus(pilot))
        virtual = sum(1 for o in garbage if type(o) is DOMNode)
        assert app.focused is tables[1] and cursor_rules() == rules[False]
        assert virtual == 0
