"""``fieldbox --headless``: the scripting interface.

Commands on stdin, one per line (the command language, ``fieldbox/language.py``); a status line on stdout whenever
something a person would notice changes (mode, enable, e-stop, comms, code, FMS link, match
phase); with ``--json`` one JSON object per line. A refused command says why on stderr and
changes nothing. Ends cleanly on ``quit``, end of input, SIGINT and SIGTERM.

Nothing on the output side may stop the commands: stdout and stderr are written by threads of
their own (fieldbox/lineout.py), so a reader that went away (``| head -3``) or one that does
not read (a full pipe) costs status lines, said once on stderr, never an e-stop or the beat.
A command line over :data:`LINE_LIMIT` characters is refused without being kept whole.
"""

from __future__ import annotations

import asyncio
import json
import logging
import os
import signal
import sys
import threading
from typing import Any, Callable, Iterator, TextIO

from roles.cores.core import CommandError
from roles.cores.views import DsView, FmsView, RioView
from roles.runtime.engine import FieldView, LoopEngine
from roles.runtime.field import FieldConfig

from .language import HELP, CommandSyntaxError, parse
from .lineout import LineOut

STATUS_PERIOD = 0.1
#: How long a requested end (quit, end of input, SIGINT, SIGTERM) may take before the process
#: ends anyway: nothing the field does may keep fieldbox running.
EXIT_GRACE = 1.5
#: What writing what is left on stdout may take of EXIT_GRACE at the end (the rest is dropped, counted).
OUT_DRAIN = 0.5
#: The longest command line taken, in characters (the longest command is under a hundred): a
#: longer one is read to its end in pieces, never kept whole, and refused.
LINE_LIMIT = 4096
#: The pieces an over-long line is read and thrown away in.
_DISCARD_PIECE = 1 << 16


class ExitGuard:
    """Ends the process if the field has not stopped :data:`EXIT_GRACE` after an end was
    asked for: armed by a signal handler, by the loop as it takes ``quit`` or the end of
    input, and by the stdin thread when it sees them while the loop does not answer. So it
    works even when the event loop is held; a script whose steps wait (``sleep``, ``wait``)
    before its ``quit`` is not cut short (the CLI's run only: it must not end a test's
    interpreter)."""

    def __init__(self, enabled: bool, err: TextIO) -> None:
        self.enabled = enabled
        self.err = err
        self._timer: threading.Timer | None = None

    def arm(self) -> None:
        if self.enabled and self._timer is None:
            self._timer = threading.Timer(EXIT_GRACE, self._fire)
            self._timer.daemon = True
            self._timer.start()

    def disarm(self) -> None:
        if self._timer is not None:
            self._timer.cancel()

    def arm_unless_answered(self, loop: asyncio.AbstractEventLoop) -> None:
        """From another thread: arm if ``loop`` does not run a callback within EXIT_GRACE."""
        if not self.enabled:
            return
        answered = threading.Event()
        try:
            loop.call_soon_threadsafe(answered.set)
        except RuntimeError:  # the loop has ended
            return
        if not answered.wait(EXIT_GRACE):
            self._fire()

    def _fire(self) -> None:
        try:
            print(f"fieldbox: the field did not stop within {EXIT_GRACE:g} s; ending now", file=self.err,
                  flush=True)
        finally:
            os._exit(0)


def _state(estopped: bool, enabled: bool) -> str:
    return "E-STOPPED" if estopped else ("enabled" if enabled else "disabled")


def robot_report(ds: DsView, rio: RioView | None = None) -> dict[str, Any]:
    """What the robot reports of itself, as its DS hears it (the ``--json`` DS line's added
    fields): ``robot_enabled`` and ``robot_estopped`` from its status packets (None without
    robot comms), and ``code``: "ok", "stuck", "starting" or "none". The status packets say
    code runs while a program hangs; "stuck" is when this field's own fake roboRIO of that
    team says its program's call has not returned, as the app's DS tab shows it."""
    status = ds.link.status if ds.link.robot_comms else None
    if ds.link.robot_code:
        code = "stuck" if rio is not None and rio.code_state == "stuck" else "ok"
    else:
        code = "starting" if status is not None and ds.link.code_starting else "none"
    return {"robot_enabled": None if status is None else status.enabled,
            "robot_estopped": None if status is None else status.estop, "code": code}


