"""The headless command language and the address plans (no packets sent anywhere)."""

import pytest

from protocol.enums import AllianceStation
from roles.cores import addresses
from roles.cores.commands import (Bypass, Disable, Enable, EStop, MatchControl, SetAxis, SetBattery, SetButton, SetMode,
                                  SetPov, StationEStop)

from fieldbox.language import CommandSyntaxError, Quit, parse


@pytest.mark.parametrize("line,expected", [
    ("enable", Enable()),
    ("  DISABLE  ", Disable()),
    ("estop", EStop()),
    ("mode auto", SetMode("auto")),
    ("mode teleop", SetMode("teleop")),
    ("axis 0 1 -0.5", SetAxis(0, 1, -0.5)),
    ("button 5 12 1", SetButton(5, 12, True)),
    ("pov 0 0 -1", SetPov(0, 0, -1)),
    ("match start", MatchControl("start")),
    ("match abort", MatchControl("abort")),
    ("@254 enable", Enable(team=254)),
    ("bypass B2", Bypass(AllianceStation.BLUE2, True)),
    ("estop r1 off", StationEStop(AllianceStation.RED1, False)),
    ("battery 6.5", SetBattery(6.5)),
    ("quit", Quit()),
    ("exit", Quit()),
    ("", None),
    ("# a comment", None),
])
def test_commands_parse_into_typed_values(line, expected):
    command = parse(line)
    assert command == expected and type(command) is type(expected)


@pytest.mark.parametrize("line,reason", [
    ("axis 6 0 0.5", "joystick must be 0..5"),
    ("axis 0 12 0.5", "axis must be 0..11"),
    ("axis 0 0 1.5", "axis value must be -1..1"),
    ("axis 0 0 nan", "axis value must be -1..1"),
    ("axis 0 0", "usage: axis J A VALUE"),
    ("button 0 0 1", "button must be 1..32"),
    ("button 0 1 2", "button state must be 0 or 1"),
    ("pov 0 0 360", "POV angle must be -1..359"),
    ("mode fast", "unknown mode 'fast'"),
    ("match go", "usage: match start|abort|next"),
    ("fly", "unknown command 'fly'"),
    ("@x enable", "team must be a whole number"),
    ("bypass Z9", "unknown station 'Z9'"),
    ("enable now", "unknown command 'enable now'"),
])
def test_bad_commands_say_why(line, reason):
    with pytest.raises(CommandSyntaxError) as info:
        parse(line)
    assert reason in str(info.value)


def test_address_plans():
    # docs/design.md#addresses: team 254 -> 2.54, team 1114 -> 11.14.
    assert addresses.robot_address(254, "loopback") == "127.2.54.2"
    assert addresses.ds_address(254, "loopback") == "127.2.54.5"
    assert addresses.robot_address(1114, "real") == "10.11.14.2"
    assert addresses.robot_address(9, "real") == "10.0.9.2"
    assert addresses.robot_address(254, "ephemeral") == "127.0.0.1"
    assert addresses.robot_address(254, "real", "usb") == "172.22.11.2"
    assert addresses.robot_address(254, "real", "mdns") == "roboRIO-254-FRC.local"
    assert addresses.robot_address(254, "real", "10.2.54.20") == "10.2.54.20"
    assert addresses.fms_address("loopback") == "127.0.100.5"
    assert addresses.fms_address("real") == "10.0.100.5"
    assert addresses.port(1110, "ephemeral") == 0 and addresses.port(1110, "real") == 1110
    with pytest.raises(ValueError):
        addresses.team_address(0, 2, "loopback")
    with pytest.raises(ValueError):
        addresses.team_address(25600, 2, "real")
