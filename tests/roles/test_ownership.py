"""Station ownership and the challenge: both tables, every pair, and the FMS that carries them
out, on a fake clock against random logins and status from the real DS's host and a
stranger's (roles/cores/ownership.py, roles/cores/fms.py)."""

from __future__ import annotations

import itertools

from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.stateful import RuleBasedStateMachine, invariant, rule

from protocol.ds_to_fms import ChallengeResponse, DsStatusPacket, TeamNumber, challenge_answer
from protocol.fms_to_ds import ChallengeQuestion, decode_control, decode_tcp
from protocol.framing import split_frames
from protocol.enums import Mode
from roles.cores.core import Close, CommandError, Connect, Datagram, StreamSend
from roles.cores.fms import UDP, FieldManagementSystem
from roles.cores.match import MatchTiming, Phase
from roles.cores.ownership import (CHALLENGE_TABLE, OWNER_TABLE, Challenge, ChallengeAction, ChallengeInput, Owner,
                                   OwnerAction, OwnerInput, challenge_transition, owner_transition)
from roles.runtime.field import Field, FieldConfig
from roles.runtime.shell import RoleSpec
from roles.sim.simnet import SimNetwork

OWNERS, OWNER_INPUTS = list(Owner), list(OwnerInput)
CHALLENGES, CHALLENGE_INPUTS = list(Challenge), list(ChallengeInput)
LOGINS = (OwnerInput.LOGIN_SAME_HOST, OwnerInput.LOGIN_HOME, OwnerInput.LOGIN_OTHER)


# -- the tables ----------------------------------------------------------------------------
def test_both_tables_are_total():
    assert set(OWNER_TABLE) == set(itertools.product(OWNERS, OWNER_INPUTS))
    assert set(CHALLENGE_TABLE) == set(itertools.product(CHALLENGES, CHALLENGE_INPUTS))


@given(st.sampled_from(OWNERS), st.sampled_from(OWNER_INPUTS))
def test_every_ownership_pair(state, event):
    action, new = owner_transition(state, event)
    # Only a login takes a station, and a taken station is live.
    assert (action is OwnerAction.TAKE) == (event in LOGINS and action is not OwnerAction.REFUSE_LOGIN)
    if action is OwnerAction.TAKE:
        assert new is Owner.LIVE
    # A live DS is refused to a stranger and to a second connection from its own host (the
    # team's own address alone may take it); a lost or absent one to nobody.
    if action is OwnerAction.REFUSE_LOGIN:
        assert state is Owner.LIVE and event is not OwnerInput.LOGIN_HOME and new is Owner.LIVE
    if state is Owner.LIVE and event in (OwnerInput.LOGIN_SAME_HOST, OwnerInput.LOGIN_OTHER):
        assert action is OwnerAction.REFUSE_LOGIN
    # Status is accepted only from the station's DS, and only when there is one.
    if action is OwnerAction.ACCEPT_STATUS:
        assert event is OwnerInput.STATUS_OWN and state is not Owner.EMPTY and new is Owner.LIVE
    if event is OwnerInput.STATUS_OTHER:
        assert action is OwnerAction.REFUSE_STATUS and new is state
    # Status never frees a station or changes its holder; silence only marks it lost.
    if event in (OwnerInput.STATUS_OWN, OwnerInput.STATUS_OTHER, OwnerInput.SILENCE):
        assert (new is Owner.EMPTY) == (state is Owner.EMPTY)
    if event is OwnerInput.LOGOUT:
        assert new is Owner.EMPTY
    if action is OwnerAction.IGNORE:
        assert new is state


@given(st.sampled_from(CHALLENGES), st.sampled_from(CHALLENGE_INPUTS))
def test_every_challenge_pair(state, event):
    action, new = challenge_transition(state, event)
    # Trust comes only from a right first answer to a question asked.
    if new is Challenge.RIGHT and state is not Challenge.RIGHT:
        assert (state, event, action) == (Challenge.SENT, ChallengeInput.ANSWER_RIGHT, ChallengeAction.TRUST)
    # Only the first answer counts: after it, answers are refused and change nothing.
    if state is not Challenge.SENT and event in (ChallengeInput.ANSWER_RIGHT, ChallengeInput.ANSWER_WRONG):
        assert action is ChallengeAction.REFUSE_ANSWER and new is state
    if event is ChallengeInput.ASK:
        assert (action, new) == (ChallengeAction.SEND_QUESTION, Challenge.SENT)
    if event is ChallengeInput.FORGET:
        assert new is Challenge.NONE
    if event is ChallengeInput.DEADLINE:
        assert new is (Challenge.LATE if state is Challenge.SENT else state)
    assert new.trusted == (new is Challenge.RIGHT)


