"""The Driver Station side of the 2010 (cRIO) protocol: the codec plugged into the DS core's
seam (``roles.cores.ds.robot_codec(legacy=True)``), the dashboard sender and NetConsole.

The DS core (roles/cores/ds.py) keeps every rule it has for the 2015+ protocol (the 20 ms grid,
comms loss, the e-stop latch, trip times, lost packets); this codec only changes what goes on
the wire and what comes back:

* DS -> robot, UDP 1110 (the DS's ``"robot"`` channel): one 1024-byte
  :class:`~protocol.legacy.LegacyControlPacket` per beat, CRC included. Control bits: the
  not-e-stop bit set in normal operation, enabled, autonomous, FMS attached, and reset for a
  reboot. The 2010 protocol had no "restart robot code" request: a cRIO restarted its code by
  rebooting, so a restart request is sent as the reset bit too. Team, alliance and position
  (ASCII ``R``/``B`` and ``1``-``3``), four joysticks of six int8 axes and twelve buttons
  (bit 0 = button 1) from the DS's first four slots, four 10-bit analog inputs and eight
  digital inputs (:meth:`LegacyRobotCodec.set_digital_input`, :meth:`set_analog_input`),
  DS version ``10020800``.
* robot -> DS, UDP 1150: :meth:`decode_status` checks size and CRC (a bad one raises
  :class:`~protocol.errors.ProtocolError`: the DS counts it on ``stats["rio->ds"]`` and drops
  it) and hands the core a plain :class:`~protocol.rio_to_ds.StatusPacket` view of it: the
  echoed packet index as the sequence, the echoed control bits, the BCD battery in volts and
  "robot code" unless the battery bytes say 0x37 0x37 (no code; the volts then read 0.0).
  The packet itself, LCD and DS digital outputs included, is kept in ``last_status``.
* DS -> dashboard, UDP 1165 (channel ``"dashboard"``, which shares the robot socket): one
  1018-byte :class:`~protocol.legacy.LegacyDashboardPacket` after every control packet (50 Hz),
  to ``dashboard`` (the field sets it: by default the DS's own address; ``None`` sends none).
* robot NetConsole, UDP 6666 (channel ``"netconsole"``): from the robot's host (any port; a
  datagram from elsewhere is counted as foreign and dropped undecoded), each datagram's lines
  go to the DS console with level ``"stdout"`` (NetConsole was the cRIO's stdout; a line that
  starts with ``ERROR``/``WARNING``, as WPILib's and our robot's do, gets that level) and to
  ``netconsole``.
  The robot's error string (setErrorData) is shown as its view's ``error_text`` on the legacy panel.
  A trailing piece with no newline is shown as a line of its own (a cRIO's printf may cut
  a line in two: no buffering, nothing is held back).

Decisions the sources leave open: the dashboard's "reply packets" counts the robot's replies
received; its error bit field is always zero; its user and error data copy the robot's.
"""

from __future__ import annotations

from typing import Any

from protocol.enums import AllianceStation, Mode
from protocol.errors import ProtocolError
from protocol.legacy import (DEFAULT_DS_VERSION, EMPTY_LEGACY_JOYSTICK, NO_CODE_BATTERY,
                             LegacyControlPacket, LegacyDashboardPacket, LegacyJoystick,
                             LegacyStatusPacket, decode_legacy_status, decode_netconsole)
from protocol.rio_to_ds import StatusPacket

from .core import Action, Address, CommandError, Datagram, LinkStats, Stream
from .views import LegacyView

ROBOT = "robot"
DASHBOARD = "dashboard"
NETCONSOLE = "netconsole"

DIGITAL_INPUTS = 8
ANALOG_INPUTS = 4
ANALOG_MAX = 1023
LEGACY_JOYSTICKS = 4
LEGACY_AXES = 6
LEGACY_BUTTONS = 12
NETCONSOLE_LINES = 500
#: Lines taken from one NetConsole datagram (the rest are counted in ``netconsole_dropped``).
MAX_LINES_PER_DATAGRAM = 200
MAX_LINE = 4096

