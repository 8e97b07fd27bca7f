"""The Console panel."""

from __future__ import annotations

import json

from textual.app import ComposeResult
from textual.widgets import Static

from .base import Panel


class ConsolePanel(Panel):
    TITLE = "Console"
    ID = "console"

    def compose(self) -> ComposeResult:
        yield Static(id="console-body")

    def refresh_view(self, engine, now: float) -> None:
        snap = engine.field.snapshot(now)
        self.query_one("#console-body", Static).update(json.dumps(snap, indent=1, default=str)[:4000])
