"""The ``fieldbox conform`` subcommand: its options, and running one role's cases."""

from __future__ import annotations

import argparse
import sys
from typing import Any, Iterable, TextIO

ROLES = ("robot", "ds", "fms")

DESCRIPTION = """\
Check an implementation of one FRC role against the protocol: fieldbox plays the other side
and runs numbered cases, each naming its rule and source. Verdicts: pass, fail (with the
packets that broke the rule, explained byte by byte) or n/a (with the reason). Exit code 1
when any case fails, 2 when the run cannot start.

  robot ADDRESS   fieldbox plays the DS: control packets to ADDRESS:1110/1115, TCP 1740
  ds ADDRESS      fieldbox plays the robot (UDP 1110/1115, TCP 1740 on --robot-bind) and the
                  FMS (TCP 1750, UDP 1160 on --fms-bind); point the DS at ADDRESS's robot and FMS
  fms ADDRESS     fieldbox plays six DSes (--teams) logging in to ADDRESS:1750

Hooks (--enable, --start, --estop...): stdin:TEXT (a line to the --launch'ed program),
prompt (ask the person at this terminal), or a shell command; {station} and {team} are
filled in.
"""

EPILOG = """\
examples:
  fieldbox conform robot 10.2.54.2 --html robot.html
  fieldbox conform robot 127.0.0.1 --launch "python -m robotpy --main wpilib_robot.py run"
  fieldbox conform ds 127.2.54.5 --team 254 --robot-bind 127.2.54.2 --fms-bind 127.0.100.5 --enable prompt
  fieldbox conform fms 127.0.100.5 --teams 254,1114,2056,118,148,1678 --start prompt
"""


