"""``fieldbox conform ds ADDRESS``: fieldbox plays the robot and the FMS and checks a Driver
Station (the NI DS, fieldbox's DS, any other implementation) at ADDRESS.

The robot side listens on ``--robot-bind`` UDP 1110 and 1115 and TCP 1740, and answers each
control packet from ADDRESS at once, to ADDRESS port 1150, as a roboRIO does (status echo,
robot code, 12.5 V, request-date until the date comes). The FMS side (unless ``--no-fms``)
listens on ``--fms-bind`` TCP 1750 and UDP 1160, answers the login (station info, event
code, game data, a challenge question) and, once the cases need it, sends control packets
from UDP 1160 to ADDRESS port 1121 (and 1120) every 500 ms. Point the DS under test at
these addresses: its robot at ``--robot-bind``, its FMS at ``--fms-bind``.

Enabling a DS without an FMS takes a person (``--enable prompt``) or the DS's own scripting
(``--enable stdin:enable`` with ``--launch``); the case that needs it is not applicable
without. A joystick in slot 0 (``--joystick``) lets the joystick tags be checked.
"""

from __future__ import annotations

import asyncio
import datetime as _dt
import struct
import sys
import time
from dataclasses import dataclass
from statistics import mean, median
from typing import Any, Callable

from protocol import ds_to_fms, ds_to_rio
from protocol.ds_to_fms import DsStatusPacket, TeamNumber, challenge_answer
from protocol.ds_to_rio import ControlPacket, Date, Joystick, JoystickDescriptor, MatchInfo, Timezone
from protocol.enums import AllianceStation, MatchType, Mode
from protocol.errors import ProtocolError
from protocol.frames import MalformedTag
from protocol.wire import UnknownTag

from .fms_side import DS_FMS_UDP, DS_FMS_UDP_LITE, EVENT_CODE, GAME_DATA, MATCH_NUMBER, FakeFms
from .hooks import Hook, Launched
from .model import Case, Evidence, Run, SetupError, judge
from .net import Arrival, FrameStream, UdpPort, resolve, until
from .robot_side import DS_UDP, ROBOT_UDP_FMS, ROBOT_VOLTS, Control, FakeRobot
from .sources import CORRECTIONS, DS_DETAILS, DS_FMS, FIELD, SEED_D2R, SEED_F2D, TRAPS

CASES = (
    Case("D01", "A steady 20 ms period",
         "Control packets go out every 20 ms, steadily: the median interval within 20 +- 2 ms; the jitter "
         "(|interval - 20 ms|) at the median not well above conform's own 20 ms timer's lateness in the same "
         "seconds (p99 reported); no long gap a robot's 100 ms watchdog would feel, beyond what the host "
         "explains.",
         (f'{SEED_D2R}: "Sent every 20ms to the RoboRIO"', f"{CORRECTIONS}: LibDS sends every ~25.5 ms instead of 20")),
    Case("D02", "Sequence numbers step by one",
         "Each control packet's u16 sequence is the last one's plus one (mod 65536); a step of two is a lost "
         "packet on a real network, allowed for at most 2 % of packets.",
         (f"{SEED_D2R} UDP table: Sequence Num", f'{CORRECTIONS}: "open-ds steps its sequence by 2"')),
    Case("D03", "No duplicate datagrams",
         "Each control packet is sent once: at most 1 % of datagrams repeat the last one.",
         (f'{CORRECTIONS}: "LibDS sends every datagram twice"',)),
    Case("D04", "Header: comm version 0x01, request 0x10, no reboot or restart asked",
         "Comm version 0x01; the request byte has a DS-attached bit (0x10 in normal operation: WPILib's "
         "simulator treats a DS as attached only when one of the high four bits is set) and never asks "
         "a reboot (0x08) or a code restart (0x04) unasked.",
         (f'{DS_DETAILS}: "Request byte: 0x08 reboot roboRIO, 0x04 restart code ... Send 0x10 in normal '
          'operation"', f'{CORRECTIONS}: "Request byte: the real DS sent 0x10 normally"',
          f'{CORRECTIONS}: LibDS "never clears a reboot request"')),
    Case("D05", "Every tag walks cleanly",
         "Each tag's size byte counts its id and data, and the data is laid out as documented: countdown "
         "0x07 an f32, date 0x0f ten bytes, time zone 0x10 text.",
         (f"{SEED_D2R} Tags", f'{CORRECTIONS}: "LibDS ... timezone tags one byte short"')),
    Case("D06", "Joystick tags: size and layout",
         "A joystick tag is [size][0x0c][axis count][int8 axes][button count][ceil(n/8) bytes][POV count]"
         "[int16 POVs]; its size byte counts exactly those; at most six tags, 12 axes, 32 buttons.",
         (f"{SEED_D2R} Joystick 0x0c", f'{DS_DETAILS}: "Buttons: ceil(count/8) bytes"',
          f'{CORRECTIONS}: "LibDS ... writes joystick tags with a wrong size byte (2015/2016: payload + 2; '
          '2020: off by buttons - 1)"', f"{TRAPS}: a joystick tag whose size byte is off by one, or that always "
          "writes two button bytes"), needs="a joystick in slot 0 (--joystick)"),
    Case("D07", "Date and time zone once, after request-date, and right",
         "When the robot sets request-date the DS sends date 0x0f (microseconds, second, minute, hour UTC, day, "
         "month 0-based, year - 1900) and time zone 0x10, once; the date is the DS's clock (within 10 minutes "
         "of fieldbox's).",
         (f'{DS_DETAILS}: "Date (0x0f) and timezone (0x10) tags go out when the robot sets request-date, once. '
          'Month is 0-based, year is years since 1900, hour UTC"', f'{CORRECTIONS} "Date tag": '
          '0b 0f 000377c7 04 06 14 01 05 79 is 2021-06-01 20:06:04.227271Z', f"{TRAPS}: date tags that send "
          "the epoch because the clock was never read")),
    Case("D08", "Joystick descriptors over TCP 1740 on connect",
         "On connecting to TCP 1740 the DS sends a joystick descriptor (0x02) for each of the six slots, "
         "empty ones included, each laid out as documented.",
         (f'{DS_DETAILS}: "joystick descriptors (0x02) on connect and on any change, one per slot, empty slots '
          'included"', f"{SEED_D2R} TCP Joystick Descriptor 0x02")),
    Case("D09", "Match info and game data from the FMS, over TCP 1740",
         "Attached to an FMS, the DS forwards the event code, match type and number (frame 0x07, with its "
         "u16 match number and u8 replay) and the game data (frame 0x0e) to the robot.",
         (f'{DS_DETAILS}: "match info (0x07: u8-length competition name, u8 match type ..., u16 match number, '
          'u8 replay); game data (0x0e: raw text to the end of the frame)"', f"{SEED_F2D} TCP Event Code 0x14, "
          "Game Data 0x1c", f'{CORRECTIONS} "Match info 0x07"'), needs="the FMS played (not --no-fms)"),
    Case("D10", "A comms loss disables; re-enable by hand",
         "A DS counts robot comms lost after about 1 s without status packets (open DSes use 1-2 s) and "
         "disables; when the robot answers again the DS stays disabled until enabled by hand.",
         (f'{DS_DETAILS}: "A DS counts robot comms as lost after about 1 s without status packets ...; after a '
          'loss the robot must be re-enabled by hand"',), needs="--enable"),
    Case("D11", "FMS login: the team number first",
         "The first frame on TCP 1750 is the login, for the DS's own team: the team number, 00 03 18 hi lo "
         "(the NI DS), or the 2027 FIRST Driver Station's hello, tag 30: u16 UDP port for the FMS's control, "
         "u8 flags, u8 length, the team number in ASCII digits.",
         (f'{DS_FMS}: "0x18 team number ... Sent first, right after connecting: it is the login"',
          f'{FIELD}: "A TCP connection whose first frame is not a team-number frame (00 03 18 hi lo) is '
          'closed without a reply"',
          f"{CORRECTIONS}: Cheesy Arena's 2027 DS hello: DS -> FMS TCP tag 30 [size u16][30][UDP reply port "
          "u16][flags u8][team length u8][team number in ASCII]"), needs="the FMS played"),
    Case("D12", "The challenge answered right",
         "The DS answers a challenge question (0x1a, u16 random value) with 0x1b and the robot name at "
         "index (team * random) % 23.",
         (f'{DS_FMS}: "Challenge response"',), needs="the FMS played"),
    Case("D13", "TCP keep-alive",
         "A DS sends a frame on TCP 1750 at least every 5 s (a DS ping, 0x1d or 0x1c, or any frame): an FMS "
         "drops a DS after 5 s without one.",
         (f'{DS_FMS}: "0x1c / 0x1d DS ping (keep-alive)"', f'{FIELD}: "A DS counts as lost after ... 5 s '
          'without any TCP frame"'), needs="the FMS played"),
    Case("D14", "UDP status at least every 500 ms",
         "While an FMS is known the DS sends its status to UDP 1160 at least every 500 ms (median at most "
         "550 ms; 95 % of gaps under 1 s, when the FMS would count it lost).",
         (f'{DS_FMS}: "UDP status, at least every 500 ms while an FMS is known"', f'{FIELD}: "A DS counts as '
          'lost after 1 s without UDP status"'), needs="the FMS played"),
    Case("D15", "UDP status: team, battery, robot comms and tags",
         "The status carries comm version 0x00, the DS's team, the robot's battery as the robot reports it "
         "(high byte volts, low byte /256), the robot-comms bit 0x20 while the robot answers, and tags laid "
         "out as documented (comms metrics 0x01: u16 lost, u16 sent, u8 trip ms).",
         (f"{DS_FMS}: the status table and its UDP tags",), needs="the FMS played"),
    Case("D16", "Obeys the FMS: attach, mode and enable",
         "On the FMS's first control packet (UDP 1121) the DS attaches: its control packets go to the robot's "
         "UDP 1115 with the FMS bit 0x08; it follows the FMS's mode and enable within a second.",
         (f'{SEED_D2R}: "UDP port 1110 (port 1115 when connected to FMS)"', f"{SEED_D2R} Control table: "
          "FMS Connected 0x08", f"{SEED_F2D} UDP Control table"), needs="the FMS played"),
    Case("D17", "Takes FMS control on 1120 too",
         "A DS listens for FMS control on UDP 1121 and on 1120, where an FMS in \"FMS Lite\" mode sends.",
         (f'{FIELD}: "sends control packets ... UDP 1121, or 1120 in \\"FMS Lite\\" mode: a DS listens on both"',
          f'{SEED_F2D}: "UDP port 1121 ... (Was 1120, changed at some point?)"'), needs="the FMS played"),
    Case("D18", "A-stop disables until auto ends",
         "An FMS a-stop (control 0x40) in auto disables the robot; in teleop the FMS's enable counts again.",
         (f'{FIELD}: "Control byte: 0x80 e-stop, 0x40 a-stop (autonomous stop) ... a-stop latches until auto '
          'ends"',), needs="the FMS played"),
    Case("D19", "E-stop from the FMS",
         "An FMS e-stop (control 0x80) e-stops the robot within a second: control 0x80 to the robot, and the "
         "DS's own status says e-stop.",
         (f'{FIELD}: "Control byte: 0x80 e-stop"', f"{SEED_F2D} UDP Control table: E-Stop",
          f"{SEED_D2R} Control table: E-Stop"), needs="the FMS played"),
)

