"""The FMS's TCP 1750 (roles/cores/fms.py): who gets a connection, the DS logins that hold
the stations, the challenge each login must answer, and what a DS reports on TCP.

A part of :class:`roles.cores.fms.FieldManagementSystem`, sans-I/O like it: the FMS hands it
the shell's TCP events and its poll, and it returns the actions. It writes each station's
:class:`StationLogin` and :class:`DsTcpReports` (roles/cores/fms_station.py) and nothing
else of it; what it needs of the FMS comes in as three callables: ``log`` (the match log),
``greeting`` (the event code and game data a login is told: not the game data for a 2027
DS, whose control packets carry it) and ``wake`` (send control packets at once, on the next
poll). A login is the NI DS's team number (0x18), answered with station info (0x19) and a
challenge, or the 2027 FIRST Driver Station's hello (0x1e), answered with the hello reply
(0x1f) and no challenge (docs/protocol.md#cheesy-2027). The rules are the module docstring of roles/cores/fms.py
(login, ownership, challenge, room on TCP 1750).
"""

from __future__ import annotations

import ipaddress
import math
import random
from dataclasses import dataclass
from typing import Callable, Hashable

from protocol.ds_to_fms import (ChallengeResponse, DsHello, DsPing, ErrorEventData, LogData, TeamNumber,
                                UsageReport, challenge_answer, check_challenge_answer, decode_tcp)
from protocol.ds_to_rio import KeepAlive
from protocol.enums import AllianceStation, StationStatus
from protocol.errors import ProtocolError
from protocol.fms_to_ds import ChallengeQuestion, DeviceVersion, HelloReply, StationInfo, VersionDevice
from protocol.framing import FrameDecoder

from .core import Action, Address, Close, LinkStats, StreamSend, Throttle
from .fms_station import Station, StationLogin, station_of_team
from .ownership import (CHALLENGE_TIMEOUT, Challenge, ChallengeAction, ChallengeInput, Owner, OwnerAction,
                        OwnerInput, challenge_transition, owner_transition)

KIND_TCP = "fms-to-ds-tcp"
#: The hello reply's flags (bit 0: FMS Lite). fieldbox's FMS is a full FMS: it sends control to
#: the DS's 1121 (or the port a hello names), never FMS Lite's 1120, so no bit is set.
HELLO_FLAGS = 0x00
UDP_TIMEOUT = 1.0      # s without UDP status: the DS is lost
TCP_TIMEOUT = 5.0      # s without a TCP frame: the connection is dropped
MAX_CONNECTIONS = 32   # TCP connections at once; more are closed at once
#: TCP connections one host may hold: a machine running a whole field in the ephemeral plan
#: has six DSes on 127.0.0.1, and a DS reconnecting may briefly hold two.
PER_HOST = 8
#: The largest DS -> FMS frame accepted. A DS sends a few hundred bytes at most (an error
#: with its call stack is the big one); Cheesy Arena reads 4 KiB at a time. A frame over
#: this bound is a framing error: that connection is closed, nobody else notices.
MAX_FRAME = 16 * 1024
CHALLENGE_RANGE = (1000, 2000)
MAX_ANSWER = 40  # characters of a wrong challenge answer kept and logged (the names are short)


def team_from_address(host: str) -> int | None:
    """The team a field address names: 10.TE.AM.x or 127.TE.AM.x -> TEAM, else None."""
    try:
        ip = ipaddress.ip_address(host)
    except ValueError:
        return None
    if ip.version == 6:
        ip = ip.ipv4_mapped  # type: ignore[assignment]
        if ip is None:
            return None
    first, te, am, _ = ip.packed
    if first not in (10, 127) or am > 99:
        return None
    team = te * 100 + am
    return team or None


def host_key(host: str) -> str:
    """One spelling per host: an IPv4-mapped IPv6 address as its IPv4 (a dual-stack TCP
    socket reports ``::ffff:10.2.54.5`` where the UDP socket says ``10.2.54.5``)."""
    try:
        ip = ipaddress.ip_address(host)
    except ValueError:
        return str(host).lower()
    if ip.version == 6 and ip.ipv4_mapped is not None:
        return str(ip.ipv4_mapped)
    return str(ip)


