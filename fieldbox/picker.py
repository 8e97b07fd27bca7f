"""The role picker (F8): roles, team, station, network plan and 2010 mode, changed without
restarting the process.

A keyboard form, as the NI Driver Station's setup is: Tab and shift+Tab move, ``x`` ticks a
box or opens a list (Up and Down open one too), ctrl+s picks the highlighted choice of an open
list and otherwise applies (from any field), Esc cancels. Space and Enter stay the robot's
while it is open (fieldbox/app.py): Space e-stops and Enter disables, whatever field has the
focus. A mouse works too.
"""

from __future__ import annotations

from dataclasses import replace

from textual.app import ComposeResult
from textual.binding import Binding
from textual.containers import Horizontal, Vertical
from textual.screen import ModalScreen
from textual.widgets import Button, Checkbox, Input, Label, OptionList, Select, Static

from protocol.enums import AllianceStation
from roles.cores.addresses import PLANS, check_team
from roles.runtime.field import FieldConfig

from .serve import tab_allows_plan
from .widgets import TextBox, Tick


class RolePicker(ModalScreen[FieldConfig | None]):
    DEFAULT_CSS = """
    RolePicker { align: center middle; }
    RolePicker > Vertical { width: 68; max-width: 100%; height: auto; border: thick $primary;
                            padding: 0 1; background: $surface; }
    RolePicker .picker-row { height: auto; margin-top: 1; }
    RolePicker .picker-label { width: 9; padding: 1 1 0 0; }
    RolePicker Checkbox { width: auto; }
    RolePicker #team { width: 10; }
    RolePicker #station { width: 16; }
    /* the longest plan, "ephemeral", whole: at 16 it wrapped as "ephemera/l" */
    RolePicker #plan { width: 20; }
    RolePicker #station-label { width: auto; padding: 1 1 0 2; }
    RolePicker #picker-error { color: $error; height: auto; }
    RolePicker #picker-keys { color: $text-muted; height: auto; margin-top: 1; }
    RolePicker Button { margin-right: 2; }
    """
    BINDINGS = [
        Binding("escape", "cancel", "Cancel"),
        Binding("ctrl+s", "apply", "Apply", priority=True),
        # the form's Space and Enter: those are the robot's e-stop and disable
        Binding("x", "press", "Tick or open"),
    ]
    KEYS = "Tab moves · x ticks/opens · ctrl+s picks/applies · Esc cancels"

    def __init__(self, config: FieldConfig) -> None:
        super().__init__()
        self.config = config

    def compose(self) -> ComposeResult:
        c = self.config
        with Vertical():
            # the robot's keys work here too: said first, where the eye lands
            yield Label("[b]Roles and field[/b]  (F8)     robot: Space e-stops · Enter disables", id="picker-title")
            with Horizontal(classes="picker-row"):
                yield Label("Roles", classes="picker-label")
                yield Tick("Driver Station", "ds" in c.roles, id="role-ds")
                yield Tick("roboRIO", "rio" in c.roles, id="role-rio")
                yield Tick("FMS", "fms" in c.roles, id="role-fms")
            with Horizontal(classes="picker-row"):
                yield Label("Team", classes="picker-label")
                yield TextBox(str(c.team), id="team", type="integer", max_length=5)
                yield Label("Station", id="station-label")
                yield Select([(s.label, s) for s in AllianceStation], value=c.station, id="station",
                             allow_blank=False)
            with Horizontal(classes="picker-row"):
                yield Label("Network", classes="picker-label")
                # In a browser tab, only the plans the server was started to allow: "real"
                # binds every interface of the server (fieldbox/serve.py).
                plans = [p for p in PLANS if tab_allows_plan(p) or p == c.plan]
                yield Select([(p, p) for p in plans], value=c.plan, id="plan", allow_blank=False)
                yield Tick("2010 legacy", c.legacy, id="legacy")
            yield Label("", id="picker-error")
            with Horizontal(classes="picker-row"):
                yield Button("Apply  ctrl+s", variant="primary", id="apply")
                yield Button("Cancel  Esc", id="cancel")
            yield Static(self.KEYS, id="picker-keys")

    def on_mount(self) -> None:
        self.query_one("#role-ds", Checkbox).focus()

    def _open_list(self) -> OptionList | None:
        """The open list of choices (a Select's overlay, which has the focus then), or None."""
        focused = self.focused
        if isinstance(focused, OptionList) and isinstance(focused.parent, Select) and focused.parent.expanded:
            return focused
        return None

    def action_press(self) -> None:
        """``x``, what Space did in a form (it e-stops now): tick the box, open the list, press
        the button. (In an open list a letter jumps to a choice: Textual's, as before.)"""
        focused = self.focused
        if isinstance(focused, Checkbox):
            focused.toggle()
        elif isinstance(focused, Select):
            focused.action_show_overlay()
        elif isinstance(focused, Button):
            focused.press()

    def action_apply(self) -> None:
        """ctrl+s, what Enter did: the highlighted choice of an open list, else Apply."""
        choices = self._open_list()
        if choices is not None:
            choices.action_select()
            return
        config = self._config()
        if config is not None:
            self.dismiss(config)

    def on_button_pressed(self, event: Button.Pressed) -> None:
        event.stop()
        if event.button.id == "cancel":
            self.dismiss(None)
        else:
            self.action_apply()

    def _config(self) -> FieldConfig | None:
        """The form's configuration, or None with the reason shown."""
        roles = frozenset(r for r in ("ds", "rio", "fms") if self.query_one(f"#role-{r}", Checkbox).value)
        error = self.query_one("#picker-error", Label)
        if not roles:
            error.update("choose at least one role")
            return None
        try:
            team = check_team(int(self.query_one("#team", Input).value or "0"))
        except ValueError as exc:
            error.update(str(exc))
            self.query_one("#team", Input).focus()
            return None
        station = self.query_one("#station", Select).value
        plan = self.query_one("#plan", Select).value
        # Both are built with allow_blank=False: a choice is always made.
        assert isinstance(station, AllianceStation) and isinstance(plan, str)
        if not tab_allows_plan(plan):
            error.update(f"the {plan} plan binds every interface of the server: not from a browser tab")
            return None
        return replace(self.config, roles=roles, team=team, station=station, teams=None, plan=plan,
                       legacy=self.query_one("#legacy", Checkbox).value)

    def action_cancel(self) -> None:
        self.dismiss(None)
