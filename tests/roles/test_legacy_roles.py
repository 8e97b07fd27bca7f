"""The 2010 (cRIO) mode end to end: our DS's exact bytes at the seed's offsets, our robot's
replies, CRCs both ways, bad input, NetConsole, the dashboard, a whole legacy field on the fake
clock and over real loopback sockets, and the FMS that does not run in 2010 mode."""

from __future__ import annotations

import asyncio
import logging
import time
import zlib

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from protocol import kinds as protocol_kinds
from protocol.enums import AllianceStation, Mode
from protocol.legacy import (DASHBOARD_SIZE, NO_CODE_BATTERY, LegacyControlPacket, LegacyJoystick,
                             LegacyStatusPacket, decode_legacy_control, decode_legacy_dashboard,
                             decode_legacy_status, volts_to_bcd)
from roles.cores.core import CommandError, Connect, Datagram
from roles.cores.ds import ControlState, DriverStation, robot_codec
from roles.cores.legacy_ds import LegacyRobotCodec
from roles.cores.legacy_rio import LegacyBuiltinProgram, LegacyRioWire, fake_mac
from roles.cores.rio import CODE_REBOOTING, CODE_RUNNING, Rio, RioConfig, wire_for
from roles.cores.robot_program import RobotApi
from roles.runtime.program_host import CodeHost, Message
from roles.runtime.engine import SimEngine
from roles.runtime.field import LEGACY_FMS_NOTE, Field, FieldConfig, parse_dashboard
from roles.runtime.shell import Runtime
from roles.sim.simnet import SimNetwork

from fieldbox.language import parse

ROBOT = ("127.2.94.2", 1110)
DS_ADDR = ("127.2.94.5", 1150)
ZERO4 = bytes(4)

# -- golden vectors, built by hand from the seed's table (frc_2010_protocol.txt, with the
# 0x00-0x4f control block of PROTOCOL-NOTES), not from our encoder ------------------------
# DS -> robot, team 294 at B2, enabled in autonomous, packet index 0x1234, digital inputs 1
# and 8, analog 0/512/1023/7, joystick 1: axes +1.0 -1.0 +0.5 0 0 0, buttons 1, 3 and 12.
GOLDEN_CONTROL_HEAD = bytes.fromhex(
    "1234"              # 0x00 packet index
    "70"                # 0x02 control: 0x40 not-e-stop | 0x20 enabled | 0x10 autonomous
    "81"                # 0x03 DS digital inputs 1 and 8 (bit 0 = input 1)
    "0126"              # 0x04 team 294
    "4232"              # 0x06 'B' '2'
    "7f8040000000" "0805"  # 0x08 joystick 1: int8 axes 127 -128 64 0 0 0, buttons 1, 3, 12
    "000000000000" "0000"  # 0x10 joystick 2
    "000000000000" "0000"  # 0x18 joystick 3
    "000000000000" "0000"  # 0x20 joystick 4
    "0000" "0200" "03ff" "0007"  # 0x28 analog inputs 0, 512, 1023, 7
    + "00" * 8          # 0x30 cRIO checksum
    + "00" * 16         # 0x38 FPGA checksums
    + "3130303230383030"  # 0x48 DS version "10020800"
)
assert len(GOLDEN_CONTROL_HEAD) == 0x50


def with_crc(body: bytes, crc_at: int) -> bytes:
    """Independent of protocol/: zlib's CRC-32 over the packet with the CRC field zeroed."""
    assert len(body) == crc_at
    return body + zlib.crc32(body + ZERO4).to_bytes(4, "big")


GOLDEN_CONTROL = with_crc(GOLDEN_CONTROL_HEAD + bytes(0x3FC - 0x50), 0x3FC)

# robot -> DS: our fake cRIO's reply to GOLDEN_CONTROL, battery forced to 12.34 V, a program
# that set DS digital outputs 1, 3, 6, 8 and LCD lines 1 and 6.
LCD = ["fieldbox", "", "", "", "", "line six is 21 chars!"]
GOLDEN_STATUS_HEAD = bytes.fromhex(
    "70"                # 0x00 control echo (e-stop/enabled/auto as the robot applies them)
    "1234"              # 0x01 battery 12.34 V in BCD
    "a5"                # 0x03 DS digital outputs 1, 3, 6, 8
    "00000000"          # 0x04 not documented
    "0126"              # 0x08 team 294
    "00802f100126"      # 0x0a MAC (NI's 00:80:2f block, 0x10, team)
    "3036333030383030"  # 0x10 FPGA version "06300800"
    "000000000000"      # 0x18 not documented
    "1234"              # 0x1e packet index echoed
    "00"                # 0x20 user data update number
    "00000000" "00000000" "00000000"  # 0x21 user, error and user-low lengths: all empty
)
GOLDEN_STATUS = (with_crc(GOLDEN_STATUS_HEAD + bytes(0x3FC - len(GOLDEN_STATUS_HEAD)), 0x3FC)
                 + b"\x9f\xff" + "".join(line.ljust(21) for line in LCD).encode("ascii"))


