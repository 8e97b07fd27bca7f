"""``fieldbox dissector`` on the 2010 (cRIO) protocol: its 1024-byte control packets with their
joysticks, dynamic blocks and CRC, the status packets with their user data and LCD lines, the
dashboard and NetConsole packets, each shown field by field as ``fieldbox decode --json`` shows
it, and what decode refuses or calls malformed shown as expert info, never a Lua error.

tshark is needed, as for tests/test_dissector.py (which has the helpers used here).
"""

from __future__ import annotations

from pathlib import Path

import pytest

from protocol.enums import AllianceStation
from protocol.legacy import (DynamicBlock, LegacyControlPacket, LegacyDashboardPacket, LegacyJoystick,
                             LegacyStatusPacket, NetConsoleText, legacy_crc, volts_to_bcd)

from .test_dissector import TSHARK, Link, compare, fieldbox_packets, frc_values, model, opaque_classes, pcap, \
    plugin, tshark_json  # noqa: F401 - plugin: the module's fixture, shared

pytestmark = pytest.mark.skipif(TSHARK is None, reason="tshark is not installed (CI installs it; "
                                "`sudo apt-get install -y tshark`, or set FIELDBOX_TSHARK)")

LEGACY = ("legacy-ds-to-robot", "legacy-robot-to-ds", "legacy-dashboard", "legacy-netconsole")
DS, ROBOT = ("10.2.94.5", 1150), ("10.2.94.2", 1110)


def frames_of(plugin: Path, path: Path) -> list[tuple[list[tuple[str, str]], list[tuple[str, str]]]]:
    return [frc_values(p["_source"]["layers"]) for p in tshark_json(plugin, path)]


def sealed(data: bytes | bytearray) -> bytes:
    """A 2010 control packet with its CRC made right again after a byte was changed."""
    data = bytearray(data)
    data[0x3FC:0x400] = legacy_crc(bytes(data), 0x3FC).to_bytes(4, "big")
    return bytes(data)


def test_a_recorded_2010_field_shows_every_field_of_every_packet_as_fieldbox_decodes_it(plugin, tmp_path):
    # A 2010 DS and cRIO on the loopback plan, enabled, a joystick moved and a button and a
    # digital input pressed halfway through: what `fieldbox --legacy-2010` puts on the wire.
    from fieldbox.capture import CaptureRing, Endpoints
    from fieldbox.pcap import write_pcap
    from roles.cores.commands import Enable, SetAxis, SetButton, ToggleDigitalInput
    from roles.runtime.field import FieldConfig

    from .app.test_capture import LoopbackSim

    engine = LoopbackSim(FieldConfig(team=294, legacy=True))
    ring = CaptureRing()
    engine.add_tap(ring.tap)
    engine.advance(1.0)
    for command in (Enable(), SetAxis(joystick=0, axis=1, value=-0.5), SetButton(joystick=0, button=3, down=True),
                    ToggleDigitalInput(number=2)):
        engine.field.execute(command, engine.now())
    engine.advance(1.0)
    ring.drain()
    path = tmp_path / "run2010.pcap"
    assert write_pcap(path, ring.packets(), Endpoints()) > 200
    for kind in LEGACY:  # every 2010 layout is walked field by field: none is shown as bytes only
        assert not opaque_classes(model(kind)), kind
    counted, fields = compare(plugin, path)  # every packet's fields equal fieldbox decode's, field by field
    assert set(counted) == set(LEGACY) and counted["legacy-ds-to-robot"] > 90 and counted["legacy-robot-to-ds"] > 90
    assert fields > 9_000  # 4 joysticks x 8, analog, version, checksums, LCD lines ... (10,088; 310 when shown as bytes)
    decoded = fieldbox_packets(path)
    shown = frames_of(plugin, path)
    last_control = max(n for n, ps in decoded.items() if ps[0]["kind"] == "legacy-ds-to-robot")
    values = shown[last_control - 1][0]
    assert ("frc.ds2010.enabled", "1") in values and ("frc.ds2010.estop", "0") in values
    assert ("frc.ds2010.team", "294") in values and ("frc.ds2010.station", str(0x5231)) in values  # "R1": RED1
    assert ("frc.ds2010.legacy_joystick.axes", "-64") in values  # -0.5 of an int8 axis
    assert ("frc.ds2010.legacy_joystick.buttons", "4") in values and ("frc.ds2010.ds_digital_in", "2") in values
    status = max(n for n, ps in decoded.items() if ps[0]["kind"] == "legacy-robot-to-ds")
    lcd = [v for k, v in shown[status - 1][0] if k == "frc.rio2010.lcd"]
    assert lcd == decoded[status][0]["fields"]["lcd"] and len(lcd) == 6 and lcd[1] == "teleop enabled" and lcd[4] == "J1 btn 3"