#: The cases that need fieldbox to play the FMS.
FMS_CASES = ("D09", "D11", "D12", "D13", "D14", "D15", "D16", "D17", "D18", "D19")
FOLLOW = 1.5  # seconds a DS gets to follow the FMS (the rule says within a second; +0.5 s for the wire)
SETTLE = 0.5  # seconds after its first control packet before D01-D04 start measuring a DS
SILENCE = 0.5  # seconds without a control packet that D01 reports as a silence (a robot disables at 0.1)
WATCHDOG_MS = 100.0  # a robot disables after this long without a control packet
#: D01 fails a DS for any gap this much longer than the watchdog (and the host's own worst
#: lateness), or for gaps over the watchdog in more than GAPS_ALLOWED of its intervals: a DS
#: starved once or twice by a busy host is excused, a silence every robot feels is not.
LONG_GAP_MS = 400.0
GAPS_ALLOWED = 0.02


def _pct(values: list[float], q: float) -> float:
    """The ``q`` quantile of ``values`` (sorted), the nearest rank below."""
    return values[min(len(values) - 1, int(q * len(values)))] if values else 0.0


async def _host_clock(late: list[float]) -> None:
    """conform's own 20 ms timer, for as long as D01-D04 measure: how late each wake-up was, in
    ms. Arrival times are taken when conform's loop reads a datagram, so a busy host's
    lateness is in every interval measured: this is how much of a DS's jitter the host explains."""
    start = time.monotonic()
    k = 0
    while len(late) < 100_000:
        k += 1
        await asyncio.sleep(max(0.0, start + k * 0.020 - time.monotonic()))
        now = time.monotonic()
        late.append(max(0.0, (now - (start + k * 0.020)) * 1000))
        k = max(k, int((now - start) / 0.020))  # late: the next slot after now, never a burst


@dataclass
class DsOptions:
    address: str  # the DS's host
    team: int
    station: AllianceStation = AllianceStation.RED1
    robot_bind: str = "0.0.0.0"
    fms_bind: str = "0.0.0.0"
    fms: bool = True
    launch: str | None = None
    launch_cwd: str | None = None
    wait: float = 30.0
    enable_hook: str | None = None
    joystick_hook: str | None = None
    cases: frozenset[str] | None = None
    reply_port: int = DS_UDP
    measure: float = 5.0  # seconds of control packets at 20 ms D01-D04 measure (measure / 20 ms packets)
    measure_more: float = 15.0  # seconds longer D01-D04 wait for the packets a stalled DS owes





# -- evidence -------------------------------------------------------------------------------------
def _ctl(run: Run, c: Control, note: str) -> Evidence:
    return Evidence("received", run.since(c.at), note, "ds-to-rio", c.data)


def _frame_ev(run: Run, at: float, data: bytes, note: str, kind: str, direction: str = "received") -> Evidence:
    return Evidence(direction, run.since(at), note, kind, data)


