"""The ``fieldbox`` command line.

Arguments are parsed before anything heavy is imported: ``fieldbox --help`` and
``fieldbox --version`` must answer at once, so textual, rich, pygame and the roles are
imported only by the command that needs them.
"""

from __future__ import annotations

import argparse

from . import __version__

KIND_NAMES = (
    "ds-to-rio", "rio-to-ds", "ds-to-rio-tcp", "rio-to-ds-tcp", "fms-to-ds", "ds-to-fms",
    "fms-to-ds-tcp", "ds-to-fms-tcp", "legacy-ds-to-robot", "legacy-robot-to-ds",
    "legacy-dashboard", "legacy-netconsole",
)

EPILOG = """\
examples:
  fieldbox                                   one team's DS and fake roboRIO on loopback: e e enables
  fieldbox --roles ds,rio,fms                and an FMS, which enables the robot in a match
  fieldbox --roles ds --robot 10.2.54.2      drive a real robot (or WPILib's simulator)
  fieldbox field --teams 254,1114,2056,118,148,1678   a full field of six stations
  fieldbox --headless                        no TUI: commands on stdin, status on stdout
  fieldbox decode --as ds-to-rio 00010100100004...   explain a packet byte by byte
  fieldbox decode --pcap capture.pcapng      every FRC packet of a capture, one a line
  fieldbox dissector -o frc.lua              a Wireshark plugin (tshark -X lua_script:frc.lua)
  fieldbox replay capture.pcapng             play it in the Inspector and Timeline (p pause, . step)
  fieldbox run auto.fbx --roles ds --robot 127.0.0.1 --launch "python -m robotpy run"
                                             test robot code from a script (TAP, --junit FILE)
  fieldbox logs                              the NI log files of every run: battery, modes, events
  fieldbox conform robot 10.2.54.2 --html report.html
                                             check a robot, DS or FMS against the protocol
"""


#: The run options a subcommand has no use for: its --help does not list them, and given
#: they are refused in main() with the reason.
NOT_FOR = {
    "serve": {"--headless", "--json", "--join", "--join-as"},
    "run": {"--headless", "--theme", "--join", "--join-as", "--wire"},
}


