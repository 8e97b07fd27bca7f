"""What a person or a script may see of a core: frozen, typed views.

A view is made by a core from its parts at one moment (``at``, on the wire's clock) and never
changes after. The app's panels, the status line, headless ``--json`` and a classroom seat
read views; only the core's own thread reads the core; a view is what crosses from the wire
process to the app (roles/runtime/viewwire.py). The DS's view holds each part's fragment
under the part's name (``ds.link.robot_comms``, ``ds.arbiter.estopped``), so it reads as the
core does; the roboRIO's keeps flat names (``enabled``, ``code_state``) while the Rio itself
is read through its parts (``rio.control.enabled``); the FMS's holds its match and each
station's login, report, commands and the readiness the core computes.

A view holds only primitives, protocol values and frozen sub-views; this module imports
nothing from the cores. Append-only streams (consoles, events, battery history, round-trip
times, the match log) are :class:`StreamView` values, numbered, so a view crosses a process
boundary with only the items new since the last one sent, and a reader follows them by
number.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, replace
from typing import TYPE_CHECKING, Generic, Iterator, Protocol, TypeVar

from protocol import rio_to_ds
from protocol.ds_to_fms import LogRecord
from protocol.ds_to_rio import MatchInfo
from protocol.enums import AllianceStation, Mode, TournamentLevel
from protocol.legacy import LCD_LINES as LEGACY_LCD_LINES
from protocol.legacy import LegacyStatusPacket
from protocol.legacy_control import LegacyControlPacket
from protocol.rio_to_ds import StatusPacket

if TYPE_CHECKING:
    from roles.sim.faults import LinkFault  # a frozen value (roles.sim imports this module)

T = TypeVar("T")


@dataclass(frozen=True, slots=True)
class StreamView(Generic[T]):
    """An append-only stream (console lines, events, battery history, round-trip times, the
    match log) as it was at one moment: ``items[i]`` is item number ``first_seq + i`` of all
    the stream ever held; ``end`` is how many were ever appended. The older items are gone
    (a stream keeps its newest few hundred or thousand). Two views of one stream share their
    numbering, so a reader that has seen up to ``seq`` takes ``since(seq)``: this is how a view
    crosses a process boundary as the items new since the last one (roles/runtime/viewwire.py).
    """

    first_seq: int
    items: tuple[T, ...]

    @property
    def end(self) -> int:
        return self.first_seq + len(self.items)

    def since(self, seq: int) -> tuple[T, ...]:
        """The items numbered ``seq`` and after (all that are kept, if ``seq`` is older)."""
        return self.items[max(0, seq - self.first_seq):]

    def __len__(self) -> int:
        return len(self.items)

    def __iter__(self) -> Iterator[T]:
        return iter(self.items)

    def __getitem__(self, index: int) -> T:
        return self.items[index]


@dataclass(frozen=True, slots=True)
class EventsView:
    """A core's events, ``(time, text)``."""

    items: StreamView[tuple[float, str]]


@dataclass(frozen=True, slots=True)
class TripView:
    """Round-trip times of the DS's control packets, in ms."""

    samples: StreamView[float]
    last_ms: float | None


# -- the Driver Station ----------------------------------------------------------------------
# A DsView is composed of its parts' own fragments, each made by the part (its ``view()``) and
# named as the part is in roles/cores/ds.py (``link``, ``telemetry``, ``tcp``, ``sticks``,
# ``arbiter``, ``fms``), so ``ds.link.robot_comms`` reads the same on a view as on the core.
# Values a fragment holds are primitives, protocol/'s frozen messages and enums, and the
# frozen views below: never a core's own object.


@dataclass(frozen=True, slots=True)
class LinkStatsView:
    """One link's counters (roles/cores/core.py LinkStats) at one moment."""

    name: str
    packets_in: int
    packets_out: int
    bytes_in: int
    bytes_out: int
    bad_packets: int
    lost_packets: int
    stale_packets: int
    foreign_packets: int
    last_rx: float | None
    last_error: str
    connected: bool


