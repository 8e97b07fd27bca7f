"""``fieldbox conform ds`` against fieldbox's own DS (every case passes) and against
deliberately wrong DSes (tests/conform/wrong_ds.py): the matching case fails and says why."""

from __future__ import annotations

import json
import os
import socket
import subprocess
import sys
from pathlib import Path

import pytest

from fieldbox.conform.cases_ds import DsOptions, conform_ds
from fieldbox.conform.model import Verdict
from fieldbox.conform.report import text_report

from .conftest import loopback_free

HERE = Path(__file__).parent
ROOT = HERE.parent.parent
# team 9973 in the loopback plan: the DS at .5, fieldbox's robot at .2, its FMS at .100
TEAM, DS, ROBOT, FMS = 9973, "127.99.73.5", "127.99.73.2", "127.99.73.100"
DS_ARGS = f"--roles ds --team {TEAM} --robot {ROBOT} --fms {FMS} --headless --no-log-files"


def _free() -> None:
    if not loopback_free((ROBOT, 1110, socket.SOCK_DGRAM), (ROBOT, 1115, socket.SOCK_DGRAM),
                         (ROBOT, 1740, socket.SOCK_STREAM), (FMS, 1750, socket.SOCK_STREAM),
                         (FMS, 1160, socket.SOCK_DGRAM), (DS, 1150, socket.SOCK_DGRAM)):
        pytest.skip("team 9973's loopback ports are taken")


def _launch(bug: str | None) -> str:
    if bug is None:
        return f"{sys.executable} -m fieldbox {DS_ARGS}"
    return f"{sys.executable} {HERE / 'wrong_ds.py'} {bug} -- {DS_ARGS}"


def _options(bug: str | None, tmp_path: Path, **kw) -> DsOptions:
    return DsOptions(DS, team=TEAM, robot_bind=ROBOT, fms_bind=FMS, launch=_launch(bug), launch_cwd=str(tmp_path),
                     enable_hook="stdin:enable", joystick_hook="stdin:axis 0 0 0.5", **kw)


async def test_fieldbox_ds_passes_every_ds_case(linux_loopback, tmp_path):
    _free()
    run = await conform_ds(_options(None, tmp_path))
    report = text_report(run)
    assert [r.case.id for r in run.ordered()] == [f"D{n:02d}" for n in range(1, 20)]
    assert all(r.verdict is Verdict.PASS for r in run.ordered()), report
    assert run.duration < 120


# The wrong DSes are measured on what they get wrong: the cases without the FMS (D01-D08).
@pytest.mark.parametrize("bug, case, why", [
    # the keyboard joystick of `axis 0 0 0.5`: 6 axes, 12 buttons, 1 POV
    ("libds-joystick-size", "D06", "size byte 15, but 6 axes, 12 buttons (2 bytes) and 1 POVs need 14 (off by +1)"),
    ("step-two", "D02", "sequence steps are not 1"),
    ("period-25ms", "D01", "where the rule is 20 ms"),
    # issue 30: a median of 20 ms, every interval 6 ms off it: judged by its jitter against the host's own
    ("swing-14-26", "D01", "half the intervals are more than"),
    # a 2 s gap in the middle trips every robot's 100 ms watchdog: no pass for it
    ("gap-2s", "D01", "a robot disables after 100 ms without a packet"),
])
async def test_a_wrong_ds_fails_the_matching_case_and_says_why(linux_loopback, tmp_path, bug, case, why):
    _free()
    run = await conform_ds(_options(bug, tmp_path, fms=False, measure=3.0,
                                    cases=frozenset({"D01", "D02", "D03", "D04", "D05", "D06"})))
    verdicts = {r.case.id: r for r in run.ordered()}
    report = text_report(run)
    assert [cid for cid, r in verdicts.items() if r.verdict is Verdict.FAIL] == [case], report
    assert why in verdicts[case].reason, report
    if bug == "period-25ms":  # the figure that says why: 25 ms, far from 20 (never a tight timing)
        assert "median interval" in verdicts[case].reason and 23 < verdicts[case].figures["median_ms"] < 27
    assert verdicts[case].evidence and verdicts[case].evidence[0].kind == "ds-to-rio"
    others = {cid: r.verdict for cid, r in verdicts.items() if cid != case}
    if bug == "libds-joystick-size":
        # nothing after its joystick tag can be read: D05 judges only packets without one (the
        # date's, when it went out before the joystick came), or has nothing to judge
        assert others.pop("D05") in (Verdict.PASS, Verdict.NA), report
    assert all(v is Verdict.PASS for v in others.values()), report


