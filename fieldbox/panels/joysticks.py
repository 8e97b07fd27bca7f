"""The Joysticks panel."""

from __future__ import annotations

import json

from textual.app import ComposeResult
from textual.widgets import Static

from .base import Panel


class JoysticksPanel(Panel):
    TITLE = "Joysticks"
    ID = "joysticks"

    def compose(self) -> ComposeResult:
        yield Static(id="joysticks-body")

    def refresh_view(self, engine, now: float) -> None:
        snap = engine.field.snapshot(now)
        self.query_one("#joysticks-body", Static).update(json.dumps(snap, indent=1, default=str)[:4000])