def golden_state(**kw) -> ControlState:
    from protocol.ds_to_rio import Joystick

    sticks = (Joystick((127, -128, 64, 0, 0, 0), 0x0805, 12, (90,)),) + (Joystick(),) * 3 \
        + (Joystick((5, 5), 0xFFFF, 16, ()), Joystick())  # slots 5 and 6 are not sent in 2010
    values = dict(sequence=0x1234, estop=False, fms_attached=False, enabled=True, mode=Mode.AUTONOMOUS,
                  reboot=False, restart=False, station=AllianceStation.BLUE2, team=294, countdown=None,
                  joysticks=sticks)
    values.update(kw)
    return ControlState(**values)


def golden_codec() -> LegacyRobotCodec:
    codec = LegacyRobotCodec()
    codec.set_digital_input(1, True)
    codec.set_digital_input(8, True)
    for n, v in enumerate((0, 512, 1023, 7), 1):
        codec.set_analog_input(n, v)
    return codec


def test_our_ds_control_packet_matches_the_seed_offsets_byte_for_byte():
    codec = golden_codec()
    assert codec.encode_control(golden_state()) == GOLDEN_CONTROL
    # the library reads it back as the same fields
    pkt = decode_legacy_control(GOLDEN_CONTROL)
    assert pkt.enabled and pkt.autonomous and not pkt.estop and pkt.station is AllianceStation.BLUE2
    assert pkt.joysticks[0] == LegacyJoystick((127, -128, 64, 0, 0, 0), 0x0805)
    assert [pkt.joysticks[0].pressed(b) for b in (1, 2, 3, 12)] == [True, False, True, True]


def test_control_bits_one_by_one():
    codec = LegacyRobotCodec()
    byte = lambda **kw: codec.encode_control(golden_state(**kw))[2]  # noqa: E731
    assert byte(enabled=False, mode=Mode.TELEOP) == 0x40  # normal operation: not-e-stop set
    assert byte(enabled=True, mode=Mode.TELEOP) == 0x60
    assert byte(enabled=False, mode=Mode.AUTONOMOUS) == 0x50
    assert byte(enabled=False, estop=True, mode=Mode.TELEOP) == 0x00  # e-stop: 0x40 cleared
    assert byte(enabled=False, fms_attached=True, mode=Mode.TELEOP) == 0x48
    assert byte(enabled=False, reboot=True, mode=Mode.TELEOP) == 0xC0  # reset for a reboot
    assert byte(enabled=False, restart=True, mode=Mode.TELEOP) == 0xC0  # 2010 restarts by rebooting
    data = codec.encode_control(golden_state(station=AllianceStation.RED3, team=25599))
    assert data[4:8] == b"\x63\xff" + b"R3"


def test_the_ds_core_sends_the_golden_packet_for_that_state():
    """The same bytes from a whole DS core: its joysticks, station, team and 2010 inputs."""
    ds = DriverStation(294, ROBOT, ROBOT, station=AllianceStation.BLUE2, legacy=True)
    ds.legacy.set_digital_input(1, True)
    ds.legacy.toggle_digital_input(8)
    for n, v in enumerate((0, 512, 1023, 7), 1):
        ds.legacy.set_analog_input(n, v)
    ds.set_joystick(0, 6, 12, 1, 0.0)
    for axis, value in enumerate((1.0, -1.0, 0.5)):
        ds.set_axis(0, axis, value, 0.0)
    for b in (1, 3, 12):
        ds.set_button(0, b, True, 0.0)
    ds.set_mode("auto", 0.0)
    rio = Rio(RioConfig(team=294, wire="2010"), CodeHost(), now=0.0)
    sent = []
    for k in range(10):  # a few packets so robot comms and code are up
        t = k * 0.020
        for a in ds.poll(t):
            if a.channel == "robot":
                sent.append(a)
                for r in rio.datagram("ds", a.data, DS_ADDR, t):
                    if r.channel == "ds":
                        ds.datagram("robot", r.data, ROBOT, t + 0.0005)
        rio.poll(t)
    t = 10 * 0.020
    ds.enable(t)
    packet = next(a for a in ds.poll(t) if a.channel == "robot")
    assert packet.kind == "legacy-ds-to-robot" and packet.dest == ROBOT and len(packet.data) == 1024
    index = packet.data[:2]
    assert index == (10).to_bytes(2, "big")
    assert packet.data[2:0x3FC] == GOLDEN_CONTROL[2:0x3FC]
    assert packet.data == with_crc(index + GOLDEN_CONTROL[2:0x3FC], 0x3FC)
    assert all(len(a.data) == 1024 and a.data[2] == 0x50 for a in sent)  # disabled in auto before


def golden_program(state, robot: RobotApi) -> None:
    for n in (1, 3, 6, 8):
        robot.set_digital_output(n, True)
    robot.set_lcd(1, "fieldbox")
    robot.set_lcd(6, "line six is 21 chars! and more")  # cut to 21 characters


