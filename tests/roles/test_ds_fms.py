"""The Driver Station's FMS client: login, keep-alive, status, and obeying the field."""

from __future__ import annotations

import dataclasses

import pytest
from hypothesis import assume, given
from hypothesis import strategies as st

from protocol import ds_to_fms, ds_to_rio, fms_to_ds
from protocol.ds_to_fms import (ChallengeResponse, CommsMetrics, DsPing, LogData, TeamNumber,
                                challenge_answer, decode_status)
from protocol.ds_to_rio import Countdown
from protocol.enums import AllianceStation, MatchType, Mode, StationStatus, TournamentLevel
from protocol.errors import ProtocolError
from protocol.fms_to_ds import ChallengeQuestion, EventCode, FmsControlPacket, GameData, StationInfo
from roles.cores.core import CommandError
from roles.cores.ds_fms import PING_PERIOD, STATUS_PERIOD

from .test_ds import ROBOT_HOST, Harness, make_ds

FMS_HOST = "127.0.100.5"
FMS_TCP = (FMS_HOST, 1750)
FMS_UDP = (FMS_HOST, 1160)

# PROTOCOL-NOTES "A TCP connection whose first frame is not a team-number frame
# (00 03 18 hi lo) is closed": team 254 = 0x00fe.
LOGIN_254 = bytes.fromhex("0003 18 00fe")


class FakeFms:
    """Sends control packets from the FMS host every 500 ms (PROTOCOL-NOTES) and TCP frames
    on demand."""

    def __init__(self, h: Harness) -> None:
        self.h = h
        self.pkt = FmsControlPacket(mode=Mode.AUTONOMOUS, station=AllianceStation.BLUE2,
                                    tournament_level=TournamentLevel.QUALIFICATION, match_number=12,
                                    play_number=1, remaining_seconds=0)
        self.seq = 0
        self.online = True
        self.source = (FMS_HOST, 50123)
        self.channel = "fms"  # port 1121; "fms-lite" is port 1120
        self.timer = h.every(0.5, self.send)

    def set(self, **kw) -> None:
        self.pkt = dataclasses.replace(self.pkt, **kw)
        self.send(self.h.t)  # and at once on a phase change, as a real FMS does

    def send(self, t: float) -> None:
        if self.online:
            self.seq = (self.seq + 1) & 0xFFFF
            data = dataclasses.replace(self.pkt, sequence=self.seq).encode()
            self.h.handle(self.h.ds.datagram(self.channel, data, self.source, t))

    def tcp(self, *frames) -> None:
        data = b"".join(f if isinstance(f, bytes) else f.encode() for f in frames)
        self.h.handle(self.h.ds.stream_data("fms-tcp", data, self.h.t))


def field(fms_up: bool = True, seconds: float = 1.0, **kw) -> tuple[Harness, FakeFms]:
    h = Harness(make_ds(fms_tcp=FMS_TCP, fms_udp=FMS_UDP, **kw))
    h.tcp_up["fms-tcp"] = fms_up
    h.run(seconds)
    return h, FakeFms(h)


def fms_frames(h: Harness) -> list:
    return [ds_to_fms.decode_tcp(f) for f in h.tcp_frames("fms-tcp")]


# -- login, challenge, keep-alive, status ----------------------------------------------------
def test_login_is_the_first_frame_and_the_challenge_is_answered():
    h, fms = field()
    frames = h.tcp_frames("fms-tcp")
    assert frames[0] == LOGIN_254
    fms.tcp(ChallengeQuestion("Coolest robot EVER!!??", 1234))
    # (254 * 1234) % 23 = 15: "Opportunity" (PROTOCOL-NOTES' list)
    assert h.tcp_frames("fms-tcp")[-1] == bytes.fromhex("000c 1b") + b"Opportunity"
    assert h.tcp_frames("fms-tcp")[-1] == ChallengeResponse(challenge_answer(254, 1234)).encode()
    assert h.ds.fms.challenges_answered == 1


