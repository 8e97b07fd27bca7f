"""Every workaround fieldbox needs in Textual, in one module, and the one switch that puts
them in.

:func:`install` is called by the app when it is made (never as a side effect of an import),
and only on the Textual releases pyproject.toml pins (:data:`TEXTUAL_RANGE`); on another it
logs why and leaves Textual as it is: the Footer and TabbedContent here then behave as
Textual's own, and :func:`set_virtual_rows` sets ``virtual_size`` as anyone would.

* reference cycles Textual makes of what it throws away, which wait for a full collection
  with the app's thread stopped: :func:`divide`, :func:`crop_extend`, :func:`lru_clear`,
  :func:`process_component_classes`;
* :class:`FieldboxFooter`: the Footer rebuilt all its keys at every binding change, kept
  the old ones alive, and relabelled a frame after the tab it belongs to;
* :class:`FieldboxTabs`: a focus arriving late from the tab left took the user back to it;
* :func:`set_virtual_rows`: a list growing ten times a second laid the whole screen out;
* :func:`reread_environment`: Textual reads its environment once, at import.

What each bought: docs/figures.md, "Why". Each has canary tests in
tests/app/test_textual_fixes.py that fail once Textual changes what it relies on (a private
name gone, the bug fixed), so an upgrade says which fix to look at, or to drop.
"""

from __future__ import annotations

import importlib
import logging
import re
from typing import Iterable, Sequence

from rich.style import Style
from textual.app import ComposeResult
from textual.cache import LRUCache
from textual.css.stylesheet import Stylesheet
from textual.dom import DOMNode
from textual.geometry import Size
from textual.scroll_view import ScrollView
from textual.strip import Strip
from textual.widget import Widget
from textual.widgets import Footer, TabbedContent, TabPane

try:  # a private module: another Textual may have moved it (install then says so)
    from textual.widgets._footer import FooterKey
except ImportError:  # pragma: no cover - not on the pinned releases
    FooterKey = None  # type: ignore[assignment,misc]

log = logging.getLogger("fieldbox.textual")

#: The Textual releases these were written and checked against: pyproject.toml's
#: ``textual>=8,<9`` (a test keeps the two the same).
TEXTUAL_RANGE = ((8,), (9,))

_installed = False


def _release(version: str) -> tuple[int, ...]:
    """``"8.2.8"`` -> ``(8, 2, 8)``; ``"9.0.0a1"`` -> ``(9, 0, 0)``."""
    parts = []
    for part in version.split("."):
        number = re.match(r"\d+", part)
        if number is None:
            break
        parts.append(int(number.group()))
        if number.end() != len(part):
            break
    return tuple(parts)


def supported(version: str) -> bool:
    """Whether the Textual ``version`` is in :data:`TEXTUAL_RANGE`."""
    low, high = TEXTUAL_RANGE
    release = _release(version)
    return bool(release) and low <= release < high


def installed() -> bool:
    """Whether :func:`install` put the workarounds in (in this process)."""
    return _installed


def install() -> bool:
    """Put every workaround in, for every widget of this process (calling again is harmless).
    False, Textual left as it is and the log saying why, on a release outside
    :data:`TEXTUAL_RANGE`."""
    global _installed
    import textual

    version = getattr(textual, "__version__", "")
    low, high = (".".join(map(str, bound)) for bound in TEXTUAL_RANGE)
    if not supported(version):
        log.warning("Textual %s: fieldbox's workarounds are for Textual >=%s,<%s; left out, Textual "
                    "runs as it is", version or "?", low, high)
        return False
    if FooterKey is None:  # pragma: no cover - not on the pinned releases
        log.warning("Textual %s has no textual.widgets._footer.FooterKey; fieldbox's workarounds left out", version)
        return False
    Strip.divide = divide  # type: ignore[method-assign]
    Strip.crop_extend = crop_extend  # type: ignore[method-assign]
    LRUCache.clear = lru_clear  # type: ignore[method-assign]
    Stylesheet._process_component_classes = process_component_classes  # type: ignore[method-assign]
    _installed = True
    return True