def test_our_robot_reply_matches_the_seed_offsets_byte_for_byte():
    rio = Rio(RioConfig(team=294, wire="2010", program=golden_program), CodeHost(), now=0.0)
    rio.set_battery(12.34, 0.0)
    rio.poll(0.0)  # the program's first beat
    [reply] = rio.datagram("ds", GOLDEN_CONTROL, DS_ADDR, 0.001)
    assert reply.channel == "ds" and reply.dest == DS_ADDR and reply.kind == "legacy-robot-to-ds"
    assert len(reply.data) == 1152
    assert reply.data == GOLDEN_STATUS
    status = decode_legacy_status(reply.data)
    assert status.volts == 12.34 and status.lcd == tuple(LCD) and status.ds_digital_out == 0xA5
    assert rio.control.enabled and rio.control.mode is Mode.AUTONOMOUS


def test_no_code_battery_is_0x37_0x37_and_no_lcd():
    rio = Rio(RioConfig(team=294, wire="2010", program=golden_program), CodeHost(), now=0.0)
    rio.poll(0.0)
    rio.restart_code(0.01)  # the code is starting: no user code runs
    [reply] = rio.datagram("ds", GOLDEN_CONTROL, DS_ADDR, 0.02)
    assert len(reply.data) == 1024
    assert reply.data[1:3] == b"\x37\x37" and reply.data[0] == 0x50  # not enabled: no code
    assert reply.data[3] == 0  # no outputs without code
    status = decode_legacy_status(reply.data)
    assert status.no_code and status.volts is None and status.lcd is None
    # ... and the DS reads that as "no robot code"
    codec = LegacyRobotCodec()
    view = codec.decode_status(reply.data)
    assert view.robot_code is False and view.battery == 0.0 and view.sequence == 0x1234


def test_crc_both_ways_is_zlib_crc32_of_the_packet_with_the_field_zeroed():
    rio = Rio(RioConfig(team=294, wire="2010"), CodeHost(), now=0.0)
    [reply] = rio.datagram("ds", GOLDEN_CONTROL, DS_ADDR, 0.001)
    for data in (GOLDEN_CONTROL, reply.data):
        body = data[:0x3FC]
        assert int.from_bytes(data[0x3FC:0x400], "big") == zlib.crc32(body + ZERO4)


# -- bad input: counted and dropped on both sides --------------------------------------------
def corrupt(data: bytes, at: int) -> bytes:
    return data[:at] + bytes((data[at] ^ 0x01,)) + data[at + 1:]


def test_bad_crc_and_size_are_counted_and_dropped_by_the_robot():
    rio = Rio(RioConfig(team=294, wire="2010"), CodeHost(), now=0.0)
    link = rio.stats["ds->rio"]
    for bad in (corrupt(GOLDEN_CONTROL, 0x02), corrupt(GOLDEN_CONTROL, 0x3FF), GOLDEN_CONTROL[:-1],
                GOLDEN_CONTROL + b"\0", b""):
        assert rio.datagram("ds", bad, DS_ADDR, 0.001) == []
    assert link.bad_packets == 5 and link.packets_in == 0
    assert "crc" in link.last_error.lower() or "size" in link.last_error.lower()
    assert rio.control.ds_address is None and not rio.control.enabled and not rio.control.ds_enabled
    assert rio.datagram("ds", GOLDEN_CONTROL, DS_ADDR, 0.002)  # a good one is answered
    assert link.packets_in == 1


def test_malformed_dynamic_blocks_under_a_good_crc_keep_the_control_data():
    # GOLDEN_CONTROL's control data (enabled, autonomous) with, from 0x73, three blocks of 255
    # bytes and at 0x370 a block size of 0xff with only 135 bytes left before 0x3f8. The CRC
    # is right: the robot obeys the control data and counts the malformed block.
    body = bytearray(GOLDEN_CONTROL[:0x3FC])
    for at, block_id in ((0x73, 1), (0x172, 2), (0x271, 3)):
        body[at:at + 2] = bytes((0xFE, block_id))
    body[0x370:0x372] = b"\xff\x04"
    rio = Rio(RioConfig(team=294, wire="2010"), CodeHost(), now=0.0)
    t = 0.0
    for index in range(1, 11):
        t += 0.02
        rio.poll(t)
        body[0:2] = index.to_bytes(2, "big")
        packet = with_crc(bytes(body), 0x3FC)
        assert rio.datagram("ds", packet, DS_ADDR, t)  # answered
    assert rio.control.enabled and rio.control.mode is Mode.AUTONOMOUS
    assert rio.faults.malformed_tags == 10 and rio.stats["ds->rio"].bad_packets == 0
    # a bad CRC on the same packet still drops it
    assert rio.datagram("ds", corrupt(packet, 0x02), DS_ADDR, t + 0.001) == []
    assert rio.stats["ds->rio"].bad_packets == 1


