"""The parts of ``fieldbox conform`` that need no peer: the report in its three forms, the
joystick comparisons, the readback of a robot program's lines, hooks and the case lists."""

from __future__ import annotations

import asyncio
import json
import re
from pathlib import Path

import pytest

from fieldbox.conform.cases_ds import CASES as DS_CASES
from fieldbox.conform.cases_ds import joystick_size_problem
from fieldbox.conform.cases_fms import CASES as FMS_CASES
from fieldbox.conform.cases_robot import CASES as ROBOT_CASES
from fieldbox.conform.cases_robot import LIBDS_JOYSTICK_TAG, expected_stick, stick_differences
from fieldbox.conform.cli import parse_cases
from fieldbox.conform.hooks import MAX_LINE, Hook, Readback
from fieldbox.conform.model import Evidence, Run, Verdict
from fieldbox.conform.report import html_report, json_report, text_report
from protocol import ds_to_rio
from protocol.ds_to_rio import Joystick
from protocol.kinds import coverage_gaps
from protocol.wire import Span
from tests.conform.wrong_ds import libds_sizes

PROTOCOL_DOC = (Path(__file__).resolve().parents[2] / "docs" / "protocol.md").read_text(encoding="utf-8")

# LibDS's 2015 control packet, a joystick of 4 axes, 12 buttons, 1 POV with size 0x0d where
# the layout needs 0x0c (LibDS src/protocols/frc_2015.c get_joystick_size; tests/test_decode_cli.py).
LIBDS_2015 = bytes.fromhex("0010 01 04 80 00 0d 0c 04 00000000 0c 0001 01 ffff")
# The same packet as a right DS writes it.
RIGHT_2015 = bytes.fromhex("0010 01 04 80 00 0c 0c 04 00000000 0c 0001 01 ffff")


def test_every_case_names_its_rule_and_a_source():
    for prefix, cases in (("R", ROBOT_CASES), ("D", DS_CASES), ("F", FMS_CASES)):
        ids = [c.id for c in cases]
        assert ids == [f"{prefix}{n:02d}" for n in range(1, len(cases) + 1)]  # numbered, in order
        for c in cases:
            assert c.title and c.rule.endswith(".") and c.sources
            # every source is a section of docs/protocol.md (the capture's too), which exists
            assert all(s.startswith(("docs/protocol.md#", "capture ")) for s in c.sources), c.id
            for s in c.sources:
                anchor = re.search(r"docs/protocol\.md#([a-z0-9-]+)", s)
                assert anchor and f'id="{anchor.group(1)}"' in PROTOCOL_DOC, (c.id, s)


def _run_with_a_fail() -> Run:
    run = Run("robot", "127.0.0.1", list(ROBOT_CASES))
    run.peer["versions"] = {"<script>alert(1)</script>": "x"}  # a peer's own words, escaped in HTML
    run.passed("R01", "100 of 100 answered", {"answered": 100, "reply_ms_median": 0.41})
    sent = ds_to_rio.ControlPacket(538, tags=(Joystick((0,), 0, 0, (90, 180, 270, 45)),)).encode()
    run.failed("R12", "slot 0 POV 1: robot reads 0, sent 180", evidence=[
        Evidence("sent", 9.2, "the control packet", "ds-to-rio", sent),
        Evidence("received", 9.5, "what robot code reads", text='conform {"povs":[90,0,180,0]} <b>')])
    run.not_applicable("R05", "the trace says it is no roboRIO")
    run.failed("R19", "a status packet does not decode", evidence=[
        Evidence("received", 1.0, "bad packet", "rio-to-ds", bytes.fromhex("0001 01 00 20 0c"))])
    run.finish()
    return run