_CODE_TEXT = {"ok": "ok", "stuck": "stuck", "starting": "starting", "none": "NO"}


def _ds_line(s: dict[str, Any]) -> str:
    """A DS's text line: the state is what the robot reports (with what the DS asks for when
    they differ, e.g. "teleop disabled (DS: enabled)" after the code died); without robot
    comms, what the DS asks for."""
    asked = _state(s["estopped"], s["enabled"])
    state = asked
    if s.get("robot_enabled") is not None:
        state = _state(s["robot_estopped"], s["robot_enabled"])
        if state != asked:
            state += f" (DS: {asked})"
    parts = [f"{s['mode']} {state}",
             f"comms {'ok' if s['robot_comms'] else 'NO'}",
             f"code {_CODE_TEXT[s['code']]}",
             f"battery {s['battery']:.2f} V" if s["battery"] is not None else "battery -",
             f"trip {s['trip_ms']:.1f} ms" if s["trip_ms"] is not None else "trip -",
             f"lost {s['lost_packets']}"]
    if s.get("fms_status") and s["fms_status"] != "off":
        parts.append(f"FMS {s['fms_status']}")
    if s.get("estop_reason"):  # what holds the e-stop: the FMS for the rest of the match, a latch...
        parts.append(s["estop_reason"])
    if s.get("fms_refused"):  # never "FMS good" alone while the field's control is refused
        parts.append(s["fms_refused"])
    if s.get("practice"):
        parts.append(f"practice {s['practice']}")
    return " | ".join(parts)


def _rio_line(r: RioView) -> str:
    state = "E-STOPPED" if r.estopped else ("enabled" if r.enabled else "disabled")
    return f"robot {r.code_state}, {state}, {r.battery.volts:.2f} V" + (" BROWNOUT" if r.battery.brownout else "")


def _ds_key(ds: DsView, report: dict[str, Any]) -> tuple:
    """What a DS's status line is printed again for, read off its view and what its robot
    reports (its snapshot, a dict of everything, is made only for a line that is printed)."""
    practice = ds.arbiter.practice_phase if ds.arbiter.practising else None
    return (ds.mode.label, ds.enabled, ds.arbiter.estopped, ds.link.robot_comms, ds.link.robot_code, ds.fms.status,
            practice, ds.telemetry.brownout, report["robot_enabled"], report["robot_estopped"], report["code"], ds.fms.refused,
            ds.estop_reason)


def _fms_key(fms: FmsView) -> tuple:
    """The same for the FMS's line: its phase, match and each station's links and stops."""
    return (fms.match.phase, fms.match.number) + tuple(
        (s.team, s.ds_link, s.report.robot_link, s.enabled, s.estop, s.astop, s.bypass, s.status)
        for s in fms.stations)