def test_pings_log_data_and_udp_status_go_out_on_their_own_schedules():
    h, fms = field()
    opened = [t for t, c in h.connects if c == "fms-tcp"][0]
    h.run(12.0)
    msgs = fms_frames(h)
    assert isinstance(msgs[0], TeamNumber)
    pings = [m for m in msgs if isinstance(m, DsPing)]
    logs = [m for m in msgs if isinstance(m, LogData)]
    assert len(pings) == int((h.t - opened) / PING_PERIOD)
    assert pings[0].encode() == bytes.fromhex("0001 1d")  # Cheesy Arena's and open-ds's keep-alive
    assert len(logs) == int((h.t - opened) / 3.0)
    rec = logs[-1].records[0]
    assert rec.battery == 12.5 and rec.lost_packets == 0 and rec.ds_disabled and not rec.ds_auto
    assert rec.trip_time_ms in (0, 1)  # a 0.5 ms round trip, in whole ms
    status = [(t, d) for t, d in h.datagrams if d.channel == "fms-out"]
    times = [t for t, _ in status]
    assert all(d.dest == FMS_UDP and d.kind == "ds-to-fms" for _, d in status)
    # on a 500 ms grid from the login (the first one as soon as the DS is polled)
    slots = [(t - opened) / STATUS_PERIOD for t in times]
    assert [round(k) for k in slots] == list(range(len(times)))
    assert all(abs(k - round(k)) < 0.002 for k in slots)
    pkt = decode_status(status[-1][1].data)
    assert pkt.team == 254 and pkt.robot_comms and pkt.rio_ping and pkt.radio_ping
    assert pkt.battery == 12.5 and not pkt.estop
    metrics = pkt.tag(CommsMetrics)
    assert metrics.lost_packets == 0 and metrics.average_trip_time_ms in (0, 1)
    assert 0 < metrics.sent_packets <= h.ds.link.echoes.sent_packets
    assert pkt.sequence == len(status) - 1


def test_log_data_carries_the_round_trip_as_the_comms_tag_does():
    # Issue 18: a 32 ms round trip went out as 63 in the log data (twice the figure).
    h = Harness(make_ds(fms_tcp=FMS_TCP, fms_udp=FMS_UDP), latency=0.032)
    h.tcp_up["fms-tcp"] = True
    h.run(7.0)
    assert h.ds.trip_ms == pytest.approx(32.0)
    log = [f for f in h.tcp_frames("fms-tcp") if f[2] == 0x16][-1]
    assert log[3] == 32  # the trip byte: the round trip in ms
    status = decode_status([d for _, d in h.datagrams if d.channel == "fms-out"][-1].data)
    assert status.tag(CommsMetrics).average_trip_time_ms == 32 == ds_to_fms.decode_tcp(log).records[0].trip_time_ms


def test_station_info_is_shown_in_state():
    h, fms = field()
    assert h.ds.fms.status == "connected"
    fms.tcp(StationInfo(AllianceStation.RED1, StationStatus.WAITING))
    assert h.ds.fms.status == "waiting"
    fms.tcp(StationInfo(AllianceStation.BLUE2, StationStatus.BAD))
    assert h.ds.fms.status == "wrong station"
    assert any("wrong station" in text and "B2" in text for _, text in h.ds.events.items)
    fms.tcp(StationInfo(AllianceStation.BLUE2, StationStatus.GOOD), EventCode("CMPTX"))
    assert h.ds.fms.status == "good" and h.ds.fms.event_code == "CMPTX"


def test_control_on_the_fms_lite_port_attaches_as_on_1121():
    # PROTOCOL-NOTES "How a real FMS behaves": UDP 1121, or 1120 in "FMS Lite" mode; a DS
    # listens on both (the shell binds channel "fms-lite" on 1120).
    h, fms = field()
    fms.channel = "fms-lite"
    fms.set(enabled=True)
    h.run(0.1)
    assert h.ds.fms.attached and h.ds.enabled and h.last_control().fms_attached
    assert h.ds.stats["fms-udp"].packets_in >= 1


def test_fms_tcp_is_retried_every_second():
    h, fms = field(fms_up=False)
    h.run(3.0)
    times = [t for t, c in h.connects if c == "fms-tcp"]
    assert [round(b - a, 3) for a, b in zip(times, times[1:])] == [1.0] * (len(times) - 1)
    assert len(times) == 5 and h.ds.fms.status == "connecting"
    assert not [d for _, d in h.datagrams if d.channel == "fms-out"]