@dataclass(frozen=True, slots=True)
class EchoView:
    """Control packets sent and their echoes (roles/cores/ds_robot.py EchoLedger)."""

    sent_packets: int
    lost_packets: int
    stale_echoes: int
    trip: TripView


@dataclass(frozen=True, slots=True)
class LinkView:
    """The robot UDP link (roles/cores/ds_robot.py RobotLink): robot comms and what the last
    status packet said (``status``, the protocol's frozen packet, kept after comms are lost)."""

    robot_udp: tuple[str, int]
    robot_udp_fms: tuple[str, int]
    presume_simulator: bool
    timezone_name: str
    robot_comms: bool
    robot_code: bool
    status: StatusPacket | None
    robot_estopped: bool
    code_starting: bool
    battery: float | None
    program_mode: str  # what the robot program says it runs ("" without comms)
    drives_simulator: bool
    robot_source: str | None
    foreign_packets: int
    missed_slots: int
    echoes: EchoView


@dataclass(frozen=True, slots=True)
class TelemetryView:
    """What the status packets report beyond their bits (roles/cores/ds_robot.py RobotTelemetry)."""

    battery_history: StreamView[tuple[float, float]]  # (time, volts)
    brownout: bool
    brownouts: int
    brownout_changed: float | None
    disk: rio_to_ds.DiskInfo | None
    cpu: rio_to_ds.CpuInfo | None
    ram: rio_to_ds.RamInfo | None
    pdp: rio_to_ds.PdpLog | None
    can: rio_to_ds.CanMetrics | None


@dataclass(frozen=True, slots=True)
class RobotTcpView:
    """The robot TCP client (roles/cores/ds_robot_tcp.py RobotTcpClient). ``versions`` and
    ``faults`` are ``(name, value)`` pairs in the order the robot first sent them (``dict()``
    them to look one up)."""

    address: tuple[str, int]
    state: str  # closed | connecting | open
    console: StreamView[tuple[float, str, str]]  # (time, level, text)
    versions: tuple[tuple[str, str], ...]
    faults: tuple[tuple[str, int], ...]
    usage_reports: int
    unknown_frames: int
    match_info: MatchInfo | None
    game_data: str | None

    @property
    def console_total(self) -> int:
        """Console lines ever added (a reader's cheap "anything new?")."""
        return self.console.end


@dataclass(frozen=True, slots=True)
class JoystickSlotView:
    """One occupied joystick slot (roles/cores/ds_joysticks.py JoystickSlot)."""

    name: str
    is_xbox: bool
    joystick_type: int
    axis_types: tuple[int, ...]
    axes: tuple[float, ...]  # -1.0..1.0
    button_count: int
    povs: tuple[int, ...]  # degrees, -1 centred
    buttons: int  # bit 0 = button 1


@dataclass(frozen=True, slots=True)
class JoystickView:
    """The six joystick slots (roles/cores/ds_joysticks.py JoystickSlots) and the robot's
    outputs for them."""

    slots: tuple[JoystickSlotView | None, ...]
    outputs: tuple[rio_to_ds.JoystickOutput | None, ...]
    in_use: bool


@dataclass(frozen=True, slots=True)
class PracticeTimingView:
    """A practice run's phase lengths in seconds (roles/cores/practice.py PracticeTiming)."""

    countdown: float
    auto: float
    pause: float
    teleop: float


@dataclass(frozen=True, slots=True)
class EnableView:
    """The enable arbiter (roles/cores/ds_enable.py EnableArbiter): the e-stop latch, the
    practice run, what the last control packet said."""

    estopped: bool
    practising: bool  # a practice run is going
    practice_phase: str | None  # its phase ("countdown", "auto", "pause", "teleop"), None without a run
    practice_timing: PracticeTimingView
    sent_enabled: bool
    sent_mode: Mode | None


