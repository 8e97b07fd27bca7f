"""The FMS core: six alliance stations, the DS logins on TCP 1750, the DS status on UDP 1160,
the control packets to each DS, and the match (:mod:`roles.cores.match`).

Sans-IO (roles/cores/core.py): the shell calls ``datagram("udp", data, source, now)`` for every
packet on the FMS's UDP 1160 socket (control packets go out from the same socket, channel
``"udp"``), ``stream_opened / stream_data / stream_closed`` for TCP 1750 connections (``conn``
is whatever hashable the shell chose), and ``poll(now)`` at ``next_deadline()``. User
commands (start, abort, e-stop, bypass...) change state or raise :class:`CommandError`; what
they need sent waits for the next ``poll``, and ``next_deadline()`` asks for that at once.

Field behaviour (docs/protocol.md#fms-behaviour, checked against Cheesy Arena's
``field/driver_station_connection.go``):

* Login: the first frame must be a team number (``00 03 18 hi lo``), else the connection is
  closed without a reply. A team in the match gets station info (status good, or bad when
  its source address 10.TE.AM.x / 127.TE.AM.x is another team's in another station), the
  event code, game data if set and a challenge question. A team not in the match gets
  station info "waiting" (``00 03 19 00 02``) and stays connected (Cheesy Arena closes it
  after a second; the notes say keep it).
* A station belongs to its logged-in DS (:mod:`roles.cores.ownership`): UDP status, matched to a
  station by the team number inside it, is taken only from the host of that team's live TCP
  login; from anywhere else it is counted and dropped (it never e-stops, never moves the
  station's control packets). A second login for the team is refused while the first DS is
  live, from another host or from the DS's own host on another connection, and takes the
  station once that DS is lost or its connection closed (or at once from the team's own
  10.TE.AM.x / 127.TE.AM.x when the holder's address is not). Control packets go to
  the host of the DS's TCP connection (as Cheesy Arena does), port ``ds_port`` 1121; with
  ``ds_port=None`` (the ephemeral plan, where ports are the OS's) to the port its first
  status came from, which is then the only one taken.
* The challenge counts: a station is trusted only after its DS answered the question right,
  first time, within 5 s.
* Control packets every 500 ms on a drift-free grid, and at once on a phase change or a
  station command. A DS is lost after 1 s without UDP status, or 5 s without a TCP frame.
* A station is enabled only while the match enables (auto, teleop) and it is not e-stopped,
  not a-stopped in auto, not bypassed, not at the wrong station, and its DS answered the
  challenge right.
* TCP 1750 keeps room for the real DSes: at most ``per_host`` connections from one host and
  ``max_connections`` in all; when full, a newcomer evicts a connection that never logged in
  (the oldest first), and one from a DS's own address (a station's DS, or 10.TE.AM.x /
  127.TE.AM.x of a team in the match) may also evict a logged-in one that holds no station.
  A station's DS is never evicted.
* Every refusal is counted (the station's ``link.foreign_packets``, ``refused_logins``,
  ``challenge_failures``...) and logged at most once a second per kind and station, naming
  the address: "status for 254 from 127.9.9.9 refused: its DS is 127.2.54.5".
* The station's DS that starts reporting an e-stop (status bit 0x80) while a match runs e-stops its
  station here, latched like a station e-stop (a code restart that clears the DS's own
  latch does not bring the FMS's enable back). A DS already e-stopped when the match began
  is left to its own latch, and named before the start (``start_warnings``: "robot still
  e-stopped: restart its code"), since the field's enable cannot reach its robot.
* ``match_log`` keeps the last ``MATCH_LOG_SIZE`` entries; ``match_log_total`` counts all.
"""

from __future__ import annotations

import dataclasses
import datetime as _dt
import ipaddress
import math
import random
from collections import deque
from dataclasses import dataclass, field
from typing import Any, Callable, Hashable, Iterable, Sequence

from protocol.ds_to_fms import (ChallengeResponse, CommsMetrics, DsPing, DsStatusPacket,
                                ErrorEvent, ErrorEventData, LogData, LogRecord, TeamNumber,
                                UsageReport, challenge_answer, check_challenge_answer,
                                decode_status, decode_tcp)
from protocol.ds_to_rio import KeepAlive
from protocol.enums import AllianceStation, Mode, StationStatus, TournamentLevel
from protocol.errors import ProtocolError
from protocol.fms_to_ds import (ChallengeQuestion, DeviceVersion, EventCode, FmsControlPacket,
                                FmsDate, GameData, StationInfo, VersionDevice)
from protocol.framing import FrameDecoder

from .addresses import DS_FMS_UDP, check_team
from .core import (Action, Address, Close, CommandError, Datagram, Events, Grid, LinkStats, StreamSend,
                   Throttle, utc_now)
from .views import FmsView
from .match import PHASE_EVENT, REFUSALS, Input, Match, MatchTiming, Phase
from .match import Action as MatchAction
from .ownership import (CHALLENGE_TIMEOUT, Challenge, ChallengeAction, ChallengeInput, Owner, OwnerAction,
                        OwnerInput, challenge_transition, owner_transition)

#: The shell's channel for UDP 1160: status in, control packets out from the same socket.
UDP = "udp"
KIND_CONTROL = "fms-to-ds"
KIND_TCP = "fms-to-ds-tcp"

CONTROL_PERIOD = 0.5   # s between control packets
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

_LOG_RECORDS = 1000    # log-data records kept per station (a match at 4 per second)
MATCH_LOG_SIZE = 10_000  # match-log entries kept (hundreds of matches)
_ERROR_EVENTS = 200    # error/event entries kept per station


class MatchStartRefused(CommandError):
    """A start that cannot happen; ``reasons`` lists every one of them."""

    def __init__(self, reasons: Iterable[str]) -> None:
        self.reasons = list(reasons)
        super().__init__("cannot start the match: " + "; ".join(self.reasons))

    def __reduce__(self) -> tuple[type[MatchStartRefused], tuple[list[str]]]:  # pickled with its reasons (a refusal from a wire process)
        return (type(self), (self.reasons,))


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