def addr(a: Address | None) -> str:
    return f"{a[0]}:{a[1]}" if a else "?"


@dataclass(eq=False)
class DsConnection:
    """One TCP 1750 connection: its own frame decoder (never shared), its login."""

    conn: Hashable
    peer: Address
    opened: float
    decoder: FrameDecoder
    last_rx: float
    team: int | None = None          # None until the login frame
    station: Station | None = None   # None: not logged in, or waiting (not in the match)
    hello: DsHello | None = None     # the 2027 DS's hello, when that was the login


class Refusals:
    """How the FMS names an address and logs a refusal: at most once a second per kind and
    station (UDP status and TCP logins alike)."""

    def __init__(self, ds_port: int | None, log: Callable[[float, str], None]) -> None:
        self.ds_port = ds_port
        self._log = log
        self._throttle = Throttle()

    def who(self, address: Address | None) -> str:
        """An address as the log names it: the host; host:port in the ephemeral plan, where
        every role shares 127.0.0.1 and only the port tells them apart."""
        if not address:
            return "?"
        return f"{address[0]}:{address[1]}" if self.ds_port is None else str(address[0])

    def refused(self, st: Station, kind: str, text: str, source: Address | None, now: float) -> None:
        """Log a refusal by address, at most once a second per kind and station."""
        st.last_refused = self.who(source)
        held = self._throttle.due((kind, st.label), now)
        if held is not None:
            self._log(now, text + Throttle.suffix(held))

    def due(self, key: Hashable, now: float) -> int | None:
        return self._throttle.due(key, now)


def live_until(login: StationLogin, last_udp: float | None) -> float:
    """When the station's DS counts as lost: a second after its last status, or after its
    login when no status came since."""
    heard = login.login_at if login.login_at is not None else -math.inf
    if last_udp is not None:
        heard = max(heard, last_udp)
    return heard + UDP_TIMEOUT


