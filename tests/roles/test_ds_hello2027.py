"""Our DS logging in as the 2027 FIRST Driver Station (issue 29, item 4): the hello (TCP 0x1e)
in place of the team number, the hello reply (0x1f) taken as station info is, and game data
from tag 0x20 of the FMS's control packets. Byte layouts: docs/protocol.md#cheesy-2027."""

from __future__ import annotations

import asyncio
import time

import pytest

from protocol import ds_to_rio, fms_to_ds
from protocol.ds_to_fms import DsPing, LogData
from protocol.enums import AllianceStation, Mode, StationStatus
from protocol.fms_to_ds import GameData, GameDataTag, HelloReply
from roles.cores.ds_fms import FmsClient, WAITING_REDIAL
from roles.runtime.field import Field, FieldConfig
from roles.runtime.shell import Runtime

from .cheesy_fms import CheesyLikeFms
from .test_ds import Harness, make_ds
from .test_ds_fms import FMS_TCP, FMS_UDP, FakeFms, LOGIN_254, fms_frames

# Cheesy Arena's 2027 hello (field/driver_station_connection.go at 1612d071):
# [size u16][0x1e][UDP reply port u16][flags u8][team length u8][team as ASCII]:
# team 254, control to port 1121 (0x0461), no flags.
HELLO_254 = bytes.fromhex("0008 1e 0461 00 03") + b"254"


def field_2027(seconds: float = 1.0) -> tuple[Harness, FakeFms]:
    h = Harness(make_ds(fms_tcp=FMS_TCP, fms_udp=FMS_UDP, fms_hello="2027"))
    h.tcp_up["fms-tcp"] = True
    h.run(seconds)
    return h, FakeFms(h)


def test_the_2027_ds_logs_in_with_its_hello_and_the_ni_ds_stays_the_default():
    h, _ = field_2027()
    assert h.tcp_frames("fms-tcp")[0] == HELLO_254
    assert any("as a 2027 DS (control to UDP 1121)" in text for _, text in h.ds.events.items)
    ni = Harness(make_ds(fms_tcp=FMS_TCP, fms_udp=FMS_UDP))
    ni.tcp_up["fms-tcp"] = True
    ni.run(1.0)
    assert ni.tcp_frames("fms-tcp")[0] == LOGIN_254


def test_the_hello_names_the_port_the_ds_was_given():
    h = Harness(make_ds(fms_tcp=FMS_TCP, fms_udp=FMS_UDP, fms_hello="2027"))
    h.ds.fms.hello_port = 40001  # as the field sets it when the OS chose the port
    h.tcp_up["fms-tcp"] = True
    h.run(1.0)
    assert h.tcp_frames("fms-tcp")[0] == bytes.fromhex("0008 1e 9c41 00 03") + b"254"


def test_a_bad_hello_choice_is_refused_in_words():
    with pytest.raises(ValueError, match="hello must be one of ni, 2027"):
        FmsClient(lambda: None, None, FMS_TCP, FMS_UDP, hello="2026")  # type: ignore[arg-type, return-value]


def test_the_hello_reply_is_taken_as_station_info():
    h, fms = field_2027()
    assert h.ds.fms.status == "connected"
    # 00 06 1f station status flags team_hi team_lo: B2 (4), good, FMS Lite, team 254
    fms.tcp(bytes.fromhex("0006 1f 04 00 01 00fe"))
    assert h.ds.fms.status == "good"
    assert h.ds.fms.hello_reply == HelloReply(AllianceStation.BLUE2, StationStatus.GOOD, 1, 254)
    texts = [text for _, text in h.ds.events.items]
    assert "FMS: hello answered for team 254 (FMS Lite)" in texts and "FMS: station B2: good" in texts
    fms.tcp(bytes.fromhex("0006 1f 01 01 00 00fe"))  # R2, bad: the wrong station
    assert h.ds.fms.status == "wrong station"
    assert any("the FMS expects team 254 at R2" in text for text in [t for _, t in h.ds.events.items])


def test_a_2027_ds_answered_waiting_goes_quiet_and_logs_in_again_with_its_hello():
    h, fms = field_2027()
    fms.online = False
    fms.tcp(bytes.fromhex("0006 1f 00 02 00 00fe"))  # R1, waiting (Cheesy: a team not in the match)
    assert h.ds.fms.status == "waiting"
    before, t0 = len(h.tcp_frames("fms-tcp")), h.t
    h.run(WAITING_REDIAL - 0.1)
    assert len(h.tcp_frames("fms-tcp")) == before  # no keep-alive, no log data while waiting
    assert not [d for t, d in h.datagrams if d.channel == "fms-out" and t > t0]
    h.run(0.2)
    frames = h.tcp_frames("fms-tcp")
    assert len(frames) == before + 1 and frames[-1] == HELLO_254  # the same hello, on a new login
    fms.tcp(bytes.fromhex("0006 1f 04 00 00 00fe"))  # placed: B2, good
    h.run(3.5)
    kinds = {type(m) for m in fms_frames(h)[before + 1:]}
    assert h.ds.fms.status == "good" and DsPing in kinds and LogData in kinds


