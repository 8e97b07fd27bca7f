"""Reference cycles Textual makes of what it throws away, broken so reference counting
frees it, not the cyclic garbage collector.

Garbage in a cycle waits for the collector. What survives two young collections piles up in
the oldest generation until a full collection, which walks the whole heap with the app's
thread stopped (100-200 ms on this machine), and the memory it held stays with the
allocator meanwhile. Three things in Textual (8.x) made much of the app's cyclic garbage
(how much each fix took away: docs/figures.md, "Why"):

**Lines drawn whole.** Textual draws each line of the screen as a ``Strip``, and its
compositor cuts every strip at the edges of what overlaps it with ``strip.divide(cuts)``. A
strip that nothing overlaps is "cut" once, at its own width, and Textual returns ``[strip]``
and keeps that list in the strip's own ``_divide_cache``: the strip refers to itself, with
the seven caches, lists and segments it holds. :func:`divide` returns the same ``[strip]``
without caching it; every other cut goes to Textual's own ``divide`` unchanged.
``crop_extend`` kept a strip in its own cache the same way when asked for the whole of it,
and :func:`crop_extend` gets the same fix.

**A cleared LRU cache.** Textual's ``LRUCache`` keeps its entries in a ring, each entry a
list ``[prev, next, key, value]``; ``clear()`` dropped the ring whole, a cycle holding every
key and value. A ``DataTable`` clears its caches (cells, rows and lines drawn) whenever its
style may have changed: the focus gained or lost, its tab shown. :func:`lru_clear` empties
each entry of the old ring.

**Virtual style nodes made afresh at each restyle.** :func:`process_component_classes`
re-uses them.

:func:`install` is the one place these are put in: the app calls it when it is made (not as a
side effect of an import), and only on the Textual series they were written against
(:data:`TEXTUAL_SERIES`); on another it says so and leaves Textual as it is. Each fix has a
canary test (tests/app/test_cycles.py) that fails once Textual stops making the cycle, so
the fix can go. No report of these cycles was found among Textual's issues.
"""

from __future__ import annotations

from typing import Iterable

from rich.style import Style
from textual.cache import LRUCache
from textual.css.stylesheet import Stylesheet
from textual.dom import DOMNode
from textual.strip import Strip

_textual_divide = Strip.divide
_textual_crop_extend = Strip.crop_extend
_textual_lru_clear = LRUCache.clear
_textual_component_classes = Stylesheet._process_component_classes


def divide(self: Strip, cuts: Iterable[int]) -> list[Strip]:
    """``Strip.divide``; a single cut at the strip's own width returns ``[self]`` uncached."""
    cuts = list(cuts)
    cell_length = self.cell_length
    if [cut for cut in cuts if cut <= cell_length] == [cell_length]:
        return [self]
    return _textual_divide(self, cuts)


def crop_extend(self: Strip, start: int, end: int, style: Style | None) -> Strip:
    """``Strip.crop_extend``; a crop of the whole strip returns ``self`` uncached (Textual's
    keeps it in the strip's own cache too: a line exactly a widget's width, not scrolled
    sideways, as in the Legacy tab's NetConsole log)."""
    if start <= 0 and end == self.cell_length:
        return self
    return _textual_crop_extend(self, start, end, style)


def lru_clear(self: LRUCache) -> None:
    """``LRUCache.clear``, then each entry of the old ring emptied: nothing of it is left in
    a cycle. Textual's clear runs first, so the cache is already empty and whole when the
    values go (a value's finalizer may read the cache). Every entry of the ring is in the
    cache's dict but the head of a cache of size 0, taken too; an entry evicted or
    discarded leaves the ring. (A cache's only entry, discarded, still links to itself:
    Textual's ``Log`` discards lines one at a time, so that cycle is rare.)"""
    links = list(self._cache.values())
    head = self._head
    _textual_lru_clear(self)
    for link in links:
        link.clear()
    head.clear()


def process_component_classes(self: Stylesheet, node: DOMNode) -> None:
    """``Stylesheet._process_component_classes``, re-using the node's virtual style nodes.

    To style a widget's component classes (a table's cursor, a footer key's key), Textual
    makes a virtual ``DOMNode`` per class, styles it, and keeps its styles; each restyle of
    the widget (the focus gained or lost, its tab shown) made them afresh, and the old ones
    died in cycles (a node and its styles refer to each other), forty objects each. Here a
    virtual node still attached to the widget is styled again in place, and the widget is
    refreshed when its rules changed, as Textual does when the fresh node's rules differ;
    anything else (a first styling, a node from elsewhere) goes the way Textual goes."""
    component_classes = node._get_component_classes()
    if not component_classes:
        return
    old_component_styles = node._component_styles.copy()
    node._component_styles.clear()
    refresh_node = False
    for component in sorted(component_classes):
        styles = old_component_styles.get(component)
        virtual = styles.node if styles is not None else None
        if virtual is not None and type(virtual) is DOMNode and virtual._parent is node:
            before = (styles.base.get_rules(), styles.inline.get_rules())
            self.apply(virtual, animate=False)
            changed = before != (styles.base._rules, styles.inline._rules)
        else:
            virtual = DOMNode(classes=component)
            virtual._attach(node)
            self.apply(virtual, animate=False)
            changed = styles != virtual.styles
        refresh_node = refresh_node or changed
        node._component_styles[component] = virtual.styles
    if refresh_node:
        node.refresh()


#: The Textual releases these fixes were written and checked against (pyproject: textual>=8,<9).
TEXTUAL_SERIES = "8."


def install() -> bool:
    """Use :func:`divide` and :func:`crop_extend` for every Strip in this process,
    :func:`lru_clear` for every LRUCache and :func:`process_component_classes` for every
    stylesheet (calling again is harmless). False, and nothing changed, on another Textual."""
    import textual

    version = getattr(textual, "__version__", "")
    if not version.startswith(TEXTUAL_SERIES):
        import logging

        logging.getLogger("fieldbox.cycles").info("Textual %s: its reference-cycle fixes are for %sx; left out",
                                                  version, TEXTUAL_SERIES)
        return False
    Strip.divide = divide  # type: ignore[method-assign]
    Strip.crop_extend = crop_extend  # type: ignore[method-assign]
    LRUCache.clear = lru_clear  # type: ignore[method-assign]
    Stylesheet._process_component_classes = process_component_classes  # type: ignore[method-assign]
    return True