def test_bad_crc_and_size_are_counted_and_dropped_by_the_ds():
    ds = DriverStation(294, ROBOT, ROBOT, legacy=True)
    rio = Rio(RioConfig(team=294, wire="2010"), CodeHost(), now=0.0)
    [reply] = rio.datagram("ds", GOLDEN_CONTROL, DS_ADDR, 0.001)
    for bad in (corrupt(reply.data, 0x01), corrupt(reply.data, 0x3FC), reply.data[:1024 - 1],
                reply.data + bytes(76), reply.data + b"\0" * 200):
        assert ds.datagram("robot", bad, ROBOT, 0.01) == []
    assert ds.stats["rio->ds"].bad_packets == 5
    assert not ds.link.robot_comms and ds.link.status is None and ds.legacy.replies == 0
    ds.datagram("robot", reply.data, ROBOT, 0.02)
    assert ds.link.robot_comms and ds.legacy.replies == 1


def test_netconsole_text_is_taken_from_the_robots_host_only():
    # Issue 27: every port judges a datagram by its source first. A cRIO's NetConsole comes
    # from the robot's address (any port); text from anywhere else never reaches the console.
    ds = DriverStation(294, ROBOT, ROBOT, legacy=True)
    assert ds.datagram("netconsole", b"ERROR forged line\n", ("127.9.9.9", 6666), 1.0) == []
    assert ds.datagram("netconsole", bytes(65507), ("127.9.9.9", 6666), 1.0) == []
    stats = ds.legacy.stats["netconsole"]
    assert stats.foreign_packets == 2 and stats.bad_packets == 0 and not ds.legacy.netconsole
    ds.datagram("netconsole", b"real line\n", (ROBOT[0], 40000), 1.1)
    assert [text for _, text in ds.legacy.netconsole] == ["real line"] and stats.packets_in == 1


@settings(max_examples=150)
@given(data=st.binary(max_size=1300), channel=st.sampled_from(["robot", "netconsole", "dashboard", "x"]))
def test_random_bytes_never_break_the_legacy_ds(data, channel):
    ds = DriverStation(294, ROBOT, ROBOT, legacy=True)
    before = (ds.link.robot_comms, ds.enabled, ds.arbiter.estopped, ds.legacy.replies, ds.legacy.digital_in)
    assert ds.datagram(channel, data, ROBOT, 1.0) == []
    assert (ds.link.robot_comms, ds.enabled, ds.arbiter.estopped, ds.legacy.replies, ds.legacy.digital_in) == before
    if channel == "robot":
        assert ds.stats["rio->ds"].bad_packets == 1


@settings(max_examples=150)
@given(data=st.one_of(st.binary(max_size=1300), st.binary(min_size=1020, max_size=1020)
                      .map(lambda b: with_crc(b, 0x3FC) if len(b) == 0x3FC else b)))
def test_random_bytes_never_break_the_legacy_robot(data):
    rio = Rio(RioConfig(team=294, wire="2010"), CodeHost(), now=0.0)
    out = rio.datagram("ds", data, DS_ADDR, 0.001)
    link = rio.stats["ds->rio"]
    assert link.bad_packets + link.packets_in == 1
    if link.bad_packets:
        assert out == [] and rio.control.ds_address is None and not rio.control.ds_enabled


# -- the cores' seams ----------------------------------------------------------------------------
def test_the_seams_choose_the_2010_codec_and_wire():
    assert robot_codec(True).name == "2010" and robot_codec().name == "2015+"
    assert isinstance(wire_for("2010"), LegacyRioWire) and wire_for("legacy-2010").name == "2010"
    assert Rio(RioConfig(wire="2010"), CodeHost()).wire.rio is not None  # bound to its robot
    with pytest.raises(ValueError):
        wire_for("1999")


def test_a_legacy_ds_opens_no_tcp_and_has_no_test_mode():
    ds = DriverStation(294, ROBOT, ROBOT, legacy=True)
    actions = []
    t = 0.0
    while t < 5.0:
        actions += ds.poll(t)
        deadline = ds.next_deadline()
        assert deadline is not None and deadline > t - 1e-9
        t = max(deadline, t + 0.001)
    assert not any(isinstance(a, Connect) for a in actions)
    assert ds.tcp.state == "closed"
    with pytest.raises(CommandError, match="2010 protocol has no test mode"):
        ds.set_mode("test", t)
    ds.set_mode("auto", t)
    assert ds.mode is Mode.AUTONOMOUS
    with pytest.raises(CommandError):
        ds.legacy.set_digital_input(9, True)
    with pytest.raises(CommandError):
        ds.legacy.set_analog_input(1, 1024)
    assert ds.legacy.digital_in == 0 and ds.legacy.analog == [0, 0, 0, 0]


def test_robot_api_lcd_and_digital_io():
    robot = RobotApi()
    robot.set_lcd(2, "héllo\tworld" + "x" * 30)
    assert robot.lcd[1] == "h?llo?worldxxxxxxxxxx" and len(robot.lcd[1]) == 21
    robot.set_digital_output(8)
    robot.set_digital_output(1)
    robot.set_digital_output(8, False)
    assert robot.ds_digital_out == 0x01
    for bad in (lambda: robot.set_lcd(7, "x"), lambda: robot.set_digital_output(0),
                lambda: robot.set_digital_outputs(256), lambda: robot.digital_in(9)):
        with pytest.raises(ValueError):
            bad()
    robot.reset()
    assert robot.lcd is None and robot.ds_digital_out == 0
    assert fake_mac(294) == bytes.fromhex("00802f100126")


