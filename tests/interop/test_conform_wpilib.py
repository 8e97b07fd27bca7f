"""``fieldbox conform robot`` against WPILib's simulated roboRIO (robotpy with
halsim_ds_socket, headless on loopback), with the conformance RobotPy program reporting what
robot code sees on its stdout (the simulator sends nothing on TCP 1740).

The verdicts are facts about WPILib 2026 (the interop extra pins it below 2027): its POV bug
(POV i read from povs[2*i]) is a fail, and what it does right passes. The other fails are
its own too, each seen on the wire or in robot code; the comments say which line of
halsim_ds_socket (allwpilib simulation/halsim_ds_socket) does it.
"""

from __future__ import annotations

import sys

import pytest

from fieldbox.conform.cases_robot import RobotOptions, conform_robot
from fieldbox.conform.model import Verdict
from fieldbox.conform.programs import WPILIB_PROGRAM
from fieldbox.conform.report import text_report

from .test_wpilib_sim import _extension, _ports_free, _unavailable

pytestmark = pytest.mark.interop

# R23: DecodeUDP's joystickNum is unchecked, so a seventh tag goes to m_joystick_packets[6], one
# past the array: it harmed nothing robot code reads (nor its answers) in 2026.2.2.
RIGHT = ("R01", "R02", "R04", "R06", "R08", "R09", "R10", "R11", "R13", "R14", "R18", "R19", "R23")
WRONG = {
    "R03": "code initializing",  # SetupSendHeader echoes the whole control byte, FMS bit (0x08) and all
    "R07": "slot 1: 2 axes read, 0 sent",  # a slot keeps its values until a tag for it comes
    "R12": "slot 0 POV 1: robot reads 0, sent 180",  # ReadJoystickTag writes povs[i] for i += 2
    "R15": "still read itself enabled",  # its 100 ms timeout sets enabled off but never notifies new data
    "R16": "got no answer",  # it binds UDP 1110 only
    "R17": "does not latch",  # the e-stop bit is taken from each packet
    # At and past the limits (issue 30). ReadJoystickTag's povs[2*i]: at 12 POVs, the most a real
    # DS sends, POV 1 reads 0 and the writes past the 12-entry array change the stick's
    # descriptor (its type and Xbox flag).
    "R20": "slot 0 POV 1: robot reads 0, sent 45",
    "R21": "slot 0 POV 1: robot reads 0, sent 180",  # 13 POVs; 125 too, and slot 1's type changes
    # axes[i] for every axis sent: with 13 robot code reads 13 axes, the 13th 0.0 (written past
    # the 12 floats); with 251 the descriptors of slots 0-2 change
    "R22": "slot 0 axis 12: robot reads 0.0, sent 0.0787",
    # ReadJoystickDescriptionTag indexes m_joystick_packets with the slot byte unchecked: a
    # descriptor for slot 6 writes past the array into libuv's UDP handle, and the simulator
    # aborts (udp.cpp: Assertion `handle->type == UV_UDP' failed)
    "R24": "the robot stopped answering after a descriptor for slot 6 on TCP 1740",
}


async def test_conform_robot_on_wpilib_simulated_roborio(tmp_path, monkeypatch):
    extension = _extension()
    if extension is None:
        _unavailable("wpilib and robotpy-halsim-ds-socket are not installed (pip install -e '.[interop]')")
    if not _ports_free():
        _unavailable("UDP 1110 or TCP 1740 is taken on this machine: the simulator needs them")
    monkeypatch.setenv("HALSIM_EXTENSIONS", extension)
    launch = f"{sys.executable} -m robotpy --main {WPILIB_PROGRAM} run"
    # the simulator answers port 1150 of the sender's address: fieldbox's DS takes it on 127.0.0.5
    run = await conform_robot(RobotOptions("127.0.0.1", bind="127.0.0.5", launch=launch, launch_cwd=str(tmp_path),
                                           wait=60.0))
    report = text_report(run)
    verdicts = {r.case.id: r for r in run.ordered()}
    assert run.peer["readback"] == "robot program reports on its stdout", report
    for cid in RIGHT:
        assert verdicts[cid].verdict is Verdict.PASS, report
    for cid, why in WRONG.items():
        assert verdicts[cid].verdict is Verdict.FAIL and why in verdicts[cid].reason, report
    # the POV fail shows the packet sent (four POVs) and what robot code read
    r12 = verdicts["R12"]
    assert [e.kind for e in r12.evidence] == ["ds-to-rio", None]
    assert "povs\":[90,0,180,0]" in r12.evidence[1].text
    # the crash is said as that: how the process ended, and the last packet sent
    r24 = verdicts["R24"]
    assert "its process ended, killed by SIGABRT (signal 6)" in r24.reason, report
    assert "The last packet sent: " in r24.reason and r24.evidence[0].kind == "ds-to-rio-tcp", report
    # it never asks for the date, and says it is no roboRIO: not applicable, not a fail
    assert verdicts["R05"].verdict is Verdict.NA
    assert run.duration < 120
