"""The Driver Station's FMS client: login, keep-alive, status and obeying the field.

Links: TCP conn ``"fms-tcp"`` to ``fms_tcp`` (1750); UDP channels ``"fms"`` and
``"fms-lite"`` receive FMS control packets (the shell binds them on ports 1121 and 1120: an
FMS in "FMS Lite" mode, Cheesy Arena's setting, sends to 1120, and a real DS takes either);
UDP channel ``"fms-out"`` sends the DS status packet to ``fms_udp`` (1160).

* Login: the first frame on every connection is the team number (``00 03 18 hi lo``), as the
  NI DS logs in (the default); a challenge question (0x1a) is answered with
  ``challenge_answer(team, random)`` (0x1b). As the 2027 FIRST Driver Station (``hello="2027"``,
  Cheesy Arena's "new DS" path, docs/protocol.md#cheesy-2027) it is the hello (0x1e) instead,
  naming the UDP port control must come to (``hello_port``, 1121 on a real field); the FMS's
  hello reply (0x1f) is taken as station info (0x19) is, and game data comes as tag 0x20 of
  the control packet instead of TCP frame 0x1c. The robot link is the same either way.
* While the TCP connection is up: a DS ping (0x1d, as Cheesy Arena and open-ds; an FMS
  drops a DS after 5 s of TCP silence) every 2 s, a log-data record (0x16) every 3 s, and
  the UDP status every 500 ms on its own grid, with the comms-metrics tag (lost, sent,
  average trip time). Both carry the same round-trip figure in ms.
* Control packets are obeyed only from the FMS it logged in to: the host of its TCP
  connection, and one source port per login, the ``fms_udp`` port (fieldbox's FMS sends
  from 1160) or else the port of the first control packet (Cheesy Arena sends from one
  socket per DS connection, on a port of the OS's). Anything else is counted in
  ``foreign_packets`` (and the ``fms-udp`` link's), logged at most once a second by address,
  and dropped before decoding; while they go on, :meth:`~FmsClient.refusal` says so for the
  screens (an FMS whose station info says "good" but whose control is refused never enables). From a configured FMS host while no TCP connection is up,
  they are counted in ``ignored_packets``: a DS attaches only to an FMS it is logged in to.
* The first accepted control packet attaches the DS: the FMS decides enable, mode and
  station, control goes to the robot's port 1115 with the FMS bit, and the remaining time is
  sent as the countdown tag. E-stop latches in the DS (its enable arbiter,
  roles/cores/ds_enable.py); a-stop disables until auto ends. The operator's ``disable()`` or
  e-stop asks this client to :meth:`~FmsClient.hold` the robot disabled until the FMS changes
  phase, as its control packets show it (another match or play, another mode, or an enable
  when the hold began in a disabled period: pre-match to auto, pause to teleop) or detaches;
  one packet saying "disabled" mid-period does not end it, so neither can a forged one. No
  control packet for 1 s, or the TCP connection closing, detaches: disabled, back to local
  control, and the operator must enable again.
* A login the FMS answers with station status "waiting" (this team is not in the loaded
  match) goes quiet: no ping, no log data, no UDP status on it, so an FMS that drains such a
  connection until a read times out (Cheesy Arena, 5 s) closes it; after
  :data:`WAITING_REDIAL` the DS closes it itself (for an FMS that keeps it open), and logs in
  again at once, so a DS that connected before its match was loaded is in it within about
  5 s of the load. An FMS that places a waiting DS when its match is loaded (fieldbox's) does
  so at once on the open connection.
* The radio-ping and roboRIO-ping status bits are set from robot comms: this DS does not
  ping, and a robot that answers control packets is one that answers pings.

What the field asks of the DS itself (attach, detach, e-stop, match info, game data) comes
out as events (:data:`FmsEvent`, :meth:`FmsClient.take_events`) that the DS applies: the
client reads the DS's public state (team, trip time, battery), writes only its own event
log lines and link counters, and never calls into it. What it tells the FMS about the DS (team,
enable, robot comms, battery, packet counts) it asks of the DS as a :class:`DsReport`, a
frozen value the DS makes when a login, a status packet or a log record needs one.
"""

from __future__ import annotations

import ipaddress
import math
from typing import Any, Callable

