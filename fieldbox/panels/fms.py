"""The FMS panel."""

from __future__ import annotations

import json

from textual.app import ComposeResult
from textual.widgets import Static

from .base import Panel


class FmsPanel(Panel):
    TITLE = "FMS"
    ID = "fms"

    def compose(self) -> ComposeResult:
        yield Static(id="fms-body")

    def refresh_view(self, engine, now: float) -> None:
        snap = engine.field.snapshot(now)
        self.query_one("#fms-body", Static).update(json.dumps(snap, indent=1, default=str)[:4000])
