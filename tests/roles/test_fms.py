"""The FMS core on a fake clock: logins, DS status, control packets, a whole match, the
station commands and bad input. Every byte it emits is decoded with protocol/."""

from __future__ import annotations

import datetime as dt
import json
import random

import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st
from hypothesis.stateful import RuleBasedStateMachine, invariant, rule

from protocol.ds_to_fms import (ChallengeResponse, CommsMetrics, DsStatusPacket,
                                ErrorEvent, ErrorEventData, LogData, LogRecord, TeamNumber,
                                challenge_answer, decode_status)
from protocol.enums import AllianceStation, Mode, StationStatus, TournamentLevel
from protocol.errors import ProtocolError
from protocol.fms_to_ds import (ChallengeQuestion, DeviceVersion, EventCode,
                                GameData, StationInfo, VersionDevice, decode_control, decode_tcp)
from protocol.framing import split_frames
from roles.cores.core import Close, CommandError, Datagram, StreamSend
from roles.cores.fms import (MAX_CONNECTIONS, MAX_FRAME, PER_HOST, UDP, FieldManagementSystem, MatchStartRefused,
                             team_from_address)
from roles.cores.match import MatchTiming, Phase

# -- vectors -------------------------------------------------------------------------------
# PROTOCOL-NOTES "How a real FMS behaves": the login and the station info replies.
LOGIN_254 = bytes.fromhex("0003 18 00fe")        # team number 254
WAITING = bytes.fromhex("0003 19 00 02")         # station info: R1, waiting (not in the match)
R1_GOOD = bytes.fromhex("0003 19 00 00")
R1_BAD = bytes.fromhex("0003 19 00 01")
B3_GOOD = bytes.fromhex("0003 19 05 00")
PING_1C = bytes.fromhex("0001 1c")               # DS ping as the notes send it
PING_1D = bytes.fromhex("0001 1d")               # ... as Cheesy Arena (2023+) expects it

TEAMS = [254, 1114, 2056, 118, 148, 1678]
WALL = dt.datetime(2024, 4, 20, 15, 30, 5, 250000, tzinfo=dt.timezone.utc)
T0 = 1000.0


def ds_address(team: int, host: int = 5) -> str:
    return f"127.{team // 100}.{team % 100}.{host}"


class Field:
    """An FMS and the DSes talking to it, on a fake clock; records what the FMS sends."""

    def __init__(self, teams=TEAMS, **kw) -> None:
        kw.setdefault("seed", 7)
        kw.setdefault("wall_clock", lambda: WALL)
        self.fms = FieldManagementSystem(teams, **kw)
        self.now = T0
        self.sent: list[tuple[float, object]] = []
        self.seq: dict[int, int] = {}
        self.hosts: dict[int, str] = {}  # team -> the host its login came from
        self.record(self.fms.poll(self.now))

    def record(self, actions) -> list:
        actions = list(actions)
        self.sent += [(self.now, a) for a in actions]
        return actions

    # -- a DS ------------------------------------------------------------------------------
    def open(self, conn, peer=None, team=None):
        peer = peer or (ds_address(team or 1), 50000)
        return self.record(self.fms.stream_opened(conn, peer, self.now))

    def tcp(self, conn, data: bytes):
        return self.record(self.fms.stream_data(conn, data, self.now))

    def login(self, team: int, conn=None, peer=None, answer: bool = True) -> list:
        """Open a connection and log in as ``team``; answer the challenge right, as our DS
        does (``answer=False``: leave it unanswered). Returns the login's replies."""
        conn = conn if conn is not None else ("fms-tcp", team)
        peer = peer or (ds_address(team), 50000)
        self.open(conn, peer)
        replies = self.tcp(conn, TeamNumber(team).encode())
        if conn in self.fms.logins.connections:
            self.hosts[team] = peer[0]
        question = [f for f in self.frames_to(conn, replies) if isinstance(f, ChallengeQuestion)]
        if answer and question:
            self.tcp(conn, ChallengeResponse(challenge_answer(team, question[-1].random_value)).encode())
        return replies

    def status(self, team: int, source=None, **fields):
        """A status packet from ``source``; by default from the host ``team`` logged in from."""
        seq = self.seq.get(team, 0)
        self.seq[team] = (seq + 1) & 0xFFFF
        fields.setdefault("robot_comms", True)
        fields.setdefault("battery", 12.5)
        data = DsStatusPacket(sequence=seq, team=team, **fields).encode()
        source = source or (self.hosts.get(team, ds_address(team)), 1145)
        return self.record(self.fms.datagram(UDP, data, source, self.now))

    def connect_all(self, teams=None):
        for team in teams or [t for t in TEAMS]:
            self.login(team)
            self.status(team)
        self.poll()

    # -- time --------------------------------------------------------------------------------
    def poll(self, now: float | None = None):
        if now is not None:
            self.now = now
        return self.record(self.fms.poll(self.now))

    def run_until(self, end: float, status_every: float | None = 0.25, teams=None):
        """Poll at every deadline, and send every DS's status every ``status_every`` s."""
        teams = [t for t in (teams if teams is not None else TEAMS)]
        next_status = self.now + status_every if status_every else None
        while True:
            deadline = self.fms.next_deadline()
            t = min(x for x in (deadline, next_status, end) if x is not None)
            self.now = max(self.now, t)
            if next_status is not None and self.now >= next_status:
                for team in teams:
                    self.status(team)
                    if ("fms-tcp", team) in self.fms.logins.connections:
                        self.tcp(("fms-tcp", team), PING_1C)  # the DS's TCP keep-alive
                next_status += status_every
            if deadline is not None and self.now >= deadline:
                self.poll()
            if self.now >= end and (deadline is None or deadline > end):
                break

    # -- what was sent -------------------------------------------------------------------------
    def controls(self, station="R1", since: float = float("-inf")):
        index = int(AllianceStation.parse(station))
        out = []
        for t, a in self.sent:
            if isinstance(a, Datagram) and t >= since:
                pkt = decode_control(a.data)
                if pkt.station == index:
                    out.append((t, pkt, a.dest))
        return out

    def frames_to(self, conn, actions=None):
        acts = actions if actions is not None else [a for _, a in self.sent]
        return [decode_tcp(f) for a in acts if isinstance(a, StreamSend) and a.conn == conn
                for f in split_frames(a.data)]


def texts(fms: FieldManagementSystem) -> list[str]:
    return [text for _, text in fms.events.items]


