"""fieldbox/textual_fixes.py: each workaround does what it says, goes in only on the Textual
releases it was written for, and has a canary: a test that fails once Textual changes what the
workaround relies on (a private name gone, the bug it works around fixed), so an upgrade says
which one to look at, or to drop. The canaries are the tests whose names start with
``test_textual``."""

from __future__ import annotations

import gc
import inspect
import logging
import sys
import tomllib
import weakref

import pytest
from rich.segment import Segment
from rich.style import Style
from textual.app import App, ComposeResult
from textual.binding import Binding
from textual.cache import LRUCache
from textual.dom import DOMNode
from textual.geometry import Size
from textual.strip import Strip
from textual.widget import Widget
from textual.widgets import DataTable, Footer, Input, TabbedContent, TabPane
from textual.widgets._footer import FooterKey

from fieldbox import textual_fixes

from .helpers import ROOT, left_to_the_collector, make_app, one_team, step


@pytest.fixture(autouse=True)
def fixes_in() -> None:
    """What the app does when it is made (FieldboxApp.__init__)."""
    assert textual_fixes.install()


# -- the version gate ---------------------------------------------------------------------------
def test_the_range_is_the_one_pyproject_pins():
    pins = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["dependencies"]
    (textual_pin,) = [pin for pin in pins if pin.startswith("textual")]
    low, high = textual_fixes.TEXTUAL_RANGE
    assert textual_pin == f"textual>={'.'.join(map(str, low))},<{'.'.join(map(str, high))}"


@pytest.mark.parametrize("version,ok", [("8.0.0", True), ("8.2.8", True), ("8.10.1.dev2", True), ("9.0.0", False),
                                        ("9.0.0a1", False), ("7.5.0", False), ("", False), ("unknown", False)])
def test_supported_releases(version, ok):
    assert textual_fixes.supported(version) is ok


def test_the_fixes_stay_out_of_another_textual_and_the_log_says_why(monkeypatch, caplog):
    import textual

    monkeypatch.setattr(textual, "__version__", "9.0.0")
    monkeypatch.setattr(textual_fixes, "_installed", False)
    divide = Strip.divide
    monkeypatch.setattr(Strip, "divide", textual_fixes._textual_divide)
    with caplog.at_level(logging.WARNING, logger="fieldbox.textual"):
        assert not textual_fixes.install()
    assert not textual_fixes.installed() and Strip.divide is textual_fixes._textual_divide
    assert "Textual 9.0.0" in caplog.text and ">=8,<9" in caplog.text
    assert divide is textual_fixes.divide  # (put back by monkeypatch)


async def test_left_out_the_footer_tabs_and_rows_are_textuals_own(monkeypatch):
    monkeypatch.setattr(textual_fixes, "_installed", False)
    app = _KeysApp(textual_fixes.FieldboxFooter())
    async with app.run_test(size=(80, 10)) as pilot:
        await pilot.pause()
        footer = app.query_one(Footer)
        before = list(footer.query(FooterKey))
        assert len(getattr(footer, "__watchers", {}).get("compact", [])) == 2  # Textual's data_bind
        app.screen.refresh_bindings()
        await pilot.pause()
        await pilot.pause()
        assert not set(footer.query(FooterKey)) & set(before)  # rebuilt, as Textual does
    event = TabPane.Focused(TabPane("a", id="a"))
    textual_fixes.FieldboxTabs()._on_tab_pane_focused(event)
    assert not event._no_default_action  # Textual's own handler runs


def a_strip() -> Strip:
    return Strip([Segment("ds 254 ", Style(bold=True)), Segment("robot out", None), Segment(" 20.0 ms")], 24)


def test_textual_keeps_a_strip_cut_at_its_own_width_in_its_own_cache():
    # Why the fix exists: with Textual's divide the strip refers to itself. If Textual stops
    # doing that, this fails and fieldbox/textual_fixes.py can go.
    strip = a_strip()
    before = sys.getrefcount(strip)
    assert textual_fixes._textual_divide(strip, [24]) == [strip]
    assert sys.getrefcount(strip) == before + 1  # the cached [strip]


def test_a_strip_cut_at_its_own_width_refers_to_nothing_after():
    strip = a_strip()
    before = sys.getrefcount(strip)
    parts = strip.divide([24])
    assert parts == [strip] and parts[0] is strip
    del parts
    assert sys.getrefcount(strip) == before
    assert strip.divide(iter([24, 30])) == [strip]  # cuts past the end are dropped, as Textual does