from protocol import fms_to_ds
from protocol.ds_to_fms import (ChallengeResponse, CommsMetrics, DsHello, DsPing, DsStatusPacket, LogData,
                                LogRecord, TeamNumber, challenge_answer, quantize_battery)
from protocol.ds_to_rio import MatchInfo
from protocol.enums import MatchType, Mode, StationStatus, TournamentLevel
from dataclasses import dataclass

from protocol.errors import ProtocolError
from protocol.framing import FrameDecoder
from protocol.rio_to_ds import StatusPacket

from .core import (Action, Address, Close, Connect, Datagram, Events, Grid, LinkStats, StreamSend, Throttle,
                   decode_frames)
from .views import FmsLinkView

FMS_TCP = "fms-tcp"
FMS_OUT = "fms-out"
#: The UDP channels FMS control packets arrive on: port 1121, and 1120 ("FMS Lite").
FMS_CONTROL_CHANNELS = ("fms", "fms-lite")
STATUS_PERIOD = 0.5
PING_PERIOD = 2.0
LOG_PERIOD = 3.0
FMS_TIMEOUT = 1.0
FMS_RETRY = 1.0
#: A login answered "waiting" is dropped and made again after this long, quiet until then.
#: Why quiet, and why 5 s: Cheesy Arena (field/driver_station_connection.go,
#: handleInvalidTcpConnection, 2026) answers the login of a team not in the loaded match with
#: status 2 and then only reads the connection until a read fails, each read with its 5 s TCP
#: link timeout; it never assigns that connection to the match. Its earlier versions closed
#: such a connection after 1 s "so it doesn't chew up bandwidth constantly trying to
#: reconnect". Both rest on what the NI DS does: it sends nothing on a connection that is
#: waiting, and logs in again when it closes. A DS that kept sending keep-alives there (as
#: fieldbox did) was never let into its match (issue 29, seen with Cheesy Arena).
WAITING_REDIAL = 5.0
#: A refused control packet is shown on the screens (the DS tab, headless, Faults) this long
#: after it came: an FMS sends one every 500 ms, so a refusal that goes on stays shown.
REFUSAL_SHOWN = 2.0
MAX_EVENT_CODE = 64
#: How a DS logs in to an FMS: ``ni`` (the NI Driver Station: team number 0x18, station info
#: 0x19, game data on TCP) or ``2027`` (the 2027 FIRST Driver Station: hello 0x1e, hello
#: reply 0x1f, game data as control packet tag 0x20).
HELLOS = ("ni", "2027")
#: What each is called on the screens.
HELLO_NAMES = {"ni": "NI DS", "2027": "2027 DS"}
#: The UDP port a 2027 hello names when none is given: the DS's control port on a real field.
HELLO_PORT = 1121
#: FMS frames are short (the longest is a u8-length string): anything above is garbage.
MAX_FMS_FRAME = 1024

_MATCH_TYPES: dict[int, MatchType] = {TournamentLevel.MATCH_TEST: MatchType.NONE, TournamentLevel.PRACTICE: MatchType.PRACTICE,
                TournamentLevel.QUALIFICATION: MatchType.QUALIFICATION,
                TournamentLevel.PLAYOFF: MatchType.ELIMINATION}
_STATION_STATUS: dict[int, str] = {StationStatus.GOOD: "good", StationStatus.BAD: "wrong station",
                   StationStatus.WAITING: "waiting"}


# -- what the client tells its DS ----------------------------------------------------------
@dataclass(frozen=True, slots=True)
class Attached:
    """The first control packet from the FMS logged in to: the field decides from now on."""


@dataclass(frozen=True, slots=True)
class Detached:
    reason: str  # no control packet for a second, or the TCP connection closed


@dataclass(frozen=True, slots=True)
class Estopped:
    """The FMS's control packet carries the e-stop bit."""


@dataclass(frozen=True, slots=True)
class MatchInfoChanged:
    info: MatchInfo


@dataclass(frozen=True, slots=True)
class GameDataChanged:
    text: str


FmsEvent = Attached | Detached | Estopped | MatchInfoChanged | GameDataChanged


