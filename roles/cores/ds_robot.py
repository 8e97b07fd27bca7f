"""The Driver Station's robot UDP link: the 20 ms control packets and the status packets
that answer them (roles/cores/ds.py's module docstring states the rules kept here).

:class:`RobotLink` sends on the grid, takes status only from the robot, keeps robot comms
and the restart/reboot requests; :class:`EchoLedger` matches echoes to control packets (trip
times, lost packets); :class:`DateTag` sends the date once the robot asks;
:class:`RobotTelemetry` keeps what the status packets report beyond their bits. What goes in
a control packet about enable, mode and joysticks the DS hands in; a status packet the link
accepted it hands back, for the DS to route.
"""

from __future__ import annotations

import datetime as _dt
import functools
import ipaddress
import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Callable

from protocol import rio_to_ds
from protocol.ds_to_rio import Joystick
from protocol.enums import AllianceStation, Mode
from protocol.errors import ProtocolError
from protocol.rio_to_ds import StatusPacket

from .addresses import ROBOT_UDP, ROBOT_UDP_FMS
from .core import Address, Datagram, Events, Grid, LinkStats, Stream, Throttle, TripTimer
from .views import EchoView, LinkView, TelemetryView, TripView

if TYPE_CHECKING:  # pragma: no cover
    from .ds_joysticks import JoystickSlots

ROBOT = "robot"
COMMS_TIMEOUT = 1.0
ECHO_TIMEOUT = 1.0
REQUEST_PACKETS = 10
BATTERY_SAMPLES = 3000  # one minute at 50 Hz


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


class EchoLedger:
    """Control packets sent and the status packets echoing their sequence numbers: trip times
    (the last 256, ``trip``), packets lost (sent while robot comms were up, no echo within
    ``ECHO_TIMEOUT``: a lost control packet and a lost reply count alike) and stale echoes
    (of nothing outstanding: late or duplicated)."""

    def __init__(self, stats: LinkStats) -> None:
        self.trip = TripTimer()
        self.sent_packets = 0
        self.lost_packets = 0
        self.stale_echoes = 0
        self._stats = stats  # the "ds->rio" link, which counts the lost packets too
        self._outstanding: dict[int, tuple[float, bool]] = {}  # sequence -> (sent at, comms up)

    def sent(self, seq: int, now: float, robot_comms: bool) -> None:
        self.trip.sent(seq, now)
        self._outstanding.pop(seq, None)
        self._outstanding[seq] = (now, robot_comms)
        self.sent_packets += 1

    def view(self) -> EchoView:
        trip = self.trip
        return EchoView(self.sent_packets, self.lost_packets, self.stale_echoes,
                        TripView(trip.samples.view(), trip.last_ms))

    def echoed(self, seq: int, now: float) -> None:
        self.trip.echoed(seq, now)
        if self._outstanding.pop(seq, None) is None:
            self.stale_echoes += 1

    def expire(self, now: float) -> None:
        out = self._outstanding
        while out:
            seq = next(iter(out))
            sent_at, counted = out[seq]
            if now - sent_at < ECHO_TIMEOUT:
                break
            del out[seq]
            if counted:
                self.lost_packets += 1
                self._stats.lost_packets += 1


class DateTag:
    """The date (0x0f) and time zone (0x10) tags: in the first control packet after a status
    packet that asks, then not again until robot comms are lost (a rebooted robot asks anew)."""

    def __init__(self, clock: Callable[[], _dt.datetime], timezone_name: str) -> None:
        self.clock = clock
        self.timezone_name = timezone_name
        self._due = False
        self._sent = False

    def asked(self) -> None:
        if not self._sent:
            self._due = True

    def forget(self) -> None:
        self._due = self._sent = False

    def take(self, now: float, events: Events) -> _dt.datetime | None:
        """The wall clock for this packet, if the tags are due (None: not due, or it failed)."""
        if not self._due:
            return None
        self._due, self._sent = False, True
        try:
            when = self.clock()
            utc = when.astimezone(_dt.timezone.utc) if when.tzinfo else when
            if not 1900 <= utc.year <= 2155:
                raise ValueError(f"year {utc.year} does not fit the date tag")
            events.add(now, "robot asked for the date: sent date and time zone")
            return when
        except Exception as exc:  # an injected clock is outside our control: never crash
            events.add(now, f"date not sent: the wall clock failed ({exc})")
            return None