def test_a_strip_cropped_whole_refers_to_nothing_after():
    strip = a_strip()
    before = sys.getrefcount(strip)
    assert textual_fixes._textual_crop_extend(a_strip(), 0, 24, None) is not None
    assert strip.crop_extend(0, 24, None) is strip
    assert strip.crop_extend(-3, 24, Style(bold=True)) is strip
    assert sys.getrefcount(strip) == before
    textuals = a_strip()
    textual_fixes._textual_crop_extend(textuals, 0, 24, None)
    assert sys.getrefcount(textuals) == before + 1  # Textual's keeps it in its own cache


def test_every_other_crop_is_textuals_own():
    def shape(s):
        return (s.text, s.cell_length, list(s))

    for start, end in ((0, 24), (-2, 24), (0, 30), (3, 24), (0, 10), (5, 40), (24, 24), (30, 40)):
        for style in (None, Style(italic=True)):
            assert shape(a_strip().crop_extend(start, end, style)) == \
                shape(textual_fixes._textual_crop_extend(a_strip(), start, end, style)), (start, end, style)


def test_every_other_cut_is_textuals_own():
    def shape(strips):
        return [(s.text, s.cell_length, list(s)) for s in strips]

    for cuts in ([24], [8, 24], [3, 10, 24], [7], [0, 24], [5, 24, 40], [], [30]):
        assert shape(a_strip().divide(iter(cuts))) == shape(textual_fixes._textual_divide(a_strip(), cuts)), cuts
    empty = Strip([], 0)
    assert shape(empty.divide([0])) == shape(textual_fixes._textual_divide(Strip([], 0), [0]))


async def test_the_inspector_draws_without_leaving_strips_to_the_collector():
    # Before the fix, every line the compositor drew whole was a reference cycle.
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
    # Canary: Textual's clear drops the ring of entries whole, and only the collector frees
    # its values. If Textual stops doing that, this fails and lru_clear can go.
    cache, refs = filled_cache()
    gc.disable()  # no collection between the clear and the count
    try:
        textual_fixes._textual_lru_clear(cache)
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
    # clear left a ring of [prev, next, key, value] lists, with what they held, to the collector.
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
    # per component class, the old ones left to the collector.
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
            textual_fixes._textual_component_classes(app.stylesheet, table)  # Textual's, afresh
            assert cursor_rules() == rules[focused is table]
            table._component_styles["datatable--cursor"] = ours
        assert rules[True] != rules[False]  # the cursor looks different when the table has the focus

        garbage = await left_to_the_collector(lambda: app.trade_focus(pilot))
        virtual = sum(1 for o in garbage if type(o) is DOMNode)
        assert app.focused is tables[1] and cursor_rules() == rules[False]
        assert virtual == 0


async def test_textual_makes_fresh_virtual_style_nodes_at_each_restyle_from_what_the_fix_reaches():
    # Canary: process_component_classes re-uses what Textual's makes afresh, through the
    # private names below. If Textual re-uses its nodes, or renames one of these, this fails.
    app = TwoTables(("R1",))
    async with app.run_test(size=(80, 20)) as pilot:
        await pilot.pause()
        table = app.query_one(DataTable)
        styles = table._component_styles["datatable--cursor"]
        virtual = styles.node
        assert type(virtual) is DOMNode and virtual._parent is table and callable(virtual._attach)
        assert "datatable--cursor" in table._get_component_classes()
        assert isinstance(styles.base._rules, dict) and isinstance(styles.inline._rules, dict)
        textual_fixes._textual_component_classes(app.stylesheet, table)
        assert table._component_styles["datatable--cursor"].node is not virtual


# -- the footer -----------------------------------------------------------------------------------
class _KeysApp(App):
    """Two keys and a footer (Textual's or ours)."""

    BINDINGS = [Binding("a", "one", "One"), Binding("b", "two", "Two")]

    def __init__(self, footer: Footer) -> None:
        super().__init__()
        self.footer = footer

    def compose(self) -> ComposeResult:
        yield self.footer


async def test_textual_footer_rebuilds_every_key_at_each_bindings_update_and_keeps_the_old_ones():
    # Canary: Textual's Footer makes its keys afresh whenever the screen's bindings are
    # updated, and each key's data_bind leaves it in the Footer's watcher list
    # (Textualize/textual#6666). If the first stops, FieldboxFooter can go; if only the
    # second, the data_bind it undoes in compose no longer needs undoing.
    app = _KeysApp(Footer())
    async with app.run_test(size=(80, 10)) as pilot:
        await pilot.pause()
        footer = app.query_one(Footer)
        first = list(footer.query(FooterKey))
        for _ in range(3):
            app.screen.refresh_bindings()
            await pilot.pause()
            await pilot.pause()
        shown = list(footer.query(FooterKey))
        assert not set(shown) & set(first)
        watchers = getattr(footer, "__watchers", {}).get("compact", [])
        assert len(watchers) > len(shown)


