"""The fake roboRIO: a sans-IO core that answers a Driver Station like a real robot.

Channels and connections (the shell owns the sockets, see roles/cores/core.py):

* UDP ``"ds"`` (the robot address, port 1110) and ``"ds-fms"`` (port 1115, used while the
  DS is attached to an FMS): every DS control packet is answered at once, from the channel
  it arrived on, to the DS's address on port 1150 (``reply_port``; ``None`` answers the
  packet's source port, for the ephemeral address plan);
* TCP 1740: each DS connection is whatever hashable ``conn`` the shell passes to
  ``stream_opened``; one :class:`~protocol.framing.FrameDecoder` per connection.

Behaviour, as a real roboRIO (PROTOCOL-NOTES "How a real roboRIO behaves"): the status byte
echoes the DS's e-stop/enabled/mode bits as the robot applies them; no DS packet for
``watchdog`` seconds disables (a comms disable fault); an e-stop latches until the code
restarts or the roboRIO reboots; restart code shows "code starting" for a moment; a reboot
goes silent for a few seconds and comes back fresh; only one DS is followed at a time.

Nothing is obeyed late. The shell says when each datagram *arrived* (the kernel's receive
time) and whether a newer one from the same sender was already waiting behind it; the
watchdog counts from arrival. A control packet is obeyed only if it is the newest: not
superseded, taken up within ``watchdog`` of its arrival, and its 16-bit sequence newer than
the last one obeyed (serial-number arithmetic; the last one counts only while younger than
``watchdog``, so a DS that restarts from 0 is taken again, disabled, once the watchdog has
tripped). Anything else is counted in ``faults.stale_packets`` (and the link's
``stale_packets``), answered with the state applied now, and changes nothing. A sequence
more than :data:`MAX_SEQUENCE_JUMP` ahead is counted in ``faults.sequence_jumps`` and not
obeyed either. The e-stop bit is the exception: from the DS followed, in any packet, stale
or not, it latches at once.

A control packet with a malformed tag is obeyed for its header, as WPILib's robot side does;
the tag's data is dropped and counted in ``faults.malformed_tags`` (a malformed joystick keeps
its slot, neutral).

TCP clients are bounded (``max_clients``, and half of that from any one host); with every
slot taken, a newcomer evicts the oldest client that never sent a valid frame, else one
silent for over 5 s, else is refused; the host of the DS followed on UDP is always served.

The robot program runs every 20 ms on a drift-free grid, apart from the network side
(roles/runtime/program_host.py): a program file runs in a process of its own when ``isolate`` is set
(every real-socket field), so the replies, the watchdog and the e-stop never wait for it. A
call still running when the next beat comes is an overrun (counted, reported once a
second); one that has not returned for a second is *stuck* (``code_state`` "stuck": the
robot still answers, as a real roboRIO whose user code hangs; restart code kills it).

Every event method returns the actions to perform at once; ``poll(now)`` returns what is
due by time and ``next_deadline()`` says when to call it next.
"""

from __future__ import annotations

import math
import os
from collections import deque
from dataclasses import dataclass
from typing import Any, Callable, Hashable

from protocol import ds_to_rio, rio_to_ds
from protocol.ds_to_rio import EMPTY_JOYSTICK, ControlPacket, Countdown, Date, Joystick, MalformedTag, Timezone
from protocol.enums import AllianceStation, DeviceType, Mode
from protocol.errors import ProtocolError
from protocol.framing import FrameDecoder
from protocol.rio_to_ds import (CanMetrics, CpuInfo, CpuLoad, DisableFaults, DiskInfo, ErrorMessage,
                                IDLE_JOYSTICK_OUTPUT, JoystickOutput, PdpLog, RailFaults, RamInfo,
                                StatusPacket, StdoutMessage, UsageReport, VersionInfo)

from ..runtime.program_host import (NO_OUTPUTS, STUCK_AFTER, Ended, InlineHost, LoadFailed, Loaded, Message,
                                    ProcessHost, ProgramOutputs, Result, check_program)
from .addresses import DS_UDP
from .battery import Battery
from .views import RioView
from .core import (Action, Address, Close, CommandError, Datagram, Events, Grid, LinkStats, StreamSend, Throttle,
                   decode_frames)
from .robot_program import (MAX_TEXT, SLOTS, BuiltinProgram, ControlState, JoystickState, Program,
                            ProgramError, RobotApi, load_program)

CHANNEL_DS = "ds"
CHANNEL_DS_FMS = "ds-fms"
CHANNELS = (CHANNEL_DS, CHANNEL_DS_FMS)
LINK_DS_TO_RIO = "ds->rio"
LINK_RIO_TO_DS = "rio->ds"
LINK_TCP = "rio-tcp"

BEAT = 0.020  # the robot program's period (TimedRobot's default)

CODE_RUNNING = "running"
CODE_STARTING = "starting"
CODE_REBOOTING = "rebooting"
CODE_NONE = "no code"
CODE_STUCK = "stuck"  # the program's call has not returned for STUCK_AFTER: the robot still answers
CODE_ALIVE = (CODE_RUNNING, CODE_STUCK)

#: A sequence number further ahead of the last one obeyed than this (a second of packets),
#: plus two a beat since that one arrived, is not a DS that lost a few: it is counted and not
#: obeyed (a forged packet must not make the real DS's next packets look old).
MAX_SEQUENCE_JUMP = 50
#: How often overruns of the program's 20 ms are reported (WPILib prints each loop's).
OVERRUN_REPORT = 1.0

IMAGE_VERSION = "FRC_roboRIO_2025_v2.0"
LIB_VERSION = "fieldbox fake roboRIO"
RAILS = ("6v", "5v", "3.3v")
# A program that prints in a tight loop must not flood the DS: messages past this many in
# one 20 ms beat are counted and dropped (with one warning saying so).
MAX_MESSAGES_PER_BEAT = 50
# The DS sends small frames (descriptors, match info, game data); a larger size field is a
# broken or hostile peer, closed at once rather than buffered.
MAX_DS_FRAME = 8192
# With every TCP slot taken, a newcomer evicts a client that never sent a valid frame (the
# oldest first), else one silent for longer than this (a DS that sent nothing new for a while
# is normal, so the bar is high): idle or half-sent connections cannot lock a DS out.
CLIENT_IDLE_EVICT = 5.0

_MODE_LABEL = {Mode.TELEOP: "teleop", Mode.TEST: "test", Mode.AUTONOMOUS: "auto", Mode.RESERVED: "mode 3"}


