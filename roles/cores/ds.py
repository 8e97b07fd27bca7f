"""The Driver Station core: a sans-IO state machine on the shell's clock (roles/cores/core.py).

Links (names the shell binds and the core uses):

* UDP channel ``"robot"``: bound on the DS address, port 1150. Control packets go from it
  every 20 ms to ``robot_udp`` (port 1110), or to ``robot_udp_fms`` (1115) with the FMS bit
  while an FMS is attached; robot status packets arrive on it.
* TCP conn ``"robot-tcp"``: a client connection to ``robot_tcp`` (1740), asked for with
  :class:`Connect` and retried every second while closed.
* ``"fms"`` and ``"fms-lite"`` (UDP in, ports 1121 and 1120: a real DS takes FMS control
  on both), ``"fms-out"`` (UDP out, to ``fms_udp`` 1160) and ``"fms-tcp"`` (TCP client to
  ``fms_tcp`` 1750): the FMS client, ``roles/cores/ds_fms.py``. On loopback the shell opens the
  TCP connections from the DS's own address (``RoleHost._tcp_source``), as a real DS's leave
  from 10.TE.AM.5: an FMS sends control to the address of the DS's TCP connection.

Rules this core keeps, and how it measures:

* The 20 ms beat is ``start + k * 0.020``: polled late, it sends once and goes on at the
  next slot of the grid (the skipped slots are counted in ``missed_slots``), never a burst.
* Status packets count only from the robot: the host of ``robot_udp`` / ``robot_udp_fms``
  when it is an IP literal (any port), else (a host name) the first address that answers,
  until comms are lost. Others are counted in ``foreign_packets`` and dropped.
* Robot comms are lost after 1 s without a status packet. The DS then disables and forgets
  the operator's enable: the robot needs a fresh ``enable()`` (an event says so).
* Enabling is refused without robot comms or robot code, while e-stopped (by the DS or as the
  robot reports), while a practice run is going (it enables by itself) and while an FMS is
  attached (the FMS decides).
* E-stop latches. The NI DS clears an e-stop only when the robot code restarts or the roboRIO
  reboots, so here the latch clears only through ``restart_code()`` / ``reboot_roborio()``:
  the packets carrying the request no longer carry the e-stop bit, so the robot, whose own
  latch that request clears, does not latch again. Nothing else clears it: not a comms loss,
  not a reconnect, not an FMS (an FMS e-stop latches it too).
* Restart-code / reboot request bits are sent for ``REQUEST_PACKETS`` packets (200 ms, so a
  lost datagram or two do not lose the request); a restart request stops early once the
  robot, which had code when asked, shows its code restarting (no robot code, or code
  initializing). A robot should act on the first packet that carries the bit. Both need
  robot comms, and both disable.
* Under an FMS, ``disable()`` still works: it holds the robot disabled until the FMS
  changes phase (the period ends) or detaches. ``estop()`` always works.
* Date (0x0f) and timezone (0x10) tags go out once, in the first packet after a status
  packet with request-date; again only after a comms loss (a rebooted robot asks anew).
* Joystick tags go out for slots 0 to the last one in use, none without a joystick, as a
  real NI DS does. To WPILib's simulator (its status trace says it is no roboRIO; before
  any status, ``simulator=True``, given for a loopback ``--robot``) all six go out, each
  with at most one POV, and an event says why once: its 2026 release reads POV i from
  ``povs[2*i]`` (every POV after the first is wrong, more than 6 write past its array) and
  keeps a slot's values until a tag for that slot comes. On robot TCP connect: a descriptor
  for each of the six slots, then match info and game data, empty when there are none;
  descriptors again on every change.
* Trip time: control packet sent -> the status echoing its sequence (``TripTimer``); the
  panel figure is the average of the last 256. Lost packets: control packets sent while
  robot comms were up whose echo did not come back within 1 s (a lost control packet and a
  lost reply count alike; packets sent to a robot that is not there are not "lost").
  Echoes of nothing outstanding (late, duplicated) are counted in ``stale_echoes``.

The encoder/decoder pair for the robot link is chosen in one place, :func:`robot_codec`:
the 2010 legacy protocol plugs in there (roles/cores/legacy_ds.py: its codec also sends the
dashboard packet after each control packet and takes the NetConsole channel; it has no TCP).
"""

from __future__ import annotations

import functools
import datetime as _dt
import ipaddress
import math
from collections import deque
from dataclasses import dataclass
from typing import Any, Callable, Hashable

from protocol import rio_to_ds
from protocol.ds_to_rio import (EMPTY_JOYSTICK, MAX_AXES, MAX_BUTTONS, MAX_JOYSTICKS, MAX_POVS,
                                ControlPacket, Countdown, Date, GameData, Joystick, JoystickDescriptor,
                                MatchInfo, Timezone, axis_to_int8)
from protocol.enums import AllianceStation, JoystickType, Mode
from protocol.errors import ProtocolError
from protocol.framing import FrameDecoder
from protocol.rio_to_ds import StatusPacket

from .addresses import ROBOT_UDP, ROBOT_UDP_FMS, check_team
from .core import (Action, Address, Close, CommandError, Connect, Datagram, Events, Grid, LinkStats,
                   StreamSend, TripTimer, decode_frames, utc_now)
from .ds_fms import FMS_CONTROL_CHANNELS, FmsClient, GameDataChanged, MatchInfoChanged
from .ds_fms import Attached as FmsAttached
from .ds_fms import Detached as FmsDetached
from .ds_fms import Estopped as FmsEstopped
from .practice import PracticePhase, PracticeRun, PracticeTiming

