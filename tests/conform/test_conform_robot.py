"""``fieldbox conform robot`` against fieldbox's own fake roboRIO (every case passes), and
against robots that answer with garbage (verdicts with the bytes, never a traceback)."""

from __future__ import annotations

import asyncio
import socket
import sys
from pathlib import Path

import pytest

from fieldbox.conform.cases_robot import RawStick, RobotOptions, conform_robot
from fieldbox.conform.model import Verdict
from fieldbox.conform.programs import FIELDBOX_PROGRAM
from fieldbox.conform.report import html_report, text_report
from protocol.ds_to_rio import decode_control
from protocol.rio_to_ds import StatusPacket, StdoutMessage

from .conftest import loopback_free

ROOT = Path(__file__).resolve().parents[2]

ROBOT, DS = "127.99.72.2", "127.99.72.5"  # team 9972's robot and DS in the loopback plan


async def test_fieldbox_fake_roborio_passes_every_robot_case(linux_loopback, tmp_path):
    if not loopback_free((ROBOT, 1110, socket.SOCK_DGRAM), (ROBOT, 1740, socket.SOCK_STREAM),
                         (DS, 1150, socket.SOCK_DGRAM)):
        pytest.skip("team 9972's loopback ports are taken")
    launch = (f"{sys.executable} -m fieldbox --roles rio --team 9972 --robot-program {FIELDBOX_PROGRAM} "
              "--headless --no-log-files")
    run = await conform_robot(RobotOptions(ROBOT, bind=DS, launch=launch, launch_cwd=str(tmp_path)))
    report = text_report(run)
    assert [r.case.id for r in run.ordered()] == [f"R{n:02d}" for n in range(1, 25)]
    assert all(r.verdict is Verdict.PASS for r in run.ordered()), report
    assert run.peer["readback"] == "robot program reports on the DS console (TCP 1740)"
    assert run.duration < 120  # a role's cases within 2 minutes
    page = html_report(run)
    assert page.count('<span class="v pass">pass</span>') >= 19


class GarbageRobot(asyncio.DatagramProtocol):
    """Answers each control packet with bytes no robot would send: too short, or a status
    whose tag runs past its end."""

    def __init__(self) -> None:
        self.n = 0

    def connection_made(self, transport):
        self.transport = transport

    def datagram_received(self, data, addr):
        self.n += 1
        reply = data[:3] if self.n % 2 else data[:2] + bytes.fromhex("01 00 20 0c80 00 ff 01")
        self.transport.sendto(reply, (addr[0], 1150))


async def _garbage_tcp(reader, writer):
    writer.write(bytes.fromhex("ffff 0c") + b"x" * 100)  # a frame size over any bound
    await writer.drain()


async def test_a_robot_that_answers_garbage_gets_verdicts_with_the_bytes(linux_loopback):
    host, ds = "127.99.74.2", "127.99.74.5"
    if not loopback_free((host, 1110, socket.SOCK_DGRAM), (host, 1740, socket.SOCK_STREAM),
                         (ds, 1150, socket.SOCK_DGRAM)):
        pytest.skip("team 9974's loopback ports are taken")
    loop = asyncio.get_running_loop()
    transport, _ = await loop.create_datagram_endpoint(GarbageRobot, local_addr=(host, 1110))
    server = await asyncio.start_server(_garbage_tcp, host, 1740)
    try:
        run = await conform_robot(RobotOptions(host, bind=ds, wait=3.0, cases=frozenset({"R01", "R04", "R19"})))
    finally:
        transport.close()
        server.close()
    verdicts = {r.case.id: r for r in run.ordered()}
    assert set(verdicts) == {"R01", "R04", "R19"}
    assert verdicts["R01"].verdict is Verdict.FAIL
    r19 = verdicts["R19"]
    assert r19.verdict is Verdict.FAIL and "does not decode" in r19.reason
    assert r19.evidence and r19.evidence[0].direction == "received" and r19.evidence[0].kind == "rio-to-ds"
    assert "decode error" in text_report(run)


class FloodingRobot(asyncio.DatagramProtocol):
    """Answers each control packet with a 64 KB datagram (``huge``), or with a good status
    echoing it: robot code running, 12.5 V."""

    def __init__(self, huge: bool) -> None:
        self.huge = huge

    def connection_made(self, transport):
        self.transport = transport

    def datagram_received(self, data, addr):
        if self.huge:
            reply = bytes([data[0], data[1], 0x01]) + bytes(65_000 - 3)
        else:
            control = decode_control(data)
            reply = StatusPacket(control.sequence, enabled=control.enabled, mode=control.mode, estop=control.estop,
                                 robot_code=True, battery=12.5).encode()
        self.transport.sendto(reply, (addr[0], 1150))


