"""The footer: it shows the keys of the tab in front, and using the app does not grow it.

Textual 8's Footer rebuilds its keys every time the screen's bindings are updated (several
times a tab switch, mostly with the same keys), and each old FooterKey stayed referenced
from the Footer's ``compact`` watcher list (Textualize/textual#6666). fieldbox's Footer
(fieldbox/textual_fixes.py) does nothing while the keys stay the same, relabels the keys it
has when they change, and binds nothing.
"""

from __future__ import annotations

import gc

import pytest
from textual.app import App, ComposeResult
from textual.binding import Binding
from textual.dom import DOMNode
from textual.widgets import Footer
from textual.widgets._footer import FooterKey

from fieldbox import textual_fixes
from fieldbox.app import panel_classes
from fieldbox.textual_fixes import FieldboxFooter

from .helpers import SIZE, left_to_the_collector, make_app, one_team


@pytest.fixture(autouse=True)
def fixes_in() -> None:
    """What the app does when it is made (a test here may run a plain App with our Footer)."""
    assert textual_fixes.install()


def _alive_footer_keys() -> int:
    gc.collect()
    return sum(1 for o in gc.get_objects() if isinstance(o, FooterKey))


def _shown_keys(footer: Footer) -> list[FooterKey]:
    """The keys the footer shows (it keeps spare keys hidden, for a tab with more)."""
    return [key for key in footer.query(FooterKey) if key.display]


def _descriptions(footer: Footer) -> list[str]:
    return [key.description for key in _shown_keys(footer)]


async def test_footer_shows_the_keys_of_the_tab_in_front():
    app, _ = make_app(one_team(roles=frozenset({"ds", "rio", "fms"})))
    async with app.run_test(size=SIZE) as pilot:
        await pilot.pause()
        footer = app.query_one(Footer)
        assert "Teleop" in _descriptions(footer) and "Start match" not in _descriptions(footer)
        app.action_show_tab("fms")
        await pilot.pause()
        await pilot.pause()
        assert "Start match" in _descriptions(footer)
        app.action_show_tab("ds")
        await pilot.pause()
        await pilot.pause()
        assert "Teleop" in _descriptions(footer) and "Start match" not in _descriptions(footer)
        # The keys look as Textual draws them: not compact (the palette key is, as in Textual).
        assert not any(k.has_class("-compact") for k in _shown_keys(footer)
                       if not k.has_class("-command-palette"))


async def test_the_first_layout_after_a_tab_switch_has_the_new_tabs_keys():
    # The footer is relabelled before the next frame: the tab and its keys are laid out and
    # drawn together, not the new tab over the old tab's keys and a second layout after.
    app, _ = make_app(one_team(roles=frozenset({"ds", "rio", "fms"})))
    async with app.run_test(size=SIZE) as pilot:
        await pilot.pause()
        await pilot.pause()
        footer = app.query_one(Footer)
        screen = app.screen
        seen: list[list[str]] = []
        original = screen._refresh_layout

        def refresh_layout(*args, **kwargs):
            seen.append(_descriptions(footer))
            return original(*args, **kwargs)

        screen._refresh_layout = refresh_layout
        app.action_show_tab("fms")
        for _ in range(4):
            await pilot.pause()
        assert seen, "the switch laid nothing out"
        assert "Start match" in seen[0]


async def test_same_keys_are_not_rebuilt():
    app, _ = make_app(one_team())
    async with app.run_test(size=SIZE) as pilot:
        await pilot.pause()
        footer = app.query_one(Footer)
        before = list(footer.query(FooterKey))
        app.screen.refresh_bindings()  # what a focus change inside a tab does
        await pilot.pause()
        await pilot.pause()
        assert list(footer.query(FooterKey)) == before  # the very same widgets