# -- reference cycles ---------------------------------------------------------------------------
# Garbage in a cycle waits for a full collection, which walks the whole heap with the app's
# thread stopped; reference counting frees what is not in one at once. Seen with
# gc.DEBUG_SAVEALL while the tabs cycled (tests/app/test_textual_fixes.py keeps each case).
_textual_divide = Strip.divide
_textual_crop_extend = Strip.crop_extend
_textual_lru_clear = LRUCache.clear
_textual_component_classes = Stylesheet._process_component_classes


def divide(self: Strip, cuts: Iterable[int]) -> Sequence[Strip]:
    """``Strip.divide``; a single cut at the strip's own width returns ``[self]`` uncached.

    The compositor cuts every line at the edges of what overlaps it; a line nothing overlaps
    is cut once, at its own width, and Textual kept the ``[strip]`` it returned in the strip's
    own ``_divide_cache``: the strip referred to itself. No report of it found among
    Textual's issues."""
    cuts = list(cuts)
    cell_length = self.cell_length
    if [cut for cut in cuts if cut <= cell_length] == [cell_length]:
        return [self]
    return _textual_divide(self, cuts)


def crop_extend(self: Strip, start: int, end: int, style: Style | None) -> Strip:
    """``Strip.crop_extend``; a crop of the whole strip returns ``self`` uncached.

    Textual kept the strip in its own cache as :func:`divide` did (a line exactly a widget's
    width, not scrolled sideways, as in the Legacy tab's NetConsole log). No report found."""
    if start <= 0 and end == self.cell_length:
        return self
    return _textual_crop_extend(self, start, end, style)


def lru_clear(self: LRUCache) -> None:
    """``LRUCache.clear``, then each entry of the old ring emptied.

    The cache keeps its entries in a ring of ``[prev, next, key, value]`` lists and ``clear``
    dropped the ring whole, a cycle holding every key and value; a ``DataTable`` clears its
    caches whenever its style may change (the focus, its tab shown). No report found.
    Textual's clear runs first, so the cache is whole and empty when the values go (a value's
    finalizer may read it); the head is taken too, for a cache of size 0."""
    links = list(self._cache.values())
    head = self._head
    _textual_lru_clear(self)
    for link in links:
        link.clear()
    head.clear()


def process_component_classes(self: Stylesheet, node: DOMNode) -> None:
    """``Stylesheet._process_component_classes``, re-using the node's virtual style nodes.

    To style a widget's component classes (a table's cursor, a footer key's key) Textual makes
    a virtual ``DOMNode`` per class; each restyle made them afresh, and the old ones died in
    cycles (a node and its styles refer to each other; Textualize/textual#6017 proposed weak
    references there and was closed unmerged; #6410 made ``RenderStyles`` weak, ``Styles.node``
    is still strong). A virtual node still attached to the widget is
    styled again in place, and the widget refreshed when its rules changed, as Textual does
    when a fresh node's rules differ; anything else goes Textual's way."""
    component_classes = node._get_component_classes()
    if not component_classes:
        return
    old_component_styles = node._component_styles.copy()
    node._component_styles.clear()
    refresh_node = False
    for component in sorted(component_classes):
        styles = old_component_styles.get(component)
        virtual = styles.node if styles is not None else None
        if styles is not None and virtual is not None and type(virtual) is DOMNode and virtual._parent is node:
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