def console_side(kind: str, handlers: set):
    """TCP 1740: a report line (so conform reads a robot program at once), then ``kind``; each
    connection's task in ``handlers``, ended by the test."""
    async def serve(reader, writer):
        handlers.add(asyncio.current_task())
        try:
            writer.write(StdoutMessage(0.0, 0, "conform {}").encode())
            if kind == "huge frame":  # 64 KB: the u16 size's largest
                writer.write(b"\xff\xff\x0c" + b"x" * 0xFFFE)
            elif kind == "endless frame":  # 16 KB announced, 1000 bytes sent, then nothing
                writer.write(b"\x40\x00\x0c" + b"x" * 999)
            await writer.drain()
            if kind == "dripping frame":  # an 18-byte frame, a byte a second
                for byte in b"\x00\x10\x0c" + b"y" * 15:
                    writer.write(bytes([byte]))
                    await writer.drain()
                    await asyncio.sleep(1.0)
            await reader.read()  # held open until conform closes it
        except (asyncio.CancelledError, ConnectionError, OSError):
            pass
        finally:
            writer.close()
    return serve


@pytest.mark.parametrize("kind, verdicts", [
    ("huge datagrams", ["R01 FAIL", "R04 n/a   Battery", "none of the", "R19 FAIL",
                        "65000 bytes, longer than any status packet"]),
    ("huge frame", ["R01 pass", "R19 FAIL", "frame of 65537 bytes is over the 32768-byte bound"]),
    ("endless frame", ["R01 pass", "R19 FAIL", "not finished (1002 bytes of it came)"]),
    ("dripping frame", ["R01 pass", "R19 FAIL", "not finished"]),
])
async def test_a_robot_that_floods_or_drips_gets_a_report_never_a_traceback(linux_loopback, kind, verdicts):
    """``conform robot`` against a robot sending 64 KB datagrams, a 64 KB TCP frame, a frame it
    never ends, or one a byte a second: a report with verdicts, exit code 1 (a failing peer),
    nothing on stderr (it printed a traceback: min() of no battery readings)."""
    host, ds = "127.99.77.2", "127.99.77.5"
    if not loopback_free((host, 1110, socket.SOCK_DGRAM), (host, 1115, socket.SOCK_DGRAM),
                         (host, 1740, socket.SOCK_STREAM), (ds, 1150, socket.SOCK_DGRAM)):
        pytest.skip("team 9977's loopback ports are taken")
    loop = asyncio.get_running_loop()
    transports = [(await loop.create_datagram_endpoint(lambda: FloodingRobot(kind == "huge datagrams"),
                                                       local_addr=(host, port)))[0] for port in (1110, 1115)]
    handlers: set[asyncio.Task] = set()
    server = await asyncio.start_server(console_side(kind, handlers), host, 1740)
    try:
        proc = await asyncio.create_subprocess_exec(
            sys.executable, "-m", "fieldbox", "conform", "robot", host, "--bind", ds, "--wait", "5",
            "--cases", "R01,R04,R05,R16,R19", cwd=ROOT, stdout=asyncio.subprocess.PIPE,
            stderr=asyncio.subprocess.PIPE)
        try:
            out, err = await asyncio.wait_for(proc.communicate(), 120)
        finally:
            if proc.returncode is None:
                proc.kill()
                await proc.wait()
    finally:
        for t in transports:
            t.close()
        server.close()
        for task in handlers:
            task.cancel()
        await asyncio.gather(*handlers, return_exceptions=True)
    report, err = out.decode(), err.decode()
    assert err == "", err
    assert proc.returncode == 1, report
    for text in verdicts:
        assert text in report, report
    assert max(len(line) for line in report.splitlines()) < 2000  # a 64 KB packet is not printed whole


class TurnsToGarbageRobot(asyncio.DatagramProtocol):
    """Answers its first 3 control packets with a good status (robot code running), then
    every one with three bytes no status packet is."""

    def __init__(self) -> None:
        self.n = 0

    def connection_made(self, transport):
        self.transport = transport

    def datagram_received(self, data, addr):
        self.n += 1
        control = decode_control(data)
        reply = StatusPacket(control.sequence, enabled=control.enabled, mode=control.mode,
                             robot_code=True, battery=12.5).encode() if self.n <= 3 else data[:3]
        self.transport.sendto(reply, (addr[0], 1150))


async def test_a_robot_with_no_answer_to_judge_is_n_a_never_0_of_0_passed(linux_loopback):
    # Issue 30: R02 passed "0 of 0 answers" against a robot that sends garbage
    host, ds = "127.99.78.2", "127.99.78.5"
    if not loopback_free((host, 1110, socket.SOCK_DGRAM), (host, 1740, socket.SOCK_STREAM),
                         (ds, 1150, socket.SOCK_DGRAM)):
        pytest.skip("team 9978's loopback ports are taken")
    loop = asyncio.get_running_loop()
    transport, _ = await loop.create_datagram_endpoint(TurnsToGarbageRobot, local_addr=(host, 1110))
    handlers: set[asyncio.Task] = set()
    server = await asyncio.start_server(console_side("quiet", handlers), host, 1740)
    try:
        run = await conform_robot(RobotOptions(host, bind=ds, wait=3.0, cases=frozenset({"R02"})))
    finally:
        transport.close()
        server.close()
        for task in handlers:
            task.cancel()
        await asyncio.gather(*handlers, return_exceptions=True)
    [r02] = run.ordered()
    report = text_report(run)
    assert r02.case.id == "R02" and r02.verdict is Verdict.NA, report
    assert "nothing to judge" in r02.reason and "do not decode: R19 says why" in r02.reason, report
    assert r02.figures["checked"] == 0 and len(r02.figures["steps_unanswered"]) == 6


