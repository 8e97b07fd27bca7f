"""``fieldbox conform fms ADDRESS``: fieldbox plays six Driver Stations and checks an FMS (a
real one, Cheesy Arena, fieldbox's FMS, any other implementation) at ADDRESS.

Each DS is what a real one is on a field: its own address (on loopback, its team's
127.TE.AM.5, the loopback plan's; elsewhere ``--ds-hosts``), a TCP 1750 login (team number,
then the challenge answered), a DS ping every 2 s, UDP status to ADDRESS port 1160 every
250 ms from its UDP 1121, where it takes control packets (and on 1120). A seventh login,
from a team not in the match, checks the waiting status; another first sends something
that is not a login; another logs in for a team from another team's address. Last, the DS
the FMS dropped (F12) logs in again as the 2027 FIRST Driver Station (its hello, naming a UDP
port of its own), to see the FMS answer it and send its control there.

The match cases need a match played: ``--start`` says how to start it (``prompt`` asks the
person at the FMS; ``stdin:match start`` writes to a launched fieldbox), ``--estop`` and
``--astop`` how to stop one station, ``--abort`` how to end the match early (else the loss
case waits for it to end). Without them those cases are not applicable.
"""

from __future__ import annotations

import asyncio
import datetime as _dt
import socket
import sys
import time
from dataclasses import dataclass
from statistics import median
from typing import Any, Callable

from protocol import fms_to_ds
from protocol.ds_to_fms import DsHello, DsPing, TeamNumber
from protocol.enums import AllianceStation, Mode, StationStatus
from protocol.errors import ProtocolError
from protocol.fms_to_ds import FmsControlPacket, HelloReply, StationInfo

from .hooks import Hook, HookOutcome, Launched
from .model import Case, Evidence, Run, SetupError, judge
from .net import FrameStream, UdpPort, connect, resolve, until
from .sources import CORRECTIONS, DS_FMS, FIELD, SEED_F2D
from .station_ds import FMS_TCP, FakeDs, Received, team_host

CASES = (
    Case("F01", "Login: station info for a team in the match",
         "A team in the match gets station info 00 03 19 <station 0-5> <status> after its login, status 0 "
         "(good) at its own station.",
         (f'{FIELD}: "A team in the match gets station info 00 03 19 <station 0-5> <status>, status 0 good"',
          f"{SEED_F2D} TCP Station Info 0x19")),
    Case("F02", "The challenge question",
         "A challenge question (0x1a) carries a u8-length question and a u16 random value 1000-2000; the "
         "right answer is taken (the station is then enabled in the match).",
         (f'{DS_FMS}: "Challenge response: the FMS sends a challenge question (0x1a) with a u16 random value '
          '(1000-2000)"', f'{CORRECTIONS}: Cheesy Arena "sends no challenge"')),
    Case("F03", "A team not in the match waits",
         "A team not in the current match gets station info waiting, 00 03 19 00 02, and its connection is "
         "kept open.",
         (f'{FIELD}: "A team that is not in the current match gets station info with status waiting '
          '(00 03 19 00 02) and the connection is kept open"',)),
    Case("F04", "A first frame that is not a login is closed, no reply",
         "A TCP connection whose first frame is not a team number (00 03 18 hi lo) is closed without a reply.",
         (f'{FIELD}: "A TCP connection whose first frame is not a team-number frame (00 03 18 hi lo) is closed '
          'without a reply"',)),
    Case("F05", "Wrong station detected",
         "A DS logging in for a team from another team's address (10.TE.AM.x / 127.TE.AM.x naming a team at "
         "another station) gets station info status 1, bad. On loopback a good status is not applicable: an FMS "
         "may rightly check stations only for a field's 10.TE.AM.x addresses.",
         (f'{FIELD}: "status 0 good, 1 bad (wrong station: on a real field, the DS\'s source address 10.TE.AM.x '
          'names another team\'s station)"', f'{CORRECTIONS}: Cheesy Arena "checks wrong stations only with '
          'network security on"'), needs="loopback (or --ds-hosts naming team addresses)"),
    Case("F06", "Control packets every 500 ms",
         "Each logged-in DS gets a control packet every 500 ms (median 450-600 ms, 95 % of gaps under 1 s "
         "before the match).",
         (f'{FIELD}: "Control packets go out every 500 ms"', f'{SEED_F2D}: "Sent to the DS on UDP port 1121 by '
          'the FMS every 500ms"', f'{CORRECTIONS}: Cheesy Arena median 506 ms, p99 585 ms')),
    Case("F07", "A control packet at once on a phase change",
         "On every match phase change a control packet goes out at once, not at the next 500 ms slot: at "
         "least one of the phase changes seen comes less than 450 ms after the packet before it.",
         (f'{FIELD}: "Control packets go out every 500 ms, and at once on every match phase change"',),
         needs="--start"),
    Case("F08", "Remaining time counts down the current period",
         "Bytes 20-21 of the control packet count down the current period, about 1 per second: teleop "
         "starts with more time left than auto ended with.",
         (f'{FIELD}: "Remaining time (bytes 20-21 of the control packet) counts down the current period, not the '
          'whole match"', f'{SEED_F2D}: "Remaining Time ... Time left in current mode"'), needs="--start"),
    Case("F09", "E-stop latches until the match is over",
         "A station e-stopped in auto gets control 0x80, not enabled, in every control packet to the end of "
         "the match (through teleop).",
         (f'{FIELD}: "E-stop of a station latches until the match is over"', f"{SEED_F2D} UDP Control table: "
          "E-Stop"), needs="--start, --estop"),
    Case("F10", "A-stop latches until auto ends",
         "A station a-stopped in auto gets control 0x40 and is not enabled for the rest of auto; in teleop it "
         "is enabled again.",
         (f'{FIELD}: "a-stop latches until auto ends"; "enabled only when ... not a-stopped during auto"',),
         needs="--start, --astop"),
    Case("F11", "Phases: pre-match, auto, pause, teleop, post-match",
         "Pre-match is auto mode disabled, auto enabled, the pause disabled, teleop enabled, post-match "
         "disabled: as control packets to a station with nothing stopped show them.",
         (f'{FIELD}: "Phases: pre-match (auto mode, disabled), auto (enabled), pause (disabled), teleop '
          '(enabled), post-match (disabled)"',), needs="--start"),
    Case("F12", "A DS silent on TCP for 5 s is dropped",
         "A DS counts as lost after 5 s without any TCP frame: the FMS closes its connection (allowed: 4-10 s "
         "after its last frame).",
         (f'{FIELD}: "A DS counts as lost after ... 5 s without any TCP frame"',)),
    Case("F13", "A DS silent on UDP for 1 s is lost: no match starts",
         "A DS counts as lost after 1 s without UDP status, and a match refuses to start while a station is "
         "neither connected nor bypassed.",
         (f'{FIELD}: "A DS counts as lost after 1 s without UDP status"', f'{FIELD}: "A match refuses to start '
          'while any station is e-stopped, or neither connected nor bypassed"'), needs="--start"),
    Case("F14", "Control packet layout and date",
         "Every control packet decodes (22-byte header, tags), comm version 0x00, the DS's own station, its "
         "sequence one more each packet; the date block as the seed says it: UTC, month 0-based, year - 1900 "
         "(within 10 minutes of fieldbox's clock).",
         (f"{SEED_F2D} UDP table and Date table", f'{FIELD}: "Date block ... The seed says month 0 = January; a '
          'widely used open FMS sends 1-12 and local time. ... encode as the seed says"')),
    Case("F15", "The 2027 DS's hello",
         "A team in the match that logs in with the 2027 FIRST Driver Station's hello (tag 30, naming a UDP "
         "port) gets the hello reply 00 06 1f <station> <status> <flags> <team hi> <team lo>, status 0 at its own "
         "station, its own team, and the FMS's control packets come to the port the hello named. An FMS that "
         "never answers a 2027 hello (one for the NI DS only) is not judged.",
         (f"{CORRECTIONS}: Cheesy Arena's 2027 DS hello: DS -> FMS TCP tag 30 [size u16][30][UDP reply port u16]"
          "[flags u8][team length u8][team number in ASCII]; reply tag 31, 8 bytes 00 06 1f station status flags "
          "team_hi team_lo (flags bit 0: FMS Lite); control goes to the port named in the hello",)),
)

