"""The Inspector panel."""

from __future__ import annotations

import json

from textual.app import ComposeResult
from textual.widgets import Static

from .base import Panel


class InspectorPanel(Panel):
    TITLE = "Inspector"
    ID = "inspector"

    def compose(self) -> ComposeResult:
        yield Static(id="inspector-body")

    def refresh_view(self, engine, now: float) -> None:
        snap = engine.field.snapshot(now)
        self.query_one("#inspector-body", Static).update(json.dumps(snap, indent=1, default=str)[:4000])
