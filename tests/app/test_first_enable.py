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