SPARE_OFFSET = 3  # the spare team's DS address: 127.TE.AM.5 of the spare team


@dataclass
class FmsOptions:
    address: str
    teams: list[int | None]
    spare_team: int = 9999
    ds_hosts: list[str] | None = None  # one per station (default: 127.TE.AM.5 on loopback)
    spare_host: str | None = None
    launch: str | None = None
    launch_cwd: str | None = None
    wait: float = 30.0
    start_hook: str | None = None
    abort_hook: str | None = None
    estop_hook: str | None = None
    astop_hook: str | None = None
    cases: frozenset[str] | None = None


def _loopback(host: str) -> bool:
    try:
        return socket.inet_aton(host)[0] == 127
    except OSError:
        return host == "localhost"


def _host_team(host: str) -> int | None:
    """The team a DS address names: 10.TE.AM.x on a field, 127.TE.AM.x on loopback."""
    try:
        b = socket.inet_aton(host)
    except OSError:
        return None
    return b[1] * 100 + b[2] if b[0] in (10, 127) and host.count(".") == 3 else None


def _ctl_ev(run: Run, c: Received, note: str) -> Evidence:
    return Evidence("received", run.since(c.at), note, "fms-to-ds", c.data)


def _tcp_ev(run: Run, at: float, data: bytes, note: str, direction: str = "received") -> Evidence:
    return Evidence(direction, run.since(at), note, "fms-to-ds-tcp" if direction == "received" else "ds-to-fms-tcp",
                    data)


def _phase(p: FmsControlPacket) -> str:
    return f"{p.mode.label} {'enabled' if p.enabled else 'disabled'}"