# -- a legacy field on the fake clock --------------------------------------------------------------
class LegacyField:
    def __init__(self, team=294, station=AllianceStation.BLUE2, **cfg) -> None:
        self.net = SimNetwork()
        self.packets: list[tuple] = []  # (role, link, direction, kind, data, remote, local, now)
        self.net.taps.append(lambda r: self.packets.append((r.role, r.link, r.direction, r.kind, r.data, r.remote,
                                                             r.local, r.time)))
        cfg.setdefault("roles", frozenset({"ds", "rio"}))
        self.field = Field(FieldConfig(team=team, station=station, plan="ephemeral", legacy=True, **cfg))
        self.field.start_sim(self.net)
        self.st = self.field.stations[0]
        self.ds, self.rio = self.st.ds, self.st.rio

    def run(self, seconds: float) -> None:
        self.net.run_for(seconds)

    def do(self, text: str) -> None:
        command = parse(text)
        self.net.command(self.field.host_for(command), lambda: self.field.execute(command, self.net.now))

    def sent(self, kind: str, role: str | None = None) -> list[tuple]:
        return [p for p in self.packets if p[3] == kind and p[2] == "out" and (role is None or p[0] == role)]


def test_legacy_field_enable_joysticks_estop_and_reboot_on_the_fake_clock():
    f = LegacyField()
    f.run(1.0)
    assert f.ds.link.robot_comms and f.ds.link.robot_code and f.rio.control.ds_connected
    assert f.ds.link.battery == pytest.approx(f.rio.telemetry.battery.volts, abs=0.02)  # decoded from BCD
    assert f.ds.view().legacy.battery_bytes == volts_to_bcd(round(f.ds.link.battery, 2))
    f.do("mode auto")
    f.do("enable")
    f.do("axis 0 1 -0.5")
    f.do("button 0 12 1")
    f.run(0.1)
    assert f.rio.control.enabled and f.rio.control.mode is Mode.AUTONOMOUS and f.ds.enabled
    joy = f.rio.inputs.joysticks[0]
    assert joy.axis(1) == -0.5 and joy.button(12) and joy.button_count == 12 and len(joy.axes) == 6
    assert f.rio.control.station is AllianceStation.BLUE2
    last = decode_legacy_control(f.sent("legacy-ds-to-robot")[-1][4])
    assert last.enabled and last.autonomous and last.joysticks[0].axes[1] == -64 and last.joysticks[0].buttons == 0x800
    f.do("estop")
    f.run(0.1)
    assert f.rio.control.estopped and not f.rio.control.enabled and f.ds.arbiter.estopped and f.ds.link.robot_estopped
    assert decode_legacy_control(f.sent("legacy-ds-to-robot")[-1][4]).control_byte & 0x40 == 0
    with pytest.raises(CommandError):
        f.do("enable")
    # A reboot (the reset bit) is the only way out of a 2010 e-stop: the cRIO comes back fresh.
    f.do("reboot")
    f.run(0.05)
    assert f.rio.program.code_state == CODE_REBOOTING and not f.ds.arbiter.estopped
    assert any(decode_legacy_control(p[4]).reset for p in f.sent("legacy-ds-to-robot"))
    f.run(6.0)
    assert f.rio.program.code_state == CODE_RUNNING and not f.rio.control.estopped and f.ds.link.robot_comms
    f.do("enable")
    f.run(0.1)
    assert f.rio.control.enabled
    # the packets sent during the second before the DS saw the reboot are lost, no more
    assert f.ds.link.echoes.lost_packets <= 1.0 / 0.020 + 2 and sum(s.bad_packets for s in f.ds.stats.values()) == 0


PROGRAM = """
def robot_periodic(state, robot):
    robot.set_digital_outputs(robot.ds_digital_in ^ 0xFF)
    robot.set_lcd(1, f"{state.enabled} {state.mode} {state.estop}")
    robot.set_lcd(2, f"x {state.joystick(0).axis(0):+.2f} b1 {state.joystick(0).button(1)}")
    robot.set_lcd(3, f"in3 {robot.digital_in(3)} a2 {robot.analog_in(2)}")
    if state.enabled:
        print("hello from the cRIO")
        robot.warning("low air pressure")
"""


