"""Textual's ``Strip.divide`` and ``crop_extend``, without the reference cycles they made
of lines drawn whole.

Textual (8.x) draws each line of the screen as a ``Strip``, and its compositor cuts every
strip at the edges of what overlaps it with ``strip.divide(cuts)``. A strip that nothing
overlaps is "cut" once, at its own width, and Textual returns ``[strip]`` and keeps that list
in the strip's own ``_divide_cache``: the strip now refers to itself. Reference counting
cannot free such a strip, nor the seven caches, lists and segments it holds; they wait for
the cyclic garbage collector, and pile up in its oldest generation until a full collection,
which walks the whole heap with the app's thread stopped.

Measured with ``python benchmarks/field.py --app`` (a full field, every panel live, tabs
cycling, the inspector recording; the app's process over 60 s, two runs each, the same
hour): cyclic garbage 11 300-11 500 -> 5 700 objects a second, full collections 10 -> 9 a
minute and their median 183-189 -> 115-132 ms; the process's CPU 30.4-30.7 % -> 28.6-28.7 %.
With the inspector shown alone, the strips, segments and caches left to the collector went
from 36 000 objects every 10 s to none (docs/figures.md, "What changed", 18).

The fix returns the same ``[strip]`` without caching it; every other cut goes to Textual's
own ``divide`` unchanged. ``crop_extend`` kept a strip in its own cache the same way when
asked for the whole of it, and gets the same fix. :func:`install` is called when the app's
module is imported.
"""

from __future__ import annotations

from typing import Iterable

from rich.style import Style
from textual.strip import Strip

_textual_divide = Strip.divide
_textual_crop_extend = Strip.crop_extend


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


def install() -> None:
    """Use :func:`divide` and :func:`crop_extend` for every Strip in this process (calling
    again is harmless)."""
    Strip.divide = divide  # type: ignore[method-assign]
    Strip.crop_extend = crop_extend  # type: ignore[method-assign]