def add_parser(sub: Any) -> argparse.ArgumentParser:
    p = sub.add_parser("conform", help="check a DS, robot or FMS against the protocol (numbered cases, "
                                       "text/--json/--html report)",
                       description=DESCRIPTION, epilog=EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("role", choices=ROLES, help="what ADDRESS is: robot, ds or fms")
    p.add_argument("address", metavar="ADDRESS", help="the implementation under test (an IP address)")
    out = p.add_argument_group("output")
    out.add_argument("--json", action="store_true", help="print the report as one JSON object")
    out.add_argument("--html", metavar="FILE", help="also write the report as an HTML page")
    out.add_argument("-v", "--verbose", action="store_true", help="rule, source and packets for every case")
    out.add_argument("--cases", metavar="LIST", help="run only these cases (e.g. R01,R12 or D01-D03)")
    run = p.add_argument_group("running the peer")
    run.add_argument("--launch", metavar="CMD", help="start the implementation under test first (its stdout is "
                                                    "read, its stdin takes stdin: hooks); stopped at the end")
    run.add_argument("--team", type=int, default=None, metavar="N", help="the team number (ds: the DS's team)")
    run.add_argument("--station", default="R1", metavar="S", help="the alliance station R1..B3 (default R1)")
    run.add_argument("--wait", type=float, default=30.0, metavar="S",
                     help="how long the peer may take to answer at first (default 30 s)")
    robot = p.add_argument_group("robot")
    robot.add_argument("--bind", default="0.0.0.0", metavar="HOST",
                       help="the address fieldbox's DS binds UDP 1150 on (default every address)")
    robot.add_argument("--no-enable", action="store_true", dest="no_enable",
                       help="never enable the robot (the cases that need it are n/a)")
    ds = p.add_argument_group("ds")
    ds.add_argument("--robot-bind", default="0.0.0.0", metavar="HOST",
                    help="where fieldbox's robot listens (UDP 1110/1115, TCP 1740)")
    ds.add_argument("--fms-bind", default="0.0.0.0", metavar="HOST",
                    help="where fieldbox's FMS listens (TCP 1750, UDP 1160)")
    ds.add_argument("--no-fms", action="store_true", dest="no_fms", help="do not play the FMS")
    ds.add_argument("--enable", metavar="HOOK", help="how to enable the DS by hand (e.g. prompt, stdin:enable)")
    ds.add_argument("--joystick", metavar="HOOK", help="how to attach a joystick to slot 0 (e.g. prompt, "
                                                       "'stdin:axis 0 0 0.5')")
    fms = p.add_argument_group("fms")
    fms.add_argument("--teams", metavar="LIST", help="the FMS's match: six teams R1,R2,R3,B1,B2,B3")
    fms.add_argument("--ds-hosts", metavar="LIST",
                     help="six addresses of this machine for the six DSes (default on loopback: 127.TE.AM.5)")
    fms.add_argument("--spare-team", type=int, default=9999, metavar="N",
                     help="a team not in the match, for the waiting case (default 9999)")
    fms.add_argument("--start", metavar="HOOK", help="how to start the match (e.g. prompt, 'stdin:match start')")
    fms.add_argument("--abort", metavar="HOOK", help="how to abort the match (e.g. 'stdin:match abort')")
    fms.add_argument("--estop", metavar="HOOK", help="how to e-stop a station (e.g. 'stdin:estop {station} on')")
    fms.add_argument("--astop", metavar="HOOK", help="how to a-stop a station in auto (e.g. 'stdin:astop {station} on')")
    return p


def parse_cases(text: str | None, prefix: str, known: Iterable[str] | None = None) -> frozenset[str] | None:
    """``R01,R05-R07`` -> {R01, R05, R06, R07}; ValueError for anything else. With ``known``
    (the role's case ids), an id that names no case, or a range that holds none, is refused:
    a run of nothing would pass on no evidence."""
    if not text:
        return None
    known = None if known is None else frozenset(known)
    out: set[str] = set()
    for item in text.replace(" ", "").split(","):
        if not item:
            continue
        lo, _, hi = item.partition("-")
        try:
            a = int(lo.upper().lstrip(prefix))
            b = int(hi.upper().lstrip(prefix)) if hi else a
        except ValueError:
            raise ValueError(f"bad case {item!r}: use ids like {prefix}01 or ranges like {prefix}01-{prefix}05") from None
        if not 1 <= a <= b <= 99:
            raise ValueError(f"bad case range {item!r}")
        ids = {f"{prefix}{n:02d}" for n in range(a, b + 1)}
        if known is not None:
            ids &= known
            if not ids:
                raise ValueError(f"no case {item!r}: this role's cases are {_span(known)}")
        out.update(ids)
    return frozenset(out)


def _span(ids: frozenset[str]) -> str:
    ordered = sorted(ids)
    return f"{ordered[0]}-{ordered[-1]}" if ordered else "none"


def main(args: argparse.Namespace, out: TextIO | None = None, err: TextIO | None = None) -> int:
    import asyncio

    from .model import SetupError

    out = out or sys.stdout
    err = err or sys.stderr
    try:
        run = asyncio.run(execute(args, err))
    except KeyboardInterrupt:
        return 130
    except ValueError as exc:
        print(f"fieldbox conform: {exc}", file=err)
        return 2
    except SetupError as exc:
        print(f"fieldbox conform: {exc}", file=err)
        return 2
    return write_reports(run, args, out, err)


def write_reports(run: Any, args: argparse.Namespace, out: TextIO, err: TextIO) -> int:
    from .report import html_report, json_report, text_report

    code = 1 if run.any_failed else 0
    try:
        print(json_report(run) if args.json else text_report(run, args.verbose), file=out, end="", flush=True)
    except BrokenPipeError:
        pass
    if args.html:
        try:
            with open(args.html, "w", encoding="utf-8") as f:
                f.write(html_report(run))
        except OSError as exc:
            print(f"fieldbox conform: cannot write {args.html}: {exc.strerror or exc}", file=err)
            return 2
    return code


async def execute(args: argparse.Namespace, err: TextIO) -> Any:
    from protocol.enums import AllianceStation

    station = AllianceStation.parse(args.station)
    if args.role == "robot":
        from .cases_robot import CASES as ROBOT_CASES, RobotOptions, conform_robot

        opts = RobotOptions(args.address, bind=args.bind, station=station, launch=args.launch, wait=args.wait,
                            enable=not args.no_enable, cases=parse_cases(args.cases, "R", (c.id for c in ROBOT_CASES)))
        return await conform_robot(opts, err)
    if args.role == "ds":
        from .cases_ds import CASES as DS_CASES, DsOptions, conform_ds

        if args.team is None:
            raise ValueError("conform ds needs --team, the DS's team number")
        ds_opts = DsOptions(args.address, team=args.team, station=station, robot_bind=args.robot_bind,
                         fms_bind=args.fms_bind, fms=not args.no_fms, launch=args.launch, wait=args.wait,
                         enable_hook=args.enable, joystick_hook=args.joystick, cases=parse_cases(args.cases, "D", (c.id for c in DS_CASES)))
        return await conform_ds(ds_opts, err)
    from .cases_fms import CASES as FMS_CASES, FmsOptions, conform_fms

    if not args.teams:
        raise ValueError("conform fms needs --teams, the six teams of the FMS's match (R1,R2,R3,B1,B2,B3)")
    from roles.runtime.field import parse_teams

    teams = parse_teams(args.teams)
    hosts = [h.strip() for h in args.ds_hosts.split(",")] if args.ds_hosts else None
    if hosts is not None and len(hosts) != 6:
        raise ValueError("--ds-hosts needs six addresses, one a station (R1,R2,R3,B1,B2,B3)")
    fms_opts = FmsOptions(args.address, teams=teams, spare_team=args.spare_team, ds_hosts=hosts, launch=args.launch, wait=args.wait,
                      start_hook=args.start, abort_hook=args.abort, estop_hook=args.estop, astop_hook=args.astop,
                      cases=parse_cases(args.cases, "F", (c.id for c in FMS_CASES)))
    return await conform_fms(fms_opts, err)