def test_the_robot_program_sees_the_legacy_packet_and_drives_lcd_and_outputs(tmp_path):
    path = tmp_path / "robot.py"
    path.write_text(PROGRAM)
    f = LegacyField(program=str(path))
    f.run(1.0)
    assert f.ds.view().legacy.lcd[0] == "False teleop False"
    f.net.command(f.st.ds_name, lambda: (f.ds.legacy.set_digital_input(3, True),
                                         f.ds.legacy.set_analog_input(2, 777)))
    f.do("axis 0 0 1.0")
    f.do("button 0 1 1")
    f.do("enable")
    f.run(0.2)
    assert f.ds.view().legacy.lcd[:3] == ("True teleop False", "x +1.00 b1 True", "in3 True a2 777")
    assert f.ds.view().legacy.digital_out == 0xFB
    status = decode_legacy_status(f.sent("legacy-robot-to-ds")[-1][4])
    assert status.lcd[2] == "in3 True a2 777" and status.ds_digital_out == 0xFB
    f.do("estop")
    f.run(0.1)
    assert f.ds.view().legacy.lcd[0] == "False teleop True"


def test_the_built_in_2010_program_echoes_inputs_and_fills_the_lcd():
    f = LegacyField()
    assert f.rio.program.name == LegacyBuiltinProgram.__name__
    f.net.command(f.st.ds_name, lambda: f.ds.legacy.set_digital_input(2, True))
    f.run(1.0)
    assert f.ds.view().legacy.digital_out == 0x02
    assert f.ds.view().legacy.lcd[0] == "fieldbox cRIO 2010" and f.ds.view().legacy.lcd[1] == "disabled"
    assert f.ds.view().legacy.lcd[5].startswith("DIn 01000000")


def test_netconsole_text_reaches_the_ds_console(tmp_path):
    path = tmp_path / "robot.py"
    path.write_text(PROGRAM)
    f = LegacyField(program=str(path))
    f.run(1.0)
    f.do("enable")
    f.run(0.1)
    assert f.rio.netconsole_address == f.field.bound[f.st.ds_name]["netconsole"]
    console = list(f.ds.tcp.console)
    assert any(level == "stdout" and text == "hello from the cRIO" for _, level, text in console)
    assert any(level == "warning" and "low air pressure" in text for _, level, text in console)
    assert any(text == "hello from the cRIO" for _, text in f.ds.legacy.netconsole)
    nc = f.sent("legacy-netconsole")
    assert nc and all(p[0] == f.st.rio_name and p[5] == f.rio.netconsole_address for p in nc)
    arrived = [p for p in f.packets if p[3] == "legacy-netconsole" and p[2] == "in"]
    assert 0 < f.ds.legacy.stats["netconsole"].packets_in == len(arrived) <= len(nc)
    # the error string (setErrorData) carries the last warning
    assert "low air pressure" in f.ds.view().legacy.error_text


def test_without_a_field_netconsole_goes_to_the_ds_it_heard_on_port_6666():
    rio = Rio(RioConfig(team=294, wire="2010"), CodeHost(), now=0.0)
    rio.datagram("ds", GOLDEN_CONTROL, DS_ADDR, 0.001)
    rio.program_events([Message("stdout", "hi\n")], 0.0015)  # the program printed (its host said so)
    out = rio.poll(0.002)
    assert Datagram("netconsole", b"hi\n", (DS_ADDR[0], 6666), "legacy-netconsole") in out


def test_dashboard_packets_at_50_hz_with_a_good_crc():
    engine = SimEngine(FieldConfig(team=294, station=AllianceStation.BLUE2, roles=frozenset({"ds", "rio"}),
                                   legacy=True))
    dash = []
    engine.add_tap(lambda r: dash.append((r.time, r.data, r.remote, r.link))
                   if r.kind == "legacy-dashboard" else None)
    ds = engine.field.stations[0].ds
    engine.call(lambda: ds.legacy.set_digital_input(5, True), engine.field.stations[0].ds_name)
    engine.advance(2.0)
    window = [d for d in dash if 1000.5 <= d[0] < 1001.5]
    assert len(window) == 50
    assert all(link == "dashboard" and remote == ("127.0.0.1", 1165) for _, _, remote, link in dash)
    numbers = []
    for now, data, _, _ in dash:
        assert len(data) == DASHBOARD_SIZE
        assert int.from_bytes(data[0x3F6:0x3FA], "big") == zlib.crc32(data[:0x3F6] + ZERO4)
        pkt = decode_legacy_dashboard(data)  # checks the CRC too
        numbers.append(pkt.packet_number)
        assert pkt.team == 294 and pkt.ds_digital_in == 0x10 and pkt.ds_version == "10020800"
    assert numbers == list(range(len(dash)))
    last = decode_legacy_dashboard(dash[-1][1])
    assert last.battery == ds.view().legacy.battery_bytes and last.ds_digital_out == 0x10  # the 2010 built-in echo
    assert last.reply_packets == ds.legacy.replies & 0xFFFF and last.control == 0x40
    assert ds.legacy.dashboard_sent == len(dash)
    intervals = {round(b[0] - a[0], 6) for a, b in zip(dash, dash[1:])}
    assert intervals == {0.02}