class Status:
    """What to print, and whether it changed since the last line: read off the engine's
    views (what the app would show), made only when a line is due."""

    def __init__(self, as_json: bool) -> None:
        self.as_json = as_json
        self._last: dict[str, tuple] = {}

    def lines(self, field: FieldView, now: float, force: bool = False) -> list[str]:
        """The lines of what changed in ``field`` (all with ``force``)."""
        out = []
        own_rio = not field.config.robot  # with --robot its DS talks to another robot
        for st in field.stations:
            # the station the FMS assigned where a DS runs here (--json says the same), not
            # the one configured: under an FMS, the DS plays where the field puts it
            name = f"{st.team} {(st.ds.station if st.ds is not None else st.station).label}"
            if st.ds is not None:
                report = robot_report(st.ds, st.rio if own_rio else None)
                key = ("ds",) + _ds_key(st.ds, report)
                if force or self._last.get(st.ds_name) != key:
                    self._last[st.ds_name] = key
                    snap = {**st.ds.snapshot(), **report}
                    out.append(json.dumps({"type": "status", "role": "ds", **snap}) if self.as_json
                               else f"ds {name}: {_ds_line(snap)}")
            if st.rio is not None:
                r = st.rio
                key = ("rio", r.code_state, r.enabled, r.estopped, r.battery.brownout, r.mode)
                if force or self._last.get(st.rio_name) != key:
                    self._last[st.rio_name] = key
                    if self.as_json:
                        out.append(json.dumps({"type": "status", "role": "rio", "team": st.team,
                                               "code_state": r.code_state, "enabled": r.enabled,
                                               "estopped": r.estopped, "mode": r.snapshot()["mode"],
                                               "battery": round(r.battery.volts, 2),
                                               "brownout": r.battery.brownout}))
                    else:
                        out.append(f"rio {name}: {_rio_line(r)}")
        fms = field.fms
        if fms is not None:
            key = ("fms",) + _fms_key(fms)
            if force or self._last.get("fms") != key:
                self._last["fms"] = key
                if self.as_json:
                    out.append(json.dumps({"type": "status", "role": "fms", **fms.snapshot(now)}))
                else:
                    stations = " ".join(
                        f"{s.label}:{s.team}{'+' if s.ds_link else '-'}"
                        f"{'E' if s.estop else ''}{'A' if s.astop else ''}{'B' if s.bypass else ''}"
                        f"{'*' if s.enabled else ''}"
                        for s in fms.stations if s.team is not None)
                    out.append(f"fms: match {fms.match.number} {fms.match.phase} {fms.remaining_left} s "
                               f"| {stations}")
        return out


#: The roles of ``fieldbox`` with no --roles: a DS and its robot, enabled from the keys.
ONE_TEAM_ROLES = frozenset({"ds", "rio"})


def config_from_args(args) -> FieldConfig:
    """Build a FieldConfig from the parsed command line; ValueError says what is wrong."""
    from protocol.enums import AllianceStation
    from roles.runtime.field import parse_roles, parse_teams

    teams = parse_teams(args.teams) if args.teams else None
    whole_field = args.command == "field" or getattr(args, "classroom", False)
    # One team's field starts without an FMS, so a newcomer's first enable works (the FMS
    # would decide it); F8 (or --roles ds,rio,fms) adds one. A full field has its FMS.
    roles = parse_roles(args.roles) if args.roles or whole_field else ONE_TEAM_ROLES
    if whole_field and not teams:
        what = "fieldbox serve --classroom" if args.command == "serve" else "fieldbox field"
        raise ValueError(f"{what} needs --teams, six teams for R1,R2,R3,B1,B2,B3 "
                         "(e.g. --teams 254,1114,2056,118,148,1678)")
    station = AllianceStation.parse(args.station) if args.station else AllianceStation.RED1
    team = args.team if args.team is not None else (next((t for t in teams if t), 1) if teams else 1)
    config = FieldConfig(roles=roles, team=team, station=station, plan=args.net or "loopback",
                         robot=args.robot, fms=args.fms, legacy=bool(args.legacy_2010),
                         program=getattr(args, "robot_program", None),
                         dashboard=getattr(args, "dashboard", None))
    if whole_field:
        config.teams = teams
    else:
        config.fms_teams = teams
    from roles.sim.faults import FaultSpecError, parse_fault

    for spec in getattr(args, "fault", None) or ():
        try:
            parse_fault(spec)
        except FaultSpecError as exc:
            raise ValueError(f"--fault {spec!r}: {exc}") from None
    config.faults = tuple(getattr(args, "fault", None) or ())
    config.log_dir = getattr(args, "log_dir", None)
    config.log_files = not getattr(args, "no_log_files", False)
    config.dslog_version = getattr(args, "dslog_version", None) or config.dslog_version
    config.single_ds = not getattr(args, "any_ds", False)
    config.no_fms = bool(getattr(args, "no_fms", False))
    config.ds_hello = getattr(args, "ds_hello", None) or config.ds_hello
    if config.ds_hello != "ni" and config.legacy:
        raise ValueError("--ds-hello 2027 is a login to a 2015+ FMS: not with --legacy-2010 (no FMS then)")
    config.ds_ip_server = getattr(args, "ds_ip_server", None)
    from roles.runtime.ds_ip_server import parse_port
    parse_port(config.ds_ip_server, config.plan)  # a bad port is said before anything binds
    if config.no_fms and (config.fms or "fms" in roles):
        raise ValueError("--no-fms keeps the DS off an FMS: not with --fms or the fms role")
    from roles.cores.addresses import check_team
    check_team(config.team)
    return config