# -- what the DS tells the client ----------------------------------------------------------
@dataclass(frozen=True, slots=True)
class DsReport:
    """What the FMS is told of its DS at one moment: the login's team, the status packet's
    bits and comms metrics, a log record's figures. ``status`` is the robot's last status
    packet while robot comms are up (None otherwise); ``can_utilization`` its CAN tag's."""

    team: int
    robot_comms: bool
    estopped: bool
    enabled: bool
    mode: Mode
    battery: float | None
    brownout: bool
    lost_packets: int
    sent_packets: int
    trip_ms: float | None
    status: StatusPacket | None
    can_utilization: float | None


def _half(value: float | None) -> float:
    """A value for a "halved" u8 log field: steps of 0.5, 0..127.5, 0 for nothing/NaN/inf."""
    if value is None or not math.isfinite(value):
        return 0.0
    return min(max(round(value * 2), 0), 0xFF) / 2


def _host(host: str) -> str:
    """One spelling per host (an IPv4-mapped IPv6 address as its IPv4)."""
    try:
        ip = ipaddress.ip_address(host)
    except ValueError:
        return host.lower()
    if ip.version == 6 and ip.ipv4_mapped is not None:
        return str(ip.ipv4_mapped)
    return str(ip)


def _phase_of(control: fms_to_ds.FmsControlPacket | None) -> tuple[Any, ...] | None:
    """The FMS's phase as its control packets show it: the match, the mode and the enable."""
    if control is None:
        return None
    return (control.tournament_level, control.match_number, control.play_number, control.mode, control.enabled)


def _phase_changed(hold: tuple[Any, ...], now: tuple[Any, ...] | None) -> bool:
    """Whether the FMS changed phase since an operator's hold began: another match, play or
    mode (auto to the pause, a new match's pre-match), or an enable after a hold that began
    disabled (pre-match to auto, pause to teleop). A disabled packet mid-period is not one:
    an a-stop, an FMS e-stop (latched here anyway) or a forgery look just like it."""
    if now is None or hold[:4] != now[:4]:
        return True
    return not hold[4] and now[4]


def _round_trip_ms(value: float | None) -> int:
    """The round trip as the comms tag and the log data both carry it: whole ms, 0..255."""
    if value is None or not math.isfinite(value):
        return 0
    return min(max(round(value), 0), 0xFF)


class FmsReports:
    """What the DS tells the FMS it is logged in to, each on its own grid from the login: the
    UDP status every 500 ms (with the comms metrics), a ping every 2 s and a log-data record
    every 3 s on TCP. Both carry the same round-trip figure, from the DS's :class:`DsReport`."""

    def __init__(self) -> None:
        self._status_seq = 0
        self._status, self._ping, self._log = Grid(STATUS_PERIOD), Grid(PING_PERIOD), Grid(LOG_PERIOD)
        self._logged_lost = 0  # the DS's lost packets when the last log record went

    def start(self, now: float, lost_packets: int) -> None:
        self._status.start(now)
        self._ping.start(now + PING_PERIOD)
        self._log.start(now + LOG_PERIOD)
        self._logged_lost = lost_packets

    def stop(self) -> None:
        for grid in (self._status, self._ping, self._log):
            grid.stop()

    def next_deadline(self) -> float:
        status, ping, log = self._status.next, self._ping.next, self._log.next
        if status is None or ping is None or log is None:  # the three start and stop together
            return math.inf
        return min(status, ping, log)

    def due(self, now: float, report: Callable[[], DsReport], send_status: bool) -> tuple[bytes | None, list[bytes]]:
        """``(status datagram or None, TCP frames)`` due at ``now``; the status is made only when
        it can be sent (``send_status``), so its sequence counts only those that went. A late
        look sends each once (missed slots are skipped). ``report`` is asked only when one is due."""
        status: bytes | None = None
        frames: list[bytes] = []
        if self._status.take(now) is not None and send_status:
            status = self._status_packet(report()).encode()
        if self._ping.take(now) is not None:
            frames.append(DsPing().encode())
        if self._log.take(now) is not None:
            frames.append(self._log_data(report()).encode())
        return status, frames

    def _status_packet(self, ds: DsReport) -> DsStatusPacket:
        seq = self._status_seq
        self._status_seq = (seq + 1) & 0xFFFF
        metrics = CommsMetrics(min(ds.lost_packets, 0xFFFF), min(ds.sent_packets, 0xFFFF),
                               _round_trip_ms(ds.trip_ms))
        comms = ds.robot_comms
        return DsStatusPacket(seq, 0x00, ds.estopped, comms, comms, comms, ds.enabled, ds.mode, ds.team,
                              quantize_battery(ds.battery or 0.0), (metrics,))

    def _log_data(self, ds: DsReport) -> LogData:
        lost = ds.lost_packets - self._logged_lost
        self._logged_lost = ds.lost_packets
        enabled, mode = ds.enabled, ds.mode
        s = ds.status
        record = LogRecord(
            trip_time_ms=_round_trip_ms(ds.trip_ms), lost_packets=min(max(lost, 0), 0xFF),
            battery=quantize_battery(ds.battery or 0.0), brownout=ds.brownout, watchdog=False,
            ds_teleop=enabled and mode == Mode.TELEOP, ds_auto=enabled and mode == Mode.AUTONOMOUS,
            ds_disabled=not enabled,
            robot_teleop=bool(s and s.user_teleop), robot_auto=bool(s and s.user_auto),
            robot_disabled=bool(s and s.user_disabled),
            can_utilization=_half(ds.can_utilization))
        return LogData((record,))