def _add_run_options(p: argparse.ArgumentParser, suppress: bool, skip: set[str] = set(),
                     own: set[str] = set()) -> None:
    """Options shared by the app, ``field``, ``serve`` and ``run`` (defaults only on the top
    parser, so a subcommand's copy never overwrites what was given before it), but ``skip``
    (refused when given) and ``own`` (the subcommand has its own, with its own meaning)."""

    def d(value):
        return argparse.SUPPRESS if suppress else value

    def option(*names: str, **kw) -> None:
        if names[0] in own:
            return
        if names[0] in skip:  # parsed, to be refused with the reason, but not listed
            kw["help"] = argparse.SUPPRESS
        p.add_argument(*names, **kw)


    option("--roles", default=d(None), metavar="LIST",
                   help="any of ds,rio,fms, comma-separated (default ds,rio: you enable the robot; "
                        "`fieldbox field` has the FMS, and F8 adds one)")
    option("--team", type=int, default=d(None), metavar="N", help="team number (default 1)")
    option("--station", default=d(None), metavar="S", help="alliance station R1..B3 (default R1)")
    option("--robot", default=d(None), metavar="ADDR",
                   help="robot address: an IP, a host name, 'usb' (172.22.11.2) or 'mdns' "
                        "(roboRIO-TEAM-FRC.local)")
    option("--fms", default=d(None), metavar="ADDR",
                   help="FMS address for the DS (with --net real: 10.0.100.5 unless --no-fms)")
    option("--no-fms", action="store_true", default=d(False), dest="no_fms",
                   help="with --net real: the DS stays off the field's FMS (a bench, not a field)")
    option("--ds-hello", choices=("ni", "2027"), default=d(None), dest="ds_hello",
                   help="how the DS logs in to an FMS: ni, as the NI Driver Station (the default), or "
                        "2027, as the 2027 FIRST Driver Station (its hello; game data in the control packet)")
    option("--net", choices=("loopback", "real", "ephemeral"), default=d(None),
                   help="address plan (default loopback: team on 127.TE.AM.x)")
    option("--teams", default=d(None), metavar="LIST",
                   help="the match's six teams, R1,R2,R3,B1,B2,B3")
    option("--legacy-2010", action="store_true", default=d(False), dest="legacy_2010",
                   help="DS and fake robot speak the 2010 (cRIO) protocol")
    option("--dashboard", default=d(None), metavar="ADDR",
                   help="with --legacy-2010: where the DS sends dashboard packets, HOST[:PORT] "
                        "(port 1165) or 'off' (default: the DS's own address)")
    option("--ds-ip-server", default=d(None), metavar="PORT", dest="ds_ip_server",
                   help="where the DS tells dashboards (Shuffleboard, Glass, Elastic, startDSClient) "
                        "the robot's address: a TCP port on 127.0.0.1 or 'off' (default 1742, as the "
                        "NI Driver Station; a full field's is the DS of --team, else R1's)")
    option("--headless", action="store_true", default=d(False),
                   help="no TUI: commands on stdin, a status line per change on stdout")
    option("--json", action="store_true", default=d(False),
                   help="with --headless: one JSON object per status line")
    option("--robot-program", default=d(None), metavar="FILE", dest="robot_program",
                   help="a Python file with robot_periodic(state, robot), run by the fake roboRIO "
                        "every 20 ms (default: the built-in program)")
    option("--theme", default=d(None), metavar="NAME",
                   help="app theme: fieldbox-dark, projector-light, alliance, or one of yours")
    option("--fault", action="append", default=d(None), metavar="SPEC",
                   help="inject a fault, e.g. ds-rio:loss=10%%,delay=30ms~10ms or ds-rio:cut "
                        "(links ds-rio, ds-rio-tcp, ds-fms, ds-fms-tcp, all; repeatable)")
    option("--log-dir", default=d(None), metavar="DIR",
                   help="where console, event and match log files go, one folder per run "
                        "(default: the user's log folder, e.g. ~/.local/state/fieldbox/log)")
    option("--no-log-files", action="store_true", default=d(False), dest="no_log_files",
                   help="write no console/event/match log files")
    option("--dslog-version", type=int, choices=(3, 4), default=d(None), dest="dslog_version",
                   help="the layout of each DS's .dslog/.dsevents files: 4, as the NI Driver Station "
                        "writes now (AdvantageScope, DSLOG-Reader; the default), or 3 (dslogparser)")
    option("--any-ds", action="store_true", default=d(False), dest="any_ds",
                   help="a fake roboRIO follows whichever DS spoke last (default: one DS at a time; "
                        "packets from a second one are counted and ignored)")
    option("--log-file", default=d(None), metavar="PATH", help="write the log here")
    option("--join", default=d(None), metavar="SOCKET",
                   help="the app joins a classroom's field (fieldbox serve --classroom) instead of running one")
    option("--join-as", default=d("driver"), metavar="SEAT", dest="join_as",
                   help="with --join: driver (a free station, else watch), observer, or teacher:KEY")
    option("--wire", choices=("process", "thread"), default=d(None),
                   help="the app: run the wire in a process of its own (default: its own "
                        "interpreter keeps the 20 ms beat while the app draws) or on a thread beside "
                        "the app (one process; the beat wavers while the app draws) "
                        "(environment: FIELDBOX_WIRE)")


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="fieldbox",
        description="An FRC field in a box: Driver Station, fake roboRIO and FMS in one app.",
        epilog=EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("--version", action="version", version=f"fieldbox {__version__}")
    _add_run_options(parser, suppress=False)
    # no COMMAND is the app itself: the usage line shows it optional
    sub = parser.add_subparsers(dest="command", metavar="[COMMAND]")

    field = sub.add_parser("field", help="a full field: six DS, six fake roboRIOs and the FMS",
                           description="The app (or --headless) with a full field: six Driver Stations, "
                                       "six fake roboRIOs and the FMS, teams from --teams (R1,R2,R3,B1,B2,B3).")
    _add_run_options(field, suppress=True)

    serve = sub.add_parser("serve", help="the app in a browser (textual-serve)",
                           description="Serve the app to browsers: each tab runs its own field, or with "
                                       "--classroom one field whose stations the tabs share, or with --replay "
                                       "FILE a capture that each tab replays.")
    _add_run_options(serve, suppress=True, skip=NOT_FOR["serve"])
    serve.add_argument("--host", default="127.0.0.1", help="address to serve on (default 127.0.0.1)")
    serve.add_argument("--port", type=int, default=8000, help="port to serve on (default 8000)")
    serve.add_argument("--public-url", default=None, metavar="URL",
                       help="the URL browsers use to reach this machine (for a classroom)")
    serve.add_argument("--no-token", action="store_true", dest="no_token",
                       help="serve without a token (default: a random one per start, printed in the "
                            "URL to open)")
    serve.add_argument("--classroom", action="store_true",
                       help="one field (with --teams) for every tab: a tab drives a free station or "
                            "watches; the teacher's URL runs the FMS and hands stations out")
    serve.add_argument("--replay", default=None, metavar="FILE",
                       help="serve a capture (pcap or pcapng) instead of a field: each tab plays it from "
                            "the start in the Inspector and Timeline, with its own pause, step and speed "
                            "(p . < > b, as fieldbox replay); no field runs")
    _add_replay_pace(serve, default=None, where=" (with --replay: how each tab starts)")
    from .serve import MAX_TABS, TABS_PER_CLIENT  # the standard library only: --help stays quick

    serve.add_argument("--max-tabs", type=int, default=MAX_TABS, metavar="N", dest="max_tabs",
                       help=f"the most tabs open at once, each a process (default {MAX_TABS}); more are refused "
                            "(with --classroom: the teacher's tabs are never refused for it)")
    serve.add_argument("--tabs-per-client", type=int, default=TABS_PER_CLIENT, metavar="N", dest="tabs_per_client",
                       help=f"the most tabs open from one address (default {TABS_PER_CLIENT})")

    run = sub.add_parser(
        "run", help="test robot code from a script of headless commands (TAP; --json, --junit FILE)",
        description="Play a script of headless commands and test steps (sleep, wait, expect) against "
                    "a field built from the same options as --headless; print each step's result; "
                    "exit 1 on the first failed step.")
    _add_run_options(run, suppress=True, skip=NOT_FOR["run"], own={"--json"})
    run.add_argument("--json", action="store_true", default=argparse.SUPPRESS,
                     help="print each step's result as one JSON object a line instead of TAP")
    run.add_argument("script", metavar="SCRIPT", help="the script: one command per line, # comments")
    run.add_argument("--launch", default=None, metavar="CMD",
                     help="start this robot program first (e.g. \"python -m robotpy --main robot.py run\"); "
                          "its output counts as console lines; it is stopped at the end")
    run.add_argument("--junit", default=None, metavar="FILE", help="also write the results as JUnit XML")

    from .conform.cli import add_parser as add_conform

    add_conform(sub)

    from .logview_cmd import add_parser as add_logs

    add_logs(sub)

    decode = sub.add_parser(
        "decode", help="explain a packet byte by byte",
        description="Decode one packet given as hex and print every field with its bytes. "
                    "For the TCP kinds, HEX is one whole frame, its u16 size included. Each line is one "
                    "packet: several lines (on stdin, say) are decoded one by one, each titled with its line.",
    )
    decode.add_argument("--as", dest="kind", default=None, choices=KIND_NAMES, metavar="KIND",
                        help="one of: " + ", ".join(KIND_NAMES))
    decode.add_argument("hex", metavar="HEX", nargs="?", default=None,
                        help="the packet as hex (spaces allowed), or - for stdin")
    decode.add_argument("--pcap", default=None, metavar="FILE",
                        help="instead: every FRC packet of a capture (pcap or pcapng: Wireshark's, tcpdump's, "
                             "fieldbox's), one a line with its time, link and kind; other packets are counted")
    decode.add_argument("--json", action="store_true",
                        help="print one JSON object (for several lines, one a line, with its \"line\"; "
                             "with --pcap, one a packet and a final {\"type\": \"summary\"})")
    dissector = sub.add_parser(
        "dissector", help="write a Wireshark Lua plugin for every FRC packet kind",
        description="Write one Wireshark Lua plugin, generated from the layouts `fieldbox decode` uses, for "
                    "every kind it knows (DS, roboRIO, FMS, FMS Lite and the 2010 protocol). Install it in "
                    "Wireshark's personal Lua plugins folder, or run `tshark -X lua_script:FILE`.")
    dissector.add_argument("-o", "--output", default=None, metavar="FILE",
                           help="write the plugin here (default: standard output)")

    replay = sub.add_parser(
        "replay", help="play a capture in the Inspector and Timeline, every byte explained",
        description="Open a pcap or pcapng capture (Wireshark's, tcpdump's, fieldbox's) in the app's Inspector "
                    "and Timeline: its packets play at their recorded pace, faster, or one at a time (p pauses, "
                    ". steps, < > change the speed). Nothing is sent: no field runs.")
    replay.add_argument("file", metavar="FILE", help="the capture")
    _add_replay_pace(replay)
    return parser


