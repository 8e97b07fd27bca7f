"""Whole fields: on the fake clock (a match in milliseconds) and over loopback sockets, six
teams each on their own 127.TE.AM.x addresses with the real ports."""

from __future__ import annotations

import asyncio
import time

from protocol import fms_to_ds
from protocol.enums import AllianceStation, Mode
from roles.field import Field, FieldConfig
from roles.shell import Runtime
from roles.simnet import SimNetwork

TEAMS = [254, 1114, 2056, 118, 148, 1678]


def test_full_match_on_the_fake_clock():
    net = SimNetwork()
    fms_packets = []
    net.taps.append(lambda role, link, d, kind, data, peer, now:
                    fms_packets.append((now, fms_to_ds.decode_control(data)))
                    if kind == "fms-to-ds" and d == "out" else None)
    field = Field(FieldConfig(teams=list(TEAMS), plan="ephemeral"))
    field.start_sim(net)
    wall = time.perf_counter()
    net.run_for(3.0)
    fms = field.fms
    assert all(st.ds.fms_status == "good" and st.ds.robot_comms for st in field.stations)
    assert fms.start_refusals() == []
    net.command("fms", lambda: fms.start_match(net.now))
    net.run_for(1.0)
    assert fms.phase.value == "auto"
    assert all(st.ds.enabled and st.ds.mode is Mode.AUTONOMOUS and st.rio.enabled for st in field.stations)
    net.run_for(20.0)  # into the pause
    assert fms.phase.value == "pause"
    assert not any(st.rio.enabled for st in field.stations)
    net.run_for(4.0)
    assert fms.phase.value == "teleop"
    assert all(st.rio.enabled and st.rio.mode is Mode.TELEOP for st in field.stations)
    # A station e-stop disables that robot within one FMS control packet (sent at once).
    blue2 = field.stations[4]
    net.command("fms", lambda: fms.estop(AllianceStation.BLUE2, net.now))
    t0 = net.now
    net.run_for(0.1)
    assert not blue2.rio.enabled and blue2.rio.estopped and blue2.ds.estopped
    assert all(st.rio.enabled for st in field.stations if st is not blue2)
    net.run_for(140.0)
    assert fms.phase.value == "post-match"
    assert not any(st.rio.enabled for st in field.stations)
    # The whole 167 s match took a fraction of that on the fake clock.
    assert time.perf_counter() - wall < 30
    # Remaining time counts the current period; control packets at least every 500 ms.
    teleop = [p for now, p in fms_packets if p.enabled and p.mode is Mode.TELEOP]
    assert max(p.remaining_seconds for p in teleop) == 140
    to_blue2 = [(now, p) for now, p in fms_packets if p.station is AllianceStation.BLUE2 and now >= t0]
    assert any(now - t0 < 0.01 and p.estop and not p.enabled for now, p in to_blue2)
    assert not any(st.ds.lost_packets for st in field.stations)
    assert not any(sum(s.bad_packets for s in st.ds.stats.values()) for st in field.stations)


async def test_full_field_over_loopback_sockets_on_team_addresses():
    runtime = Runtime()
    field = Field(FieldConfig(teams=list(TEAMS), plan="loopback"))
    try:
        await field.start(runtime)
        runtime.start()
        # Six teams, each on its own addresses with the real ports (DESIGN.md).
        assert field.bound["rio 254"]["ds"] == ("127.2.54.2", 1110)
        assert field.bound["rio 1678"]["tcp"] == ("127.16.78.2", 1740)
        assert field.bound["ds 1114"]["robot"] == ("127.11.14.5", 1150)
        assert field.bound["fms"]["udp"] == ("127.0.100.5", 1160)
        deadline = time.monotonic() + 10
        while time.monotonic() < deadline:
            if all(st.ds.robot_comms and st.ds.fms_status == "good" for st in field.stations):
                break
            await asyncio.sleep(0.05)
        assert [st.ds.fms_status for st in field.stations] == ["good"] * 6
        # Each DS's TCP login leaves from its own 127.TE.AM.5, where its status comes from
        # and its control packets go (the FMS takes status only from a station's login).
        assert [s.peer[0] for s in field.fms.stations] == \
            ["127.2.54.5", "127.11.14.5", "127.20.56.5", "127.1.18.5", "127.1.48.5", "127.16.78.5"]
        assert all(s.ds_address[0] == s.peer[0] and s.challenge == "right" for s in field.fms.stations)
        field.fms.set_timing(auto=1, pause=0.5, teleop=1)
        field.fms.start_match(runtime.clock())
        runtime.hosts["fms"].kick()
        await asyncio.sleep(0.5)
        assert all(st.rio.enabled and st.rio.mode is Mode.AUTONOMOUS for st in field.stations)
        await asyncio.sleep(2.5)
        assert field.fms.phase.value == "post-match"
        assert not any(st.rio.enabled for st in field.stations)
        assert all(st.ds.lost_packets == 0 for st in field.stations)
    finally:
        await runtime.close()