def station_index(key: "StationKey") -> int:
    """The index 0-5 of a station given by ``AllianceStation``, label (``R1``..``B3``) or index."""
    try:
        if isinstance(key, AllianceStation):
            return int(key)
        if isinstance(key, str):
            return int(AllianceStation.parse(key))
        if isinstance(key, int) and not isinstance(key, bool) and 0 <= key <= 5:
            return key
        raise ValueError(f"unknown station {key!r}")
    except ValueError as exc:
        raise CommandError(str(exc)) from None

@dataclass(eq=False)
class Station:
    """One alliance station: who should be there, what its DS reports, what we command.

    Plain attributes, written by the core, read by panels at ~10 Hz.
    """

    station: AllianceStation
    team: int | None = None
    link: LinkStats = field(default_factory=lambda: LinkStats("fms"))
    # The DS's TCP login (None: no DS logged in for this team).
    conn: Hashable | None = None
    peer: Address | None = None
    status: str | None = None                 # "good" / "bad": what station info told the DS
    wrong_station: AllianceStation | None = None  # where its address says it is, when bad
    owner: Owner = Owner.EMPTY                # roles/cores/ownership.py: empty / live / lost
    login_at: float | None = None             # when the login holding the station came
    challenge: Challenge = Challenge.NONE     # none / sent / right / wrong / late
    challenge_value: int | None = None
    challenge_at: float | None = None         # when the question went out
    challenge_answer: str | None = None       # the answer received
    last_tcp: float | None = None
    # Refusals: status from elsewhere is counted in link.foreign_packets.
    refused_logins: int = 0                   # logins for this team refused: its DS was live
    # ...of which status that came while no DS was logged in: a real DS sends status before its
    # login is answered (Cheesy Arena drops it unsaid), so at every start: logged, not flagged
    unclaimed_status: int = 0
    last_refused: str | None = None           # the address refused last
    # The DS's UDP status.
    udp_link: bool = False
    ds_address: Address | None = None         # where its status comes from
    status_port: int | None = None            # ds_port=None: the one port its status is taken from
    last_udp: float | None = None
    last_sequence: int | None = None
    robot_link: bool = False
    radio_ping: bool = False
    rio_ping: bool = False
    ds_estop: bool = False
    ds_enabled: bool = False
    ds_mode: Mode | None = None
    battery: float | None = None
    trip_time_ms: int | None = None
    lost_packets: int | None = None
    sent_packets: int | None = None
    # What the field commands.
    estop: bool = False
    estop_by: str | None = None               # who e-stopped it: "FMS" (the field's x) or "DS" (mid-match)
    astop: bool = False
    bypass: bool = False
    enabled: bool = False
    control_sequence: int = 0
    # What the DS reported on TCP.
    log_data: LogRecord | None = None
    log_records: deque[LogRecord] = field(default_factory=lambda: deque(maxlen=_LOG_RECORDS))
    versions: dict[str, DeviceVersion] = field(default_factory=dict)
    error_events: deque[ErrorEvent] = field(default_factory=lambda: deque(maxlen=_ERROR_EVENTS))
    usage_report: UsageReport | None = None

    def __post_init__(self) -> None:
        self.link = LinkStats(f"fms-{self.label}")

    @property
    def label(self) -> str:
        return self.station.label

    @property
    def name(self) -> str:
        """``R2 (254)``: how events and refusals name a station."""
        return f"{self.label} ({self.team if self.team is not None else 'empty'})"

    @property
    def tcp_connected(self) -> bool:
        return self.conn is not None

    @property
    def ds_link(self) -> bool:
        """The DS is linked: logged in on TCP and its UDP status is arriving."""
        return self.conn is not None and self.udp_link

    def forget_ds(self) -> None:
        """Forget everything the last team's DS reported (the station got a new team)."""
        fresh = Station(self.station, self.team)
        keep = {"station", "team", "link", "estop", "estop_by", "astop", "bypass", "enabled", "control_sequence",
                "refused_logins", "last_refused", "unclaimed_status"}
        for f in dataclasses.fields(self):
            if f.name not in keep:
                setattr(self, f.name, getattr(fresh, f.name))

    @property
    def estop_status(self) -> str | None:
        """What e-stops this station, in words for its row (None: nothing): the field's own
        e-stop ("FMS e-stop"), its DS's e-stop in the match, which the field latched ("DS
        e-stop"), or its DS reporting an e-stop the field does not hold: a robot e-stopped in
        an earlier match (or before this one) stays e-stopped until its code restarts, as a
        real roboRIO does, whatever the field says ("robot still e-stopped")."""
        if self.estop:
            return "DS e-stop" if self.estop_by == "DS" else "FMS e-stop"
        if self.ds_estop and self.udp_link:
            return "robot still e-stopped"
        return None

    def snapshot(self) -> dict[str, Any]:
        return {
            "station": self.label,
            "team": self.team,
            "ds_link": self.ds_link,
            "tcp": self.tcp_connected,
            "udp": self.udp_link,
            "ds_address": f"{self.ds_address[0]}:{self.ds_address[1]}" if self.ds_address else None,
            "robot_link": self.robot_link,
            "radio_ping": self.radio_ping,
            "rio_ping": self.rio_ping,
            "battery": self.battery,
            "trip_time_ms": self.trip_time_ms,
            "lost_packets": self.lost_packets,
            "sent_packets": self.sent_packets,
            "ds_estop": self.ds_estop,
            "ds_enabled": self.ds_enabled,
            "ds_mode": self.ds_mode.label if self.ds_mode is not None else None,
            "estop": self.estop,
            "estop_status": self.estop_status,
            "astop": self.astop,
            "bypass": self.bypass,
            "enabled": self.enabled,
            "status": self.status,
            "wrong_station": self.wrong_station.label if self.wrong_station is not None else None,
            "challenge": self.challenge.value,
            "owner": self.owner.value,
            "refused_logins": self.refused_logins,
            "refused_status": self.link.foreign_packets,
            "last_refused": self.last_refused,
            "log_data": dataclasses.asdict(self.log_data) if self.log_data else None,
            "versions": {k: v.version for k, v in self.versions.items()},
            "error_events": len(self.error_events),
            "bad_packets": self.link.bad_packets,
        }


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