def test_dashboard_address_option():
    assert parse_dashboard(None, "127.2.94.5") == ("127.2.94.5", 1165)
    assert parse_dashboard("10.2.94.9", "x") == ("10.2.94.9", 1165)
    assert parse_dashboard("localhost:5000", "x") == ("localhost", 5000)
    assert parse_dashboard("::1", "x") == ("::1", 1165)
    assert parse_dashboard("[::1]:7", "x") == ("::1", 7)
    assert parse_dashboard("off", "x") is None
    for bad in ("host:port", "host:0", "host:70000"):
        with pytest.raises(ValueError):
            parse_dashboard(bad, "x")
    f = LegacyField(dashboard="127.0.0.9:5000")
    f.run(0.1)
    assert {p[5] for p in f.sent("legacy-dashboard")} == {("127.0.0.9", 5000)}
    f = LegacyField(dashboard="off")
    f.run(0.1)
    assert f.sent("legacy-dashboard") == [] and f.ds.legacy.dashboard is None
    # loopback plan (on the in-memory network: nothing binds): the DS's own team address
    field = Field(FieldConfig(team=294, plan="loopback", legacy=True, roles=frozenset({"ds", "rio"})))
    field.start_sim(SimNetwork())
    assert field.stations[0].ds.legacy.dashboard == ("127.2.94.5", 1165)
    assert field.bound["ds 294"] == {"robot": ("127.2.94.5", 1150), "netconsole": ("127.2.94.5", 6666),
                                     "dashboard": ("127.2.94.5", 1150)}
    assert field.bound["rio 294"] == {"ds": ("127.2.94.2", 1110), "netconsole": ("127.2.94.2", 1110)}
    # there the robot sends NetConsole to the DS it hears from, port 6666: the DS's socket
    net = SimNetwork()
    field = Field(FieldConfig(team=294, plan="loopback", legacy=True, roles=frozenset({"ds", "rio"})))
    field.start_sim(net)
    net.run_for(0.5)
    st = field.stations[0]
    assert st.rio.netconsole_address is None and st.rio.control.ds_address == ("127.2.94.5", 1150)
    assert st.ds.legacy.stats["netconsole"].packets_in > 0
    assert any(text.startswith("Robot program") or text.startswith("Joystick") for _, text in st.ds.legacy.netconsole)


def test_every_legacy_packet_is_tapped_with_its_kind_and_annotates():
    f = LegacyField()
    f.run(1.0)
    f.do("enable")
    f.run(0.2)
    seen = {(role.split()[0], link, d, kind) for role, link, d, kind, *_ in f.packets}
    assert seen == {
        ("ds", "robot", "out", "legacy-ds-to-robot"), ("rio", "ds", "in", "legacy-ds-to-robot"),
        ("rio", "ds", "out", "legacy-robot-to-ds"), ("ds", "robot", "in", "legacy-robot-to-ds"),
        ("ds", "dashboard", "out", "legacy-dashboard"),
        ("rio", "netconsole", "out", "legacy-netconsole"), ("ds", "netconsole", "in", "legacy-netconsole"),
    }
    for kind in {p[3] for p in f.packets}:
        data = next(p[4] for p in f.packets if p[3] == kind)
        spans = protocol_kinds.get(kind).annotate(data)
        assert protocol_kinds.coverage_gaps(spans, len(data)) == []


def test_a_corrupting_link_is_counted_on_both_sides_and_comms_stay_up():
    f = LegacyField()
    count = {"robot": 0, "ds": 0}

    def flip_every_tenth(host, link, dest, data, now):
        if link in count and len(data) >= 1024:  # the DS's robot link, the robot's DS link
            count[link] += 1
            if count[link] % 10 == 0:
                return [(0.0, corrupt(data, 0x10))]
        return [(0.0, data)]

    f.net.filters.append(flip_every_tenth)
    f.run(2.0)
    assert f.ds.link.robot_comms and f.rio.control.ds_connected
    assert f.rio.stats["ds->rio"].bad_packets > 0 and f.ds.stats["rio->ds"].bad_packets > 0
    assert f.ds.snapshot()["bad_packets"] == f.ds.stats["rio->ds"].bad_packets


def test_the_ds_loses_a_silent_legacy_robot():
    f = LegacyField()
    f.run(1.0)
    f.do("enable")
    f.run(0.1)
    f.net.remove(f.st.rio_name)
    f.run(1.5)
    assert not f.ds.link.robot_comms and not f.ds.enabled
    last = decode_legacy_dashboard(f.sent("legacy-dashboard")[-1][4])
    assert last.battery == NO_CODE_BATTERY and last.ds_digital_out == 0


# -- the FMS does not run in 2010 mode, and says so -----------------------------------------------
def test_the_fms_role_does_not_run_in_legacy_mode_and_says_why(caplog):
    caplog.set_level(logging.WARNING, logger="fieldbox.field")
    net = SimNetwork()
    field = Field(FieldConfig(team=294, plan="ephemeral", legacy=True))  # all three roles asked
    field.start_sim(net)
    assert field.fms is None and "fms" not in field.bound
    assert field.fms_note == LEGACY_FMS_NOTE
    assert "the 2010 field protocol is not documented" in LEGACY_FMS_NOTE
    assert LEGACY_FMS_NOTE in caplog.text
    assert field.snapshot(net.now)["fms_note"] == LEGACY_FMS_NOTE
    with pytest.raises(CommandError, match="not documented"):
        field.execute(parse("match start"), net.now)
    net.run_for(1.0)
    st = field.stations[0]
    assert st.ds.link.robot_comms and st.ds.fms.status == "off"  # DS and robot still run
    # without legacy the FMS runs as before
    assert Field(FieldConfig(team=294, plan="ephemeral")).fms_note is None


