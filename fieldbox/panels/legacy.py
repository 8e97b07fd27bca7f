"""The Legacy 2010 panel."""

from __future__ import annotations

import json

from textual.app import ComposeResult
from textual.widgets import Static

from .base import Panel


class LegacyPanel(Panel):
    TITLE = "Legacy 2010"
    ID = "legacy"

    def compose(self) -> ComposeResult:
        yield Static(id="legacy-body")

    def refresh_view(self, engine, now: float) -> None:
        snap = engine.field.snapshot(now)
        self.query_one("#legacy-body", Static).update(json.dumps(snap, indent=1, default=str)[:4000])