async def test_a_ds_that_stalls_after_its_first_packet_is_judged_on_the_packets_that_came(linux_loopback,
                                                                                           tmp_path):
    # Issue 30: open-ds sends one packet, then nothing for 6 s. D01-D04 measured a fixed span
    # after the first packet: D01 and D02 were n/a, and D03 and D04 passed on 0 datagrams.
    _free()
    run = await conform_ds(_options("stall-6s", tmp_path, fms=False, measure=2.0,
                                    cases=frozenset({"D01", "D02", "D03", "D04"})))
    verdicts = {r.case.id: r for r in run.ordered()}
    report = text_report(run)
    assert all(r.verdict is Verdict.PASS for r in verdicts.values()), report
    assert verdicts["D03"].figures["datagrams"] >= 100, report  # 2 s of packets at 20 ms, all after the stall
    d01 = verdicts["D01"]
    assert d01.figures["longest_silence_s"] >= 5.0, report
    assert "the DS was silent for" in d01.reason and "measured over the packets that came after" in d01.reason
    assert int(verdicts["D04"].reason.split(" in ")[-1].split()[0]) >= 100, report  # "... in N control packets"


async def test_a_ds_that_sends_one_packet_and_no_more_gets_n_a_with_why_never_a_pass(linux_loopback, tmp_path):
    # D03 and D04 passed on 0 datagrams: a case with nothing to judge is n/a, and says why
    _free()
    run = await conform_ds(_options("one-packet", tmp_path, fms=False, measure=1.0, measure_more=1.0,
                                    cases=frozenset({"D01", "D02", "D03", "D04"})))
    verdicts = {r.case.id: r for r in run.ordered()}
    report = text_report(run)
    assert all(r.verdict is Verdict.NA for r in verdicts.values()), report
    for r in verdicts.values():
        assert f"came from {DS} in " in r.reason and "nothing to judge" in r.reason, report
    assert "no control packets came" in verdicts["D03"].reason and "(at least 50 wanted)" in verdicts["D04"].reason


async def test_a_ds_whose_enable_toggles_keeps_the_first_tries_finding(linux_loopback, tmp_path):
    # Issue 30: D10's retry fired the enable hook again, which disabled open-ds (its enable is
    # a toggle), and a true FAIL became n/a
    _free()
    run = await conform_ds(_options("toggle-stays-enabled", tmp_path, fms=False, cases=frozenset({"D10"})))
    [d10] = run.ordered()
    report = text_report(run)
    assert d10.verdict is Verdict.FAIL and "still sending enabled 3 s after the robot fell silent" in d10.reason, report
    assert d10.evidence and d10.evidence[0].kind == "ds-to-rio"


def test_the_command_line_exits_1_on_a_fail_and_writes_json_and_html(linux_loopback, tmp_path):
    _free()
    page = tmp_path / "report.html"
    result = subprocess.run(
        [sys.executable, "-m", "fieldbox", "conform", "ds", DS, "--team", str(TEAM), "--robot-bind", ROBOT,
         "--no-fms", "--cases", "D02", "--json", "--html", str(page), "--launch", _launch("step-two")],
        cwd=tmp_path, capture_output=True, text=True, timeout=120, env=dict(os.environ, PYTHONPATH=str(ROOT)))
    assert result.returncode == 1, result.stderr
    data = json.loads(result.stdout)
    assert data["role"] == "ds" and data["summary"] == {"pass": 0, "fail": 1, "n/a": 0}
    case = data["cases"][0]
    assert case["id"] == "D02" and case["verdict"] == "fail" and case["sources"]
    assert case["evidence"][0]["spans"][0]["field"] == "sequence"
    assert "D02" in page.read_text() and "<!doctype html>" in page.read_text()


def test_a_port_that_cannot_be_bound_is_exit_2(linux_loopback, tmp_path):
    result = subprocess.run([sys.executable, "-m", "fieldbox", "conform", "ds", DS, "--team", str(TEAM),
                             "--robot-bind", "192.0.2.77", "--no-fms"], cwd=tmp_path, capture_output=True,
                            text=True, timeout=60, env=dict(os.environ, PYTHONPATH=str(ROOT)))
    assert result.returncode == 2 and "cannot bind the robot side on 192.0.2.77" in result.stderr


async def test_a_ds_that_sends_udp_status_but_never_logs_in_fails_the_login_and_its_status_is_judged(
        linux_loopback, tmp_path):
    # Issue 30: LibDS never opens TCP 1750 but sends its status to the FMS; it got 11 n/a and
    # the hint "point its FMS address there", though it had found the FMS
    _free()
    run = await conform_ds(_options("udp-only-fms", tmp_path, cases=frozenset({"D11", "D13", "D14", "D15"})))
    verdicts = {r.case.id: r for r in run.ordered()}
    report = text_report(run)
    assert verdicts["D11"].verdict is Verdict.FAIL and "never opened TCP 1750" in verdicts["D11"].reason, report
    assert "UDP status packets to" in verdicts["D11"].reason and verdicts["D11"].evidence[0].kind == "ds-to-fms"
    assert verdicts["D14"].verdict is Verdict.PASS and verdicts["D15"].verdict is Verdict.PASS, report
    assert verdicts["D13"].verdict is Verdict.NA and "point its FMS address" not in verdicts["D13"].reason, report