@dataclass(frozen=True, slots=True)
class FmsLinkView:
    """The DS's FMS client (roles/cores/ds_fms.py FmsClient). ``refused`` is the sentence that
    says why the FMS control it refuses now is refused, ``refused_from`` its host (None while
    none is refused)."""

    attached: bool
    status: str  # off | connecting | connected | good | wrong station | waiting
    foreign_packets: int
    refused_from: str | None
    refused: str | None


@dataclass(frozen=True, slots=True)
class LegacyView:
    """The 2010 codec (roles/cores/legacy_ds.py LegacyRobotCodec): what goes to the robot and
    what it sent, the dashboard and NetConsole."""

    dashboard: tuple[str, int] | None
    digital_in: int  # bit 0 = digital input 1
    analog: tuple[int, ...]  # 0..1023
    last_control: LegacyControlPacket | None
    last_status: LegacyStatusPacket | None
    replies: int
    dashboard_sent: int
    netconsole: StreamView[tuple[float, str]]
    netconsole_dropped: int
    stats: tuple[LinkStatsView, ...]

    @property
    def control_byte(self) -> int | None:
        """The control byte of the last packet sent to the robot."""
        return None if self.last_control is None else self.last_control.control_byte

    @property
    def battery_bytes(self) -> tuple[int, int] | None:
        """The robot's two BCD battery bytes, as last received."""
        if self.last_status is None:
            return None
        high, low = self.last_status.battery
        return high, low

    @property
    def digital_out(self) -> int:
        """The robot's DS digital outputs (bit 0 = output 1), as last received."""
        return 0 if self.last_status is None else self.last_status.ds_digital_out

    @property
    def error_text(self) -> str:
        """The robot's error string (setErrorData), as last received."""
        return "" if self.last_status is None else self.last_status.error_text

    @property
    def lcd(self) -> tuple[str, ...]:
        """The DS LCD: six lines (empty until the robot sends LCD data)."""
        lines = self.last_status.lcd if self.last_status is not None else None
        return tuple(lines) + ("",) * (LEGACY_LCD_LINES - len(lines)) if lines else ("",) * LEGACY_LCD_LINES

    def snapshot(self) -> dict[str, object]:
        """The 2010 fields, JSON-able."""
        st = self.last_status
        return {
            "control": self.control_byte, "digital_in": self.digital_in, "analog": list(self.analog),
            "digital_out": self.digital_out,
            "battery_bytes": None if st is None else [st.battery[0], st.battery[1]],
            "battery_volts": None if st is None else st.volts, "lcd": list(self.lcd),
            "dashboard": None if self.dashboard is None else f"{self.dashboard[0]}:{self.dashboard[1]}",
            "dashboard_sent": self.dashboard_sent, "replies": self.replies,
            "netconsole_lines": self.netconsole.end,
        }


