"""The robot side of the 2010 (cRIO) protocol: the wire the fake roboRIO uses with
``RioConfig(wire="2010")`` (``roles.cores.rio.wire_for``), and a built-in program that uses the 2010 DS.

The Rio core keeps all its behaviour (watchdog, e-stop latch, code states, the 20 ms
program beat, one DS at a time); :class:`LegacyRioWire` only changes the bytes:

* DS -> robot, UDP 1110 (channel ``"ds"``): :meth:`~LegacyRioWire.decode_control` checks
  size and CRC (a bad one raises :class:`~protocol.errors.ProtocolError`: the Rio counts it on
  ``stats["ds->rio"]`` and drops it; malformed dynamic blocks under a good CRC do not: the
  control data holds, and the view carries a ``MalformedTag`` the Rio counts) and gives the
  core a plain
  :class:`~protocol.ds_to_rio.ControlPacket` view: packet index as the sequence, e-stop
  (not-e-stop bit clear), enabled, autonomous or teleop, FMS attached, the reset bit as a
  reboot request, the station, and the four joysticks (six axes, twelve buttons each). The
  robot program sees those through its ``state`` like any other, and reads the DS's digital
  and analog inputs with ``robot.digital_in(n)`` / ``robot.analog_in(n)``.
* robot -> DS, UDP 1150, in reply to each accepted packet: 1024 bytes, 1152 once the
  program wrote the LCD (``robot.set_lcd``). The control byte echoes the DS's, with its
  e-stop, enabled and autonomous bits as the robot applies them (as the 2015+ robot does:
  a robot with no code shows disabled); the battery in BCD, 0x37 0x37 while no code runs;
  the DS digital outputs (``robot.set_digital_output``); team; a MAC in NI's 00:80:2f block
  made from the team number; FPGA version 06300800; the echoed packet index; the last
  error or warning the program raised as the error string (setErrorData); CRC.
* NetConsole, UDP 6666: every console line (print, warnings, errors) as a plain-text
  datagram from channel ``"netconsole"`` to ``rio.netconsole_address`` when the field set
  it, else to the address the DS's packets come from, port 6666. A real cRIO broadcast to
  10.255.255.255: we never broadcast. Lines before any DS was heard are counted in
  ``netconsole_unsent``. There is no TCP in 2010: a TCP frame is refused.
"""

from __future__ import annotations

from typing import Any

from protocol.ds_to_rio import ControlPacket, ControlTag, Joystick, MalformedTag
from protocol.enums import AllianceStation, Mode
from protocol.errors import ProtocolError
from protocol.legacy import (CONTROL_AUTONOMOUS, CONTROL_ENABLED, CONTROL_NOT_ESTOP, NO_CODE_BATTERY,
                             PORT_NETCONSOLE, LegacyControlPacket, LegacyStatusPacket, NetConsoleText,
                             decode_legacy_control, volts_to_bcd)
from protocol.rio_to_ds import StatusPacket

from .core import Action, Datagram
from .robot_program import BuiltinProgram, ControlState, RobotApi

CHANNEL_DS = "ds"
CHANNEL_NETCONSOLE = "netconsole"
BUTTON_MASK = 0x0FFF  # twelve buttons
MAX_ERROR_TEXT = 256  # bytes of error text sent; the user data area holds 951

#: (link, direction) -> protocol kind, for the Rio's RoleSpec in 2010 mode.
KINDS = {
    (CHANNEL_DS, "in"): "legacy-ds-to-robot", (CHANNEL_DS, "out"): "legacy-robot-to-ds",
    (CHANNEL_NETCONSOLE, "out"): "legacy-netconsole",
}


def fake_mac(team: int) -> bytes:
    """A cRIO-like MAC (NI's 00:80:2f block) that tells teams apart: 00:80:2f:10:TT:TT."""
    team &= 0xFFFF
    return bytes((0x00, 0x80, 0x2F, 0x10, team >> 8, team & 0xFF))


