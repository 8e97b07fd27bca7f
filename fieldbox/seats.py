"""What a classroom seat's screen shows (roles/runtime/classroom.py): only what the seat may do.

An observer, and a driver the teacher took a station back from (who watches from then on), had
the Enable, E-STOP and Restart buttons and their footer keys, all refused when pressed: only a
toast said "you watch" (issue 31). Here an observer's main screen gets the class ``-watching``
(its CSS hides the DS tab's and the Diagnostics tab's command buttons and key help), and
:func:`offered` keeps the robot's actions out of its footer. The title names the seat: a
driver's tab says its own team, not the field's first.
"""

from __future__ import annotations

from typing import Any, Callable

from roles.runtime.field import FieldConfig

#: The class the main screen of an observer's app has.
WATCHING = "-watching"

#: What an observer does not see: the buttons that send the robot commands, and the key help
#: that offers their keys. (The status line says "classroom: you watch".)
WATCHING_CSS = f"""
Screen.{WATCHING} #ds-control .ds-row, Screen.{WATCHING} #ds-practice-btn, Screen.{WATCHING} #ds-keys,
Screen.{WATCHING} #ds-note, Screen.{WATCHING} #diag-buttons, Screen.{WATCHING} #diag-keys {{ display: none; }}
"""

#: The actions that command a robot or the field: an observer's footer leaves them out (the
#: classroom refuses an observer's command anyway).
COMMAND_ACTIONS = frozenset({"enable", "disable", "estop", "mode", "practice", "restart_code", "reboot"})
#: What no seat does: the field's roles and its restart are the classroom's (the app refuses them).
FIELD_ACTIONS = frozenset({"pick_roles", "restart_field"})


def watching(seat: Any) -> bool:
    """Whether ``seat`` (a classroom's Seat, or None outside a classroom) only watches."""
    return seat is not None and getattr(seat, "kind", None) == "observer"


def offered(seat: Any, action: str) -> bool:
    """Whether a footer shows ``action`` to ``seat`` (False hides its key)."""
    if seat is not None and action in FIELD_ACTIONS:
        return False
    return not (watching(seat) and action in COMMAND_ACTIONS)


def seat_title(seat: Any, shared: FieldConfig | None, describe: Callable[[FieldConfig], str]) -> str | None:
    """The app's sub-title in a classroom: the seat first (a driver's own team), then the
    field. None outside a classroom."""
    if seat is None:
        return None
    field = f"classroom {describe(shared)}" if shared is not None else "classroom"
    if seat.kind == "driver":
        return f"team {seat.team} · {field}"
    return f"{'teacher' if seat.kind == 'teacher' else 'watching'} · {field}"