# -- obeying the FMS --------------------------------------------------------------------------
def test_fms_control_is_obeyed_and_sent_to_port_1115_with_the_fms_bit():
    h, fms = field()
    h.ds.set_joystick(0, 1, 1, 0, h.t)
    fms.tcp(EventCode("CMPTX"), GameData("LRL"))
    fms.set(enabled=True, remaining_seconds=15)
    h.run(0.1)
    ds = h.ds
    assert ds.fms.attached and ds.enabled and ds.mode == Mode.AUTONOMOUS and ds.station == AllianceStation.BLUE2
    pkt = h.last_control()
    assert pkt.fms_attached and pkt.enabled and pkt.mode == Mode.AUTONOMOUS
    assert pkt.control_byte == 0x08 | 0x04 | 0x02
    assert pkt.station == AllianceStation.BLUE2
    assert [t for t in pkt.tags if isinstance(t, Countdown)] == [Countdown(15.0)]
    assert h.robot.dests[-1] == (ROBOT_HOST, 1115)
    robot_msgs = [ds_to_rio.decode_tcp(f) for f in h.tcp_frames("robot-tcp")]
    assert ds_to_rio.MatchInfo("CMPTX", MatchType.QUALIFICATION, 12, 1) in robot_msgs
    assert ds_to_rio.GameData("LRL") in robot_msgs
    with pytest.raises(CommandError, match="FMS"):
        ds.enable(h.t)
    with pytest.raises(CommandError, match="FMS"):
        ds.set_mode(Mode.TELEOP, h.t)
    with pytest.raises(CommandError, match="FMS"):
        ds.set_station("R1", h.t)
    with pytest.raises(CommandError, match="FMS"):
        ds.start_practice(h.t)
    fms.set(mode=Mode.TELEOP, remaining_seconds=135)
    h.run(0.5)
    assert h.last_control().mode == Mode.TELEOP
    assert decode_status([d for _, d in h.datagrams if d.channel == "fms-out"][-1].data).enabled
    fms.set(enabled=False, remaining_seconds=0)
    h.run(0.05)
    assert not h.last_control().enabled
    assert not [t for t in h.last_control().tags if isinstance(t, Countdown)]


def test_fms_estop_latches_through_fms_enable_and_detach():
    h, fms = field()
    fms.set(enabled=True)
    h.run(0.1)
    fms.set(estop=True, enabled=False)
    h.run(0.1)
    assert h.ds.arbiter.estopped and h.last_control().estop
    fms.set(estop=False, enabled=True)
    h.run(1.0)
    assert not h.ds.enabled and h.last_control().estop and not h.last_control().enabled
    fms.online = False
    h.run(1.5)
    assert not h.ds.fms.attached and h.ds.arbiter.estopped and h.last_control().estop
    with pytest.raises(CommandError, match="e-stopped"):
        h.ds.enable(h.t)
    status = decode_status([d for _, d in h.datagrams if d.channel == "fms-out"][-1].data)
    assert status.estop


def test_local_estop_works_under_the_fms():
    h, fms = field()
    fms.set(enabled=True)
    h.run(0.1)
    h.ds.estop(h.t)
    h.run(0.05)
    assert h.last_control().estop and not h.last_control().enabled


def test_astop_disables_auto_until_teleop():
    h, fms = field()
    fms.set(enabled=True)
    h.run(0.2)
    fms.set(astop=True)
    h.run(0.2)
    assert not h.ds.enabled and not h.last_control().enabled
    fms.set(astop=False)  # a-stop latches until auto ends
    h.run(0.5)
    assert not h.ds.enabled
    fms.set(mode=Mode.TELEOP)
    h.run(0.1)
    assert h.ds.enabled and h.last_control().enabled and h.last_control().mode == Mode.TELEOP


def test_fms_loss_disables_detaches_and_needs_a_fresh_enable():
    h, fms = field()
    fms.set(enabled=True, mode=Mode.TELEOP)
    h.run(0.5)
    assert h.last_control().enabled
    fms.online = False
    h.run(0.9)
    assert h.ds.fms.attached
    h.run(0.7)
    assert not h.ds.fms.attached and not h.ds.enabled
    pkt = h.last_control()
    assert not pkt.fms_attached and not pkt.enabled and h.robot.dests[-1] == (ROBOT_HOST, 1110)
    assert any("FMS lost" in text for _, text in h.ds.events.items)
    assert h.ds.station == AllianceStation.RED1  # local control again
    h.run(0.5)
    assert not h.last_control().enabled
    h.ds.enable(h.t)
    h.run(0.05)
    assert h.last_control().enabled