class LegacyRioWire:
    """The 2010 wire of one fake roboRIO (``wire_for("2010")`` gives an unbound one; the
    Rio binds it to itself). Same shape as ``roles.cores.rio.RioWire``."""

    name = "2010"
    status_kind = "legacy-robot-to-ds"
    tcp_kind = ""

    def __init__(self, rio: Any = None) -> None:
        self.rio = rio
        self.mac = fake_mac(getattr(rio, "team", 0) or 0)
        self.last_control: LegacyControlPacket | None = None  # the last packet answered
        self._decoded: LegacyControlPacket | None = None
        self.error_text = ""
        self.netconsole_sent = 0
        self.netconsole_unsent = 0

    def bind(self, rio: Any) -> "LegacyRioWire":
        return LegacyRioWire(rio)

    # -- DS -> robot ---------------------------------------------------------------------
    def decode_control(self, data: bytes) -> ControlPacket:
        packet = decode_legacy_control(data)
        self._decoded = packet
        station = packet.station if isinstance(packet.station, AllianceStation) else AllianceStation.RED1
        sticks: tuple[ControlTag, ...] = tuple(Joystick(tuple(j.axes), j.buttons & BUTTON_MASK, 12, ())
                                               for j in packet.joysticks)
        if packet.blocks_malformed:
            sticks += (MalformedTag(None, packet.dynamic_padding, "a dynamic block's size runs past 0x3f7"),)
        return ControlPacket(sequence=packet.packet_index, estop=packet.estop, fms_attached=packet.fms_attached,
                             enabled=packet.enabled,
                             mode=Mode.AUTONOMOUS if packet.autonomous else Mode.TELEOP,
                             reboot_roborio=packet.reset, restart_code=False, station=station, tags=sticks)

    def ds_inputs(self) -> tuple[int, tuple[int, ...]] | None:
        """The DS's digital and analog inputs in the packet just decoded (the Rio takes them
        for the program only from a packet it obeys)."""
        packet = self._decoded
        return None if packet is None else (packet.ds_digital_in, tuple(packet.analog))

    @staticmethod
    def decode_tcp(frame: bytes) -> Any:
        raise ProtocolError("TCP", "frame", 0, "the 2010 protocol has no TCP connection")

    # -- robot -> DS ---------------------------------------------------------------------
    def encode_status(self, status: StatusPacket) -> bytes:
        """The reply to the packet just decoded."""
        rio, packet = self.rio, self._decoded
        out = rio.program.program_out  # what the program wrote, as checked (roles/runtime/program_host.py)
        if packet is not None:
            self.last_control = packet
        control = packet.control_byte if packet is not None else CONTROL_NOT_ESTOP
        control &= ~(CONTROL_NOT_ESTOP | CONTROL_ENABLED | CONTROL_AUTONOMOUS)
        control |= ((0 if status.estop else CONTROL_NOT_ESTOP) | (CONTROL_ENABLED if status.enabled else 0)
                    | (CONTROL_AUTONOMOUS if status.mode is Mode.AUTONOMOUS else 0))
        code = status.robot_code
        battery = volts_to_bcd(min(max(status.battery, 0.0), 99.99)) if code else NO_CODE_BATTERY
        lcd = out.lcd if code else None
        return LegacyStatusPacket(
            control=control, battery=battery, ds_digital_out=out.digital_out & 0xFF if code else 0,
            team=rio.team & 0xFFFF, mac=self.mac, packet_index=status.sequence & 0xFFFF,
            error_text=self.error_text if code else "",
            lcd=tuple(lcd) if lcd is not None else None).encode()

    # -- NetConsole ----------------------------------------------------------------------
    def console_actions(self, kind: str, text: str) -> list[Action]:
        rio = self.rio
        if kind != "stdout":
            label = "ERROR" if kind == "error" else "WARNING"
            text = f"{label}: {text}"
            self.error_text = text.encode("utf-8", "surrogateescape")[:MAX_ERROR_TEXT].decode(
                "utf-8", "ignore")
        if not text.endswith("\n"):
            text += "\n"
        target = rio.netconsole_address
        if target is None and rio.control.ds_address is not None:
            target = (rio.control.ds_address[0], PORT_NETCONSOLE)
        if target is None:
            self.netconsole_unsent += 1
            return []
        try:
            data = NetConsoleText(text).encode()
        except ProtocolError:
            self.netconsole_unsent += 1
            return []
        self.netconsole_sent += 1
        return [Datagram(CHANNEL_NETCONSOLE, data, target, "legacy-netconsole")]

    def snapshot(self) -> dict[str, Any]:
        c = self.last_control
        return {"mac": ":".join(f"{b:02x}" for b in self.mac),
                "control": None if c is None else c.control_byte,
                "digital_in": 0 if c is None else c.ds_digital_in,
                "analog": [0, 0, 0, 0] if c is None else list(c.analog),
                "error_text": self.error_text, "netconsole_sent": self.netconsole_sent,
                "netconsole_unsent": self.netconsole_unsent}


class LegacyBuiltinProgram(BuiltinProgram):
    """The built-in program, plus what a 2010 DS shows: the DS's digital inputs echoed to its
    digital outputs, and the LCD filled with the robot's state."""

    name = "built-in (2010)"

    def __init__(self, readout_interval: float = 0.5) -> None:
        super().__init__(readout_interval)
        self._lcd: tuple[str, ...] = ()

    def __call__(self, state: ControlState, robot: RobotApi) -> None:
        super().__call__(state, robot)
        robot.set_digital_outputs(robot.ds_digital_in & 0xFF)
        joy = state.joystick(0)
        mode = "E-STOPPED" if state.estop else (f"{state.mode} enabled" if state.enabled else "disabled")
        din = "".join("1" if robot.ds_digital_in >> k & 1 else "0" for k in range(8))
        lines = ("fieldbox cRIO 2010", mode, f"battery {state.battery:5.2f} V",
                 f"J1 x{joy.axis(0):+.2f} y{joy.axis(1):+.2f}",
                 "J1 btn " + (",".join(map(str, joy.pressed)) or "none"),
                 f"DIn {din} A1 {robot.ds_analog_in[0]}")
        if lines != self._lcd or robot.lcd is None:
            self._lcd = lines
            for n, text in enumerate(lines, 1):
                robot.set_lcd(n, text)