# -- login -------------------------------------------------------------------------------------
def test_login_of_a_team_in_the_match():
    f = Field()
    assert TeamNumber(254).encode() == LOGIN_254
    f.open("c1", ("127.2.54.5", 50000))
    replies = f.tcp("c1", LOGIN_254)
    assert all(isinstance(a, StreamSend) and a.conn == "c1" for a in replies)
    assert replies[0].data == R1_GOOD
    frames = f.frames_to("c1", replies)
    assert frames[:2] == [StationInfo(AllianceStation.RED1, StationStatus.GOOD), EventCode("FIELDBOX")]
    q = frames[2]
    assert isinstance(q, ChallengeQuestion) and len(frames) == 3
    # The challenge value comes from the injectable RNG: seeded 7, the first draw.
    assert q.random_value == random.Random(7).randint(1000, 2000)
    st_ = f.fms.station("R1")
    assert (st_.tcp_connected, st_.login.status, st_.login.challenge, st_.login.challenge_value) == (True, "good", "sent", q.random_value)
    assert "R1 (254): DS logged in from 127.2.54.5:50000" in texts(f.fms)


def test_login_sends_game_data_when_set_and_rng_is_injectable():
    f = Field(game_data="LRL", event_code="CAMA", rng=random.Random(99))
    frames = f.frames_to("c", f.login(1678, conn="c"))
    assert frames[0] == StationInfo(AllianceStation.BLUE3, StationStatus.GOOD)
    assert f.frames_to("c")[0].encode() == B3_GOOD
    assert frames[1:3] == [EventCode("CAMA"), GameData("LRL")]
    assert frames[3].random_value == random.Random(99).randint(1000, 2000)
    assert 1000 <= frames[3].random_value <= 2000


def test_team_not_in_the_match_waits_and_stays_connected():
    f = Field()
    replies = f.login(9999, conn="w", peer=("127.99.99.5", 50001))
    assert [a.data for a in replies] == [WAITING]
    assert "w" in f.fms.logins.connections and not any(isinstance(a, Close) for a in replies)
    # Keep-alives keep it; when it is put in the match it hears where it goes.
    f.poll(T0 + 3)
    f.tcp("w", PING_1C)
    f.fms.set_team("B2", 9999, f.now)
    out = f.poll()
    frames = f.frames_to("w", out)
    assert frames[0] == StationInfo(AllianceStation.BLUE2, StationStatus.GOOD)
    assert isinstance(frames[-1], ChallengeQuestion)
    assert f.fms.station("B2").tcp_connected
    # And taken out again, it is told to wait.
    f.fms.set_team("B2", None, f.now)
    assert [a.data for a in f.poll() if isinstance(a, StreamSend)] == [WAITING]
    assert not f.fms.station("B2").tcp_connected and "w" in f.fms.logins.connections


@pytest.mark.parametrize("peer", ["10.1.18.5", "127.1.18.5", "::ffff:10.1.18.7"])
def test_wrong_station_from_the_source_address(peer):
    f = Field()
    # Team 254 (R1) plugs in at team 118's station (B1): its address is 10.1.18.x.
    replies = f.login(254, conn="c", peer=(peer, 50000))
    assert replies[0].data == R1_BAD
    s = f.fms.station("R1")
    assert (s.login.status, s.login.wrong_station) == ("bad", AllianceStation.BLUE1)
    f.status(254)
    f.connect_all([t for t in TEAMS if t != 254])
    with pytest.raises(MatchStartRefused) as info:
        f.fms.start_match(f.now)
    assert info.value.reasons == ["R1 (254): DS at the wrong station (B1) and not bypassed"]


@pytest.mark.parametrize("peer", ["127.2.54.5", "10.2.54.9", "127.0.0.1", "10.99.99.5", "192.168.1.4",
                                  "127.0.100.5", "not an address"])
def test_addresses_that_do_not_name_another_station_are_good(peer):
    f = Field()
    assert f.login(254, conn="c", peer=(peer, 1))[0].data == R1_GOOD


def test_team_from_address():
    assert team_from_address("10.2.54.5") == 254
    assert team_from_address("127.11.14.2") == 1114
    assert team_from_address("10.0.9.1") == 9
    assert team_from_address("127.0.100.5") is None  # AM is 0-99: the FMS's own address
    assert team_from_address("127.0.0.1") is None
    assert team_from_address("192.168.2.54") is None
    assert team_from_address("::1") is None


@pytest.mark.parametrize("first", [
    PING_1C,                                  # a keep-alive before the login
    b"\x00\x00",                              # an empty keep-alive frame
    bytes.fromhex("0004 18 00fe 00"),         # a team number frame one byte too long
    bytes.fromhex("0003 19 0000"),            # an FMS frame sent back
    ChallengeResponse("Data").encode(),
])
def test_first_frame_not_a_login_is_closed_without_reply(first):
    f = Field()
    f.open("x", ("127.2.54.5", 1))
    out = f.tcp("x", first + LOGIN_254)
    assert out == [Close("x", "first frame is not a team number")]
    assert "x" not in f.fms.logins.connections and not f.fms.station("R1").tcp_connected
    assert f.fms.logins.tcp_stats.bad_packets == 1
    # The shell's close report afterwards changes nothing.
    assert f.fms.stream_closed("x", "closed", f.now) == []


def test_login_in_any_chunking():
    f = Field()
    f.open("c", ("127.2.54.5", 1))
    out = []
    for b in LOGIN_254 + PING_1D:
        out += f.tcp("c", bytes([b]))
    assert out[0].data == R1_GOOD and f.fms.station("R1").tcp_connected


def test_a_second_login_of_a_team_replaces_a_first_that_is_lost():
    f = Field()
    f.login(254, conn="old")
    f.poll(T0 + 1.0)  # no status for a second: lost, its connection still open
    out = f.login(254, conn="new")
    assert out[0] == Close("old", "replaced by a new login")
    assert out[1].data == R1_GOOD
    assert f.fms.station("R1").login.conn == "new" and "old" not in f.fms.logins.connections


def test_connections_are_bounded_per_host_and_in_all_and_the_oldest_silent_one_makes_room():
    f = Field()
    # One host holds at most PER_HOST: its next connection closes its oldest that never logged in.
    for i in range(PER_HOST):
        assert f.open(("a", i), ("127.9.9.9", 40000 + i)) == []
    assert f.open(("a", "next"), ("127.9.9.9", 1)) == \
        [Close(("a", 0), "evicted to make room for a new connection: it never logged in")]
    assert f.fms.logins.evicted_connections == 1
    # In all, at most MAX_CONNECTIONS: many hosts' silent connections make room the same way.
    for i in range(MAX_CONNECTIONS):
        f.open(("b", i), (f"127.9.8.{i}", 40000))
    assert len(f.fms.logins.connections) == MAX_CONNECTIONS
    # Connections that logged in and hold no station are not evicted for just anyone ...
    f2 = Field(max_connections=4)
    for i in range(4):
        f2.login(9000 + i, conn=("w", i), peer=(f"127.90.0.{i}", 1))
    assert f2.open("stranger", ("127.9.9.9", 1)) == [Close("stranger", "too many connections")]
    assert f2.fms.logins.refused_connections == 1
    # ... but a DS from its team's own address is always served, and no station's DS is evicted.
    f2.fms.set_team("B3", 9000, f2.now)
    out = f2.open("home", ("127.2.54.5", 1))
    assert out == [Close(("w", 1), "evicted to make room for a new connection: team 9001 holds no station")]
    assert "home" in f2.fms.logins.connections and ("w", 0) in f2.fms.logins.connections