def test_fms_tcp_closing_detaches_at_once():
    h, fms = field()
    fms.set(enabled=True, mode=Mode.TELEOP)
    h.run(0.2)
    h.open.discard("fms-tcp")
    h.handle(h.ds.stream_closed("fms-tcp", "peer closed", h.t))
    assert not h.ds.fms.attached and not h.ds.enabled
    assert h.ds.fms.status == "connecting"


def test_operator_disable_under_the_fms_holds_until_the_fms_changes_phase():
    h, fms = field()
    fms.set(enabled=True, mode=Mode.AUTONOMOUS)  # auto
    h.run(0.2)
    h.ds.disable(h.t)
    h.run(1.0)
    assert not h.last_control().enabled and h.ds.fms.attached
    # A disabled packet mid-period (an a-stop looks the same) is not a change of phase: once
    # enabled again in the same period, the robot stays held.
    fms.set(enabled=False)
    h.run(0.5)
    fms.set(enabled=True)
    h.run(0.5)
    assert h.ds.fms.hold_disabled and not h.last_control().enabled
    fms.set(enabled=False, mode=Mode.TELEOP)  # the pause: auto is over, the hold with it
    h.run(0.5)
    assert not h.ds.fms.hold_disabled
    fms.set(enabled=True)  # teleop enables again
    h.run(0.1)
    assert h.last_control().enabled


def test_a_hold_begun_while_the_fms_disables_ends_when_the_next_period_enables():
    h, fms = field()
    fms.set(enabled=False, mode=Mode.TELEOP)  # the pause
    h.run(0.2)
    h.ds.disable(h.t)
    h.run(0.6)
    assert h.ds.fms.hold_disabled
    fms.set(enabled=True)  # teleop: a new period
    h.run(0.1)
    assert h.last_control().enabled and not h.ds.fms.hold_disabled
    # Another match (its number) is a new phase too.
    h.ds.disable(h.t)
    fms.set(match_number=13, enabled=False, mode=Mode.AUTONOMOUS)
    h.run(0.1)
    assert not h.ds.fms.hold_disabled


def test_a_forged_disabled_packet_from_the_fms_host_does_not_end_the_operators_hold():
    # The attack of issue 17: under a running match, one "disabled" packet from the FMS's
    # address (another port: any program on the FMS's machine can send it) cleared the hold,
    # and the real FMS's next packet enabled the robot again.
    h, fms = field()
    fms.set(enabled=True, mode=Mode.TELEOP)
    h.run(0.2)
    h.ds.disable(h.t)
    h.run(0.1)
    forged = dataclasses.replace(fms.pkt, sequence=999, enabled=False).encode()
    before = h.ds.fms.foreign_packets
    h.handle(h.ds.datagram("fms", forged, (FMS_HOST, 40404), h.t))
    assert h.ds.fms.foreign_packets == before + 1 and h.ds.stats["fms-udp"].foreign_packets >= 1
    assert any(f"FMS control from {FMS_HOST}:40404 refused: its FMS is {FMS_HOST}:50123" in text
               for _, text in h.ds.events.items)
    h.run(2.0)  # the real FMS keeps saying "enabled"
    assert h.ds.fms.attached and h.ds.fms.hold_disabled and not h.last_control().enabled
    # Even from the FMS's own socket, a disabled packet mid-period keeps the hold.
    h.handle(h.ds.datagram("fms", forged, fms.source, h.t))
    h.run(1.0)
    assert h.ds.fms.hold_disabled and not h.last_control().enabled


def test_control_is_taken_from_one_socket_per_login_the_fms_udp_port_first():
    h, fms = field()
    fms.set(enabled=False)  # from port 50123 (as Cheesy Arena, on a port of the OS's)
    assert h.ds.fms.control_source == fms.source and h.ds.fms.attached
    fms.source = (FMS_HOST, 1160)  # from the FMS's 1160 (fieldbox's FMS): followed from now on
    fms.set(mode=Mode.TELEOP)
    assert h.ds.fms.control_source == FMS_UDP and h.ds.mode == Mode.TELEOP
    before = h.ds.fms.foreign_packets
    h.handle(h.ds.datagram("fms", dataclasses.replace(fms.pkt, enabled=True).encode(), (FMS_HOST, 50123), h.t))
    assert h.ds.fms.foreign_packets == before + 1 and not h.ds.enabled
    # A new login starts over: the first control packet's port again.
    h.open.discard("fms-tcp")
    h.handle(h.ds.stream_closed("fms-tcp", "peer closed", h.t))
    h.run(1.1)
    assert h.ds.fms.control_source is None and h.ds.fms.fms_host == FMS_HOST


