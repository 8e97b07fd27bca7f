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
  until comms are lost. Others are counted in ``foreign_packets`` and dropped before they are
  decoded (logged once a second).
* Robot comms are lost after 1 s without a status packet. The DS then disables and forgets
  the operator's enable: the robot needs a fresh ``enable()`` (an event says so).
* Enabling is refused without robot comms or robot code, while e-stopped (by the DS or as the
  robot reports), while a practice run is going (it enables by itself) and while an FMS is
  attached (the FMS decides).
* E-stop latches. The NI DS clears an e-stop only when the robot code restarts or the roboRIO
  reboots, so here the latch clears only through ``restart_code()`` / ``reboot_roborio()``:
  the packets carrying the request no longer carry the e-stop bit, so the robot, whose own
  latch that request clears, does not latch again. Nothing else clears it: not a comms loss,
  not a reconnect, not an FMS (an FMS e-stop latches it too). What holds it is said in words
  (``estop_kind``, ``estop_reason``): an FMS keeps its station e-stopped for the rest of the
  match (a restart within it is e-stopped again by the FMS's next packet), and a robot
  e-stopped in one match stays e-stopped into the next until its code restarts.
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

:class:`DriverStation` is a composition: it routes what the shell reports and the operator's
commands to its parts, which never reach into one another (each is handed what it reads; the
FMS client asks the DS for a frozen :class:`~roles.cores.ds_fms.DsReport` when it sends).
Readers read the parts (``ds.link.robot_comms``) or, better, the view: :meth:`DriverStation.view`
is a frozen :class:`~roles.cores.views.DsView` composed of each part's own fragment (its
``view()``), under the part's name, with what the DS decides from them (station, mode, enable,
what holds an e-stop, what blocks an enable).

* ``link``: the robot UDP link, :class:`~roles.cores.ds_robot.RobotLink` (the grid, robot
  comms, trip times, lost packets, requests), and ``telemetry`` beside it
  (:class:`~roles.cores.ds_robot.RobotTelemetry`: battery history, brownouts, the status tags);
* ``tcp``: the robot TCP client, :class:`~roles.cores.ds_robot_tcp.RobotTcpClient` (console,
  versions, faults, match info, game data);
* ``sticks``: the joystick slots, :class:`~roles.cores.ds_joysticks.JoystickSlots`;
* ``arbiter``: enable, mode, station, e-stop and practice,
  :class:`~roles.cores.ds_enable.EnableArbiter`;
* ``fms``: the FMS client, :class:`~roles.cores.ds_fms.FmsClient`, whose events the DS applies.

