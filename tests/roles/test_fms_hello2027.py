"""Our FMS and the 2027 FIRST Driver Station (issue 29, item 4): a hello (TCP tag 30) is
answered with the hello reply (tag 31) in place of station info, control goes to the port the
hello named, and game data goes as tag 32 of that DS's control packets instead of TCP tag 28.
The NI DS's login is unchanged beside it. Byte layouts: docs/protocol.md#cheesy-2027."""

from __future__ import annotations

import json

from protocol.ds_to_fms import DsHello, DsPing
from protocol.enums import AllianceStation, StationStatus
from protocol.fms_to_ds import (ChallengeQuestion, EventCode, GameData, GameDataTag, HelloReply, StationInfo,
                                decode_control)
from roles.cores.core import Close, Datagram, StreamSend
from roles.runtime.field import Field as RealField
from roles.runtime.field import FieldConfig
from roles.sim.simnet import SimNetwork

from .test_fms import T0, TEAMS, Field, texts

# team 254, control to UDP 1121 (0x0461), no flags
HELLO_254 = bytes.fromhex("0008 1e 0461 00 03") + b"254"


def hello(f: Field, team: int | str, conn, port: int = 1121, peer=None) -> list:
    """Open ``conn`` and log in with a 2027 hello for ``team`` (a number, or the text as sent)."""
    f.open(conn, peer or (f"127.{int(team) // 100}.{int(team) % 100}.5" if str(team).isdigit() else "127.0.0.9",
                          50000))
    text = str(team)
    data = DsHello(port, 0, text).encode()
    if text == "254" and port == 1121:
        assert data == HELLO_254
    return f.tcp(conn, data)


def test_a_2027_hello_is_answered_with_the_hello_reply_and_no_challenge():
    f = Field()
    replies = hello(f, 254, "c")
    # 00 06 1f station status flags team_hi team_lo: R1, good, not FMS Lite (fieldbox's FMS
    # sends to 1121, a full FMS's port), team 254
    assert replies[0].data == bytes.fromhex("0006 1f 00 00 00 00fe")
    frames = f.frames_to("c", replies)
    assert frames == [HelloReply(AllianceStation.RED1, StationStatus.GOOD, 0, 254), EventCode("FIELDBOX")]
    assert not any(isinstance(m, (StationInfo, ChallengeQuestion)) for m in frames)
    st = f.fms.station("R1")
    assert st.tcp_connected and st.login.status == "good" and st.login.ds_kind == "2027 DS"
    assert "R1 (254): DS logged in from 127.2.54.5:50000 (2027 DS)" in texts(f.fms)


def test_a_2027_station_enables_in_the_match_without_a_challenge():
    f = Field()
    for team in TEAMS[1:]:
        f.login(team)
    hello(f, 254, ("fms-tcp", 254))
    f.hosts[254] = "127.2.54.5"
    f.run_until(T0 + 1.0)
    f.fms.start_match(f.now)
    f.run_until(T0 + 2.0)
    (_, pkt, dest) = f.controls("R1")[-1]
    assert pkt.enabled and dest == ("127.2.54.5", 1121)
    assert f.fms.station("R1").commands.enabled


def test_control_goes_to_the_port_the_hello_named():
    f = Field()
    hello(f, 254, "c", port=40001)
    f.poll(T0 + 0.5)
    assert f.controls("R1")[-1][2] == ("127.2.54.5", 40001)
    f.login(118, conn="n")  # the NI DS beside it: its 1121, as before
    f.poll(T0 + 1.0)
    assert f.controls("B1")[-1][2] == ("127.1.18.5", 1121)


def test_game_data_goes_to_a_2027_ds_as_tag_32_and_to_an_ni_ds_on_tcp():
    f = Field(game_data="LRL")
    frames = f.frames_to("c", hello(f, 254, "c"))
    assert GameData("LRL") not in frames  # no TCP tag 28 for the 2027 DS
    f.login(118, conn="n")
    f.poll(T0 + 0.5)
    r1 = [a for _, a in f.sent if isinstance(a, Datagram) and decode_control(a.data).station == AllianceStation.RED1]
    assert r1 and r1[-1].data.endswith(bytes.fromhex("04 20") + b"LRL")  # [n + 1][0x20][text]
    assert decode_control(r1[-1].data).game_data == "LRL"
    assert f.controls("B1")[-1][1].game_data is None  # the NI DS's packets carry no tag
    f.fms.set_game_data("RBL", f.now)
    out = f.poll()
    assert {a.conn: f.frames_to(a.conn, [a]) for a in out if isinstance(a, StreamSend)} == {"n": [GameData("RBL")]}
    assert f.controls("R1")[-1][1].game_data == "RBL"