#: The paces a replay plays at (fieldbox/replay.py's < and > step through them).
REPLAY_SPEEDS = (0.1, 0.25, 0.5, 1.0, 2.0, 5.0, 10.0, 50.0)


def _add_replay_pace(parser: argparse.ArgumentParser, default: float | None = 1.0, where: str = "") -> None:
    parser.add_argument("--speed", type=float, default=default, choices=REPLAY_SPEEDS, metavar="X",
                        help=f"play X times the recorded pace (0.1 to 50; default 1){where}")
    parser.add_argument("--paused", action="store_true", help=f"open paused (. steps, p plays){where}")


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.command == "decode":
        from .decode_cmd import run_decode, run_pcap

        if args.pcap is not None:
            if args.kind is not None or args.hex is not None:
                parser.error("decode: --pcap reads packets from the capture: give no --as and no HEX")
            return run_pcap(args.pcap, as_json=args.json)
        if args.kind is None or args.hex is None:
            parser.error("decode: give --as KIND and HEX (or --pcap FILE)")
        return run_decode(args.kind, args.hex, as_json=args.json)
    if args.command == "logs":
        from .logview_cmd import run_logs

        return run_logs(args.path, print_only=args.print_only, theme=getattr(args, "theme", None))
    if args.command == "dissector":
        from .dissector import run_dissector

        return run_dissector(args.output)
    if args.command == "replay":
        from .replay import run_replay

        return run_replay(args.file, speed=args.speed, paused=args.paused, theme=args.theme)
    if args.command == "conform":
        from .conform.cli import main as run_conform

        return run_conform(args)
    refused = _refused(args)
    if refused:
        parser.error(refused)
    from .launch import run

    return run(args, parser)


def _refused(args: argparse.Namespace) -> str | None:
    """Why the options given cannot go together (None: they can)."""
    command = args.command or "the app"
    if args.command == "serve" and getattr(args, "replay", None) is not None:
        from .serve import replay_refusal

        refusal = replay_refusal(args)
        if refusal is not None:
            return refusal
    elif args.command == "serve" and (args.speed is not None or args.paused):
        return "serve takes --speed and --paused only with --replay FILE (how each tab's replay starts)"
    for option in sorted(NOT_FOR.get(args.command, ())):
        name = option.lstrip("-").replace("-", "_")
        value = getattr(args, name, None)
        if value and value != "driver":  # --join-as's default
            why = {"serve": "serve shows the app in browser tabs", "run": "run plays a script on its own"}
            return f"{command} takes no {option}: {why[args.command]}"
    if args.json and not args.headless and args.command != "run":
        return f"--json is for --headless (one JSON status line per change); {command} has a screen"
    return None
