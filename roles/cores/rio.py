"""The fake roboRIO: a sans-IO core that answers a Driver Station like a real robot.

Channels and connections (the shell owns the sockets, see roles/cores/core.py):

* UDP ``"ds"`` (the robot address, port 1110) and ``"ds-fms"`` (port 1115, used while the
  DS is attached to an FMS): every DS control packet is answered at once, from the channel
  it arrived on, to the DS's address on port 1150 (``reply_port``; ``None`` answers the
  packet's source port, for the ephemeral address plan);
* TCP 1740: each DS connection is whatever hashable ``conn`` the shell passes to
  ``stream_opened``; one :class:`~protocol.framing.FrameDecoder` per connection.

Behaviour, as a real roboRIO (docs/protocol.md#rio-behaviour): the status byte
echoes the DS's e-stop/enabled/mode bits as the robot applies them; no DS packet for
``watchdog`` seconds disables (a comms disable fault); an e-stop latches until the code
restarts or the roboRIO reboots; restart code shows "code starting" for a moment; a reboot
goes silent for a few seconds and comes back fresh; only one DS is followed at a time, known
by its host (the address it is answered at), whatever port it sends from: a DS that re-creates
its socket is the same DS; another host is a second DS, ignored while the first is heard.

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
due by time and ``next_deadline()`` says when to call it next. Every command takes ``now``.

The :class:`Rio` is a composition that routes the shell's events and the user's commands to
its parts, each a module of its own:

* :class:`~roles.cores.rio_control.ControlLink`: the DS followed, the packet obeyed, the
  watchdog, the e-stop latch and the one rule for enabling (the safety heart);
* :class:`~roles.cores.rio_inputs.DsInputs`: joysticks, date, countdown, match info and game
  data, as the robot program reads them;
* :class:`~roles.cores.rio_program.ProgramRunner`: the program, its code state and its calls
  (asked of the runtime's host as typed requests; what the program did comes back as input);
* :class:`~roles.cores.rio_tcp.TcpClients`: the DS's TCP connections and the console;
* :class:`~roles.cores.rio_telemetry.Telemetry`: battery, brownouts, PDP, CPU/RAM/disk/CAN.

The parts share the Rio's event log, fault counters and link counters; none reaches into
another. Each public name of the Rio (``rio.enabled``, ``rio.code_state``...) answers from
the part that keeps it.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, fields, replace
from typing import TYPE_CHECKING, Any, Callable, Hashable, Sequence

from protocol import ds_to_rio
from protocol.ds_to_rio import ControlPacket
from protocol.errors import ProtocolError
from protocol.rio_to_ds import IDLE_JOYSTICK_OUTPUT, JoystickOutput, StatusPacket

from .addresses import DS_UDP
from .battery import Battery
from .commands import Command, SetBattery
from .core import Action, Address, Close, CommandError, Datagram, Events, Grid, LinkStats
from .rio_control import FOREIGN, MAX_SEQUENCE_JUMP, STALE, ControlLink  # noqa: F401 - re-exported
from .rio_inputs import DsInputs
from .rio_program import (BEAT, CODE_ALIVE, CODE_NONE, CODE_REBOOTING, CODE_RUNNING,  # noqa: F401 - re-exported
                          CODE_STARTING, CODE_STUCK, ProgramEvent, ProgramHost, ProgramRunner, ProgramSource)
from .rio_tcp import TcpClients
from .rio_telemetry import Telemetry
from .views import (MODE_LABEL, BatteryView, ConsoleLine, EventsView, ProgramOutView, RioJoystickView,  # noqa: F401 - re-exported
                    RioFaultsView, RioView)
from .robot_program import ControlState, Program, ProgramError

if TYPE_CHECKING:
    from protocol.rio_to_ds import StatusTag

    from .legacy_rio import LegacyRioWire

CHANNEL_DS = "ds"
CHANNEL_DS_FMS = "ds-fms"
CHANNELS = (CHANNEL_DS, CHANNEL_DS_FMS)
LINK_DS_TO_RIO = "ds->rio"
LINK_RIO_TO_DS = "rio->ds"
LINK_TCP = "rio-tcp"

IMAGE_VERSION = "FRC_roboRIO_2025_v2.0"
LIB_VERSION = "fieldbox fake roboRIO"
RAILS = {"6v": "rail_6v", "5v": "rail_5v", "3.3v": "rail_3v3"}  # a rail's name -> its fault counter


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


def wire_for(name: str) -> RioWire | LegacyRioWire:
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

    def clear(self) -> None:
        """A reboot: every counter back to 0 (in place: the Rio's parts count into this one)."""
        for f in fields(self):
            setattr(self, f.name, f.default)

    def view(self) -> RioFaultsView:
        # vars(), not dataclasses.asdict: asdict deep-copies each counter, and made half the
        # cost of a field's views (a view is made every 20 ms: docs/figures.md)
        return RioFaultsView(**vars(self))


@dataclass(frozen=True)
class RioConfig:
    """How a fake roboRIO is set up (everything fixed at its start; the settings a panel may
    change later live on its parts)."""

    team: int = 0
    #: A program file's path, a callable ``robot_periodic(state, robot)`` (a class: made afresh
    #: at each code start) or None for the built-in program.
    program: Program | type[Any] | str | os.PathLike[str] | None = None
    #: Run a program file in a process of its own (every real-socket field); off on a fake
    #: clock, where the file runs in the wire's thread, deterministically.
    isolate: bool = False
    reply_port: int | None = DS_UDP  # None: answer the packet's source port (the ephemeral plan)
    watchdog: float = 0.100
    restart_time: float = 1.0
    reboot_time: float = 3.0
    single_ds: bool = True
    ds_timeout: float = 1.0
    extra_tags: bool = True
    battery: Battery | None = None  # None: a fresh one
    max_clients: int = 8
    usage_interval: float = 5.0
    max_failures: int = 5
    console_size: int = 500
    backlog: int = 50
    wire: str = "2015"
    image_version: str = IMAGE_VERSION
    lib_version: str = LIB_VERSION


class Rio:
    """The fake roboRIO core. See the module docstring for channels and behaviour."""

    def __init__(self, config: RioConfig, host: ProgramHost, *, now: float | None = None) -> None:
        """A roboRIO set up as ``config`` says, its program run by ``host`` (the runtime's
        roles.runtime.program_host.CodeHost); ``now``: boot at once (else at the first event).
        Raises ProgramError if the program cannot run."""
        self.config = config
        self.team = config.team
        self.reboot_time = config.reboot_time
        #: 2010: where NetConsole text goes (None: the address the DS's packets come from, port 6666)
        self.netconsole_address: Address | None = None
        self.events = Events()
        self.stats = {name: LinkStats(name) for name in (LINK_DS_TO_RIO, LINK_RIO_TO_DS, LINK_TCP)}
        self.faults = RioFaults()
        self.beats = 0
        self._beats = Grid(BEAT)
        self._booted_at: float | None = None
        self._now = 0.0
        self._wake_at: float | None = None  # a command asks for a poll at once
        self._reboot_until: float | None = None
        self._wire = wire_for(config.wire).bind(self)
        self.control = ControlLink(watchdog=config.watchdog, ds_timeout=config.ds_timeout, single_ds=config.single_ds,
                                   events=self.events, faults=self.faults, link=self.stats[LINK_DS_TO_RIO],
                                   reply_port=config.reply_port)
        self.inputs = DsInputs(self.events)
        self.tcp = TcpClients(max_clients=config.max_clients, usage_interval=config.usage_interval,
                              image_version=config.image_version, lib_version=config.lib_version,
                              console_size=config.console_size, backlog=config.backlog,
                              kind=self._wire.tcp_kind, events=self.events, faults=self.faults,
                              link=self.stats[LINK_TCP])
        self.telemetry = Telemetry(config.battery if config.battery is not None else Battery(),
                                   extra_tags=config.extra_tags, events=self.events, faults=self.faults)
        source = ProgramSource.of(config.program, config.isolate)
        self.program = ProgramRunner(source, host, restart_time=config.restart_time,
                                     max_failures=config.max_failures, events=self.events, faults=self.faults,
                                     emit=self._emit, changed=self._apply)
        self.program.check(source, 0.0 if now is None else now, keep=True)  # ProgramError
        if now is not None:
            self._init(now)

    @property
    def brownout(self) -> bool:
        return self.telemetry.battery.brownout

    @property
    def outputs_enabled(self) -> bool:
        """Whether the robot's motor outputs are live (enabled, code running, no brownout)."""
        return self.control.enabled and not self.telemetry.battery.brownout

    @property
    def outputs(self) -> list[int]:
        return list(self.program.program_out.outputs)

    @property
    def rumble(self) -> list[tuple[float, float]]:
        """(left, right) per slot, 0.0..1.0."""
        out = self.program.program_out
        return list(zip(out.left_rumble, out.right_rumble))

    @property
    def lcd(self) -> tuple[str, ...] | None:
        """2010: the six LCD lines the program wrote (None until it wrote one)."""
        return self.program.program_out.lcd

    @property
    def pdp_amps(self) -> tuple[float, ...]:
        return tuple(self._pdp_amps())

    @property
    def wire(self) -> RioWire | LegacyRioWire:
        """The wire format this roboRIO speaks (bound to it)."""
        return self._wire

    # -- the shell's events -----------------------------------------------------------
    # The shell passes each datagram's arrival time and whether a newer one from the same
    # sender waits behind it (``arrived``, ``superseded``: roles/runtime/shell.py).
    def datagram(self, channel: str, data: bytes, source: Address, now: float, arrived: float | None = None,
                 superseded: bool = False) -> list[Action]:
        self._init(now)
        with self.control.arriving():  # this packet, which may say disabled, decides first
            self._advance(now)
        out = self._take_pending()
        if self.program.code_state == CODE_REBOOTING:
            return out  # the roboRIO is off: nothing hears the packet
        link = self.stats[LINK_DS_TO_RIO]
        if channel not in CHANNELS:
            link.bad(f"datagram on unknown channel {channel!r}", now)
            return out
        # The source first, then the size, then the bytes (issue 27): a second DS's packets,
        # or a flood from anywhere, are dropped before a byte is decoded; the decoder refuses
        # a packet over its size bound by its length alone (counted bad, logged once a second).
        source = (str(source[0]), int(source[1]))
        if self.control.foreign(source, now):
            return out
        try:
            packet = self._wire.decode_control(data if type(data) is bytes else bytes(data))
        except ProtocolError as exc:
            link.bad(exc, now)
            return out
        arrived = now if arrived is None else min(arrived, now)
        verdict = self.control.receive(packet, len(data), source, now, arrived, superseded)
        if not isinstance(verdict, str):  # obeyed (not STALE)
            inputs = self._wire.ds_inputs()
            if inputs is not None:  # 2010: the DS's digital and analog inputs, for the program
                self.inputs.take_ds_io(inputs)
            if verdict.reboot:
                out.extend(self._begin_reboot(now, "the DS asked for a reboot"))
                return out
            if verdict.restart:
                self._begin_restart(now, "the DS asked to restart the robot code")
            self.control.obey(packet, now)
            self.inputs.take_tags(packet.tags)
            self._apply(now)
            self._update_battery(now)
        # Every packet heard is answered as a real roboRIO answers: its sequence echoed with
        # the state the robot applies now (a stale one too, so the DS's trip time stays true).
        reply = self._wire.encode_status(self._status(packet.sequence))
        port = self.control.reply_port if self.control.reply_port is not None else source[1]
        out.append(Datagram(channel, reply, (source[0], port), self._wire.status_kind))
        self.stats[LINK_RIO_TO_DS].sent(len(reply))
        return out

    def stream_opened(self, conn: Hashable, peer: Address | None, now: float) -> list[Action]:
        self._init(now)
        self._advance(now)
        out = self._take_pending()
        if self.program.code_state == CODE_REBOOTING:
            out.append(Close(conn, "the roboRIO is rebooting"))
            return out
        out.extend(self.tcp.open(conn, peer, now, self.control.ds_host))
        return out

    def stream_data(self, conn: Hashable, data: bytes, now: float) -> list[Action]:
        self._init(now)
        self._advance(now)
        out = self._take_pending()
        messages, error = self.tcp.receive(conn, bytes(data), now, self._wire.decode_tcp)
        for message in messages:
            wrong = self.inputs.take_message(message, now)
            if wrong is not None:
                self.stats[LINK_TCP].bad(wrong, now)
        if error is not None:  # counted: the connection goes
            out.append(self.tcp.drop(conn, error, now))
        return out

    def stream_closed(self, conn: Hashable, reason: str, now: float) -> list[Action]:
        self._init(now)
        self.tcp.closed(conn, reason, now)
        self._advance(now)
        return self._take_pending()

    def poll(self, now: float) -> list[Action]:
        self._init(now)
        self._advance(now)
        return self._take_pending()

    def next_deadline(self) -> float | None:
        if self._booted_at is None:
            return 0.0  # not started yet: poll at once
        times = [t for t in (self._wake_at, self.tcp.wake_at) if t is not None]
        if self.program.code_state == CODE_REBOOTING:
            assert self._reboot_until is not None  # set while rebooting
            times.append(self._reboot_until)
            return min(times)
        times += self.control.deadlines()
        for t in (self._beats.next, self.program.deadline(), self.tcp.deadline()):
            if t is not None:
                times.append(t)
        return min(times)

    def program_events(self, events: Sequence[ProgramEvent], now: float) -> list[Action]:
        """What the program's process did (answered, printed, raised, ended), as the runtime
        read it from its channel: taken at the next poll, which is due at once."""
        self.program.receive(events, now)
        return []

    def shutdown(self) -> None:
        """The field stops: a robot program's process goes with it."""
        self.program.stop()

    # -- user commands ----------------------------------------------------------------
    def apply(self, command: Command, now: float) -> None:
        """Carry out one of the fake roboRIO's commands (roles/cores/commands.py), or raise
        CommandError saying why not."""
        if not isinstance(command, SetBattery):
            raise CommandError(f"{command.verb} is not a roboRIO command")
        self.set_battery(command.volts, now)

    def set_battery(self, volts: float | None, now: float) -> None:
        """Force the battery reading to ``volts`` (fault injection); ``None`` releases it."""
        try:
            self.telemetry.battery.force(volts)
        except ValueError as exc:
            raise CommandError(str(exc)) from None
        self._init(now)

    def set_battery_rest(self, volts: float, now: float) -> None:
        """Swap in a battery resting at ``volts``."""
        try:
            self.telemetry.battery.set_voltage(volts)
        except ValueError as exc:
            raise CommandError(str(exc)) from None
        self._init(now)

    def restart_code(self, now: float) -> None:
        self._init(now)
        self._refuse_while_rebooting("the roboRIO is rebooting")
        self._begin_restart(now, "restart asked from the roboRIO panel")
        self._wake(now)

    def reboot(self, now: float) -> None:
        self._init(now)
        self._refuse_while_rebooting("the roboRIO is already rebooting")
        self.tcp.queue(self._begin_reboot(now, "reboot asked from the roboRIO panel"), now)
        self._wake(now)

    def load_program(self, path: str | os.PathLike[str], now: float) -> None:
        """Run the program in ``path`` from now on (the code restarts to load it)."""
        self._init(now)
        self._refuse_while_rebooting("the roboRIO is rebooting")
        source = replace(self.program.source, path=os.fspath(path), program=None)
        try:
            self.program.check(source, now)
        except ProgramError as exc:
            raise CommandError(str(exc)) from None
        self.program.source = source
        self._begin_restart(now, f"loading {self.program.name}")
        self._wake(now)

    def use_builtin_program(self, now: float) -> None:
        self._init(now)
        self._refuse_while_rebooting("the roboRIO is rebooting")
        self.program.source = replace(self.program.source, path=None, program=None)
        self._begin_restart(now, "switching to the built-in program")
        self._wake(now)

    def inject_rail_fault(self, rail: str, now: float) -> None:
        """Count a fault on the 6 V, 5 V or 3.3 V rail (sent in the next 0x05 frame)."""
        key = rail.strip().lower().replace(" ", "")
        if key not in RAILS:
            raise CommandError(f"unknown rail {rail!r}: one of {', '.join(RAILS)}")
        self._init(now)
        setattr(self.faults, RAILS[key], getattr(self.faults, RAILS[key]) + 1)
        self.events.add(now, f"{key} rail fault injected")
        self._wake(now)

    def send_netconsole_to(self, address: Address | None) -> None:
        """2010: where NetConsole text goes (the field's ephemeral plan, where the DS listens on a
        port the robot cannot guess); None: the DS's address, port 6666."""
        self.netconsole_address = address

    def _refuse_while_rebooting(self, why: str) -> None:
        if self.program.code_state == CODE_REBOOTING:
            raise CommandError(why)

    # -- time -------------------------------------------------------------------------
    def _init(self, now: float) -> None:
        if self._booted_at is not None:
            return
        self._booted_at = now
        self._now = now
        self._beats.start(now)  # the first beat is due at once
        self.events.add(now, "roboRIO up")
        self.program.start(now)

    def _wake(self, now: float) -> None:
        self._wake_at = now if self._wake_at is None else min(self._wake_at, now)

    def _take_pending(self) -> list[Action]:
        self._wake_at = None
        return self.tcp.take()

    def _advance(self, now: float) -> None:
        self._now = now
        if self.program.code_state == CODE_REBOOTING:
            assert self._reboot_until is not None  # set while rebooting
            if now < self._reboot_until:
                return
            self._finish_reboot(now)
        self.program.advance(now)
        self.control.watch(now)
        self._apply(now)
        skipped = self._beats.take(now)
        if skipped is not None:
            self.faults.missed_beats += skipped
            self._beat(now)
        self.tcp.housekeeping(now, self.team)

    def _beat(self, now: float) -> None:
        self.beats += 1
        self.tcp.new_beat()
        self._update_battery(now)
        self._apply(now)
        self.program.report_overruns(now)
        if self.program.ready_for_call:  # else no code, or the last call has not returned (an overrun)
            self.program.call(self._control_state(now), self.inputs.ds_io, now)

    def _apply(self, now: float) -> None:
        self.control.apply(now, self.program.code_alive)

    def _update_battery(self, now: float) -> None:
        self.telemetry.update_battery(now, self.outputs_enabled, self.inputs.joysticks)

    def _pdp_amps(self) -> list[float]:
        return self.telemetry.pdp_amps(self.outputs_enabled, self.inputs.joysticks)

    # -- restarts and reboots ---------------------------------------------------------
    def _begin_restart(self, now: float, why: str) -> None:
        self.control.clear_estop(now)
        self.program.restart(now, why)

    def _begin_reboot(self, now: float, why: str) -> list[Action]:
        self.events.add(now, f"roboRIO rebooting: {why}")
        closes: list[Action] = list(self.tcp.close_all("roboRIO rebooting"))
        self.control.power_off()
        self.program.power_off()
        self._reboot_until = now + self.reboot_time
        return closes

    def _finish_reboot(self, now: float) -> None:
        """Back from a reboot: everything the roboRIO knew of its DS and its code is forgotten."""
        until, self._reboot_until = self._reboot_until, None
        assert until is not None  # set while rebooting
        self.control.power_on()
        self.inputs = DsInputs(self.events)
        self.tcp.power_on()
        self.telemetry.power_on()
        self.faults.clear()
        self._booted_at = now
        self._beats.start(now)
        self.events.add(now, f"roboRIO back after reboot ({now - until + self.reboot_time:.1f} s)")
        self.program.power_on(now)

    # -- console ----------------------------------------------------------------------
    def _emit(self, kind: str, text: str, code: int = 0, location: str = "", call_stack: str = "",
              bounded: bool = True) -> None:
        """A console line or a diagnostic (the robot program's, or ours about it): to the TCP
        clients and, in 2010, as a NetConsole datagram."""
        now = self._now
        line = self.tcp.write(kind, text, code, location, call_stack, bounded, now,
                              max(0.0, now - (self._booted_at or 0.0)))
        if line is not None:
            self.tcp.queue(self._wire.console_actions(*line), now)  # 2010: NetConsole datagrams

    # -- the program's view and the status packet ---------------------------------------
    def _control_state(self, now: float) -> ControlState:
        control, inputs, battery = self.control, self.inputs, self.telemetry.battery
        return ControlState(
            time=now - self.program.started_at, enabled=control.enabled, mode=MODE_LABEL[control.mode],
            estop=control.estopped, joysticks=inputs.joysticks, ds_attached=control.ds_connected,
            fms_attached=control.fms_attached, station=control.station.label, match_info=inputs.match_info,
            game_data=inputs.game_data, countdown=inputs.countdown, battery=battery.volts,
            brownout=battery.brownout)

    def _status(self, sequence: int) -> StatusPacket:
        control, program, battery = self.control, self.program, self.telemetry.battery
        running = program.code_alive
        trace = program.trace_mode if running else None
        tags: list[StatusTag] = []
        out = program.program_out
        # A real roboRIO sent no output tag in 4,352 status packets with nothing set (the 2021
        # capture, docs/protocol.md#idle-outputs): a tag per slot up to the last one with something set; an
        # idle one (01 01) only to keep a later slot's number.
        for slot in range(len(self.inputs.joystick_tags)):
            outputs = out.outputs[slot]
            left = _rumble_u16(out.left_rumble[slot])
            right = _rumble_u16(out.right_rumble[slot])
            tags.append(JoystickOutput(outputs, right, left) if outputs or left or right
                        else IDLE_JOYSTICK_OUTPUT)
        while tags and tags[-1] is IDLE_JOYSTICK_OUTPUT:
            tags.pop()
        tags.extend(self.telemetry.status_tags(self.outputs_enabled, self.inputs.joysticks, running,
                                               control.enabled, self.beats))
        return StatusPacket(
            sequence=sequence, comm_version=0x01, estop=control.estopped, brownout=battery.brownout,
            code_initializing=program.code_state == CODE_STARTING, enabled=control.enabled, mode=control.mode,
            robot_code=running, is_roborio=True, user_test=trace == "test", user_auto=trace == "auto",
            user_teleop=trace == "teleop", user_disabled=trace == "disabled",
            battery=min(max(battery.volts, 0.0), 255.99), request_date=self.inputs.request_date,
            tags=tuple(tags))

    # -- plain view -------------------------------------------------------------------
    def view(self, now: float | None = None) -> RioView:
        """What the panels show, as a frozen value: each part's own fields, copied."""
        control, inputs, program, telemetry = self.control, self.inputs, self.program, self.telemetry
        out, battery = program.program_out, telemetry.battery
        return RioView(
            at=self._now if now is None else now, team=self.team, beats=self.beats,
            enabled=control.enabled, estopped=control.estopped, mode=control.mode, ds_address=control.ds_address,
            ds_connected=control.ds_connected, ds_enabled=control.ds_enabled,
            watchdog_tripped=control.watchdog_tripped, fms_attached=control.fms_attached, station=control.station,
            outputs_enabled=self.outputs_enabled,
            request_date=inputs.request_date, game_data=inputs.game_data, match_info=inputs.match_info,
            countdown=inputs.countdown,
            joysticks=tuple(RioJoystickView(j.axes, j.pressed, j.povs, j.name) for j in inputs.joysticks),
            code_state=program.code_state, program_name=program.name, trace_mode=program.trace_mode,
            program_out=ProgramOutView(out.outputs, out.left_rumble, out.right_rumble), lcd=out.lcd,
            tcp_clients=self.tcp.count, console=self.tcp.console.view(),
            battery=BatteryView(battery.volts, battery.brownout, battery.brownouts), pdp_amps=self.pdp_amps,
            events=EventsView(self.events.items.view()), faults=self.faults.view(),
            stats={name: stats.view() for name, stats in self.stats.items()})

    def snapshot(self) -> dict[str, Any]:
        """Everything a panel or ``--json`` status line shows, as plain JSON-able values."""
        return self.view().snapshot()


def _rumble_u16(value: float) -> int:
    return max(0, min(0xFFFF, round(value * 0xFFFF)))