@dataclass(frozen=True, slots=True, kw_only=True)
class DsView:
    """A Driver Station (roles/cores/ds.py) as its panels show it: what the DS decides
    (station, mode, enable, what holds an e-stop, what blocks an enable) and its parts' fragments."""

    at: float
    team: int
    station: AllianceStation
    mode: Mode
    enabled: bool
    estop_kind: str  # what holds the robot e-stopped (roles/cores/ds_enable.py estop_state), "" nothing
    estop_reason: str  # the same in words, "" when nothing does
    # What keeps the robot from being enabled now (roles/cores/ds_enable.py blocker): its kind
    # (fms, estop, comms, robot-estop, code, practice) and the words an enable is refused with;
    # None when nothing does.
    enable_blocker: str | None
    enable_refusal: str | None
    trip_ms: float | None  # the average round trip while robot comms are up
    countdown_left: float | None  # seconds left in the period, while a match or practice run times
    link: LinkView
    telemetry: TelemetryView
    tcp: RobotTcpView
    sticks: JoystickView
    arbiter: EnableView
    fms: FmsLinkView
    events: EventsView
    stats: tuple[LinkStatsView, ...]  # each link's counters, in LINKS order (roles/cores/ds.py)
    legacy: LegacyView | None  # the 2010 codec, None in the 2015+ protocol

    def link_stats(self, name: str) -> LinkStatsView | None:
        """The counters of the link called ``name`` ("ds->rio", "fms-udp"...), None: no such link."""
        for stats in self.stats:
            if stats.name == name:
                return stats
        return None

    def wire_ended(self, now: float, why: str) -> "DsView":
        """This view once the process that ran the DS is gone: no robot comms and no enable
        shown any more, and an event that says why (the app's own copy of the stream)."""
        kept = self.events.items
        events = EventsView(StreamView(kept.first_seq, kept.items + ((now, f"{why}: no robot comms, disabled"),)))
        link = replace(self.link, robot_comms=False, robot_code=False, battery=None, program_mode="")
        return replace(self, events=events, enabled=False, trip_ms=None, countdown_left=None, link=link,
                       tcp=replace(self.tcp, state="closed"),
                       fms=replace(self.fms, attached=False, status="off", refused_from=None, refused=None))

    def snapshot(self) -> dict[str, object]:
        """The panel/status-line fields, JSON-able (the headless ``--json`` line)."""
        link, battery, trip, countdown = self.link, self.link.battery, self.trip_ms, self.countdown_left
        practice = self.arbiter.practice_phase if self.arbiter.practising else None
        return {
            "team": self.team, "station": self.station.label, "mode": self.mode.label,
            "enabled": self.enabled, "estopped": self.arbiter.estopped, "estop_reason": self.estop_reason,
            "robot_comms": link.robot_comms,
            "robot_code": link.robot_code, "joysticks_ok": self.sticks.in_use,
            "battery": None if battery is None else round(battery, 2), "brownout": self.telemetry.brownout,
            "trip_ms": None if trip is None else round(trip, 1), "lost_packets": link.echoes.lost_packets,
            "sent_packets": link.echoes.sent_packets, "fms_attached": self.fms.attached,
            "fms_status": self.fms.status, "fms_refused": self.fms.refused,
            "practice": practice or None,
            "countdown": None if countdown is None else round(countdown, 1),
            "robot_tcp": self.tcp.state == "open", "faults": dict(self.tcp.faults),
            "brownouts": self.telemetry.brownouts,
            "bad_packets": sum(s.bad_packets for s in self.stats),
        }


@dataclass(frozen=True, slots=True)
class ConsoleLine:
    """A line of the robot's console (its program's output, warnings and errors)."""

    time: float  # the core's clock
    kind: str  # "stdout", "warning" or "error"
    text: str
    sequence: int


#: A control mode as the robot program and the panels name it.
MODE_LABEL = {Mode.TELEOP: "teleop", Mode.TEST: "test", Mode.AUTONOMOUS: "auto", Mode.RESERVED: "mode 3"}

@dataclass(frozen=True, slots=True)
class BatteryView:
    """The robot's battery as the roboRIO reads it (roles/cores/battery.py)."""

    volts: float
    brownout: bool
    brownouts: int


@dataclass(frozen=True, slots=True)
class RioFaultsView:
    """The roboRIO's fault counters (roles/cores/rio.py RioFaults says what each counts)."""

    comms: int
    rail_12v: int
    rail_6v: int
    rail_5v: int
    rail_3v3: int
    program_errors: int
    foreign_packets: int
    stale_packets: int
    sequence_jumps: int
    program_overruns: int
    output_problems: int
    evicted_clients: int
    missed_beats: int
    refused_clients: int
    console_dropped: int
    malformed_tags: int


@dataclass(frozen=True, slots=True)
class RioJoystickView:
    """A joystick slot as the robot program reads it: axes -1.0..1.0, the buttons down
    (1-based), POV degrees (-1 centred), the name from the DS's descriptor."""

    axes: tuple[float, ...]
    pressed: tuple[int, ...]
    povs: tuple[int, ...]
    name: str


