"""The timeline (F6 F6): one exchange across the FMS, a DS and its roboRIO, from the inspector's
capture, on a SimEngine (issue 20, item 6)."""

from __future__ import annotations

import pytest

from roles.runtime.field import FieldConfig

from fieldbox.exchange import hops, split_summary
from fieldbox.panels.timeline import TimelinePanel, TimelineView, time_text

from .helpers import Harness, one_team

pytestmark = pytest.mark.usefixtures("no_real_joysticks")

SIZE = (160, 50)


def routes(view: TimelineView) -> set[tuple[str, str, str]]:
    return {(h.src, h.dst, h.packet.kind) for h in view.hops}


async def test_the_timeline_shows_every_link_between_the_three_lanes_in_time_order():
    h = Harness(FieldConfig(team=254), "timeline")
    async with h.app.run_test(size=SIZE) as pilot:
        for _ in range(30):
            h.run(0.1)
        await pilot.pause()
        view = h.app.query_one(TimelineView)
        assert routes(view) >= {("ds", "rio", "ds-to-rio"), ("rio", "ds", "rio-to-ds"),
                                ("fms", "ds", "fms-to-ds"), ("ds", "fms", "ds-to-fms"),
                                ("ds", "rio", "ds-to-rio-tcp"), ("rio", "ds", "rio-to-ds-tcp"),
                                ("fms", "ds", "fms-to-ds-tcp"), ("ds", "fms", "ds-to-fms-tcp")}
        times = [hop.time for hop in view.hops]
        assert times == sorted(times)
        # a control packet, then its echo a fraction of a millisecond later
        controls = {hop.name.split("#")[1]: hop for hop in view.hops if hop.name.startswith("control #")}
        echoes = [hop for hop in view.hops if hop.name.startswith("status #") and hop.name.split("#")[1] in controls]
        assert echoes and all(0 < e.time - controls[e.name.split("#")[1]].time < 0.005 for e in echoes)
        # several packets of each link on a tall screen, the 50 Hz link not drowning the others
        assert sum(1 for hop in view.hops if hop.packet.kind == "fms-to-ds") >= 3
        drawn = str(view.render())
        assert "FMS" in drawn.splitlines()[0] and "DS 254" in drawn and "roboRIO 254" in drawn
        assert "─ FMS control #" in drawn and "▶│" in drawn and "│◀" in drawn and "╌" in drawn  # TCP dashed


async def test_p_holds_the_picture_still_and_i_opens_the_packet_in_the_inspector():
    h = Harness(one_team(), "timeline")
    async with h.app.run_test(size=SIZE) as pilot:
        for _ in range(20):
            h.run(0.1)
        await pilot.pause()
        view = h.app.query_one(TimelineView)
        await pilot.press("p")
        held = [hop.packet.seq for hop in view.hops]
        h.run(3.0)
        assert [hop.packet.seq for hop in view.hops] == held  # still: a teacher talks it through
        await pilot.press("up", "up")
        picked = view.selected()
        assert picked is not None and picked is view.hops[-3]
        assert picked.name in str(h.app.query_one("#timeline-detail").render())
        await pilot.press("i")
        await pilot.pause()
        inspector = h.app.query_one("#panel-inspector")
        assert h.app.query_one("TabbedContent").active == "inspector"
        assert inspector.link == picked.packet.key and inspector.packets.selected().seq == picked.packet.seq
        await pilot.press("f6")  # F6 on the inspector goes on to the timeline
        await pilot.press("p")  # live again: a new picture
        h.run(1.0)
        assert [hop.packet.seq for hop in view.hops] != held


async def test_without_an_fms_its_lane_says_so_and_2010_mode_draws_the_dashboard_there():
    h = Harness(one_team(), "timeline")
    async with h.app.run_test(size=SIZE) as pilot:
        for _ in range(10):
            h.run(0.1)
        await pilot.pause()
        view = h.app.query_one(TimelineView)
        assert view.names["fms"] == "FMS (not here)" and all("fms" not in (hop.src, hop.dst) for hop in view.hops)
    h = Harness(FieldConfig(team=294, legacy=True, roles=frozenset({"ds", "rio"})), "timeline")
    async with h.app.run_test(size=SIZE) as pilot:
        for _ in range(10):
            h.run(0.1)
        await pilot.pause()
        view = h.app.query_one(TimelineView)
        assert view.names["fms"] == "dashboard"
        assert ("ds", "fms", "legacy-dashboard") in routes(view) and ("ds", "rio", "legacy-ds-to-robot") in routes(view)


def test_a_summary_becomes_an_arrows_name_and_what_else_it_says():
    assert split_summary("ControlPacket #612: no e-stop, enabled", "control") == ("control #612", "no e-stop, enabled")
    assert split_summary("stdout #3: text hi", "") == ("stdout #3", "text hi")
    assert split_summary("ds_ping", "") == ("ds ping", "")
    assert split_summary("BAD short | ControlPacket #1: x", "control") == ("control #1", "BAD short | x")
    assert time_text(-0.0196) == "-19.6 ms" and time_text(0.0) == " 0.0 ms" and time_text(-2.5) == "-2.50 s"


def test_hops_take_the_last_packets_of_each_link_of_one_role():
    from roles.runtime.engine import SimEngine

    from fieldbox.capture import CaptureRing

    engine = SimEngine(FieldConfig(team=254))
    ring = CaptureRing()
    engine.add_tap(ring.tap)
    engine.advance(3.0)
    ring.drain()
    got = hops(ring, "ds 254", 2)
    by_kind: dict[str, int] = {}
    for hop in got:
        by_kind[hop.packet.kind] = by_kind.get(hop.packet.kind, 0) + 1
        assert hop.packet.role == "ds 254"  # the DS's own taps: each packet once
    assert by_kind["ds-to-rio"] == 2 and by_kind["fms-to-ds"] == 2
    newest = ring.links[("ds 254", "robot", "out", "ds-to-rio")][-1]
    assert newest.seq in {hop.packet.seq for hop in got}
    assert hops(ring, None, 2) == []


def test_the_timeline_panel_is_f6_twice_and_in_the_palette():
    from fieldbox.app import tab_key_text

    assert TimelinePanel.ID == "timeline" and tab_key_text("timeline") == "F6 F6"