#: (link, direction) -> protocol kind, for the DS's RoleSpec in 2010 mode.
KINDS = {
    (ROBOT, "out"): "legacy-ds-to-robot", (ROBOT, "in"): "legacy-robot-to-ds",
    (DASHBOARD, "out"): "legacy-dashboard", (NETCONSOLE, "in"): "legacy-netconsole",
}


def _check_int(value: Any, what: str, lo: int, hi: int) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or not lo <= value <= hi:
        raise CommandError(f"{what} must be a whole number {lo}..{hi}, not {value!r}")
    return value


def _level(line: str) -> str:
    """NetConsole is plain text: a line the robot marked ``ERROR:``/``WARNING:`` gets that level."""
    head = line.lstrip()[:8].upper()
    return "error" if head.startswith("ERROR") else "warning" if head.startswith("WARNING") else "stdout"


class LegacyRobotCodec:
    """The 2010 robot link of one Driver Station, with the 2010-only state it sends.

    Plugged into ``DriverStation`` by ``roles.cores.ds.robot_codec(legacy=True)``; reached by panels
    and the field through ``ds.legacy``. Commands (run on the wire's side, e.g. with
    ``engine.call``) raise :class:`~roles.cores.core.CommandError` and change nothing when refused.
    """

    name = "2010"
    control_kind = "legacy-ds-to-robot"
    status_kind = "legacy-robot-to-ds"
    uses_tcp = False  # the cRIO protocol is UDP only
    modes = (Mode.TELEOP, Mode.AUTONOMOUS)  # no test mode in 2010

    def __init__(self, dashboard: Address | None = None, ds_version: str = DEFAULT_DS_VERSION) -> None:
        self.dashboard: Address | None = dashboard
        self.ds_version = ds_version
        # what the DS sends
        self.digital_in = 0  # bit 0 = digital input 1
        self.analog = [0] * ANALOG_INPUTS  # 0..1023
        self.last_control: LegacyControlPacket | None = None
        # what the robot sent
        self.last_status: LegacyStatusPacket | None = None
        self.replies = 0  # good status packets received
        # dashboard and NetConsole
        self.dashboard_sent = 0
        self.netconsole: Stream[tuple[float, str]] = Stream(NETCONSOLE_LINES)
        self.netconsole_dropped = 0
        self.stats = {DASHBOARD: LinkStats(DASHBOARD), NETCONSOLE: LinkStats(NETCONSOLE)}

    # -- what panels read ------------------------------------------------------------------
    @property
    def control_byte(self) -> int | None:
        """The control byte of the last packet sent to the robot."""
        return None if self.last_control is None else self.last_control.control_byte

    def view(self) -> LegacyView:
        return LegacyView(self.dashboard, self.digital_in, tuple(self.analog), self.last_control, self.last_status,
                          self.replies, self.dashboard_sent, self.netconsole.view(), self.netconsole_dropped,
                          tuple(s.view() for s in self.stats.values()))

    def snapshot(self) -> dict[str, object]:
        """The 2010 fields, JSON-able (:meth:`LegacyView.snapshot`)."""
        return self.view().snapshot()

    # -- commands --------------------------------------------------------------------------
    def set_digital_input(self, number: int, on: bool) -> None:
        """DS digital input ``number`` (1..8) on or off."""
        _check_int(number, "digital input", 1, DIGITAL_INPUTS)
        if on not in (True, False, 0, 1) or isinstance(on, float):
            raise CommandError(f"on must be true or false, not {on!r}")
        bit = 1 << (number - 1)
        self.digital_in = self.digital_in | bit if on else self.digital_in & ~bit

    def toggle_digital_input(self, number: int) -> bool:
        """Flip DS digital input ``number`` (1..8); returns its new state."""
        _check_int(number, "digital input", 1, DIGITAL_INPUTS)
        self.digital_in ^= 1 << (number - 1)
        return bool(self.digital_in >> (number - 1) & 1)

    def set_analog_input(self, number: int, value: int) -> None:
        """DS analog input ``number`` (1..4) to ``value`` (0..1023, 10 bits)."""
        _check_int(number, "analog input", 1, ANALOG_INPUTS)
        _check_int(value, "analog value", 0, ANALOG_MAX)
        self.analog[number - 1] = value

    # -- the codec seam (called by the DS core) ------------------------------------------------
    def encode_control(self, s: Any) -> bytes:
        """One 1024-byte control packet from the core's ``ControlState``."""
        sticks = []
        for j in s.joysticks[:LEGACY_JOYSTICKS]:
            axes = tuple(j.axes[:LEGACY_AXES])
            sticks.append(LegacyJoystick(axes + (0,) * (LEGACY_AXES - len(axes)),
                                         j.buttons & ((1 << LEGACY_BUTTONS) - 1)))
        sticks += [EMPTY_LEGACY_JOYSTICK] * (LEGACY_JOYSTICKS - len(sticks))
        packet = LegacyControlPacket(
            packet_index=s.sequence & 0xFFFF, reset=bool(s.reboot or s.restart), estop=bool(s.estop),
            enabled=bool(s.enabled), autonomous=s.mode is Mode.AUTONOMOUS,
            fms_attached=bool(s.fms_attached), ds_digital_in=self.digital_in, team=s.team,
            station=AllianceStation(s.station), joysticks=tuple(sticks), analog=tuple(self.analog),
            ds_version=self.ds_version)
        self.last_control = packet
        return packet.encode()

    def decode_status(self, data: bytes) -> StatusPacket:
        """Check and decode a robot reply; raises ProtocolError (size, CRC, a field)."""
        packet = decode_legacy_status(data)
        self.last_status = packet
        self.replies += 1
        volts = packet.volts
        return StatusPacket(sequence=packet.packet_index, estop=packet.estop, enabled=packet.enabled,
                            mode=Mode.AUTONOMOUS if packet.autonomous else Mode.TELEOP,
                            robot_code=not packet.no_code, battery=volts if volts is not None else 0.0)

    def after_control(self, ds: Any, now: float) -> list[Action]:
        """Called by the core after each control packet: the dashboard packet."""
        if self.dashboard is None:
            return []
        data = self._dashboard_packet(ds)
        self.dashboard_sent += 1
        self.stats[DASHBOARD].sent(len(data))
        return [Datagram(DASHBOARD, data, self.dashboard, "legacy-dashboard")]

    def _dashboard_packet(self, ds: Any) -> bytes:
        st = self.last_status if ds.link.robot_comms else None
        fields: dict[str, Any] = dict(
            packet_number=self.dashboard_sent & 0xFFFF, ds_digital_in=self.digital_in,
            ds_digital_out=st.ds_digital_out if st else 0,
            battery=tuple(st.battery) if st else NO_CODE_BATTERY,
            control=self.control_byte if self.control_byte is not None else 0x40,
            team=ds.team, ds_version=self.ds_version, reply_packets=self.replies & 0xFFFF)
        if st is not None:
            try:
                return LegacyDashboardPacket(**fields, update_number=st.update_number,
                                             user_data_high=st.user_data_high, error_text=st.error_text,
                                             user_data_low=st.user_data_low).encode()
            except ProtocolError:
                pass  # the robot's user data does not fit: send the packet without it
        return LegacyDashboardPacket(**fields).encode()

    def datagram(self, ds: Any, channel: str, data: bytes, source: Address, now: float) -> list[Action]:
        """A datagram on a channel the core does not know: NetConsole text, taken from the
        robot's host only (any port), as status is: others' are counted and dropped undecoded."""
        if channel != NETCONSOLE:
            return []
        stats = self.stats[NETCONSOLE]
        if not ds.link.is_robot(source):
            stats.foreign_packets += 1
            return []
        try:
            text = decode_netconsole(data).text
        except ProtocolError as exc:
            stats.bad(exc, now)
            return []
        stats.received(len(data), now)
        lines = [line for line in text.splitlines() if line.strip()]
        if len(lines) > MAX_LINES_PER_DATAGRAM:
            self.netconsole_dropped += len(lines) - MAX_LINES_PER_DATAGRAM
            lines = lines[-MAX_LINES_PER_DATAGRAM:]
        for line in lines:
            line = line[:MAX_LINE]
            self.netconsole.append((now, line))
            ds.add_console_line(now, _level(line), line)
        return []