def test_game_data_longer_than_a_tag_holds_is_cut_for_the_2027_ds_and_said():
    f = Field()
    hello(f, 254, "c")
    f.fms.set_game_data("ABCDEFGHIJ", f.now)
    f.poll(T0 + 0.5)
    assert f.controls("R1")[-1][1].game_data == "ABCDEFGH"
    assert any("2027 DS gets its first 8" in text for text in texts(f.fms))


def test_a_hello_for_a_team_not_in_the_match_waits_and_is_placed_when_its_match_is_loaded():
    f = Field()
    replies = hello(f, 9999, "w")
    assert [a.data for a in replies] == [bytes.fromhex("0006 1f 00 02 00 270f")]  # R1, waiting, team 9999
    assert "w" in f.fms.logins.connections
    f.tcp("w", DsPing().encode())
    f.fms.set_team("B2", 9999, f.now)
    frames = f.frames_to("w", f.poll())
    assert frames[0] == HelloReply(AllianceStation.BLUE2, StationStatus.GOOD, 0, 9999)
    assert f.fms.station("B2").login.ds_kind == "2027 DS"


def test_a_hello_whose_team_is_not_a_number_or_port_0_gets_status_2_and_is_closed():
    f = Field()
    f.open("x", ("127.0.0.9", 50000))
    out = f.tcp("x", DsHello(1121, 0, "25a").encode())
    assert [a.data for a in out if isinstance(a, StreamSend)] == [bytes.fromhex("0006 1f 00 02 00 0000")]
    assert any(isinstance(a, Close) for a in out) and "x" not in f.fms.logins.connections
    assert f.fms.logins.tcp_stats.bad_packets == 1
    f.open("y", ("127.2.54.5", 50001))  # a team, but no port for its control: the same
    out = f.tcp("y", DsHello(0, 0, "254").encode())
    assert [a.data for a in out if isinstance(a, StreamSend)] == [bytes.fromhex("0006 1f 00 02 00 00fe")]
    assert "y" not in f.fms.logins.connections and f.fms.logins.tcp_stats.bad_packets == 2
    assert f.fms.station("R1").login.conn is None


def test_the_snapshot_and_the_view_say_which_ds_each_station_has():
    f = Field()
    hello(f, 254, "c")
    f.login(118, conn="n")
    snap = f.fms.snapshot(f.now)
    json.dumps(snap)
    by_station = {s["station"]: s for s in snap["stations"]}
    assert by_station["R1"]["ds_kind"] == "2027 DS" and by_station["B1"]["ds_kind"] == "NI DS"
    assert by_station["R2"]["ds_kind"] is None


def test_our_2027_ds_on_our_fms_enables_and_gets_its_game_data_on_the_fake_clock():
    net = SimNetwork()
    seen: list[tuple[str, str, bytes]] = []
    net.taps.append(lambda r: seen.append((r.role, r.kind, bytes(r.data))) if r.direction == "out" else None)
    field = RealField(FieldConfig(teams=list(TEAMS), plan="ephemeral", ds_hello="2027"))
    field.start_sim(net)
    fms = field.fms
    net.command("fms", lambda: fms.set_game_data("LRL", net.now))
    net.run_for(3.0)
    assert all(st.ds.fms.status == "good" and st.ds.fms.hello_reply is not None for st in field.stations)
    assert all(s.login.ds_kind == "2027 DS" for s in fms.stations)
    net.command("fms", lambda: fms.start_match(net.now))
    net.run_for(1.0)
    assert all(st.rio.control.enabled and st.rio.inputs.game_data == "LRL" for st in field.stations)
    hellos = [data for role, kind, data in seen if kind == "ds-to-fms-tcp" and data[2:3] == b"\x1e"]
    assert len(hellos) == 6 and not [d for _, k, d in seen if k == "ds-to-fms-tcp" and d[2:3] == b"\x18"]
    assert not [d for _, k, d in seen if k == "fms-to-ds-tcp" and d[2:3] in (b"\x19", b"\x1c")]