@dataclass(frozen=True, slots=True)
class ProgramOutView:
    """What the robot program writes back to the DS, per joystick slot (rumble 0.0..1.0)."""

    outputs: tuple[int, ...]
    left_rumble: tuple[float, ...]
    right_rumble: tuple[float, ...]


@dataclass(frozen=True, slots=True, kw_only=True)
class RioView:
    """A fake roboRIO (roles/cores/rio.py, 2010 too) as its panels show it: each field is
    the fragment of the part that keeps it (roles/cores/rio.py ``view``)."""

    at: float
    team: int
    beats: int
    # the control link (rio_control.py)
    enabled: bool
    estopped: bool
    mode: Mode
    ds_address: tuple[str, int] | None
    ds_connected: bool
    ds_enabled: bool
    watchdog_tripped: bool
    fms_attached: bool
    station: AllianceStation
    outputs_enabled: bool
    # the DS's inputs (rio_inputs.py)
    request_date: bool
    game_data: str
    match_info: MatchInfo | None
    countdown: float | None
    joysticks: tuple[RioJoystickView, ...]
    # the program (rio_program.py)
    code_state: str
    program_name: str
    trace_mode: str | None
    program_out: ProgramOutView
    lcd: tuple[str, ...] | None  # 2010: the six LCD lines the program wrote (None until it wrote one)
    # TCP 1740 (rio_tcp.py) and the telemetry (rio_telemetry.py)
    tcp_clients: int
    console: StreamView[ConsoleLine]
    battery: BatteryView
    pdp_amps: tuple[float, ...]
    # shared by the parts
    events: EventsView
    faults: RioFaultsView
    stats: dict[str, LinkStatsView]

    def wire_ended(self) -> "RioView":
        """This view once the process that ran the roboRIO is gone: nothing it can vouch for."""
        return replace(self, enabled=False, ds_connected=False, code_state="state unknown", outputs_enabled=False)

    def snapshot(self) -> dict[str, object]:
        """Everything a panel or ``--json`` status line shows, as plain JSON-able values."""
        out = self.program_out
        info = self.match_info
        return {
            "enabled": self.enabled,
            "estopped": self.estopped,
            "mode": MODE_LABEL[self.mode],
            "code_state": self.code_state,
            "program": self.program_name,
            "trace_mode": self.trace_mode,
            "ds_address": list(self.ds_address) if self.ds_address else None,
            "ds_connected": self.ds_connected,
            "ds_enabled": self.ds_enabled,
            "watchdog_tripped": self.watchdog_tripped,
            "fms_attached": self.fms_attached,
            "station": self.station.label,
            "request_date": self.request_date,
            "battery_volts": round(self.battery.volts, 3),
            "brownout": self.battery.brownout,
            "outputs_enabled": self.outputs_enabled,
            "pdp_amps": [round(a, 2) for a in self.pdp_amps],
            "outputs": [{"outputs": o, "left_rumble": l, "right_rumble": r}
                        for o, l, r in zip(out.outputs, out.left_rumble, out.right_rumble)],
            "joysticks": [{"axes": list(j.axes), "buttons": list(j.pressed), "povs": list(j.povs), "name": j.name}
                          for j in self.joysticks],
            "game_data": self.game_data,
            "match_info": (None if info is None else {
                "competition": info.competition,
                "match_type": int(info.match_type),
                "match_number": info.match_number,
                "replay": info.replay}),
            "countdown": self.countdown,
            "tcp_clients": self.tcp_clients,
            "console": [{"time": c.time, "kind": c.kind, "text": c.text, "sequence": c.sequence}
                        for c in self.console],
            "faults": asdict(self.faults),
            "stats": {name: asdict(s) for name, s in self.stats.items()},
            "events": [{"time": t, "text": text} for t, text in self.events.items],
            "beats": self.beats,
        }