class Logins:
    """TCP 1750: the connections, the logins holding stations, the challenge."""

    def __init__(self, stations: list[Station], refusals: Refusals, log: Callable[[float, str], None],
                 rng: random.Random, *, max_connections: int, per_host: int,
                 greeting: Callable[[bool], list[bytes]], wake: Callable[[], None]) -> None:
        self.stations = stations
        self.refusals = refusals
        self._log = log
        self.rng = rng
        self.max_connections = max_connections
        self.per_host = per_host
        self._greeting = greeting
        self._wake = wake
        self.connections: dict[Hashable, DsConnection] = {}
        self.tcp_stats = LinkStats("fms-tcp")
        self.refused_connections = 0
        self.evicted_connections = 0  # closed to make room for a newcomer (never logged in, or no station)
        self.refused_logins = 0       # logins refused: that team's DS is live elsewhere
        self.challenge_failures = 0   # wrong, late, repeated or unasked challenge answers

    # -- the shell's TCP events ---------------------------------------------------------------
    def opened(self, conn: Hashable, peer: Address, now: float) -> list[Action]:
        if conn in self.connections:
            return []
        peer = (str(peer[0]), int(peer[1])) if peer else ("?", 0)
        host = host_key(peer[0])
        actions: list[Action] = []
        same_host = [c for c in self.connections.values() if host_key(c.peer[0]) == host]
        if len(same_host) >= self.per_host:
            actions += self._make_room(same_host, host, f"{self.per_host} already open from {host}", now)
        if len(self.connections) >= self.max_connections:
            actions += self._make_room(list(self.connections.values()), host,
                                       f"{self.max_connections} already open", now)
        full = len(self.connections) >= self.max_connections or \
            sum(1 for c in self.connections.values() if host_key(c.peer[0]) == host) >= self.per_host
        if full:
            self.refused_connections += 1
            limit = (f"{self.max_connections} already open" if len(self.connections) >= self.max_connections
                     else f"{self.per_host} already open from {host}")
            self.tcp_stats.bad(f"connection from {addr(peer)} refused: {limit}", now)
            return actions + [Close(conn, "too many connections")]
        decoder = FrameDecoder(f"fms-tcp {addr(peer)}", MAX_FRAME)
        self.connections[conn] = DsConnection(conn, peer, now, decoder, now)
        self.tcp_stats.connected = True
        return actions

    def data(self, conn: Hashable, data: bytes, now: float) -> list[Action]:
        c = self.connections.get(conn)
        if c is None:
            return []
        frames, error = c.decoder.feed_until_error(data)  # the frames before a bad header first
        actions: list[Action] = []
        for frame in frames:
            c.last_rx = now
            self.tcp_stats.received(len(frame), now)
            if c.team is None:
                actions += self._login_frame(c, frame, now)
                if c.conn not in self.connections:
                    break  # closed: the rest of the bytes go nowhere
            else:
                self._frame(c, frame, now)
        if error is not None and c.conn in self.connections:
            self._bad_tcp(c, error, now)
            actions += self._close(c, f"bad frame: {error}", now)
        return actions

    def closed(self, conn: Hashable, reason: str, now: float) -> bool:
        """A connection the peer closed; whether it was one of ours."""
        c = self.connections.pop(conn, None)
        if c is None:
            return False
        self._detach(c, reason or "closed", now)
        self.tcp_stats.connected = bool(self.connections)
        return True

    def poll(self, now: float) -> list[Action]:
        """Close the connections silent for :data:`TCP_TIMEOUT`."""
        actions: list[Action] = []
        for c in list(self.connections.values()):
            if now >= c.last_rx + TCP_TIMEOUT:
                actions += self._close(c, f"keep-alive timeout: no frame for {TCP_TIMEOUT:g} s", now)
        return actions

    def check_live(self, st: Station, now: float) -> None:
        """A station's DS silent for a second is lost: logins may take its station."""
        if st.login.owner is Owner.LIVE and now >= live_until(st.login, st.report.last_udp):
            _, st.login.owner = owner_transition(st.login.owner, OwnerInput.SILENCE)  # MARK_LOST

    def check_challenge(self, st: Station, now: float) -> None:
        """A question unanswered for :data:`CHALLENGE_TIMEOUT` is a late answer."""
        login = st.login
        if login.challenge is Challenge.SENT and login.challenge_at is not None \
                and now >= login.challenge_at + CHALLENGE_TIMEOUT:
            self._challenge_input(st, ChallengeInput.DEADLINE, now)

    def deadlines(self) -> list[float]:
        """When each connection, ownership or challenge needs the next poll."""
        out = [c.last_rx + TCP_TIMEOUT for c in self.connections.values()]
        out.extend(live_until(st.login, st.report.last_udp) for st in self.stations
                   if st.login.owner is Owner.LIVE)
        out.extend(st.login.challenge_at + CHALLENGE_TIMEOUT for st in self.stations
                   if st.login.challenge is Challenge.SENT and st.login.challenge_at is not None)
        return out

    # -- teams changed --------------------------------------------------------------------------
    def unseat(self, st: Station) -> DsConnection | None:
        """The connection holding ``st`` (whose team changes) leaves it; None if none did."""
        if st.login.conn is None:
            return None
        c = self.connections.get(st.login.conn)
        if c is not None:
            c.station = None
        return c

    def replace(self, moved: list[DsConnection], now: float) -> list[Action]:
        """After a team change, every logged-in DS whose place changed hears about it: a new
        station or "waiting"."""
        actions: list[Action] = []
        for c in self.connections.values():
            if c.team is None:
                continue
            target = station_of_team(self.stations, c.team)
            if c.station is target and c not in moved:
                continue
            if c.station is None and target is None and c not in moved:
                continue  # was waiting, still waiting
            actions += self._place(c, now)
        return actions

    # -- internals: room on TCP 1750 ------------------------------------------------------------
    def _served(self, host: str) -> bool:
        """A DS's own address: a station's logged-in DS, or one naming a team in the match."""
        if any(st.login.peer is not None and st.login.conn is not None and host_key(st.login.peer[0]) == host
               for st in self.stations):
            return True
        team = team_from_address(host)
        return team is not None and station_of_team(self.stations, team) is not None

    def _make_room(self, among: list[DsConnection], host: str, why: str, now: float) -> list[Action]:
        """Close one of ``among`` for a newcomer from ``host``: one that never logged in, the
        oldest first; for a newcomer from a DS's own address, else a logged-in one holding no
        station (the longest silent first). Never a station's DS, and never one from a DS's own
        address for a newcomer from elsewhere. Nothing when none qualifies."""
        served = self._served(host)
        pick = [c for c in among if c.station is None and c.conn in self.connections
                and (served or not self._served(host_key(c.peer[0])))]
        fresh = [c for c in pick if c.team is None]
        if fresh:
            victim = min(fresh, key=lambda c: c.opened)
            reason = "it never logged in"
        else:
            waiting = [c for c in pick if c.team is not None] if served else []
            if not waiting:
                return []
            victim = min(waiting, key=lambda c: c.last_rx)
            reason = f"team {victim.team} holds no station"
        self.evicted_connections += 1
        held = self.refusals.due(("evict", None), now)
        if held is not None:
            self._log(now, f"TCP {why}: closed {self.refusals.who(victim.peer)} ({reason}) to make room for "
                           f"{host}{Throttle.suffix(held)}")
        return self._close(victim, f"evicted to make room for a new connection: {reason}", now)

    # -- internals: connections and logins --------------------------------------------------------
    def _bad_tcp(self, c: DsConnection, error: Exception | str, now: float) -> None:
        self.tcp_stats.bad(error, now)
        if c.station is not None:
            c.station.link.bad(error, now)

    def _close(self, c: DsConnection, reason: str, now: float) -> list[Action]:
        self.connections.pop(c.conn, None)
        self.tcp_stats.connected = bool(self.connections)
        self._detach(c, reason, now)
        return [Close(c.conn, reason)]

    def _detach(self, c: DsConnection, reason: str, now: float) -> None:
        """The login leaves its station: a fresh StationLogin, its tables told first."""
        st = c.station
        c.station = None
        if st is None or st.login.conn != c.conn:
            return
        _, st.login.owner = owner_transition(st.login.owner, OwnerInput.LOGOUT)
        self._challenge_input(st, ChallengeInput.FORGET, now)
        st.login = StationLogin(owner=st.login.owner, challenge=st.login.challenge)
        self._log(now, f"{st.name}: DS disconnected ({reason})")

    def _login_frame(self, c: DsConnection, frame: bytes, now: float) -> list[Action]:
        try:
            msg = decode_tcp(frame)
        except ProtocolError:
            msg = None
        if type(msg) is DsHello:
            team = msg.team
            if team is None or msg.udp_port == 0:
                # Cheesy Arena answers a team it cannot read with status 2; with no number (or no
                # port for its control) it can never be placed, so the connection goes too
                # (counted in the TCP link's bad packets, with the address).
                what = (f"team {msg.team_text[:8]!r}, not a team number" if team is None
                        else "UDP port 0 for its control")
                self.tcp_stats.bad(f"{addr(c.peer)}: 2027 hello with {what}", now)
                reply = HelloReply(AllianceStation.RED1, StationStatus.WAITING, HELLO_FLAGS, team or 0).encode()
                return [StreamSend(c.conn, reply, KIND_TCP)] + self._close(c, f"2027 hello with {what}", now)
            c.hello = msg
        elif type(msg) is TeamNumber:
            team = msg.team
        else:
            # docs/protocol.md#fms-login-rule: a first frame that is not a team number is closed, no reply.
            self.tcp_stats.bad(f"{addr(c.peer)}: first frame is not a team number login: "
                               f"{frame[:8].hex(' ')}", now)
            return self._close(c, "first frame is not a team number", now)
        st = station_of_team(self.stations, team)
        if st is not None:
            self.check_live(st, now)  # a DS silent for a second is lost, polled yet or not
            login = self._login_input(st, team, c.peer)
            action, _ = owner_transition(st.login.owner, login)
            if action is OwnerAction.REFUSE_LOGIN:
                return self._refuse_login(c, st, team, login, now)
        c.team = team
        actions: list[Action] = []
        for other in list(self.connections.values()):
            if other is not c and other.team == c.team:
                self._log(now, f"Team {c.team}: logged in again from {addr(c.peer)}; "
                               "the old connection is closed")
                actions += self._close(other, "replaced by a new login", now)
        return actions + self._place(c, now)

    def _login_input(self, st: Station, team: int, peer: Address) -> OwnerInput:
        """Which login this is to the station's ownership table."""
        holder = st.login.peer if st.login.conn is not None else None
        if holder is not None and host_key(holder[0]) == host_key(peer[0]):
            return OwnerInput.LOGIN_SAME_HOST
        if team_from_address(peer[0]) == team and (holder is None or team_from_address(holder[0]) != team):
            return OwnerInput.LOGIN_HOME
        return OwnerInput.LOGIN_OTHER

    def _refuse_login(self, c: DsConnection, st: Station, team: int, login: OwnerInput,
                      now: float) -> list[Action]:
        who = self.refusals.who
        if login is OwnerInput.LOGIN_SAME_HOST:
            # Both from one host: only the ports tell the two connections apart.
            text = (f"login as {team} from {addr(c.peer)} refused: its DS is live on another "
                    f"connection from that host ({addr(st.login.peer)})")
            reason = f"team {team}'s DS is live on another connection from this host"
        else:
            text = f"login as {team} from {who(c.peer)} refused: its DS {who(st.login.peer)} is live"
            reason = f"team {team}'s DS is live at another address"
        st.refused_logins += 1
        self.refused_logins += 1
        self.tcp_stats.foreign_packets += 1  # the FMS TCP row's "foreign": logins not followed
        self.refusals.refused(st, "login", text, c.peer, now)
        self.connections.pop(c.conn, None)
        self.tcp_stats.connected = bool(self.connections)
        return [Close(c.conn, reason)]

    def _place(self, c: DsConnection, now: float) -> list[Action]:
        """Tell a logged-in DS where it stands: its station, or waiting."""
        assert c.team is not None
        st = station_of_team(self.stations, c.team)
        kind = " (2027 DS)" if c.hello is not None else ""
        if st is None:
            c.station = None
            self._log(now, f"Team {c.team} logged in from {addr(c.peer)}{kind}: not in this match, waiting")
            return [StreamSend(c.conn, self._station_frame(c, AllianceStation.RED1, StationStatus.WAITING), KIND_TCP)]
        if st.login.conn is not None and st.login.conn != c.conn and st.login.conn in self.connections:
            self.connections[st.login.conn].station = None  # a stale login for this station
        # TAKE: live, a second to show it. The station has no holder left here (a login closed
        # the team's other connection first; a team change forgot it), and from empty any
        # login takes it.
        _, owner = owner_transition(st.login.owner, self._login_input(st, c.team, c.peer))
        status = StationStatus.GOOD
        wrong = None
        at_team = team_from_address(c.peer[0])
        if at_team is not None and at_team != c.team:
            other = station_of_team(self.stations, at_team)
            if other is not None and other is not st:
                status, wrong = StationStatus.BAD, other.station
        c.station = st
        # A new login: what the last one was told and asked goes (the challenge's state goes
        # through its table below, from where the last login left it).
        st.login = StationLogin(conn=c.conn, peer=c.peer, owner=owner, login_at=now,
                                status="good" if status is StationStatus.GOOD else "bad", wrong_station=wrong,
                                challenge=st.login.challenge, challenge_value=st.login.challenge_value,
                                challenge_at=st.login.challenge_at, challenge_answer=st.login.challenge_answer,
                                hello=c.hello)
        if wrong is None:
            self._log(now, f"{st.name}: DS logged in from {addr(c.peer)}{kind}")
        else:
            self._log(now, f"{st.name}: DS logged in from {addr(c.peer)}{kind}, which is "
                           f"{wrong.label}'s address: wrong station")
        frames = [self._station_frame(c, st.station, status), *self._greeting(c.hello is None)]
        if c.hello is None:
            self._challenge_input(st, ChallengeInput.ASK, now)
            assert st.login.challenge_value is not None  # drawn by the ASK above
            frames.append(ChallengeQuestion(random_value=st.login.challenge_value).encode())
        else:  # the 2027 DS is asked no question (StationLogin.trusted): no answer of a last login stays
            self._challenge_input(st, ChallengeInput.FORGET, now)
        self._wake()  # its first control packet need not wait for the grid
        return [StreamSend(c.conn, f, KIND_TCP) for f in frames]

    @staticmethod
    def _station_frame(c: DsConnection, station: AllianceStation, status: StationStatus) -> bytes:
        """Where a login stands: station info (0x19) for the NI DS, the hello reply (0x1f,
        with the FMS's flags and the team) for the 2027 DS."""
        if c.hello is not None:
            assert c.team is not None  # a hello's login has its team
            return HelloReply(station, status, HELLO_FLAGS, c.team).encode()
        return StationInfo(station, status).encode()

    def _frame(self, c: DsConnection, frame: bytes, now: float) -> None:
        st = c.station
        if st is not None:
            st.link.received(len(frame), now)
        try:
            msg = decode_tcp(frame)
        except ProtocolError as exc:
            # Well framed but not what the layout says: dropped, the connection kept (a DS
            # whose frame we misread must not be thrown off the field).
            self._bad_tcp(c, exc, now)
            return
        if type(msg) in (DsPing, KeepAlive):
            return
        if isinstance(msg, (TeamNumber, DsHello)):  # a login again on a logged-in connection
            if msg.team != c.team:
                self._bad_tcp(c, f"team number {msg.team} on a connection logged in as {c.team}", now)
            return
        if st is None:
            return  # a waiting DS: nothing of it is kept
        reports = st.tcp
        if type(msg) is DeviceVersion:
            device = msg.device
            label = device.label if isinstance(device, VersionDevice) else f"device {device}"
            reports.versions[label] = msg
        elif type(msg) is LogData:
            if msg.records:
                reports.log_records.extend(msg.records)
                reports.log_data = msg.records[-1]
        elif type(msg) is ErrorEventData:
            reports.error_events.extend(msg.entries)
        elif type(msg) is UsageReport:
            reports.usage_report = msg
        elif type(msg) is ChallengeResponse:
            self._challenge_response(st, c, msg.answer, now)

    # -- internals: the challenge -----------------------------------------------------------------
    def _challenge_response(self, st: Station, c: DsConnection, answer: str, now: float) -> None:
        value = st.login.challenge_value
        right = (value is not None and c.team is not None and check_challenge_answer(c.team, value, answer))
        self._challenge_input(st, ChallengeInput.ANSWER_RIGHT if right else ChallengeInput.ANSWER_WRONG,
                              now, answer)

    def _challenge_input(self, st: Station, event: ChallengeInput, now: float, answer: str = "") -> None:
        """Drive the station's challenge table (roles/cores/ownership.py) and carry out its action."""
        login = st.login
        action, login.challenge = challenge_transition(login.challenge, event)
        who = self.refusals.who
        if action is ChallengeAction.SEND_QUESTION:
            login.challenge_value = self.rng.randint(*CHALLENGE_RANGE)
            login.challenge_at, login.challenge_answer = now, None
        elif action is ChallengeAction.TRUST:
            login.challenge_answer = answer
            self._log(now, f"{st.name}: challenge answered")
        elif action is ChallengeAction.DISTRUST:
            answer = answer[:MAX_ANSWER]  # a frame may carry 16 KiB of it: the log keeps a name's worth
            login.challenge_answer = answer
            self.challenge_failures += 1
            value = login.challenge_value
            expected = challenge_answer(st.team, value) if st.team and value else "?"
            self._log(now, f"{st.name}: WRONG challenge answer {answer!r} from {who(login.peer)} "
                           f"(expected {expected!r}): never enabled until its DS logs in again")
            self._wake()
        elif action is ChallengeAction.EXPIRE:
            self.challenge_failures += 1
            self._log(now, f"{st.name}: no challenge answer from {who(login.peer)} within "
                           f"{CHALLENGE_TIMEOUT:g} s: never enabled until its DS logs in again")
            self._wake()
        elif action is ChallengeAction.REFUSE_ANSWER:
            self.challenge_failures += 1
            what = "no question asked" if login.challenge is Challenge.NONE else "only the first answer counts"
            self.refusals.refused(st, "answer", f"{st.name}: challenge answer {answer[:MAX_ANSWER]!r} from "
                                                f"{who(login.peer)} refused: {what}", login.peer, now)


__all__ = ["DsConnection", "Logins", "MAX_CONNECTIONS", "MAX_FRAME", "PER_HOST", "Refusals", "TCP_TIMEOUT",
           "UDP_TIMEOUT", "host_key", "live_until", "team_from_address"]
