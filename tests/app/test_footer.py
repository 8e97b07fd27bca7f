"""The footer: it shows the keys of the tab in front, and using the app does not grow it.

Textual 8's Footer rebuilds its keys every time the screen's bindings are updated (three to
four times a tab switch, mostly with the same keys), and each old FooterKey stayed
referenced from the Footer's ``compact`` watcher list (Textualize/textual#6666): about
1.4 MB a switch with our panels, 35 MB a minute in ``benchmarks/memory.py``, and most of
the app's cyclic garbage. fieldbox's Footer (fieldbox/widgets.py) rebuilds only when the
keys change, and binds nothing.
"""

from __future__ import annotations

import gc

from textual.widgets import Footer
from textual.widgets._footer import FooterKey

from fieldbox.app import panel_classes

from .helpers import SIZE, make_app, one_team


def _alive_footer_keys() -> int:
    gc.collect()
    return sum(1 for o in gc.get_objects() if isinstance(o, FooterKey))


def _descriptions(footer: Footer) -> list[str]:
    return [key.description for key in footer.query(FooterKey)]


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
        assert not any(k.has_class("-compact") for k in footer.query(FooterKey)
                       if not k.has_class("-command-palette"))


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