# -- the footer -----------------------------------------------------------------------------------
class FieldboxFooter(Footer):
    """Textual's Footer, whose keys are relabelled in place when they change.

    Textual's Footer rebuilds every key each time the screen says its bindings were updated
    (several times a tab switch, mostly with the same keys); each key mounted is styled from
    scratch, restyled as its ``compact`` binding is set and cleared, and dies in a reference
    cycle: most of the app's cyclic garbage. Its ``data_bind(compact=...)`` also kept every
    removed key alive in the Footer's watcher list (Textualize/textual#6666).

    Here nothing happens while the keys show what they should. When they change, the keys
    mounted are relabelled; keys left over are hidden and kept for a tab with more, and only
    keys missing are mounted. Keys get the Footer's ``compact`` before they mount instead of a
    binding; a change of ``compact`` rebuilds them all, and so does anything this does not
    relabel (binding groups, the palette's key). Without :func:`install`, Textual's Footer.
    """

    _shown: tuple | None = None
    #: Keys shown first, whatever tab is in front: a narrow terminal cuts the footer's end,
    #: and the keys that stop the robot and quit must never be what is cut.
    FIRST_KEYS = ("space", "enter", "ctrl+q")

    @classmethod
    def _first(cls, key: str) -> int:
        return cls.FIRST_KEYS.index(key) if key in cls.FIRST_KEYS else len(cls.FIRST_KEYS)

    def bindings_changed(self, screen) -> None:
        """Relabel before the next frame, not after it: a tab switch and its footer are then
        laid out and drawn once (Textual's Footer waits for the refresh, and the screen was
        laid out twice a switch, the new tab drawn over the old tab's keys in between). No
        report found among Textual's issues."""
        if not _installed:
            super().bindings_changed(screen)
            return
        self._bindings_ready = True
        if screen.app.app_focus and self.is_attached and screen is self.screen:
            self.call_next(self.recompose)

    def _plain_keys(self) -> tuple[tuple, ...] | None:
        """The keys Footer.compose would show now, left to right, as ``(key, display,
        description, action, enabled, tooltip)``: one a action, its first binding. None where
        Textual would group keys."""
        get_display = self.app.get_key_display
        first: dict[str, tuple] = {}
        for _node, binding, enabled, tooltip in self.screen.active_bindings.values():
            if not binding.show:
                continue
            if binding.group is not None:
                return None
            if binding.action not in first:
                first[binding.action] = (binding.key, get_display(binding), binding.description,
                                         binding.action, enabled, tooltip)
        return tuple(sorted(first.values(), key=lambda spec: self._first(spec[0])))

    def _signature(self) -> tuple | None:
        """What the footer would show now, as ``(keys, fixed)``: the plain keys, which
        :meth:`_relabel` can change in place, and what only a rebuild changes (the palette's
        key, ``compact``, whether keys are grouped). None before the screen's bindings are
        known."""
        if not self._bindings_ready or not self.is_attached:
            return None
        palette = None
        if self.show_command_palette and self.app.ENABLE_COMMAND_PALETTE:
            found = self.screen.active_bindings.get(self.app.COMMAND_PALETTE_BINDING)
            if found is not None:
                _node, binding, enabled, tooltip = found
                palette = (binding.key, binding.description, enabled, binding.tooltip)
        keys = self._plain_keys()
        grouped = keys is None
        if grouped:  # anything that changes rebuilds
            keys = tuple((binding.key, binding.action, binding.description, enabled, tooltip,
                          binding.group)
                         for _node, binding, enabled, tooltip in self.screen.active_bindings.values()
                         if binding.show)
        return keys, (palette, self.compact, grouped)

    async def recompose(self) -> None:
        if not _installed:
            await super().recompose()
            return
        if not self.is_attached or self._pruning:
            return
        signature = self._signature()
        if signature is not None and signature == self._shown:
            return
        old = self._shown
        if (signature is not None and old is not None and signature[1] == old[1]
                and not signature[1][2] and await self._relabel(signature[0])):
            self._shown = signature
            return
        await super().recompose()

    async def _relabel(self, specs: tuple[tuple, ...]) -> bool:
        """Show ``specs`` with the keys mounted now: the keys left over are hidden, and only
        the keys missing are mounted (at most once each: as many as the most any tab shows).
        False (nothing touched) where the footer holds anything else than plain keys and the
        palette's key: then it is rebuilt."""
        keys: list[FooterKey] = []
        palette: FooterKey | None = None
        for child in self.children:
            if child.has_class("-textual-system"):
                continue
            if type(child) is not FooterKey or child.has_class("-grouped"):
                return False
            if child.has_class("-command-palette"):
                palette = child
            else:
                keys.append(child)
        async with self.batch():  # drawn once, as Textual's recompose is
            for key, spec in zip(keys, specs):
                self._label(key, *spec)
                key.display = True
            for key in keys[len(specs):]:  # kept, hidden, for a tab with more keys: a key
                key.display = False          # removed would die in a reference cycle
            if len(specs) > len(keys):
                new = [self._new_key(*spec) for spec in specs[len(keys):]]
                await self.mount_all(new, before=palette)
            self.styles.grid_size_columns = len(specs)
        return True

    @staticmethod
    def _label(key: FooterKey, name: str, display: str, description: str, action: str,
               enabled: bool, tooltip: str) -> None:
        """Give a mounted key what Footer.compose would give a new one (``_disabled`` is what
        FooterKey's constructor sets and its click reads)."""
        if (key.key, key.key_display, key.description, key.action, not key._disabled,
                key.tooltip or "") == (name, display, description, action, enabled, tooltip or ""):
            return
        key.key, key.key_display, key.description, key.action = name, display, description, action
        key._disabled = not enabled
        key.set_class(not enabled, "-disabled")
        if (key.tooltip or "") != (tooltip or ""):
            key.tooltip = tooltip or None
        key.refresh(layout=True)  # its width follows its text

    def _new_key(self, name: str, display: str, description: str, action: str, enabled: bool,
                 tooltip: str) -> FooterKey:
        key = FooterKey(name, display, description, action, disabled=not enabled, tooltip=tooltip)
        self._give_compact(key)
        return key

    def _give_compact(self, key: FooterKey) -> None:
        """What Footer.compose's ``data_bind(compact=...)`` gave a key before it mounts: the
        Footer's ``compact``, and its class (the first watch that would set it is skipped)."""
        key.set_reactive(FooterKey.compact, self.compact)
        key.set_class(self.compact, "-compact")

    def _watch_compact(self, compact: bool) -> None:
        # Textual's keys followed the Footer's ``compact`` through their binding; ours are
        # made again (it is part of the signature, so the recompose does not skip).
        if _installed and self.is_attached:
            self.call_after_refresh(self.recompose)

    def compose(self) -> ComposeResult:
        if not _installed:
            yield from super().compose()
            return
        self._shown = self._signature()
        widgets = list(super().compose())
        if self._plain_keys() is not None:  # no groups: the keys in the order _relabel gives them
            keys = [w for w in widgets if type(w) is FooterKey and not w.has_class("-command-palette")]
            ordered = iter(sorted(keys, key=lambda k: self._first(k.key)))
            widgets = [next(ordered) if w in keys else w for w in widgets]
        for widget in widgets:
            if isinstance(widget, FooterKey) and widget._reactive_connect:
                # Undo the data_bind Footer.compose made (the palette key has none: it stays
                # as Textual draws it) and give the key the value the binding would.
                widget._reactive_connect = None
                self._give_compact(widget)
            yield widget