# -- the FMS carrying them out, against a stranger ---------------------------------------------
HOME = "127.2.54.5"        # team 254's own loopback address
STRANGER = "127.9.9.9"


class Ownership(RuleBasedStateMachine):
    """Random logins, answers, status and time from team 254's DS and from a stranger.

    Whatever happens: control packets for R1 go only to the host of the login holding it;
    status from anywhere but that login's host changes nothing (no e-stop, no battery); the
    station is enabled only after a right first answer from that login; a stranger never
    holds the station while a live DS from the team's own address is there."""

    def __init__(self) -> None:
        super().__init__()
        self.fms = FieldManagementSystem([254, None, None, None, None, None], seed=3,
                                         timing=MatchTiming(3.0, 0.5, 5.0))
        self.now = 1000.0
        self.sent: list = []
        self.conns = 0
        self.take(self.fms.poll(self.now))

    def take(self, actions) -> None:
        st_ = self.fms.station("R1")
        for a in actions:
            self.sent.append((a, st_.login.peer if st_.login.conn is not None else None, st_.login.challenge))

    def conn_of(self, host):
        return next((c for c in self.fms.logins.connections.values() if c.peer[0] == host), None)

    @rule(host=st.sampled_from([HOME, STRANGER]), answer=st.sampled_from(["right", "wrong", "none"]))
    def login(self, host, answer):
        self.conns += 1
        conn = ("c", self.conns)
        self.take(self.fms.stream_opened(conn, (host, 40000 + self.conns), self.now))
        out = self.fms.stream_data(conn, TeamNumber(254).encode(), self.now)
        self.take(out)
        questions = [f for a in out if isinstance(a, StreamSend) for f in map(decode_tcp, split_frames(a.data))
                     if isinstance(f, ChallengeQuestion)]
        if questions and answer != "none" and conn in self.fms.logins.connections:
            text = challenge_answer(254, questions[-1].random_value) if answer == "right" else "Nope"
            self.take(self.fms.stream_data(conn, ChallengeResponse(text).encode(), self.now))

    @rule(host=st.sampled_from([HOME, STRANGER]), estop=st.booleans())
    def status(self, host, estop):
        st_ = self.fms.station("R1")
        holder = st_.login.peer[0] if st_.login.conn is not None else None
        before = (st_.commands.estop, st_.report.battery, st_.report.ds_estop)
        data = DsStatusPacket(team=254, estop=estop, battery=9.0 if host == STRANGER else 12.5,
                              robot_comms=True).encode()
        self.take(self.fms.datagram(UDP, data, (host, 1145), self.now))
        if host != holder:
            assert (st_.commands.estop, st_.report.battery, st_.report.ds_estop) == before

    @rule(host=st.sampled_from([HOME, STRANGER]))
    def close(self, host):
        c = self.conn_of(host)
        if c is not None:
            self.take(self.fms.stream_closed(c.conn, "peer closed", self.now))

    @rule(cmd=st.sampled_from(["start_match", "abort_match", "reset"]))
    def match(self, cmd):
        try:
            getattr(self.fms, cmd)(self.now)
        except CommandError:
            pass

    @rule(dt=st.sampled_from([0.1, 0.5, 1.1, 5.5]))
    def time_passes(self, dt):
        self.now += dt
        self.take(self.fms.poll(self.now))

    @invariant()
    def safe(self):
        st_ = self.fms.station("R1")
        for action, holder, challenge in self.sent:
            if isinstance(action, Datagram):  # control packets: to the holder's host, enabled only if trusted
                assert holder is not None and action.dest[0] == holder[0]
                assert not decode_control(action.data).enabled or challenge is Challenge.RIGHT
        self.sent.clear()
        if st_.commands.enabled:
            assert st_.login.challenge is Challenge.RIGHT and st_.login.conn is not None
            assert self.fms.phase in (Phase.AUTO, Phase.TELEOP)
        if st_.login.owner is Owner.EMPTY:
            assert st_.login.conn is None
        else:
            assert st_.login.conn in self.fms.logins.connections
        # The team's own address, live, is never displaced by a stranger.
        if st_.login.conn is not None and st_.login.peer[0] == STRANGER:
            home = self.conn_of(HOME)
            assert home is None or home.station is None


TestOwnership = Ownership.TestCase
TestOwnership.settings = settings(max_examples=150, stateful_step_count=40, deadline=None)


