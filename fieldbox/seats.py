"""What a classroom seat's screen shows (roles/runtime/classroom.py): only what the seat may do.

An observer, and a driver the teacher took a station back from (who watches from then on), had
the Enable, E-STOP and Restart buttons and their footer keys, all refused when pressed: only a
toast said "you watch" (issue 31). Here an observer's main screen gets the class ``-watching``
(its CSS hides the DS tab's and the Diagnostics tab's command buttons and key help), and
:func:`offered` keeps the robot's actions out of its footer. A driver and an observer (a
*student*: any seat but the teacher's) get the class ``-student`` too: the FMS and the faults on
purpose are the teacher's, so the FMS tab and the Faults tab show the match and the counters
without the keys, the help and the boxes that run them. The 2010 tab of a field that is not a
2010 one only says how to switch to 2010, which only the teacher can: a student's tab bar leaves
it out (:func:`hidden_tabs`). The title names the seat: a driver's tab says its own team, not
the field's first.

A key a seat's footer does not offer, pressed anyway, is still refused, with the words the
classroom's wire refuses it with (:func:`refusal`, roles/runtime/wireproc.py ``refusal``).
"""

from __future__ import annotations

from typing import Any, Callable

from roles.runtime.field import FieldConfig

#: The class the main screen of an observer's app has.
WATCHING = "-watching"
#: The class the main screen of a driver's or an observer's app has: not the teacher's.
STUDENT = "-student"

#: What an observer does not see: the buttons that send the robot commands, and the key help
#: that offers their keys. (The status line says "classroom: you watch".) What no student
#: sees: the FMS tab's match controls and key help, and the Faults tab's injector; instead a
#: line that says who runs them (shown to a student only).
WATCHING_CSS = f"""
Screen.{WATCHING} #ds-control .ds-row, Screen.{WATCHING} #ds-practice-btn, Screen.{WATCHING} #ds-keys,
Screen.{WATCHING} #ds-note, Screen.{WATCHING} #diag-buttons, Screen.{WATCHING} #diag-keys,
Screen.{WATCHING} #js-keys {{ display: none; }}
Screen.{STUDENT} #fms-timing, Screen.{STUDENT} #fms-help, Screen.{STUDENT} #fault-injector {{ display: none; }}
.student-only {{ display: none; }}
Screen.{STUDENT} .student-only {{ display: block; }}
"""

#: The actions that command a robot or the field: an observer's footer leaves them out (the
#: classroom refuses an observer's command anyway).
COMMAND_ACTIONS = frozenset({"enable", "disable", "estop", "mode", "practice", "restart_code", "reboot"})
#: An observer's joysticks drive nothing (the classroom refuses its updates): the Joysticks
#: tab's keys that place them are not offered, nor the keyboard joystick's key help.
WATCHING_ACTIONS: dict[str, frozenset[str]] = {
    "joysticks": frozenset({"move_keyboard", "toggle_keyboard", "lock", "rescan"}),
}
#: What no seat does: the field's roles and its restart are the classroom's (the app refuses them).
FIELD_ACTIONS = {
    "pick_roles": "this app shares the classroom's field: its roles are the teacher's",
    "restart_field": "this app shares the classroom's field: quit with ctrl+q and join it again",
}
#: The teacher's actions, by the tab whose keys they are: running the match and faults on
#: purpose (the classroom refuses them from a student: roles/runtime/wireproc.py). Picking a
#: station (1-6) and the match log are a look, not a command: every seat has them.
TEACHER_ACTIONS: dict[str, frozenset[str]] = {
    "fms": frozenset({"bypass", "station_estop", "astop", "start", "abort", "next_match", "replay",
                      "match_type", "edit_durations"}),
    "faults": frozenset({"focus_injector"}),
}
#: The classroom's own words for what a seat may not do (roles/runtime/wireproc.py refusal).
YOU_WATCH = "you watch this field: ask the teacher for a station"
TEACHERS = "the FMS and the faults are the teacher's: you watch them here"
NOT_2010 = "this classroom's field is not a 2010 one: the 2010 tab has nothing to show"


def watching(seat: Any) -> bool:
    """Whether ``seat`` (a classroom's Seat, or None outside a classroom) only watches."""
    return seat is not None and getattr(seat, "kind", None) == "observer"


def student(seat: Any) -> bool:
    """Whether ``seat`` is a classroom's driver or observer: the FMS and the faults are not its."""
    return seat is not None and getattr(seat, "kind", None) in ("driver", "observer")


def refusal(seat: Any, action: str, tab: str | None = None) -> str | None:
    """Why ``seat`` may not do ``action`` (of ``tab``'s keys; None: the app's own), in the
    classroom's words; None if it may. Outside a classroom (``seat`` None) everything may."""
    if seat is None:
        return None
    if action in FIELD_ACTIONS:
        return FIELD_ACTIONS[action]
    if watching(seat) and (action in COMMAND_ACTIONS or action in WATCHING_ACTIONS.get(tab or "", ())):
        return YOU_WATCH
    if student(seat) and tab is not None and action in TEACHER_ACTIONS.get(tab, ()):
        return YOU_WATCH if watching(seat) else TEACHERS
    return None


def offered(seat: Any, action: str, tab: str | None = None) -> bool:
    """Whether a footer shows ``action`` to ``seat`` (False hides its key)."""
    return refusal(seat, action, tab) is None


def hidden_tabs(seat: Any, shared: FieldConfig | None) -> frozenset[str]:
    """The tabs ``seat``'s tab bar leaves out: a student's 2010 tab, unless the classroom's
    field (``shared``) is a 2010 one."""
    if student(seat) and not (shared is not None and shared.legacy):
        return frozenset({"legacy"})
    return frozenset()


def seat_title(seat: Any, shared: FieldConfig | None, describe: Callable[[FieldConfig], str]) -> str | None:
    """The app's sub-title in a classroom: the seat first (a driver's own team), then the
    field. None outside a classroom."""
    if seat is None:
        return None
    field = f"classroom {describe(shared)}" if shared is not None else "classroom"
    if seat.kind == "driver":
        return f"team {seat.team} · {field}"
    return f"{'teacher' if seat.kind == 'teacher' else 'watching'} · {field}"
