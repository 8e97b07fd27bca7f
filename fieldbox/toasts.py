"""How many toasts a screen shows at once, and where.

Textual stacks every notification as a toast in the bottom right corner until it times out:
at 80x24 the start-up hint and two more covered the Driver Station's charts and its
Communications and Robot code lights (issue 31). Here a small screen keeps the newest
:data:`SMALL_SCREEN_TOASTS` toasts (a bigger one :data:`TOASTS`); an older one goes, an
error last, and the newest says how many went ("+2 earlier"). :data:`TOAST_CSS` keeps a
toast in the right third of the screen, the DS tab's match and messages column, clear of its
lights in the middle column. :func:`clear_of_hints` keeps toasts above a tab's key-hint rows
(the rows over the footer that say what Space, Enter and e do): at 80x24 a toast covered their
end.
"""

from __future__ import annotations

from typing import Any

from textual.css.query import NoMatches
from textual.notifications import Notification, Notifications
from textual.widgets._toast import ToastRack

#: Toasts shown at once on a screen under :data:`SMALL_SCREEN_ROWS` rows, and on a bigger one.
SMALL_SCREEN_TOASTS = 2
TOASTS = 3
SMALL_SCREEN_ROWS = 40

#: The class of a tab's key-hint rows (a Static): toasts stay above them.
KEY_HINTS = "key-hints"
#: Rows under the toasts with no hints to keep clear: the footer's (Textual's own margin).
FOOTER_ROWS = 1

#: The app's CSS for toasts: a third of the width at most (Textual's is half), so a toast
#: covers the DS tab's right column only (its columns are thirds).
TOAST_CSS = "Toast { max-width: 33%; }"


def make_room(notifications: Notifications, new: Notification, rows: int) -> int:
    """Drop the oldest toasts so that ``new`` is one of at most the limit for a screen of
    ``rows``: information and warnings before errors, older before newer. ``new``'s title
    then counts what went (with what the dropped ones had counted). The number dropped."""
    limit = SMALL_SCREEN_TOASTS if rows < SMALL_SCREEN_ROWS else TOASTS
    shown = [n for n in notifications if not n.has_expired]
    excess = len(shown) + 1 - limit
    if excess <= 0:
        return 0
    dropped = sorted(shown, key=lambda n: (n.severity == "error", n.raised_at))[:excess]
    earlier = 0
    for note in dropped:
        earlier += 1 + _earlier(note)
        del notifications[note]
    new.title = f"{new.title} · +{earlier} earlier" if new.title else f"+{earlier} earlier"
    return len(dropped)


def _earlier(note: Notification) -> int:
    """How many toasts ``note``'s title says went before it (0 if it says none)."""
    _, sep, rest = note.title.rpartition("+")
    count = rest.removesuffix(" earlier")
    return int(count) if sep and rest.endswith(" earlier") and count.isdigit() else 0


def hint_rows(screen: Any, panel: Any) -> int:
    """Rows from the top of ``panel``'s key hints to the bottom of ``screen`` (the hints and the
    footer under them), or :data:`FOOTER_ROWS` where the panel has none at its bottom (hints
    higher up are not where toasts stack, from the bottom up)."""
    bottom = panel.region.bottom
    tops = [hint.region.y for hint in panel.query(f".{KEY_HINTS}")
            if hint.display and hint.region.height and hint.region.bottom >= bottom - 1]
    return max(FOOTER_ROWS, screen.size.height - min(tops)) if tops else FOOTER_ROWS


def clear_of_hints(screen: Any, panel: Any) -> int:
    """Put ``screen``'s toasts above ``panel``'s key hints (Textual docks them at the bottom,
    over the last rows but the footer's); the rows under them."""
    rows = hint_rows(screen, panel) if panel is not None else FOOTER_ROWS
    try:
        rack = screen.get_child_by_type(ToastRack)
    except NoMatches:  # an app run without notifications (a test's): no toasts to place
        return rows
    if rack.styles.margin.bottom != rows:
        rack.styles.margin = (0, 0, rows, 0)
    return rows
