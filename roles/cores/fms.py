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
* The 2027 FIRST Driver Station logs in with its hello instead (``0x1e``: the UDP port for
  its control, flags, its team as ASCII; docs/protocol.md#cheesy-2027), as Cheesy Arena
  takes it: it gets the hello reply (``00 06 1f station status flags team``) where the NI DS
  gets station info, the same station and status, and no challenge (no source says it
  answers one; Cheesy asks neither DS); a hello whose team is no number gets status 2 and is
  closed. Its control packets go to the port its hello named, and carry the game data as
  tag 0x20 (at most 8 bytes; longer game data is cut there, and that is logged) instead of
  TCP frame 0x1c. Everything else (ownership, status, the match) is the same for both.
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
  first time, within 5 s (an NI DS's login; a 2027 DS is asked none).
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

import datetime as _dt
import random
from dataclasses import replace
from typing import Any, Callable, Hashable, Iterable, Sequence

from protocol.ds_to_fms import CommsMetrics, DsStatusPacket, decode_status
from protocol.enums import AllianceStation, TournamentLevel
from protocol.errors import ProtocolError
from protocol.fms_to_ds import MAX_GAME_DATA_TAG, EventCode, FmsControlPacket, FmsDate, GameData, GameDataTag

from .addresses import DS_FMS_UDP, check_team
from .commands import (Bypass, Command, MatchControl, ReplayMatch, SetMatchTiming, SetUpMatch, StationAStop,
                       StationEStop)
from .core import Action, Address, CommandError, Datagram, Events, Grid, LinkStats, Stream, StreamSend, utc_now
from .fms_login import (KIND_TCP, MAX_CONNECTIONS, MAX_FRAME, PER_HOST, TCP_TIMEOUT, UDP_TIMEOUT, DsConnection,
                        Logins, Refusals, host_key, team_from_address)
from .fms_login import addr as _addr
from .fms_station import Station, readiness, start_refusal, station_of_team
from .match import PHASE_EVENT, REFUSALS, Input, Match, MatchTiming, Phase
from .match import Action as MatchAction
from .ownership import OwnerAction, OwnerInput, owner_transition
from .views import DsReport, EventsView, FmsView, MatchView, StationView, TimingView

#: The shell's channel for UDP 1160: status in, control packets out from the same socket.
UDP = "udp"
KIND_CONTROL = "fms-to-ds"

CONTROL_PERIOD = 0.5   # s between control packets
MATCH_LOG_SIZE = 10_000  # match-log entries kept (hundreds of matches)


class MatchStartRefused(CommandError):
    """A start that cannot happen; ``reasons`` lists every one of them."""

    def __init__(self, reasons: Iterable[str]) -> None:
        self.reasons = list(reasons)
        super().__init__("cannot start the match: " + "; ".join(self.reasons))

    def __reduce__(self) -> tuple[type[MatchStartRefused], tuple[list[str]]]:  # pickled with its reasons (a refusal from a wire process)
        return (type(self), (self.reasons,))




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
        self.rng = rng if rng is not None else random.Random(seed)
        self.wall_clock = wall_clock or utc_now
        self.match = Match(timing, TournamentLevel.PRACTICE, 1)
        try:
            self.match.setup(level, match_number)
        except CommandError as exc:
            raise ValueError(str(exc)) from None
        self.event_code = _checked_text(EventCode, event_code, ValueError)
        self.game_data = _checked_text(GameData, game_data, ValueError)
        self._cut_said: str | None = None  # the game data whose cut for a 2027 DS was logged

        self.stations: list[Station] = [Station(s) for s in AllianceStation]
        self.events = Events()
        #: Match-related happenings for the match log file: the last ``MATCH_LOG_SIZE``, numbered
        #: (its ``total``: a reader's cheap "anything new?"; total - len is how many scrolled
        #: out). Each one is also an ``events`` happening, as it is logged.
        self.match_log: Stream[tuple[float, str]] = Stream(MATCH_LOG_SIZE)
        self.udp_stats = LinkStats("fms-udp")
        self.udp_unknown_team = 0     # good status packets from a team not in the match
        self.refused_status = 0       # status for a station from an address that is not its DS's
        self.missed_sends = 0         # control slots skipped because a poll came late
        self.refusals = Refusals(ds_port, self._log)  # logged once a second per kind and station
        #: TCP 1750: connections, logins, the challenge (roles/cores/fms_login.py).
        self.logins = Logins(self.stations, self.refusals, self._log, self.rng, max_connections=max_connections,
                             per_host=per_host, greeting=self._greeting, wake=self._wake)

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
        return station_of_team(self.stations, team)

    @property
    def match_log_total(self) -> int:
        """Match log entries ever logged (the log keeps the last ``MATCH_LOG_SIZE``)."""
        return self.match_log.total

    def remaining(self, now: float) -> int:
        return self.match.remaining_seconds(now)

    def view(self, now: float) -> FmsView:
        m = self.match
        running, period = m.running, m.period_start
        return FmsView(
            at=now, udp_unknown_team=self.udp_unknown_team, refused_status=self.refused_status,
            refused_logins=self.logins.refused_logins, refused_connections=self.logins.refused_connections,
            evicted_connections=self.logins.evicted_connections, challenge_failures=self.logins.challenge_failures,
            missed_sends=self.missed_sends, game_data=self.game_data, event_code=self.event_code,
            match_log=self.match_log.view(), events=EventsView(self.events.items.view()),
            match=MatchView(phase=m.phase.value, running=running, level=m.level, number=m.number, play=m.play,
                            label=m.label, aborted=m.aborted, period_start=period,
                            timing=TimingView(m.timing.auto, m.timing.pause, m.timing.teleop)),
            stations=tuple(_station_view(st, running, period) for st in self.stations),
            connections=len(self.logins.connections), udp_stats=self.udp_stats.view(),
            tcp_stats=self.logins.tcp_stats.view(), refusals=tuple(self.start_refusals()),
            warnings=tuple(self.start_warnings()), remaining_left=self.remaining(now))

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
            if st.commands.estop:
                reasons.append(f"{st.name}: e-stopped")
            teams = teams or st.team is not None
            refusal = start_refusal(st)
            if refusal is not None:
                reasons.append(f"{st.name}: {refusal}")
        if not teams:
            reasons.append("no teams in the match")
        return reasons

    def start_warnings(self) -> list[str]:
        """What a start would not fix: each station whose robot will not be enabled though the
        match may start, because its DS reports an e-stop the field does not hold (the field's
        own e-stops clear with the next match; the robot's latch only with a code restart).
        Cheesy Arena shows such a station all green."""
        return [f"{st.name}: robot still e-stopped: restart its code" for st in self.stations
                if st.team is not None and not st.commands.bypass and not st.commands.estop
                and st.estop_status is not None]

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
            action, st.login.owner = owner_transition(st.login.owner, OwnerInput.STATUS_OTHER)
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
        action, st.login.owner = owner_transition(st.login.owner, event)
        if action is OwnerAction.REFUSE_STATUS:
            self._refuse_status(st, pkt.team, pkt.estop, source, now)
            return []
        st.link.received(len(data), now)
        self._status_received(st, pkt, source, now)
        self._sync()
        return []

    def stream_opened(self, conn: Hashable, peer: Address, now: float) -> list[Action]:
        self._now = now
        actions = self.logins.opened(conn, peer, now)
        self._sync()
        return actions

    def stream_data(self, conn: Hashable, data: bytes, now: float) -> list[Action]:
        self._now = now
        actions = self.logins.data(conn, data, now)
        self._sync()
        return actions

    def stream_closed(self, conn: Hashable, reason: str, now: float) -> list[Action]:
        self._now = now
        if self.logins.closed(conn, reason, now):
            self._sync()
        return []

    def poll(self, now: float) -> list[Action]:
        self._now = now
        actions, self._pending = self._pending, []
        for boundary, action in self.match.advance(now):
            self._phase_changed(action, boundary)  # each asks for a send at once

        actions += self.logins.poll(now)
        for st in self.stations:
            self.logins.check_live(st, now)
            report = st.report
            if report.udp_link and report.last_udp is not None and now >= report.last_udp + UDP_TIMEOUT:
                self._udp_lost(st, now)
            self.logins.check_challenge(st, now)

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
        deadlines.extend(st.report.last_udp + UDP_TIMEOUT for st in self.stations
                         if st.report.udp_link and st.report.last_udp is not None)
        deadlines.extend(self.logins.deadlines())
        return min(deadlines)

    # -- user commands ---------------------------------------------------------------------------
    def apply(self, command: Command, now: float) -> None:
        """Carry out one of the FMS's commands (roles/cores/commands.py FMS_COMMANDS), or raise
        CommandError saying why not (nothing changed)."""
        match command:
            case MatchControl(action=action):
                {"start": self.start_match, "abort": self.abort_match, "next": self.next_match}[action](now)
            case ReplayMatch():
                self.reset(now)
            case SetUpMatch(number=number, level=level):
                self.next_match(now, number=number, level=level)
            case SetMatchTiming(auto=auto, pause=pause, teleop=teleop):
                self.set_timing(now, auto=auto, pause=pause, teleop=teleop)
            case Bypass(station=station, on=on):
                self.set_bypass(station, on, now)
            case StationEStop(station=station, on=on):
                self.estop(station, now) if on else self.clear_estop(station, now)
            case StationAStop(station=station, on=on):
                if not on:
                    raise CommandError("an a-stop latches until auto ends; it cannot be taken back")
                self.astop(station, now)
            case _:
                raise CommandError(f"{command.verb} is not an FMS command")

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
        cmd = st.commands
        if not cmd.estop:
            cmd.estop, cmd.estop_by = True, "FMS"
            self._log(now, f"{st.name}: e-stop")
        self._send_now = True
        self._sync()

    def clear_estop(self, station: StationKey, now: float) -> None:
        st = self.station(station)
        cmd = st.commands
        if self.match.running:
            raise CommandError(f"{st.name}: an e-stop latches until the match is over")
        if cmd.estop:
            cmd.estop, cmd.estop_by = False, None
            self._log(now, f"{st.name}: e-stop cleared")
            self._send_now = True
        self._sync()

    def astop(self, station: StationKey, now: float) -> None:
        """A-stop a station: disabled for the rest of auto (only during auto)."""
        st = self.station(station)
        if self.match.phase is not Phase.AUTO:
            raise CommandError(f"{st.name}: a-stop works only during auto")
        if not st.commands.astop:
            st.commands.astop = True
            self._log(now, f"{st.name}: a-stop")
        self._send_now = True
        self._sync()

    def set_bypass(self, station: StationKey, on: bool, now: float) -> None:
        """Bypass a station (never enabled, not needed to start). Removing a bypass would
        enable a robot mid-match, so that waits until the match is over."""
        st = self.station(station)
        cmd = st.commands
        on = bool(on)
        if not on and cmd.bypass and self.match.running:
            raise CommandError(f"{st.name}: cannot remove a bypass while a match runs")
        if cmd.bypass != on:
            cmd.bypass = on
            self._log(now, f"{st.name}: {'bypassed' if on else 'bypass removed'}")
            self._send_now = True
        self._sync()

    def set_game_data(self, text: str, now: float) -> None:
        """Set the game-specific message and send it to every DS in the match."""
        self.game_data = _checked_text(GameData, text, CommandError)
        frame = GameData(self.game_data).encode()
        for st in self.stations:
            if st.login.conn is not None and st.login.hello is None:  # a 2027 DS's come in its control packets
                self._pending.append(StreamSend(st.login.conn, frame, KIND_TCP))
        self._send_now = True  # and at once to a 2027 DS
        self._log(now, f"game data set to {self.game_data!r}")

    # -- internals: logging -------------------------------------------------------------------
    def _log(self, now: float, text: str) -> None:
        self.match_log.append((now, text))
        self.events.add(now, text)

    def _wake(self) -> None:
        """Send control packets at the next poll, off the grid (a login, a refused challenge)."""
        self._send_now = True

    def _greeting(self, tcp_game_data: bool = True) -> list[bytes]:
        """What a login is told after its station: the event code, and the game data if set
        (``tcp_game_data`` False: a 2027 DS, whose control packets carry it)."""
        frames = [EventCode(self.event_code).encode()]
        if self.game_data and tcp_game_data:
            frames.append(GameData(self.game_data).encode())
        return frames

    def _tag_game_data(self, now: float) -> tuple[GameDataTag, ...]:
        """The game data as a 2027 DS's control packets carry it (tag 0x20): at most
        :data:`MAX_GAME_DATA_TAG` bytes, so longer game data is cut there, and that is said
        once per text (an NI DS gets it whole, on TCP)."""
        text = self.game_data
        if not text:
            return ()
        data = text.encode("utf-8")
        if len(data) > MAX_GAME_DATA_TAG:
            cut = data[:MAX_GAME_DATA_TAG].decode("utf-8", "ignore")  # whole characters only
            if self._cut_said != text:
                self._cut_said = text
                self._log(now, f"game data {text!r} is longer than the {MAX_GAME_DATA_TAG} bytes of a control "
                               f"packet's tag: a 2027 DS gets its first {MAX_GAME_DATA_TAG}, {cut!r}")
            text = cut
        return (GameDataTag(text),)

    def _sync(self) -> None:
        """Recompute what every station is commanded (the one place that decides enable)."""
        enabling = self.match.enabling
        auto = self.match.phase is Phase.AUTO
        for st in self.stations:
            cmd, login = st.commands, st.login
            cmd.enabled = (enabling and st.team is not None and not cmd.bypass and not cmd.estop
                           and not (cmd.astop and auto) and login.status != "bad" and login.trusted)
            st.link.connected = st.ds_link

    # -- internals: the match --------------------------------------------------------------------
    def _phase_changed(self, action: MatchAction, at: float) -> None:
        self._log(at, f"{self.match.label} {PHASE_EVENT[action]}")
        if self.match.phase is not Phase.AUTO:
            for st in self.stations:
                if st.commands.astop:
                    st.commands.astop = False
                    self._log(at, f"{st.name}: a-stop released (auto is over)")
        self._send_now = True

    def _clear_stops(self, now: float) -> None:
        for st in self.stations:
            cmd = st.commands
            if cmd.estop:
                cmd.estop, cmd.estop_by = False, None
                self._log(now, f"{st.name}: e-stop cleared")
            cmd.astop = False

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
            c = self.logins.unseat(st)
            if c is not None:
                moved.append(c)
            st.team = team
            st.forget_ds()
            if not quiet:
                self._log(now, f"{old} -> {st.name}")
        self._pending += self.logins.replace(moved, now)
        self._send_now = True
        self._sync()

    # -- internals: UDP ------------------------------------------------------------------------------
    def _status_received(self, st: Station, pkt: DsStatusPacket, source: Address, now: float) -> None:
        """A status from the station's own DS: a new report replaces the last one."""
        last = st.report
        if last.last_sequence is not None:
            gap = (pkt.sequence - last.last_sequence - 1) & 0xFFFF
            if 0 < gap < 1000:  # a large jump is a restarted DS, not a loss
                st.link.lost_packets += gap
        if self.ds_port is None and st.login.status_port is None:
            st.login.status_port = source[1]  # the ephemeral plan: this port, and no other, from now on
        if not last.udp_link:
            self._log(now, f"{st.name}: DS status arriving from {_addr(source)}")
        if pkt.robot_comms != last.robot_link:
            self._log(now, f"{st.name}: robot link {'up' if pkt.robot_comms else 'down'}")
        cmd = st.commands
        if pkt.estop and not last.ds_estop and self.match.running and not cmd.estop:
            # The DS e-stopped its robot mid-match: latched here like a station e-stop, so a
            # code restart that clears the DS's own latch does not bring the FMS's enable back.
            cmd.estop, cmd.estop_by = True, "DS"
            self._log(now, f"{st.name} e-stopped by its DS")
            self._send_now = True
        comms = pkt.tag(CommsMetrics)  # without it, the last figures stand
        st.report = DsReport(
            udp_link=True, ds_address=source, last_udp=now, last_sequence=pkt.sequence,
            robot_link=pkt.robot_comms, radio_ping=pkt.radio_ping, rio_ping=pkt.rio_ping,
            ds_estop=pkt.estop, ds_enabled=pkt.enabled, ds_mode=pkt.mode, battery=pkt.battery,
            trip_time_ms=last.trip_time_ms if comms is None else comms.average_trip_time_ms,
            lost_packets=last.lost_packets if comms is None else comms.lost_packets,
            sent_packets=last.sent_packets if comms is None else comms.sent_packets)

    def _udp_lost(self, st: Station, now: float) -> None:
        st.report = replace(st.report, udp_link=False, robot_link=False, radio_ping=False, rio_ping=False,
                            ds_enabled=False)
        self._log(now, f"{st.name}: DS lost (no UDP status for {UDP_TIMEOUT:g} s)")

    def _control_dest(self, st: Station) -> Address | None:
        """The host of the DS's TCP login (Cheesy Arena's choice): never an address a UDP
        packet named, so status from elsewhere cannot move a station's control packets."""
        login = st.login
        if login.conn is None or login.peer is None or login.peer[0] == "?":
            return None  # control packets go to logged-in DSes only
        if login.hello is not None:  # the 2027 DS names its port (Cheesy Arena sends there)
            return (login.peer[0], login.hello.udp_port)
        if self.ds_port is None:
            return (login.peer[0], login.status_port) if login.status_port is not None else None
        return (login.peer[0], self.ds_port)

    def _from_its_ds(self, st: Station, source: Address) -> bool:
        """Whether status came from the station's logged-in DS: its TCP login's host (and,
        with ``ds_port=None``, the port its first status came from)."""
        login = st.login
        if login.conn is None or login.peer is None or host_key(source[0]) != host_key(login.peer[0]):
            return False
        return self.ds_port is not None or login.status_port in (None, source[1])

    def _refuse_status(self, st: Station, team: int, estop: bool, source: Address, now: float) -> None:
        self.udp_stats.foreign_packets += 1
        st.link.foreign_packets += 1
        self.refused_status += 1
        login, who = st.login, self.refusals.who
        if login.conn is None or login.peer is None:
            why = "no DS is logged in for it"
            st.unclaimed_status += 1
        else:
            ds = (login.peer[0], login.status_port) if self.ds_port is None and login.status_port is not None \
                else login.peer
            why = f"its DS is {who(ds)}"
        what = " (e-stop)" if estop else ""
        self.refusals.refused(st, "status", f"status{what} for {team} from {who(source)} refused: {why}",
                              source, now)

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
            cmd = st.commands
            data = FmsControlPacket(
                sequence=cmd.control_sequence, estop=cmd.estop, astop=cmd.astop and auto,
                enabled=cmd.enabled, mode=m.mode, station=st.station,
                tournament_level=m.level, match_number=m.number, play_number=m.play,
                date=date, remaining_seconds=remaining,
                tags=self._tag_game_data(now) if st.login.hello is not None else ()).encode()
            cmd.control_sequence = (cmd.control_sequence + 1) & 0xFFFF
            st.link.sent(len(data))
            self.udp_stats.sent(len(data))
            actions.append(Datagram(UDP, data, dest, KIND_CONTROL))
        return actions


def _station_view(st: Station, running: bool, period_start: float | None) -> StationView:
    """What panels and ``--json`` see of a station: its parts' values, and its readiness."""
    login, cmd = st.login, st.commands
    state, reason = readiness(st, running, period_start)
    return StationView(
        station=st.station, team=st.team, name=st.name, link=st.link.view(),
        tcp_connected=st.tcp_connected, ds_link=st.ds_link, peer=login.peer, status=login.status,
        wrong_station=login.wrong_station, challenge=login.challenge.value, owner=login.owner.value,
        report=st.report,
        estop=cmd.estop, estop_by=cmd.estop_by, estop_status=st.estop_status, astop=cmd.astop, bypass=cmd.bypass,
        enabled=cmd.enabled, refused_logins=st.refused_logins, unclaimed_status=st.unclaimed_status,
        last_refused=st.last_refused, log_data=st.tcp.log_data,
        versions=tuple((k, v.version) for k, v in st.tcp.versions.items()), error_events=len(st.tcp.error_events),
        readiness=state.value, reason=reason, ds_kind=login.ds_kind)


def _checked_text(cls: type[EventCode | GameData], text: str, error: type[Exception]) -> str:
    """``text`` if ``cls(text)`` encodes (a u8-length string), else ``error``."""
    try:
        cls(text).encode()
    except ProtocolError as exc:
        raise error(f"{cls.__name__}: {exc.reason}") from None
    return text


__all__ = ["CONTROL_PERIOD", "DsConnection", "FieldManagementSystem", "MAX_CONNECTIONS", "MAX_FRAME", "MatchStartRefused",
           "Station", "TCP_TIMEOUT", "UDP", "UDP_TIMEOUT", "host_key", "team_from_address"]