async def test_a_robot_that_crashes_on_many_povs_is_reported_crashed_with_the_packet(linux_loopback, tmp_path):
    # Issue 30: no case sent more than 4 POVs, so a robot that writes past its POV array (WPILib's
    # simulator's povs[2*i]) went unseen. A robot that dies is reported as exactly that: it
    # stopped answering, how its process ended, and the packet it was sent (hex).
    host, ds = "127.99.79.2", "127.99.79.5"
    if not loopback_free((host, 1110, socket.SOCK_DGRAM), (host, 1740, socket.SOCK_STREAM),
                         (ds, 1150, socket.SOCK_DGRAM)):
        pytest.skip("team 9979's loopback ports are taken")
    launch = (f"{sys.executable} {Path(__file__).parent / 'wrong_robot.py'} crash-many-povs -- --roles rio --team 9979 "
              f"--robot-program {FIELDBOX_PROGRAM} --headless --no-log-files")
    run = await conform_robot(RobotOptions(host, bind=ds, launch=launch, launch_cwd=str(tmp_path),
                                           cases=frozenset({"R12", "R21", "R22"})))
    verdicts = {r.case.id: r for r in run.ordered()}
    report = text_report(run)
    assert verdicts["R12"].verdict is Verdict.PASS, report  # four POVs: it holds them
    r21 = verdicts["R21"]
    assert r21.verdict is Verdict.FAIL, report
    assert "the robot stopped answering after a joystick of 0 axes, 0 buttons, 13 POVs in slot 0" in r21.reason, report
    assert "its process ended, killed by SIGSEGV (signal 11)" in r21.reason, report
    first_silent, last_sent = r21.evidence
    assert first_silent.direction == "sent" and first_silent.kind == "ds-to-rio"
    tag = RawStick((), 0, 0, tuple(45 * ((3 * p + 1) % 8) for p in range(13))).tag()
    assert tag in first_silent.data[6:] and tag in last_sent.data[6:], report
    assert f"The last packet sent: {last_sent.data.hex(' ')}" in r21.reason, report
    assert last_sent.data.hex(" ") in report  # the evidence, byte by byte
    # what came after has nothing to judge, and says why
    assert verdicts["R22"].verdict is Verdict.NA and "stopped answering in R21" in verdicts["R22"].reason, report


class PickyRobot(asyncio.DatagramProtocol):
    """Answers each control packet with a good status (robot code running), except a packet
    with a joystick of more than 12 POVs or axes: no answer to that one (it ignores what it
    cannot hold, and goes on)."""

    def connection_made(self, transport):
        self.transport = transport

    def datagram_received(self, data, addr):
        control = decode_control(data)
        if any(len(j.povs) > 12 or len(j.axes) > 12 for j in control.joysticks):
            return
        reply = StatusPacket(control.sequence, enabled=control.enabled, mode=control.mode, robot_code=True,
                             battery=12.5).encode()
        self.transport.sendto(reply, (addr[0], 1150))


async def test_limits_without_a_robot_program_are_judged_on_the_answers_and_a_dropped_packet_is_no_crash(
        linux_loopback):
    # Issue 30: at and past the limits, a robot with no program to report is judged on its
    # answers; one that ignores packets it cannot hold but answers the rest has not crashed
    host, ds = "127.99.80.2", "127.99.80.5"
    if not loopback_free((host, 1110, socket.SOCK_DGRAM), (ds, 1150, socket.SOCK_DGRAM)):
        pytest.skip("team 9980's loopback ports are taken")
    loop = asyncio.get_running_loop()
    transport, _ = await loop.create_datagram_endpoint(PickyRobot, local_addr=(host, 1110))
    try:
        run = await conform_robot(RobotOptions(host, bind=ds, wait=3.0, cases=frozenset({"R20", "R21", "R22"})))
    finally:
        transport.close()
    verdicts = {r.case.id: r for r in run.ordered()}
    report = text_report(run)
    assert verdicts["R20"].verdict is Verdict.PASS and "judged on the answers alone" in verdicts["R20"].reason, report
    for cid, what in (("R21", "0 axes, 0 buttons, 13 POVs"), ("R22", "13 axes, 0 buttons, 0 POVs")):
        r = verdicts[cid]
        assert r.verdict is Verdict.FAIL, report
        assert f"25 of 25 packets with a joystick of {what} in slot 0 got no answer (packets without it are " \
               "answered)" in r.reason, report
        assert "stopped answering" not in r.reason and r.evidence[0].kind == "ds-to-rio", report