# -- the wire seam --------------------------------------------------------------------
@dataclass(frozen=True)
class RioWire:
    """The one place the fake roboRIO's wire format is chosen.

    The 2010 legacy protocol plugs in here with its own decoder and encoder
    (roles/cores/legacy_rio.py); the core only ever calls these, and the two methods below.
    """

    name: str
    decode_control: Callable[[bytes], ControlPacket]
    encode_status: Callable[[StatusPacket], bytes]
    decode_tcp: Callable[[bytes], Any]
    status_kind: str
    tcp_kind: str

    def bind(self, rio: Any) -> "RioWire":
        """The wire one Rio uses (the 2010 wire reads that Rio's team, LCD and outputs)."""
        return self

    def console_actions(self, kind: str, text: str) -> list[Action]:
        """Datagrams carrying one console line (the 2010 NetConsole); 2015+ uses TCP frames."""
        return []

    def ds_inputs(self) -> tuple[int, tuple[int, ...]] | None:
        """2010: the DS's (digital, analog) inputs in the packet just decoded; 2015+: None."""
        return None


WIRE_2015 = RioWire("2015", ds_to_rio.decode_control, StatusPacket.encode, ds_to_rio.decode_tcp,
                    "rio-to-ds", "rio-to-ds-tcp")
WIRES = {"2015": WIRE_2015}


def wire_for(name: str) -> RioWire:
    if name in WIRES:
        return WIRES[name]
    if name in ("2010", "legacy", "legacy-2010"):
        from .legacy_rio import LegacyRioWire

        return LegacyRioWire()
    raise ValueError(f"unknown roboRIO wire {name!r}: one of {', '.join(WIRES)}")


# -- plain state ----------------------------------------------------------------------
@dataclass
class RioFaults:
    """Counters a panel shows. comms/rail_12v go out in TCP frame 0x04, the rails in 0x05."""

    comms: int = 0  # disables because DS packets stopped (watchdog)
    rail_12v: int = 0  # brownouts
    rail_6v: int = 0
    rail_5v: int = 0
    rail_3v3: int = 0
    program_errors: int = 0  # exceptions raised inside the robot program
    foreign_packets: int = 0  # packets from a second DS, ignored
    stale_packets: int = 0  # control packets not the newest, or taken up late: answered, not obeyed
    sequence_jumps: int = 0  # control packets whose sequence jumped too far ahead: answered, not obeyed
    program_overruns: int = 0  # program calls that took longer than their 20 ms
    output_problems: int = 0  # program outputs refused or clamped (NaN, None, out of range)
    evicted_clients: int = 0  # TCP clients closed to make room (never sent a valid frame, or long idle)
    missed_beats: int = 0  # 20 ms program slots skipped because poll came late
    refused_clients: int = 0  # TCP connections over the bound
    console_dropped: int = 0  # program messages over the per-beat bound
    malformed_tags: int = 0  # control-packet tags not laid out as documented: header applied, tag dropped


@dataclass(frozen=True, slots=True)
class ConsoleLine:
    time: float  # the core's clock
    kind: str  # "stdout", "warning" or "error"
    text: str
    sequence: int