class FmsConformance:
    def __init__(self, opts: FmsOptions, run: Run, err: Any = None) -> None:
        self.o = opts
        self.run = run
        self.err = err or sys.stderr
        self.launched: Launched | None = None
        self.dses: list[FakeDs] = []
        self.extra: list[FrameStream] = []
        self.match: dict[str, float] = {}  # what happened when: start, estop, astop, abort

    # -- plumbing ---------------------------------------------------------------------------------
    async def execute(self) -> Run:
        try:
            await self._setup()
            await self._cases()
        finally:
            await self._teardown()
        self.run.finish("not run")
        return self.run

    async def _setup(self) -> None:
        o, run = self.o, self.run
        try:
            o.address = await resolve(o.address)
        except OSError as exc:
            raise SetupError(f"cannot find the FMS {o.address}: {exc.strerror or exc}") from None
        teams = list(o.teams) + [None] * (6 - len(o.teams))
        hosts = o.ds_hosts
        if hosts is None:
            if not _loopback(o.address):
                raise SetupError("an FMS off this machine sends control packets to each DS's own address: give six "
                                 "addresses of this machine with --ds-hosts (one a station)")
            hosts = [team_host(t) if t else "" for t in teams]
        for i, team in enumerate(teams):
            if team is None:
                continue
            ds = FakeDs(team, AllianceStation(i), hosts[i], o.address)
            try:
                await ds.bind()
            except OSError as exc:
                await ds.close()
                raise SetupError(f"cannot bind UDP {hosts[i]}:1121/1120 for team {team}'s DS: "
                                 f"{exc.strerror or exc}") from None
            self.dses.append(ds)
        run.notes.append("fieldbox plays six DSes: " + ", ".join(f"{d.station.label} {d.team} at {d.host}"
                                                                 for d in self.dses))
        if o.launch:
            try:
                self.launched = await Launched.start(o.launch, o.launch_cwd)
            except (OSError, ValueError) as exc:
                raise SetupError(f"cannot launch {o.launch!r}: {exc}") from None
            run.notes.append(f"launched: {o.launch}")

    async def _teardown(self) -> None:
        for ds in self.dses:
            await ds.close()
        for s in self.extra:
            await s.wait_closed()
        if self.launched is not None:
            await self.launched.stop()

    async def _guard(self, cid: str, step: Callable[[], Any], retries: int = 0) -> None:
        await judge(self.run, cid, step, self.err, retries)

    async def _hook(self, spec: str | None, what: str, **values: Any) -> tuple[bool, str]:
        return await Hook(what, spec).fire(self.launched, err=self.err, **values)

    def _spare_host(self) -> str | None:
        if self.o.spare_host:
            return self.o.spare_host
        return team_host(self.o.spare_team) if _loopback(self.o.address) else None

    async def _connect(self, name: str, local: str | None) -> FrameStream | None:
        try:
            s = await connect(name, (self.o.address, FMS_TCP), local_host=local)
        except (OSError, asyncio.TimeoutError):
            return None
        self.extra.append(s)
        return s

    # -- the order of things ------------------------------------------------------------------------
    async def _cases(self) -> None:
        run = self.run
        t0 = time.monotonic()
        reached = False
        while time.monotonic() - t0 < self.o.wait:
            probe = await self._connect("probe", None)
            if probe is not None:
                await probe.wait_closed()
                reached = True
                break
            await asyncio.sleep(0.5)
        if not reached:
            run.failed("F01", f"no TCP connection to {self.o.address}:{FMS_TCP} in {self.o.wait:g} s")
            run.finish("the FMS cannot be reached: nothing to check")
            return
        await asyncio.sleep(0.3)
        # the odd logins first: a wrong-station login must not find the real DS holding the station
        await asyncio.gather(self._guard("F03", self.f03), self._guard("F04", self.f04),
                             self._guard("F05", self.f05))
        for ds in self.dses:
            try:
                await ds.login()
            except (OSError, asyncio.TimeoutError) as exc:
                run.notes.append(f"team {ds.team}'s DS could not connect: {exc}")
        await asyncio.sleep(1.0)
        await self._guard("F01", self.f01)
        await self._guard("F02", self.f02)
        await asyncio.sleep(3.0)
        await self._guard("F06", self.f06)
        await self._match()
        await self._guard("F12", self.f12)
        await self._guard("F14", self.f14)
        await self._guard("F15", self.f15)

    # -- logins -----------------------------------------------------------------------------------
    async def f01(self) -> None:
        run = self.run
        await until(lambda: all(d.station_info for d in self.dses), 2.0)
        for d in self.dses:
            if d.station_info is None:
                frames = list(d.tcp.frames) if d.tcp else []
                run.failed("F01", f"no station info for team {d.team} within 3 s of its login",
                           evidence=[_tcp_ev(run, f.at, f.data, "a frame") for f in frames[:3]])
                return
            at, data = d.station_info
            info = fms_to_ds.decode_tcp(data)  # kept only once it decoded (station_ds.FakeDs._frame)
            assert isinstance(info, StationInfo)  # and only a station info is kept
            if info.station != d.station or info.status != StationStatus.GOOD:
                run.failed("F01", f"team {d.team} at {d.station.label} got station {info.station.label} status "
                                  f"{int(info.status)}", evidence=[_tcp_ev(run, at, data, "its station info")])
                return
        if not self.dses:
            run.not_applicable("F01", "no team of the match has a DS here to log in")
            return
        d = self.dses[0]
        assert d.station_info is not None  # every DS had one (the loop above)
        run.passed("F01", f"{len(self.dses)} logins, each told its station, status good",
                   evidence=[_tcp_ev(run, d.station_info[0], d.station_info[1], f"team {d.team}'s station info")])

    async def f02(self) -> None:
        run = self.run
        asked = [d for d in self.dses if d.challenge]
        if not asked:
            run.not_applicable("F02", "no challenge question within a second of the logins (Cheesy Arena sends none)")
            return
        values: list[int] = []
        for d in asked:
            assert d.challenge is not None  # asked: those with a question
            at, data, value = d.challenge
            values.append(value)
            if not 1000 <= value <= 2000:
                run.failed("F02", f"random value {value}, outside 1000-2000",
                           evidence=[_tcp_ev(run, at, data, f"team {d.team}'s question")])
                return
        run.passed("F02", f"{len(asked)} questions, random values "
                          + ", ".join(str(v) for v in values) + " (answered right; see F11)")

    async def f03(self) -> None:
        run = self.run
        host = self._spare_host()
        s = await self._connect("spare", host)
        if s is None:
            run.failed("F03", "could not connect to TCP 1750")
            return
        login = TeamNumber(self.o.spare_team).encode()
        s.send(login)
        t0 = time.monotonic()
        await until(lambda: s.frames, 2.0)
        info = next((f for f in s.frames if len(f.data) > 2 and f.data[2] == fms_to_ds.FRAME_STATION_INFO), None)
        ev = [_tcp_ev(run, t0, login, f"login as team {self.o.spare_team}, not in the match", "sent")]
        if info is None:
            why = "the connection was closed" if not s.is_open else "no station info"
            run.failed("F03", f"{why} within 2 s of a login for team {self.o.spare_team}, not in the match",
                       evidence=ev)
            return
        ev.append(_tcp_ev(run, info.at, info.data, "the FMS's answer"))
        if info.data != bytes.fromhex("0003190002"):
            run.failed("F03", f"station info {info.data.hex(' ')}, waiting is 00 03 19 00 02", evidence=ev)
            return
        for _ in range(3):
            await asyncio.sleep(1.0)
            s.send(DsPing().encode())
        if s.closed_at is not None:  # closed (is_open is False)
            run.failed("F03", f"the connection was closed {s.closed_at - t0:.1f} s after the waiting status",
                       evidence=ev)
            return
        run.passed("F03", "00 03 19 00 02 (waiting), and the connection kept open 3 s")
        s.close()

    async def f04(self) -> None:
        run = self.run
        s = await self._connect("not-a-login", self._spare_host())
        if s is None:
            run.failed("F04", "could not connect to TCP 1750")
            return
        ping = DsPing().encode()
        s.send(ping)
        t0 = time.monotonic()
        closed = await until(lambda: not s.is_open, 3.0)
        ev = [_tcp_ev(run, t0, ping, "a DS ping as the first frame", "sent")]
        if s.frames:
            f = s.frames[0]
            run.failed("F04", "the FMS replied to a first frame that is no login",
                       evidence=ev + [_tcp_ev(run, f.at, f.data, "its reply")])
        elif not closed:
            run.failed("F04", "the connection was still open 3 s after a first frame that is no login", evidence=ev)
        else:
            assert s.closed_at is not None  # closed: set as it closed
            run.passed("F04", f"closed {s.closed_at - t0:.2f} s after a DS ping as first frame, no reply")

    async def f05(self) -> None:
        run = self.run
        if len(self.dses) < 2:
            run.not_applicable("F05", "two teams are needed")
            return
        victim, other = self.dses[0], self.dses[-1]
        if _host_team(other.host) != other.team:  # the hosts given (--ds-hosts), or 127.TE.AM.5
            run.not_applicable("F05", f"the DS addresses do not name their teams ({other.host} for team "
                                      f"{other.team}; 10.TE.AM.x or 127.TE.AM.x would)")
            return
        s = await self._connect("wrong-station", other.host)
        if s is None:
            run.failed("F05", "could not connect to TCP 1750")
            return
        login = TeamNumber(victim.team).encode()
        s.send(login)
        t0 = time.monotonic()
        await until(lambda: s.frames or not s.is_open, 2.0)
        info = next((f for f in s.frames if len(f.data) > 2 and f.data[2] == fms_to_ds.FRAME_STATION_INFO), None)
        ev = [_tcp_ev(run, t0, login, f"login as team {victim.team} from {other.host}, team {other.team}'s "
                                      "address", "sent")]
        s.close()
        if info is None:
            run.failed("F05", "no station info for the login from another team's address", evidence=ev)
            return
        ev.append(_tcp_ev(run, info.at, info.data, "the FMS's answer"))
        try:
            msg = fms_to_ds.decode_tcp(info.data)
        except ProtocolError as exc:
            run.failed("F05", f"the station info does not decode: {exc}", evidence=ev)
            return
        assert isinstance(msg, StationInfo)  # its frame id was the station info's
        if msg.status == StationStatus.GOOD and _loopback(other.host):
            # On a field a DS's address is 10.TE.AM.x; an FMS may rightly judge stations only by
            # such addresses (Cheesy Arena does), so a good status on loopback proves nothing.
            run.not_applicable("F05", f"status 0 (good) for team {victim.team} logging in from {other.host}, team "
                                      f"{other.team}'s loopback address: an FMS may check stations only for 10.TE.AM.x "
                                      "addresses, as a field's are (give --ds-hosts 10.TE.AM.5 ... to judge it)")
            return
        if msg.status != StationStatus.BAD:
            run.failed("F05", f"status {int(msg.status)} for team {victim.team} logging in from team {other.team}'s "
                              f"address at {other.station.label}; 1 (bad, wrong station) expected", evidence=ev)
            return
        run.passed("F05", f"team {victim.team} from {other.host} (team {other.team}, {other.station.label}): "
                          "status 1, wrong station", evidence=ev)

    # -- control packets ------------------------------------------------------------------------------
    async def f06(self) -> None:
        run = self.run
        medians, p95s, worst = [], [], 0.0
        if not self.dses:
            run.not_applicable("F06", "no team of the match has a DS here to receive control packets")
            return
        for d in self.dses:
            packets = d.good()
            if len(packets) < 4:
                run.failed("F06", f"{len(packets)} control packets to team {d.team} at {d.host}:1121 in 4 s")
                return
            gaps = sorted((b.at - a.at) * 1000 for a, b in zip(packets, packets[1:]))
            medians.append(median(gaps))
            p95s.append(gaps[min(len(gaps) - 1, int(0.95 * len(gaps)))])
            worst = max(worst, gaps[-1])
        figures = {"median_ms": round(median(medians), 1), "p95_ms": round(max(p95s), 1), "max_ms": round(worst, 1),
                   "allowed": "median 450-600 ms, 95 % of gaps <= 1000 ms"}
        what = f"control every {median(medians):.0f} ms (median), 95 % within {max(p95s):.0f} ms, {worst:.0f} ms at most"
        if not 450 <= median(medians) <= 600 or max(p95s) > 1000:
            run.failed("F06", what, figures)
        else:
            run.passed("F06", what, figures)

    async def f14(self) -> None:
        run = self.run
        for d in self.dses:
            last = None
            for c in d.mine():
                if c.packet is None:
                    run.failed("F14", f"a control packet does not decode: {c.error}", evidence=[_ctl_ev(run, c, "")])
                    return
                p = c.packet
                if p.comm_version != 0x00:
                    run.failed("F14", f"comm version 0x{p.comm_version:02x}", evidence=[_ctl_ev(run, c, "")])
                    return
                if p.station != d.station:
                    run.failed("F14", f"station {p.station.label} in control packets to team {d.team} at "
                                      f"{d.station.label}", evidence=[_ctl_ev(run, c, "")])
                    return
                if last is not None and (p.sequence - last.sequence) & 0xFFFF != 1:
                    run.failed("F14", f"sequence {last.sequence} then {p.sequence} to team {d.team}",
                               evidence=[_ctl_ev(run, c, "")])
                    return
                last = p
        sample = next((c for d in self.dses for c in reversed(d.mine()) if c.packet is not None), None)
        if sample is None:
            run.failed("F14", "no control packets")
            return
        when = sample.pkt.date.to_datetime()
        now = _dt.datetime.fromtimestamp(time.time() - (time.monotonic() - sample.at), _dt.timezone.utc)
        ev = [_ctl_ev(run, sample, "a control packet")]
        if when is None or abs((when - now).total_seconds()) > 600:
            one = sample.pkt.date.to_datetime(one_based_month=True, tz=None)
            hint = ""
            if one is not None and abs((one - now.replace(tzinfo=None)).total_seconds()) < 15 * 3600:
                hint = ": month 1-based (and perhaps local time), as Cheesy Arena sends it"
            run.failed("F14", f"date block {when.isoformat() if when else 'not a date'} read as the seed says, "
                              f"fieldbox's clock {now.isoformat(timespec='seconds')}{hint}", evidence=ev)
            return
        run.passed("F14", f"every control packet decodes; date {when.isoformat(timespec='seconds')} "
                          f"({(when - now).total_seconds():+.1f} s)", {"date": when.isoformat()})

    # -- the match ------------------------------------------------------------------------------------
    async def _match(self) -> None:
        run, o = self.run, self.o
        match_cases = ("F07", "F08", "F09", "F10", "F11", "F13")
        if not any(run.wanted(c) for c in match_cases):
            return
        if not o.start_hook:
            for cid in match_cases:
                if run.wanted(cid):
                    run.not_applicable(cid, "no --start: a match has to be played (e.g. --start prompt)")
            return
        watch = self._watcher()
        if watch is None:
            for cid in match_cases:
                run.not_applicable(cid, "no station is left to watch the phases on")
            return
        silent = self.dses[-1]
        refused = None
        if run.wanted("F13"):
            silent.udp_silent = True
            await asyncio.sleep(2.0)
            t_try = time.monotonic()
            tried = await Hook(f"try to start the match (it should refuse: {silent.station.label}'s DS is silent)",
                               o.start_hook).outcome(self.launched, err=self.err)
            await asyncio.sleep(3.0)
            started = [c for d in self.dses for c in d.good(t_try) if c.pkt.enabled]
            refused = (tried, started, t_try)
            silent.udp_silent = False
            await asyncio.sleep(1.5)
        t_start = time.monotonic()
        self.match["start"] = t_start
        done, note = await self._hook(o.start_hook, "start the match")
        if refused is not None:
            self._f13(silent, *refused)
        auto = await until(lambda: any(c.pkt.enabled and c.pkt.mode == Mode.AUTONOMOUS
                                       for c in watch.good(t_start)), 10.0)
        if not auto:
            for cid in match_cases:
                run.not_applicable(cid, f"the match did not start within 10 s of --start ({note})")
            return
        t_auto = next(c.at for c in watch.good(t_start) if c.pkt.enabled)
        stop_e, stop_a = self.dses[0], (self.dses[1] if len(self.dses) > 2 else None)
        await asyncio.sleep(max(0.0, t_auto + 1.0 - time.monotonic()))
        if o.estop_hook:
            self.match["estop"] = time.monotonic()
            _, note = await self._hook(o.estop_hook, "e-stop station {station}", station=stop_e.station.label,
                                       team=stop_e.team)
            run.notes.append(f"--estop {stop_e.station.label}: {note}")
        if o.astop_hook and stop_a is not None:
            await asyncio.sleep(0.5)
            self.match["astop"] = time.monotonic()
            _, note = await self._hook(o.astop_hook, "a-stop station {station}", station=stop_a.station.label,
                                       team=stop_a.team)
            run.notes.append(f"--astop {stop_a.station.label}: {note}")
        # auto ends, the pause, then teleop
        teleop = await until(lambda: any(c.pkt.enabled and c.pkt.mode == Mode.TELEOP
                                         for c in watch.good(t_auto)), 40.0, 0.05)
        if teleop:
            await asyncio.sleep(3.0)
        t_end = time.monotonic()
        if teleop and o.abort_hook:
            # the abort's time is when the hook starts: with --abort prompt a person clicks
            # abort, then presses Enter, and the match is over well before the hook returns
            self.match["abort"] = time.monotonic()
            _, note = await self._hook(o.abort_hook, "abort the match")
            await until(lambda: any(not c.pkt.enabled for c in watch.good(self.match["abort"])), 3.0)
            await asyncio.sleep(0.6)
        self.match["end"] = t_end
        for cid, step in (("F07", lambda: self.f07(watch)), ("F08", lambda: self.f08(watch)),
                          ("F09", lambda: self.f09(stop_e, watch)), ("F10", lambda: self.f10(stop_a, watch)),
                          ("F11", lambda: self.f11(watch))):
            await self._guard(cid, step)

    def _watcher(self) -> FakeDs | None:
        """A station nothing will stop: its control packets show the phases."""
        return self.dses[3] if len(self.dses) >= 5 else (self.dses[-1] if len(self.dses) > 2 else None)

    def _f13(self, silent: FakeDs, tried: HookOutcome, started: list[Received], t_try: float) -> None:
        run = self.run
        if not tried.ran:
            run.not_applicable("F13", f"the start hook did not run: {tried.note}")
        elif started:
            c = started[0]
            run.failed("F13", f"the match started {c.at - t_try:.1f} s after --start, with {silent.station.label}'s DS "
                              "silent on UDP for 2 s (lost after 1 s)", evidence=[_ctl_ev(run, c, "enabled")])
        elif not tried.done:  # a start command that failed: the FMS said no, and why
            run.passed("F13", f"the FMS refused to start while {silent.station.label}'s DS was silent on UDP "
                              f"({tried.note}), and no station was enabled in the 3 s after; the match started "
                              "once it was back")
        else:
            run.passed("F13", f"no station enabled in the 3 s after --start while {silent.station.label}'s DS was "
                              "silent on UDP; the match started once it was back")

    def _phases(self, ds: FakeDs, since: float) -> list[tuple[str, Received, Received]]:
        """Each change of mode or enable: (new phase, its first packet, the packet before)."""
        out: list[tuple[str, Received, Received]] = []
        prev: Received | None = None
        for c in ds.good(since - 2.0):
            if prev is not None and _phase(c.pkt) != _phase(prev.pkt) and c.at >= since:
                out.append((_phase(c.pkt), c, prev))
            prev = c
        return out

    async def f07(self, watch: FakeDs) -> None:
        run = self.run
        changes = self._phases(watch, self.match["start"])
        packets = watch.good()
        rows = []
        for name, c, before in changes:
            after = next((p for p in packets if p.at > c.at), None)
            # Sent at once, the change's packet falls between two of the 500 ms beat: one of the
            # gaps around it is short. (Phase lengths are whole half-seconds, so every change
            # can fall at the same point of the beat: the gap before alone cannot tell.)
            gaps = [round((c.at - before.at) * 1000)] + ([round((after.at - c.at) * 1000)] if after else [])
            rows.append((name, gaps, c, before))
        figures: dict[str, Any] = {"changes": [f"{n}: {g[0]} ms after the packet before"
                               + (f", {g[1]} ms before the next" if len(g) > 1 else "") for n, g, _, _ in rows]}
        for key, enabled in (("start", True), ("abort", False)):  # how long after the hook, for the record
            if key in self.match:
                first = next((c for c in packets if c.at >= self.match[key] and c.pkt.enabled == enabled), None)
                if first is not None:
                    figures[f"after_{key}_ms"] = round((first.at - self.match[key]) * 1000)
        at_once = [r for r in rows if min(r[1]) < 450]
        if len(rows) < 2:
            run.not_applicable("F07", f"only {len(rows)} phase change seen", figures)
        elif not at_once:
            name, gaps, c, before = rows[0]
            run.failed("F07", "every phase change waited for the 500 ms beat: no packet came between two of it",
                       figures, [_ctl_ev(run, before, "the packet before"), _ctl_ev(run, c, f"the first {name}")])
        else:
            run.passed("F07", f"{len(at_once)} of {len(rows)} phase changes sent between two beats (at once)",
                       figures)

    async def f08(self, watch: FakeDs) -> None:
        run = self.run
        packets = watch.good(self.match["start"])
        auto = [c for c in packets if c.pkt.enabled and c.pkt.mode == Mode.AUTONOMOUS]
        teleop = [c for c in packets if c.pkt.enabled and c.pkt.mode == Mode.TELEOP]
        if len(auto) < 3 or len(teleop) < 3:
            run.not_applicable("F08", "auto and teleop were not both seen")
            return
        figures: dict[str, Any] = {"auto": [auto[0].pkt.remaining_seconds, auto[-1].pkt.remaining_seconds],
                   "teleop": [teleop[0].pkt.remaining_seconds, teleop[-1].pkt.remaining_seconds]}
        for name, part in (("auto", auto), ("teleop", teleop)):
            t = part[-1].at - part[0].at
            drop = part[0].pkt.remaining_seconds - part[-1].pkt.remaining_seconds
            figures[f"{name}_rate"] = round(drop / t, 2) if t > 0 else None
            # whole seconds on the wire: a second either way, and 10 % for the clocks
            if abs(drop - t) > 1.5 + 0.1 * t:
                run.failed("F08", f"in {name} the remaining time fell {drop} s in {t:.1f} s", figures,
                           [_ctl_ev(run, part[0], f"first {name}"), _ctl_ev(run, part[-1], f"last {name}")])
                return
        if teleop[0].pkt.remaining_seconds <= auto[-1].pkt.remaining_seconds:
            run.failed("F08", f"teleop began with {teleop[0].pkt.remaining_seconds} s left, auto ended with "
                              f"{auto[-1].pkt.remaining_seconds}: the whole match counted, not the period", figures,
                       [_ctl_ev(run, auto[-1], "the last auto packet"), _ctl_ev(run, teleop[0], "the first teleop")])
            return
        run.passed("F08", f"auto {figures['auto'][0]} -> {figures['auto'][1]} s, teleop from "
                          f"{figures['teleop'][0]} s: each period counted down", figures)

    def _match_over(self, watch: FakeDs) -> float:
        """When the match was over: the abort (when its hook started) or the end of the run's
        wait, or post-match as the watching station saw it, whichever came first. Post-match
        begins halfway between the last enabled teleop packet and the disabled one after it:
        the FMS sends each phase's packets to every station at once, so another station's
        packets fall clearly on one side."""
        end = self.match.get("abort", self.match["end"])
        last_teleop: Received | None = None
        for c in watch.good(self.match.get("start", 0.0)):
            if c.pkt.enabled and c.pkt.mode == Mode.TELEOP:
                last_teleop = c
            elif last_teleop is not None and not c.pkt.enabled:
                return min(end, (last_teleop.at + c.at) / 2)
        return end

    async def f09(self, d: FakeDs, watch: FakeDs) -> None:
        run = self.run
        if "estop" not in self.match:
            run.not_applicable("F09", "no --estop: a station has to be e-stopped (e.g. --estop 'stdin:estop {station} on')")
            return
        t = self.match["estop"]
        after = d.good(t)
        first = next((c for c in after if c.pkt.estop), None)
        if first is None:
            run.failed("F09", f"no control packet to {d.station.label} with e-stop (0x80) after --estop",
                       evidence=[_ctl_ev(run, c, "") for c in after[-1:]])
            return
        end = self._match_over(watch)
        broken = next((c for c in after if c.at > first.at and c.at < end and (not c.pkt.estop or c.pkt.enabled)),
                      None)
        if broken is not None:
            run.failed("F09", f"{d.station.label}'s e-stop cleared (or enabled) at {_phase(broken.pkt)} before the "
                              "match was over", evidence=[_ctl_ev(run, first, "e-stop"), _ctl_ev(run, broken, "later")])
            return
        held = [c for c in after if first.at <= c.at < end]
        run.passed("F09", f"e-stop in all {len(held)} control packets to {d.station.label} from {first.at - t:.2f} s "
                          "after --estop to the end of the match", {"after_s": round(first.at - t, 3)})

    async def f10(self, d: FakeDs | None, watch: FakeDs) -> None:
        run = self.run
        if "astop" not in self.match or d is None:
            run.not_applicable("F10", "no --astop: a station has to be a-stopped in auto")
            return
        t = self.match["astop"]
        after = d.good(t)
        first = next((c for c in after if c.pkt.astop), None)
        if first is None:
            run.failed("F10", f"no control packet to {d.station.label} with a-stop (0x40) after --astop",
                       evidence=[_ctl_ev(run, c, "") for c in after[-1:]])
            return
        in_auto = [c for c in after if c.pkt.mode == Mode.AUTONOMOUS and c.at >= first.at]
        bad = next((c for c in in_auto if c.pkt.enabled), None)
        if bad is not None:
            run.failed("F10", f"{d.station.label} enabled in auto after its a-stop",
                       evidence=[_ctl_ev(run, first, "a-stop"), _ctl_ev(run, bad, "enabled again")])
            return
        tele = next((c for c in after if c.pkt.mode == Mode.TELEOP and c.pkt.enabled), None)
        if tele is None:
            run.failed("F10", f"{d.station.label} not enabled in teleop after an a-stop in auto",
                       evidence=[_ctl_ev(run, first, "a-stop")] + [_ctl_ev(run, c, "") for c in after[-1:]])
            return
        run.passed("F10", f"{d.station.label} a-stopped {first.at - t:.2f} s after --astop, disabled for the rest "
                          "of auto, enabled in teleop", {"after_s": round(first.at - t, 3)})

    async def f11(self, watch: FakeDs) -> None:
        run = self.run
        before = [c for c in watch.good() if c.at < self.match["start"]]
        seq = [name for name, _, _ in self._phases(watch, self.match["start"])]
        first = before[-1] if before else None
        figures = {"pre_match": _phase(first.pkt) if first else None, "then": seq}
        want = [f"{Mode.AUTONOMOUS.label} enabled", "disabled", f"{Mode.TELEOP.label} enabled"]
        got: list[str] = []
        for n in seq:  # the pause may change mode while disabled (Cheesy Arena sends it as teleop)
            n = "disabled" if n.endswith("disabled") else n
            if not got or got[-1] != n:
                got.append(n)
        if first is None or first.pkt.mode != Mode.AUTONOMOUS or first.pkt.enabled:
            run.failed("F11", f"pre-match is {figures['pre_match']}, auto mode disabled expected", figures,
                       [_ctl_ev(run, first, "pre-match")] if first else [])
            return
        if got[:3] != want:
            run.failed("F11", f"phases {got}, {want} expected", figures)
            return
        if "abort" in self.match:
            if len(got) < 4 or got[3] != "disabled":
                run.failed("F11", "still enabled after the match was aborted", figures)
                return
        run.passed("F11", "pre-match auto disabled, auto enabled, pause disabled, teleop enabled"
                   + (", disabled after" if "abort" in self.match else ""), figures)

    async def f12(self) -> None:
        run = self.run
        d = self.dses[-1] if self.dses else None
        if d is None or d.tcp is None or not d.tcp.is_open:
            run.not_applicable("F12", "no DS connection to fall silent")
            return
        if "start" in self.match and "abort" not in self.match and self.o.start_hook:
            run.notes.append("F12 runs while the match may still be on (no --abort)")
        tcp = d.tcp  # the DS logs in once, at setup
        d.tcp_silent = True
        last = d.last_tcp_sent
        closed = await until(lambda: not tcp.is_open, 12.0, 0.05)
        if not closed:
            run.failed("F12", f"{d.station.label}'s connection still open 12 s after its last TCP frame "
                              "(UDP status still coming)")
            return
        assert tcp.closed_at is not None  # closed: set as it closed
        took = tcp.closed_at - last
        figures = {"closed_after_s": round(took, 2), "allowed_s": "4-10 (a busy host may close it late)"}
        if not 4.0 <= took <= 10.0:
            run.failed("F12", f"closed {took:.1f} s after the DS's last TCP frame, 5 s expected", figures)
        else:
            run.passed("F12", f"closed {took:.1f} s after the DS's last TCP frame", figures)


    async def f15(self) -> None:
        """The DS F12 silenced (the last station's) logs in again as a 2027 DS, from its address,
        naming a UDP port of its own: the reply and the control that comes there are judged."""
        run = self.run
        d = self.dses[-1] if self.dses else None
        if d is None:
            run.not_applicable("F15", "no team of the match has a DS here to log in")
            return
        if d.tcp is not None and d.tcp.is_open:  # F12 did not see it dropped: end that login first
            d.tcp_silent = True
            d.tcp.close()
            await until(lambda: d.tcp is not None and not d.tcp.is_open, 2.0)
        try:
            port = await UdpPort.open(f"ds {d.team} 2027", d.host, 0)
        except OSError as exc:
            run.failed("F15", f"cannot bind a UDP port on {d.host} for the hello: {exc.strerror or exc}")
            return
        try:
            await self._f15(d, port)
        finally:
            port.close()

    async def _f15(self, d: FakeDs, port: UdpPort) -> None:
        run = self.run
        s = await self._connect("hello-2027", d.host)
        if s is None:
            run.failed("F15", "could not connect to TCP 1750")
            return
        udp_port = port.address[1]
        hello = DsHello.for_team(d.team, udp_port).encode()
        s.send(hello)
        t0 = time.monotonic()
        await until(lambda: s.frames or not s.is_open, 3.0)
        ev = [_tcp_ev(run, t0, hello, f"team {d.team}'s 2027 hello from {d.host}, control to UDP {udp_port}", "sent")]
        if not s.frames:
            s.close()
            how = "closed the connection without a reply" if not s.is_open else "sent nothing in 3 s"
            run.not_applicable("F15", f"the FMS {how} after a 2027 hello: it takes the NI DS's login only "
                                      "(as the FMS did before 2027), so the 2027 path is not there to judge")
            return
        f = s.frames[0]
        ev.append(_tcp_ev(run, f.at, f.data, "the FMS's answer"))
        try:
            msg = fms_to_ds.decode_tcp(f.data)
        except ProtocolError as exc:
            s.close()
            run.failed("F15", f"the answer to a 2027 hello does not decode: {exc}", evidence=ev)
            return
        if type(msg) is not HelloReply:
            s.close()
            run.failed("F15", f"answered a 2027 hello with {type(msg).__name__} (frame 0x{f.data[2]:02x}), not the "
                              "hello reply 0x1f", evidence=ev)
            return
        if (msg.station, msg.status, msg.team) != (d.station, StationStatus.GOOD, d.team):
            s.close()
            run.failed("F15", f"hello reply: station {msg.station.label}, status {int(msg.status)}, team {msg.team}; "
                              f"team {d.team} is at {d.station.label}, status 0 (good) expected", evidence=ev)
            return
        await until(lambda: len(port.received) >= 2, 3.0, 0.05)
        s.close()
        got = list(port.received)
        if not got:
            run.failed("F15", f"no control packet to UDP {udp_port}, the port the hello named, within 3 s of the "
                              f"reply (the NI DS's ports 1121/1120 had {len(d.good(t0))} since)", evidence=ev)
            return
        a = got[-1]
        ev.append(Evidence("received", run.since(a.at), f"a control packet to UDP {udp_port}", "fms-to-ds", a.data))
        try:
            pkt = fms_to_ds.decode_control(a.data)
        except ProtocolError as exc:
            run.failed("F15", f"a control packet to the hello's port does not decode: {exc}", evidence=ev)
            return
        if pkt.station != d.station:
            run.failed("F15", f"the control packet to the hello's port names station {pkt.station.label}, not "
                              f"{d.station.label}", evidence=ev)
            return
        lite = "FMS Lite" if msg.fms_lite else "not FMS Lite"
        run.passed("F15", f"hello reply {f.data.hex(' ')} ({d.station.label}, good, {lite}, team {d.team}); "
                          f"{len(got)} control packets to UDP {udp_port}, the port the hello named",
                   {"reply_s": round(f.at - t0, 3), "flags": msg.flags}, ev)


async def conform_fms(opts: FmsOptions, err: Any = None) -> Run:
    run = Run("fms", opts.address, list(CASES), selected=opts.cases)
    return await FmsConformance(opts, run, err).execute()