async def run(config: FieldConfig, *, as_json: bool = False, stdin: TextIO | None = None,
              out: TextIO | None = None, err: TextIO | None = None, exit_guard: bool = False,
              realtime: bool = False) -> int:
    """A headless run. ``exit_guard`` and ``realtime`` are the command line's: the
    process ends even if its loop were held, and the loop's thread (the wire) runs at
    real-time priority where allowed (roles/runtime/process_tuning.py), above the robot programs."""
    stdin = stdin if stdin is not None else sys.stdin  # None: fd 0 was closed, an end of input
    out = out or sys.stdout
    err = err or sys.stderr
    loop = asyncio.get_running_loop()
    done = asyncio.Event()
    guard = ExitGuard(exit_guard, err)
    # Every line out goes through a writer thread: never a held loop, never an exception here.
    errors = LineOut(err, "stderr")
    output = LineOut(out, "stdout", problems=errors)
    emit, say = output.line, errors.line

    def on_signal(signum, frame) -> None:  # the main thread, even while the loop is held
        guard.arm()
        loop.call_soon_threadsafe(done.set)

    # Before anything is bound or printed: a SIGINT/SIGTERM at any moment ends us cleanly.
    previous = {}
    if threading.current_thread() is threading.main_thread():
        for sig in (signal.SIGINT, signal.SIGTERM):
            previous[sig] = signal.signal(sig, on_signal)
    engine = LoopEngine(config)  # the wire on this loop, the process's main thread
    field = engine.field  # live: what it bound, and its log files (the wire's side)
    try:
        await engine.start()
    except (OSError, ValueError) as exc:
        for sig, handler in previous.items():
            signal.signal(sig, handler)
        say(f"fieldbox: {exc}")
        output.close(OUT_DRAIN)
        errors.close(OUT_DRAIN)
        return 1
    if realtime:
        from roles.runtime.process_tuning import raise_wire_thread

        logging.getLogger("fieldbox.headless").info("the wire runs at %s", raise_wire_thread())

    if as_json:
        emit(json.dumps({"type": "bound", "roles": {name: {link: f"{ip}:{port}" for link, (ip, port) in links.items()}
                                                   for name, links in field.bound.items()}}))
    else:
        for line in field.describe_bound():
            emit(f"bound {line}")

    field_log = None
    if getattr(config, "log_files", False):
        from roles.runtime.logfiles import FieldLog

        try:  # console lines, errors and match events, flushed as they arrive (roles/runtime/logfiles.py)
            field_log = FieldLog(field, config.log_dir).attach()
        except OSError as exc:
            say(f"fieldbox: cannot write log files: {exc}")
        else:
            emit(json.dumps({"type": "logs", "folder": str(field_log.folder)}) if as_json
                 else f"logs {field_log.folder}")

    status = Status(as_json)
    from .script import Runner, Step

    steps = Runner(engine)  # sleep, wait and expect: the test steps of `fieldbox run`
    # a command line; the length of a line refused as too long (said in its turn); None: the end
    lines: asyncio.Queue[str | int | None] = asyncio.Queue()

    def refused(length: int) -> None:
        loop.call_soon_threadsafe(lines.put_nowait, length)

    def reader() -> None:
        try:
            for line in command_lines(stdin, refused) if stdin is not None else ():
                loop.call_soon_threadsafe(lines.put_nowait, line)
                if line.split("#", 1)[0].strip().lower() in ("quit", "exit"):
                    guard.arm_unless_answered(loop)
        except Exception as exc:  # noqa: BLE001 - unreadable input ends the run, saying why
            try:
                loop.call_soon_threadsafe(say, f"fieldbox: cannot read commands: {exc}")
            except RuntimeError:  # the loop has already ended
                return
        try:
            loop.call_soon_threadsafe(lines.put_nowait, None)
        except RuntimeError:  # the loop has already ended
            return
        guard.arm_unless_answered(loop)

    threading.Thread(target=reader, name="fieldbox-stdin", daemon=True).start()

    async def commands() -> None:
        while True:
            line = await lines.get()
            if line is None:
                guard.arm()
                done.set()
                return
            if isinstance(line, int):
                say(f"error: line over {LINE_LIMIT} characters refused ({line} characters): nothing changed")
                continue
            try:
                command = parse(line)
            except CommandSyntaxError as exc:
                say(f"error: {exc}")
                continue
            if command is None:
                continue
            if command.verb == "quit":
                guard.arm()
                done.set()
                return
            if command.verb == "help":
                say(HELP)
                continue
            if command.verb == "status":
                for text in status.lines(engine.views(engine.now()), engine.now(), force=True):
                    emit(text)
                continue
            if command.verb in ("sleep", "wait", "expect"):
                result = await steps.perform(Step(0, 0, line.strip(), command))
                if as_json:
                    emit(json.dumps({"type": "step", "step": line.strip(), "ok": result.ok,
                                     "seconds": round(result.seconds, 3), "detail": result.detail}))
                elif result.ok:
                    emit(f"ok: {line.strip()}" + (f" ({result.detail})" if result.detail else ""))
                if not result.ok:
                    say(f"error: {line.strip()}: {result.detail}")
                continue
            try:  # on this loop: done at once (an e-stop first), its role polled after it
                reply = engine.execute(command)
            except CommandError as exc:
                say(f"error: {line.strip()}: {exc}")
                continue
            if reply:
                if as_json:
                    faults = engine.views(engine.now()).faults if command.verb == "fault" else None
                    emit(json.dumps({"type": "faults", "faults": faults.snapshot()} if faults is not None
                                    else {"type": "reply", "verb": command.verb, "text": reply}))
                else:
                    for text in reply.splitlines():
                        emit(text)
            for text in status.lines(engine.views(engine.now()), engine.now()):
                emit(text)

    async def ticker() -> None:
        while not done.is_set():
            field = await engine.views_between_beats()  # never a whole field's views at once
            for text in status.lines(field, engine.now()):
                emit(text)
            if field_log is not None:
                field_log.poll()
                problem = field_log.take_problem()
                if problem is not None:  # a full disk: said, and the run goes on
                    say(f"fieldbox: {problem}")
            try:
                await asyncio.wait_for(done.wait(), STATUS_PERIOD)
            except asyncio.TimeoutError:
                pass

    def ended(task: asyncio.Task) -> None:
        """A task that fails ends the run, saying why: a run that no longer takes its
        commands must not go on (its DS falls silent and the robot disables)."""
        if task.cancelled() or task.exception() is None:
            return
        logging.getLogger("fieldbox.headless").error("%s failed", task.get_name(), exc_info=task.exception())
        say(f"fieldbox: {task.get_name()} failed ({task.exception()!r}): ending")
        guard.arm()
        done.set()

    tasks = [asyncio.create_task(commands(), name="the command reader"),
             asyncio.create_task(ticker(), name="the status ticker")]
    for t in tasks:
        t.add_done_callback(ended)
    await done.wait()
    for t in tasks:
        t.cancel()
    await asyncio.gather(*tasks, return_exceptions=True)
    if field_log is not None:
        field_log.close()
    await engine.close()
    for sig, handler in previous.items():
        signal.signal(sig, handler)
    output.close(OUT_DRAIN)
    errors.close(OUT_DRAIN)
    guard.disarm()
    return 0


def command_lines(stdin: TextIO, refused: Callable[[int], None]) -> Iterator[str]:
    """The lines of ``stdin``, none over :data:`LINE_LIMIT` characters: a longer one is read
    to its end in pieces and thrown away, ``refused(its length)`` says so, and the next line
    is the next command. So a megabyte line costs the reader's thread a read, and neither
    memory nor the loop's time."""
    while True:
        line = stdin.readline(LINE_LIMIT + 1)
        if not line:
            return
        if len(line) <= LINE_LIMIT or line.endswith("\n"):
            yield line
            continue
        length, piece = len(line), line
        while piece and not piece.endswith("\n"):
            piece = stdin.readline(_DISCARD_PIECE)
            length += len(piece)
        refused(length - piece.endswith("\n"))