def test_text_json_and_html_reports():
    run = _run_with_a_fail()
    text = text_report(run)
    assert "R12 FAIL  Four POVs, each in its place" in text
    assert "tags[0].povs[1] = 180" in text  # the bytes explained as fieldbox decode explains them
    assert "rule: POV i is the i-th int16" in text and "source: " in text
    assert "R05 n/a   The trace says it is no roboRIO" not in text and "R05 n/a   Asks for the date" in text
    assert "1 pass, 2 fail, 21 not applicable" in text
    data = json.loads(json_report(run))
    assert data["summary"] == {"pass": 1, "fail": 2, "n/a": 21}  # unrun cases are n/a, said why
    r12 = next(c for c in data["cases"] if c["id"] == "R12")
    packet = r12["evidence"][0]
    assert packet["kind"] == "ds-to-rio" and r12["sources"] and r12["rule"]
    spans = [Span(**s) for s in packet["spans"]]
    assert not coverage_gaps(spans, len(bytes.fromhex(packet["hex"])))  # every byte explained
    bad = next(c for c in data["cases"] if c["id"] == "R19")["evidence"][0]
    assert bad["error"] and bad["spans"][-1]["field"] == "(undecodable)"
    page = html_report(run)
    assert page.startswith("<!doctype html>") and "<script>" not in page
    assert "&lt;script&gt;alert(1)&lt;/script&gt;" in page and "&lt;b&gt;" in page
    assert 'id="R12"' in page and "tags[0].povs[1]" in page


def test_parse_cases():
    assert parse_cases("R01,R05-R07", "R") == {"R01", "R05", "R06", "R07"}
    assert parse_cases("d1-3", "D") == {"D01", "D02", "D03"}
    assert parse_cases(None, "F") is None
    for bad in ("R5-R2", "Rx", "R0"):
        with pytest.raises(ValueError):
            parse_cases(bad, "R")


def test_an_unknown_case_is_refused_before_anything_runs(capsys):
    """Issue 30: ``--cases R99`` ran nothing and exited 0, a pass on no evidence."""
    from fieldbox.cli import build_parser
    from fieldbox.conform.cli import main as conform_main
    from fieldbox.conform.cases_robot import CASES

    known = [c.id for c in CASES]
    with pytest.raises(ValueError, match="R99"):
        parse_cases("R01,R99", "R", known)
    assert parse_cases("R01-R99", "R", known) == frozenset(known)  # a range takes the cases it holds
    # the command: exit 2, the reason on stderr, no report (nothing was sent to 127.0.0.1)
    args = build_parser().parse_args(["conform", "robot", "127.0.0.1", "--cases", "R99"])
    assert conform_main(args) == 2
    out, err = capsys.readouterr()
    assert "no case 'R99'" in err and f"{known[0]}-{known[-1]}" in err and out == ""


def test_stick_comparison_names_each_difference():
    sent = Joystick((-128, 0, 127), 0b1001, 4, (90, 180))
    want = expected_stick(sent)
    assert want == {"axes": [-1.0, 0.0, 1.0], "buttons": [1, 4], "povs": [90, 180]}
    assert stick_differences(0, {"axes": [-1.0, 0.0, 1.0], "buttons": [1, 4], "povs": [90, 180]}, want) == []
    # what WPILib's 2026 simulator reads (POV i from povs[2*i])
    diffs = stick_differences(0, {"axes": [-1.0, 0.0, 1.0], "buttons": [1, 4], "povs": [90, 0]}, want)
    assert diffs == ["slot 0 POV 1: robot reads 0, sent 180"]
    # a robot program's report is the peer's: anything in it is compared, nothing raises
    assert stick_differences(2, {"axes": "lots", "povs": None}, want) == ["slot 2: the report has no axes"]
    assert stick_differences(0, {"axes": [None, 0.0, 1.0], "buttons": 7, "povs": [90, 180]}, want)


