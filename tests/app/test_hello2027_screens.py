"""The 2027 FIRST Driver Station on our FMS, as the screens show it (issue 29, item 4): the
FMS tab names each station's DS, and the inspector and the timeline decode the hello and its
reply (through protocol/, as every frame)."""

from __future__ import annotations

import pytest

from fieldbox.packet_text import summarize
from fieldbox.panels.inspector import InspectorPanel
from fieldbox.panels.timeline import TimelineView
from roles.runtime.field import FieldConfig

from .helpers import Harness, make_app, step

pytestmark = pytest.mark.usefixtures("no_real_joysticks")

ALL = frozenset({"ds", "rio", "fms"})


def cell(app, station: str, column: str) -> str:
    return str(app.query_one("#fms-stations").get_cell(station, column))


async def test_the_fms_tab_names_the_2027_ds_and_then_the_ni_ds_beside_it():
    app, engines = make_app(FieldConfig(team=254, roles=ALL, ds_hello="2027"), "fms")
    async with app.run_test(size=(160, 40)) as pilot:
        await step(pilot, 2.0)
        assert cell(app, "R1", "ds") == "● 2027 DS"
        assert engines[0].field.fms.station("R1").commands.enabled is False  # (no match yet)
    app, _ = make_app(FieldConfig(team=254, roles=ALL), "fms")  # the NI DS alone: its link, as ever
    async with app.run_test(size=(160, 40)) as pilot:
        await step(pilot, 2.0)
        assert cell(app, "R1", "ds") == "●"


async def test_the_inspector_decodes_the_2027_hello_and_its_reply():
    app, _ = make_app(FieldConfig(team=254, roles=ALL, ds_hello="2027"), "inspector")
    async with app.run_test(size=(120, 40)) as pilot:
        await step(pilot, 1.0)
        ring = app.query_one(InspectorPanel).ring
        hello = [p for k, ps in ring.links.items() if k[0] == "ds 254" and k[3] == "ds-to-fms-tcp" for p in ps]
        reply = [p for k, ps in ring.links.items() if k[3] == "fms-to-ds-tcp" and k[2] == "in" for p in ps]
        assert hello and reply
        port = app.engine.field.bound["ds 254"]["fms"][1]  # the OS's, on the SimEngine's plan
        assert summarize(hello[0].kind, hello[0].data) == f"ds_hello: udp_port {port} · flags 0x00 · team_text 254"
        assert summarize(reply[0].kind, reply[0].data) == "hello_reply: station R1 · status GOOD · flags 0x00 · team 254"


async def test_the_timeline_draws_the_hello_and_its_reply():
    h = Harness(FieldConfig(team=254, roles=ALL, ds_hello="2027"), "timeline")
    async with h.app.run_test(size=(160, 50)) as pilot:
        for _ in range(30):  # as the timeline's own tests run it: its picture settles
            h.run(0.1)
        await pilot.pause()
        view = h.app.query_one(TimelineView)
        names = {(hop.src, hop.dst, hop.name) for hop in view.hops}
        assert ("ds", "fms", "ds hello") in names and ("fms", "ds", "hello reply") in names