class Rio:
    """The fake roboRIO core. See the module docstring for channels and behaviour."""

    def __init__(self, *, team: int = 0, program: Program | str | os.PathLike | None = None,
                 reply_port: int | None = DS_UDP, watchdog: float = 0.100, restart_time: float = 1.0,
                 reboot_time: float = 3.0, single_ds: bool = True, ds_timeout: float = 1.0,
                 extra_tags: bool = True, battery: Battery | None = None, max_clients: int = 8,
                 usage_interval: float = 5.0, max_failures: int = 5, console_size: int = 500,
                 backlog: int = 50, wire: str = "2015", image_version: str = IMAGE_VERSION,
                 lib_version: str = LIB_VERSION, isolate: bool = False, now: float | None = None) -> None:
        self.team = team
        #: Run a program file in a process of its own (roles/runtime/program_host.py). Off on a fake
        #: clock (the tests): there the file runs in the core's thread, deterministically.
        self.isolate = isolate
        self.reply_port = reply_port
        self.watchdog = watchdog
        self.restart_time = restart_time
        self.reboot_time = reboot_time
        self.single_ds = single_ds
        self.ds_timeout = ds_timeout
        self.extra_tags = extra_tags
        self.max_clients = max_clients
        self.usage_interval = usage_interval
        self.max_failures = max_failures
        self.image_version = image_version
        self.lib_version = lib_version
        self._wire = wire_for(wire)
        self.battery = battery if battery is not None else Battery()
        self.events = Events()
        self.console: deque[ConsoleLine] = deque(maxlen=console_size)
        self.stats = {name: LinkStats(name) for name in (LINK_DS_TO_RIO, LINK_RIO_TO_DS, LINK_TCP)}
        self.robot = RobotApi(self._emit)
        #: 2010: where NetConsole text goes (None: the address the DS's packets come from, port 6666)
        self.netconsole_address: Address | None = None
        self._wire = self._wire.bind(self)

        # the robot program: a factory, so a restart re-initialises it
        self._program_path: str | None = None
        self._program_callable: Program | None = None
        self._preloaded: Program | None = None
        self.program_name = BuiltinProgram.name
        if isinstance(program, (str, os.PathLike)):
            self._program_path = os.fspath(program)
            if isolate:  # its top level runs in its own process, never here
                check_program(self._program_path)  # ProgramError
            else:
                self._preloaded = load_program(self._program_path, console=self.robot.print)  # ProgramError
            self.program_name = os.path.basename(self._program_path)
        elif program is not None:
            if not callable(program):
                raise TypeError(f"program must be a path or a callable, not {program!r}")
            self._program_callable = program
            self.program_name = getattr(program, "__name__", type(program).__name__)
        self._host: InlineHost | ProcessHost | None = None
        self._arriving = False  # a control packet is being taken up: no enable before it is

        self._booted_at: float | None = None
        self._now = 0.0
        self._pending: list[Action] = []
        self._wake_at: float | None = None
        self._clients: dict[Hashable, FrameDecoder] = {}
        # per client: (opened at, last valid frame at or None, peer host) for eviction
        self._client_life: dict[Hashable, tuple[float, float | None, str | None]] = {}
        self._tcp_log = Throttle()  # refused and evicted clients: logged once a second
        self._backlog_size = backlog
        self._beat_messages = 0
        self._fresh_boot_state()
        self.faults = RioFaults()
        self.beats = 0
        if now is not None:
            self._init(now)

    def _fresh_boot_state(self) -> None:
        """Everything a reboot forgets."""
        self.code_state = CODE_RUNNING
        self.program_out: ProgramOutputs = NO_OUTPUTS  # the program's outputs, as checked
        self._ds_inputs: tuple[int, tuple[int, ...]] = (0, (0, 0, 0, 0))  # 2010: the DS's digital, analog in
        self._call_state: ControlState | None = None  # the state of the call under way
        self._stuck_since: float | None = None
        self._overruns = 0  # since the last report
        self._longest_ms = 0.0
        self._overrun_reported_at = float("-inf")
        self._problems_reported: set[str] = set()
        self._code_started_at = 0.0
        self._code_ready_at: float | None = None
        self._reboot_until: float | None = None
        self._consecutive_failures = 0
        self.estopped = False
        self.enabled = False  # applied
        self.mode = Mode.TELEOP  # the DS's mode, echoed
        self.watchdog_tripped = False
        self.ds_address: Address | None = None
        self.ds_enabled = False  # what the DS asks
        self.ds_estop = False
        self.fms_attached = False
        self.station = AllianceStation.RED1
        self.last_sequence: int | None = None
        self._last_packet_at: float | None = None  # when the last packet obeyed arrived
        self._ds_alive = False
        self._restart_bit = False
        self._reboot_bit = False
        self._joystick_tags: tuple[Joystick, ...] = ()
        self._joystick_states: tuple[JoystickState, ...] | None = ()
        self._amps_key: Any = None
        self._amps: list[float] = [0.0] * 16
        self._extra_key: Any = None
        self._extra: list = []
        self.countdown: float | None = None
        self.got_date = False
        self.got_timezone = False
        self.ds_date = None
        self.ds_timezone = ""
        self.descriptors: list[ds_to_rio.JoystickDescriptor | None] = [None] * SLOTS
        self.match_info: ds_to_rio.MatchInfo | None = None
        self.game_data = ""
        self._trace_mode: str | None = None
        self._seq = 0
        self._backlog: deque[bytes] = deque(maxlen=self._backlog_size)
        self._sent_disable: tuple[int, int] | None = None
        self._sent_rails: tuple[int, int, int] | None = None
        self._next_usage: float | None = None
        self._battery_brownouts = self.battery.brownouts
        self._foreign_logged_at = float("-inf")
        self._jump_logged_at = float("-inf")
        self._enable_held = False  # a restarted DS's sequence: no enabling before a disabled packet
        self._beats = Grid(BEAT)

    # -- properties panels read -------------------------------------------------------
    @property
    def battery_volts(self) -> float:
        return self.battery.volts

    @property
    def brownout(self) -> bool:
        return self.battery.brownout

    @property
    def outputs_enabled(self) -> bool:
        """Whether the robot's motor outputs are live (enabled, code running, no brownout)."""
        return self.enabled and not self.battery.brownout

    @property
    def ds_connected(self) -> bool:
        return self._ds_alive

    @property
    def request_date(self) -> bool:
        return not (self.got_date and self.got_timezone)

    @property
    def joysticks(self) -> tuple[JoystickState, ...]:
        return self._joystick_view()

    @property
    def outputs(self) -> list[int]:
        return list(self.program_out.outputs)

    @property
    def rumble(self) -> list[tuple[float, float]]:
        """(left, right) per slot, 0.0..1.0."""
        return list(zip(self.program_out.left_rumble, self.program_out.right_rumble))

    @property
    def lcd(self) -> tuple[str, ...] | None:
        """2010: the six LCD lines the program wrote (None until it wrote one)."""
        return self.program_out.lcd

    @property
    def code_alive(self) -> bool:
        """Whether robot code runs (stuck included: it is there, it has not returned)."""
        return self.code_state in CODE_ALIVE

    @property
    def tcp_clients(self) -> int:
        return len(self._clients)

    @property
    def trace_mode(self) -> str | None:
        """The mode the program last ran in: "disabled", "teleop", "auto", "test" or None."""
        return self._trace_mode

    @property
    def pdp_amps(self) -> tuple[float, ...]:
        return tuple(self._pdp_amps())

    # -- the shell's events -----------------------------------------------------------
    #: The shell passes each datagram's arrival time and whether a newer one from the same
    #: sender waits behind it (``arrived``, ``superseded``: roles/runtime/shell.py).
    takes_arrival = True

    def datagram(self, channel: str, data: bytes, source: Address, now: float, arrived: float | None = None,
                 superseded: bool = False) -> list[Action]:
        self._init(now)
        # What fell due before this packet (a code start, a beat) must not enable the robot on
        # the word of the packet before it: this one, which may say disabled, decides first.
        self._arriving = True
        try:
            self._advance(now)
        finally:
            self._arriving = False
        out = self._take_pending()
        if self.code_state == CODE_REBOOTING:
            return out  # the roboRIO is off: nothing hears the packet
        link = self.stats[LINK_DS_TO_RIO]
        if channel not in CHANNELS:
            link.bad(f"datagram on unknown channel {channel!r}", now)
            return out
        try:
            packet = self._wire.decode_control(bytes(data))
        except ProtocolError as exc:
            link.bad(exc, now)
            return out
        source = (str(source[0]), int(source[1]))
        if (self.single_ds and self.ds_address is not None and source != self.ds_address
                and self._ds_alive):
            self.faults.foreign_packets += 1
            link.foreign_packets += 1
            if now - self._foreign_logged_at >= 1.0:
                self._foreign_logged_at = now
                self.events.add(now, f"ignoring a second DS at {source[0]}:{source[1]} "
                                     f"(following {self.ds_address[0]}:{self.ds_address[1]})")
            return out
        port = self.reply_port if self.reply_port is not None else source[1]
        arrived = now if arrived is None else min(arrived, now)
        refused = self._refusal(packet.sequence, source, now, arrived, superseded)
        if refused is not None and refused != "resync":
            # Not the newest packet (a delayed, reordered, duplicated or superseded one), taken
            # up late (the robot's process stalled), or a sequence far ahead. It changes
            # nothing, not even the watchdog, but an e-stop in it latches, and it is answered
            # as a real roboRIO answers every packet: its sequence echoed with the state the
            # robot applies now, so the DS's trip time stays true.
            if packet.estop and (source == self.ds_address or not self._ds_alive):
                self._latch_estop(now)
            if refused == "jump":
                self.faults.sequence_jumps += 1
                self._log_jump(packet.sequence, now)
            else:
                self.faults.stale_packets += 1
            link.stale_packets += 1
            reply = self._wire.encode_status(self._status(packet.sequence, now))
            out.append(Datagram(channel, reply, (source[0], port), self._wire.status_kind))
            self.stats[LINK_RIO_TO_DS].sent(len(reply))
            return out
        link.received(len(data), now)
        link.connected = True
        if source != self.ds_address:
            self.events.add(now, f"following the DS at {source[0]}:{source[1]}")
            self.ds_address = source
        elif not self._ds_alive:
            self.events.add(now, "DS packets arriving again")
        self._ds_alive = True
        self._last_packet_at = arrived
        self.watchdog_tripped = False
        self.last_sequence = packet.sequence
        if refused == "resync" and not self._enable_held:
            # the DS restarted (or its packets were lost and a far older or newer one came):
            # followed again, but a packet from before the gap must not enable the robot
            self._enable_held = True
            self.events.add(now, f"DS sequence restarted at {packet.sequence}: disabled until it sends "
                                 "a disabled packet")
        if not packet.enabled:
            self._enable_held = False
        inputs = self._wire.ds_inputs()
        if inputs is not None:  # 2010: the DS's digital and analog inputs, for the program
            self._ds_inputs = inputs

        # requests act on the bit's rising edge: a DS may repeat the bit for a few packets
        reboot = packet.reboot_roborio and not self._reboot_bit
        restart = packet.restart_code and not self._restart_bit
        self._reboot_bit, self._restart_bit = packet.reboot_roborio, packet.restart_code
        if reboot:
            out.extend(self._begin_reboot(now, "the DS asked for a reboot"))
            return out
        if restart:
            self._begin_restart(now, "the DS asked to restart the robot code")

        self.ds_estop = packet.estop
        if packet.estop:
            self._latch_estop(now)
        self.ds_enabled = packet.enabled
        self.mode = packet.mode
        self.fms_attached = packet.fms_attached
        self.station = packet.station
        joysticks = []
        for tag in packet.tags:
            kind = type(tag)
            if kind is Joystick:
                if len(joysticks) < SLOTS:  # a 7th joystick tag overwrites nothing
                    joysticks.append(tag)
            elif kind is Date:
                self.got_date = True
                self.ds_date = tag.to_datetime()
            elif kind is Timezone:
                self.got_timezone = True
                self.ds_timezone = tag.name
            elif kind is Countdown:
                self.countdown = tag.seconds if math.isfinite(tag.seconds) else None
            elif kind is MalformedTag:
                # The header above is applied all the same, as WPILib's robot side does; only
                # this tag's data is dropped, and a malformed joystick keeps its slot, neutral.
                self.faults.malformed_tags += 1
                link.last_error = f"malformed tag dropped, header applied: {tag.reason}"
                if tag.tag_id == ds_to_rio.TAG_JOYSTICK and len(joysticks) < SLOTS:
                    joysticks.append(EMPTY_JOYSTICK)
        joysticks = tuple(joysticks)
        if joysticks != self._joystick_tags:
            self._joystick_tags = joysticks
            self._joystick_states = None
        self._apply(now)
        self._update_battery(now)

        reply = self._wire.encode_status(self._status(packet.sequence, now))
        out.append(Datagram(channel, reply, (source[0], port), self._wire.status_kind))
        self.stats[LINK_RIO_TO_DS].sent(len(reply))
        return out

    def _refusal(self, sequence: int, source: Address, now: float, arrived: float,
                 superseded: bool) -> str | None:
        """Why a control packet is not obeyed: ``"stale"`` (superseded, taken up more than
        ``watchdog`` after it arrived, or not newer than the last one obeyed from the same
        sender while that one is younger than ``watchdog``), ``"jump"`` (more than
        MAX_SEQUENCE_JUMP ahead of it), or None: obey it; ``"resync"``: obey it, but its
        sequence does not follow the last one, which is older than ``watchdog`` (a restarted
        DS): the robot stays disabled until the DS sends a disabled packet. Newer means
        ``(seq - last) mod 65536`` in 1..32767 (serial-number arithmetic)."""
        if superseded or now - arrived > self.watchdog:
            return "stale"
        if self.last_sequence is None or self._last_packet_at is None or source != self.ds_address:
            return None
        step = (sequence - self.last_sequence) & 0xFFFF
        gap = arrived - self._last_packet_at
        # as far ahead as a DS can get in that time (50 Hz; open-ds steps by 2), and a second more
        follows = 0 < step <= min(0x7FFF, MAX_SEQUENCE_JUMP + int(2 * max(gap, 0.0) / BEAT))
        if gap >= self.watchdog:
            return None if follows else "resync"  # the watchdog has tripped: taken again
        if not 0 < step < 0x8000:
            return "stale"
        return None if follows else "jump"

    def _log_jump(self, sequence: int, now: float) -> None:
        if now - self._jump_logged_at >= 1.0:
            self._jump_logged_at = now
            self.events.add(now, f"ignoring a control packet whose sequence jumped from {self.last_sequence} "
                                 f"to {sequence} (more than {MAX_SEQUENCE_JUMP} ahead)")

    def _latch_estop(self, now: float) -> None:
        if not self.estopped:
            self.estopped = True
            self.events.add(now, "E-STOP: latched until the code restarts or the roboRIO reboots")
            self._apply(now)

    def stream_opened(self, conn: Hashable, peer: Address | None, now: float) -> list[Action]:
        self._init(now)
        self._advance(now)
        out = self._take_pending()
        if self.code_state == CODE_REBOOTING:
            out.append(Close(conn, "the roboRIO is rebooting"))
            return out
        if conn in self._clients:
            return out
        host = str(peer[0]) if peer else None
        # One host (a stray program, a scan) never holds more than half the slots; the host of
        # the DS followed on UDP is not held to that.
        per_host = max(1, self.max_clients // 2)
        limited = host is not None and host != (self.ds_address[0] if self._ds_alive and self.ds_address else None)

        def from_host() -> list[Hashable]:
            return [c for c, life in self._client_life.items() if life[2] == host and c in self._clients]

        if limited and len(from_host()) >= per_host:
            out.extend(self._evict_for_newcomer(now, host, from_host()))
        if len(self._clients) >= self.max_clients:
            out.extend(self._evict_for_newcomer(now, host))
        over = limited and len(from_host()) >= per_host
        if len(self._clients) >= self.max_clients or over:
            self.faults.refused_clients += 1
            limit = f"{per_host} already connected from {host}" if over else f"{self.max_clients} already connected"
            held = self._tcp_log.due("refused", now)
            if held is not None:
                self.events.add(now, f"TCP: refused a client from {host}, {limit}{Throttle.suffix(held)}")
            out.append(Close(conn, f"too many clients ({limit})"))
            return out
        self._clients[conn] = FrameDecoder(ds_to_rio.TCP, MAX_DS_FRAME)
        self._client_life[conn] = (now, None, str(peer[0]) if peer else None)
        self.stats[LINK_TCP].connected = True
        where = f" from {peer[0]}:{peer[1]}" if peer else ""
        self.events.add(now, f"TCP: DS connected{where}")
        frames = [
            VersionInfo(DeviceType.SOFTWARE, 0, 0, "roboRIO Image", self.image_version).encode(),
            VersionInfo(DeviceType.SOFTWARE, 0, 0, "FRC_Lib_Version", self.lib_version).encode(),
            rio_to_ds.END_OF_VERSION_LIST.encode(),
            DisableFaults(*self._disable_counts()).encode(),
            RailFaults(*self._rail_counts()).encode(),
            *self._backlog,
        ]
        for frame in frames:
            out.append(self._tcp_send(conn, frame))
        if self._next_usage is None:
            self._next_usage = now + self.usage_interval
        return out

    def stream_data(self, conn: Hashable, data: bytes, now: float) -> list[Action]:
        self._init(now)
        self._advance(now)
        out = self._take_pending()
        decoder = self._clients.get(conn)
        if decoder is None:
            return out  # a connection we refused or already closed
        messages, error = decode_frames(decoder, bytes(data), self._wire.decode_tcp, self.stats[LINK_TCP], now,
                                        stop_on_bad=True)
        for message in messages:
            life = self._client_life.get(conn)
            if life is not None:  # a valid frame (a keep-alive too): a sign of life
                self._client_life[conn] = (life[0], now, life[2])
            self._tcp_message(message, now)
        if error is not None:  # counted: the connection goes
            out.append(self._drop_client(conn, error, now))
        return out

    def stream_closed(self, conn: Hashable, reason: str, now: float) -> list[Action]:
        self._init(now)
        self._client_life.pop(conn, None)
        if self._clients.pop(conn, None) is not None:
            self.events.add(now, f"TCP: DS disconnected ({reason or 'closed'})")
        self.stats[LINK_TCP].connected = bool(self._clients)
        self._advance(now)
        return self._take_pending()

    def poll(self, now: float) -> list[Action]:
        self._init(now)
        self._advance(now)
        return self._take_pending()

    def next_deadline(self) -> float | None:
        if self._booted_at is None:
            return 0.0  # not started yet: poll at once
        times = []
        if self._wake_at is not None:
            times.append(self._wake_at)
        if self.code_state == CODE_REBOOTING:
            times.append(self._reboot_until)
            return min(times)
        if self.code_state == CODE_STARTING and self._code_ready_at is not None:
            times.append(self._code_ready_at)
        if self._last_packet_at is not None:
            if not self.watchdog_tripped:
                times.append(self._last_packet_at + self.watchdog)
            if self._ds_alive:
                times.append(self._last_packet_at + self.ds_timeout)
        times.append(self._beats.next)
        busy = self._host.busy_since if self._host is not None else None
        if busy is not None and self._stuck_since is None:
            times.append(busy + STUCK_AFTER)
        if self._clients and self._next_usage is not None:
            times.append(self._next_usage)
        return min(times)

    def shutdown(self) -> None:
        """The field stops: a robot program's process goes with it."""
        self._stop_host()

    # -- user commands ----------------------------------------------------------------
    def set_battery(self, volts: float | None) -> None:
        """Force the battery reading to ``volts`` (fault injection); ``None`` releases it."""
        try:
            self.battery.force(volts)
        except ValueError as exc:
            raise CommandError(str(exc)) from None

    def set_battery_rest(self, volts: float) -> None:
        """Swap in a battery resting at ``volts``."""
        try:
            self.battery.set_voltage(volts)
        except ValueError as exc:
            raise CommandError(str(exc)) from None

    def restart_code(self, now: float) -> None:
        self._init(now)
        if self.code_state == CODE_REBOOTING:
            raise CommandError("the roboRIO is rebooting")
        self._begin_restart(now, "restart asked from the roboRIO panel")
        self._wake(now)

    def reboot(self, now: float) -> None:
        self._init(now)
        if self.code_state == CODE_REBOOTING:
            raise CommandError("the roboRIO is already rebooting")
        self._pending.extend(self._begin_reboot(now, "reboot asked from the roboRIO panel"))
        self._wake(now)

    def load_program(self, path: str | os.PathLike, now: float) -> None:
        """Run the program in ``path`` from now on (the code restarts to load it)."""
        self._init(now)
        if self.code_state == CODE_REBOOTING:
            raise CommandError("the roboRIO is rebooting")
        try:  # isolated: what can be checked without running it (its top level runs apart)
            check_program(path) if self.isolate else load_program(path, console=self.robot.print)
        except ProgramError as exc:
            raise CommandError(str(exc)) from None
        self._program_path = os.fspath(path)
        self._program_callable = None
        self._preloaded = None
        self.program_name = os.path.basename(self._program_path)
        self._begin_restart(now, f"loading {self.program_name}")
        self._wake(now)

    def use_builtin_program(self, now: float) -> None:
        self._init(now)
        if self.code_state == CODE_REBOOTING:
            raise CommandError("the roboRIO is rebooting")
        self._program_path = None
        self._program_callable = None
        self._preloaded = None
        self.program_name = BuiltinProgram.name
        self._begin_restart(now, "switching to the built-in program")
        self._wake(now)

    def inject_rail_fault(self, rail: str, now: float) -> None:
        """Count a fault on the 6 V, 5 V or 3.3 V rail (sent in the next 0x05 frame)."""
        key = rail.strip().lower().replace(" ", "")
        if key not in RAILS:
            raise CommandError(f"unknown rail {rail!r}: one of {', '.join(RAILS)}")
        self._init(now)
        name = {"6v": "rail_6v", "5v": "rail_5v", "3.3v": "rail_3v3"}[key]
        setattr(self.faults, name, getattr(self.faults, name) + 1)
        self.events.add(now, f"{key} rail fault injected")
        self._wake(now)

    # -- time -------------------------------------------------------------------------
    def _init(self, now: float) -> None:
        if self._booted_at is not None:
            return
        self._booted_at = now
        self._now = now
        self._beats.start(now)  # the first beat is due at once
        self.events.add(now, "roboRIO up")
        self._start_code(now)

    def _wake(self, now: float) -> None:
        self._wake_at = now if self._wake_at is None else min(self._wake_at, now)

    def _take_pending(self) -> list[Action]:
        out, self._pending = self._pending, []
        self._wake_at = None
        return out

    def _advance(self, now: float) -> None:
        self._now = now
        if self.code_state == CODE_REBOOTING:
            if now < self._reboot_until:
                return
            self._finish_reboot(now)
        if self.code_state == CODE_STARTING and self._code_ready_at is not None and now >= self._code_ready_at:
            self._start_code(now)
        self._collect(now)
        self._check_stuck(now)
        if self._last_packet_at is not None:
            if not self.watchdog_tripped and now >= self._last_packet_at + self.watchdog:
                self.watchdog_tripped = True
                if self.enabled:
                    self.faults.comms += 1
                    self.events.add(now, f"watchdog: no DS packet for {self.watchdog * 1000:.0f} ms, "
                                         "robot disabled")
            if self._ds_alive and now >= self._last_packet_at + self.ds_timeout:
                self._ds_alive = False
                self.stats[LINK_DS_TO_RIO].connected = False
                self.events.add(now, f"DS lost: no packet for {self.ds_timeout:g} s")
        self._apply(now)
        skipped = self._beats.take(now)
        if skipped is not None:
            self.faults.missed_beats += skipped
            self._beat(now)
        self._tcp_housekeeping(now)

    def _beat(self, now: float) -> None:
        self.beats += 1
        self._beat_messages = 0
        self._update_battery(now)
        self._apply(now)
        self._report_overruns(now)
        host = self._host
        if host is None or not self.code_alive or not host.idle:
            return  # no code, or the last call has not returned (an overrun under way)
        state = self._control_state(now)
        if host.offer(state, self._ds_inputs, now):
            self._call_state = state
            self._collect(now)  # an inline program has already run

    # -- what the program did --------------------------------------------------------------
    def _collect(self, now: float) -> None:
        host = self._host
        if host is None:
            return
        for event in host.collect(now):
            kind = type(event)
            if kind is Message:
                self._emit(event.kind, event.text, event.code, event.location, event.call_stack)
            elif kind is Result:
                self._result(event, now)
            elif kind is Loaded:
                self.code_state = CODE_RUNNING
                self._stuck_since = None
                self.events.add(now, f"robot code running ({self.program_name})")
                self._apply(now)
            elif kind is LoadFailed:
                self._stop_code(now, f"robot code failed to start: {event.text}",
                                f"Robot code failed to start: {event.text}")
            elif kind is Ended:
                self._stop_code(now, f"robot code ended: {event.text}",
                                f"Robot code ended: {event.text}; restart the code to run it again")
            if self._host is not host:
                return  # the code stopped: what it sent after that is moot

    def _result(self, result: Result, now: float) -> None:
        state, self._call_state = self._call_state, None
        self.program_out = result.outputs
        for problem in result.problems:
            what = problem.split(" = ", 1)[0]
            if what not in self._problems_reported:  # once per output and code start
                self._problems_reported.add(what)
                self.faults.output_problems += 1
                self._emit("warning", f"robot program output not sent as written: {problem}", bounded=False)
        if result.took > BEAT:
            self.faults.program_overruns += 1
            self._overruns += 1
            self._longest_ms = max(self._longest_ms, result.took * 1000.0)
        self.faults.console_dropped += result.dropped
        if self._stuck_since is not None:
            text = f"robot program returned after {now - self._stuck_since:.1f} s stuck"
            self._stuck_since = None
            self.code_state = CODE_RUNNING if self.code_state == CODE_STUCK else self.code_state
            self.events.add(now, text)
            self._emit("warning", text, bounded=False)
        if result.error is not None:
            self._program_failed(result.error, now)
        else:
            self._consecutive_failures = 0
        if self.code_state == CODE_RUNNING and state is not None:  # what WPILib's HAL_ObserveUserProgram* report
            self._trace_mode = self._mode_bits_label(state)

    def _check_stuck(self, now: float) -> None:
        busy = self._host.busy_since if self._host is not None else None
        if busy is None or self._stuck_since is not None or now - busy < STUCK_AFTER:
            return
        self._stuck_since = busy
        if self.code_state == CODE_RUNNING:
            self.code_state = CODE_STUCK
            text = (f"robot program stuck: robot_periodic has not returned for {now - busy:.1f} s "
                    "(the robot still answers its DS; restart the code to stop it)")
        else:
            text = (f"robot program stuck: its file's top level has not finished for {now - busy:.1f} s "
                    "(restart the code to stop it)")
        self.events.add(now, text)
        self._emit("warning", text, bounded=False)

    def _report_overruns(self, now: float) -> None:
        """At most once a second, as WPILib reports loop overruns (its "Loop time of 0.02s overrun")."""
        if not self._overruns or now - self._overrun_reported_at < OVERRUN_REPORT:
            return
        calls = "call" if self._overruns == 1 else "calls"
        self._emit("warning", f"Loop time of {BEAT:g}s overrun: {self._overruns} {calls} of robot_periodic "
                              f"took longer (the longest {self._longest_ms:.0f} ms)", bounded=False)
        self._overrun_reported_at = now
        self._overruns = 0
        self._longest_ms = 0.0

    @staticmethod
    def _mode_bits_label(state: ControlState) -> str:
        if not state.enabled or state.mode not in ("teleop", "auto", "test"):
            return "disabled"
        return state.mode

    def _apply(self, now: float) -> None:
        enabled = (self.ds_enabled and not self.estopped and self.code_state in CODE_ALIVE
                   and not self.watchdog_tripped and not self._enable_held
                   and (self.enabled or not self._arriving) and self._last_packet_at is not None)
        if enabled != self.enabled:
            self.enabled = enabled
            self.events.add(now, f"robot enabled in {_MODE_LABEL[self.mode]}" if enabled else "robot disabled")

    def _update_battery(self, now: float) -> None:
        self.battery.update(now, sum(self._pdp_amps()) + 2.5)  # roboRIO, radio and friends: ~2.5 A
        if self.battery.brownouts != self._battery_brownouts:
            self.faults.rail_12v += self.battery.brownouts - self._battery_brownouts
            self._battery_brownouts = self.battery.brownouts
            self.events.add(now, f"BROWNOUT at {self.battery.volts:.2f} V: outputs disabled")

    # -- code states ------------------------------------------------------------------
    def _make_program(self) -> Program:
        if self._preloaded is not None:
            program, self._preloaded = self._preloaded, None
            return program
        if self._program_path is not None:
            return load_program(self._program_path, console=self.robot.print)
        if isinstance(self._program_callable, type):
            return self._program_callable()  # a class: a fresh instance each time the code starts
        if self._program_callable is not None:
            return self._program_callable
        return BuiltinProgram()

    def _start_code(self, now: float) -> None:
        self._stop_host()
        self._trace_mode = None
        self._consecutive_failures = 0
        self._code_started_at = now
        self._code_ready_at = None
        self._problems_reported = set()
        if self.isolate and self._program_path is not None:
            try:
                self._host = ProcessHost(self._program_path, now)
            except OSError as exc:
                self._stop_code(now, f"robot code failed to start: {exc}",
                                f"Robot code failed to start: cannot start its process: {exc.strerror or exc}")
                return
            self.code_state = CODE_STARTING  # until its top level has run (Loaded)
            self.events.add(now, f"robot code loading ({self.program_name}) in a process of its own")
            return
        self._host = InlineHost(self._make_program, self.robot)
        self._collect(now)  # Loaded or LoadFailed, at once

    def _stop_host(self) -> None:
        """The program stops where it is (a process is killed); its outputs go off."""
        if self._host is not None:
            self._host.stop()
            self._host = None
        self.robot.reset()
        self.program_out = NO_OUTPUTS
        self._call_state = None
        self._stuck_since = None

    def _stop_code(self, now: float, event: str, console: str) -> None:
        self._stop_host()
        self.code_state = CODE_NONE
        self._trace_mode = None
        self.events.add(now, event)
        self._emit("error", console, code=1, bounded=False)
        self._apply(now)

    def _begin_restart(self, now: float, why: str) -> None:
        if self.estopped:
            self.events.add(now, "e-stop cleared by the code restart")
        self.estopped = False
        self.code_state = CODE_STARTING
        self._code_ready_at = now + self.restart_time
        self._stop_host()
        self._trace_mode = None
        self.events.add(now, f"robot code restarting: {why}")
        self._apply(now)

    def _begin_reboot(self, now: float, why: str) -> list[Action]:
        self.events.add(now, f"roboRIO rebooting: {why}")
        closes = [Close(conn, "roboRIO rebooting") for conn in self._clients]
        self._clients.clear()
        self._client_life.clear()
        self.stats[LINK_TCP].connected = False
        self.stats[LINK_DS_TO_RIO].connected = False
        self.code_state = CODE_REBOOTING
        self._reboot_until = now + self.reboot_time
        self._stop_host()
        self._trace_mode = None
        self.enabled = False
        return closes

    def _finish_reboot(self, now: float) -> None:
        until = self._reboot_until
        self._fresh_boot_state()
        self.faults = RioFaults()
        self._booted_at = now
        self._beats.start(now)
        self.events.add(now, f"roboRIO back after reboot ({now - until + self.reboot_time:.1f} s)")
        self.code_state = CODE_STARTING
        self._code_ready_at = now + self.restart_time

    def _program_failed(self, error: tuple[str, str, str], now: float) -> None:
        self.faults.program_errors += 1
        self._consecutive_failures += 1
        details, location, stack = error
        self._emit("error", details, code=1, location=location, call_stack=stack, bounded=False)
        if self._consecutive_failures >= self.max_failures:
            text = (f"Robot code stopped after {self._consecutive_failures} consecutive errors; "
                    "restart the code to run it again")
            self._stop_code(now, text, text)

    # -- the program's view ------------------------------------------------------------
    def _joystick_view(self) -> tuple[JoystickState, ...]:
        """The joysticks as the program reads them; rebuilt only when a packet or a
        descriptor changed them."""
        if self._joystick_states is None:
            names = [d.name if d else "" for d in self.descriptors]
            self._joystick_states = tuple(
                JoystickState(tuple(ds_to_rio.int8_to_axis(a) for a in j.axes), j.buttons, j.button_count,
                              tuple(j.povs), names[i])
                for i, j in enumerate(self._joystick_tags))
        return self._joystick_states

    def _control_state(self, now: float) -> ControlState:
        return ControlState(
            time=now - self._code_started_at, enabled=self.enabled, mode=_MODE_LABEL[self.mode],
            estop=self.estopped, joysticks=self._joystick_view(), ds_attached=self._ds_alive,
            fms_attached=self.fms_attached, station=self.station.label, match_info=self.match_info,
            game_data=self.game_data, countdown=self.countdown, battery=self.battery.volts,
            brownout=self.battery.brownout)

    def _pdp_amps(self) -> list[float]:
        """Sixteen PDP channel currents: 8 "drive motors" follow the joystick axes (40 A at
        full stick), the other channels draw a little while enabled; nothing when the
        outputs are off (disabled, brownout, no code)."""
        key = (self.outputs_enabled, self._joystick_tags)
        if key == self._amps_key:
            return self._amps
        amps = [0.0] * 16
        if key[0]:
            axes = [abs(a) for joy in self._joystick_view() for a in joy.axes]
            amps = [0.25] * 16
            if axes:
                for c in range(8):
                    amps[c] += 40.0 * axes[c % len(axes)]
        self._amps_key, self._amps = key, amps
        return amps

    # -- the status packet ------------------------------------------------------------
    def _status(self, sequence: int, now: float) -> StatusPacket:
        running = self.code_state in CODE_ALIVE
        trace = self._trace_mode if running else None
        tags: list = []
        out = self.program_out
        # A real roboRIO sent no output tag in 4,352 status packets with nothing set (the 2021
        # capture, PROTOCOL-NOTES): a tag per slot up to the last one with something set; an
        # idle one (01 01) only to keep a later slot's number.
        for slot in range(len(self._joystick_tags)):
            outputs = out.outputs[slot]
            left = _rumble_u16(out.left_rumble[slot])
            right = _rumble_u16(out.right_rumble[slot])
            tags.append(JoystickOutput(outputs, right, left) if outputs or left or right
                        else IDLE_JOYSTICK_OUTPUT)
        while tags and tags[-1] is IDLE_JOYSTICK_OUTPUT:
            tags.pop()
        if self.extra_tags:
            tags.extend(self._extra_tags())
        return StatusPacket(
            sequence=sequence, comm_version=0x01, estop=self.estopped, brownout=self.battery.brownout,
            code_initializing=self.code_state == CODE_STARTING, enabled=self.enabled, mode=self.mode,
            robot_code=running, is_roborio=True, user_test=trace == "test", user_auto=trace == "auto",
            user_teleop=trace == "teleop", user_disabled=trace == "disabled",
            battery=min(max(self.battery.volts, 0.0), 255.99), request_date=self.request_date,
            tags=tuple(tags))

    def _extra_tags(self) -> list:
        """Disk, CPU, RAM, PDP and CAN tags, as a real roboRIO sends (the simulator does not)."""
        amps = self._pdp_amps()
        # the numbers move a little every half second (deterministic, so tests stay exact)
        key = (self._amps_key, self.code_state, self.enabled, self.beats // 25)
        if key == self._extra_key:
            return self._extra
        busy = 1.0 if self.code_state in CODE_ALIVE else 0.0
        wobble = 2.0 * math.sin(key[3] * 1.7)
        cpu = CpuLoad(time_critical=4.0 * busy, above_normal=3.0, normal=18.0 * busy + 6.0 * self.enabled + wobble + 5.0,
                      low=1.0)
        cpu2 = CpuLoad(time_critical=1.0, above_normal=2.0, normal=9.0 * busy + 3.0, low=0.5)
        self._extra_key = key
        self._extra = [
            DiskInfo(free_bytes=412_000_000, block=0),
            CpuInfo((cpu, cpu2)),
            RamInfo(block=256_000_000, free_bytes=int(118_000_000 - 4_000_000 * busy)),
            PdpLog(currents=tuple(min(rio_to_ds.MAX_PDP_RAW, round(a / rio_to_ds.PDP_AMPS_PER_UNIT))
                                  for a in amps)),
            CanMetrics(utilization=(12.0 + 0.02 * sum(amps)) if busy else 3.0),
        ]
        return self._extra

    # -- TCP --------------------------------------------------------------------------
    def _tcp_send(self, conn: Hashable, frame: bytes) -> StreamSend:
        self.stats[LINK_TCP].sent(len(frame))
        return StreamSend(conn, frame, self._wire.tcp_kind)

    def _broadcast(self, frame: bytes) -> None:
        if self._clients:
            for conn in self._clients:
                self._pending.append(self._tcp_send(conn, frame))
            self._wake(self._now)

    def _evict_for_newcomer(self, now: float, newcomer: str | None = None,
                            among: list[Hashable] | None = None) -> list[Action]:
        """Make room for a new client from host ``newcomer`` (among ``among``, else every
        client): close the oldest client that never sent a valid frame; if none, the one
        silent the longest, if that is more than ``CLIENT_IDLE_EVICT`` seconds and it is not
        on the host of the DS followed on UDP. The DS's own host is always served: for it,
        else the longest-silent client on another host. Nothing (the newcomer is refused) when
        every client is healthy and, for the DS's host, on that host too."""
        pool = {conn: self._client_life[conn] for conn in (among if among is not None else self._client_life)
                if conn in self._clients and conn in self._client_life}
        ds_host = self.ds_address[0] if self._ds_alive and self.ds_address else None
        never = [(opened, conn) for conn, (opened, valid, _) in pool.items() if valid is None]
        if never:
            conn = min(never, key=lambda item: item[0])[1]
            why = "it never sent a valid frame"
        elif newcomer is not None and newcomer == ds_host:
            elsewhere = [(valid, conn) for conn, (_, valid, host) in pool.items() if host != ds_host]
            if not elsewhere:
                return []  # every slot is the DS's own host's, all healthy (the ephemeral plan's 127.0.0.1)
            conn = min(elsewhere, key=lambda item: item[0])[1]
            why = f"the DS at {ds_host} is always served"
        else:
            idle = [(valid, conn) for conn, (_, valid, host) in pool.items()
                    if valid is not None and now - valid > CLIENT_IDLE_EVICT and host != ds_host]
            if not idle:
                return []
            conn = min(idle, key=lambda item: item[0])[1]
            why = f"no valid frame for more than {CLIENT_IDLE_EVICT:g} s"
        host = self._client_life[conn][2]
        self._clients.pop(conn, None)
        self._client_life.pop(conn, None)
        self.faults.evicted_clients += 1
        held = self._tcp_log.due("evicted", now)
        if held is not None:
            self.events.add(now, f"TCP: no room for a client from {newcomer}: closed one from {host} ({why})"
                                 f"{Throttle.suffix(held)}")
        return [Close(conn, f"evicted to make room for a new client: {why}")]

    def _drop_client(self, conn: Hashable, exc: Exception, now: float) -> Close:
        """A client that sent a bad frame (counted where it was read) is closed."""
        self._clients.pop(conn, None)
        self._client_life.pop(conn, None)
        self.stats[LINK_TCP].connected = bool(self._clients)
        self.events.add(now, f"TCP: closed a DS connection that sent a bad frame: {exc}")
        return Close(conn, f"bad frame: {exc}")

    def _tcp_message(self, message: Any, now: float) -> None:
        kind = type(message)
        if kind is ds_to_rio.JoystickDescriptor:
            if 0 <= message.index < SLOTS:
                self.descriptors[message.index] = message
                self._joystick_states = None
            else:
                self.stats[LINK_TCP].bad(f"joystick descriptor for slot {message.index}, only 0-{SLOTS - 1}",
                                         now)
        elif kind is ds_to_rio.MatchInfo:
            if message != self.match_info:
                self.events.add(now, f"match info: {message.competition or '(no event)'} "
                                     f"{getattr(message.match_type, 'name', message.match_type)} "
                                     f"#{message.match_number}")
            self.match_info = message
        elif kind is ds_to_rio.GameData:
            text = message.text[:MAX_TEXT]
            if text != self.game_data:
                self.events.add(now, f"game data: {text!r}")
            self.game_data = text
        # keep-alives and frames no document names are fine: nothing to do

    def _disable_counts(self) -> tuple[int, int]:
        return min(self.faults.comms, 0xFFFF), min(self.faults.rail_12v, 0xFFFF)

    def _rail_counts(self) -> tuple[int, int, int]:
        f = self.faults
        return min(f.rail_6v, 0xFFFF), min(f.rail_5v, 0xFFFF), min(f.rail_3v3, 0xFFFF)

    def _tcp_housekeeping(self, now: float) -> None:
        disable, rails = self._disable_counts(), self._rail_counts()
        if disable != self._sent_disable:
            if self._sent_disable is not None:
                self._broadcast(DisableFaults(*disable).encode())
            self._sent_disable = disable
        if rails != self._sent_rails:
            if self._sent_rails is not None:
                self._broadcast(RailFaults(*rails).encode())
            self._sent_rails = rails
        if self._clients and self._next_usage is not None and now >= self._next_usage:
            self._broadcast(UsageReport(min(max(self.team, 0), 0xFFFF), 0, b"").encode())
            periods = math.floor((now - self._next_usage) / self.usage_interval) + 1
            self._next_usage += periods * self.usage_interval
        elif not self._clients:
            self._next_usage = None

    def _emit(self, kind: str, text: str, code: int = 0, location: str = "", call_stack: str = "",
              bounded: bool = True) -> None:
        """A console line or a diagnostic: kept in ``console``, sent to every TCP client,
        stdout and errors sharing one sequence counter."""
        now = self._now
        self._beat_messages += bounded
        if bounded and self._beat_messages > MAX_MESSAGES_PER_BEAT:
            self.faults.console_dropped += 1
            if self._beat_messages != MAX_MESSAGES_PER_BEAT + 1:
                return
            kind, text, code, location, call_stack = (
                "warning", f"more than {MAX_MESSAGES_PER_BEAT} console messages in one 20 ms loop: "
                           "the rest of this loop's messages are dropped", 0, "", "")
        seq = self._seq
        self._seq = (seq + 1) & 0xFFFF
        text = _safe_text(text)
        stamp = max(0.0, now - (self._booted_at or 0.0))
        if kind == "stdout":
            frame = StdoutMessage(stamp, seq, text).encode()
        else:
            frame = ErrorMessage(stamp, seq, 1, max(-0x80000000, min(0x7FFFFFFF, int(code))), kind == "error",
                                 False, text, _safe_text(location), _safe_text(call_stack)).encode()
        self.console.append(ConsoleLine(now, kind, text.rstrip("\n"), seq))
        self._backlog.append(frame)
        self._broadcast(frame)
        sends = self._wire.console_actions(kind, text)  # 2010: NetConsole datagrams
        if sends:
            self._pending.extend(sends)
            self._wake(now)

    # -- plain view -------------------------------------------------------------------
    def __getstate__(self) -> dict[str, Any]:
        # A robot program loaded from a file lives in a module made on the fly: it cannot be
        # pickled (nor would a copy run it). A copy (the app's mirror of a wire process,
        # roles/runtime/wireproc.py) has the program's name and state, not the program.
        state = dict(self.__dict__)
        state["_host"] = None  # a process, a socket: the copy has the program's state, not the program
        if state.get("_program_path") is not None:
            state["_preloaded"] = None
        return state

    def view(self, now: float | None = None) -> RioView:
        return RioView.of(self, self._now if now is None else now)

    def snapshot(self) -> dict[str, Any]:
        """Everything a panel or ``--json`` status line shows, as plain JSON-able values."""
        return self.view().snapshot()


def _rumble_u16(value: float) -> int:
    return max(0, min(0xFFFF, round(value * 0xFFFF)))


def _safe_text(text: str, limit: int = MAX_TEXT) -> str:
    """Text that encodes (lone surrogates replaced) and fits a frame."""
    text = str(text)[:limit]
    try:
        text.encode("utf-8", "surrogateescape")
    except UnicodeEncodeError:
        text = text.encode("utf-8", "replace").decode("utf-8")
    return text