Every command takes ``now``, the shell's clock, as every wire event does.
"""

from __future__ import annotations

import datetime as _dt
from dataclasses import replace
from typing import Any, Callable, Hashable

from protocol import rio_to_ds
from protocol.ds_to_rio import ControlPacket, Countdown, Date, Timezone
from protocol.enums import AllianceStation, JoystickType, Mode
from protocol.errors import ProtocolError

from .addresses import check_team
from .commands import (ClearJoystick, Command, DeclareJoystick, Disable, Enable, EStop, JoystickChange,
                       KeepRoundTrips, Practice, RebootRoboRIO, RestartCode, SetAnalogInput, SetAxis, SetButton,
                       SetGameData, SetMode, SetPov, SetPracticeTiming, ToggleDigitalInput, UpdateJoysticks)
from .core import Action, Address, Close, CommandError, Events, LinkStats, utc_now
from .ds_enable import EnableArbiter
from .views import DsView, EventsView
from .ds_fms import FMS_CONTROL_CHANNELS, DsReport, FmsClient, GameDataChanged, MatchInfoChanged
from .ds_fms import Attached as FmsAttached
from .ds_fms import Detached as FmsDetached
from .ds_fms import Estopped as FmsEstopped
from .ds_joysticks import JoystickSlot, JoystickSlots
from .ds_robot import (BATTERY_SAMPLES, COMMS_TIMEOUT, ECHO_TIMEOUT, REQUEST_PACKETS, ROBOT, ControlState,
                       RobotLink, RobotTelemetry)
from .ds_robot_tcp import CONSOLE_LINES, MAX_ROBOT_FRAME, ROBOT_TCP, TCP_RETRY, RobotTcpClient
from .practice import PracticeTiming

__all__ = ["BATTERY_SAMPLES", "COMMS_TIMEOUT", "CONSOLE_LINES", "ECHO_TIMEOUT", "KINDS", "LINKS",
           "MAX_ROBOT_FRAME", "PERIOD", "REQUEST_PACKETS", "ROBOT", "ROBOT_TCP", "TCP_RETRY", "ControlState",
           "DriverStation", "JoystickSlot", "ModernRobotCodec", "robot_codec"]

#: An enable asked for longer ago than this (the wire did not answer: it stalled) is refused:
#: nothing is obeyed late, and an enable least of all.
ENABLE_FRESH = 1.0
PERIOD = 0.020  # read when a DS is made (a conformance test makes a DS with another beat)
LINKS = ("ds->rio", "rio->ds", "robot-tcp", "fms-udp", "fms-tcp")
#: (link, direction) -> protocol kind, for a RoleSpec's ``kinds``.
KINDS = {
    ("robot", "out"): "ds-to-rio", ("robot", "in"): "rio-to-ds",
    ("robot-tcp", "out"): "ds-to-rio-tcp", ("robot-tcp", "in"): "rio-to-ds-tcp",
    ("fms", "in"): "fms-to-ds", ("fms-lite", "in"): "fms-to-ds", ("fms-out", "out"): "ds-to-fms",
    ("fms-tcp", "out"): "ds-to-fms-tcp", ("fms-tcp", "in"): "fms-to-ds-tcp",
}


# -- the codec seam -------------------------------------------------------------------------
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


class DriverStation:
    """One team's Driver Station. See the module docstring for the links, the rules and the parts."""

    def __init__(self, team: int, robot_udp: Address, robot_tcp: Address, *,
                 station: AllianceStation = AllianceStation.RED1, robot_udp_fms: Address | None = None,
                 fms_tcp: Address | None = None, fms_udp: Address | None = None,
                 clock: Callable[[], _dt.datetime] | None = None, timezone_name: str = "UTC",
                 practice_timing: PracticeTiming | None = None, legacy: bool = False,
                 simulator: bool = False, fms_hello: str = "ni") -> None:
        self.team = check_team(team)
        try:
            # checked as the tag will carry it: text of at most 254 bytes
            ControlPacket(tags=(Timezone(timezone_name),)).encode()
        except (ProtocolError, TypeError) as exc:
            raise ValueError(f"bad time zone name {timezone_name!r}: {exc}") from None
        self._codec = codec = robot_codec(legacy)
        self.events = Events()
        self.link = RobotLink(codec, robot_udp, robot_udp_fms, self.events, period=PERIOD,
                              clock=clock or utc_now, timezone_name=timezone_name, simulator=simulator)
        self.telemetry = RobotTelemetry(self.events)
        self.tcp = RobotTcpClient(robot_tcp, self.events, uses_tcp=codec.uses_tcp)
        self.sticks = JoystickSlots()
        self.arbiter = EnableArbiter(station, practice_timing or PracticeTiming(), self.events,
                                     modes=codec.modes, protocol=codec.name)
        # fms_hello: how it logs in to an FMS, as the NI DS ("ni") or the 2027 FIRST DS ("2027")
        self.fms = FmsClient(self._fms_report, self.events, fms_tcp, fms_udp, hello=fms_hello)
        self._now = 0.0  # the shell's clock at the last wire event
        self._pending: list[Action] = []  # actions a command asked for, sent at the next poll

    # -- what the DS decides from its parts (readers read the parts, or better, the view) --------
    @property
    def legacy(self) -> Any:
        """The 2010 codec (roles/cores/legacy_ds.py: digital and analog inputs, LCD, dashboard,
        NetConsole), or None in the 2015+ protocol."""
        return self._codec if self._codec.name == "2010" else None

    @property
    def stats(self) -> dict[str, LinkStats]:
        """The counters of each link, by name (``LINKS``)."""
        link, fms = self.link, self.fms
        return {"ds->rio": link.stats_out, "rio->ds": link.stats_in, "robot-tcp": self.tcp.stats,
                "fms-udp": fms.udp_stats, "fms-tcp": fms.tcp_stats}

    @property
    def station(self) -> AllianceStation:
        return self.arbiter.station(self.fms)

    @property
    def mode(self) -> Mode:
        return self.arbiter.mode(self.fms)

    @property
    def enabled(self) -> bool:
        """What the control packets say: the operator's, the FMS's or the practice run's
        enable, never while e-stopped or without robot comms."""
        return self.arbiter.enabled(self.link.robot_comms, self.fms)

    @property
    def estop_kind(self) -> str:
        """What holds the robot e-stopped (:meth:`EnableArbiter.estop_state`): ``fms``,
        ``fms-held``, ``stale``, ``latched``, ``robot`` or "" (nothing)."""
        return self.arbiter.estop_state(self.fms, self.link.still_estopped)[0]

    @property
    def estop_reason(self) -> str:
        """The same in words: "FMS e-stop: the FMS holds this station e-stopped for the rest of
        the match", "robot still e-stopped: restart its code"... ("" when nothing does)."""
        return self.arbiter.estop_state(self.fms, self.link.still_estopped)[1]

    @property
    def trip_ms(self) -> float | None:
        return self.link.echoes.trip.average_ms if self.link.robot_comms else None

    @property
    def enable_blocker(self) -> tuple[str, str] | None:
        """What keeps the robot from being enabled now, ``(kind, words)`` (None: nothing):
        :meth:`EnableArbiter.blocker`, whose words :meth:`enable` refuses with."""
        return self.arbiter.blocker(self.link, self.fms)

    def countdown(self, now: float | None = None) -> float | None:
        """Seconds left in the current period, while a match or a practice run is timing."""
        return self.arbiter.countdown(self._now if now is None else now, self.fms)

    def _fms_report(self) -> DsReport:
        """What this DS tells the FMS now (roles/cores/ds_fms.py asks when it sends)."""
        link, comms = self.link, self.link.robot_comms
        can = self.telemetry.can
        return DsReport(self.team, comms, self.arbiter.estopped, self.enabled, self.mode, link.battery,
                        self.telemetry.brownout, link.echoes.lost_packets, link.echoes.sent_packets, self.trip_ms,
                        link.status if comms else None, can.utilization if can is not None else None)

    def view(self, now: float | None = None) -> DsView:
        """What a screen shows of this DS at ``now`` (default: the last wire event), composed
        of its parts' own fragments."""
        now = self._now if now is None else now
        blocker, legacy = self.enable_blocker, self.legacy
        kind, reason = self.arbiter.estop_state(self.fms, self.link.still_estopped)
        return DsView(at=now, team=self.team, station=self.station, mode=self.mode, enabled=self.enabled,
                      estop_kind=kind, estop_reason=reason,
                      enable_blocker=None if blocker is None else blocker[0],
                      enable_refusal=None if blocker is None else blocker[1],
                      trip_ms=self.trip_ms, countdown_left=self.countdown(now), link=self.link.view(),
                      telemetry=self.telemetry.view(), tcp=self.tcp.view(), sticks=self.sticks.view(),
                      arbiter=self.arbiter.view(), fms=self.fms.view(now), events=EventsView(self.events.items.view()),
                      stats=tuple(s.view() for s in self.stats.values()),
                      legacy=None if legacy is None else legacy.view())

    def snapshot(self) -> dict[str, object]:
        """The panel/status-line fields, JSON-able (the headless ``--json`` line)."""
        return self.view().snapshot()

    # -- the core contract -----------------------------------------------------------------
    def poll(self, now: float) -> list[Action]:
        self._now = now
        out, self._pending = self._pending, []
        if self.link.comms_timed_out(now):
            self.link.lose_comms()
            self.arbiter.comms_lost(now, self.fms)
        self.link.echoes.expire(now)
        self.arbiter.update_practice(now)
        out += self.fms.poll(now)
        self._apply_fms_events(now)
        out += self.tcp.poll(now)
        if self.tcp.state == "open":
            out += self._robot_tcp_sends()
        if self.link.slot_due(now):
            enabled, mode = self.enabled, self.mode
            self.arbiter.sent(now, enabled, mode)
            out.append(self.link.control_datagram(
                now, estop=self.arbiter.estopped, fms_attached=self.fms.attached, enabled=enabled, mode=mode,
                station=self.station, team=self.team, countdown=self.countdown(now), sticks=self.sticks))
            out += self._codec.after_control(self, now)
        return out

    def next_deadline(self) -> float | None:
        if not self.link.started or self._pending:
            return self._now
        if self.tcp.state == "open" and (self.sticks.descriptors_dirty or self.tcp.dirty):
            return self._now
        best = self.link.next_deadline()  # asked after every event: no list, no generator
        for d in (self.tcp.next_deadline(), self.arbiter.next_deadline(self._now), self.fms.next_deadline()):
            if d is not None and (best is None or d < best):
                best = d
        return best

    def shutdown(self) -> None:
        """Nothing of this core runs outside it (the shell calls this on every core)."""

    def datagram(self, channel: str, data: bytes, source: Address, now: float, arrived: float | None = None,
                 superseded: bool = False) -> list[Action]:
        """(``arrived``, ``superseded``: the one signature of every core; not judged here.)"""
        self._now = now
        if channel == ROBOT:
            pkt = self.link.on_status(data, source, now)
            if pkt is not None:
                self.telemetry.take(pkt, now)
                self.sticks.take_outputs(pkt.tags)
        elif channel in FMS_CONTROL_CHANNELS:
            out = self.fms.datagram(data, source, now)
            self._apply_fms_events(now)
            return out
        else:
            actions: list[Action] = self._codec.datagram(self, channel, data, source, now)
            return actions
        return []

    def stream_opened(self, conn: Hashable, peer: Address, now: float) -> list[Action]:
        self._now = now
        if conn == ROBOT_TCP:
            self.tcp.opened(peer, now)
            self.sticks.resend_descriptors()
            return self._robot_tcp_sends()
        if conn == "fms-tcp":
            out = self.fms.stream_opened(peer, now)
            self._apply_fms_events(now)
            return out
        return [Close(conn, "the Driver Station accepts no connections")]

    def stream_data(self, conn: Hashable, data: bytes, now: float) -> list[Action]:
        self._now = now
        if conn == ROBOT_TCP:
            return self.tcp.data(data, now)
        if conn == "fms-tcp":
            out = self.fms.stream_data(data, now)
            self._apply_fms_events(now)
            return out
        return []

    def stream_closed(self, conn: Hashable, reason: str, now: float) -> list[Action]:
        self._now = now
        if conn == ROBOT_TCP:
            self.tcp.closed(reason, now)
        elif conn == "fms-tcp":
            self.fms.stream_closed(reason, now)
            self._apply_fms_events(now)
        return []

    def _robot_tcp_sends(self) -> list[Action]:
        return self.tcp.sends(self.sticks.take_descriptors())

    def add_console_line(self, now: float, level: str, text: str) -> None:
        self.tcp.add_console_line(now, level, text)

    # -- what the FMS client says ----------------------------------------------------------
    def _apply_fms_events(self, now: float) -> None:
        """What the FMS client says the field asked of this DS (roles/cores/ds_fms.py), in order."""
        for event in self.fms.take_events():
            if type(event) is FmsAttached:
                self.arbiter.fms_attached(now)
            elif type(event) is FmsDetached:
                self.arbiter.fms_detached(now, event.reason)
            elif type(event) is FmsEstopped:
                self._latch_estop(now, "the FMS e-stopped this station", "FMS")
            elif type(event) is MatchInfoChanged:
                self.tcp.set_match_info(event.info)
            elif type(event) is GameDataChanged:
                self.tcp.set_game_data(event.text)

    def _latch_estop(self, now: float, why: str, by: str = "operator") -> None:
        attached = self.fms.attached
        self.arbiter.latch_estop(now, why, self.fms, by)
        if attached:
            # A restart clears the e-stop, not the FMS's enable from before it: without this
            # an e-stop then a restart within one FMS packet (500 ms) enabled the robot again
            # on the FMS's last word (found by tests/roles/test_safety.py's property). Held
            # disabled until the FMS changes phase (the period ends) or detaches, as a disable.
            self.fms.hold(now)

    # -- commands (each takes ``now``, the shell's clock) --------------------------------------
    def enable(self, now: float) -> None:
        self.arbiter.enable(now, self.link, self.fms)

    def disable(self, now: float) -> None:
        """Always works. Under an FMS it holds the robot disabled until the FMS changes phase
        (the period ends) or detaches."""
        self.arbiter.disable(now)
        if self.fms.attached and not self.fms.hold_disabled:
            self.fms.hold(now)
            self.events.add(now, "disabled by the operator: held until the FMS changes phase or detaches")

    def estop(self, now: float) -> None:
        self._latch_estop(now, "operator")

    def set_mode(self, mode: Mode | str, now: float) -> None:
        self.arbiter.set_mode(mode, now, self.fms, self.enabled)

    def set_station(self, station: AllianceStation | str, now: float) -> None:
        self.arbiter.set_station(station, now, self.fms)

    def set_team(self, team: int, now: float) -> None:
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
            self.events.add(now, f"team: {team}")
            self._pending += self.fms.relogin(now)
            self._apply_fms_events(now)

    def _request(self, what: str, now: float) -> None:
        if not self.link.robot_comms:
            raise CommandError(f"no robot comms: cannot {what}")
        self.arbiter.request(now, what)

    def restart_code(self, now: float) -> None:
        self._request("restart robot code", now)
        self.link.request_restart(now)

    def reboot_roborio(self, now: float) -> None:
        self._request("reboot the roboRIO", now)
        self.link.request_reboot(now)

    def set_game_data(self, text: str, now: float) -> None:
        """Local game data (practice, bench tests); an FMS's game data replaces it."""
        if not isinstance(text, str) or len(text.encode("utf-8", "surrogateescape")) > 255:
            raise CommandError("game data must be text of at most 255 bytes")
        self.tcp.set_game_data(text)

    def start_practice(self, now: float, timing: PracticeTiming | None = None) -> None:
        self.arbiter.start_practice(now, self.link, self.fms, timing)

    def stop_practice(self, now: float) -> None:
        self.arbiter.stop_practice(now)

    def set_robot_addresses(self, now: float, *, robot_udp: Address | None = None,
                            robot_tcp: Address | None = None, robot_udp_fms: Address | None = None) -> None:
        self.link.set_addresses(robot_udp, robot_udp_fms)
        if robot_tcp is not None:
            self._pending += self.tcp.set_address(robot_tcp, now)

    def set_fms_addresses(self, fms_tcp: Address | None, fms_udp: Address | None, now: float) -> None:
        """Another FMS (None, None: no FMS). An attached FMS is detached: disabled."""
        self._pending += self.fms.set_addresses(fms_tcp, fms_udp, now)
        self._apply_fms_events(now)

    # -- commands -----------------------------------------------------------------------------
    def apply(self, command: Command, now: float) -> None:
        """Carry out one of the Driver Station's commands (roles/cores/commands.py), or raise
        CommandError saying why not (nothing changed)."""
        match command:
            case Enable(issued=issued):
                if issued is not None and now - issued > ENABLE_FRESH:
                    raise CommandError(f"the enable was asked for {now - issued:.1f} s ago, while the wire "
                                       "did not answer: press it again")
                self.enable(now)
            case Disable():
                self.disable(now)
            case EStop():
                self.estop(now)
            case RestartCode():
                self.restart_code(now)
            case RebootRoboRIO():
                self.reboot_roborio(now)
            case SetMode(mode=mode):
                self.set_mode({"teleop": Mode.TELEOP, "auto": Mode.AUTONOMOUS, "test": Mode.TEST}[mode], now)
            case SetAxis() | SetButton() | SetPov():
                if self.sticks.is_empty(command.joystick):  # (a slot out of range: CommandError)
                    # a headless command may move a joystick no one plugged in: give the slot a
                    # standard gamepad (6 axes, 12 buttons, 1 POV), as a keyboard joystick would
                    self.set_joystick(command.joystick, 6, 12, 1, now, name="fieldbox keyboard")
                self._joystick_change(command, now)
            case DeclareJoystick() | ClearJoystick():
                self._joystick_change(command, now)
            case UpdateJoysticks(changes=changes):
                for change in changes:
                    self._joystick_change(change, now)
            case Practice(action=action):
                self.start_practice(now) if action == "start" else self.stop_practice(now)
            case SetPracticeTiming():
                lengths = {name: value for name, value in (("countdown", command.countdown), ("auto", command.auto),
                                                           ("pause", command.pause), ("teleop", command.teleop))
                           if value is not None}
                try:
                    self.arbiter.practice_timing = replace(self.arbiter.practice_timing, **lengths)
                except (TypeError, ValueError) as exc:
                    raise CommandError(str(exc)) from None
            case SetGameData(text=text):
                self.set_game_data(text, now)
            case ToggleDigitalInput(number=number):
                self._legacy_or_refuse().toggle_digital_input(number)
            case SetAnalogInput(number=number, value=value):
                self._legacy_or_refuse().set_analog_input(number, value)
            case KeepRoundTrips(samples=samples):
                if isinstance(samples, bool) or not isinstance(samples, int) or not 1 <= samples <= 10_000_000:
                    raise CommandError(f"round-trip samples must be 1..10000000, not {samples!r}")
                self.link.echoes.trip.samples.restart(samples)
            case _:
                raise CommandError(f"{command.verb} is not a Driver Station command")

    def _joystick_change(self, change: JoystickChange, now: float) -> None:
        if isinstance(change, DeclareJoystick):
            self.set_joystick(change.slot, change.axes, change.buttons, change.povs, now, name=change.name,
                              is_xbox=change.is_xbox, joystick_type=change.joystick_type)
        elif isinstance(change, ClearJoystick):
            self.clear_joystick(change.slot, now)
        elif isinstance(change, SetAxis):
            self.set_axis(change.joystick, change.axis, change.value, now)
        elif isinstance(change, SetButton):
            self.set_button(change.joystick, change.button, change.down, now)
        elif isinstance(change, SetPov):
            self.set_pov(change.joystick, change.pov, change.degrees, now)
        else:
            raise CommandError(f"{type(change).__name__} is not a joystick change")

    def _legacy_or_refuse(self) -> Any:
        if self.legacy is None:
            raise CommandError("this Driver Station is not a 2010 one: press F8 and tick 2010 legacy")
        return self.legacy

    # -- joystick commands -----------------------------------------------------------------
    def set_joystick(self, slot: int, axes_count: int, button_count: int, pov_count: int, now: float, *,
                     name: str = "", is_xbox: bool = False,
                     joystick_type: JoystickType | int = JoystickType.UNKNOWN,
                     axis_types: tuple[int, ...] | list[int] | None = None) -> None:
        self.sticks.set_joystick(slot, axes_count, button_count, pov_count, name=name, is_xbox=is_xbox,
                                 joystick_type=joystick_type, axis_types=axis_types)

    def clear_joystick(self, slot: int, now: float) -> None:
        self.sticks.clear_joystick(slot)

    def set_axis(self, slot: int, axis: int, value: float, now: float) -> None:
        self.sticks.set_axis(slot, axis, value)

    def set_button(self, slot: int, button: int, pressed: bool, now: float) -> None:
        self.sticks.set_button(slot, button, pressed)

    def set_pov(self, slot: int, pov: int, degrees: int, now: float) -> None:
        self.sticks.set_pov(slot, pov, degrees)
