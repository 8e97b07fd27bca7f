"""``fieldbox conform fms`` against fieldbox's own FMS, driven through its headless stdin
(``match start``, ``estop R1 on``...): every case passes."""

from __future__ import annotations

import socket
import sys
from pathlib import Path

import pytest

from fieldbox.conform.cases_fms import CASES, FmsConformance, FmsOptions, _host_team, conform_fms
from fieldbox.conform.hooks import Hook
from fieldbox.conform.model import Run, Verdict
from fieldbox.conform.report import text_report
from fieldbox.conform.station_ds import FakeDs, Received, team_host
from protocol.enums import AllianceStation, Mode
from protocol.fms_to_ds import FmsControlPacket

from .conftest import loopback_free, station_blind_fms

TEAMS = [9911, 9912, 9913, 9921, 9922, 9923]  # R1..B3, each DS on its own 127.99.x.5
FMS = "127.0.100.5"  # the loopback plan's FMS, where `fieldbox --roles fms` binds


async def test_fieldbox_fms_passes_every_fms_case(linux_loopback, tmp_path, monkeypatch):
    monkeypatch.setenv("PYTHONPATH", str(Path(__file__).parent.parent.parent))  # the launched FMS is this tree's
    if not loopback_free((FMS, 1750, socket.SOCK_STREAM), (FMS, 1160, socket.SOCK_DGRAM),
                         *[(team_host(t), 1121, socket.SOCK_DGRAM) for t in TEAMS]):
        pytest.skip("the FMS's or the DSes' loopback ports are taken")
    teams = ",".join(map(str, TEAMS))
    run = await conform_fms(FmsOptions(
        FMS, teams=TEAMS, launch=f"{sys.executable} -m fieldbox --roles fms --teams {teams} --headless --no-log-files",
        launch_cwd=str(tmp_path), start_hook="stdin:match start", abort_hook="stdin:match abort",
        estop_hook="stdin:estop {station} on", astop_hook="stdin:astop {station} on"))
    report = text_report(run)
    assert [r.case.id for r in run.ordered()] == [f"F{n:02d}" for n in range(1, 16)]
    assert all(r.verdict is Verdict.PASS for r in run.ordered()), report
    assert run.duration < 120


def _ds(team: int, station: int, packets: list[tuple[float, FmsControlPacket]]) -> FakeDs:
    ds = FakeDs(team, AllianceStation(station), team_host(team), FMS)
    ds.login_at = 0.0
    ds.controls.extend(Received(at, p.encode(), 1121, p, None) for at, p in packets)
    return ds


async def test_f09_ends_the_match_at_post_match_not_when_the_abort_hook_returned():
    # --abort prompt: the person clicks abort at 20.0 s and presses Enter at 24.0 s. Post-match
    # (disabled, e-stop cleared) began at 20.0: the e-stop held to the end of the match.
    auto, tele = Mode.AUTONOMOUS, Mode.TELEOP
    beat = [10.0 + 0.5 * i for i in range(28)]  # 10.0 .. 23.5
    watch = _ds(9921, 3, [(t, FmsControlPacket(enabled=True, mode=auto if t < 15 else tele)) if t < 20 else
                          (t, FmsControlPacket(mode=tele)) for t in beat])
    stopped = _ds(9911, 0, [(t + 0.001, FmsControlPacket(estop=t >= 11 and t < 20, mode=auto if t < 15 else tele))
                            for t in beat])
    run = Run("fms", FMS, list(CASES))
    fms = FmsConformance(FmsOptions(FMS, teams=[9911, 9921]), run)
    fms.match = {"start": 9.9, "estop": 10.8, "end": 17.0, "abort": 24.0}
    await fms.f09(stopped, watch)
    assert run.results["F09"].verdict is Verdict.PASS, run.results["F09"].reason
    # an e-stop that clears in teleop still fails
    stopped.controls.append(Received(19.2, (p := FmsControlPacket(mode=tele)).encode(), 1121, p, None))
    run.results.clear()
    await fms.f09(stopped, watch)
    assert run.results["F09"].verdict is Verdict.FAIL


async def test_f13_an_fms_that_refuses_to_start_with_its_reason_passes():
    start = Hook("start the match", "echo 'cannot start: B3 is not connected' >&2; exit 1")
    tried = await start.outcome(None)
    assert tried.ran and not tried.done and "cannot start: B3 is not connected" in tried.note
    run = Run("fms", FMS, list(CASES))
    FmsConformance(FmsOptions(FMS, teams=[9911]), run)._f13(_ds(9923, 5, []), tried, [], 0.0)
    r = run.results["F13"]
    assert r.verdict is Verdict.PASS and "refused" in r.reason and "B3 is not connected" in r.reason, r.reason


async def test_f05_on_loopback_a_good_status_is_not_applicable_and_says_why(linux_loopback):
    host = "127.99.77.5"  # an FMS of its own, out of the other tests' way
    if not loopback_free((host, 1750, socket.SOCK_STREAM)):
        pytest.skip("the port is taken")
    server = await station_blind_fms(host)
    try:
        run = Run("fms", host, list(CASES))
        fms = FmsConformance(FmsOptions(host, teams=[9911, 9923]), run)
        fms.dses = [FakeDs(9911, AllianceStation(0), team_host(9911), host),
                    FakeDs(9923, AllianceStation(5), team_host(9923), host)]
        await fms.f05()
        await fms._teardown()
    finally:
        server.close()
        await server.wait_closed()
    r = run.results["F05"]
    assert r.verdict is Verdict.NA and "10.TE.AM.x" in r.reason, r.reason


def test_f05_takes_the_team_from_the_hosts_given():
    assert [_host_team(h) for h in ("10.99.21.5", "127.1.90.5", "192.168.1.5", "10.0.5.5")] == [9921, 190, None, 5]


async def test_f15_an_fms_that_closes_a_2027_hello_without_a_reply_is_not_judged(linux_loopback):
    # Issue 29, item 4: an FMS for the NI DS only closes a connection whose first frame is not a
    # team number (as the real FMS does): the 2027 path is not there, which is not a fault.
    import asyncio

    host = "127.99.78.5"
    if not loopback_free((host, 1750, socket.SOCK_STREAM)):
        pytest.skip("the port is taken")
    firsts: list[bytes] = []

    async def ni_only(reader, writer):
        try:
            firsts.append(await reader.readexactly(3))
        except (OSError, asyncio.IncompleteReadError):
            pass
        writer.close()  # not 00 03 18: closed, no reply

    server = await asyncio.start_server(ni_only, host, 1750)
    try:
        run = Run("fms", host, list(CASES))
        fms = FmsConformance(FmsOptions(host, teams=[9911]), run)
        fms.dses = [FakeDs(9911, AllianceStation(0), team_host(9911), host)]
        await fms.f15()
        await fms._teardown()
    finally:
        server.close()
        await server.wait_closed()
    r = run.results["F15"]
    assert firsts and firsts[0][2] == 0x1e  # the hello went
    assert r.verdict is Verdict.NA and "closed the connection without a reply" in r.reason, r.reason