class RobotTelemetry:
    """What the robot's status packets report beyond their bits: the battery's history,
    brownouts, and the last disk, CPU, RAM, PDP and CAN tags."""

    def __init__(self, events: Events) -> None:
        self.events = events
        self.battery_history: Stream[tuple[float, float]] = Stream(BATTERY_SAMPLES)  # (time, volts)
        self.brownout = False
        self.brownouts = 0
        # when the brownout bit last changed (the status packet's arrival): the NI log shows a
        # brownout's end at its record, though no event marks the end
        self.brownout_changed: float | None = None
        self.disk: rio_to_ds.DiskInfo | None = None
        self.cpu: rio_to_ds.CpuInfo | None = None
        self.ram: rio_to_ds.RamInfo | None = None
        self.pdp: rio_to_ds.PdpLog | None = None
        self.can: rio_to_ds.CanMetrics | None = None

    def view(self) -> TelemetryView:
        return TelemetryView(self.battery_history.view(), self.brownout, self.brownouts, self.brownout_changed,
                             self.disk, self.cpu, self.ram, self.pdp, self.can)

    def take(self, pkt: StatusPacket, now: float) -> None:
        self.battery_history.append((now, pkt.battery))
        if pkt.brownout and not self.brownout:
            self.brownouts += 1
            self.events.add(now, f"robot brownout ({pkt.battery:.2f} V)")
        if pkt.brownout != self.brownout:  # after the event: its listeners see the state before
            self.brownout_changed = now
        self.brownout = pkt.brownout
        for tag in pkt.tags:
            if type(tag) is rio_to_ds.DiskInfo:
                self.disk = tag
            elif type(tag) is rio_to_ds.CpuInfo:
                self.cpu = tag
            elif type(tag) is rio_to_ds.RamInfo:
                self.ram = tag
            elif type(tag) is rio_to_ds.PdpLog:
                self.pdp = tag
            elif type(tag) is rio_to_ds.CanMetrics:
                self.can = tag