def test_textual_footer_relabels_after_the_next_refresh():
    # Canary: Textual's Footer subscribes bindings_changed to the screen's signal and
    # recomposes only after the next refresh (one layout for the tab, one for its keys).
    # FieldboxFooter.bindings_changed recomposes before it; if Textual stops waiting, or no
    # longer calls bindings_changed, the override can go.
    assert "call_after_refresh(self.recompose)" in inspect.getsource(Footer.bindings_changed)
    assert "self.bindings_changed" in inspect.getsource(Footer.on_mount)


class _Composed(Footer):
    """Textual's Footer, keeping what its compose gave each key's ``_reactive_connect``."""

    def __init__(self) -> None:
        super().__init__()
        self.connects: list[dict] = []

    def compose(self) -> ComposeResult:
        for widget in super().compose():
            if isinstance(widget, FooterKey) and not widget.has_class("-command-palette"):
                self.connects.append(dict(widget._reactive_connect or {}))
            yield widget


async def test_textual_footer_has_what_fieldbox_footer_reaches_into():
    # Canary: the private names FieldboxFooter reads and writes.
    key = FooterKey("a", "a", "One", "one", disabled=True)
    assert key._disabled is True and "_disabled" in inspect.getsource(FooterKey.on_mouse_down)
    assert isinstance(vars(Footer)["_bindings_ready"], type(Footer.compact))  # a reactive
    assert "_watch_compact" not in vars(Footer)  # ours would hide Textual's own
    assert key._pruning is False
    app = _KeysApp(_Composed())
    async with app.run_test(size=(80, 10)) as pilot:
        await pilot.pause()
        footer = app.query_one(_Composed)
        assert footer._bindings_ready is True
        # compose binds each key's compact with data_bind, which the fix undoes before mounting
        assert footer.connects and all("compact" in connect for connect in footer.connects)


# -- the tabs -------------------------------------------------------------------------------------
class _TwoPanes(App):
    def __init__(self, tabs: TabbedContent) -> None:
        super().__init__()
        self.tabs = tabs

    def compose(self) -> ComposeResult:
        with self.tabs:
            with TabPane("A", id="a"):
                yield Input(id="in-a")
            with TabPane("B", id="b"):
                yield Input(id="in-b")


@pytest.mark.parametrize("ours", [False, True])
async def test_textual_tabs_follow_a_focus_from_a_hidden_pane_and_ours_do_not(ours):
    # Canary: Textual switches to the tab of a widget focused in a hidden pane, in
    # TabbedContent._on_tab_pane_focused (Textualize/textual#4955 is that switch coming late).
    # If Textual stops switching, or the handler is renamed, FieldboxTabs no longer applies.
    assert "_on_tab_pane_focused" in vars(TabbedContent)
    app = _TwoPanes(textual_fixes.FieldboxTabs() if ours else TabbedContent())
    async with app.run_test(size=(60, 10)) as pilot:
        await pilot.pause()
        tabs = app.query_one(TabbedContent)
        tabs.active = "b"
        await pilot.pause()
        app.query_one("#in-a").focus()  # late, from the tab left
        await pilot.pause()
        await pilot.pause()
        assert tabs.active == ("b" if ours else "a")


# -- a list's rows --------------------------------------------------------------------------------
def test_textual_lays_the_screen_out_for_a_virtual_size_and_updates_scrollbars_apart():
    # Canary: setting virtual_size asks for a layout (why set_virtual_rows exists), and
    # _scroll_update(virtual_size) is what Textual's own resize without a layout calls.
    assert Widget.virtual_size._layout is True
    assert list(inspect.signature(Widget._scroll_update).parameters) == ["self", "virtual_size"]
    from textual.scroll_view import ScrollView

    assert "_scroll_update" in inspect.getsource(ScrollView._size_updated)


def test_rows_left_out_set_the_virtual_size(monkeypatch):
    class View:
        size = Size(20, 5)
        virtual_size = Size(20, 3)
        is_mounted = True

    monkeypatch.setattr(textual_fixes, "_installed", False)
    view = View()
    textual_fixes.set_virtual_rows(view, 7)  # type: ignore[arg-type]
    assert view.virtual_size == Size(20, 7)


# -- the environment ------------------------------------------------------------------------------
def test_textual_reads_its_environment_at_import(monkeypatch):
    # Canary: textual.constants is read once, at import; a forked tab re-reads it. If Textual
    # reads its environment lazily, reread_environment is no longer needed.
    import textual.constants

    fps = textual.constants.MAX_FPS
    monkeypatch.setenv("TEXTUAL_FPS", str(fps + 7))
    try:
        assert textual.constants.MAX_FPS == fps
        textual_fixes.reread_environment()
        assert textual.constants.MAX_FPS == fps + 7
    finally:
        monkeypatch.undo()
        textual_fixes.reread_environment()
    assert textual.constants.MAX_FPS == fps