def test_joystick_size_problem_says_how_far_off():
    packet = ds_to_rio.decode_control(LIBDS_2015)
    tag = packet.tags[0]
    assert type(tag).__name__ == "MalformedTag"
    assert joystick_size_problem(tag) == ("size byte 13, but 4 axes, 12 buttons (2 bytes) and 1 POVs need 12 "
                                          "(off by +1)")
    assert libds_sizes(RIGHT_2015) == LIBDS_2015  # the wrong DS of the tests writes LibDS's byte
    # R18's packet: enabled teleop and LibDS's tag; it decodes, header and all, the tag malformed
    packet = ds_to_rio.decode_control(bytes.fromhex("000001041000") + LIBDS_JOYSTICK_TAG)
    assert packet.enabled and [type(t).__name__ for t in packet.tags] == ["MalformedTag"]


def test_readback_takes_report_lines_and_nothing_breaks_it():
    rb = Readback()
    rb.add_text(1.0, 'noise\nconform {"enabled": true, "sticks": []}\nconform {bad json\nconform [1, 2]\n', "stdout")
    rb.add_text(2.0, "conform " + "[" * 100_000, "stdout")  # deep nesting, too long a line
    rb.add_text(3.0, "x" * (MAX_LINE + 10))
    assert [r.state for r in rb.reports] == [{"enabled": True, "sticks": []}]
    assert rb.reports[0].source == "stdout" and rb.bad_reports == 2
    assert rb.reports[0].stick(3) == {} and rb.since(1.5) == []


def test_hooks():
    async def go():
        stdin_without_launch = await Hook("enable", "stdin:enable").fire(None)
        shell = await Hook("e-stop {station}", "test {station} = R2").fire(None, station="R2")
        failing = await Hook("start", "exit 3").fire(None)
        none = await Hook("start", None).fire(None)
        return stdin_without_launch, shell, failing, none
    stdin_without_launch, shell, failing, none = asyncio.run(go())
    assert stdin_without_launch == (False, "'stdin:enable' writes to a launched program's stdin: give --launch")
    assert shell[0] is True and "exit 0" in shell[1]
    assert failing[0] is False and "exit 3" in failing[1]
    assert none == (False, "no hook given to start")


def test_unrun_cases_are_not_applicable_with_a_reason():
    run = Run("ds", "x", list(DS_CASES), selected=frozenset({"D01", "D02"}))
    run.passed("D01", "ok")
    run.finish("no control packets")
    assert [(r.case.id, r.verdict, r.reason) for r in run.ordered()] == [
        ("D01", Verdict.PASS, "ok"), ("D02", Verdict.NA, "no control packets")]
    assert not run.any_failed


def test_a_timing_case_gets_a_second_try_and_a_bug_of_ours_is_na():
    import io

    from fieldbox.conform.model import judge

    run = Run("robot", "x", list(ROBOT_CASES))
    tries = []

    async def flaky():
        tries.append(1)
        (run.failed if len(tries) == 1 else run.passed)("R01", f"try {len(tries)}")

    async def wrong():
        run.failed("R16", "no answer on 1115")

    async def broken():
        raise KeyError("oops")

    err = io.StringIO()

    async def go():
        await judge(run, "R01", flaky, err, retries=1)
        await judge(run, "R16", wrong, err, retries=1)
        await judge(run, "R02", broken, err)
    asyncio.run(go())
    assert run.results["R01"].verdict is Verdict.PASS and run.results["R01"].figures["first_try"] == "fail: try 1"
    assert run.results["R16"].verdict is Verdict.FAIL and run.results["R16"].figures["first_try"].startswith("fail")
    assert run.results["R02"].verdict is Verdict.NA and "KeyError" in run.results["R02"].reason
    assert "Traceback" in err.getvalue()


def test_a_report_says_yes_and_no_not_python():
    """What the HTML report's "The peer" list and every case's figures print (seen in Chromium:
    "is roborio: True" read as Python, not as a report for a team's maintainers)."""
    from fieldbox.conform.report import figures_text

    assert figures_text({"is_roborio": True, "robot_code": False, "reply_ms": 0.5}) == \
        "is roborio yes; robot code no; reply ms 0.5"