class RobotLink:
    """The UDP side of one DS's robot link. ``codec`` is the robot codec (roles/cores/ds.py's
    :func:`~roles.cores.ds.robot_codec`); ``simulator`` presumes WPILib's simulator until a
    status packet says what the robot is."""

    def __init__(self, codec: Any, robot_udp: Address, robot_udp_fms: Address | None, events: Events, *,
                 period: float, clock: Callable[[], _dt.datetime], timezone_name: str,
                 simulator: bool = False) -> None:
        self.codec = codec
        self.events = events
        self.robot_udp: Address = robot_udp
        self.robot_udp_fms: Address = robot_udp_fms or _fms_port(robot_udp)
        #: the robot is taken for WPILib's simulator until a status packet says what it is
        self.presume_simulator = simulator
        self._simulator_noted = False
        self.stats_out = LinkStats("ds->rio")
        self.stats_in = LinkStats("rio->ds")
        self.echoes = EchoLedger(self.stats_out)
        self.date = DateTag(clock, timezone_name)
        self.robot_comms = False
        self.status: StatusPacket | None = None
        self.missed_slots = 0
        #: robot status packets from an address that is not the robot's, dropped (also
        #: counted on the "rio->ds" link); ``robot_source`` is the host status is taken from
        self.foreign_packets = 0
        self.robot_source: str | None = None
        self._refusals = Throttle()  # a refusal is logged once a second
        self._last_status = -math.inf
        self._seq = 0
        self._sends = Grid(period)  # the 20 ms control packets
        self._reboot_left = 0
        self._restart_left = 0
        self._restart_had_code = False

    # -- what the status packets say --------------------------------------------------------------
    @property
    def robot_code(self) -> bool:
        return self.robot_comms and self.status is not None and self.status.robot_code

    @property
    def robot_estopped(self) -> bool:
        """The robot's own e-stop, as its last status packet said."""
        return self.status is not None and self.status.estop

    @property
    def code_starting(self) -> bool:
        return self.status is not None and self.status.code_initializing

    @property
    def battery(self) -> float | None:
        return self.status.battery if self.robot_comms and self.status is not None else None

    @property
    def program_mode(self) -> str:
        """The mode the robot program says it runs (the status packet's trace bits)."""
        s = self.status
        if not self.robot_comms or s is None:
            return ""
        return ("disabled" if s.user_disabled else "auto" if s.user_auto else "teleop" if s.user_teleop
                else "test" if s.user_test else "")

    @property
    def drives_simulator(self) -> bool:
        """Whether the robot is taken for WPILib's simulator: its status trace says it is no
        roboRIO (a real one and fieldbox's fake one say they are), or, before any status, it
        was presumed (``simulator=True``). The 2010 protocol has no such bit, and no POVs."""
        if self.codec.name == "2010":
            return False
        if self.robot_comms and self.status is not None:
            return not self.status.is_roborio
        return self.presume_simulator

    def view(self) -> LinkView:
        return LinkView(self.robot_udp, self.robot_udp_fms, self.presume_simulator, self.date.timezone_name,
                        self.robot_comms, self.robot_code, self.status, self.robot_estopped, self.code_starting,
                        self.battery, self.program_mode, self.drives_simulator, self.robot_source,
                        self.foreign_packets, self.missed_slots, self.echoes.view())

    # -- the 20 ms beat -------------------------------------------------------------------------
    @property
    def started(self) -> bool:
        return self._sends.origin is not None

    def slot_due(self, now: float) -> bool:
        """Whether a control packet is due at ``now`` (the first poll starts the grid); the
        slots a late poll skipped are counted in ``missed_slots``, never sent."""
        if self._sends.origin is None:
            self._sends.start(now)
        skipped = self._sends.take(now)
        if skipped is None:
            return False
        self.missed_slots += skipped
        return True

    def control_datagram(self, now: float, *, estop: bool, fms_attached: bool, enabled: bool, mode: Mode,
                         station: AllianceStation, team: int, countdown: float | None,
                         sticks: JoystickSlots) -> Datagram:
        seq = self._seq
        self._seq = (seq + 1) & 0xFFFF
        date = self.date.take(now, self.events)
        state = ControlState(seq, estop, fms_attached, enabled, mode, self._reboot_left > 0,
                             self._restart_left > 0, station, team, countdown, self._joystick_tags(sticks, now),
                             date, self.date.timezone_name if date else None)
        self._reboot_left = max(0, self._reboot_left - 1)
        self._restart_left = max(0, self._restart_left - 1)
        data = self.codec.encode_control(state)
        self.echoes.sent(seq, now, self.robot_comms)
        self.stats_out.sent(len(data))
        dest = self.robot_udp_fms if fms_attached else self.robot_udp
        return Datagram(ROBOT, data, dest, self.codec.control_kind)

    def _joystick_tags(self, sticks: JoystickSlots, now: float) -> tuple[Joystick, ...]:
        simulator = self.drives_simulator
        if simulator and not self._simulator_noted:
            self._simulator_noted = True
            self.events.add(now, "the robot looks like WPILib's simulator (no roboRIO in its status): "
                                 "sending one POV per joystick and all six joystick slots (its 2026 "
                                 "release misreads every POV after the first, overruns past 6, and "
                                 "keeps an unplugged slot's last values)")
        return sticks.tags(simulator)

    def next_deadline(self) -> float | None:
        """The next slot of the grid, or the moment robot comms time out if sooner."""
        deadline = self._sends.next
        if self.robot_comms and deadline is not None:
            deadline = min(deadline, self._last_status + COMMS_TIMEOUT)
        return deadline

    # -- status packets ---------------------------------------------------------------------------
    def on_status(self, data: bytes, source: Address | None, now: float) -> StatusPacket | None:
        """A datagram on the robot channel: the status packet if it is the robot's, else None
        (others' are counted and dropped before a byte is decoded, as a flood from anywhere
        must cost no more; bad ones, a packet over the size bound too, are counted)."""
        stats = self.stats_in
        host = self._robot_host(source)
        if host is None:
            self.foreign_packets += 1
            stats.foreign_packets += 1
            held = self._refusals.due("status", now)
            if held is not None:
                where = f"{source[0]}:{source[1]}" if source else "?"
                robot = self.robot_source or self.robot_udp[0]
                self.events.add(now, f"robot status from {where} ignored: the robot is {robot}{Throttle.suffix(held)}")
            return None
        try:
            pkt: rio_to_ds.StatusPacket = self.codec.decode_status(data)
        except ProtocolError as exc:
            stats.bad(exc, now)
            return None
        self.robot_source = host
        stats.received(len(data), now)
        self._last_status = now
        if not self.robot_comms:
            self.robot_comms = True
            self.events.add(now, "robot comms established")
        self.echoes.echoed(pkt.sequence, now)
        if self.status is None or pkt.robot_code != self.status.robot_code:
            self.events.add(now, "robot code running" if pkt.robot_code else "no robot code")
        self.status = pkt
        if self._restart_left and self._restart_had_code and (not pkt.robot_code or pkt.code_initializing):
            self._restart_left = 0  # the robot shows its code restarting: request done
        if pkt.request_date:
            self.date.asked()
        return pkt

    def is_robot(self, source: Address | None) -> bool:
        """Whether a datagram from ``source`` comes from the robot (its host, any port)."""
        return self._robot_host(source) is not None

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

    def comms_timed_out(self, now: float) -> bool:
        return self.robot_comms and now - self._last_status >= COMMS_TIMEOUT

    def lose_comms(self) -> None:
        """Robot comms are lost: the requests and the date start over with the next robot."""
        self.robot_comms = False
        self.robot_source = None  # a robot found by name may answer from elsewhere next time
        self.echoes.trip.reset()
        self.date.forget()
        self._reboot_left = self._restart_left = 0

    @property
    def still_estopped(self) -> bool:
        """The robot reports an e-stop that no restart or reboot asked now will clear: not while a
        request goes out, nor while its code is (re)starting."""
        return (self.robot_comms and self.robot_estopped and self.robot_code
                and not (self._restart_left or self._reboot_left))

    # -- commands ----------------------------------------------------------------------------------
    def request_restart(self, now: float) -> None:
        """Restart-code bits for ``REQUEST_PACKETS`` packets, or until the robot, which had code
        when asked, shows its code restarting."""
        self._restart_left = REQUEST_PACKETS
        self._restart_had_code = self.robot_code
        self.events.add(now, "restart robot code requested")

    def request_reboot(self, now: float) -> None:
        self._reboot_left = REQUEST_PACKETS
        self.events.add(now, "reboot roboRIO requested")

    def set_addresses(self, robot_udp: Address | None, robot_udp_fms: Address | None) -> None:
        if robot_udp is not None or robot_udp_fms is not None:
            self.robot_source = None  # whoever answers at the new address
        if robot_udp is not None:
            self.robot_udp = robot_udp
            self.robot_udp_fms = robot_udp_fms or _fms_port(robot_udp)
        elif robot_udp_fms is not None:
            self.robot_udp_fms = robot_udp_fms


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