@dataclass(frozen=True, slots=True)
class TimingView:
    """A match's period lengths, in seconds."""

    auto: float
    pause: float
    teleop: float


@dataclass(frozen=True, slots=True, kw_only=True)
class MatchView:
    """The FMS's match (roles/cores/match.py) at one moment."""

    phase: str  # roles.cores.match.Phase's value: "pre-match", "auto", "pause", "teleop", "post-match"
    running: bool
    level: TournamentLevel | int  # an int: a level no document names
    number: int
    play: int
    label: str  # "Match 12 (play 2)"
    aborted: bool
    period_start: float | None  # when the current period began (running only), on the wire's clock
    timing: TimingView


@dataclass(frozen=True, slots=True)
class DsReport:
    """What an FMS station's DS said in its latest UDP status (the defaults: nothing heard).
    The FMS core keeps one per station (roles/cores/fms_station.py) and replaces it on each
    status; the station's view holds the same one."""

    udp_link: bool = False
    ds_address: tuple[str, int] | None = None  # where its status comes from
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


@dataclass(frozen=True, slots=True, kw_only=True)
class StationView:
    """One FMS alliance station (roles/cores/fms_station.py) at one moment: its login, its DS's
    latest report (the core's own, frozen), what the field commands, and what its row says
    (``readiness``, computed by the core: roles.cores.fms_station.Readiness's value, and
    ``reason``, its words)."""

    station: AllianceStation
    team: int | None
    name: str  # "R2 (254)"
    link: LinkStatsView
    # the DS's login
    tcp_connected: bool
    ds_link: bool  # logged in, and its UDP status arrives
    peer: tuple[str, int] | None
    status: str | None  # "good" / "bad": what station info told the DS
    wrong_station: AllianceStation | None
    challenge: str  # roles.cores.ownership.Challenge's value
    owner: str  # roles.cores.ownership.Owner's value
    report: DsReport  # the DS's latest report
    # what the field commands
    estop: bool
    estop_by: str | None
    estop_status: str | None  # what e-stops it, in words (None: nothing)
    astop: bool
    bypass: bool
    enabled: bool
    # refusals, and what its DS said on TCP
    refused_logins: int
    unclaimed_status: int
    last_refused: str | None
    log_data: LogRecord | None
    versions: tuple[tuple[str, str], ...]  # (device, version)
    error_events: int
    readiness: str
    reason: str
    #: Which DS holds the station: "NI DS" (its team-number login) or "2027 DS" (the 2027
    #: FIRST Driver Station's hello); None while none is logged in.
    ds_kind: str | None = None

    @property
    def label(self) -> str:
        return self.station.label

    def snapshot(self) -> dict[str, object]:
        r = self.report
        return {
            "station": self.label,
            "team": self.team,
            "ds_link": self.ds_link,
            "ds_kind": self.ds_kind,
            "tcp": self.tcp_connected,
            "udp": r.udp_link,
            "ds_address": f"{r.ds_address[0]}:{r.ds_address[1]}" if r.ds_address else None,
            "robot_link": r.robot_link,
            "radio_ping": r.radio_ping,
            "rio_ping": r.rio_ping,
            "battery": r.battery,
            "trip_time_ms": r.trip_time_ms,
            "lost_packets": r.lost_packets,
            "sent_packets": r.sent_packets,
            "ds_estop": r.ds_estop,
            "ds_enabled": r.ds_enabled,
            "ds_mode": r.ds_mode.label if r.ds_mode is not None else None,
            "estop": self.estop,
            "estop_status": self.estop_status,
            "astop": self.astop,
            "bypass": self.bypass,
            "enabled": self.enabled,
            "status": self.status,
            "wrong_station": self.wrong_station.label if self.wrong_station is not None else None,
            "challenge": self.challenge,
            "owner": self.owner,
            "refused_logins": self.refused_logins,
            "refused_status": self.link.foreign_packets,
            "last_refused": self.last_refused,
            "log_data": asdict(self.log_data) if self.log_data else None,
            "versions": dict(self.versions),
            "error_events": self.error_events,
            "bad_packets": self.link.bad_packets,
        }

    def wire_ended(self) -> "StationView":
        """This station once the process that ran the FMS is gone: no DS linked, nothing
        enabled. Its row says "no DS" where it said anything past that rung of the core's
        ladder (roles/cores/fms_station.py readiness: empty, bypassed and a wrong station
        come before it)."""
        gone = self.readiness not in ("empty", "bypassed", "wrong-station")
        return replace(self, tcp_connected=False, ds_link=False, enabled=False,
                       report=replace(self.report, udp_link=False, robot_link=False),
                       estop_status=self.estop_status if self.estop else None,
                       readiness="no-ds" if gone else self.readiness, reason="no DS" if gone else self.reason)