async def test_a_ds_that_stops_sending_is_said_to_have_stopped_not_to_ignore_the_fms(linux_loopback, tmp_path):
    # Issue 30: D16 said "no control packet with the FMS bit" when the DS sent nothing at all
    _free()
    run = await conform_ds(_options("one-packet", tmp_path, cases=frozenset({"D16", "D17"})))
    report = text_report(run)
    for r in run.ordered():
        assert r.verdict is Verdict.FAIL and "sent the robot no control packet at all for" in r.reason, report
        assert "FMS bit" not in r.reason, report


async def test_a_ds_whose_date_tag_has_no_size_byte_is_told_and_d06_names_it_not_the_joystick(linux_loopback,
                                                                                               tmp_path):
    # Issue 30: LibDS's date tag has no size byte, so the robot keeps asking for the date and
    # LibDS sends the date instead of joysticks; D06 said "attach one (--joystick)" though the
    # hook had fired. D07 finds the real cause and names the date sent (the epoch); D06 says it.
    _free()
    run = await conform_ds(_options("libds-date", tmp_path, fms=False, cases=frozenset({"D06", "D07"})))
    verdicts = {r.case.id: r for r in run.ordered()}
    report = text_report(run)
    d06, d07 = verdicts["D06"], verdicts["D07"]
    assert d07.verdict is Verdict.FAIL and "the date tag has no size byte" in d07.reason, report
    assert "1970-01-00 00:00:00.000000 UTC" in d07.reason and "the epoch, 1970-01-01" in d07.reason, report
    assert "written id first too (10 03 'UTC')" in d07.reason, report
    assert d07.evidence[0].data.endswith(bytes.fromhex("0f 00000000 00 00 00 00 00 46 10 03") + b"UTC")
    assert d06.verdict is Verdict.NA and "its date tag has no size byte (D07)" in d06.reason, report
    assert "the epoch" in d06.reason and "attach one" not in d06.reason, report


async def test_an_empty_match_info_frame_fails_the_match_info_case_not_the_descriptors(linux_loopback, tmp_path):
    # Issue 30: D08 (descriptors) failed on an empty match info frame: a malformed frame is
    # filed under the case about that frame (D09), with the FMS played or not
    _free()
    run = await conform_ds(_options("empty-match-info", tmp_path, fms=False, cases=frozenset({"D08", "D09"})))
    verdicts = {r.case.id: r for r in run.ordered()}
    report = text_report(run)
    assert verdicts["D08"].verdict is Verdict.PASS, report
    d09 = verdicts["D09"]
    assert d09.verdict is Verdict.FAIL and "a match info (0x07) frame on TCP 1740 does not decode" in d09.reason
    assert d09.evidence[0].data == bytes.fromhex("000107") and d09.evidence[0].kind == "ds-to-rio-tcp", report


async def test_fieldbox_ds_logging_in_as_the_2027_ds_passes_and_its_hello_is_judged(linux_loopback, tmp_path,
                                                                                     monkeypatch):
    # Issue 29, item 4: the login case takes the 2027 DS's hello and judges its layout; the FMS
    # fieldbox plays answers it as Cheesy Arena does and sends its control where it says.
    _free()
    monkeypatch.setenv("PYTHONPATH", str(ROOT))  # the launched DS is this tree's
    opts = _options(None, tmp_path, cases=frozenset({"D09", "D11", "D12", "D16", "D17"}))
    opts.launch = f"{sys.executable} -m fieldbox {DS_ARGS} --ds-hello 2027"
    run = await conform_ds(opts)
    verdicts = {r.case.id: r for r in run.ordered()}
    report = text_report(run)
    assert verdicts["D11"].verdict is Verdict.PASS, report
    # team 9973, control to 1121 (0x0461), no flags
    assert verdicts["D11"].reason == (f"first frame 00 09 1e 04 61 00 04 {' '.join(f'{b:02x}' for b in b'9973')}: "
                                      "the 2027 DS's hello, team 9973, control to UDP 1121"), report
    assert verdicts["D16"].verdict is Verdict.PASS and verdicts["D09"].verdict is Verdict.PASS, report  # tag 32
    assert verdicts["D12"].verdict is Verdict.NA and "2027 hello" in verdicts["D12"].reason, report
    assert verdicts["D17"].verdict is Verdict.NA and "UDP 1121" in verdicts["D17"].reason, report
