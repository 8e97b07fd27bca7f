"""How many toasts a screen shows at once, and where.

Textual stacks every notification as a toast in the bottom right corner until it times out:
at 80x24 the start-up hint and two more covered the Driver Station's charts and its
Communications and Robot code lights (issue 31). Here a small screen keeps the newest
:data:`SMALL_SCREEN_TOASTS` toasts (a bigger one :data:`TOASTS`); an older one goes, an
error last, and the newest says how many went ("+2 earlier"). :data:`TOAST_CSS` keeps a
toast in the right third of the screen, the DS tab's match and messages column, clear of its
lights in the middle column.
"""

from __future__ import annotations

from textual.notifications import Notification, Notifications

#: Toasts shown at once on a screen under :data:`SMALL_SCREEN_ROWS` rows, and on a bigger one.
SMALL_SCREEN_TOASTS = 2
TOASTS = 3
SMALL_SCREEN_ROWS = 40

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