def every_field_set() -> list[bytes]:
    """2010 packets with every field away from its default: the layouts' corners."""
    sticks = (LegacyJoystick((-128, 127, -1, 1, 0, 64), 0x0FFF), LegacyJoystick((5,) * 6, 0x8001),
              LegacyJoystick(), LegacyJoystick((0, 0, 0, 0, 0, -7), 2))
    control = LegacyControlPacket(
        packet_index=0xBEEF, reset=True, estop=True, enabled=True, autonomous=True, fms_attached=True, resync=True,
        crio_checksum_bit=True, fpga_checksum_bit=True, ds_digital_in=0xA5, team=9999, station=AllianceStation.BLUE3,
        joysticks=sticks, analog=(0, 1, 512, 1023), crio_checksum=bytes(range(8)),
        fpga_checksums=(b"\x01\x02\x03\x04", bytes(4), b"\xff" * 4, b"abcd"), ds_version="10020801",
        unknown_0x50=b"\x07" + bytes(34),
        dynamic_blocks=(DynamicBlock(17, b"\x01\x02\x03"), DynamicBlock(200), DynamicBlock(24, bytes(range(40)))),
        dynamic_padding=b"\x00\x00\x09")  # a 0 size byte ends the blocks; then bytes kept raw
    raw_station = LegacyControlPacket(packet_index=1, station=b"ZZ", team=294)  # no station: kept as its bytes
    status = LegacyStatusPacket(
        control=0x70, battery=volts_to_bcd(12.34), ds_digital_out=0x81, unknown_0x04=b"\x01\x00\x00\x02", team=294,
        mac=bytes.fromhex("00802f1200ff"), fpga_version="06300801", packet_index=0xBEEF, update_number=7,
        user_data_high=b"\x10\x20", error_text="ERROR: Joystick 5 not found", user_data_low=b"\x00\x01",
        user_padding=b"\x00\x03", dseio_status=b"\x01" * 32, reserved=b"\x00\x00\x00\x09",
        lcd=("fieldbox", "", "line with spaces  ", "x" * 21))
    no_lcd = LegacyStatusPacket(battery=(0x37, 0x37), team=294, error_text="é ok")
    dashboard = LegacyDashboardPacket(packet_number=513, ds_digital_in=3, ds_digital_out=4, battery=volts_to_bcd(9.5),
                                      control=0x60, error_bits=2, team=294, reply_packets=258, update_number=9,
                                      user_data_high=b"\xaa", error_text="hi", user_data_low=b"\xbb\xcc")
    return [control.encode(), raw_station.encode(), status.encode(), no_lcd.encode(), dashboard.encode(),
            NetConsoleText("Joystick 0: buttons 3\n").encode()]


def udp(pairs: list[tuple[tuple[str, int], bytes]]) -> list[bytes]:
    link = Link(DS, ROBOT)
    for dst, data in pairs:
        link.udp(ROBOT if dst != ROBOT else DS, dst, data)
    return link.frames


CONSOLE = ("10.2.94.5", 6666)
DASHBOARD = ("10.2.94.5", 1165)


def test_2010_packets_with_every_field_set_show_as_fieldbox_decodes_them(plugin, tmp_path):
    control, raw_station, status, no_lcd, dashboard, console = every_field_set()
    path = tmp_path / "every.pcap"
    path.write_bytes(pcap(udp([(ROBOT, control), (ROBOT, raw_station), (DS, status), (DS, no_lcd),
                               (DASHBOARD, dashboard), (CONSOLE, console)])))
    counted, fields = compare(plugin, path)
    assert counted == {"legacy-ds-to-robot": 2, "legacy-robot-to-ds": 2, "legacy-dashboard": 1, "legacy-netconsole": 1}
    assert fields > 180  # (187)
    frames = frames_of(plugin, path)
    values = frames[0][0]
    assert ("frc.ds2010.estop", "1") in values and ("frc.ds2010.reset", "1") in values
    assert ("frc.ds2010.station", str(0x4233)) in values  # "B3": BLUE3
    assert [v for k, v in values if k == "frc.ds2010.dynamic_block.block_id"] == ["17", "200", "24"]
    assert [v for k, v in values if k == "frc.ds2010.dynamic_block.data"][:2] == ["01:02:03", ""]
    assert ("frc.ds2010.dynamic_padding", "00:00:09") in values
    assert ("frc.ds2010.station", str(0x5A5A)) in frames[1][0]  # "ZZ" names no station: its bytes, as decode keeps them
    assert ("frc.rio2010.error_text", "ERROR: Joystick 5 not found") in frames[2][0]
    assert [v for k, v in frames[2][0] if k == "frc.rio2010.lcd"] == ["fieldbox", "", "line with spaces", "x" * 21, "", ""]
    assert ("frc.dash2010.team", "294") in frames[4][0]  # sent as 2 and 94
    assert ("frc.dash2010.reply_packets", "258") in frames[4][0]  # little-endian, as the seed says