def test_foreign_fms_packets_are_logged_at_most_once_a_second():
    h, fms = field()
    for i in range(50):
        h.handle(h.ds.datagram("fms", fms.pkt.encode(), ("127.9.9.9", 5000 + i), h.t + i * 0.02))
    refused = [text for _, text in h.ds.events.items if "refused" in text]
    assert h.ds.fms.foreign_packets == 50 and len(refused) == 1
    assert refused[0].startswith("FMS control from 127.9.9.9:5000 refused")
    h.handle(h.ds.datagram("fms", fms.pkt.encode(), ("127.9.9.9", 1), h.t + 1.5))
    refused = [text for _, text in h.ds.events.items if "refused" in text]
    assert len(refused) == 2 and refused[1].endswith("(and 49 more since the last report)")


def test_fms_addresses_can_change_and_be_turned_off():
    h, fms = field()
    fms.set(enabled=True, mode=Mode.TELEOP)
    h.run(0.2)
    h.ds.set_fms_addresses(None, None, h.t)
    h.run(0.1)
    assert not h.ds.fms.attached and not h.ds.enabled and h.ds.fms.status == "off"
    assert any(c.conn == "fms-tcp" for c in h.closes)
    n = len(h.connects)
    h.run(3.0)
    assert len(h.connects) == n
    h.tcp_up["fms-tcp"] = True
    h.ds.set_fms_addresses(FMS_TCP, FMS_UDP, h.t)
    h.run(0.1)
    assert h.ds.fms.status == "connected"


def test_foreign_fms_packets_are_counted_and_dropped():
    h, fms = field()
    fms.source = ("127.0.100.6", 50123)
    fms.set(enabled=True)
    h.run(1.0)
    assert not h.ds.fms.attached and not h.ds.enabled
    assert h.ds.fms.foreign_packets >= 3
    assert h.ds.stats["fms-udp"].packets_in == 0


def test_fms_control_is_ignored_until_logged_in_over_tcp():
    h, fms = field(fms_up=False)
    fms.set(enabled=True)
    h.run(1.0)
    assert not h.ds.fms.attached and h.ds.fms.ignored_packets >= 2


def test_a_ds_without_an_fms_counts_every_fms_packet_as_foreign():
    h = Harness(make_ds())
    h.handle(h.ds.datagram("fms", FmsControlPacket(enabled=True).encode(), (FMS_HOST, 1), h.t))
    assert h.ds.fms.foreign_packets == 1 and not h.ds.fms.attached and h.ds.fms.status == "off"


def test_a_team_change_logs_in_again():
    h, fms = field()
    h.ds.set_team(1114, h.t)
    h.run(1.1)
    logins = [f for f in h.tcp_frames("fms-tcp") if f[2] == 0x18]
    assert logins == [LOGIN_254, bytes.fromhex("0003 18 045a")]
    assert any(c.conn == "fms-tcp" for c in h.closes)


def test_fms_framing_error_closes_the_fms_connection_only():
    h, fms = field()
    fms.tcp(bytes.fromhex("7fff 19"))
    assert [c.conn for c in h.closes] == ["fms-tcp"]
    assert h.ds.tcp.state == "open" and h.ds.stats["fms-tcp"].bad_packets == 1


def test_a_whole_match_on_the_fake_clock():
    h, fms = field()
    fms.tcp(StationInfo(AllianceStation.BLUE2, StationStatus.GOOD))
    fms.set(enabled=False, mode=Mode.AUTONOMOUS, remaining_seconds=15)
    h.run(2.0)
    fms.set(enabled=True, remaining_seconds=15)
    for left in range(15, 0, -1):
        fms.set(remaining_seconds=left)
        h.run(1.0)
        assert h.last_control().enabled
    fms.set(enabled=False, mode=Mode.TELEOP, remaining_seconds=3)
    h.run(3.0)
    fms.set(enabled=True, remaining_seconds=135)
    h.run(135.0)
    assert h.last_control().enabled and h.last_control().mode == Mode.TELEOP
    fms.set(enabled=False, remaining_seconds=0)
    h.run(1.0)
    assert not h.ds.enabled and h.ds.link.echoes.lost_packets == 0 and h.ds.fms.status == "good"