PERIOD = 0.020
COMMS_TIMEOUT = 1.0
ECHO_TIMEOUT = 1.0
TCP_RETRY = 1.0
REQUEST_PACKETS = 10
CONSOLE_LINES = 2000
BATTERY_SAMPLES = 3000  # one minute at 50 Hz
MAX_TEXT = 4096  # characters kept of one console line
MAX_VERSIONS = 64
MAX_NAME = 64
#: Robot TCP frames above this are a framing error (the connection is dropped). The wire
#: allows 64 KiB; a real robot's largest frame is an error with its call stack, a few KiB.
MAX_ROBOT_FRAME = 0x8000

ROBOT = "robot"
ROBOT_TCP = "robot-tcp"
LINKS = ("ds->rio", "rio->ds", "robot-tcp", "fms-udp", "fms-tcp")
#: (link, direction) -> protocol kind, for a RoleSpec's ``kinds``.
KINDS = {
    ("robot", "out"): "ds-to-rio", ("robot", "in"): "rio-to-ds",
    ("robot-tcp", "out"): "ds-to-rio-tcp", ("robot-tcp", "in"): "rio-to-ds-tcp",
    ("fms", "in"): "fms-to-ds", ("fms-lite", "in"): "fms-to-ds", ("fms-out", "out"): "ds-to-fms",
    ("fms-tcp", "out"): "ds-to-fms-tcp", ("fms-tcp", "in"): "fms-to-ds-tcp",
}


# -- the codec seam -------------------------------------------------------------------------
@dataclass(frozen=True, slots=True)
class ControlState:
    """Everything one control packet says, whatever the protocol year."""

    sequence: int
    estop: bool
    fms_attached: bool
    enabled: bool
    mode: Mode
    reboot: bool
    restart: bool
    station: AllianceStation
    team: int
    countdown: float | None
    joysticks: tuple[Joystick, ...]
    date: _dt.datetime | None = None
    timezone: str | None = None


class ModernRobotCodec:
    """The 2015+ protocol (protocol/ds_to_rio.py, protocol/rio_to_ds.py)."""

    name = "2015+"
    control_kind = "ds-to-rio"
    status_kind = "rio-to-ds"
    uses_tcp = True
    modes = (Mode.TELEOP, Mode.AUTONOMOUS, Mode.TEST)

    @staticmethod
    def encode_control(s: ControlState) -> bytes:
        tags: list[Any] = []
        if s.countdown is not None:
            tags.append(Countdown(s.countdown))
        tags.extend(s.joysticks)
        if s.date is not None:
            tags.append(Date.from_datetime(s.date))
            tags.append(Timezone(s.timezone or "UTC"))
        return ControlPacket(s.sequence, 0x01, s.estop, s.fms_attached, s.enabled, s.mode, s.reboot,
                             s.restart, s.station, tuple(tags)).encode()

    decode_status = staticmethod(rio_to_ds.decode_status)

    @staticmethod
    def after_control(ds: Any, now: float) -> list[Action]:
        """Datagrams that go out with each control packet (the 2010 dashboard): none."""
        return []

    @staticmethod
    def datagram(ds: Any, channel: str, data: bytes, source: Address, now: float) -> list[Action]:
        """A datagram on a channel the core does not know (the 2010 NetConsole): ignored."""
        return []


def robot_codec(legacy: bool = False) -> Any:
    """The one place the robot link's encoder/decoder pair is chosen (2010: roles/cores/legacy_ds.py)."""
    if legacy:
        from .legacy_ds import LegacyRobotCodec

        return LegacyRobotCodec()
    return ModernRobotCodec()


# -- joysticks -------------------------------------------------------------------------------
@dataclass
class JoystickSlot:
    """One occupied slot: its descriptor and its live values (axes -1.0..1.0, buttons as a
    word with bit 0 = button 1, POVs in degrees or -1)."""

    name: str
    is_xbox: bool
    joystick_type: JoystickType | int
    axis_types: tuple[int, ...]
    axes: list[float]
    button_count: int
    povs: list[int]
    buttons: int = 0

    def wire(self) -> Joystick:
        return Joystick(tuple(axis_to_int8(a) for a in self.axes), self.buttons, self.button_count,
                        tuple(self.povs))

    def descriptor(self, index: int) -> JoystickDescriptor:
        return JoystickDescriptor(index, self.is_xbox, self.joystick_type, self.name, self.axis_types,
                                  self.button_count, len(self.povs))


def _empty_descriptor(index: int) -> JoystickDescriptor:
    return JoystickDescriptor(index, False, JoystickType.UNKNOWN, "", (), 0, 0)


def _int_arg(value: Any, what: str, lo: int, hi: int) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or not lo <= value <= hi:
        raise CommandError(f"{what} must be a whole number {lo}..{hi}, not {value!r}")
    return value


def _clip(text: str, n: int) -> str:
    return text if len(text) <= n else text[:n] + "…"