def test_a_bad_or_malformed_2010_packet_gets_expert_info_not_a_lua_error(plugin, tmp_path):
    good = LegacyControlPacket(packet_index=5, enabled=True, team=294).encode()
    bad_crc = good[:0x3FC] + bytes(4)
    bad_analog = bytearray(good)
    bad_analog[0x28:0x2A] = (1024).to_bytes(2, "big")  # a 10-bit input: decode refuses it
    # three blocks of 256 bytes, then a size byte that runs past 0x3f7: decode keeps the control
    # data and calls the rest malformed (a robot drops those blocks)
    blocks = tuple(DynamicBlock(17, bytes(254)) for _ in range(3))
    runs_past = LegacyControlPacket(packet_index=6, enabled=True, team=294, dynamic_blocks=blocks,
                                    dynamic_padding=b"\xc8\x05\x06").encode()
    lcd = bytearray(LegacyStatusPacket(team=294, lcd=("hello",)).encode())
    lcd[0x400] = 0x00  # the LCD marker is 9f ff
    dashboard = bytearray(LegacyDashboardPacket(team=294).encode())
    dashboard[0x09] = 150  # the team's last two digits cannot be 150
    path = tmp_path / "bad.pcap"
    path.write_bytes(pcap(udp([(ROBOT, bad_crc), (ROBOT, sealed(bad_analog)), (ROBOT, runs_past), (DS, bytes(lcd)),
                               (DASHBOARD, sealed_dashboard(dashboard)), (DASHBOARD, bytes(1000))])))
    decoded = fieldbox_packets(path)
    assert [("error" in decoded[n][0]) for n in range(1, 7)] == [True, True, False, True, True, True]
    counted, _ = compare(plugin, path)  # an error where decode refuses; every field of the malformed one
    assert counted == {"legacy-ds-to-robot": 3, "legacy-robot-to-ds": 1, "legacy-dashboard": 2}
    frames = frames_of(plugin, path)
    errors = [[m for name, m in experts if name == "frc.error"] for _, experts in frames]
    assert "crc: expected 0x" in errors[0][0] and "found 0x00000000" in errors[0][0]
    assert "analog[0]: 1024" in errors[1][0]
    assert not errors[2]
    malformed = [m for name, m in frames[2][1] if name == "frc.malformed"]
    assert len(malformed) == 1 and "dynamic_blocks[3]: size 200 runs past" in malformed[0]
    assert ("frc.ds2010.enabled", "1") in frames[2][0] and ("frc.ds2010.dynamic_padding", "c8:05:06") in frames[2][0]
    assert "lcd.header" in errors[3][0]
    assert "team" in errors[4][0]
    assert "size: 1000 bytes" in errors[5][0]


def sealed_dashboard(data: bytearray) -> bytes:
    data[0x3F6:0x3FA] = legacy_crc(bytes(data), 0x3F6).to_bytes(4, "big")
    return bytes(data)


def damaged_2010(seed: int, count: int) -> list[bytes]:
    """``count`` 2010 packets (every_field_set's), each with one to three bytes set and, most of
    the time, its CRC made right again so that the decoder's field checks are what is tried (a
    user data length past its area, an analog input over 1023, a team's digits, the LCD marker)."""
    from random import Random

    rng = Random(seed)
    base = every_field_set()
    where = {1024: ROBOT, 1152: DS, 1018: DASHBOARD}
    crc_at = {1024: 0x3FC, 1152: 0x3FC, 1018: 0x3F6}
    pairs = []
    for i in range(count):
        k = rng.randrange(len(base))
        data = bytearray(base[k])
        for _ in range(rng.randint(1, 3)):
            if rng.random() < 0.3:  # a length, a size or a count: where the walk can go wrong
                data[rng.choice([0x21, 0x24, 0x73, 0x74, 0x1B, 0x1E, 0x2A, 0x28])  % len(data)] = rng.randrange(256)
            else:
                data[rng.randrange(len(data))] = rng.randrange(256)
        if len(data) in crc_at and rng.random() < 0.8:
            at = crc_at[len(data)]
            data[at:at + 4] = legacy_crc(bytes(data), at).to_bytes(4, "big")
        dst = DS if k in (2, 3) else where.get(len(data), CONSOLE)
        pairs.append((dst, bytes(data)))
    return udp(pairs)


def test_damaged_2010_packets_show_as_fieldbox_decodes_them_or_as_an_error(plugin, tmp_path):
    # 300 packets with bytes set, most with a CRC that holds: each shows every field fieldbox
    # decodes from it or, where fieldbox refuses it, the plugin's error: never a Lua error.
    path = tmp_path / "damaged.pcap"
    path.write_bytes(pcap(damaged_2010(seed=2010, count=300)))
    decoded = fieldbox_packets(path)
    refused = sum("error" in ps[0] for ps in decoded.values())
    assert 30 < refused < 270  # both outcomes tried
    counted, fields = compare(plugin, path)
    assert sum(counted.values()) == 300 and len(counted) == 4 and fields > 5000
