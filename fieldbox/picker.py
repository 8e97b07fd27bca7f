"""The role picker: change roles, team, station, network plan and 2010 mode without
restarting the process."""

from __future__ import annotations

from dataclasses import replace

from textual.app import ComposeResult
from textual.containers import Horizontal, Vertical
from textual.screen import ModalScreen
from textual.widgets import Button, Checkbox, Input, Label, Select

from protocol.enums import AllianceStation
from roles.addresses import PLANS, check_team
from roles.field import FieldConfig

from .serve import tab_allows_plan


class RolePicker(ModalScreen[FieldConfig | None]):
    DEFAULT_CSS = """
    RolePicker { align: center middle; }
    RolePicker > Vertical { width: 64; height: auto; border: thick $primary; padding: 1 2; background: $surface; }
    RolePicker Horizontal { height: auto; }
    RolePicker Label { padding: 1 1 0 0; }
    RolePicker #picker-error { color: $error; height: auto; }
    """
    BINDINGS = [("escape", "cancel", "Cancel")]

    def __init__(self, config: FieldConfig) -> None:
        super().__init__()
        self.config = config

    def compose(self) -> ComposeResult:
        c = self.config
        with Vertical():
            yield Label("[b]Roles[/b]")
            with Horizontal():
                yield Checkbox("Driver Station", "ds" in c.roles, id="role-ds")
                yield Checkbox("roboRIO", "rio" in c.roles, id="role-rio")
                yield Checkbox("FMS", "fms" in c.roles, id="role-fms")
            with Horizontal():
                yield Label("Team")
                yield Input(str(c.team), id="team", type="integer", max_length=5)
                yield Label("Station")
                yield Select([(s.label, s) for s in AllianceStation], value=c.station, id="station",
                             allow_blank=False)
            with Horizontal():
                yield Label("Network")
                # In a browser tab, only the plans the server was started to allow: "real"
                # binds every interface of the server (fieldbox/serve.py).
                plans = [p for p in PLANS if tab_allows_plan(p) or p == c.plan]
                yield Select([(p, p) for p in plans], value=c.plan, id="plan", allow_blank=False)
                yield Checkbox("2010 legacy", c.legacy, id="legacy")
            yield Label("", id="picker-error")
            with Horizontal():
                yield Button("Apply", variant="primary", id="apply")
                yield Button("Cancel", id="cancel")

    def on_button_pressed(self, event: Button.Pressed) -> None:
        if event.button.id == "cancel":
            self.dismiss(None)
            return
        roles = frozenset(r for r in ("ds", "rio", "fms") if self.query_one(f"#role-{r}", Checkbox).value)
        error = self.query_one("#picker-error", Label)
        if not roles:
            error.update("choose at least one role")
            return
        try:
            team = check_team(int(self.query_one("#team", Input).value or "0"))
        except ValueError as exc:
            error.update(str(exc))
            return
        station = self.query_one("#station", Select).value
        plan = self.query_one("#plan", Select).value
        if not tab_allows_plan(plan):
            error.update(f"the {plan} plan binds every interface of the server: not from a browser tab")
            return
        config = replace(self.config, roles=roles, team=team, station=station, teams=None, plan=plan,
                         legacy=self.query_one("#legacy", Checkbox).value)
        self.dismiss(config)

    def action_cancel(self) -> None:
        self.dismiss(None)