# -- challenge -------------------------------------------------------------------------------------
def test_challenge_right_and_wrong_answers_and_only_the_first_counts():
    f = Field()
    q = f.frames_to("c", f.login(254, conn="c", answer=False))[-1]
    f.tcp("c", ChallengeResponse("Not A Robot").encode())
    s = f.fms.station("R1")
    assert s.login.challenge == "wrong" and s.login.challenge_answer == "Not A Robot"
    right = challenge_answer(254, q.random_value)
    assert any("WRONG challenge answer 'Not A Robot' from 127.2.54.5" in t and repr(right) in t
               for t in texts(f.fms))
    assert any("WRONG challenge" in t for _, t in f.fms.match_log)
    # 23 names cannot be tried one by one: a second answer, even the right one, is refused.
    f.tcp("c", ChallengeResponse(right).encode())
    assert s.login.challenge == "wrong" and f.fms.logins.challenge_failures == 2
    assert f"R1 (254): challenge answer {right!r} from 127.2.54.5 refused: only the first answer counts" \
        in texts(f.fms)
    assert f.fms.snapshot()["stations"][0]["challenge"] == "wrong"
    # A new login is a new question: answered right, the station is trusted.
    f.fms.stream_closed("c", "peer closed", f.now)
    f.login(254, conn="d")
    assert s.login.challenge == "right" and "R1 (254): challenge answered" in texts(f.fms)
    assert f.fms.snapshot()["stations"][0]["challenge"] == "right"


# -- keep-alive and link loss ----------------------------------------------------------------------
def test_keepalive_timeout_5s_and_both_ping_ids():
    f = Field()
    f.login(254, conn="c")
    f.poll(T0 + 4.9)
    f.tcp("c", PING_1C)                  # 0x1c keeps it alive
    f.poll(T0 + 9.8)
    f.tcp("c", PING_1D)                  # and so does 0x1d
    f.poll(T0 + 14.7)
    assert "c" in f.fms.logins.connections
    f.tcp("c", PING_1C[:2])              # a partial frame is not a frame
    assert f.fms.next_deadline() <= T0 + 9.8 + 5.0
    assert not any(isinstance(a, Close) for a in f.poll(T0 + 14.79))
    out = f.poll(T0 + 9.8 + 5.0)
    assert Close("c", "keep-alive timeout: no frame for 5 s") in out
    assert "c" not in f.fms.logins.connections and not f.fms.station("R1").tcp_connected
    assert any("R1 (254): DS disconnected (keep-alive timeout" in t for t in texts(f.fms))
    assert f.fms.stream_closed("c", "closed", f.now) == []


def test_udp_loss_after_1s():
    f = Field()
    f.login(254, conn="c")
    f.status(254)
    s = f.fms.station("R1")
    assert s.report.udp_link and s.ds_link and s.report.robot_link
    f.poll(T0 + 0.999)
    assert s.ds_link
    assert f.fms.next_deadline() == pytest.approx(T0 + 1.0)
    f.poll(T0 + 1.0)
    assert not s.report.udp_link and not s.ds_link and not s.report.robot_link
    assert "R1 (254): DS lost (no UDP status for 1 s)" in texts(f.fms)
    f.status(254)
    assert s.ds_link


def test_tcp_close_drops_the_ds_link():
    f = Field()
    f.login(254, conn="c")
    f.status(254)
    f.fms.stream_closed("c", "peer closed", f.now)
    s = f.fms.station("R1")
    assert not s.ds_link and s.report.udp_link and s.login.conn is None
    assert "R1 (254): DS disconnected (peer closed)" in texts(f.fms)
    f.poll(T0 + 0.5)
    assert f.controls("R1", since=T0 + 0.5) == []  # no login: no control packets


# -- UDP status ---------------------------------------------------------------------------------
def test_status_matched_by_team_number_from_its_logins_host_only():
    f = Field()
    f.login(254, conn="c", peer=("192.168.7.7", 50000))
    # The team number inside matches it to a station; the TCP login's host must send it (from
    # any port: a DS sends status from 1145 where it can, Cheesy Arena does not look).
    f.status(254, source=("192.168.7.7", 5555), robot_comms=True, radio_ping=True, rio_ping=True,
             battery=12.25, mode=Mode.AUTONOMOUS,
             tags=(CommsMetrics(lost_packets=3, sent_packets=400, average_trip_time_ms=7),))
    s = f.fms.station("R1")
    assert (s.report.robot_link, s.report.radio_ping, s.report.rio_ping, s.report.battery) == (True, True, True, 12.25)
    assert (s.report.trip_time_ms, s.report.lost_packets, s.report.sent_packets) == (7, 3, 400)
    assert s.report.ds_address == ("192.168.7.7", 5555) and s.report.ds_mode is Mode.AUTONOMOUS
    f.poll(T0 + 0.5)
    assert f.controls("R1")[-1][2] == ("192.168.7.7", 1121)
    # From anywhere else (the team's own loopback address included): counted, never obeyed.
    f.status(254, source=("127.2.54.5", 1145), battery=7.0, estop=True)
    assert (s.report.battery, s.report.ds_estop, s.link.foreign_packets, f.fms.refused_status) == (12.25, False, 1, 1)
    assert "status (e-stop) for 254 from 127.2.54.5 refused: its DS is 192.168.7.7" in texts(f.fms)
    # A team not in the match: ignored, counted.
    f.status(4444)
    assert f.fms.udp_unknown_team == 1


def test_ephemeral_plan_replies_to_the_source_port():
    f = Field(ds_port=None)
    f.login(254, conn="c", peer=("127.0.0.1", 50000))
    f.poll(T0 + 0.5)
    assert f.controls("R1") == []       # no UDP heard yet: nowhere to send
    f.status(254, source=("127.0.0.1", 61234))
    f.poll(T0 + 1.0)
    assert f.controls("R1")[-1][2] == ("127.0.0.1", 61234)


def test_control_packets_go_to_the_tcp_address_before_udp():
    f = Field()
    f.login(254, conn="c", peer=("10.2.54.5", 50000))
    f.poll()
    assert f.controls("R1")[-1][2] == ("10.2.54.5", 1121)


