"""``fieldbox conform fms`` against fieldbox's own FMS, driven through its headless stdin
(``match start``, ``estop R1 on``...): every case passes."""

from __future__ import annotations

import socket
import sys

import pytest

from fieldbox.conform.cases_fms import FmsOptions, conform_fms
from fieldbox.conform.model import Verdict
from fieldbox.conform.report import text_report
from fieldbox.conform.station_ds import team_host

from .conftest import loopback_free

TEAMS = [9911, 9912, 9913, 9921, 9922, 9923]  # R1..B3, each DS on its own 127.99.x.5
FMS = "127.0.100.5"  # the loopback plan's FMS, where `fieldbox --roles fms` binds


async def test_fieldbox_fms_passes_every_fms_case(linux_loopback, tmp_path):
    if not loopback_free((FMS, 1750, socket.SOCK_STREAM), (FMS, 1160, socket.SOCK_DGRAM),
                         *[(team_host(t), 1121, socket.SOCK_DGRAM) for t in TEAMS]):
        pytest.skip("the FMS's or the DSes' loopback ports are taken")
    teams = ",".join(map(str, TEAMS))
    run = await conform_fms(FmsOptions(
        FMS, teams=TEAMS, launch=f"{sys.executable} -m fieldbox --roles fms --teams {teams} --headless --no-log-files",
        launch_cwd=str(tmp_path), start_hook="stdin:match start", abort_hook="stdin:match abort",
        estop_hook="stdin:estop {station} on", astop_hook="stdin:astop {station} on"))
    report = text_report(run)
    assert [r.case.id for r in run.ordered()] == [f"F{n:02d}" for n in range(1, 15)]
    assert all(r.verdict is Verdict.PASS for r in run.ordered()), report
    assert run.duration < 120
