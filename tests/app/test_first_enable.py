"""A newcomer's first enable works (issue 31, item 3): ``fieldbox`` with no options starts a
field the keys drive, the first screen (the DS tab's note) says who enables the robot, and under an FMS the first
``e`` says at once that the FMS decides, never inviting a second press that would be refused."""

from __future__ import annotations

from fieldbox.cli import build_parser
from fieldbox.headless import config_from_args

from .helpers import SIZE, Harness, text_of


def _default(*extra: str):
    """What ``fieldbox --team 254 ...`` starts (the team only names the packets in the test)."""
    return config_from_args(build_parser().parse_args(["--team", "254", *extra]))


async def test_the_default_start_is_driven_from_the_keys_and_says_so():
    config = _default()
    assert config.roles == {"ds", "rio"}
    h = Harness(config)
    async with h.app.run_test(size=SIZE) as pilot:
        await pilot.pause()
        h.run(1.0)
        await pilot.pause()
        assert "Ready: press e twice to enable" in text_of(h.app, "#ds-note")
        await pilot.press("e", "e")
        h.run(0.5)
        assert h.engine.field.stations[0].ds.enabled and h.wire.last_control().enabled


async def test_under_an_fms_the_first_e_says_the_fms_decides():
    h = Harness(_default("--roles", "ds,rio,fms"))
    async with h.app.run_test(size=SIZE) as pilot:
        await pilot.pause()
        h.run(1.5)  # the DS logs in; the FMS's control packets attach it
        await pilot.pause()
        assert "The FMS decides enable" in text_of(h.app, "#ds-note")
        assert h.engine.field.stations[0].ds.fms.attached
        await pilot.press("e")
        assert "an FMS is attached: it decides enable" in h.messages[-1]
        assert not any("Press e again" in m for m in h.messages)
        await pilot.press("e")
        h.run(0.5)
        assert not h.wire.last_control().enabled


def _offered(app) -> set[str]:
    """The actions the footer offers now."""
    return {active.binding.action for active in app.screen.active_bindings.values() if active.enabled}


async def test_under_an_fms_the_ds_tab_offers_no_key_the_fms_would_refuse():
    """Enable, the mode and a practice run are the FMS's while it is attached: the tab's key
    hints and the footer leave out e e, t a s and p (Enter and Space stay); without an FMS they
    are there."""
    alone = Harness(_default())
    async with alone.app.run_test(size=SIZE) as pilot:
        await pilot.pause()
        alone.run(1.0)
        await pilot.pause()
        hints = alone.app.query_one("#ds-keys").render().plain
        assert "t a s" in hints and "practice" in hints and "e e" in hints
        assert {"mode('teleop')", "practice", "enable"} <= _offered(alone.app)
        assert not [b.id for b in alone.app.query("Button") if b.disabled]
    h = Harness(_default("--roles", "ds,rio,fms"))
    async with h.app.run_test(size=SIZE) as pilot:
        await pilot.pause()
        h.run(1.5)  # the DS logs in; the FMS's control packets attach it
        await pilot.pause()
        assert h.engine.field.stations[0].ds.fms.attached
        hints = h.app.query_one("#ds-keys").render().plain
        assert "t a s" not in hints and "practice" not in hints and "e e" not in hints
        assert "Enter" in hints and "Space" in hints and "restart code" in hints
        offered = _offered(h.app)
        assert not {"mode('teleop')", "mode('auto')", "mode('test')", "practice"} & offered
        assert "restart_code" in offered and "enable" not in offered
        from textual.widgets import Button

        greyed = {b.id for b in h.app.query(Button) if b.disabled}
        assert {"ds-mode-teleop", "ds-mode-auto", "ds-mode-test", "ds-enable-btn", "ds-practice-btn"} <= greyed
        assert not {"ds-disable-btn", "ds-estop-btn", "ds-restart-btn"} & greyed
        await pilot.press("t")  # pressed anyway: said why, and the mode stays the FMS's
        await pilot.pause()
        assert any("an FMS is attached: it decides the mode" in m for m in h.messages)