# -- the tabs -------------------------------------------------------------------------------------
class FieldboxTabs(TabbedContent):
    """Textual's TabbedContent, whose tab changes only when the user picks one.

    Textual makes the tab of a widget that receives the focus the active tab, and focus moves
    are queued: a focus asked for in the tab being left, or handed by a focused widget to its
    sibling as its tab hides (Textualize/textual#4955; the fix proposed there, #6416, was
    closed unmerged), arrived after the new tab was shown and took the user back. Here a
    focus arriving late is not a tab change: the message goes on to the app, which gives the
    focus back to the tab shown (``FieldboxApp``). Without :func:`install`, Textual's own.
    """

    def _on_tab_pane_focused(self, event: TabPane.Focused) -> None:
        if _installed:
            event.prevent_default()  # not TabbedContent's own handler, which switches tabs


# -- a list's rows --------------------------------------------------------------------------------
def set_virtual_rows(view: ScrollView, rows: int, width: int | None = None) -> None:
    """Give ``view`` (one line per row, its own size set by its container) ``rows`` rows.

    Setting ``virtual_size`` asks for a layout of the whole screen, and a list that grows every
    100 ms laid the screen out ten times a second. The view's own size does not depend on its
    rows, so only its scrollbars change: this does what Textual's own
    ``_size_updated(layout=False)`` does for them (``_scroll_update``). A scrollbar that
    appears or goes still lays the screen out. No report found among Textual's issues."""
    size = Size(max(1, view.size.width if width is None else width), rows)
    old = view.virtual_size
    if size == old:
        return
    if not _installed or not view.is_mounted or size.width != old.width:
        view.virtual_size = size
        return
    view.set_reactive(Widget.virtual_size, size)
    view._scroll_update(size)  # scrollbars, and the scroll clamped to the new size
    view.refresh()


# -- the environment ------------------------------------------------------------------------------
def reread_environment() -> None:
    """In a tab forked from the fork server: Textual reads its environment (the driver, the
    frame rate, colours) into ``textual.constants`` once, at import, and the fork server
    imported it before the tab's environment was known. Needed on any release; no report
    found among Textual's issues (a fork after import is ours to handle)."""
    import textual.constants

    importlib.reload(textual.constants)