class DriverStation:
    """One team's Driver Station. See the module docstring for the links and the rules."""

    def __init__(self, team: int, robot_udp: Address, robot_tcp: Address, *,
                 station: AllianceStation = AllianceStation.RED1, robot_udp_fms: Address | None = None,
                 fms_tcp: Address | None = None, fms_udp: Address | None = None,
                 clock: Callable[[], _dt.datetime] | None = None, timezone_name: str = "UTC",
                 practice_timing: PracticeTiming | None = None, legacy: bool = False,
                 simulator: bool = False) -> None:
        self.team = check_team(team)
        self._codec = robot_codec(legacy)
        self.robot_udp: Address = robot_udp
        self.robot_tcp: Address = robot_tcp
        self.robot_udp_fms: Address = robot_udp_fms or _fms_port(robot_udp)
        self.clock = clock or utc_now
        try:
            # checked as the tag will carry it: text of at most 254 bytes
            ControlPacket(tags=(Timezone(timezone_name),)).encode()
        except (ProtocolError, TypeError) as exc:
            raise ValueError(f"bad time zone name {timezone_name!r}: {exc}") from None
        self.timezone_name = timezone_name
        self.practice_timing = practice_timing or PracticeTiming()
        #: the robot is taken for WPILib's simulator until a status packet says what it is
        self.presume_simulator = simulator
        self._simulator_noted = False
        self.events = Events()
        self.stats: dict[str, LinkStats] = {name: LinkStats(name) for name in LINKS}
        # what the operator chose (the FMS or a practice run may override while they run)
        self._station = AllianceStation(station)
        self._mode = Mode.TELEOP
        self._enabled_local = False
        self.estopped = False
        # robot link
        self.robot_comms = False
        self.status: StatusPacket | None = None
        self.robot_estopped = False
        self.brownout = False
        self.brownouts = 0
        self.code_starting = False
        self._battery: float | None = None
        self.battery_history: deque[tuple[float, float]] = deque(maxlen=BATTERY_SAMPLES)
        self.joystick_outputs: list[rio_to_ds.JoystickOutput | None] = [None] * MAX_JOYSTICKS
        self.disk: rio_to_ds.DiskInfo | None = None
        self.cpu: rio_to_ds.CpuInfo | None = None
        self.ram: rio_to_ds.RamInfo | None = None
        self.pdp: rio_to_ds.PdpLog | None = None
        self.can: rio_to_ds.CanMetrics | None = None
        self.trip = TripTimer()
        self.sent_packets = 0
        self.lost_packets = 0
        self.missed_slots = 0
        self.stale_echoes = 0
        #: robot status packets from an address that is not the robot's, dropped (also
        #: counted on the "rio->ds" link); ``robot_source`` is the host status is taken from
        self.foreign_packets = 0
        self.robot_source: str | None = None
        self._outstanding: dict[int, tuple[float, bool]] = {}  # sequence -> (sent at, comms up)
        self._last_status = -math.inf
        self._seq = 0
        self._sends = Grid(PERIOD)  # the 20 ms control packets
        self._reboot_left = 0
        self._restart_left = 0
        self._restart_had_code = False
        self._date_due = False
        self._date_sent = False
        self._sent_enabled = False
        self._sent_mode: Mode | None = None
        # joysticks
        self.joysticks: list[JoystickSlot | None] = [None] * MAX_JOYSTICKS
        self._wire: list[Joystick] = [EMPTY_JOYSTICK] * MAX_JOYSTICKS
        # robot TCP
        self.robot_tcp_state = "closed"  # closed | connecting | open
        self._tcp_retry_at = -math.inf if self._codec.uses_tcp else math.inf  # 2010: no TCP at all
        self._decoder: FrameDecoder | None = None
        self._descriptors_dirty = False
        self._match_info_dirty = False
        self._game_data_dirty = False
        self.console: deque[tuple[float, str, str]] = deque(maxlen=CONSOLE_LINES)
        self.console_total = 0  # lines ever added: a panel's cheap "anything new?"
        self.versions: dict[str, str] = {}
        self.faults = {"comms": 0, "12v": 0, "6v": 0, "5v": 0, "3.3v": 0}
        self.usage_reports = 0
        self.unknown_frames = 0
        self.match_info: MatchInfo | None = None
        self.game_data: str | None = None
        # practice
        self.practice: PracticeRun | None = None
        self.practice_phase: PracticePhase | None = None
        # plumbing
        self._now = 0.0
        self._pending: list[Action] = []
        self.fms = FmsClient(self, fms_tcp, fms_udp)

    # -- what panels read ------------------------------------------------------------------
    @property
    def legacy(self) -> Any:
        """The 2010 codec (roles/cores/legacy_ds.py: digital and analog inputs, LCD, dashboard,
        NetConsole), or None in the 2015+ protocol."""
        return self._codec if self._codec.name == "2010" else None

    @property
    def fms_attached(self) -> bool:
        return self.fms.attached

    @property
    def fms_status(self) -> str:
        return self.fms.status

    @property
    def station(self) -> AllianceStation:
        if self.fms.attached and self.fms.control is not None:
            return self.fms.control.station
        return self._station

    @property
    def mode(self) -> Mode:
        if self.fms.attached and self.fms.control is not None:
            return self.fms.control.mode
        if self.practice is not None and self.practice_phase is not None:
            return self.practice_phase.mode
        return self._mode

    @property
    def enabled(self) -> bool:
        """What the control packets say: the operator's, the FMS's or the practice run's
        enable, never while e-stopped or without robot comms."""
        if self.estopped or not self.robot_comms:
            return False
        if self.fms.attached:
            return self.fms.robot_enabled
        if self.practice is not None:
            return self.practice_phase is not None and self.practice_phase.enabled
        return self._enabled_local

    @property
    def robot_code(self) -> bool:
        return self.robot_comms and self.status is not None and self.status.robot_code

    @property
    def battery(self) -> float | None:
        return self._battery if self.robot_comms else None

    @property
    def trip_ms(self) -> float | None:
        return self.trip.average_ms if self.robot_comms else None

    @property
    def joysticks_ok(self) -> bool:
        return any(j is not None for j in self.joysticks)

    @property
    def robot_program_mode(self) -> str:
        """The mode the robot program says it runs (the status packet's trace bits)."""
        s = self.status
        if not self.robot_comms or s is None:
            return ""
        return ("disabled" if s.user_disabled else "auto" if s.user_auto else "teleop" if s.user_teleop
                else "test" if s.user_test else "")

    def countdown(self, now: float | None = None) -> float | None:
        """Seconds left in the current period, while a match or a practice run is timing."""
        now = self._now if now is None else now
        if self.fms.attached:
            left = self.fms.control.remaining_seconds if self.fms.control else 0
            return float(left) if left > 0 else None
        if self.practice is not None:
            phase, left = self.practice.phase_at(now)
            return left if phase is not PracticePhase.ENDED else None
        return None

    def snapshot(self) -> dict[str, Any]:
        """The panel/status-line fields, JSON-able (the headless ``--json`` line)."""
        battery, trip = self.battery, self.trip_ms
        countdown = self.countdown()
        return {
            "team": self.team, "station": self.station.label, "mode": self.mode.label,
            "enabled": self.enabled, "estopped": self.estopped, "robot_comms": self.robot_comms,
            "robot_code": self.robot_code, "joysticks_ok": self.joysticks_ok,
            "battery": None if battery is None else round(battery, 2), "brownout": self.brownout,
            "trip_ms": None if trip is None else round(trip, 1), "lost_packets": self.lost_packets,
            "sent_packets": self.sent_packets, "fms_attached": self.fms_attached,
            "fms_status": self.fms_status,
            "practice": self.practice_phase.value if self.practice is not None and self.practice_phase else None,
            "countdown": None if countdown is None else round(countdown, 1),
            "robot_tcp": self.robot_tcp_state == "open", "faults": dict(self.faults),
            "brownouts": self.brownouts,
            "bad_packets": sum(s.bad_packets for s in self.stats.values()),
        }

    # -- the core contract -----------------------------------------------------------------
    def poll(self, now: float) -> list[Action]:
        self._now = now
        out, self._pending = self._pending, []
        self._check_comms(now)
        self._expire_echoes(now)
        self._update_practice(now)
        out += self.fms.poll(now)
        self._apply_fms_events(now)
        out += self._robot_tcp_poll(now)
        if self._sends.origin is None:
            self._sends.start(now)
        skipped = self._sends.take(now)
        if skipped is not None:
            self.missed_slots += skipped
            out.append(self._control_datagram(now))
            out += self._codec.after_control(self, now)
        return out

    def next_deadline(self) -> float | None:
        if self._sends.origin is None or self._pending:
            return self._now
        if self.robot_tcp_state == "open" and (self._descriptors_dirty or self._match_info_dirty
                                               or self._game_data_dirty):
            return self._now
        deadline = self._sends.next
        if self.robot_comms:
            deadline = min(deadline, self._last_status + COMMS_TIMEOUT)
        if self.robot_tcp_state == "closed":
            deadline = min(deadline, self._tcp_retry_at)
        if self.practice is not None:
            boundary = self.practice.next_boundary(self._now)
            deadline = min(deadline, self._now if boundary is None else boundary)
        fms = self.fms.next_deadline()
        return deadline if fms is None else min(deadline, fms)

    def datagram(self, channel: str, data: bytes, source: Address, now: float) -> list[Action]:
        self._now = now
        if channel == ROBOT:
            self._on_status(data, source, now)
        elif channel in FMS_CONTROL_CHANNELS:
            out = self.fms.datagram(data, source, now)
            self._apply_fms_events(now)
            return out
        else:
            return self._codec.datagram(self, channel, data, source, now)
        return []

    def stream_opened(self, conn: Hashable, peer: Address, now: float) -> list[Action]:
        self._now = now
        if conn == ROBOT_TCP:
            self.robot_tcp_state = "open"
            self._decoder = FrameDecoder("robot-tcp", MAX_ROBOT_FRAME)
            self.stats["robot-tcp"].connected = True
            self.events.add(now, f"robot TCP connected ({peer[0]}:{peer[1]})")
            self._descriptors_dirty = self._match_info_dirty = self._game_data_dirty = True
            return self._robot_tcp_sends()
        if conn == "fms-tcp":
            out = self.fms.stream_opened(peer, now)
            self._apply_fms_events(now)
            return out
        return [Close(conn, "the Driver Station accepts no connections")]

    def stream_data(self, conn: Hashable, data: bytes, now: float) -> list[Action]:
        self._now = now
        if conn == ROBOT_TCP:
            return self._on_robot_tcp(data, now)
        if conn == "fms-tcp":
            out = self.fms.stream_data(data, now)
            self._apply_fms_events(now)
            return out
        return []

    def stream_closed(self, conn: Hashable, reason: str, now: float) -> list[Action]:
        self._now = now
        if conn == ROBOT_TCP:
            if self.robot_tcp_state != "closed":
                if self.robot_tcp_state == "open":
                    self.events.add(now, f"robot TCP closed: {reason}")
                self.robot_tcp_state = "closed"
                self._tcp_retry_at = now + TCP_RETRY
                self._decoder = None
                self.stats["robot-tcp"].connected = False
        elif conn == "fms-tcp":
            self.fms.stream_closed(reason, now)
            self._apply_fms_events(now)
        return []

    # -- robot UDP -------------------------------------------------------------------------
    def _control_datagram(self, now: float) -> Datagram:
        seq = self._seq
        self._seq = (seq + 1) & 0xFFFF
        enabled, mode = self.enabled, self.mode
        if enabled != self._sent_enabled or (enabled and mode != self._sent_mode):
            self.events.add(now, f"robot enabled ({mode.label})" if enabled else "robot disabled")
        self._sent_enabled, self._sent_mode = enabled, mode
        date = None
        if self._date_due:
            self._date_due, self._date_sent = False, True
            date = self._wall_clock(now)
        state = ControlState(seq, self.estopped, self.fms.attached, enabled, mode, self._reboot_left > 0,
                             self._restart_left > 0, self.station, self.team, self.countdown(now),
                             self._wire_joysticks(now), date, self.timezone_name if date else None)
        self._reboot_left = max(0, self._reboot_left - 1)
        self._restart_left = max(0, self._restart_left - 1)
        data = self._codec.encode_control(state)
        self.trip.sent(seq, now)
        self._outstanding.pop(seq, None)
        self._outstanding[seq] = (now, self.robot_comms)
        self.sent_packets += 1
        self.stats["ds->rio"].sent(len(data))
        dest = self.robot_udp_fms if self.fms.attached else self.robot_udp
        return Datagram(ROBOT, data, dest, self._codec.control_kind)

    @property
    def drives_simulator(self) -> bool:
        """Whether the robot is taken for WPILib's simulator: its status trace says it is no
        roboRIO (a real one and fieldbox's fake one say they are), or, before any status, it
        was presumed (``simulator=True``). The 2010 protocol has no such bit, and no POVs."""
        if self.legacy is not None:
            return False
        if self.robot_comms and self.status is not None:
            return not self.status.is_roborio
        return self.presume_simulator

    def _wire_joysticks(self, now: float) -> tuple[Joystick, ...]:
        """The joystick tags of a control packet: slots 0 to the last one in use, an empty slot
        before it sent empty so slots keep their numbers. With no joystick, none: a real NI DS
        sent no joystick tag at all in 3,118 packets of the 2021 capture, one when a controller
        sat in slot 0 (e.g. frame 7366). To WPILib's simulator, see the module docstring."""
        if self.drives_simulator:
            if not self._simulator_noted:
                self._simulator_noted = True
                self.events.add(now, "the robot looks like WPILib's simulator (no roboRIO in its status): "
                                     "sending one POV per joystick and all six joystick slots (its 2026 "
                                     "release misreads every POV after the first, overruns past 6, and "
                                     "keeps an unplugged slot's last values)")
            return tuple(j if len(j.povs) <= 1 else Joystick(j.axes, j.buttons, j.button_count, j.povs[:1])
                         for j in self._wire)
        used = [i for i, slot in enumerate(self.joysticks) if slot is not None]
        return tuple(self._wire[:used[-1] + 1]) if used else ()

    def _wall_clock(self, now: float) -> _dt.datetime | None:
        try:
            when = self.clock()
            utc = when.astimezone(_dt.timezone.utc) if when.tzinfo else when
            if not 1900 <= utc.year <= 2155:
                raise ValueError(f"year {utc.year} does not fit the date tag")
            self.events.add(now, "robot asked for the date: sent date and time zone")
            return when
        except Exception as exc:  # an injected clock is outside our control: never crash
            self.events.add(now, f"date not sent: the wall clock failed ({exc})")
            return None

    def _robot_host(self, source: Address | None) -> str | None:
        """The host a status packet from ``source`` is taken from, or None: not the robot.

        The robot's host is that of ``robot_udp`` / ``robot_udp_fms`` when it is an IP literal
        (the port is not checked: a robot answers from the port the packet went to). For a host
        name (``roboRIO-254-FRC.local``) the first address that answers is the robot's until
        comms are lost."""
        host = _ip_key(str(source[0])) if source else None
        if host is None:
            return None
        named = False
        for dest in (self.robot_udp, self.robot_udp_fms):
            key = _ip_key(str(dest[0]))
            if key is None:
                named = True
            elif key == host:
                return host
        if named and self.robot_source in (None, host):
            return host
        return None

    def _on_status(self, data: bytes, source: Address | None, now: float) -> None:
        stats = self.stats["rio->ds"]
        try:
            pkt = self._codec.decode_status(data)
        except ProtocolError as exc:
            stats.bad(exc, now)
            return
        host = self._robot_host(source)
        if host is None:
            self.foreign_packets += 1
            stats.foreign_packets += 1
            return
        self.robot_source = host
        stats.received(len(data), now)
        self._last_status = now
        if not self.robot_comms:
            self.robot_comms = True
            self.events.add(now, "robot comms established")
        self.trip.echoed(pkt.sequence, now)
        if self._outstanding.pop(pkt.sequence, None) is None:
            self.stale_echoes += 1
        if self.status is None or pkt.robot_code != self.status.robot_code:
            self.events.add(now, "robot code running" if pkt.robot_code else "no robot code")
        self.status = pkt
        self._battery = pkt.battery
        self.battery_history.append((now, pkt.battery))
        if pkt.brownout and not self.brownout:
            self.brownouts += 1
            self.events.add(now, f"robot brownout ({pkt.battery:.2f} V)")
        self.brownout = pkt.brownout
        self.code_starting = pkt.code_initializing
        self.robot_estopped = pkt.estop
        if self._restart_left and self._restart_had_code and (not pkt.robot_code or pkt.code_initializing):
            self._restart_left = 0  # the robot shows its code restarting: request done
        outputs: list[rio_to_ds.JoystickOutput | None] = []
        for tag in pkt.tags:
            kind = type(tag)
            if kind is rio_to_ds.JoystickOutput:
                if len(outputs) < MAX_JOYSTICKS:  # a 7th slot overwrites nothing
                    outputs.append(tag)
            elif kind is rio_to_ds.DiskInfo:
                self.disk = tag
            elif kind is rio_to_ds.CpuInfo:
                self.cpu = tag
            elif kind is rio_to_ds.RamInfo:
                self.ram = tag
            elif kind is rio_to_ds.PdpLog:
                self.pdp = tag
            elif kind is rio_to_ds.CanMetrics:
                self.can = tag
        self.joystick_outputs = outputs + [None] * (MAX_JOYSTICKS - len(outputs))
        if pkt.request_date and not self._date_sent:
            self._date_due = True

    def wire_ended(self, now: float, why: str) -> None:
        """The process running this DS is gone (the app's copy of it, roles/runtime/wireproc.py): no
        robot comms and no enable are shown any more."""
        self.robot_comms = False
        self._enabled_local = False
        self.trip.reset()
        self.events.add(now, f"{why}: no robot comms, disabled")

    def _check_comms(self, now: float) -> None:
        if not self.robot_comms or now - self._last_status < COMMS_TIMEOUT:
            return
        had_enable = self._enabled_local or self.enabled
        self.robot_comms = False
        self.robot_source = None  # a robot found by name may answer from elsewhere next time
        self._enabled_local = False
        self.trip.reset()
        self._date_due = self._date_sent = False
        self._reboot_left = self._restart_left = 0
        self.events.add(now, "robot comms lost (no status for 1 s): disabled"
                        + ("; enable again by hand once comms return" if had_enable and not self.fms.attached
                           else ""))
        if self.practice is not None:
            self._end_practice(now, "practice run ended: robot comms lost")

    def _expire_echoes(self, now: float) -> None:
        out = self._outstanding
        while out:
            seq = next(iter(out))
            sent_at, counted = out[seq]
            if now - sent_at < ECHO_TIMEOUT:
                break
            del out[seq]
            if counted:
                self.lost_packets += 1
                self.stats["ds->rio"].lost_packets += 1

    # -- robot TCP -------------------------------------------------------------------------
    def _robot_tcp_poll(self, now: float) -> list[Action]:
        if self.robot_tcp_state == "closed" and now >= self._tcp_retry_at:
            self.robot_tcp_state = "connecting"
            return [Connect(ROBOT_TCP, self.robot_tcp)]
        if self.robot_tcp_state == "open":
            return self._robot_tcp_sends()
        return []

    def _robot_tcp_sends(self) -> list[Action]:
        frames: list[bytes] = []
        if self._descriptors_dirty:
            frames += [(slot.descriptor(i) if slot else _empty_descriptor(i)).encode()
                       for i, slot in enumerate(self.joysticks)]
        # Match info and game data go out on connect even when there are none, empty, as a
        # real NI DS sends them (00 06 07 00 00 0000 00 and 00 01 0e, the 2021 capture).
        if self._match_info_dirty:
            frames.append((self.match_info or MatchInfo()).encode())
        if self._game_data_dirty:
            frames.append(GameData(self.game_data or "").encode())
        self._descriptors_dirty = self._match_info_dirty = self._game_data_dirty = False
        stats = self.stats["robot-tcp"]
        for f in frames:
            stats.sent(len(f))
        return [StreamSend(ROBOT_TCP, f, "ds-to-rio-tcp") for f in frames]

    def _on_robot_tcp(self, data: bytes, now: float) -> list[Action]:
        stats = self.stats["robot-tcp"]
        if self.robot_tcp_state != "open" or self._decoder is None:
            return []
        messages, error = decode_frames(self._decoder, data, rio_to_ds.decode_tcp, stats, now)
        for msg in messages:
            self._on_rio_frame(msg, now)
        if error is not None:
            self.events.add(now, f"robot TCP sent a bad frame, closing it: {error}")
            self.stream_closed(ROBOT_TCP, "bad frame", now)
            return [Close(ROBOT_TCP, f"bad frame: {error}")]
        return []

    def _on_rio_frame(self, msg: Any, now: float) -> None:
        kind = type(msg)
        if kind is rio_to_ds.StdoutMessage:
            self.add_console_line(now, "stdout", msg.text)
        elif kind is rio_to_ds.ErrorMessage:
            where = f" ({msg.location})" if msg.location else ""
            code = f"[{msg.error_code}] " if msg.error_code else ""
            self.add_console_line(now, "error" if msg.is_error else "warning", f"{code}{msg.details}{where}")
        elif kind is rio_to_ds.VersionInfo:
            if not msg.is_end_of_list and (msg.name in self.versions or len(self.versions) < MAX_VERSIONS):
                self.versions[_clip(msg.name, MAX_NAME)] = _clip(msg.version, MAX_NAME)
        elif kind is rio_to_ds.DisableFaults:
            self.faults["comms"], self.faults["12v"] = msg.comms, msg.rail_12v
        elif kind is rio_to_ds.RailFaults:
            self.faults["6v"], self.faults["5v"], self.faults["3.3v"] = msg.rail_6v, msg.rail_5v, msg.rail_3v3
        elif kind is rio_to_ds.RadioEvents:
            self.add_console_line(now, "radio", msg.text)
        elif kind is rio_to_ds.UsageReport:
            self.usage_reports += 1
        elif kind is not rio_to_ds.KeepAlive:
            self.unknown_frames += 1

    def add_console_line(self, now: float, level: str, text: str) -> None:
        self.console.append((now, level, _clip(text.rstrip("\r\n"), MAX_TEXT)))
        self.console_total += 1

    # -- hooks for the FMS client ----------------------------------------------------------
    def _apply_fms_events(self, now: float) -> None:
        """What the FMS client says the field asked of this DS (roles/cores/ds_fms.py), in order."""
        for event in self.fms.take_events():
            kind = type(event)
            if kind is FmsAttached:
                self._on_fms_attach(now)
            elif kind is FmsDetached:
                self._on_fms_detach(now, event.reason)
            elif kind is FmsEstopped:
                self._latch_estop(now, "the FMS e-stopped this station")
            elif kind is MatchInfoChanged:
                self._set_match_info(event.info)
            elif kind is GameDataChanged:
                self._set_game_data(event.text)

    def _on_fms_attach(self, now: float) -> None:
        self._enabled_local = False
        if self.practice is not None:
            self._end_practice(now, "practice run ended: an FMS took over")
        self.events.add(now, "FMS attached: it decides enable, mode and station now")

    def _on_fms_detach(self, now: float, reason: str) -> None:
        self._enabled_local = False
        self.events.add(now, f"FMS lost ({reason}): disabled, back to local control; enable by hand")

    def _latch_estop(self, now: float, why: str) -> None:
        if not self.estopped:
            self.estopped = True
            held = ", and then held disabled until the FMS changes phase or detaches" if self.fms.attached else ""
            self.events.add(now, f"E-STOP ({why}): latched until the robot code restarts or the roboRIO "
                                 f"reboots{held}")
        self._enabled_local = False
        if self.fms.attached:
            # A restart clears the e-stop, not the FMS's enable from before it: without this
            # an e-stop then a restart within one FMS packet (500 ms) enabled the robot again
            # on the FMS's last word (found by tests/roles/test_safety.py's property). Held
            # disabled until the FMS changes phase (the period ends) or detaches, as a disable.
            self.fms.hold_disabled = True
        if self.practice is not None:
            self._end_practice(now, "practice run ended: e-stop")

    def _set_match_info(self, info: MatchInfo | None) -> None:
        if info != self.match_info:
            self.match_info = info
            self._match_info_dirty = True

    def _set_game_data(self, text: str) -> None:
        if text != self.game_data:
            self.game_data = text
            self._game_data_dirty = True

    # -- practice --------------------------------------------------------------------------
    def _update_practice(self, now: float) -> None:
        if self.practice is None:
            return
        phase, left = self.practice.phase_at(now)
        if phase is self.practice_phase:
            return
        self.practice_phase = phase
        if phase is PracticePhase.ENDED:
            self._end_practice(now, "practice run over")
        else:
            self.events.add(now, f"practice: {phase.value} ({left:.0f} s)")

    def _end_practice(self, now: float, why: str) -> None:
        self.practice = None
        self.practice_phase = None
        self._enabled_local = False
        self._mode = Mode.TELEOP
        self.events.add(now, why)

    # -- commands --------------------------------------------------------------------------
    def _enable_blocker(self) -> str | None:
        if self.fms.attached:
            return "an FMS is attached: it decides enable"
        if self.estopped:
            return "e-stopped: restart the robot code or reboot the roboRIO to clear it"
        if not self.robot_comms:
            return "no robot comms"
        if self.robot_estopped:
            return "the robot still reports an e-stop: restart its code"
        if not self.robot_code:
            return "no robot code"
        return None

    def enable(self) -> None:
        reason = self._enable_blocker()
        if reason is None and self.practice is not None:
            reason = "a practice run is going: it enables the robot itself"
        if reason:
            raise CommandError(reason)
        self._enabled_local = True

    def disable(self) -> None:
        """Always works. Under an FMS it holds the robot disabled until the FMS changes phase
        (the period ends) or detaches."""
        self._enabled_local = False
        if self.practice is not None:
            self._end_practice(self._now, "practice run stopped: disabled by the operator")
        if self.fms.attached and not self.fms.hold_disabled:
            self.fms.hold_disabled = True
            self.events.add(self._now, "disabled by the operator: held until the FMS changes phase or detaches")

    def estop(self) -> None:
        self._latch_estop(self._now, "operator")

    def set_mode(self, mode: Mode | str) -> None:
        if isinstance(mode, str):
            try:
                mode = Mode.parse(mode)
            except ValueError as exc:
                raise CommandError(str(exc)) from None
        if not isinstance(mode, Mode) or mode is Mode.RESERVED:
            raise CommandError(f"mode must be teleop, auto or test, not {mode!r}")
        if mode not in self._codec.modes:
            raise CommandError(f"the {self._codec.name} protocol has no {mode.label} mode")
        if self.fms.attached:
            raise CommandError("an FMS is attached: it decides the mode")
        if self.practice is not None:
            raise CommandError("a practice run is going: it sets the mode itself")
        if self.enabled:
            raise CommandError("disable the robot before changing mode")
        if mode is not self._mode:
            self._mode = mode
            self.events.add(self._now, f"mode: {mode.label}")

    def set_station(self, station: AllianceStation | str) -> None:
        if isinstance(station, str):
            try:
                station = AllianceStation.parse(station)
            except ValueError as exc:
                raise CommandError(str(exc)) from None
        if not isinstance(station, AllianceStation):
            raise CommandError(f"station must be R1..B3, not {station!r}")
        if self.fms.attached:
            raise CommandError("an FMS is attached: it decides the station")
        self._station = station

    def set_team(self, team: int) -> None:
        try:
            check_team(team)
        except ValueError as exc:
            raise CommandError(str(exc)) from None
        if self.fms.attached:
            raise CommandError("an FMS is attached: detach before changing team")
        if self.enabled:
            raise CommandError("disable the robot before changing team")
        if team != self.team:
            self.team = team
            self.events.add(self._now, f"team: {team}")
            self._pending += self.fms.relogin(self._now)
            self._apply_fms_events(self._now)

    def _request(self, what: str) -> None:
        if not self.robot_comms:
            raise CommandError(f"no robot comms: cannot {what}")
        self._enabled_local = False
        if self.practice is not None:
            self._end_practice(self._now, f"practice run stopped: {what}")
        if self.estopped:
            self.estopped = False
            self.events.add(self._now, f"e-stop cleared: {what} requested")

    def restart_code(self) -> None:
        self._request("restart robot code")
        self._restart_left = REQUEST_PACKETS
        self._restart_had_code = self.robot_code
        self.events.add(self._now, "restart robot code requested")

    def reboot_roborio(self) -> None:
        self._request("reboot the roboRIO")
        self._reboot_left = REQUEST_PACKETS
        self.events.add(self._now, "reboot roboRIO requested")

    def set_game_data(self, text: str) -> None:
        """Local game data (practice, bench tests); an FMS's game data replaces it."""
        if not isinstance(text, str) or len(text.encode("utf-8", "surrogateescape")) > 255:
            raise CommandError("game data must be text of at most 255 bytes")
        self._set_game_data(text)

    def start_practice(self, timing: PracticeTiming | None = None) -> None:
        reason = self._enable_blocker()
        if reason is None and self.practice is not None:
            reason = "a practice run is already going"
        if reason:
            raise CommandError(reason)
        self._enabled_local = False
        self.practice = PracticeRun(timing or self.practice_timing, self._now)
        self.practice_phase = None
        self.events.add(self._now, "practice run started")
        self._update_practice(self._now)

    def stop_practice(self) -> None:
        if self.practice is None:
            raise CommandError("no practice run is going")
        self._end_practice(self._now, "practice run stopped by the operator")

    def set_robot_addresses(self, robot_udp: Address | None = None, robot_tcp: Address | None = None,
                            robot_udp_fms: Address | None = None) -> None:
        if robot_udp is not None or robot_udp_fms is not None:
            self.robot_source = None  # whoever answers at the new address
        if robot_udp is not None:
            self.robot_udp = robot_udp
            self.robot_udp_fms = robot_udp_fms or _fms_port(robot_udp)
        elif robot_udp_fms is not None:
            self.robot_udp_fms = robot_udp_fms
        if robot_tcp is not None and robot_tcp != self.robot_tcp:
            self.robot_tcp = robot_tcp
            if self.robot_tcp_state != "closed":
                self._pending.append(Close(ROBOT_TCP, "robot address changed"))
                self.stream_closed(ROBOT_TCP, "robot address changed", self._now)
                self._tcp_retry_at = self._now

    def set_fms_addresses(self, fms_tcp: Address | None, fms_udp: Address | None) -> None:
        """Another FMS (None, None: no FMS). An attached FMS is detached: disabled."""
        self._pending += self.fms.set_addresses(fms_tcp, fms_udp, self._now)
        self._apply_fms_events(self._now)

    # -- joystick commands -----------------------------------------------------------------
    def _slot(self, slot: Any) -> JoystickSlot:
        _int_arg(slot, "joystick slot", 0, MAX_JOYSTICKS - 1)
        joy = self.joysticks[slot]
        if joy is None:
            raise CommandError(f"no joystick in slot {slot}")
        return joy

    def set_joystick(self, slot: int, axes_count: int, button_count: int, pov_count: int, name: str = "",
                     is_xbox: bool = False, joystick_type: JoystickType | int = JoystickType.UNKNOWN,
                     axis_types: tuple[int, ...] | list[int] | None = None) -> None:
        _int_arg(slot, "joystick slot", 0, MAX_JOYSTICKS - 1)
        _int_arg(axes_count, "axis count", 0, MAX_AXES)
        _int_arg(button_count, "button count", 0, MAX_BUTTONS)
        _int_arg(pov_count, "POV count", 0, MAX_POVS)
        if not isinstance(name, str) or len(name.encode("utf-8", "surrogateescape")) > 255:
            raise CommandError("joystick name must be text of at most 255 bytes")
        _int_arg(joystick_type, "joystick type", -128, 127)
        types = tuple(axis_types) if axis_types is not None else tuple(min(i, 4) for i in range(axes_count))
        if len(types) != axes_count:
            raise CommandError(f"{len(types)} axis types given for {axes_count} axes")
        for t in types:
            _int_arg(t, "axis type", 0, 255)
        self.joysticks[slot] = JoystickSlot(name, bool(is_xbox), joystick_type, tuple(int(t) for t in types),
                                            [0.0] * axes_count, button_count, [-1] * pov_count)
        self._wire[slot] = self.joysticks[slot].wire()
        self._descriptors_dirty = True

    def clear_joystick(self, slot: int) -> None:
        _int_arg(slot, "joystick slot", 0, MAX_JOYSTICKS - 1)
        if self.joysticks[slot] is not None:
            self.joysticks[slot] = None
            self._wire[slot] = EMPTY_JOYSTICK
            self._descriptors_dirty = True

    def set_axis(self, slot: int, axis: int, value: float) -> None:
        joy = self._slot(slot)
        if not joy.axes:
            raise CommandError(f"the joystick in slot {slot} has no axes")
        _int_arg(axis, "axis", 0, len(joy.axes) - 1)
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) \
                or not -1.0 <= value <= 1.0:
            raise CommandError(f"axis value must be -1.0..1.0, not {value!r}")
        joy.axes[axis] = float(value)
        self._wire[slot] = joy.wire()

    def set_button(self, slot: int, button: int, pressed: bool) -> None:
        joy = self._slot(slot)
        if not joy.button_count:
            raise CommandError(f"the joystick in slot {slot} has no buttons")
        _int_arg(button, "button", 1, joy.button_count)
        if pressed not in (True, False, 0, 1) or isinstance(pressed, float):
            raise CommandError(f"pressed must be true or false, not {pressed!r}")
        bit = 1 << (button - 1)
        joy.buttons = joy.buttons | bit if pressed else joy.buttons & ~bit
        self._wire[slot] = joy.wire()

    def set_pov(self, slot: int, pov: int, degrees: int) -> None:
        joy = self._slot(slot)
        if not joy.povs:
            raise CommandError(f"the joystick in slot {slot} has no POVs")
        _int_arg(pov, "POV", 0, len(joy.povs) - 1)
        if isinstance(degrees, bool) or not isinstance(degrees, int) or not -1 <= degrees <= 359:
            raise CommandError(f"POV angle must be 0..359 or -1 (centred), not {degrees!r}")
        joy.povs[pov] = degrees
        self._wire[slot] = joy.wire()


@functools.lru_cache(maxsize=1024)  # three calls per status packet: 150 a second per DS
def _ip_key(host: str) -> str | None:
    """An IP literal in one spelling (an IPv4-mapped IPv6 address as IPv4), None for a name."""
    try:
        ip = ipaddress.ip_address(host.split("%", 1)[0])
    except ValueError:
        return None
    if ip.version == 6 and ip.ipv4_mapped is not None:
        ip = ip.ipv4_mapped
    return str(ip)


def _fms_port(robot_udp: Address) -> Address:
    """Port 1115 on the robot's host when the robot listens on the real 1110; on an
    OS-chosen port (ephemeral plan) there is no second port to know: the same address."""
    return (robot_udp[0], ROBOT_UDP_FMS) if robot_udp[1] == ROBOT_UDP else robot_udp