def test_a_login_from_the_teams_own_address_takes_the_station_from_a_stranger():
    fms = FieldManagementSystem([254], seed=1)
    fms.stream_opened("s", (STRANGER, 1), 0.0)
    fms.stream_data("s", TeamNumber(254).encode(), 0.0)
    assert fms.station("R1").login.peer[0] == STRANGER
    fms.datagram(UDP, DsStatusPacket(team=254).encode(), (STRANGER, 1145), 0.1)
    assert fms.station("R1").login.owner is Owner.LIVE
    fms.stream_opened("h", (HOME, 1), 0.2)
    out = fms.stream_data("h", TeamNumber(254).encode(), 0.2)
    assert out[0] == Close("s", "replaced by a new login")
    assert fms.station("R1").login.peer[0] == HOME and "s" not in fms.logins.connections
    # ... and a stranger cannot take it back while the team's DS is live.
    fms.datagram(UDP, DsStatusPacket(team=254).encode(), (HOME, 1145), 0.3)
    fms.stream_opened("s2", (STRANGER, 2), 0.4)
    assert fms.stream_data("s2", TeamNumber(254).encode(), 0.4) == \
        [Close("s2", "team 254's DS is live at another address")]
    assert fms.station("R1").login.peer[0] == HOME and fms.logins.refused_logins == 1


# -- a whole match on the fake clock, with a second program on the DS's machine -----------------
class SameHostLogin:
    """A program on team 254's DS machine (its address, another port) that logs in as 254 and
    answers the challenge right, as anyone may compute it; when refused, tries again every
    half second."""

    def __init__(self, fms_tcp) -> None:
        self.fms_tcp, self.next, self.open, self.tries, self.closes = fms_tcp, None, False, 0, []

    def poll(self, now):
        if self.next is None or now < self.next or self.open:
            return []
        self.next, self.open = None, True
        self.tries += 1
        return [Connect("fms", self.fms_tcp)]

    def next_deadline(self):
        return self.next

    def stream_opened(self, conn, address, now):
        return [StreamSend(conn, TeamNumber(254).encode(), "ds-to-fms-tcp")]

    def stream_data(self, conn, data, now):
        return [StreamSend(conn, ChallengeResponse(challenge_answer(254, f.random_value)).encode(), "ds-to-fms-tcp")
                for f in map(decode_tcp, split_frames(data)) if isinstance(f, ChallengeQuestion)]

    def stream_closed(self, conn, reason, now):
        self.open = False
        self.closes.append(reason)
        self.next = now + 0.5
        return []

    def datagram(self, *a):
        return []


def test_a_second_login_from_the_ds_host_mid_match_is_refused_and_the_ds_stays_enabled():
    net = SimNetwork()
    packets = []  # (time, destination, control packet) for R1
    net.taps.append(lambda r: packets.append((r.time, tuple(r.remote), decode_control(r.data)))
                    if r.kind == "fms-to-ds" and r.direction == "out" else None)
    field = Field(FieldConfig(teams=[254], plan="loopback"))
    field.start_sim(net)
    fms, ds, rio = field.fms, field.stations[0].ds, field.stations[0].rio
    ds_events = []
    ds.events.listeners.append(lambda t, text: ds_events.append(text))
    net.run_for(3.0)
    assert fms.station("R1").login.challenge == "right" and ds.fms.status == "good"
    net.command("fms", lambda: fms.set_timing(net.now, auto=3, pause=1, teleop=6))
    net.command("fms", lambda: fms.start_match(net.now))
    teleop_end = net.now + 3 + 1 + 6
    net.run_for(5.0)  # into teleop
    assert fms.phase is Phase.TELEOP and rio.control.enabled
    # The program starts on the DS's own host, 127.2.54.5, on a port of its own.
    intruder = SameHostLogin(field.bound["fms"]["tcp"])
    net.add(RoleSpec("intruder", intruder, udp={"x": ("127.2.54.5", 0)}))
    intruder.next = start = net.now
    net.run_for(4.0)
    assert rio.control.enabled
    net.run_for(1.5)  # to the end of the match
    assert fms.phase is Phase.POST_MATCH
    # Refused every time; the real DS kept its connection, and every control packet of teleop
    # went to it, enabled.
    assert intruder.tries >= 8 and fms.logins.refused_logins == intruder.tries == fms.station("R1").refused_logins
    teleop = [(t, dest, p) for t, dest, p in packets if start <= t < teleop_end]
    assert len(teleop) >= 10 and all(p.mode is Mode.TELEOP for _, _, p in teleop)
    assert all(dest == ("127.2.54.5", 1121) and p.enabled for _, dest, p in teleop)
    assert not any("FMS TCP closed" in text for text in ds_events)
    said = [text for _, text in fms.match_log if "refused" in text]
    assert said and all(text.startswith("login as 254 from 127.2.54.5:") and
                        "refused: its DS is live on another connection from that host (127.2.54.5:" in text
                        for text in said)
    # The DS's machine is gone (its connection closed): the program's next login takes the station.
    net.remove(field.stations[0].ds_name)
    net.run_for(1.0)
    assert fms.station("R1").login.conn is not None and fms.station("R1").login.peer[0] == "127.2.54.5"
    assert intruder.open and fms.logins.refused_logins == intruder.tries - 1