# -- bad input --------------------------------------------------------------------------------
def _state(ds):
    snap = ds.snapshot()
    snap.pop("bad_packets")
    snap.pop("fms_refused")  # what was refused last: a foreign packet is shown (and nothing else)
    f = ds.fms
    return (snap, f.control, f.attached, f.station_info, f.event_code, f.game_data, f.astop_active,
            f.tcp_state, ds.tcp.match_info, ds.tcp.game_data)


def _undecodable(decode, data: bytes) -> bool:
    try:
        decode(data)
    except ProtocolError:
        return True
    return False


@given(st.binary(max_size=60))
def test_random_bytes_from_the_fms_host_are_counted_and_change_nothing(data):
    assume(_undecodable(fms_to_ds.decode_control, data))
    h, fms = field(seconds=0.1)
    fms.set(enabled=True, mode=Mode.TELEOP)
    before, bad = _state(h.ds), h.ds.stats["fms-udp"].bad_packets
    h.handle(h.ds.datagram("fms", data, fms.source, h.t))
    assert _state(h.ds) == before and h.ds.stats["fms-udp"].bad_packets == bad + 1


@given(st.binary(max_size=60), st.sampled_from(["10.0.0.1", "127.0.100.50", "::1"]))
def test_any_bytes_from_a_foreign_host_change_nothing(data, host):
    h, fms = field(seconds=0.1)
    before = _state(h.ds)
    h.handle(h.ds.datagram("fms", data, (host, 1121), h.t))
    assert _state(h.ds) == before and h.ds.fms.foreign_packets == 1
    assert h.ds.snapshot()["fms_refused"].startswith(f"FMS control from {host} refused: ")


@given(st.binary(min_size=1, max_size=200))
def test_any_fms_tcp_bytes_never_raise(data):
    h, fms = field(seconds=0.1)
    fms.tcp(data)
    assert h.ds.link.robot_comms


@given(st.sampled_from([0x00, 0x07, 0x14, 0x19, 0x1A, 0x1C]), st.binary(max_size=30))
def test_undecodable_fms_tcp_frames_are_counted_and_change_nothing(tag, payload):
    frame = (len(payload) + 1).to_bytes(2, "big") + bytes((tag,)) + payload
    assume(_undecodable(fms_to_ds.decode_tcp, frame))
    h, fms = field(seconds=0.1)
    before, bad = _state(h.ds), h.ds.stats["fms-tcp"].bad_packets
    fms.tcp(frame)
    assert _state(h.ds) == before and h.ds.stats["fms-tcp"].bad_packets == bad + 1


# -- a DS that logs in before its match is loaded ------------------------------------------
class CheesyLikeFms:
    """An FMS that treats a waiting login as Cheesy Arena does (field/
    driver_station_connection.go, 2026; PROTOCOL-NOTES "Cheesy Arena's waiting"): the login of
    a team not in the loaded match is answered with station status 2 (``00 03 19 00 02``),
    then the connection is only read, each read with a 5 s deadline, and closed when one
    fails; it is never assigned to the match. A login once the match is loaded gets the
    team's station (``00 03 19 04 00``: B2, good) and control packets every 500 ms."""

    READ_DEADLINE = 5.0

    def __init__(self, h: Harness) -> None:
        self.h = h
        self.match_loaded = False
        self.state = None  # None (no connection), "waiting" or "placed"
        self.seen = 0  # bytes of the DS's stream already read
        self.last_read = 0.0
        self.logins: list[tuple[float, bool]] = []  # (when, placed)
        self.udp_while_waiting = 0
        self.answered = 0.0
        self.control = FmsControlPacket(mode=Mode.AUTONOMOUS, station=AllianceStation.BLUE2, enabled=False)
        h.on_fms_tcp = self.opened
        h.every(0.05, self.tick)

    def opened(self, t: float) -> None:
        self.state, self.last_read = "login", t  # (the login frame is read at the next tick)

    def tick(self, t: float) -> None:
        h = self.h
        if "fms-tcp" not in h.open:
            self.state = None
            return
        stream = b"".join(h.streams.get("fms-tcp", []))
        new, self.seen = stream[self.seen:], len(stream)
        if new:
            self.last_read = t
        if self.state == "login" and new.startswith(bytes.fromhex("0003 18")):
            placed = self.match_loaded
            self.logins.append((t, placed))
            self.state, self.answered = ("placed" if placed else "waiting"), t
            h.handle(h.ds.stream_data("fms-tcp", bytes.fromhex("0003 19 04 00" if placed else "0003 19 00 02"), t))
        elif self.state == "waiting" and t - self.last_read >= self.READ_DEADLINE:
            h.open.discard("fms-tcp")  # the read deadline passed: Cheesy closes the connection
            self.state = None
            h.handle(h.ds.stream_closed("fms-tcp", "closed by the FMS", t))
        elif self.state == "placed" and round(t / 0.05) % 10 == 0:
            h.handle(h.ds.datagram("fms", self.control.encode(), (FMS_HOST, 50123), t))
        if self.state == "waiting":  # status after the answer (one goes with each login)
            self.udp_while_waiting += sum(1 for when, d in h.datagrams
                                          if d.channel == "fms-out" and when > max(t - 0.05, self.answered))