# -- real sockets ------------------------------------------------------------------------------------
async def _wait(predicate, timeout=20.0):
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if predicate():
            return True
        await asyncio.sleep(0.02)
    return predicate()


async def test_a_legacy_ds_drives_a_legacy_robot_over_loopback_sockets():
    runtime = Runtime()
    taps = []
    runtime.taps.append(lambda r: taps.append((r.role, r.link, r.direction, r.kind, len(r.data))))
    field = Field(FieldConfig(team=294, plan="ephemeral", legacy=True, roles=frozenset({"ds", "rio"})))
    try:
        await field.start(runtime)
        runtime.start()
        st = field.stations[0]
        ds, rio = st.ds, st.rio

        def do(text):
            command = parse(text)
            field.execute(command, runtime.clock())
            runtime.hosts[field.host_for(command)].kick()

        assert await _wait(lambda: ds.link.robot_comms and ds.link.robot_code)
        # the battery, decoded at the DS from two BCD bytes
        assert ds.view().legacy.battery_bytes == volts_to_bcd(round(ds.link.battery, 2))
        assert abs(ds.link.battery - rio.telemetry.battery.volts) < 0.05
        do("enable")
        do("axis 0 0 0.75")
        do("button 0 2 1")
        assert await _wait(lambda: rio.control.enabled and rio.inputs.joysticks and rio.inputs.joysticks[0].button(2))
        assert rio.inputs.joysticks[0].axis(0) == pytest.approx(0.75, abs=0.01)
        do("estop")
        assert await _wait(lambda: rio.control.estopped and not rio.control.enabled)
        assert ds.arbiter.estopped and not ds.enabled
        assert await _wait(lambda: any(text == "Robot e-stopped" for _, _, text in ds.tcp.console))
        assert await _wait(lambda: ds.legacy.dashboard_sent > 10)
        kinds = {(d, kind) for _, _, d, kind, _ in taps}
        assert {("out", "legacy-ds-to-robot"), ("in", "legacy-robot-to-ds"), ("out", "legacy-dashboard"),
                ("in", "legacy-netconsole")} <= kinds
        assert all(n == 1024 for _, _, _, kind, n in taps if kind == "legacy-ds-to-robot")
        assert all(n in (1024, 1152) for _, _, _, kind, n in taps if kind == "legacy-robot-to-ds")
        assert ds.stats["rio->ds"].bad_packets == 0 and rio.stats["ds->rio"].bad_packets == 0
    finally:
        await runtime.close()


def test_legacy_status_view_keeps_the_packet_for_panels():
    codec = LegacyRobotCodec()
    data = LegacyStatusPacket(control=0x60, battery=(0x12, 0x05), ds_digital_out=3, packet_index=9,
                              error_text="ERROR: x", lcd=("a",)).encode()
    view = codec.decode_status(data)
    assert view.sequence == 9 and view.enabled and view.robot_code and view.battery == 12.05
    shown = codec.view()
    assert shown.digital_out == 3 and shown.lcd == ("a", "", "", "", "", "") and shown.error_text == "ERROR: x"
    snap = codec.snapshot()
    assert snap["battery_bytes"] == [0x12, 0x05] and snap["battery_volts"] == 12.05
    assert LegacyControlPacket().encode()[2] == 0x40


def legacy_packet(index: int, control: int) -> bytes:
    """GOLDEN_CONTROL with another packet index and control byte (CRC made again)."""
    body = index.to_bytes(2, "big") + bytes([control]) + GOLDEN_CONTROL[3:0x3FC]
    return with_crc(body, 0x3FC)


def test_nothing_late_in_2010_mode_either_but_an_estop_latches():
    # issue 16: the same rules as the 2015 wire, on the cRIO's packet index and control byte
    rio = Rio(RioConfig(team=294, wire="2010", program=golden_program), CodeHost(), now=0.0)
    rio.poll(0.0)
    rio.datagram("ds", legacy_packet(1, 0x70), DS_ADDR, 0.02)  # enabled in auto
    assert rio.control.enabled
    # a disable that waited 150 ms in the socket: answered, not obeyed
    [reply] = rio.datagram("ds", legacy_packet(2, 0x50), DS_ADDR, 0.04, arrived=0.04 - 0.15)
    assert rio.control.enabled and rio.faults.stale_packets == 1 and reply.data[0x1E:0x20] == b"\x00\x02"
    # a stale e-stop (not-e-stop bit clear, an older index): it latches all the same
    [reply] = rio.datagram("ds", legacy_packet(0, 0x30), DS_ADDR, 0.05)
    assert rio.control.estopped and not rio.control.enabled and reply.data[0] & 0x40 == 0  # the echo says e-stopped
