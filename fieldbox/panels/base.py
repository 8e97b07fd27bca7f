"""What every panel shares."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, Callable

from textual.containers import Container
from textual.widgets import Static

from roles.core import CommandError

if TYPE_CHECKING:
    from roles.engine import Engine


def selected_station(engine: Any, team: int | None) -> Any:
    """The station of ``team`` on the engine's field, else its first (None: no stations)."""
    if engine is None or not engine.field.stations:
        return None
    stations = engine.field.stations
    return next((st for st in stations if st.team == team), stations[0])


class Panel(Container):
    """A tab's content. ``refresh_view`` copies state from the engine; it must be cheap and
    must not raise (the app logs and carries on if it does)."""

    #: The tab title.
    TITLE = ""
    #: The tab id (also the key used by ``--panel`` and the command palette).
    ID = ""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self._shown: dict[str, Any] = {}  # what set_shown last applied, per key

    def refresh_view(self, engine: "Engine", now: float) -> None:
        """Copy what changed from the engine's cores into the widgets."""

    @property
    def engine(self) -> "Engine":
        return self.app.engine  # type: ignore[attr-defined]

    def run_command(self, text: str) -> bool:
        """Carry out a headless-language command; a refusal is a notification. True if done."""
        return self.app.run_command(text)  # type: ignore[attr-defined]

    def call_core(self, fn: Callable[[], Any], host: str | None) -> bool:
        """Run ``fn`` on the wire's side (``engine.call``) for what the command language lacks;
        a refusal (CommandError) is a warning notification with the reason. True if done."""
        try:
            self.engine.call(fn, host)
        except CommandError as exc:
            self.notify(str(exc), severity="warning")
            return False
        return True

    def station(self) -> Any:
        """The station of the team the DS keys act on (the app's ``selected_team``), else
        the field's first; None when no station runs."""
        return selected_station(getattr(self.app, "engine", None), getattr(self.app, "selected_team", None))

    def focus_is_inside(self) -> bool:
        """Whether the panel or one of its widgets has the focus (a tab's keys work only then:
        panels take the focus when shown unless they have it)."""
        focused = self.screen.focused if self.is_mounted else None
        return focused is not None and self in focused.ancestors_with_self

    @property
    def tab_shown(self) -> bool:
        """Whether this panel's tab is the one the app shows (True outside the app's tabs)."""
        try:
            return self.app.screen_stack[0].query_one("TabbedContent").active == self.ID  # type: ignore[attr-defined]
        except Exception:  # noqa: BLE001
            return True

    def take_focus(self) -> None:
        """Focus what a shown tab's keys start on: the panel itself, unless a panel says."""
        self.focus()

    # -- drawing only what changed (panels refresh ten times a second) -----------------------
    def set_shown(self, key: str, value: Any, apply: Callable[[Any], Any]) -> None:
        """``apply(value)`` unless ``value`` is what was applied last for ``key``."""
        if self._shown.get(key, _NEVER) != value:
            self._shown[key] = value
            apply(value)

    def set_text(self, widget_id: str, content: Any, layout: bool = False) -> None:
        """Update the Static ``#widget_id`` if its content changed. Most keep their size (a
        fixed number of lines): no layout pass for them, which is most of a refresh's cost."""
        self.set_shown(widget_id, content,
                       lambda c: self.query_one(f"#{widget_id}", Static).update(c, layout=layout))


_NEVER = object()  # set_shown's "nothing applied yet" (None is a value)