def test_lost_status_packets_counted_from_sequence_gaps():
    f = Field()
    f.login(254)
    f.status(254)
    f.seq[254] += 4
    f.status(254)
    assert f.fms.station("R1").link.lost_packets == 4


# -- TCP data kept per station ----------------------------------------------------------------------
def test_log_data_versions_and_error_events_kept():
    f = Field()
    f.login(254, conn="c")
    rec = LogRecord(trip_time_ms=9, lost_packets=2, battery=12.5, ds_auto=True, robot_auto=True)
    f.tcp("c", LogData((rec,)).encode()
          + DeviceVersion(VersionDevice.DS, "<good>", "24.0").encode()
          + ErrorEventData((ErrorEvent(100, 0, "Joystick unplugged"),)).encode())
    s = f.fms.station("R1")
    assert s.tcp.log_data == rec and list(s.tcp.log_records) == [rec]
    assert s.tcp.versions["Driver Station"].version == "24.0"
    assert [e.text for e in s.tcp.error_events] == ["Joystick unplugged"]
    snap = f.fms.snapshot()
    json.dumps(snap)
    assert snap["stations"][0]["versions"] == {"Driver Station": "24.0"}
    assert snap["stations"][0]["log_data"]["trip_time_ms"] == 9


# -- a whole match ----------------------------------------------------------------------------------------
def test_a_whole_match_on_a_fake_clock():
    f = Field(level=TournamentLevel.QUALIFICATION, match_number=12)
    f.connect_all()
    f.run_until(T0 + 2.0)
    pre = f.controls("R1")
    assert pre and all(not p.enabled and p.mode is Mode.AUTONOMOUS and p.remaining_seconds == 20
                       for _, p, _ in pre)
    assert (pre[-1][1].tournament_level, pre[-1][1].match_number, pre[-1][1].play_number) == \
        (TournamentLevel.QUALIFICATION, 12, 1)
    # The date block: the wall clock, as the seed encodes it (month 0-based).
    d = pre[-1][1].date
    assert (d.year, d.month, d.day, d.hour, d.minute, d.second, d.microseconds) == (124, 3, 20, 15, 30, 5, 250000)

    start = f.now = T0 + 2.1           # off the 500 ms grid on purpose
    f.fms.start_match(f.now)
    assert f.fms.next_deadline() <= f.now  # at once
    f.poll()
    f.run_until(start + 20 + 3 + 140 + 2)

    def at(t, station="R1"):
        return [p for when, p, _ in f.controls(station) if when == pytest.approx(t)]

    # At once on each phase change, exactly at the boundary.
    first = at(start)
    assert first and first[0].enabled and first[0].mode is Mode.AUTONOMOUS and first[0].remaining_seconds == 20
    pause = at(start + 20)
    assert pause and not pause[0].enabled and pause[0].mode is Mode.TELEOP and pause[0].remaining_seconds == 3
    teleop = at(start + 23)
    assert teleop and teleop[0].enabled and teleop[0].mode is Mode.TELEOP and teleop[0].remaining_seconds == 140
    end = at(start + 163)
    assert end and not end[0].enabled and end[0].mode is Mode.TELEOP and end[0].remaining_seconds == 0
    assert f.fms.phase is Phase.POST_MATCH

    # In between, every 500 ms on the grid (from the first poll at T0), counting down the
    # current period, rounded up.
    for when, p, _ in f.controls("R1", since=start):
        if when < start + 20:
            assert p.enabled and p.mode is Mode.AUTONOMOUS
            assert p.remaining_seconds == -int(-(start + 20 - when) // 1) or when == start
        elif start + 23 < when < start + 163:
            assert p.enabled and p.mode is Mode.TELEOP
            assert p.remaining_seconds == pytest.approx(start + 163 - when, abs=1)
    grid = [when for when, _, _ in f.controls("R1")
            if abs((when - T0) / 0.5 - round((when - T0) / 0.5)) < 1e-9]
    assert all(b - a == pytest.approx(0.5) for a, b in zip(grid, grid[1:]))
    extras = [when for when, _, _ in f.controls("R1") if when not in grid]
    assert extras == pytest.approx([start, start + 20, start + 23, start + 163])
    # Sequence numbers go up by one per packet, per station.
    seqs = [p.sequence for _, p, _ in f.controls("B3")]
    assert seqs == list(range(seqs[0], seqs[0] + len(seqs)))
    # Every station was enabled the same way.
    for label in ("R2", "R3", "B1", "B2", "B3"):
        assert at(start, label)[0].enabled and not at(start + 20, label)[0].enabled

    assert [t for _, t in f.fms.match_log if t.startswith("Match 12")] == [
        "Match 12 auto started", "Match 12 pause started", "Match 12 teleop started", "Match 12 ended"]
    assert [when for when, t in f.fms.match_log if t.startswith("Match 12")] == pytest.approx(
        [start, start + 20, start + 23, start + 163])
    assert f.fms.missed_sends == 0


def test_late_poll_skips_slots_without_a_burst():
    f = Field()
    f.login(254, conn="c")
    f.poll(T0 + 0.5)
    n = len(f.controls("R1"))
    f.poll(T0 + 2.2)                  # slots 1.0, 1.5 and 2.0 were missed
    assert len(f.controls("R1")) == n + 1
    assert f.fms.missed_sends == 2
    assert f.fms.next_deadline() == pytest.approx(T0 + 2.5)


def test_short_match_with_custom_timing_runs_in_milliseconds():
    f = Field(timing=MatchTiming(auto=1, pause=0.5, teleop=2))
    f.connect_all()
    f.fms.start_match(f.now)
    f.run_until(f.now + 5)
    assert f.fms.phase is Phase.POST_MATCH
    assert f.fms.snapshot()["remaining"] == 0


# -- station commands --------------------------------------------------------------------------------
def started_field(**kw) -> Field:
    f = Field(**kw)
    f.connect_all()
    f.fms.start_match(f.now)
    f.poll()
    return f


def test_estop_latches_to_the_end_of_the_match():
    f = started_field()
    f.run_until(f.now + 5)
    f.fms.estop("R1", f.now)
    assert f.fms.next_deadline() <= f.now
    mark = len(f.sent)
    out = f.poll()
    r1 = [decode_control(a.data) for a in out if isinstance(a, Datagram) and decode_control(a.data).station == 0]
    assert r1 and r1[0].estop and not r1[0].enabled
    with pytest.raises(CommandError, match="latches"):
        f.fms.clear_estop("R1", f.now)
    f.run_until(f.now + 170)
    assert f.fms.phase is Phase.POST_MATCH
    after = [decode_control(a.data) for _, a in f.sent[mark:] if isinstance(a, Datagram)]
    after = [p for p in after if p.station == 0]
    assert len(after) > 300 and all(p.estop and not p.enabled for p in after)
    # R2 was enabled in teleop all along.
    assert any(p.enabled and p.mode is Mode.TELEOP for _, p, _ in f.controls("R2"))
    assert f.fms.station("R1").commands.estop
    with pytest.raises(MatchStartRefused):
        f.fms.start_match(f.now)
    f.fms.reset(f.now)                 # a replay: e-stops cleared, play number up
    assert not f.fms.station("R1").commands.estop and f.fms.match.play == 2
    assert "R1 (254): e-stop" in texts(f.fms) and "R1 (254): e-stop cleared" in texts(f.fms)


def test_estop_in_pre_match_blocks_start_until_cleared_or_next_match():
    f = Field()
    f.connect_all()
    f.fms.estop("B1", f.now)
    with pytest.raises(MatchStartRefused) as info:
        f.fms.start_match(f.now)
    assert info.value.reasons == ["B1 (118): e-stopped"]
    f.fms.next_match(f.now)
    assert not f.fms.station("B1").commands.estop and f.fms.match.number == 2
    f.fms.estop("B1", f.now)
    f.fms.clear_estop("B1", f.now)
    f.fms.start_match(f.now)


def test_a_ds_estop_mid_match_latches_the_station_to_the_end_of_the_match():
    f = started_field()
    f.run_until(f.now + 5)
    assert f.fms.station("R1").commands.enabled
    f.status(254, estop=True)  # the DS's operator pressed e-stop
    st1 = f.fms.station("R1")
    assert st1.commands.estop and not st1.commands.enabled and f.fms.next_deadline() <= f.now
    assert "R1 (254) e-stopped by its DS" in texts(f.fms)
    assert f.fms.match_log[-1][1] == "R1 (254) e-stopped by its DS"
    r1 = [decode_control(a.data) for a in f.poll() if isinstance(a, Datagram) and decode_control(a.data).station == 0]
    assert r1 and r1[0].estop and not r1[0].enabled  # at once, not on the 500 ms grid
    # A code restart clears the DS's own latch: the station stays e-stopped to the end.
    mark = len(f.sent)
    f.run_until(f.now + 170)
    assert f.fms.phase is Phase.POST_MATCH
    after = [p for p in (decode_control(a.data) for _, a in f.sent[mark:] if isinstance(a, Datagram))
             if p.station == 0]
    assert len(after) > 300 and all(p.estop and not p.enabled for p in after)
    assert texts(f.fms).count("R1 (254) e-stopped by its DS") == 1
    f.fms.next_match(f.now)
    assert not st1.commands.estop


def test_a_ds_estopped_before_the_match_does_not_latch_the_station():
    f = Field()
    f.connect_all()
    f.status(254, estop=True)  # pre-match: the DS's latch is its own business
    assert not f.fms.station("R1").commands.estop
    f.fms.start_match(f.now)
    f.status(254, estop=True)  # still the same e-stop, not a new one
    f.status(254)  # cleared by a code restart
    f.poll()
    assert not f.fms.station("R1").commands.estop and f.fms.station("R1").commands.enabled
    assert "e-stopped by its DS" not in " ".join(texts(f.fms))


def test_each_stations_estop_is_named_by_who_holds_it_and_a_robot_still_estopped_is_warned_of():
    # Issue 29: the field's own e-stop read "DS e-stopped"; a robot e-stopped in an earlier
    # match (its DS still reports the e-stop; the field holds nothing) showed all green.
    f = started_field()
    f.run_until(f.now + 5)
    f.fms.estop("R1", f.now)
    f.status(254, estop=True)  # its DS latches the field's e-stop, and says so
    f.status(1114, estop=True)  # R2's operator e-stops: the field latches that station too
    assert f.fms.station("R1").estop_status == "FMS e-stop"
    assert f.fms.station("R2").estop_status == "DS e-stop"
    assert f.fms.start_warnings() == []  # the field holds both (and the match runs)
    f.fms.abort_match(f.now)
    f.fms.next_match(f.now)  # the field's e-stops clear; both robots stay e-stopped
    f.status(254, estop=True)
    f.status(1114, estop=True)
    assert f.fms.station("R1").estop_status == f.fms.station("R2").estop_status == "robot still e-stopped"
    assert f.fms.start_warnings() == ["R1 (254): robot still e-stopped: restart its code",
                                      "R2 (1114): robot still e-stopped: restart its code"]
    assert f.fms.start_refusals() == []  # the match may start: the robots' latches are their own
    assert list(f.fms.view(f.now).warnings) == f.fms.start_warnings()
    f.status(254)  # its code restarted
    assert f.fms.station("R1").estop_status is None
    assert f.fms.start_warnings() == ["R2 (1114): robot still e-stopped: restart its code"]


def test_the_match_log_is_bounded_and_counts_every_entry():
    from roles.cores.core import Stream
    from roles.cores.fms import MATCH_LOG_SIZE

    f = Field()
    assert f.fms.match_log.capacity == MATCH_LOG_SIZE
    f.fms.match_log = Stream(5)
    total = f.fms.match_log_total
    for team in (254, 1114, 2056, 118):
        f.login(team, answer=False)
    assert f.fms.match_log_total == total + 4 and len(f.fms.match_log) == 4
    for n in range(3):
        f.fms.next_match(f.now)
    assert len(f.fms.match_log) == 5 and f.fms.match_log_total == total + 7
    assert f.fms.match_log[-1][1].endswith("set up (practice)")


def test_astop_only_in_auto_and_released_when_auto_ends():
    f = Field()
    f.connect_all()
    with pytest.raises(CommandError, match="only during auto"):
        f.fms.astop("R2", f.now)
    f.fms.start_match(f.now)
    start = f.now
    f.poll()
    f.run_until(start + 5)
    f.fms.astop("R2", f.now)
    out = f.poll()
    r2 = [decode_control(a.data) for a in out if isinstance(a, Datagram)]
    r2 = [p for p in r2 if p.station == 1]
    assert r2[0].astop and not r2[0].enabled and not r2[0].estop
    f.run_until(start + 24)
    later = [p for w, p, _ in f.controls("R2", since=start + 20)]
    assert later and not any(p.astop for p in later)
    teleop = [p for w, p, _ in f.controls("R2", since=start + 23)]
    assert teleop and all(p.enabled for p in teleop)
    assert not f.fms.station("R2").commands.astop
    assert "R2 (1114): a-stop released (auto is over)" in texts(f.fms)
    with pytest.raises(CommandError, match="only during auto"):
        f.fms.astop("R2", f.now)


def test_bypass_is_never_enabled_and_not_needed_to_start():
    f = Field()
    f.connect_all([t for t in TEAMS if t != 2056])   # R3's DS never comes
    f.fms.set_bypass("R3", True, f.now)
    f.fms.start_match(f.now)
    f.poll()
    f.run_until(f.now + 30)
    assert not f.fms.station("R3").commands.enabled
    with pytest.raises(CommandError, match="cannot remove a bypass"):
        f.fms.set_bypass("R3", False, f.now)
    # Bypassing a connected station mid-match disables it at once.
    assert f.fms.station("B2").commands.enabled
    f.fms.set_bypass("B2", True, f.now)
    mark = len(f.sent)
    out = f.poll()
    b2 = [decode_control(a.data) for a in out if isinstance(a, Datagram)]
    assert [p.enabled for p in b2 if p.station == 4] == [False]
    f.run_until(f.now + 10)
    after = [decode_control(a.data) for _, a in f.sent[mark:] if isinstance(a, Datagram)]
    assert not any(p.enabled for p in after if p.station == 4)


def test_refused_start_lists_every_reason():
    f = Field()
    f.connect_all([254, 2056, 148, 1678])   # R2 (1114) and B1 (118) never come
    f.fms.estop("B1", f.now)
    f.fms.estop("B3", f.now)
    with pytest.raises(MatchStartRefused) as info:
        f.fms.start_match(f.now)
    assert isinstance(info.value, CommandError)
    assert info.value.reasons == [
        "R2 (1114): not connected and not bypassed",
        "B1 (118): e-stopped",
        "B1 (118): not connected and not bypassed",
        "B3 (1678): e-stopped",
    ]
    assert f.fms.phase is Phase.PRE_MATCH
    assert any("start refused" in t for _, t in f.fms.match_log)
    f.fms.next_match(f.now)
    for label in ("R2", "B1"):
        f.fms.set_bypass(label, True, f.now)
    f.fms.start_match(f.now)
    with pytest.raises(MatchStartRefused) as info:
        f.fms.start_match(f.now)
    assert info.value.reasons == ["match already running"]
    empty = Field(teams=[None] * 6)
    with pytest.raises(MatchStartRefused) as info:
        empty.fms.start_match(empty.now)
    assert info.value.reasons == ["no teams in the match"]


def test_abort_disables_everyone_at_once():
    f = Field()
    with pytest.raises(CommandError, match="no match running"):
        f.fms.abort_match(f.now)
    f.connect_all()
    f.fms.start_match(f.now)
    f.poll()
    f.run_until(f.now + 30.2)
    assert f.fms.phase is Phase.TELEOP
    f.fms.abort_match(f.now)
    assert f.fms.phase is Phase.POST_MATCH
    assert all(not s.commands.enabled for s in f.fms.stations)
    out = [decode_control(a.data) for a in f.poll() if isinstance(a, Datagram)]
    assert len(out) == 6 and not any(p.enabled for p in out)
    assert all(p.remaining_seconds == 0 for p in out)
    assert "Match 1 aborted" in [t for _, t in f.fms.match_log]
    with pytest.raises(CommandError, match="match is over"):
        f.fms.start_match(f.now)
    f.fms.next_match(f.now, number=5, level=TournamentLevel.PLAYOFF)
    assert (f.fms.phase, f.fms.match.number, f.fms.match.level) == (Phase.PRE_MATCH, 5, TournamentLevel.PLAYOFF)


def test_teams_cannot_change_during_a_match_and_are_checked():
    f = started_field()
    with pytest.raises(CommandError, match="while a match runs"):
        f.fms.set_team("R1", 9, f.now)
    f.fms.abort_match(f.now)
    with pytest.raises(CommandError, match="more than one station"):
        f.fms.set_team("R1", 118, f.now)
    with pytest.raises(CommandError):
        f.fms.set_team("R1", 0, f.now)
    with pytest.raises(CommandError):
        f.fms.set_team("R7", 9, f.now)
    with pytest.raises(CommandError, match="six teams"):
        f.fms.set_teams([1, 2], f.now)
    with pytest.raises(ValueError):
        FieldManagementSystem([254, 254])


def test_game_data_goes_to_every_ds_in_the_match():
    f = Field()
    f.login(254, conn="a")
    f.login(118, conn="b")
    f.login(9999, conn="w")
    f.fms.set_game_data("RBL", f.now)
    out = f.poll()
    sends = {a.conn: decode_tcp(a.data) for a in out if isinstance(a, StreamSend)}
    assert sends == {"a": GameData("RBL"), "b": GameData("RBL")}
    with pytest.raises(CommandError):
        f.fms.set_game_data("x" * 300, f.now)


def test_snapshot_is_json_and_names_everything():
    f = started_field(level=TournamentLevel.QUALIFICATION, match_number=12)
    f.run_until(f.now + 5.2)
    snap = json.loads(json.dumps(f.fms.snapshot()))
    assert (snap["phase"], snap["match_type"], snap["match_number"], snap["remaining"]) == \
        ("auto", "qualification", 12, 15)
    r1 = snap["stations"][0]
    assert (r1["station"], r1["team"], r1["ds_link"], r1["enabled"], r1["battery"]) == ("R1", 254, True, True, 12.5)


# -- bad input -------------------------------------------------------------------------------------------
def _state(fms: FieldManagementSystem):
    """Everything but the counters: what bad input must not change."""
    snap = fms.snapshot()
    for s in snap["stations"]:
        s.pop("bad_packets")
    snap.pop("bad_packets")
    return snap


@given(st.binary(max_size=64))
def test_bad_udp_is_counted_and_changes_nothing(data):
    f = Field()
    f.connect_all()
    before = _state(f.fms)
    bad = f.fms.udp_stats.bad_packets
    try:
        team = decode_status(data).team
    except ProtocolError:
        team = None
        assert f.fms.datagram(UDP, data, ("6.6.6.6", 6), f.now) == []
        assert f.fms.udp_stats.bad_packets == bad + 1
        assert _state(f.fms) == before
    if team is not None and team not in TEAMS:
        assert f.fms.datagram(UDP, data, ("6.6.6.6", 6), f.now) == []
        assert _state(f.fms) == before
    assert f.fms.datagram("nonsense", data, ("6.6.6.6", 6), f.now) == []


def test_bad_udp_counted_on_the_station_when_the_team_is_readable():
    f = Field()
    f.login(254)
    good = DsStatusPacket(team=254).encode()
    f.fms.datagram(UDP, good + b"\x05\x01", (ds_address(254), 1145), f.now)  # a tag cut short
    assert f.fms.station("R1").link.bad_packets == 1 and f.fms.udp_stats.bad_packets == 1
    assert not f.fms.station("R1").report.udp_link


def test_status_from_anywhere_but_the_stations_ds_is_refused_before_it_is_decoded():
    # Issue 27: the source first, then the size, then the bytes. A station's team number is
    # read (bytes 4-5) to know whose DS may send its status; from anywhere else a packet is
    # refused as it stands, bad or 64 KB, never decoded.
    f = Field()
    f.login(254)
    good = DsStatusPacket(team=254, estop=True).encode()
    for data in (good + b"\x05\x01", good + bytes(65507 - len(good)), good):
        f.fms.datagram(UDP, data, ("127.9.9.9", 1145), f.now)
    r1 = f.fms.station("R1")
    assert r1.link.foreign_packets == 3 and f.fms.refused_status == 3
    assert r1.link.bad_packets == 0 and f.fms.udp_stats.bad_packets == 0
    assert not r1.commands.estop and not r1.report.ds_estop and not r1.report.udp_link
    said = [text for _, text in f.fms.match_log if "refused" in text]
    assert said == ["status (e-stop) for 254 from 127.9.9.9 refused: its DS is 127.2.54.5"]  # once a second
    # From its DS, a packet over the size bound is bad (counted on the station too), and the
    # next good one is taken.
    f.fms.datagram(UDP, good + bytes(65507 - len(good)), (ds_address(254), 1145), f.now)
    assert r1.link.bad_packets == 1 and f.fms.udp_stats.bad_packets == 1
    assert "over the 1024-byte bound" in f.fms.udp_stats.last_error
    f.status(254)
    assert r1.report.udp_link


@given(st.binary(max_size=80))
@example(b"\x00\x00\x00\x00@\x00")  # found by hypothesis: whole frames, then a size over the bound
def test_random_bytes_on_a_fresh_connection(data):
    f = Field()
    f.login(118, conn="other")
    f.open("x", ("127.0.0.1", 1))
    out = f.tcp("x", data)
    if data[:5] == LOGIN_254[:3] + data[3:5] and len(data) >= 5:
        return  # a valid login: covered above
    size = int.from_bytes(data[:2], "big") + 2 if len(data) >= 2 else None
    if size is not None and size > MAX_FRAME:
        assert len(out) == 1 and out[0].conn == "x" and out[0].reason.startswith("bad frame")
    elif size is not None and size <= len(data):
        assert out == [Close("x", "first frame is not a team number")]  # no reply
    else:
        assert out == []  # still waiting for a whole first frame
    assert "other" in f.fms.logins.connections and f.fms.station("B1").tcp_connected


@given(st.binary(max_size=200))
def test_random_bytes_after_login_never_disturb_another_connection(data):
    f = Field()
    f.login(254, conn="a")
    f.login(118, conn="b")
    f.status(254)
    f.status(118)
    b_before = f.fms.snapshot()["stations"][3]
    phase = f.fms.phase
    out = f.tcp("a", data)
    assert all(getattr(a, "conn", "a") == "a" for a in out)
    assert f.fms.snapshot()["stations"][3] == b_before and f.fms.phase is phase
    assert not any(s.commands.enabled for s in f.fms.stations)


def test_framing_error_closes_only_that_connection():
    f = Field()
    f.login(254, conn="a")
    f.login(118, conn="b")
    out = f.tcp("a", b"\xff\xff\x16")   # a 65 537-byte frame: over the bound
    assert len(out) == 1 and isinstance(out[0], Close) and out[0].conn == "a"
    assert "bad frame" in out[0].reason
    assert f.fms.logins.tcp_stats.bad_packets == 1 and f.fms.station("R1").link.bad_packets == 1
    assert not f.fms.station("R1").tcp_connected and f.fms.station("B1").tcp_connected
    assert f.tcp("a", PING_1C) == []   # gone: nothing more happens


def test_bad_frame_content_is_counted_and_the_connection_kept():
    f = Field()
    f.login(254, conn="a")
    out = f.tcp("a", bytes.fromhex("0004 16 010203") + bytes.fromhex("0003 18 0001"))
    assert out == [] and "a" in f.fms.logins.connections
    s = f.fms.station("R1")
    assert s.link.bad_packets == 2 and s.tcp.log_data is None   # a cut log record; another team's login


# -- the safety invariant, by hypothesis ---------------------------------------------------------------
class FieldMachine(RuleBasedStateMachine):
    """Random commands, DS traffic and time: no control packet ever enables a station that is
    e-stopped, bypassed, a-stopped in auto, or outside auto/teleop."""

    def __init__(self) -> None:
        super().__init__()
        self.f = Field(timing=MatchTiming(2.0, 0.5, 3.0))
        self.f.connect_all()
        self.checked = 0

    @rule(label=st.sampled_from(["R1", "R2", "B3"]))
    def estop(self, label):
        self.f.fms.estop(label, self.f.now)

    @rule(label=st.sampled_from(["R1", "R2", "B3"]))
    def astop(self, label):
        try:
            self.f.fms.astop(label, self.f.now)
        except CommandError:
            assert self.f.fms.phase is not Phase.AUTO

    @rule(label=st.sampled_from(["R1", "B3"]), on=st.booleans())
    def bypass(self, label, on):
        try:
            self.f.fms.set_bypass(label, on, self.f.now)
        except CommandError:
            assert self.f.fms.running and not on

    @rule(cmd=st.sampled_from(["start_match", "abort_match", "reset", "next_match"]))
    def match_command(self, cmd):
        try:
            getattr(self.f.fms, cmd)(self.f.now)
        except CommandError:
            pass

    @rule(dt=st.floats(0, 3, allow_nan=False))
    def time_passes(self, dt):
        self.f.run_until(self.f.now + dt)

    @rule()
    def poll(self):
        self.f.poll()

    @invariant()
    def safe(self):
        fms = self.f.fms
        for s in fms.stations:
            if s.commands.enabled:
                assert fms.phase in (Phase.AUTO, Phase.TELEOP)
                assert not (s.commands.estop or s.commands.bypass or (s.commands.astop and fms.phase is Phase.AUTO))
        for t, a in self.f.sent[self.checked:]:
            pkt = decode_control(a.data) if isinstance(a, Datagram) else None
            if pkt is not None and pkt.enabled:
                assert not pkt.estop and not pkt.astop
        self.checked = len(self.f.sent)
        # Whatever was commanded last is what the station is told now.
        if fms.next_deadline() is not None and fms.next_deadline() <= self.f.now:
            out = self.f.poll()
            for a in out:
                if isinstance(a, Datagram):
                    p = decode_control(a.data)
                    s = fms.stations[int(p.station)]
                    assert (p.enabled, p.estop) == (s.commands.enabled, s.commands.estop)
            self.checked = len(self.f.sent)


TestFieldMachine = FieldMachine.TestCase
TestFieldMachine.settings = settings(max_examples=60, stateful_step_count=30, deadline=None)


# -- one DS per station (issue 17) -------------------------------------------------------------------
def test_a_login_from_another_host_waits_until_the_first_ds_is_lost():
    f = Field()
    f.login(254, conn="real")
    f.status(254)
    r1 = f.fms.station("R1")
    out = f.login(254, conn="other", peer=("127.9.9.9", 1))
    assert out == [Close("other", "team 254's DS is live at another address")]
    assert r1.login.conn == "real" and r1.refused_logins == 1 and r1.last_refused == "127.9.9.9"
    assert "login as 254 from 127.9.9.9 refused: its DS 127.2.54.5 is live" in texts(f.fms)
    # A DS just logged in gets a second for its first status; then, silent, it is lost.
    f.poll(T0 + 1.0)
    assert r1.login.owner == "lost" and r1.login.conn == "real"
    out = f.login(254, conn="other2", peer=("127.9.9.9", 2))
    assert out[0] == Close("real", "replaced by a new login") and r1.login.conn == "other2"
    # The first DS's status comes back: not its station any more.
    f.status(254, source=("127.2.54.5", 1145), estop=True)
    assert not r1.report.ds_estop and r1.link.foreign_packets == 1


def test_a_second_connection_from_the_ds_host_is_refused_while_the_ds_is_live():
    f = Field()
    f.login(254, conn="a")
    f.status(254)
    r1 = f.fms.station("R1")
    out = f.login(254, conn="b", peer=("127.2.54.5", 50001))  # another program on the DS's machine
    assert out == [Close("b", "team 254's DS is live on another connection from this host")]
    assert r1.login.conn == "a" and r1.login.challenge == "right" and r1.refused_logins == 1 == f.fms.logins.refused_logins
    assert "login as 254 from 127.2.54.5:50001 refused: its DS is live on another connection from that host " \
        "(127.2.54.5:50000)" in texts(f.fms)
    assert "b" not in f.fms.logins.connections


def test_a_ds_restarted_on_the_same_host_gets_its_station_back():
    # Its process ended: the old connection closed, the new login takes the station at once.
    f = Field()
    f.login(254, conn="a")
    f.status(254)
    f.tcp("a", PING_1C)
    f.record(f.fms.stream_closed("a", "peer closed", f.now))
    out = f.login(254, conn="b", peer=("127.2.54.5", 50001))
    assert isinstance(out[0], StreamSend) and f.fms.station("R1").login.conn == "b"
    # Its machine hung (the old connection still looks open): once its status has been
    # silent for a second, not polled yet, the restarted DS takes the station.
    f.status(254)
    f.now += 1.0
    out = f.login(254, conn="c", peer=("127.2.54.5", 50002))
    assert out[0] == Close("b", "replaced by a new login") and f.fms.station("R1").login.conn == "c"
    assert f.fms.logins.refused_logins == 0


def test_refusals_are_logged_once_a_second_and_all_counted():
    f = Field()
    f.login(254)
    f.status(254)
    for i in range(100):
        f.now = T0 + i * 0.005
        f.status(254, source=("127.9.9.9", 1145))
    said = [t for t in texts(f.fms) if "refused" in t]
    assert said == ["status for 254 from 127.9.9.9 refused: its DS is 127.2.54.5"]
    f.now = T0 + 1.2
    f.status(254, source=("127.9.9.8", 1145))
    said = [t for t in texts(f.fms) if "refused" in t]
    assert said[-1] == ("status for 254 from 127.9.9.8 refused: its DS is 127.2.54.5 "
                        "(and 99 more since the last report)")
    assert f.fms.refused_status == 101 == f.fms.station("R1").link.foreign_packets
    assert f.fms.snapshot()["stations"][0]["refused_status"] == 101


def test_status_with_no_login_is_refused_and_never_moves_control():
    f = Field()
    f.status(254, estop=True)
    r1 = f.fms.station("R1")
    assert not r1.report.udp_link and r1.link.foreign_packets == 1 == r1.unclaimed_status
    assert "status (e-stop) for 254 from 127.2.54.5 refused: no DS is logged in for it" in texts(f.fms)
    # every DS sends status before its login is answered: logged, not flagged on the FMS tab
    from fieldbox.panels.fms import refusals_text
    assert refusals_text(f.fms) == ""
    f.poll(T0 + 0.5)
    assert f.controls("R1") == []
    f.login(254)
    f.status(254, source=("127.9.9.9", 1145))
    assert refusals_text(f.fms) == "R1 (254) refused 1 status packet from another address, last from 127.9.9.9"


def test_ephemeral_plan_takes_status_from_one_port_of_the_login_host():
    f = Field(ds_port=None)
    f.login(254, conn="c", peer=("127.0.0.1", 50000))
    f.status(254, source=("127.0.0.1", 61234))
    f.status(254, source=("127.0.0.1", 61999), battery=5.0, estop=True)  # another program on the host
    r1 = f.fms.station("R1")
    assert r1.report.battery == 12.5 and not r1.report.ds_estop and r1.link.foreign_packets == 1
    assert "status (e-stop) for 254 from 127.0.0.1:61999 refused: its DS is 127.0.0.1:61234" in texts(f.fms)
    f.poll(T0 + 0.5)
    assert {dest for _, _, dest in f.controls("R1")} == {("127.0.0.1", 61234)}


def test_a_challenge_not_answered_within_5_s_is_wrong_and_the_start_says_why():
    f = Field(teams=[254])
    f.login(254, answer=False)
    r1 = f.fms.station("R1")
    f.run_until(T0 + 4.9, teams=[254])
    with pytest.raises(MatchStartRefused) as info:
        f.fms.start_match(f.now)
    assert info.value.reasons == ["R1 (254): waiting for its DS's challenge answer"]
    f.run_until(T0 + 5.1, teams=[254])
    assert r1.login.challenge == "late" and f.fms.logins.challenge_failures == 1
    assert "R1 (254): no challenge answer from 127.2.54.5 within 5 s: never enabled until its DS logs in again" \
        in texts(f.fms)
    with pytest.raises(MatchStartRefused) as info:
        f.fms.start_match(f.now)
    assert info.value.reasons == ["R1 (254): its DS did not answer the challenge within 5 s; not bypassed"]
    f.fms.set_bypass("R1", True, f.now)
    f.fms.start_match(f.now)  # bypass still works
    f.run_until(f.now + 2, teams=[254])
    assert not any(p.enabled for _, p, _ in f.controls("R1"))
