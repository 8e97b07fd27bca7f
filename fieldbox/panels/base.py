"""What every panel shares."""

from __future__ import annotations

from typing import TYPE_CHECKING

from textual.containers import Container

if TYPE_CHECKING:
    from roles.engine import Engine


class Panel(Container):
    """A tab's content. ``refresh_view`` copies state from the engine; it must be cheap and
    must not raise (the app logs and carries on if it does)."""

    #: The tab title.
    TITLE = ""
    #: The tab id (also the key used by ``--panel`` and the command palette).
    ID = ""

    def refresh_view(self, engine: "Engine", now: float) -> None:
        """Copy what changed from the engine's cores into the widgets."""

    @property
    def engine(self) -> "Engine":
        return self.app.engine  # type: ignore[attr-defined]

    def run_command(self, text: str) -> bool:
        """Carry out a headless-language command; a refusal is a notification. True if done."""
        return self.app.run_command(text)  # type: ignore[attr-defined]