class FmsClient:
    """The FMS half of one DS. ``report`` makes the DS's :class:`DsReport` (what the FMS is
    told), ``events`` is its event log."""

    def __init__(self, report: Callable[[], DsReport], events: Events, fms_tcp: Address | None,
                 fms_udp: Address | None, hello: str = "ni", hello_port: int = HELLO_PORT) -> None:
        if hello not in HELLOS:
            raise ValueError(f"hello must be one of {', '.join(HELLOS)}, not {hello!r}")
        if not (isinstance(hello_port, int) and 0 < hello_port <= 0xFFFF):
            raise ValueError(f"hello_port must be a port number, not {hello_port!r}")
        self.hello = hello
        #: The UDP port a 2027 hello asks control to come to: the shell sets it to the port the
        #: ``"fms"`` channel got when the OS chose it (the ephemeral plan).
        self.hello_port = hello_port
        self._report = report
        self.events = events
        self.udp_stats = LinkStats("fms-udp")
        self.tcp_stats = LinkStats("fms-tcp")
        self.fms_tcp = fms_tcp
        self.fms_udp = fms_udp
        self.tcp_state = "closed"  # closed | connecting | open
        self._retry_at = -math.inf
        self._decoder: FrameDecoder | None = None
        self.attached = False
        self.control: fms_to_ds.FmsControlPacket | None = None
        self._last_control = -math.inf
        self.astop_active = False
        # The operator's hold (disable or e-stop while attached, :meth:`hold`): the FMS phase
        # it began in, as _phase_of says it, or None. ``hold_disabled`` is its yes/no face.
        self._hold: tuple[Any, ...] | None = None
        self.fms_host: str | None = None            # the host of the TCP connection logged in to
        self.control_source: Address | None = None  # where this login's control packets come from
        self._throttle = Throttle()
        self._to_apply: list[FmsEvent] = []  # for the DS to apply (take_events)
        self.station_info: fms_to_ds.StationInfo | None = None
        self.hello_reply: fms_to_ds.HelloReply | None = None  # a 2027 login's answer, as it came
        self.event_code: str | None = None
        self.game_data: str | None = None
        self.foreign_packets = 0
        self._refusal: tuple[float, str, str] | None = None  # (when, from host, the words) of the last
        self.ignored_packets = 0
        self.unknown_frames = 0
        self.challenges_answered = 0
        self._reports = FmsReports()
        self._waiting_since: float | None = None  # when the FMS said "waiting" on this login

    # -- what panels read ----------------------------------------------------------------
    @property
    def configured(self) -> bool:
        return self.fms_tcp is not None

    @property
    def hosts(self) -> set[str]:
        return {a[0] for a in (self.fms_tcp, self.fms_udp) if a is not None}

    @property
    def hold_disabled(self) -> bool:
        """The operator's disable (or e-stop) holds the robot disabled under the FMS."""
        return self._hold is not None

    def hold(self, now: float) -> None:
        """The operator's disable or e-stop under this FMS: the robot is held disabled until the
        FMS changes phase, as its control packets show it, or detaches. Asked again, the hold
        starts over from the current phase."""
        # () when no control packet came yet: any packet is then a change of phase
        self._hold = _phase_of(self.control) or ()

    @property
    def status(self) -> str:
        """``off``, ``connecting``, ``connected`` (logged in, no station info yet), or what the
        station info says: ``good``, ``wrong station``, ``waiting``."""
        if not self.configured:
            return "off"
        if self.tcp_state != "open":
            return "connecting"
        if self.station_info is None:
            return "connected"
        return _STATION_STATUS.get(self.station_info.status, f"status {int(self.station_info.status)}")

    def refusal(self, now: float) -> tuple[str, str] | None:
        """``(host, words)`` of the last FMS control refused, while refusals go on (one in the
        last :data:`REFUSAL_SHOWN` s), else None. A DS logged in to one address of an FMS that
        sends control from another (Cheesy Arena on one machine: 127.0.0.1, while the DS
        dialled 127.0.100.5) shows "FMS good" and never enables: this says why."""
        if self._refusal is None or now - self._refusal[0] >= REFUSAL_SHOWN:
            return None
        return self._refusal[1], self._refusal[2]

    def view(self, now: float) -> FmsLinkView:
        refusal = self.refusal(now)
        return FmsLinkView(self.attached, self.status, self.foreign_packets,
                           None if refusal is None else refusal[0], None if refusal is None else refusal[1])

    @property
    def robot_enabled(self) -> bool:
        c = self.control
        return self.attached and c is not None and c.enabled and not self.astop_active and not self.hold_disabled

    # -- the core contract (called by the DS) -----------------------------------------------
    def next_deadline(self) -> float | None:
        if not self.configured:
            return None
        deadline = math.inf
        if self.attached:
            deadline = self._last_control + FMS_TIMEOUT
        if self.tcp_state == "closed":
            deadline = min(deadline, self._retry_at)
        elif self._waiting_since is not None:  # open and quiet: until it is dropped
            deadline = min(deadline, self._waiting_since + WAITING_REDIAL)
        elif self.tcp_state == "open":
            deadline = min(deadline, self._reports.next_deadline())
        return None if deadline == math.inf else deadline

    def poll(self, now: float) -> list[Action]:
        if self.fms_tcp is None:  # not configured
            return []
        out: list[Action] = []
        if self.attached and now - self._last_control >= FMS_TIMEOUT:
            self._detach(now, "no FMS control packet for 1 s")
        if self._waiting_since is not None and now >= self._waiting_since + WAITING_REDIAL:
            why = f"waiting for {WAITING_REDIAL:g} s: logging in again"
            self.stream_closed(why, now)  # and at once (stream_closed after waiting)
            out.append(Close(FMS_TCP, why))
        if self.tcp_state == "closed" and now >= self._retry_at:
            self.tcp_state = "connecting"
            out.append(Connect(FMS_TCP, self.fms_tcp))
        if self.tcp_state != "open":
            return out
        status, frames = self._reports.due(now, self._report, self.fms_udp is not None)
        if status is not None and self.fms_udp is not None:  # (status is None without fms_udp)
            self.udp_stats.sent(len(status))
            out.append(Datagram(FMS_OUT, status, self.fms_udp, "ds-to-fms"))
        out += [self._send(frame) for frame in frames]
        return out

    def datagram(self, data: bytes, source: Address, now: float) -> list[Action]:
        stats = self.udp_stats
        source = (str(source[0]), int(source[1]))
        logged_in = self.tcp_state == "open" and self.fms_host is not None
        if not self.configured or not (self._from_its_fms(source) if logged_in else source[0] in self.hosts):
            self.foreign_packets += 1
            stats.foreign_packets += 1
            self._refused(source, now)
            return []
        try:
            pkt = fms_to_ds.decode_control(data)
        except ProtocolError as exc:
            stats.bad(exc, now)
            return []
        stats.received(len(data), now)
        if not logged_in:
            self.ignored_packets += 1
            return []
        if self.control_source is None or self._is_fms_udp(source):
            self.control_source = source  # this login's FMS socket, from now on
        self._last_control = now
        self.control = pkt
        if self._hold is not None and self.attached and _phase_changed(self._hold, _phase_of(pkt)):
            self._hold = None  # the FMS moved on: the operator's hold ends with the phase it began in
        if not self.attached:
            self.attached = True
            self._hold = None
            self._to_apply.append(Attached())
        if pkt.estop:
            self._to_apply.append(Estopped())
        if self.hello == "2027" and pkt.game_data is not None:
            self._game_data(pkt.game_data)
        if pkt.mode == Mode.AUTONOMOUS:
            if pkt.astop and not self.astop_active:
                self.astop_active = True
                self.events.add(now, "A-STOP from the FMS: disabled until teleop")
        elif self.astop_active:
            self.astop_active = False
            self.events.add(now, "a-stop over: auto ended")
        self._update_match_info()
        return []

    def _from_its_fms(self, source: Address) -> bool:
        """From the host logged in to, and this login's FMS socket: ``fms_udp`` exactly, or
        the source of the first control packet accepted."""
        if _host(source[0]) != self.fms_host:
            return False
        return self._is_fms_udp(source) or self.control_source is None or source[1] == self.control_source[1]

    def _is_fms_udp(self, source: Address) -> bool:
        """``fms_udp`` itself (fieldbox's FMS sends from its 1160): always its FMS's socket,
        even after another port of that host got in first."""
        return (self.fms_udp is not None and source[1] == self.fms_udp[1]
                and _host(self.fms_udp[0]) == _host(source[0]))

    def _refused(self, source: Address, now: float) -> None:
        if self.tcp_state == "open" and self.fms_host is not None:
            src = self.control_source
            why = (f"its FMS is {src[0]}:{src[1]}" if src else
                   f"this DS obeys only the FMS it logged in to, at {self.fms_host}")
        elif self.configured:
            why = "not from the FMS this DS logs in to"
        else:
            why = "no FMS is configured"
        self._refusal = (now, source[0], f"FMS control from {source[0]} refused: {why}")
        held = self._throttle.due("control", now)
        if held is None:
            return
        self.events.add(now, f"FMS control from {source[0]}:{source[1]} refused: {why}"
                                + Throttle.suffix(held))

    def stream_opened(self, peer: Address, now: float) -> list[Action]:
        self.tcp_state = "open"
        self._waiting_since = None
        self.fms_host = _host(str(peer[0])) if peer else None
        self.control_source = None
        self._decoder = FrameDecoder("fms-tcp", MAX_FMS_FRAME)
        self.tcp_stats.connected = True
        self.station_info = self.hello_reply = None
        report = self._report()
        self._reports.start(now, report.lost_packets)
        if self.hello == "2027":
            self.events.add(now, f"FMS TCP connected ({peer[0]}:{peer[1]}): logging in as team {report.team}, "
                                 f"as a 2027 DS (control to UDP {self.hello_port})")
            return [self._send(DsHello.for_team(report.team, self.hello_port).encode())]
        self.events.add(now, f"FMS TCP connected ({peer[0]}:{peer[1]}): logging in as team {report.team}")
        return [self._send(TeamNumber(report.team).encode())]

    def stream_data(self, data: bytes, now: float) -> list[Action]:
        if self.tcp_state != "open" or self._decoder is None:
            return []
        stats = self.tcp_stats
        messages, error = decode_frames(self._decoder, data, fms_to_ds.decode_tcp, stats, now)
        out: list[Action] = []
        for msg in messages:
            out += self._on_frame(msg, now)
        if error is not None and self.tcp_state == "open":
            self.stream_closed("bad frame", now)
            out.append(Close(FMS_TCP, f"bad frame: {error}"))
        return out

    def stream_closed(self, reason: str, now: float) -> None:
        if self.tcp_state == "closed":
            return
        if self.tcp_state == "open":
            self.events.add(now, f"FMS TCP closed: {reason}")
        self.tcp_state = "closed"
        self.fms_host = self.control_source = None
        # A waiting login that ends (its FMS's read timeout, or ours) is made again at once:
        # it was quiet for seconds, so this cannot become a storm of logins.
        self._retry_at = now if self._waiting_since is not None else now + FMS_RETRY
        self._waiting_since = None
        self._decoder = None
        self.station_info = self.hello_reply = None
        self.tcp_stats.connected = False
        self._reports.stop()
        if self.attached:
            self._detach(now, f"FMS TCP closed: {reason}")

    def relogin(self, now: float) -> list[Action]:
        """After a team change: drop the connection so the next one logs in anew."""
        if self.tcp_state == "closed":
            return []
        self.stream_closed("team changed", now)
        self._retry_at = now
        return [Close(FMS_TCP, "team changed")]

    def set_addresses(self, fms_tcp: Address | None, fms_udp: Address | None, now: float) -> list[Action]:
        """Point the client at another FMS (None turns it off); returns the Close to perform."""
        out = self.relogin(now) if (fms_tcp, fms_udp) != (self.fms_tcp, self.fms_udp) else []
        self.fms_tcp, self.fms_udp = fms_tcp, fms_udp
        return out

    # -- internals --------------------------------------------------------------------------
    def _send(self, frame: bytes) -> StreamSend:
        self.tcp_stats.sent(len(frame))
        return StreamSend(FMS_TCP, frame, "ds-to-fms-tcp")

    def _on_frame(self, msg: Any, now: float) -> list[Action]:
        kind = type(msg)
        if kind is fms_to_ds.ChallengeQuestion:
            self.challenges_answered += 1
            answer = challenge_answer(self._report().team, msg.random_value)
            return [self._send(ChallengeResponse(answer).encode())]
        if kind is fms_to_ds.HelloReply:
            # The 2027 DS's station info: the same station and status, and the FMS's mode.
            if msg != self.hello_reply:
                self.hello_reply = msg
                lite = "FMS Lite" if msg.fms_lite else "full FMS"
                self.events.add(now, f"FMS: hello answered for team {msg.team} ({lite})")
            msg = fms_to_ds.StationInfo(msg.station, msg.status)
            kind = fms_to_ds.StationInfo
        if kind is fms_to_ds.StationInfo:
            if msg != self.station_info:
                self.station_info = msg
                text = _STATION_STATUS.get(msg.status, f"status {int(msg.status)}")
                if msg.status == StationStatus.BAD:
                    text = f"wrong station: the FMS expects team {self._report().team} at {msg.station.label}"
                elif msg.status == StationStatus.GOOD:
                    text = f"station {msg.station.label}: good"
                else:
                    text = "waiting: this team is not in the current match"
                self.events.add(now, f"FMS: {text}")
            self._wait(msg.status == StationStatus.WAITING, now)
        elif kind is fms_to_ds.EventCode:
            self.event_code = msg.code[:MAX_EVENT_CODE]
            self._update_match_info()
        elif kind is fms_to_ds.GameData:
            self.game_data = msg.text
            self._to_apply.append(GameDataChanged(msg.text))
        elif kind is fms_to_ds.UnknownFrame:
            self.unknown_frames += 1
        return []

    def _game_data(self, text: str) -> None:
        """A 2027 DS's game data, control packet tag 0x20: it comes again in every packet, so
        it is applied when it changes (TCP frame 0x1c comes once per change)."""
        if text != self.game_data:
            self.game_data = text
            self._to_apply.append(GameDataChanged(text))

    def _wait(self, waiting: bool, now: float) -> None:
        """Go quiet on a login the FMS says is waiting (see :data:`WAITING_REDIAL`); report
        again from a fresh grid once it places this DS."""
        if waiting and self._waiting_since is None:
            self._waiting_since = now
            self._reports.stop()
            self.events.add(now, f"FMS: quiet on this login; logging in again in {WAITING_REDIAL:g} s "
                                 "unless the FMS places this team first")
        elif not waiting and self._waiting_since is not None:
            self._waiting_since = None
            self._reports.start(now, self._report().lost_packets)

    def _update_match_info(self) -> None:
        c = self.control
        if c is None or not self.attached:
            return
        match_type = _MATCH_TYPES.get(c.tournament_level, MatchType.NONE)
        self._to_apply.append(MatchInfoChanged(MatchInfo(self.event_code or "", match_type, c.match_number,
                                                       c.play_number)))

    def _detach(self, now: float, reason: str) -> None:
        self.attached = False
        self.astop_active = False
        self._hold = None
        self._to_apply.append(Detached(reason))

    def take_events(self) -> list[FmsEvent]:
        """What the DS must do since it last asked, in order."""
        events, self._to_apply = self._to_apply, []
        return events