@dataclass(frozen=True, slots=True, kw_only=True)
class FmsView:
    """The FMS (roles/cores/fms.py) as its panels show it, made by its ``view(now)``."""

    at: float
    udp_unknown_team: int
    refused_status: int
    refused_logins: int
    refused_connections: int
    evicted_connections: int
    challenge_failures: int
    missed_sends: int
    game_data: str
    event_code: str
    match_log: StreamView[tuple[float, str]]
    events: EventsView
    match: MatchView
    stations: tuple[StationView, ...]
    connections: int
    udp_stats: LinkStatsView
    tcp_stats: LinkStatsView
    refusals: tuple[str, ...]  # every reason a start would be refused now
    warnings: tuple[str, ...]  # what a start would not fix: robots still e-stopped
    remaining_left: int  # whole seconds left in the period

    def wire_ended(self) -> "FmsView":
        """This view once the process that ran the FMS is gone: no station linked or enabled."""
        return replace(self, stations=tuple(st.wire_ended() for st in self.stations))

    def snapshot(self, now: float | None = None) -> dict[str, object]:
        """Everything a status line or panel shows, as JSON-able values."""
        m = self.match
        level = m.level.name.lower() if isinstance(m.level, TournamentLevel) else int(m.level)
        return {
            "phase": m.phase,
            "running": m.running,
            "remaining": self.remaining_left,
            "match_type": level,
            "match_number": m.number,
            "play_number": m.play,
            "timing": {"auto": m.timing.auto, "pause": m.timing.pause, "teleop": m.timing.teleop},
            "connections": self.connections,
            "stations": [st.snapshot() for st in self.stations],
            "bad_packets": {"udp": self.udp_stats.bad_packets, "tcp": self.tcp_stats.bad_packets},
        }


@dataclass(frozen=True, slots=True)
class FaultCountersView:
    """What one link's faults did (roles/sim/faults.py FaultCounters says what each counts)."""

    seen: int
    dropped: int
    delayed: int
    duplicated: int
    reordered: int
    corrupted: int
    retransmitted: int
    held: int
    refused_connects: int


@dataclass(frozen=True, slots=True, kw_only=True)
class FaultsView:
    """The fault injector (roles/sim/faults.py): what each link does, and what it did."""

    at: float
    links: dict[str, LinkFault]  # a frozen value: what the link suffers
    counters: dict[str, FaultCountersView]

    def snapshot(self) -> dict[str, object]:
        return {link: {"fault": fault.describe(), **asdict(fault), "counters": asdict(self.counters[link])}
                for link, fault in self.links.items()}


V = TypeVar("V", covariant=True)


class Viewed(Protocol[V]):
    """A core: it says what it holds as a frozen view at a time."""

    def view(self, now: float) -> V: ...


def view_of(core: Viewed[V] | None, now: float) -> V | None:
    """The view of any core a field runs (None for None)."""
    return None if core is None else core.view(now)