def joystick_size_problem(tag: Any) -> str | None:
    """Why a joystick tag's bytes are not laid out as documented, or None."""
    raw = bytes(tag.raw) if type(tag) is MalformedTag else None
    if raw is None:
        return None
    if len(raw) < 3:
        return f"size byte {raw[0] if raw else '?'}: too short for any joystick"
    size = raw[0]
    body = raw[2:]
    try:
        n_axes = body[0]
        n_buttons = body[1 + n_axes]
        n_povs = body[2 + n_axes + (n_buttons + 7) // 8]
    except IndexError:
        return f"size byte {size}: the counts inside run past the tag ({tag.reason})"
    need = 1 + 1 + n_axes + 1 + (n_buttons + 7) // 8 + 1 + 2 * n_povs
    if need != size:
        return (f"size byte {size}, but {n_axes} axes, {n_buttons} buttons ({(n_buttons + 7) // 8} bytes) and "
                f"{n_povs} POVs need {need} (off by {size - need:+d})")
    return tag.reason


@dataclass(frozen=True)
class HeadlessDate:
    """LibDS's date (2020 protocol): the tag id 0x0f with no size byte before it, then the ten
    date bytes, then its time zone written id first (``10 length name``). A robot walking the
    tags reads a tag of 15 bytes with id 0x00 and never a date, so it keeps asking, and LibDS,
    which sends the date instead of joysticks while the robot asks, never sends a joystick."""

    control: Control
    date: Date
    timezone: str | None


def headless_date(c: Control) -> HeadlessDate | None:
    """The date tag without its size byte in ``c``, if any (only looked for where no date tag
    decodes): 0x0f at a tag's start with the time zone's id 0x10 (or the packet's end) eleven
    bytes on."""
    data, pos = c.data, 6
    while pos + 11 <= len(data):
        if data[pos] == ds_to_rio.TAG_DATE and (pos + 11 == len(data) or data[pos + 11] == ds_to_rio.TAG_TIMEZONE):
            date = Date(*struct.unpack_from(">IBBBBBB", data, pos + 1))
            tz = None
            if pos + 13 <= len(data):
                tz = data[pos + 13:pos + 13 + data[pos + 12]].decode("latin-1")
            return HeadlessDate(c, date, tz)
        if data[pos] == 0:
            return None
        pos += 1 + data[pos]
    return None


def date_words(d: Date) -> str:
    """The date a date tag's ten bytes name, as they are (a day 0 is shown as sent), and what
    is odd about it: ``1970-01-00 00:00:00.000000 UTC (day 0 is no day of the month; the epoch:
    the DS's clock was never read)``."""
    text = (f"{d.year + 1900:04d}-{d.month + 1:02d}-{d.day:02d} {d.hour:02d}:{d.minute:02d}:{d.second:02d}"
            f".{min(d.microseconds, 999_999):06d} UTC")
    notes = []
    if not 1 <= d.day <= 31:
        notes.append(f"day {d.day} is no day of the month" + ("; LibDS writes the day of the year, 0-based"
                                                                if d.day == 0 else ""))
    try:
        approx = _dt.datetime(d.year + 1900, min(d.month, 11) + 1, max(1, min(d.day, 28)), min(d.hour, 23),
                              tzinfo=_dt.timezone.utc)
    except (ValueError, OverflowError):
        approx = None
    if approx is not None and abs(approx - _dt.datetime(1970, 1, 1, tzinfo=_dt.timezone.utc)) <= _dt.timedelta(days=2):
        notes.append("the epoch, 1970-01-01: the DS's clock was never read")
    return text + (f" ({'; '.join(notes)})" if notes else "")


class DsConformance:
    def __init__(self, opts: DsOptions, run: Run, err: Any = None) -> None:
        self.o = opts
        self.run = run
        self.err = err or sys.stderr
        self.robot = FakeRobot(opts.address, opts.reply_port)
        self.fms = FakeFms(opts.team, opts.station, opts.address) if opts.fms else None
        self.launched: Launched | None = None
        self.t_first: float | None = None
        self.beat_wait = 0.0  # seconds D01-D04 waited for their packets
        self.host_late: list[float] = []  # ms each wake-up of conform's own 20 ms timer was late then
        self.joystick_note: str | None = None  # what --joystick's hook did, if given

    @property
    def fake_fms(self) -> FakeFms:
        """The FMS fieldbox plays: the FMS cases (D09, D11-D19) run only with one (not --no-fms)."""
        assert self.fms is not None
        return self.fms

    @property
    def fms_udp(self) -> UdpPort:
        """The played FMS's UDP port, open once set up."""
        udp = self.fake_fms.udp
        assert udp is not None
        return udp

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
            o.address = self.robot.ds_host = await resolve(o.address)
        except OSError as exc:
            raise SetupError(f"cannot find the DS {o.address}: {exc.strerror or exc}") from None
        if self.fms is not None:
            self.fms.ds_host = o.address
        try:
            await self.robot.start(o.robot_bind)
        except OSError as exc:
            self.robot.close()
            raise SetupError(f"cannot bind the robot side on {o.robot_bind} (UDP 1110/1115, TCP 1740): "
                             f"{exc.strerror or exc}") from None
        run.notes.append(f"fieldbox plays the robot on {o.robot_bind} (UDP 1110/1115, TCP 1740), answering "
                         f"{o.address}:{o.reply_port}")
        if self.fms is not None:
            try:
                await self.fms.start(o.fms_bind)
            except OSError as exc:
                raise SetupError(f"cannot bind the FMS side on {o.fms_bind} (TCP 1750, UDP 1160): "
                                 f"{exc.strerror or exc}") from None
            run.notes.append(f"fieldbox plays the FMS on {o.fms_bind} (TCP 1750, UDP 1160), team {o.team} at "
                             f"{o.station.label}")
        if o.launch:
            try:
                self.launched = await Launched.start(o.launch, o.launch_cwd)
            except (OSError, ValueError) as exc:
                raise SetupError(f"cannot launch {o.launch!r}: {exc}") from None
            run.notes.append(f"launched: {o.launch}")

    async def _teardown(self) -> None:
        if self.launched is not None:
            await self.launched.stop()
        if self.fms is not None:
            await self.fms.close()
        await self.robot.tcp.close()
        self.robot.close()

    async def _guard(self, cid: str, step: Callable[[], Any], retries: int = 0) -> None:
        await judge(self.run, cid, step, self.err, retries)

    def _wants(self, *cids: str) -> bool:
        return any(self.run.wanted(c) for c in cids)

    async def _hook(self, spec: str | None, what: str) -> tuple[bool, str]:
        return await Hook(what, spec).fire(self.launched, err=self.err)

    # -- the order of things ---------------------------------------------------------------------
    async def _cases(self) -> None:
        run, robot = self.run, self.robot
        if not await until(lambda: robot.controls, self.o.wait, 0.02):
            why = f"no control packet from {self.o.address} on UDP 1110 in {self.o.wait:g} s"
            if robot.foreign:
                why += f" ({robot.foreign} came from other addresses)"
            if self.launched is not None and not self.launched.running:
                why += f"; the launched program ended: {' | '.join(self.launched.tail(5))}"
            run.failed("D01", why)
            run.finish("no control packets: nothing to check")
            return
        self.t_first = robot.controls[0].at
        if self.o.joystick_hook:
            done, note = await self._hook(self.o.joystick_hook, "attach a joystick to slot 0 of the DS")
            run.notes.append(f"--joystick: {note}")
            self.joystick_note = note if done else None
        # D01-D04 measure the DS left alone; D05-D08 look at what it sent meanwhile
        if self._wants("D01", "D02", "D03", "D04"):
            window = await self._beat_window()
        else:
            await asyncio.sleep(1.0)
            window = []
        for cid, step in (("D01", lambda: self.d01(window)), ("D02", lambda: self.d02(window)),
                          ("D03", lambda: self.d03(window)), ("D04", lambda: self.d04(window))):
            await self._guard(cid, step)
        await self._guard("D10", self.d10, retries=1)
        if self.fms is not None:
            await self._fms_sequence()
        else:
            for cid in FMS_CASES:
                if run.wanted(cid) and cid != "D09":
                    run.not_applicable(cid, "--no-fms: fieldbox does not play the FMS")
        for cid, step in (("D05", self.d05), ("D06", self.d06), ("D07", self.d07), ("D08", self.d08)):
            await self._guard(cid, step)
        if self.fms is None:
            await self._guard("D09", self.d09_offline)

    # -- D01-D04: the beat ----------------------------------------------------------------------------
    async def _beat_window(self) -> list[Control]:
        """The control packets D01-D04 judge: those that came from SETTLE after the first one
        until ``measure`` seconds' worth at 20 ms have come, waiting up to ``measure_more`` seconds
        longer for a DS that stalls (open-ds sends one packet, then nothing for 6 s): a window
        of packets that actually came, never a fixed span of time that may hold none."""
        assert self.t_first is not None
        start, need = self.t_first + SETTLE, max(20, round(self.o.measure / 0.020))
        t0 = time.monotonic()
        clock = asyncio.get_running_loop().create_task(_host_clock(self.host_late))
        try:
            await until(lambda: len(self._distinct(self.robot.good(start))) >= need,
                        SETTLE + self.o.measure + self.o.measure_more, 0.05)
        finally:
            clock.cancel()
            await asyncio.gather(clock, return_exceptions=True)
        self.beat_wait = time.monotonic() - t0
        return self.robot.good(start)

    def _silence(self, window: list[Control]) -> tuple[float, float] | None:
        """The DS's longest silence from its first control packet to the window's end: (its
        length, when it began after the first packet), in seconds; None if it sent nothing more."""
        assert self.t_first is not None
        end = window[-1].at if window else self.t_first
        sent = [c.at for c in self.robot.controls if self.t_first <= c.at <= end]
        if len(sent) < 2:
            return None
        gap, at = max((b - a, a) for a, b in zip(sent, sent[1:]))
        return gap, at - self.t_first

    def _empty_why(self, window: list[Control], what: str) -> str:
        """Why a case of the beat has nothing to judge: how many came and how long it waited."""
        waited = self.beat_wait
        came = f"{len(window)} {what}" if window else f"no {what}"
        return (f"{came} came from {self.o.address} in {waited:.1f} s after its first control packet "
                f"(at least {max(20, round(self.o.measure / 0.020))} wanted): nothing to judge")

    @staticmethod
    def _distinct(window: list[Control]) -> list[Control]:
        out: list[Control] = []
        for c in window:
            if out and c.data == out[-1].data:
                continue
            out.append(c)
        return out

    async def d01(self, window: list[Control]) -> None:
        run = self.run
        assert self.t_first is not None  # set before D01-D04 run
        packets = self._distinct(window)
        silence = self._silence(window)
        if len(packets) < 20:
            why = self._empty_why(packets, "distinct control packets")
            if silence is not None and silence[0] >= SILENCE:
                why += f"; it was silent for {silence[0]:.1f} s from {silence[1]:.1f} s after its first packet"
            run.not_applicable("D01", why)
            return
        gaps = [(b.at - a.at) * 1000 for a, b in zip(packets, packets[1:])]
        jit = sorted(abs(g - 20.0) for g in gaps)
        host = sorted(self.host_late)
        # What the host explains: conform's own timer's lateness in the same seconds. A DS is
        # judged against it, so a busy machine excuses what it causes and no more.
        jitter_p50, jitter_p99 = _pct(jit, 0.5), _pct(jit, 0.99)
        host_p50, host_p99, host_max = _pct(host, 0.5), _pct(host, 0.99), host[-1] if host else 0.0
        allow_p50 = 2.0 + host_p50  # the typical interval: a DS's own swing, not a hiccup of the host's
        allow_gap = WATCHDOG_MS + host_max
        long_gaps = [(g, a) for g, a in zip(gaps, packets) if g > allow_gap]
        figures: dict[str, Any] = {
            "packets": len(packets), "mean_ms": round(mean(gaps), 2), "median_ms": round(median(gaps), 2),
            "jitter_p50_ms": round(jitter_p50, 2), "jitter_p99_ms": round(jitter_p99, 2),
            "max_ms": round(max(gaps), 1), "gaps_over_watchdog": len(long_gaps),
            "longest_silence_s": round(silence[0], 2) if silence else None,
            "host_late_p50_ms": round(host_p50, 2), "host_late_p99_ms": round(host_p99, 2),
            "host_late_max_ms": round(host_max, 1),
            "allowed": f"median 20 +- 2 ms; jitter (|interval - 20 ms|) at the median at most 2 ms + the "
                       f"host's ({allow_p50:.1f} ms; p99 reported); gaps over {WATCHDOG_MS:.0f} ms (a "
                       f"robot's watchdog) + the host's own worst lateness ({allow_gap:.0f} ms) in at most "
                       f"{GAPS_ALLOWED:.0%} of intervals, and none over {allow_gap + LONG_GAP_MS:.0f} ms"
        }
        wrong = []
        evidence_at = 10
        if abs(figures["median_ms"] - 20.0) > 2.0:
            wrong.append(f"median interval {figures['median_ms']} ms (mean {figures['mean_ms']} ms)")
        if jitter_p50 > allow_p50:
            wrong.append(f"half the intervals are more than {jitter_p50:.1f} ms off 20 ms (conform's own timer was "
                         f"{host_p50:.1f} ms late at the median: at most {allow_p50:.1f} ms is the host's doing)")
            evidence_at = max(range(len(gaps)), key=lambda i: abs(gaps[i] - 20.0))
        worst = max(long_gaps, key=lambda gap: gap[0], default=None)
        if worst is not None and (worst[0] > allow_gap + LONG_GAP_MS or len(long_gaps) > GAPS_ALLOWED * len(gaps)):
            gap, before = worst
            wrong.append(f"{len(long_gaps)} gap{'s' if len(long_gaps) != 1 else ''} over {allow_gap:.0f} ms, the "
                         f"longest {gap:.0f} ms at {before.at - self.t_first:.1f} s after its first packet (a "
                         f"robot disables after {WATCHDOG_MS:.0f} ms without a packet; conform's own timer was at "
                         f"worst {host_max:.0f} ms late)")
            evidence_at = packets.index(before)
        quiet = ""
        if silence is not None and silence[0] >= SILENCE:
            quiet = f"; the DS was silent for {silence[0]:.1f} s from {silence[1]:.1f} s after its first packet"
            if self.t_first + silence[1] + silence[0] <= packets[0].at:
                quiet += " (measured over the packets that came after)"
        if wrong:
            i = min(evidence_at, len(packets) - 2)
            run.failed("D01", "; ".join(wrong) + ", where the rule is 20 ms" + quiet, figures,
                       [_ctl(run, packets[i], "a control packet"), _ctl(run, packets[i + 1], "the next one")])
        else:
            run.passed("D01", f"median interval {figures['median_ms']} ms (mean {figures['mean_ms']} ms), jitter "
                              f"{jitter_p50:.1f} ms at the median and {jitter_p99:.1f} ms at p99 (conform's own "
                              f"timer: {host_p50:.1f} and {host_p99:.1f} ms late), longest interval "
                              f"{figures['max_ms']:.0f} ms, over {len(packets)} packets{quiet}", figures)

    async def d02(self, window: list[Control]) -> None:
        run = self.run
        packets = self._distinct(window)
        steps = [((b.pkt.sequence - a.pkt.sequence) & 0xFFFF, a, b) for a, b in zip(packets, packets[1:])]
        if len(steps) < 10:
            run.not_applicable("D02", self._empty_why(packets, "distinct control packets"))
            return
        off = [s for s in steps if s[0] != 1]
        counts: dict[int, int] = {}
        for step, _, _ in steps:
            counts[step] = counts.get(step, 0) + 1
        figures = {"steps": {str(k): v for k, v in sorted(counts.items())}, "allowed": "2 % of steps not 1"}
        if len(off) > 0.02 * len(steps):
            step, a, b = off[0]
            run.failed("D02", f"{len(off)} of {len(steps)} sequence steps are not 1 (the first: "
                              f"{a.pkt.sequence} to {b.pkt.sequence}, a step of {step})", figures,
                       [_ctl(run, a, "a control packet"), _ctl(run, b, "the next one")])
        else:
            run.passed("D02", f"{len(steps) - len(off)} of {len(steps)} steps are 1", figures)

    async def d03(self, window: list[Control]) -> None:
        run = self.run
        if len(window) < 10:
            run.not_applicable("D03", self._empty_why(window, "control packets"))
            return
        dups = [(a, b) for a, b in zip(window, window[1:]) if a.data == b.data]
        figures = {"datagrams": len(window), "duplicates": len(dups), "allowed": "1 %"}
        if len(dups) > 0.01 * len(window):
            a, b = dups[0]
            gap = (b.at - a.at) * 1000
            run.failed("D03", f"{len(dups)} of {len(window)} datagrams repeat the one before (the first "
                              f"{gap:.1f} ms after it)", figures, [_ctl(run, a, "a control packet"),
                                                                   _ctl(run, b, "the same bytes again")])
        else:
            run.passed("D03", f"{len(dups)} duplicates in {len(window)} datagrams", figures)

    async def d04(self, window: list[Control]) -> None:
        run = self.run
        if not window:
            run.not_applicable("D04", self._empty_why(window, "control packets"))
            return
        for c in window:
            p = c.pkt
            if p.comm_version != 0x01:
                run.failed("D04", f"comm version 0x{p.comm_version:02x}, 0x01 expected", evidence=[_ctl(run, c, "")])
                return
            if not p.request_byte & 0xF0:
                run.failed("D04", f"request byte 0x{p.request_byte:02x} has no DS-attached bit (0x10): WPILib's "
                                  "simulator then sees no DS", evidence=[_ctl(run, c, "a control packet")])
                return
            if p.reboot_roborio or p.restart_code:
                what = "a roboRIO reboot (0x08)" if p.reboot_roborio else "a code restart (0x04)"
                run.failed("D04", f"the DS asks {what} though nobody asked it to", evidence=[_ctl(run, c, "")])
                return
        values = sorted({c.pkt.request_byte for c in window})
        run.passed("D04", "comm version 0x01, request byte " + ", ".join(f"0x{v:02x}" for v in values)
                   + f" in {len(window)} control packets",
                   {"request_bytes": [f"0x{v:02x}" for v in values]})

    # -- D05-D08: what it sent ------------------------------------------------------------------------
    async def d05(self) -> None:
        run = self.run
        seen: dict[str, int] = {}
        after_joystick = 0
        for c in self.robot.controls:
            if c.packet is None:
                run.failed("D05", f"a control packet does not decode: {c.error}", evidence=[_ctl(run, c, "")])
                return
            if any(type(t) is MalformedTag and t.tag_id == ds_to_rio.TAG_JOYSTICK for t in c.packet.tags):
                after_joystick += 1  # what follows a joystick tag of the wrong size is D06's finding
                continue
            for tag in c.packet.tags:
                name = type(tag).__name__
                if type(tag) is MalformedTag:
                    run.failed("D05", f"a malformed tag: {tag.reason}", {"tags": seen},
                               [_ctl(run, c, "the control packet")])
                    return
                if type(tag) is UnknownTag:
                    name = f"unknown 0x{tag.tag_id:02x}"
                seen[name] = seen.get(name, 0) + 1
        figures: dict[str, Any] = {"tags": seen}
        checked = len(self.robot.controls) - after_joystick
        if after_joystick:
            figures["skipped"] = f"{after_joystick} packets with a malformed joystick tag (see D06)"
        if not checked:
            run.not_applicable("D05", "every control packet had a malformed joystick tag (D06): what follows one "
                                      "cannot be read", figures)
            return
        run.passed("D05", f"{checked} control packets walk cleanly", figures)

    async def d06(self) -> None:
        run = self.run
        tags = 0
        bad: tuple[Control, Any] | None = None
        for c in self.robot.controls:
            if c.packet is None:
                continue
            joys: list[Joystick | MalformedTag] = [t for t in c.packet.tags if type(t) is Joystick
                    or (type(t) is MalformedTag and t.tag_id == ds_to_rio.TAG_JOYSTICK)]
            if len(joys) > 6:
                run.failed("D06", f"{len(joys)} joystick tags in one packet, six at most",
                           evidence=[_ctl(run, c, "the control packet")])
                return
            for t in joys:
                tags += 1
                if isinstance(t, MalformedTag):  # (neither class has subclasses)
                    # the most telling one: a joystick with values, if any, else the first
                    if bad is None or (len(t.raw) > len(bad[1].raw)):
                        bad = (c, t)
                elif len(t.axes) > 12 or t.button_count > 32 or len(t.povs) > 12:
                    run.failed("D06", f"a joystick with {len(t.axes)} axes, {t.button_count} buttons, "
                                      f"{len(t.povs)} POVs: more than a robot's arrays hold",
                               evidence=[_ctl(run, c, "the control packet")])
                    return
        if bad is not None:
            c, t = bad
            run.failed("D06", f"a joystick tag not laid out as documented: {joystick_size_problem(t)}",
                       evidence=[_ctl(run, c, "the control packet")])
            return
        if not any(c.packet is not None and c.packet.joysticks and not all(j.is_empty for j in c.packet.joysticks)
                   for c in self.robot.controls):
            dates = self._headless_dates()
            if dates:
                # LibDS sends the date instead of joysticks while the robot asks for it: with no
                # size byte on its date tag the robot never reads it and never stops asking
                run.not_applicable("D06", f"the DS sent the date where joysticks go, in {len(dates)} of "
                                          f"{len(self.robot.controls)} control packets: its date tag has no size "
                                          "byte (D07), so a robot never reads the date and keeps asking for it "
                                          "(request-date), and the DS, sending the date while asked, never sent a "
                                          f"joystick; the date it sent: {date_words(dates[0].date)}",
                                   {"packets_with_headless_date": len(dates), "joystick_tags": tags,
                                    "a_packet": dates[-1].control.data.hex(" ")})
            elif self.joystick_note is not None:
                run.not_applicable("D06", f"the DS sent no joystick values though --joystick was done "
                                          f"({self.joystick_note})" + ("" if tags else "; it sent no joystick tag at all"))
            else:
                run.not_applicable("D06", "the DS sent no joystick values: attach one (--joystick)"
                                   + ("" if tags else "; it sent no joystick tag at all"))
            return
        run.passed("D06", f"{tags} joystick tags, each size byte right", {"joystick_tags": tags})

    async def d07(self) -> None:
        run, robot = self.run, self.robot
        dated = [c for c in robot.controls if c.packet is not None
                 and any(type(t) in (Date, Timezone) for t in c.packet.tags)]
        if not dated:
            dates = self._headless_dates()
            if dates:
                d = dates[0]
                zone = "" if d.timezone is None else (f"; its time zone tag is written id first too (10 "
                                                    f"{len(d.timezone.encode('latin-1')):02x} {d.timezone!r})")
                run.failed("D07", f"the date tag has no size byte: 0f and ten date bytes right where a tag begins "
                                  "(the layout is 0b 0f and ten bytes), so a robot reads a 15-byte tag 0x00 and "
                                  "never the date; it keeps asking (request-date) and the DS sent the date again, "
                                  f"in {len(dates)} control packets; the date it sends: {date_words(d.date)}{zone}",
                           {"packets_with_headless_date": len(dates), "date_bytes": d.control.data.hex()},
                           [_ctl(run, d.control, "the first packet with the date")])
                return
            why = ("no date or time zone tag a robot can read, though every status packet fieldbox's robot sent "
                   "asked for them (request-date 0x01)")
            broken = sum(1 for c in robot.controls if c.packet is not None
                         and any(type(t) is MalformedTag for t in c.packet.tags))
            if broken:
                why += f"; {broken} packets had a malformed tag, and what follows one cannot be read (see D06)"
            run.failed("D07", why)
            return
        first = dated[0]
        date = next((t for t in first.pkt.tags if type(t) is Date), None)
        tz = next((t for t in first.pkt.tags if type(t) is Timezone), None)
        evidence = [_ctl(run, first, "the first packet with the date")]
        if date is None or tz is None:
            run.failed("D07", "date and time zone not in one packet" if date or tz else "", evidence=evidence)
            return
        when = date.to_datetime()
        now = _dt.datetime.fromtimestamp(time.time() - (time.monotonic() - first.at), _dt.timezone.utc)
        figures = {"date": when.isoformat() if when else "not a date", "time_zone": tz.name,
                   "packets_with_date": len(dated), "fieldbox_clock": now.isoformat(timespec="seconds")}
        if when is None:
            run.failed("D07", f"the date tag names no date (month {date.month}, day {date.day})", figures, evidence)
            return
        off = (when - now).total_seconds()
        figures["off_s"] = round(off, 3)
        if abs(off) > 600:
            hint = ""
            if when.year <= 1971:
                hint = ": the epoch, the clock never read?"
            elif 25 * 86400 < abs(off) < 32 * 86400:
                hint = ": a month off, month sent 1-based?"
            elif abs(off) % 1800 < 60 or abs(off) % 1800 > 1740:
                hint = ": whole hours off, local time instead of UTC?"
            run.failed("D07", f"the date is {when.isoformat()}, {off:+.0f} s from fieldbox's clock{hint}",
                       figures, evidence)
            return
        if len(dated) > 1:
            run.failed("D07", f"date tags in {len(dated)} packets, once expected", figures,
                       evidence + [_ctl(run, dated[1], "the date again")])
            return
        if not tz.name:
            run.failed("D07", "an empty time zone", figures, evidence)
            return
        run.passed("D07", f"date {when.isoformat(timespec='seconds')} ({off:+.2f} s), time zone {tz.name!r}, once",
                   figures)

    def _headless_dates(self) -> list[HeadlessDate]:
        """Each control packet with LibDS's date tag without a size byte (and no date that decodes)."""
        out = []
        for c in self.robot.controls:
            if c.packet is not None and not any(type(t) in (Date, Timezone) for t in c.packet.tags):
                found = headless_date(c)
                if found is not None:
                    out.append(found)
        return out

    def _tcp_frames(self) -> list[tuple[FrameStream, Any]]:
        return [(s, f) for s in self.robot.tcp.streams for f in s.frames]

    async def d08(self) -> None:
        run = self.run
        streams = self.robot.tcp.streams
        if not streams:
            run.failed("D08", "the DS never connected to TCP 1740")
            return
        s = streams[0]
        slots: set[int] = set()
        for f in s.frames:
            if f.at > s.opened + 2.0:
                break
            try:
                msg = ds_to_rio.decode_tcp(f.data)
            except ProtocolError as exc:
                if len(f.data) > 2 and f.data[2] != ds_to_rio.FRAME_JOYSTICK_DESCRIPTOR:
                    continue  # judged by the case about that frame (match info and game data: D09)
                run.failed("D08", f"a joystick descriptor does not decode: {exc}",
                           evidence=[_frame_ev(run, f.at, f.data, "a TCP 1740 frame", "ds-to-rio-tcp")])
                return
            if type(msg) is JoystickDescriptor:
                slots.add(msg.index)
        if s.error is not None:
            run.failed("D08", f"TCP 1740 framing error: {s.error}")
            return
        if slots != set(range(6)):
            run.failed("D08", f"descriptors for slots {sorted(slots)} within 2 s of connecting; 0-5 expected",
                       evidence=[_frame_ev(run, f.at, f.data, "a frame on connect", "ds-to-rio-tcp")
                                 for f in list(s.frames)[:3]])
            return
        run.passed("D08", "six descriptors (slots 0-5) on connect")

    # -- D10 ----------------------------------------------------------------------------------------
    async def d10(self) -> None:
        run, robot = self.run, self.robot
        if not self.o.enable_hook:
            run.not_applicable("D10", "no --enable: enabling a DS without an FMS takes a person (--enable prompt) "
                                      "or its own scripting")
            return
        recent = robot.good(time.monotonic() - 0.2)
        if recent and recent[-1].pkt.enabled:
            # still enabled (a try before left it so, a DS that never disabled): firing the hook
            # again would disable a DS whose enable is a toggle (open-ds), undoing the finding
            done, note = True, "the DS was still enabled: --enable not fired again"
            t0 = recent[-1].at
        else:
            done, note = await self._hook(self.o.enable_hook, "enable the Driver Station")
            t0 = time.monotonic()
        if not done or not await until(lambda: any(c.pkt.enabled for c in robot.good(t0)), 10.0):
            run.not_applicable("D10", f"the DS did not send enabled within 10 s of --enable ({note})")
            return
        robot.silent = True
        silent_at = time.monotonic()
        disabled = await until(lambda: any(not c.pkt.enabled for c in robot.good(silent_at)), 3.0)
        await asyncio.sleep(max(0.0, silent_at + 2.0 - time.monotonic()))
        robot.silent = False
        back = time.monotonic()
        await asyncio.sleep(2.0)
        if not disabled:
            during = robot.good(silent_at)
            if not during:  # silent too: no packet says enabled or disabled
                run.not_applicable("D10", "the DS sent no control packet that decodes while the robot was silent")
                return
            run.failed("D10", "still sending enabled 3 s after the robot fell silent",
                       evidence=[_ctl(run, during[-1], "a control packet during the silence")])
            return
        off = next(c for c in robot.good(silent_at) if not c.pkt.enabled)
        took = off.at - silent_at
        again = next((c for c in robot.good(back) if c.pkt.enabled), None)
        figures = {"disabled_after_s": round(took, 2), "allowed_s": 2.5}
        if again is not None:
            run.failed("D10", f"enabled again {again.at - back:.2f} s after the robot came back, with nobody "
                              "enabling it", figures, [_ctl(run, again, "enabled by itself")])
        elif took > 2.5:
            run.failed("D10", f"disabled {took:.2f} s after the robot fell silent (about 1 s expected)", figures,
                       [_ctl(run, off, "the first disabled packet")])
        else:
            run.passed("D10", f"disabled {took:.2f} s after the robot fell silent; still disabled 2 s after it "
                              "came back", figures)

    # -- D09, D11-D19: the FMS -----------------------------------------------------------------------
    async def _fms_sequence(self) -> None:
        run, fms = self.run, self.fake_fms
        if not self._wants(*FMS_CASES):
            return
        logged = await until(lambda: fms.login is not None or fms.tcp.streams, 10.0, 0.05)
        if not logged:
            statuses = [a for a, _, _ in self._statuses() if a.source[0] == self.o.address]
            if not statuses:
                for cid in FMS_CASES:
                    run.not_applicable(cid, f"the DS did not connect to the FMS (TCP 1750 on {self.o.fms_bind}) "
                                            "within 10 s: point its FMS address there")
                return
            # It found the FMS (its UDP status comes), and yet never logged in: a DS that skips
            # the login (LibDS) fails it, and what it did send is judged.
            never = (f"the DS never opened TCP 1750 on {self.o.fms_bind} in 10 s, though it sent {len(statuses)} "
                     f"UDP status packets to {self.o.fms_bind}:1160")
            a = statuses[0]
            run.failed("D11", never + ": no login", evidence=[_frame_ev(run, a.at, a.data, "its first status",
                                                                          "ds-to-fms")])
            for cid, step in (("D14", self.d14), ("D15", self.d15)):
                await self._guard(cid, step)
            for cid in FMS_CASES:
                run.not_applicable(cid, never + ": an FMS sends control only to a DS logged in")
            return
        await self._guard("D11", self.d11)
        await self._guard("D12", self.d12)
        if fms.login is None:
            for cid in ("D09", "D13", "D14", "D15", "D16", "D17", "D18", "D19"):
                run.not_applicable(cid, "the DS did not log in to the FMS")
            return
        await asyncio.sleep(1.0)
        for cid, step in (("D16", self.d16), ("D17", self.d17), ("D18", self.d18), ("D19", self.d19)):
            await self._guard(cid, step, retries=1)  # each follows the FMS within a time
        await self._guard("D09", self.d09)
        for cid, step in (("D13", self.d13), ("D14", self.d14), ("D15", self.d15)):
            await self._guard(cid, step)

    async def d11(self) -> None:
        run, fms = self.run, self.fake_fms
        first = fms.tcp.streams[0]
        await until(lambda: first.frames or not first.is_open, 3.0)
        if not first.frames:
            run.failed("D11", "the DS connected to TCP 1750 but sent no frame in 3 s")
            return
        f = first.frames[0]
        ev = [_frame_ev(run, f.at, f.data, "the first frame", "ds-to-fms-tcp")]
        want = TeamNumber(self.o.team).encode()
        if len(f.data) > 2 and f.data[2] == ds_to_fms.FRAME_HELLO:
            self._judge_hello(f.data, ev)
        elif f.data != want:
            run.failed("D11", f"the first frame is not the login {want.hex(' ')}", evidence=ev)
        else:
            run.passed("D11", f"first frame {f.data.hex(' ')}: team {self.o.team}")

    def _judge_hello(self, data: bytes, ev: list[Evidence]) -> None:
        """D11 for a 2027 DS: its hello (tag 30), judged on its layout and its team."""
        run, team = self.run, self.o.team
        try:
            msg = ds_to_fms.decode_tcp(data)
        except ProtocolError as exc:
            run.failed("D11", f"a 2027 hello (tag 30) that does not decode: {exc}", evidence=ev)
            return
        assert type(msg) is ds_to_fms.DsHello  # tag 30 decodes as nothing else
        figures = {"hello": "2027", "udp_port": msg.udp_port, "flags": msg.flags}
        if msg.team is None:
            run.failed("D11", f"a 2027 hello whose team {msg.team_text!r} is not a team number (1-5 ASCII digits): "
                              "an FMS answers it status 2", figures, ev)
        elif msg.team != team:
            run.failed("D11", f"a 2027 hello for team {msg.team}, not {team}", figures, ev)
        elif msg.udp_port == 0:
            run.failed("D11", "a 2027 hello naming UDP port 0: the FMS's control has nowhere to go", figures, ev)
        else:
            run.passed("D11", f"first frame {data.hex(' ')}: the 2027 DS's hello, team {team}, control to UDP "
                              f"{msg.udp_port}", figures)

    async def d12(self) -> None:
        run, fms = self.run, self.fake_fms
        stream = fms.login
        if stream is None:
            run.not_applicable("D12", "no login to ask")
            return
        if fms.hello is not None:
            run.not_applicable("D12", "a 2027 hello: no source says an FMS asks the 2027 DS a question (Cheesy "
                                      "Arena asks neither DS), so none was asked")
            return
        value = fms.challenges.get(id(stream))
        assert value is not None  # the FMS asks each login its question as it takes it (fms_side.py)

        def answered() -> Any:
            for f in list(stream.frames)[1:]:
                try:
                    msg = ds_to_fms.decode_tcp(f.data)
                except ProtocolError:
                    continue
                if type(msg) is ds_to_fms.ChallengeResponse:
                    return f, msg
            return None
        await until(answered, 5.0, 0.05)
        got = answered()
        right = challenge_answer(self.o.team, value)
        if got is None:
            run.failed("D12", f"no challenge answer (0x1b) within 5 s of the question (random value {value}; the "
                              f"answer is {right!r})")
            return
        f, msg = got
        ev = [_frame_ev(run, f.at, f.data, "the answer", "ds-to-fms-tcp")]
        if msg.answer != right:
            run.failed("D12", f"answered {msg.answer!r} to random value {value}; {right!r} is right "
                              f"(index ({self.o.team} * {value}) % 23)", evidence=ev)
        else:
            run.passed("D12", f"answered {msg.answer!r} to random value {value}")

    async def d13(self) -> None:
        run, fms = self.run, self.fake_fms
        stream = fms.login
        assert stream is not None  # D13 runs only after the DS logged in (_fms_sequence)
        frames = list(stream.frames)
        end = time.monotonic() if stream.closed_at is None else stream.closed_at  # open: until now
        times = [stream.opened] + [f.at for f in frames] + [end]
        gaps = [b - a for a, b in zip(times, times[1:])]
        ids: dict[str, int] = {}
        for f in frames:
            key = f"0x{f.data[2]:02x}" if len(f.data) > 2 else "keep-alive"
            ids[key] = ids.get(key, 0) + 1
        figures = {"seconds": round(end - stream.opened, 1), "max_gap_s": round(max(gaps), 2), "frames": ids}
        if end - stream.opened < 6.0:
            run.not_applicable("D13", f"the login lasted only {end - stream.opened:.1f} s", figures)
        elif max(gaps) > 5.0:
            run.failed("D13", f"{max(gaps):.1f} s without a frame on TCP 1750: an FMS drops a DS after 5 s", figures)
        else:
            run.passed("D13", f"a frame at least every {max(gaps):.1f} s", figures)

    def _statuses(self) -> list[tuple[Arrival, DsStatusPacket | None, str | None]]:
        out: list[tuple[Arrival, DsStatusPacket | None, str | None]] = []
        for a in self.fms_udp.received:
            try:
                out.append((a, ds_to_fms.decode_status(a.data), None))
            except ProtocolError as exc:
                out.append((a, None, str(exc)))
        return out

    async def d14(self) -> None:
        run = self.run
        statuses = [a for a, _, _ in self._statuses() if a.source[0] == self.o.address]
        if len(statuses) < 5:
            run.failed("D14", f"{len(statuses)} UDP status packets from {self.o.address} on UDP 1160")
            return
        gaps = sorted((b.at - a.at) * 1000 for a, b in zip(statuses, statuses[1:]))
        p95 = gaps[min(len(gaps) - 1, int(0.95 * len(gaps)))]
        figures = {"packets": len(statuses), "median_ms": round(median(gaps), 1), "p95_ms": round(p95, 1),
                   "max_ms": round(gaps[-1], 1), "allowed": "median <= 550 ms, 95 % of gaps <= 1000 ms (one late "
                                                            "gap on a busy host is reported, not judged)"}
        what = f"status every {median(gaps):.0f} ms (median), 95 % within {p95:.0f} ms, {gaps[-1]:.0f} ms at most"
        if median(gaps) > 550 or p95 > 1000:
            run.failed("D14", what, figures)
        else:
            run.passed("D14", what, figures)

    async def d15(self) -> None:
        run = self.run
        statuses = [(a, p, e) for a, p, e in self._statuses() if a.source[0] == self.o.address]
        if not statuses:
            run.failed("D15", "no UDP status")
            return
        robot_up = False
        for a, p, e in statuses:
            ev = [_frame_ev(run, a.at, a.data, "a status packet", "ds-to-fms")]
            if p is None:
                run.failed("D15", f"a status packet does not decode: {e}", evidence=ev)
                return
            if p.comm_version != 0:
                run.failed("D15", f"comm version 0x{p.comm_version:02x}, 0x00 expected", evidence=ev)
                return
            if p.team != self.o.team:
                run.failed("D15", f"team {p.team}, the DS is {self.o.team}", evidence=ev)
                return
            for t in p.tags:
                if type(t) is UnknownTag and t.tag_id <= 0x04:
                    run.failed("D15", f"tag 0x{t.tag_id:02x} not laid out as documented", evidence=ev)
                    return
            if p.robot_comms:
                robot_up = True
                if abs(p.battery - ROBOT_VOLTS) > 0.05:
                    run.failed("D15", f"battery {p.battery:.3f} V, the robot reports {ROBOT_VOLTS} V (0x0c80)",
                               evidence=ev)
                    return
        if not robot_up:
            a = statuses[-1][0]
            run.failed("D15", "the robot-comms bit 0x20 never set, though fieldbox's robot answered",
                       evidence=[_frame_ev(run, a.at, a.data, "a status packet", "ds-to-fms")])
            return
        run.passed("D15", f"{len(statuses)} status packets: team {self.o.team}, battery {ROBOT_VOLTS} V, robot comms")

    async def _follow(self, check: Callable[[ControlPacket], bool], since: float,
                      timeout: float = FOLLOW) -> Control | None:
        found: list[Control] = []

        def ok() -> bool:
            for c in self.robot.good(since):
                if check(c.pkt):
                    found.append(c)
                    return True
            return False
        await until(ok, timeout, 0.01)
        return found[0] if found else None

    def _last_ctl(self) -> list[Evidence]:
        good = self.robot.good()
        if not good:
            return []
        ago = time.monotonic() - good[-1].at
        return [_ctl(self.run, good[-1], f"the DS's last control packet, {ago:.1f} s ago")]

    def _not_followed(self, since: float, what: str) -> str:
        """Why the DS did not follow the FMS: ``what`` it did not send, or, when it sent the
        robot nothing at all since ``since``, that (a DS that stalls is not one that ignores
        the FMS)."""
        if any(c.at >= since for c in self.robot.controls):
            return what
        last = self.robot.controls[-1].at if self.robot.controls else None
        silent = f"for {time.monotonic() - last:.1f} s" if last is not None else "ever"
        return f"the DS sent the robot no control packet at all {silent} (so none followed the FMS)"

    def _fms_ev(self, note: str) -> list[Evidence]:
        if not self.fake_fms.sent:
            return []
        at, data, port = self.fake_fms.sent[-1]
        return [Evidence("sent", self.run.since(at), f"{note} (to UDP {port})", "fms-to-ds", data)]

    async def d16(self) -> None:
        run, fms = self.run, self.fake_fms
        t0 = time.monotonic()
        fms.set(mode=Mode.AUTONOMOUS, enabled=False, remaining=15, port=DS_FMS_UDP)
        attached = await self._follow(lambda p: p.fms_attached, t0)
        if attached is None:
            run.failed("D16", self._not_followed(t0, f"no control packet with the FMS bit (0x08) within {FOLLOW} s "
                                                     "of the FMS's first control packet"), evidence=self._fms_ev("the FMS's control") + self._last_ctl())
            return
        if attached.port != ROBOT_UDP_FMS:
            run.failed("D16", f"attached, the DS sends to UDP {attached.port}, not 1115",
                       evidence=[_ctl(run, attached, "a control packet with the FMS bit")])
            return
        t1 = time.monotonic()
        fms.set(mode=Mode.TELEOP, enabled=True, remaining=120)
        enabled = await self._follow(lambda p: p.enabled and p.mode == Mode.TELEOP and p.fms_attached, t1)
        if enabled is None:
            run.failed("D16", self._not_followed(t1, f"not enabled in teleop within {FOLLOW} s of the FMS enabling it"),
                       evidence=self._fms_ev("the FMS's control: teleop, enabled") + self._last_ctl())
            return
        fms.set(enabled=False)
        t2 = time.monotonic()
        off = await self._follow(lambda p: not p.enabled, t2)
        if off is None:
            run.failed("D16", "still enabled after the FMS disabled it", evidence=self._fms_ev("the FMS's control")
                       + self._last_ctl())
            return
        figures = {"attach_s": round(attached.at - t0, 3), "enable_s": round(enabled.at - t1, 3),
                   "disable_s": round(off.at - t2, 3)}
        run.passed("D16", "attached (UDP 1115, FMS bit), enabled in teleop and disabled as the FMS said", figures)

    async def d17(self) -> None:
        run, fms = self.run, self.fake_fms
        if fms.hello is not None:
            run.not_applicable("D17", f"a 2027 hello names the port for the FMS's control (UDP {fms.hello.udp_port}), "
                                      "and the FMS sends there, never to 1120; D16 followed control there")
            return
        t0 = time.monotonic()
        fms.set(mode=Mode.AUTONOMOUS, enabled=True, remaining=15, port=DS_FMS_UDP_LITE)
        c = await self._follow(lambda p: p.enabled and p.mode == Mode.AUTONOMOUS, t0)
        if c is None:
            run.failed("D17", self._not_followed(t0, "did not follow control sent to UDP 1120 (auto, enabled) within "
                                                     f"{FOLLOW} s"),
                       evidence=self._fms_ev("the FMS's control") + self._last_ctl())
        else:
            run.passed("D17", f"followed control on UDP 1120 in {c.at - t0:.2f} s", {"follow_s": round(c.at - t0, 3)})

    async def d18(self) -> None:
        run, fms = self.run, self.fake_fms
        t0 = time.monotonic()
        # as a real FMS sends it: a-stop set, and the station no longer enabled
        fms.set(mode=Mode.AUTONOMOUS, enabled=False, astop=True, remaining=12, port=DS_FMS_UDP)
        off = await self._follow(lambda p: not p.enabled, t0)
        if off is None:
            run.failed("D18", "still enabled after the FMS's a-stop", evidence=self._fms_ev("a-stop") + self._last_ctl())
            fms.set(astop=False)
            return
        t1 = time.monotonic()
        fms.set(mode=Mode.TELEOP, enabled=True, astop=False, remaining=120)
        on = await self._follow(lambda p: p.enabled and p.mode == Mode.TELEOP, t1)
        if on is None:
            run.failed("D18", "not enabled in teleop after auto ended", evidence=self._fms_ev("teleop, enabled")
                       + self._last_ctl())
            return
        run.passed("D18", "disabled by the a-stop, enabled again in teleop",
                   {"disable_s": round(off.at - t0, 3), "teleop_enable_s": round(on.at - t1, 3)})

    async def d19(self) -> None:
        run, fms = self.run, self.fake_fms
        t0 = time.monotonic()
        fms.set(estop=True)
        c = await self._follow(lambda p: p.estop, t0)
        if c is None:
            run.failed("D19", "no e-stop (0x80) to the robot within 1.5 s of the FMS's e-stop",
                       evidence=self._fms_ev("e-stop") + self._last_ctl())
            return
        await asyncio.sleep(1.0)
        status = next((p for a, p, _ in reversed(self._statuses()) if p is not None and a.at > t0 + 0.6), None)
        if status is not None and not status.estop:
            run.failed("D19", "the robot got the e-stop but the DS's status to the FMS does not say e-stop",
                       evidence=[_frame_ev(run, self.fms_udp.received[-1].at, self.fms_udp.received[-1].data,
                                           "the DS's status", "ds-to-fms")])
            return
        run.passed("D19", f"e-stop sent to the robot {c.at - t0:.2f} s after the FMS's", {"estop_s": round(c.at - t0, 3)})

    def _bad_match_frames(self) -> list[tuple[Any, str]]:
        """The match info (0x07) and game data (0x0e) frames the DS sent that do not decode, with why."""
        out = []
        for _, f in self._tcp_frames():
            if len(f.data) > 2 and f.data[2] in (ds_to_rio.FRAME_MATCH_INFO, ds_to_rio.FRAME_GAME_DATA):
                try:
                    ds_to_rio.decode_tcp(f.data)
                except ProtocolError as exc:
                    out.append((f, str(exc)))
        return out

    def _fail_bad_match_frames(self) -> bool:
        """D09 fails on a match info or game data frame that does not decode, FMS or not: the
        robot cannot read it. Whether it did."""
        bad = self._bad_match_frames()
        if not bad:
            return False
        f, why = bad[0]
        what = "match info (0x07)" if f.data[2] == ds_to_rio.FRAME_MATCH_INFO else "game data (0x0e)"
        self.run.failed("D09", f"a {what} frame on TCP 1740 does not decode ({len(bad)} such frame{'s' if len(bad) != 1 else ''}): {why}",
                        {"bad_frames": len(bad)},
                        [_frame_ev(self.run, f.at, f.data, f"the {what} frame", "ds-to-rio-tcp")])
        return True

    async def d09_offline(self) -> None:
        """D09 without the FMS: only a malformed match info or game data frame can be judged."""
        if not self._fail_bad_match_frames():
            self.run.not_applicable("D09", "--no-fms: fieldbox does not play the FMS")

    async def d09(self) -> None:
        run = self.run
        if self._fail_bad_match_frames():
            return
        want = MatchInfo(EVENT_CODE, MatchType.QUALIFICATION, MATCH_NUMBER, 1)

        def found() -> tuple[Any, Any]:
            info = data = None
            for s, f in self._tcp_frames():
                try:
                    msg = ds_to_rio.decode_tcp(f.data)
                except ProtocolError:
                    continue
                if type(msg) is MatchInfo and msg.competition == EVENT_CODE:
                    info = (f, msg)
                elif type(msg) is ds_to_rio.GameData and msg.text == GAME_DATA:
                    data = (f, msg)
            return info, data
        await until(lambda: all(found()), 2.0, 0.05)
        info, data = found()
        if info is None:
            infos = []
            for s, f in self._tcp_frames():
                if len(f.data) > 2 and f.data[2] == ds_to_rio.FRAME_MATCH_INFO:
                    infos.append(f)
            run.failed("D09", f"no match info with event {EVENT_CODE!r} on TCP 1740 (the FMS sent event code "
                              f"{EVENT_CODE!r}, qualification match {MATCH_NUMBER})",
                       evidence=[_frame_ev(run, f.at, f.data, "match info the DS sent", "ds-to-rio-tcp")
                                 for f in infos[-2:]])
            return
        f, msg = info
        ev = [_frame_ev(run, f.at, f.data, "the match info", "ds-to-rio-tcp")]
        if int(msg.match_type) != int(want.match_type) or msg.match_number != want.match_number:
            run.failed("D09", f"match type {int(msg.match_type)} number {msg.match_number}; the FMS sent "
                              f"qualification (2) {MATCH_NUMBER}", evidence=ev)
            return
        if data is None:
            how = ("as tag 32 of its control packets, to the 2027 DS" if self.fake_fms.hello is not None
                   else "on login")
            run.failed("D09", f"no game data {GAME_DATA!r} on TCP 1740 (the FMS sent it {how})", evidence=ev)
            return
        run.passed("D09", f"match info {EVENT_CODE} qualification {MATCH_NUMBER} (replay {msg.replay}) and game "
                          f"data {GAME_DATA!r} forwarded", {"replay": msg.replay})


async def conform_ds(opts: DsOptions, err: Any = None) -> Run:
    run = Run("ds", opts.address, list(CASES), selected=opts.cases)
    return await DsConformance(opts, run, err).execute()