def test_game_data_comes_from_the_control_packets_tag_32_and_reaches_the_robot():
    h, fms = field_2027()
    fms.tcp(bytes.fromhex("0006 1f 04 00 00 00fe"))
    fms.set(tags=(GameDataTag("LRL"),), enabled=True, mode=Mode.TELEOP)
    h.run(1.2)  # three more packets, each with the tag
    assert h.ds.fms.attached and h.ds.fms.game_data == "LRL"
    robot = [ds_to_rio.decode_tcp(f) for f in h.tcp_frames("robot-tcp")]
    assert robot.count(ds_to_rio.GameData("LRL")) == 1  # once, not once per control packet
    fms.set(tags=(GameDataTag("RRR"),))
    h.run(0.05)
    robot = [ds_to_rio.decode_tcp(f) for f in h.tcp_frames("robot-tcp")]
    assert robot[-1] == ds_to_rio.GameData("RRR")


def test_an_ni_ds_takes_game_data_from_tcp_only():
    # The NI DS path is unchanged: tag 0x20 is the 2027 DS's; frame 0x1c is the NI DS's.
    h = Harness(make_ds(fms_tcp=FMS_TCP, fms_udp=FMS_UDP))
    h.tcp_up["fms-tcp"] = True
    h.run(1.0)
    fms = FakeFms(h)
    fms.tcp(fms_to_ds.StationInfo(AllianceStation.BLUE2))
    fms.set(tags=(GameDataTag("LRL"),))
    h.run(1.0)
    assert h.ds.fms.attached and h.ds.fms.game_data is None
    fms.tcp(GameData("RLR"))
    assert h.ds.fms.game_data == "RLR"


# -- on real sockets, with an FMS that behaves as Cheesy Arena's 2027 path -------------------
async def test_our_2027_ds_logs_in_to_a_cheesy_like_fms_and_its_robot_enables():
    # Cheesy Arena's "new DS" path (commit 1612d071): the hello answered with B2, good, FMS
    # Lite; game data as tag 32 in its control packets, to the port the hello named
    fms = CheesyLikeFms("127.0.100.78", station=AllianceStation.BLUE2, game_data="LRL")
    await fms.start()
    runtime = Runtime()
    field = Field(FieldConfig(roles=frozenset({"ds", "rio"}), team=9974, plan="loopback", fms=fms.host,
                              ds_hello="2027"))
    try:
        await field.start(runtime)
        runtime.start()
        st = field.stations[0]
        assert st.rio is not None and st.ds is not None
        deadline = time.monotonic() + 10
        while time.monotonic() < deadline and not (st.rio.control.enabled and st.rio.inputs.game_data):
            await asyncio.sleep(0.05)
        # team 9974 ("9974"), control to 1121 (0x0461), no flags; from the DS's own address
        assert fms.logins[0] == (bytes.fromhex("0009 1e 0461 00 04") + b"9974", 9974, ("127.99.74.5", 1121))
        assert st.ds.fms.status == "good" and st.ds.station == AllianceStation.BLUE2
        assert st.ds.fms.hello_reply is not None and st.ds.fms.hello_reply.fms_lite
        assert st.ds.fms.attached and st.rio.control.enabled and st.rio.control.fms_attached
        assert st.rio.inputs.game_data == "LRL"  # from tag 32, through the DS to the robot
    finally:
        await runtime.close()
        await fms.close()


def test_the_command_line_chooses_the_hello_and_refuses_it_for_a_2010_ds():
    from fieldbox.cli import build_parser
    from fieldbox.headless import config_from_args

    parse = build_parser().parse_args
    assert config_from_args(parse(["--roles", "ds", "--team", "254"])).ds_hello == "ni"
    assert config_from_args(parse(["--roles", "ds", "--team", "254", "--ds-hello", "2027"])).ds_hello == "2027"
    with pytest.raises(ValueError, match="not with --legacy-2010"):
        config_from_args(parse(["--roles", "ds", "--ds-hello", "2027", "--legacy-2010"]))
    field = Field(FieldConfig(roles=frozenset({"ds"}), team=254, plan="ephemeral", fms="127.0.0.1",
                              ds_hello="2027"))
    from roles.sim.simnet import SimNetwork

    field.start_sim(SimNetwork())
    ds = field.stations[0].ds
    assert ds is not None and ds.fms.hello == "2027"
    assert ds.fms.hello_port == field.bound["ds 254"]["fms"][1]  # the port the OS gave, named in the hello