async def test_tab_switches_do_not_keep_old_footer_keys_alive():
    app, _ = make_app(one_team())
    tabs = [cls.ID for cls in panel_classes()]
    async with app.run_test(size=SIZE) as pilot:
        await pilot.pause()
        for tab in tabs:  # every footer the app can show, once
            app.action_show_tab(tab)
            await pilot.pause()
        footer = app.query_one(Footer)
        baseline = _alive_footer_keys()
        for i in range(5 * len(tabs)):
            app.action_show_tab(tabs[i % len(tabs)])
            await pilot.pause()
        await pilot.pause()
        shown = len(footer.query(FooterKey))
        watchers = getattr(footer, "__watchers", {}).get("compact", [])
        # The Footer watches no more keys than it shows; the keys it dropped can be collected.
        assert shown > 0
        assert len(watchers) <= shown
        assert _alive_footer_keys() <= max(baseline, shown) + 2


def _footer_row(app) -> list[tuple[str, object]]:
    """The footer's line as drawn: each run of text with its style."""
    row = app.screen._compositor.render_strips()[-1]
    return [(segment.text, segment.style) for segment in row]


async def test_a_tab_switch_relabels_the_keys_it_has_and_draws_what_textual_would():
    app, _ = make_app(one_team(roles=frozenset({"ds", "rio", "fms"})))
    tabs = [cls.ID for cls in panel_classes()]
    async with app.run_test(size=SIZE) as pilot:
        await pilot.pause()
        footer = app.query_one(Footer)

        async def show(tab: str) -> None:
            app.action_show_tab(tab)
            await pilot.pause()
            await pilot.pause()

        textual_draws = {}  # each tab's footer built Textual's way: every key made afresh
        for tab in tabs:
            await show(tab)
            footer._shown = None  # it forgets what it shows, so the recompose rebuilds
            footer.refresh(recompose=True)
            await pilot.pause()
            await pilot.pause()
            textual_draws[tab] = _footer_row(app)
        first = footer.query(FooterKey).first()
        counts = set()
        # Then without rebuilding: fewer keys, then more (hidden keys shown again), both ways.
        for tab in tabs[::-1] + tabs + tabs[::2]:
            await show(tab)
            counts.add(len(_shown_keys(footer)))
            assert footer.query(FooterKey).first() is first  # relabelled, not remounted
            assert _footer_row(app) == textual_draws[tab], tab
        assert len(counts) > 2  # the tabs show different numbers of keys


async def test_tab_switches_leave_no_footer_key_to_the_collector():
    app, _ = make_app(one_team(roles=frozenset({"ds", "rio", "fms"})))
    tabs = [cls.ID for cls in panel_classes()]
    async with app.run_test(size=SIZE) as pilot:
        for tab in tabs:  # every footer the app can show, once
            app.action_show_tab(tab)
            await pilot.pause()
        await pilot.pause()

        async def switch_tabs() -> None:
            for tab in tabs * 2:
                app.action_show_tab(tab)
                await pilot.pause()
            await pilot.pause()

        garbage = await left_to_the_collector(switch_tabs)
        # Textual's way mounts new keys at each switch. The keys dropped linger (149 still
        # alive here, 7 shown), and their virtual style nodes go to the collector (284).
        footer = app.query_one(Footer)
        assert [o for o in garbage if isinstance(o, DOMNode)] == []
        assert _alive_footer_keys() == len(footer.query(FooterKey))


class _CompactApp(App):
    BINDINGS = [Binding("a", "one", "One"), Binding("b", "two", "Two")]

    def compose(self) -> ComposeResult:
        yield FieldboxFooter(compact=True)


async def test_compact_keys_look_as_textuals_and_follow_a_change():
    app = _CompactApp()
    async with app.run_test(size=(80, 10)) as pilot:
        await pilot.pause()
        footer = app.query_one(FieldboxFooter)
        plain = [k for k in _shown_keys(footer) if not k.has_class("-command-palette")]
        assert [k.description for k in plain] == ["One", "Two"]
        assert all(k.has_class("-compact") for k in plain)  # as Textual's data_bind would set
        footer.compact = False
        await pilot.pause()
        await pilot.pause()
        plain = [k for k in _shown_keys(footer) if not k.has_class("-command-palette")]
        assert [k.description for k in plain] == ["One", "Two"]
        assert not any(k.has_class("-compact") for k in plain)
