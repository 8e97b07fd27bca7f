"""Every tab at three sizes: a small SSH window (80x24), the usual (120x40) and a big screen
(200x60), on a SimEngine advanced through the same story, so every figure is the same each run.

The story: team 254 with its roboRIO and the FMS; the match starts, the battery sags, the link
to the robot is delayed and then loses packets for a few seconds, then all is well again
(fault_seed fixes which packets go). The Driver Station tab and the FMS tab show a full field
of six instead (the team row, the six stations), and the Legacy tab the 2010 mode.

Update with ``pytest tests/app/test_snapshots_sizes.py --snapshot-update`` and look at the SVGs
under tests/app/__snapshots__/test_snapshots_sizes/ first (an 80x24 one shows what an SSH
user sees: the tables keep their key columns, the footer keeps Space, Enter and ctrl+q).
"""

from __future__ import annotations

import random
import time
import types

import pytest

from roles.runtime.field import FieldConfig

from fieldbox.app import panel_classes

from .helpers import make_app, step

pytestmark = pytest.mark.usefixtures("no_real_joysticks", "the_same_world")  # no real joystick or user theme


@pytest.fixture
def the_same_world(monkeypatch):
    """What a fake clock does not fix: the FMS's challenge numbers (seeded as fault_seed seeds
    the faults) and the console's wall-clock times (a fixed instant, in UTC)."""
    import roles.cores.fms
    import fieldbox.panels.console

    monkeypatch.setattr(roles.cores.fms, "random", types.SimpleNamespace(
        Random=lambda seed=None: random.Random(20 if seed is None else seed)))
    monkeypatch.setattr(fieldbox.panels.console, "time", types.SimpleNamespace(
        time=lambda: 1_795_000_000.0, strftime=time.strftime, localtime=time.gmtime))

SIZES = {"80x24": (80, 24), "120x40": (120, 40), "200x60": (200, 60)}
TABS = [cls.ID for cls in panel_classes()]
FIELD = [254, 1114, 2056, 118, 148, 1678]


def config_for(tab: str) -> FieldConfig:
    if tab in ("ds", "fms"):
        return FieldConfig(teams=FIELD, fault_seed=20)
    if tab == "legacy":
        return FieldConfig(team=294, legacy=True, roles=frozenset({"ds", "rio"}))
    return FieldConfig(team=254, fault_seed=20)


async def live(pilot, seconds: float) -> None:
    """Run the field ``seconds``, refreshed every 100 ms as the app's timer does (the charts
    sample twice a second from that refresh)."""
    app = pilot.app
    for _ in range(round(seconds / 0.1)):
        app.engine.advance(0.1)
        app.refresh_views()
    await pilot.pause()


async def the_story(pilot, tab: str) -> None:
    app = pilot.app
    await step(pilot, 2.0)  # links up, logins done
    if tab == "legacy":
        await pilot.press("e", "e")
        app.refresh_views()  # the enable seen now, not whenever the app's own timer runs
        await live(pilot, 3.0)
    else:
        app.run_command("match start")  # 15 s of the 20 s of auto go by
        await live(pilot, 3.0)
        app.run_command("battery 11.4")
        await live(pilot, 3.0)
        app.run_command("fault ds-rio:delay=12ms")
        await live(pilot, 3.0)
        app.run_command("fault ds-rio:loss=30%")
        await live(pilot, 2.0)
        app.run_command("fault clear")
        app.run_command("battery 12.2")
        await live(pilot, 2.0)
    app.action_show_tab(tab)
    await live(pilot, 1.0)
    await live(pilot, 1.0)  # a tab's first picture comes after its size is known (the timeline)
    app.clear_notifications()  # a toast would cover a corner
    await pilot.pause()


@pytest.mark.parametrize("size", list(SIZES))
@pytest.mark.parametrize("tab", TABS)
def test_every_tab_at_three_sizes(snap_compare, tab, size):
    app, _ = make_app(config_for(tab), "ds")

    async def run_before(pilot) -> None:
        await the_story(pilot, tab)

    assert snap_compare(app, terminal_size=SIZES[size], run_before=run_before)


def test_the_timeline_on_a_projector(snap_compare):
    """The timeline in the high-contrast light theme a classroom projector needs, one packet
    picked (its summary under the lanes)."""
    app, _ = make_app(config_for("timeline"), "ds", theme_name="projector-light")

    async def run_before(pilot) -> None:
        await the_story(pilot, "timeline")
        await pilot.press("p", "up", "up", "up")

    assert snap_compare(app, terminal_size=(120, 40), run_before=run_before)