def test_a_waiting_ds_joins_its_match_within_6_s_of_the_load():
    """Issue 29: with Cheesy Arena a DS that logged in before its match was loaded stayed
    "waiting" for good (its keep-alives kept the drained connection open), and the match
    could not start. Quiet while waiting, it is in within the FMS's read deadline."""
    h = Harness(make_ds(fms_tcp=FMS_TCP, fms_udp=FMS_UDP))
    h.tcp_up["fms-tcp"] = True
    fms = CheesyLikeFms(h)
    h.run(17.0)  # before the match: still waiting, a login every 5 s, never a storm of them
    assert h.ds.fms.status == "waiting"
    assert all(not placed for _, placed in fms.logins) and len(fms.logins) == 4
    assert fms.udp_while_waiting == 0  # nothing for an FMS to log as "no DS for this packet"
    loaded = h.t
    fms.match_loaded = True
    h.run(6.0)
    assert h.ds.fms.status == "good"
    (joined, placed), = [login for login in fms.logins if login[1]]
    assert joined - loaded <= 6.0
    assert h.ds.fms.attached  # and obeying the field's control packets
    # placed, it reports again: keep-alive and log data on TCP, status on UDP
    h.run(3.5)
    kinds = {type(ds_to_fms.decode_tcp(f)) for f in h.tcp_frames("fms-tcp")[-4:]}
    assert DsPing in kinds and LogData in kinds
    assert any(d.channel == "fms-out" for t, d in h.datagrams if t > joined)


def test_a_waiting_login_sends_nothing_until_it_is_placed_on_the_same_connection():
    """fieldbox's FMS places a waiting DS when its match is loaded, on the open connection."""
    h, fms = field()
    fms.online = False
    fms.tcp(StationInfo(AllianceStation.RED1, StationStatus.WAITING))
    before, t0 = len(h.tcp_frames("fms-tcp")), h.t
    h.run(4.0)
    assert len(h.tcp_frames("fms-tcp")) == before  # no keep-alive, no log data
    assert not [d for t, d in h.datagrams if d.channel == "fms-out" and t > t0]
    fms.tcp(StationInfo(AllianceStation.BLUE2, StationStatus.GOOD))
    h.run(3.5)
    assert h.ds.fms.status == "good" and "fms-tcp" in h.open
    assert len(h.tcp_frames("fms-tcp")) > before


def test_fms_control_from_another_address_is_refused_and_every_screen_says_so():
    # Issue 29: Cheesy Arena on one machine sends its control from 127.0.0.1 while the DS
    # dialled (and logged in to) 127.0.100.5. The DS refuses it, as it must, but its screens
    # said "FMS good" and the robot was silently never enabled.
    from fieldbox.headless import _ds_line, robot_report

    h, fms = field()
    fms.tcp(StationInfo(AllianceStation.BLUE2, StationStatus.GOOD))
    fms.source = ("127.0.0.1", 50123)
    fms.set(enabled=True, mode=Mode.TELEOP)
    h.run(1.0)
    view = h.ds.view(h.t)
    assert view.fms.status == "good" and not view.fms.attached and not h.last_control().enabled
    words = "FMS control from 127.0.0.1 refused: this DS obeys only the FMS it logged in to, at 127.0.100.5"
    assert (view.fms.refused_from, view.fms.refused) == ("127.0.0.1", words)
    assert view.snapshot()["fms_refused"] == words  # headless --json
    assert _ds_line({**view.snapshot(), **robot_report(view)}).endswith(f"| FMS good | {words}")
    # Once that FMS stops sending, nothing is being refused any more.
    fms.online = False
    h.run(2.5)
    assert h.ds.view(h.t).fms.refused is None
    assert not _ds_line({**h.ds.view(h.t).snapshot(), **robot_report(h.ds.view(h.t))}).count("refused")


