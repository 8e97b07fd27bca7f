"""``fieldbox conform robot`` against fieldbox's own fake roboRIO (every case passes), and
against robots that answer with garbage (verdicts with the bytes, never a traceback)."""

from __future__ import annotations

import asyncio
import socket
import sys

import pytest

from fieldbox.conform.cases_robot import RobotOptions, conform_robot
from fieldbox.conform.model import Verdict
from fieldbox.conform.programs import FIELDBOX_PROGRAM
from fieldbox.conform.report import html_report, text_report

from .conftest import loopback_free

ROBOT, DS = "127.99.72.2", "127.99.72.5"  # team 9972's robot and DS in the loopback plan


async def test_fieldbox_fake_roborio_passes_every_robot_case(linux_loopback, tmp_path):
    if not loopback_free((ROBOT, 1110, socket.SOCK_DGRAM), (ROBOT, 1740, socket.SOCK_STREAM),
                         (DS, 1150, socket.SOCK_DGRAM)):
        pytest.skip("team 9972's loopback ports are taken")
    launch = (f"{sys.executable} -m fieldbox --roles rio --team 9972 --robot-program {FIELDBOX_PROGRAM} "
              "--headless --no-log-files")
    run = await conform_robot(RobotOptions(ROBOT, bind=DS, launch=launch, launch_cwd=str(tmp_path)))
    report = text_report(run)
    assert [r.case.id for r in run.ordered()] == [f"R{n:02d}" for n in range(1, 20)]
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