StationKey = AllianceStation | str | int


class FieldManagementSystem:
    """The FMS role core. See the module docstring for what it does on the wire.

    Every user command takes ``now`` (the shell's clock, for the match clock and the event
    log), as every wire event and poll does.
    """

    def __init__(self, teams: Sequence[int | None] = (), *, timing: MatchTiming | None = None,
                 level: TournamentLevel | int = TournamentLevel.PRACTICE, match_number: int = 1,
                 ds_port: int | None = DS_FMS_UDP, event_code: str = "FIELDBOX",
                 game_data: str = "", rng: random.Random | None = None, seed: int | None = None,
                 wall_clock: Callable[[], _dt.datetime] | None = None,
                 max_connections: int = MAX_CONNECTIONS, per_host: int = PER_HOST) -> None:
        if ds_port is not None and not (isinstance(ds_port, int) and 0 < ds_port <= 0xFFFF):
            raise ValueError(f"ds_port must be a port number or None, not {ds_port!r}")
        if not (isinstance(max_connections, int) and max_connections >= 1):
            raise ValueError(f"max_connections must be a positive int, not {max_connections!r}")
        if not (isinstance(per_host, int) and per_host >= 1):
            raise ValueError(f"per_host must be a positive int, not {per_host!r}")
        self.ds_port = ds_port
        self.max_connections = max_connections
        self.per_host = per_host
        self.rng = rng if rng is not None else random.Random(seed)
        self.wall_clock = wall_clock or utc_now
        self.match = Match(timing, TournamentLevel.PRACTICE, 1)
        try:
            self.match.setup(level, match_number)
        except CommandError as exc:
            raise ValueError(str(exc)) from None
        self.event_code = _checked_text(EventCode, event_code, ValueError)
        self.game_data = _checked_text(GameData, game_data, ValueError)

        self.stations: list[Station] = [Station(s) for s in AllianceStation]
        self.connections: dict[Hashable, DsConnection] = {}
        self.events = Events()
        #: Match-related happenings for the match log file: the last ``MATCH_LOG_SIZE``, and
        #: ``match_log_total`` ever logged (a reader's cheap "anything new?"; total - len is
        #: how many scrolled out). Each one is also an ``events`` happening, as it is logged.
        self.match_log: deque[tuple[float, str]] = deque(maxlen=MATCH_LOG_SIZE)
        self.match_log_total = 0
        self.udp_stats = LinkStats("fms-udp")
        self.tcp_stats = LinkStats("fms-tcp")
        self.refused_connections = 0
        self.evicted_connections = 0  # closed to make room for a newcomer (never logged in, or no station)
        self.udp_unknown_team = 0     # good status packets from a team not in the match
        self.refused_status = 0       # status for a station from an address that is not its DS's
        self.refused_logins = 0       # logins refused: that team's DS is live elsewhere
        self.challenge_failures = 0   # wrong, late, repeated or unasked challenge answers
        self.missed_sends = 0         # control slots skipped because a poll came late
        self._throttle = Throttle()   # refusals: logged once a second per kind and station

        self._now: float | None = None  # the shell's clock at the last wire event or poll
        self._sends = Grid(CONTROL_PERIOD)  # the control packets, every 500 ms
        self._send_now = False
        self._pending: list[Action] = []

        if teams:
            teams = list(teams)
            teams += [None] * (6 - len(teams))
            try:
                self._set_teams(teams, 0.0, quiet=True)
            except CommandError as exc:
                raise ValueError(str(exc)) from None
        self._sync()

    # -- what panels read -------------------------------------------------------------------
    @property
    def phase(self) -> Phase:
        return self.match.phase

    @property
    def running(self) -> bool:
        return self.match.running

    def station(self, key: StationKey) -> Station:
        """A station by ``AllianceStation``, label (``R1``..``B3``) or index 0-5."""
        return self.stations[station_index(key)]

    def station_of_team(self, team: int | None) -> Station | None:
        if team is None:
            return None
        for st in self.stations:
            if st.team == team:
                return st
        return None

    def remaining(self, now: float) -> int:
        return self.match.remaining_seconds(now)

    def view(self, now: float) -> FmsView:
        return FmsView.of(self, now)

    def snapshot(self, now: float | None = None) -> dict[str, Any]:
        """Everything a status line or panel shows, as JSON-able values; without ``now``, as
        of the last time the core was told (a test's look between steps)."""
        if now is None:
            now = self._now if self._now is not None else 0.0
        return self.view(now).snapshot()

    def start_refusals(self) -> list[str]:
        """Every reason a start would be refused now (empty: the match can start)."""
        reasons: list[str] = []
        key = (self.match.phase, Input.START)
        if key in REFUSALS:  # the table's own words: "match already running"
            reasons.append(REFUSALS[key])
        teams = False
        for st in self.stations:
            if st.estop:
                reasons.append(f"{st.name}: e-stopped")
            if st.team is None:
                continue
            teams = True
            if st.bypass:
                continue
            if not st.ds_link:
                reasons.append(f"{st.name}: not connected and not bypassed")
            elif st.status == "bad":
                where = st.wrong_station.label if st.wrong_station is not None else "?"
                reasons.append(f"{st.name}: DS at the wrong station ({where}) and not bypassed")
            elif st.challenge is Challenge.WRONG:
                reasons.append(f"{st.name}: its DS answered the challenge wrong; not bypassed")
            elif st.challenge is Challenge.LATE:
                reasons.append(f"{st.name}: its DS did not answer the challenge within "
                               f"{CHALLENGE_TIMEOUT:g} s; not bypassed")
            elif st.challenge is not Challenge.RIGHT:
                reasons.append(f"{st.name}: waiting for its DS's challenge answer")
        if not teams:
            reasons.append("no teams in the match")
        return reasons

    def start_warnings(self) -> list[str]:
        """What a start would not fix: each station whose robot will not be enabled though the
        match may start, because its DS reports an e-stop the field does not hold (the field's
        own e-stops clear with the next match; the robot's latch only with a code restart).
        Cheesy Arena shows such a station all green."""
        return [f"{st.name}: robot still e-stopped: restart its code" for st in self.stations
                if st.team is not None and not st.bypass and not st.estop and st.estop_status is not None]

    # -- the shell's events -------------------------------------------------------------------
    def shutdown(self) -> None:
        """Nothing of this core runs outside it (the shell calls this on every core)."""

    def datagram(self, channel: str, data: bytes, source: Address, now: float, arrived: float | None = None,
                 superseded: bool = False) -> list[Action]:
        """(``arrived``, ``superseded``: the one signature of every core; not judged here.)"""
        self._now = now
        if channel != UDP:
            self.udp_stats.bad(f"datagram on unknown channel {channel!r}", now)
            return []
        self.udp_stats.received(len(data), now)
        source = (str(source[0]), int(source[1])) if source else ("?", 0)
        # The source first, then the size, then the bytes (issue 27). Status is matched to a
        # station by the team number at bytes 4-5, so those two bytes are read to know whose
        # DS may send it: from anywhere else it is refused before it is decoded (a flood of
        # 64 KB datagrams costs a comparison each, whatever they hold). The decoder refuses
        # a packet over its size bound by its length alone.
        team = int.from_bytes(data[4:6], "big") if len(data) >= 6 else None
        st = self.station_of_team(team) if team is not None else None
        if st is not None and team is not None and not self._from_its_ds(st, source):  # (st: team is set)
            action, st.owner = owner_transition(st.owner, OwnerInput.STATUS_OTHER)
            if action is OwnerAction.REFUSE_STATUS:
                self._refuse_status(st, team, bool(data[3] & 0x80), source, now)
                return []
        try:
            pkt = decode_status(data)
        except ProtocolError as exc:
            self.udp_stats.bad(exc, now)
            # Where the team number is readable, the bad packet counts on its station too.
            if st is not None:
                st.link.received(len(data), now)
                st.link.bad(exc, now)
            return []
        st = self.station_of_team(pkt.team)
        if st is None:
            self.udp_unknown_team += 1
            return []
        event = OwnerInput.STATUS_OWN if self._from_its_ds(st, source) else OwnerInput.STATUS_OTHER
        action, st.owner = owner_transition(st.owner, event)
        if action is OwnerAction.REFUSE_STATUS:
            self._refuse_status(st, pkt.team, pkt.estop, source, now)
            return []
        st.link.received(len(data), now)
        self._status_received(st, pkt, source, now)
        self._sync()
        return []

    def stream_opened(self, conn: Hashable, peer: Address, now: float) -> list[Action]:
        self._now = now
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
            self.tcp_stats.bad(f"connection from {_addr(peer)} refused: {limit}", now)
            return actions + [Close(conn, "too many connections")]
        decoder = FrameDecoder(f"fms-tcp {_addr(peer)}", MAX_FRAME)
        self.connections[conn] = DsConnection(conn, peer, now, decoder, now)
        self.tcp_stats.connected = True
        return actions

    def stream_data(self, conn: Hashable, data: bytes, now: float) -> list[Action]:
        self._now = now
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
        self._sync()
        return actions

    def stream_closed(self, conn: Hashable, reason: str, now: float) -> list[Action]:
        self._now = now
        c = self.connections.pop(conn, None)
        if c is not None:
            self._detach(c, reason or "closed", now)
            self.tcp_stats.connected = bool(self.connections)
            self._sync()
        return []

    def poll(self, now: float) -> list[Action]:
        self._now = now
        actions, self._pending = self._pending, []
        for boundary, action in self.match.advance(now):
            self._phase_changed(action, boundary)  # each asks for a send at once

        for c in list(self.connections.values()):
            if now >= c.last_rx + TCP_TIMEOUT:
                actions += self._close(c, f"keep-alive timeout: no frame for {TCP_TIMEOUT:g} s", now)
        for st in self.stations:
            self._check_live(st, now)
            if st.udp_link and st.last_udp is not None and now >= st.last_udp + UDP_TIMEOUT:
                self._udp_lost(st, now)
            if st.challenge is Challenge.SENT and st.challenge_at is not None \
                    and now >= st.challenge_at + CHALLENGE_TIMEOUT:
                self._challenge_input(st, ChallengeInput.DEADLINE, now)

        if self._sends.origin is None:
            self._sends.start(now)
        skipped = self._sends.take(now)
        if skipped is not None:
            self.missed_sends += skipped
            self._send_now = True
        self._sync()
        if self._send_now:
            self._send_now = False
            actions += self._control_packets(now)
        return actions

    def next_deadline(self) -> float | None:
        if self._now is None:
            return None
        if self._pending or self._send_now or self._sends.origin is None:
            return self._now
        sends = self._sends.next
        assert sends is not None  # its origin is set (above)
        deadlines = [sends]
        end = self.match.period_end
        if end is not None:
            deadlines.append(end)
        deadlines.extend(c.last_rx + TCP_TIMEOUT for c in self.connections.values())
        deadlines.extend(st.last_udp + UDP_TIMEOUT for st in self.stations
                         if st.udp_link and st.last_udp is not None)
        deadlines.extend(self._live_until(st) for st in self.stations if st.owner is Owner.LIVE)
        deadlines.extend(st.challenge_at + CHALLENGE_TIMEOUT for st in self.stations
                         if st.challenge is Challenge.SENT and st.challenge_at is not None)
        return min(deadlines)

    # -- user commands ---------------------------------------------------------------------------
    def start_match(self, now: float) -> None:
        """Start auto, or raise MatchStartRefused listing every reason it cannot."""
        reasons = self.start_refusals()
        if reasons:
            self._log(now, f"{self.match.label} start refused: {'; '.join(reasons)}")
            raise MatchStartRefused(reasons)
        self._phase_changed(self.match.handle(Input.START, now), now)
        self._sync()

    def abort_match(self, now: float) -> None:
        """Disable everyone at once and end the match."""
        self._phase_changed(self.match.handle(Input.ABORT, now), now)
        self._sync()

    def reset(self, now: float) -> None:
        """Back to pre-match with the same match; after a played match that is a replay (the
        play number goes up). Clears every e-stop and a-stop. Not while a match runs."""
        played = self.match.phase is Phase.POST_MATCH
        self.match.handle(Input.RESET, now)
        if played:
            self.match.play = min(self.match.play + 1, 0xFF)
        self._clear_stops(now)
        self._phase_changed(MatchAction.RESET_MATCH, now)
        self._sync()

    def next_match(self, now: float, *, number: int | None = None,
                   level: TournamentLevel | int | None = None, play: int = 1) -> None:
        """Set up a new match (default: the next number, same type) in pre-match. Clears every
        e-stop and a-stop. Not while a match runs."""
        m = self.match
        if m.running:
            self.match.handle(Input.RESET, now)  # raises the table's refusal
        number = m.number + 1 if number is None else number
        m.setup(m.level if level is None else level, number, play)
        m.handle(Input.RESET, now)
        self._clear_stops(now)
        kind = m.level.name.lower() if isinstance(m.level, TournamentLevel) else f"level {int(m.level)}"
        self._log(now, f"{m.label} set up ({kind})")
        self._send_now = True
        self._sync()

    def set_timing(self, now: float, *, auto: float | None = None, pause: float | None = None,
                   teleop: float | None = None) -> None:
        """New period lengths (None: keep that one), for the next match that starts."""
        t = self.match.timing
        try:
            timing = MatchTiming(t.auto if auto is None else auto, t.pause if pause is None else pause,
                                 t.teleop if teleop is None else teleop)
        except ValueError as exc:
            raise CommandError(str(exc)) from None
        self.match.set_timing(timing)

    def set_teams(self, teams: Sequence[int | None], now: float) -> None:
        """Six teams for R1, R2, R3, B1, B2, B3 (None: empty). Not while a match runs."""
        self._set_teams(teams, now)

    def set_team(self, station: StationKey, team: int | None, now: float) -> None:
        st = self.station(station)
        teams = [s.team for s in self.stations]
        teams[int(st.station)] = team
        self._set_teams(teams, now)

    def estop(self, station: StationKey, now: float) -> None:
        """E-stop a station: latched until the match is reset or the next one is set up."""
        st = self.station(station)
        if not st.estop:
            st.estop, st.estop_by = True, "FMS"
            self._log(now, f"{st.name}: e-stop")
        self._send_now = True
        self._sync()

    def clear_estop(self, station: StationKey, now: float) -> None:
        st = self.station(station)
        if self.match.running:
            raise CommandError(f"{st.name}: an e-stop latches until the match is over")
        if st.estop:
            st.estop, st.estop_by = False, None
            self._log(now, f"{st.name}: e-stop cleared")
            self._send_now = True
        self._sync()

    def astop(self, station: StationKey, now: float) -> None:
        """A-stop a station: disabled for the rest of auto (only during auto)."""
        st = self.station(station)
        if self.match.phase is not Phase.AUTO:
            raise CommandError(f"{st.name}: a-stop works only during auto")
        if not st.astop:
            st.astop = True
            self._log(now, f"{st.name}: a-stop")
        self._send_now = True
        self._sync()

    def set_bypass(self, station: StationKey, on: bool, now: float) -> None:
        """Bypass a station (never enabled, not needed to start). Removing a bypass would
        enable a robot mid-match, so that waits until the match is over."""
        st = self.station(station)
        on = bool(on)
        if not on and st.bypass and self.match.running:
            raise CommandError(f"{st.name}: cannot remove a bypass while a match runs")
        if st.bypass != on:
            st.bypass = on
            self._log(now, f"{st.name}: {'bypassed' if on else 'bypass removed'}")
            self._send_now = True
        self._sync()

    def set_game_data(self, text: str, now: float) -> None:
        """Set the game-specific message and send it to every DS in the match."""
        self.game_data = _checked_text(GameData, text, CommandError)
        frame = GameData(self.game_data).encode()
        for st in self.stations:
            if st.conn is not None:
                self._pending.append(StreamSend(st.conn, frame, KIND_TCP))
        self._log(now, f"game data set to {self.game_data!r}")

    def set_event_code(self, code: str, now: float) -> None:
        self.event_code = _checked_text(EventCode, code, CommandError)

    # -- internals: logging -------------------------------------------------------------------
    def _log(self, now: float, text: str) -> None:
        self.match_log.append((now, text))
        self.match_log_total += 1
        self.events.add(now, text)

    def _sync(self) -> None:
        """Recompute what every station is commanded (the one place that decides enable)."""
        enabling = self.match.enabling
        auto = self.match.phase is Phase.AUTO
        for st in self.stations:
            st.enabled = (enabling and st.team is not None and not st.bypass and not st.estop
                          and not (st.astop and auto) and st.status != "bad" and st.challenge.trusted)
            st.link.connected = st.ds_link

    # -- internals: the match --------------------------------------------------------------------
    def _phase_changed(self, action: MatchAction, at: float) -> None:
        self._log(at, f"{self.match.label} {PHASE_EVENT[action]}")
        if self.match.phase is not Phase.AUTO:
            for st in self.stations:
                if st.astop:
                    st.astop = False
                    self._log(at, f"{st.name}: a-stop released (auto is over)")
        self._send_now = True

    def _clear_stops(self, now: float) -> None:
        for st in self.stations:
            if st.estop:
                st.estop, st.estop_by = False, None
                self._log(now, f"{st.name}: e-stop cleared")
            st.astop = False

    def _set_teams(self, teams: Sequence[int | None], now: float, quiet: bool = False) -> None:
        if self.match.running:
            raise CommandError("cannot change teams while a match runs")
        teams = list(teams)
        if len(teams) != 6:
            raise CommandError(f"six teams are needed (R1, R2, R3, B1, B2, B3), not {len(teams)}")
        for i, team in enumerate(teams):
            if team is not None:
                try:
                    check_team(team)
                except ValueError as exc:
                    raise CommandError(f"{AllianceStation(i).label}: {exc}") from None
        seen = [t for t in teams if t is not None]
        dupes = sorted({t for t in seen if seen.count(t) > 1})
        if dupes:
            raise CommandError(f"team {', '.join(map(str, dupes))} is in more than one station")

        moved: list[DsConnection] = []
        for st, team in zip(self.stations, teams):
            if st.team == team:
                continue
            old = st.name
            if st.conn is not None:
                c = self.connections.get(st.conn)
                if c is not None:
                    c.station = None
                    moved.append(c)
            st.team = team
            st.forget_ds()
            if not quiet:
                self._log(now, f"{old} -> {st.name}")
        # Every logged-in DS whose place changed hears about it: a new station or "waiting".
        for c in self.connections.values():
            if c.team is None:
                continue
            target = self.station_of_team(c.team)
            if c.station is target and c not in moved:
                continue
            if c.station is None and target is None and c not in moved:
                continue  # was waiting, still waiting
            self._pending += self._place(c, now)
        self._send_now = True
        self._sync()

    # -- internals: TCP ------------------------------------------------------------------------------
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
        st = c.station
        c.station = None
        if st is None or st.conn != c.conn:
            return
        _, st.owner = owner_transition(st.owner, OwnerInput.LOGOUT)
        self._challenge_input(st, ChallengeInput.FORGET, now)
        st.conn = None
        st.peer = None
        st.login_at = None
        st.status = None
        st.wrong_station = None
        st.status_port = None
        st.challenge_value, st.challenge_at, st.challenge_answer = None, None, None
        self._log(now, f"{st.name}: DS disconnected ({reason})")

    def _login_frame(self, c: DsConnection, frame: bytes, now: float) -> list[Action]:
        try:
            msg = decode_tcp(frame)
        except ProtocolError:
            msg = None
        if type(msg) is not TeamNumber:
            # docs/protocol.md#fms-login-rule: a first frame that is not a team number is closed, no reply.
            self.tcp_stats.bad(f"{_addr(c.peer)}: first frame is not a team number login: "
                               f"{frame[:8].hex(' ')}", now)
            return self._close(c, "first frame is not a team number", now)
        st = self.station_of_team(msg.team)
        if st is not None:
            self._check_live(st, now)  # a DS silent for a second is lost, polled yet or not
            login = self._login_input(st, msg.team, c.peer)
            action, _ = owner_transition(st.owner, login)
            if action is OwnerAction.REFUSE_LOGIN:
                return self._refuse_login(c, st, msg.team, login, now)
        c.team = msg.team
        actions: list[Action] = []
        for other in list(self.connections.values()):
            if other is not c and other.team == c.team:
                self._log(now, f"Team {c.team}: logged in again from {_addr(c.peer)}; "
                               "the old connection is closed")
                actions += self._close(other, "replaced by a new login", now)
        return actions + self._place(c, now)

    def _login_input(self, st: Station, team: int, peer: Address) -> OwnerInput:
        """Which login this is to the station's ownership table."""
        holder = st.peer if st.conn is not None else None
        if holder is not None and host_key(holder[0]) == host_key(peer[0]):
            return OwnerInput.LOGIN_SAME_HOST
        if team_from_address(peer[0]) == team and (holder is None or team_from_address(holder[0]) != team):
            return OwnerInput.LOGIN_HOME
        return OwnerInput.LOGIN_OTHER

    def _refuse_login(self, c: DsConnection, st: Station, team: int, login: OwnerInput,
                      now: float) -> list[Action]:
        if login is OwnerInput.LOGIN_SAME_HOST:
            # Both from one host: only the ports tell the two connections apart.
            text = (f"login as {team} from {_addr(c.peer)} refused: its DS is live on another "
                    f"connection from that host ({_addr(st.peer)})")
            reason = f"team {team}'s DS is live on another connection from this host"
        else:
            text = f"login as {team} from {self._who(c.peer)} refused: its DS {self._who(st.peer)} is live"
            reason = f"team {team}'s DS is live at another address"
        st.refused_logins += 1
        self.refused_logins += 1
        self.tcp_stats.foreign_packets += 1  # the FMS TCP row's "foreign": logins not followed
        self._refused(st, "login", text, c.peer, now)
        self.connections.pop(c.conn, None)
        self.tcp_stats.connected = bool(self.connections)
        return [Close(c.conn, reason)]

    def _place(self, c: DsConnection, now: float) -> list[Action]:
        """Tell a logged-in DS where it stands: its station, or waiting."""
        assert c.team is not None
        st = self.station_of_team(c.team)
        if st is None:
            c.station = None
            self._log(now, f"Team {c.team} logged in from {_addr(c.peer)}: not in this match, waiting")
            return [StreamSend(c.conn, StationInfo(AllianceStation.RED1, StationStatus.WAITING).encode(),
                               KIND_TCP)]
        if st.conn is not None and st.conn != c.conn and st.conn in self.connections:
            self.connections[st.conn].station = None  # a stale login for this station
        # TAKE: live, a second to show it. The station has no holder left here (a login closed
        # the team's other connection first; a team change forgot it), and from empty any
        # login takes it.
        _, st.owner = owner_transition(st.owner, self._login_input(st, c.team, c.peer))
        st.login_at = now
        st.status_port = None
        status = StationStatus.GOOD
        wrong = None
        at_team = team_from_address(c.peer[0])
        if at_team is not None and at_team != c.team:
            other = self.station_of_team(at_team)
            if other is not None and other is not st:
                status, wrong = StationStatus.BAD, other.station
        c.station = st
        st.conn, st.peer, st.last_tcp = c.conn, c.peer, now
        st.status = "good" if status is StationStatus.GOOD else "bad"
        st.wrong_station = wrong
        self._challenge_input(st, ChallengeInput.ASK, now)
        if wrong is None:
            self._log(now, f"{st.name}: DS logged in from {_addr(c.peer)}")
        else:
            self._log(now, f"{st.name}: DS logged in from {_addr(c.peer)}, which is "
                           f"{wrong.label}'s address: wrong station")
        frames = [StationInfo(st.station, status).encode(), EventCode(self.event_code).encode()]
        if self.game_data:
            frames.append(GameData(self.game_data).encode())
        assert st.challenge_value is not None  # drawn by the ASK above
        frames.append(ChallengeQuestion(random_value=st.challenge_value).encode())
        self._send_now = True  # its first control packet need not wait for the grid
        return [StreamSend(c.conn, f, KIND_TCP) for f in frames]

    def _frame(self, c: DsConnection, frame: bytes, now: float) -> None:
        st = c.station
        if st is not None:
            st.link.received(len(frame), now)
            st.last_tcp = now
        try:
            msg = decode_tcp(frame)
        except ProtocolError as exc:
            # Well framed but not what the layout says: dropped, the connection kept (a DS
            # whose frame we misread must not be thrown off the field).
            self._bad_tcp(c, exc, now)
            return
        if type(msg) in (DsPing, KeepAlive):
            return
        if type(msg) is TeamNumber:
            if msg.team != c.team:
                self._bad_tcp(c, f"team number {msg.team} on a connection logged in as {c.team}", now)
            return
        if st is None:
            return  # a waiting DS: nothing of it is kept
        if type(msg) is DeviceVersion:
            device = msg.device
            label = device.label if isinstance(device, VersionDevice) else f"device {device}"
            st.versions[label] = msg
        elif type(msg) is LogData:
            if msg.records:
                st.log_records.extend(msg.records)
                st.log_data = msg.records[-1]
        elif type(msg) is ErrorEventData:
            st.error_events.extend(msg.entries)
        elif type(msg) is UsageReport:
            st.usage_report = msg
        elif type(msg) is ChallengeResponse:
            self._challenge_response(st, c, msg.answer, now)

    def _challenge_response(self, st: Station, c: DsConnection, answer: str, now: float) -> None:
        right = (st.challenge_value is not None and c.team is not None
                 and check_challenge_answer(c.team, st.challenge_value, answer))
        self._challenge_input(st, ChallengeInput.ANSWER_RIGHT if right else ChallengeInput.ANSWER_WRONG,
                              now, answer)

    def _challenge_input(self, st: Station, event: ChallengeInput, now: float, answer: str = "") -> None:
        """Drive the station's challenge table (roles/cores/ownership.py) and carry out its action."""
        action, st.challenge = challenge_transition(st.challenge, event)
        if action is ChallengeAction.SEND_QUESTION:
            st.challenge_value = self.rng.randint(*CHALLENGE_RANGE)
            st.challenge_at, st.challenge_answer = now, None
        elif action is ChallengeAction.TRUST:
            st.challenge_answer = answer
            self._log(now, f"{st.name}: challenge answered")
        elif action is ChallengeAction.DISTRUST:
            answer = answer[:MAX_ANSWER]  # a frame may carry 16 KiB of it: the log keeps a name's worth
            st.challenge_answer = answer
            self.challenge_failures += 1
            expected = challenge_answer(st.team, st.challenge_value) if st.team and st.challenge_value else "?"
            self._log(now, f"{st.name}: WRONG challenge answer {answer!r} from {self._who(st.peer)} "
                           f"(expected {expected!r}): never enabled until its DS logs in again")
            self._send_now = True
        elif action is ChallengeAction.EXPIRE:
            self.challenge_failures += 1
            self._log(now, f"{st.name}: no challenge answer from {self._who(st.peer)} within "
                           f"{CHALLENGE_TIMEOUT:g} s: never enabled until its DS logs in again")
            self._send_now = True
        elif action is ChallengeAction.REFUSE_ANSWER:
            self.challenge_failures += 1
            what = "no question asked" if st.challenge is Challenge.NONE else "only the first answer counts"
            self._refused(st, "answer", f"{st.name}: challenge answer {answer[:MAX_ANSWER]!r} from "
                                        f"{self._who(st.peer)} refused: {what}", st.peer, now)
        self._sync()

    # -- internals: UDP ------------------------------------------------------------------------------
    def _status_received(self, st: Station, pkt: DsStatusPacket, source: Address, now: float) -> None:
        if st.last_sequence is not None:
            gap = (pkt.sequence - st.last_sequence - 1) & 0xFFFF
            if 0 < gap < 1000:  # a large jump is a restarted DS, not a loss
                st.link.lost_packets += gap
        st.last_sequence = pkt.sequence
        if self.ds_port is None and st.status_port is None:
            st.status_port = source[1]  # the ephemeral plan: this port, and no other, from now on
        if not st.udp_link:
            self._log(now, f"{st.name}: DS status arriving from {_addr(source)}")
        st.udp_link = True
        st.ds_address = source
        st.last_udp = now
        if pkt.robot_comms != st.robot_link:
            self._log(now, f"{st.name}: robot link {'up' if pkt.robot_comms else 'down'}")
        st.robot_link = pkt.robot_comms
        st.radio_ping = pkt.radio_ping
        st.rio_ping = pkt.rio_ping
        if pkt.estop and not st.ds_estop and self.match.running and not st.estop:
            # The DS e-stopped its robot mid-match: latched here like a station e-stop, so a
            # code restart that clears the DS's own latch does not bring the FMS's enable back.
            st.estop, st.estop_by = True, "DS"
            self._log(now, f"{st.name} e-stopped by its DS")
            self._send_now = True
        st.ds_estop = pkt.estop
        st.ds_enabled = pkt.enabled
        st.ds_mode = pkt.mode
        st.battery = pkt.battery
        comms = pkt.tag(CommsMetrics)
        if comms is not None:
            st.trip_time_ms = comms.average_trip_time_ms
            st.lost_packets = comms.lost_packets
            st.sent_packets = comms.sent_packets

    def _udp_lost(self, st: Station, now: float) -> None:
        st.udp_link = False
        st.robot_link = st.radio_ping = st.rio_ping = False
        st.ds_enabled = False
        self._log(now, f"{st.name}: DS lost (no UDP status for {UDP_TIMEOUT:g} s)")

    def _control_dest(self, st: Station) -> Address | None:
        """The host of the DS's TCP login (Cheesy Arena's choice): never an address a UDP
        packet named, so status from elsewhere cannot move a station's control packets."""
        if st.conn is None or st.peer is None or st.peer[0] == "?":
            return None  # control packets go to logged-in DSes only
        if self.ds_port is None:
            return (st.peer[0], st.status_port) if st.status_port is not None else None
        return (st.peer[0], self.ds_port)

    def _from_its_ds(self, st: Station, source: Address) -> bool:
        """Whether status came from the station's logged-in DS: its TCP login's host (and,
        with ``ds_port=None``, the port its first status came from)."""
        if st.conn is None or st.peer is None or host_key(source[0]) != host_key(st.peer[0]):
            return False
        return self.ds_port is not None or st.status_port in (None, source[1])

    def _live_until(self, st: Station) -> float:
        """When the station's DS counts as lost: a second after its last status, or after
        its login when no status came since."""
        heard = st.login_at if st.login_at is not None else -math.inf
        if st.last_udp is not None:
            heard = max(heard, st.last_udp)
        return heard + UDP_TIMEOUT

    def _check_live(self, st: Station, now: float) -> None:
        if st.owner is Owner.LIVE and now >= self._live_until(st):
            _, st.owner = owner_transition(st.owner, OwnerInput.SILENCE)  # MARK_LOST: logins may take it

    def _refuse_status(self, st: Station, team: int, estop: bool, source: Address, now: float) -> None:
        self.udp_stats.foreign_packets += 1
        st.link.foreign_packets += 1
        self.refused_status += 1
        if st.conn is None or st.peer is None:
            why = "no DS is logged in for it"
            st.unclaimed_status += 1
        else:
            ds = (st.peer[0], st.status_port) if self.ds_port is None and st.status_port is not None else st.peer
            why = f"its DS is {self._who(ds)}"
        what = " (e-stop)" if estop else ""
        self._refused(st, "status", f"status{what} for {team} from {self._who(source)} refused: {why}",
                      source, now)

    def _refused(self, st: Station, kind: str, text: str, source: Address | None, now: float) -> None:
        """Log a refusal by address, at most once a second per kind and station."""
        st.last_refused = self._who(source)
        held = self._throttle.due((kind, st.label), now)
        if held is not None:
            self._log(now, text + Throttle.suffix(held))

    def _who(self, address: Address | None) -> str:
        """An address as the log names it: the host; host:port in the ephemeral plan, where
        every role shares 127.0.0.1 and only the port tells them apart."""
        if not address:
            return "?"
        return f"{address[0]}:{address[1]}" if self.ds_port is None else str(address[0])

    # -- internals: room on TCP 1750 ---------------------------------------------------------------
    def _served(self, host: str) -> bool:
        """A DS's own address: a station's logged-in DS, or one naming a team in the match."""
        if any(st.peer is not None and st.conn is not None and host_key(st.peer[0]) == host
               for st in self.stations):
            return True
        team = team_from_address(host)
        return team is not None and self.station_of_team(team) is not None

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
        held = self._throttle.due(("evict", None), now)
        if held is not None:
            self._log(now, f"TCP {why}: closed {self._who(victim.peer)} ({reason}) to make room for "
                           f"{host}{Throttle.suffix(held)}")
        return self._close(victim, f"evicted to make room for a new connection: {reason}", now)

    def _control_packets(self, now: float) -> list[Action]:
        try:
            date = FmsDate.from_datetime(self.wall_clock())
        except (ValueError, OverflowError, TypeError, AttributeError):
            date = FmsDate()
        if not 0 <= date.year <= 0xFF:  # a clock outside 1900-2155 cannot be sent
            date = FmsDate()
        m = self.match
        remaining = m.remaining_seconds(now)
        auto = m.phase is Phase.AUTO
        actions: list[Action] = []
        for st in self.stations:
            dest = self._control_dest(st)
            if dest is None:
                continue
            data = FmsControlPacket(
                sequence=st.control_sequence, estop=st.estop, astop=st.astop and auto,
                enabled=st.enabled, mode=m.mode, station=st.station,
                tournament_level=m.level, match_number=m.number, play_number=m.play,
                date=date, remaining_seconds=remaining).encode()
            st.control_sequence = (st.control_sequence + 1) & 0xFFFF
            st.link.sent(len(data))
            self.udp_stats.sent(len(data))
            actions.append(Datagram(UDP, data, dest, KIND_CONTROL))
        return actions


def _addr(a: Address | None) -> str:
    return f"{a[0]}:{a[1]}" if a else "?"


def _checked_text(cls: type[EventCode | GameData], text: str, error: type[Exception]) -> str:
    """``text`` if ``cls(text)`` encodes (a u8-length string), else ``error``."""
    try:
        cls(text).encode()
    except ProtocolError as exc:
        raise error(f"{cls.__name__}: {exc.reason}") from None
    return text


__all__ = ["CONTROL_PERIOD", "DsConnection", "FieldManagementSystem", "MAX_CONNECTIONS", "MAX_FRAME", "MatchStartRefused",
           "Station", "TCP_TIMEOUT", "UDP", "UDP_TIMEOUT", "team_from_address"]