def test_an_fms_estop_reads_fms_estop_for_the_rest_of_the_match_then_robot_still_estopped():
    # Issue 29: the FMS's station e-stop read "DS e-stopped", and the DS's own words ("held
    # disabled until the FMS changes phase") were wrong after a restart and a phase change:
    # the FMS keeps the station e-stopped for the rest of the match.
    from fieldbox.headless import _ds_line, robot_report

    h, fms = field()
    fms.set(enabled=True, mode=Mode.AUTONOMOUS)
    h.run(0.2)
    fms.set(estop=True, enabled=False)
    h.run(0.1)
    fms_words = "FMS e-stop: the FMS holds this station e-stopped for the rest of the match"
    view = h.ds.view(h.t)
    assert view.arbiter.estopped and (view.estop_kind, view.estop_reason) == ("fms", fms_words)
    line = _ds_line({**view.snapshot(), **robot_report(view)})
    assert "E-STOPPED" in line and fms_words in line and "DS e-stopped" not in line
    latched = [text for _, text in h.ds.events.items if "E-STOP" in text]
    assert latched[-1].startswith("FMS E-STOP") and "rest of the match" in latched[-1]
    assert not any("changes phase" in text for text in latched)
    # A restart clears the DS's latch; the FMS's next packet e-stops it again, and a phase
    # change (auto to teleop) does not end it: the words stay true.
    h.ds.restart_code(h.t)
    h.run(1.0)
    fms.set(mode=Mode.TELEOP, enabled=True)
    h.run(1.0)
    view = h.ds.view(h.t)
    assert view.arbiter.estopped and not h.last_control().enabled and h.last_control().estop
    assert (view.estop_kind, view.estop_reason) == ("fms", fms_words)
    # The next match: the FMS no longer e-stops the station, the robot stays e-stopped (as a
    # real roboRIO does, until its code restarts), and the DS says so before the start.
    fms.set(match_number=13, estop=False, enabled=False, mode=Mode.AUTONOMOUS)
    h.run(1.0)
    view = h.ds.view(h.t)
    assert view.arbiter.estopped and view.estop_kind == "stale"
    assert view.estop_reason == "robot still e-stopped: restart its code"
    assert decode_status([d for _, d in h.datagrams if d.channel == "fms-out"][-1].data).estop  # the FMS hears it
    h.ds.restart_code(h.t)
    h.run(1.0)
    assert (h.ds.view(h.t).estop_kind, h.ds.view(h.t).estop_reason) == ("", "")


def test_the_operators_estop_that_the_fms_then_holds_is_not_called_the_fmss():
    # The operator's Space under an FMS: the FMS sees the DS's e-stop bit and e-stops the
    # station (ours and Cheesy Arena do). The FMS now holds it, but the screens must not say
    # the FMS e-stopped the robot ("FMS E-STOP" came from the kind alone).
    h, fms = field()
    fms.set(enabled=True, mode=Mode.TELEOP)
    h.run(0.2)
    h.ds.estop(h.t)
    h.run(0.1)
    fms.set(estop=True, enabled=False)
    h.run(0.6)
    view = h.ds.view(h.t)
    assert (view.estop_kind, view.estop_reason) == (
        "fms-held", "E-stop (operator): the FMS holds this station e-stopped for the rest of the match")


def test_the_operators_estop_reads_latched_then_robot_still_estopped_in_the_next_match():
    h, fms = field()
    fms.set(enabled=True, mode=Mode.TELEOP)
    h.run(0.2)
    h.ds.estop(h.t)
    h.run(0.1)
    assert h.ds.estop_kind == "latched" and "restart the robot code" in h.ds.estop_reason
    fms.set(match_number=13, enabled=False, mode=Mode.AUTONOMOUS)
    h.run(0.6)
    assert (h.ds.estop_kind, h.ds.estop_reason) == ("stale", "robot still e-stopped: restart its code")
