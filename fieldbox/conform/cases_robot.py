"""``fieldbox conform robot ADDRESS``: fieldbox plays the Driver Station and checks a robot
(a roboRIO, WPILib's simulator, fieldbox's fake roboRIO, any other implementation).

Control packets go out every 20 ms from UDP port 1150 of ``--bind`` (where the robot answers)
to ADDRESS port 1110 (1115 for the case that checks it), built byte by byte with
:mod:`protocol.ds_to_rio` and never through fieldbox's own DS core, so each case controls
exactly what the robot gets. A TCP client on ADDRESS port 1740 sends joystick descriptors,
match info and game data, and reads the console.

What the robot's code sees cannot be read off the wire. The cases that need it read the
lines a conformance robot program prints (``programs/``): fieldbox's fake roboRIO sends them
to the console over TCP 1740; WPILib's simulator prints them on its stdout, read when conform
starts it (``--launch``). Without such a program those cases are "not applicable".

The robot is enabled by some cases (never with ``--no-enable``): run it on blocks, with the
conformance program, which drives nothing.
"""

from __future__ import annotations

import asyncio
import datetime as _dt
import signal
import struct
import sys
import time
from dataclasses import dataclass
from statistics import median
from typing import Any, Callable

from protocol import rio_to_ds
from protocol.ds_to_rio import (MAX_AXES, MAX_BUTTONS, MAX_JOYSTICKS, MAX_POVS, TAG_JOYSTICK, Date, GameData, Joystick,
                                JoystickDescriptor, MatchInfo, Timezone, int8_to_axis)
from protocol.enums import AllianceStation, AxisType, JoystickType, MatchType, Mode
from protocol.errors import ProtocolError
from protocol.wire import UnknownTag

from .hooks import REPORT_PREFIX, Launched, Readback, Report
from .model import Case, Evidence, Run, SetupError, Verdict, judge
from .net import FrameStream, UdpPort, connect, resolve, until
from .programs import FIELDBOX_PROGRAM, WPILIB_PROGRAM
from .robot_link import DS_UDP, ROBOT_TCP, ROBOT_UDP, ROBOT_UDP_FMS, DsDriver, Reply, Sent
from .sources import CAPTURE, CORRECTIONS, DS_DETAILS, ROBOT_SIDE, SEED_D2R, SEED_R2D, TRAPS


CASES = (
    Case("R01", "Answers every control packet at once",
         "A robot answers every DS control packet at once, to the DS's address on UDP 1150, echoing its "
         "sequence number, comm version 0x01.",
         (f'{ROBOT_SIDE}: "Answers every DS packet at once"', f'{SEED_R2D} UDP table: "Sequence Num", '
          '"Comm Version 0x01"')),
    Case("R02", "Status echoes mode and enable; trace says robot code",
         "The status byte echoes the control byte's mode and enabled bits as the robot applies them; the "
         "trace byte sets 0x20 while robot code runs.",
         (f'{ROBOT_SIDE}: "status byte an echo of the DS control byte\'s e-stop/enabled/mode bits, trace '
          'byte (0x20 robot code running ...)"', f"{SEED_R2D} Status and Trace tables"),
         needs="the robot enabled (not with --no-enable)"),
    Case("R03", "Status does not echo the FMS-attached bit",
         "Only e-stop, enabled and mode are echoed: status bit 0x08 means code initializing, so a robot "
         "whose code runs leaves it clear whatever the DS's control byte carries (0x08 there is "
         "FMS attached).",
         (f'{ROBOT_SIDE}: "status byte an echo of the DS control byte\'s e-stop/enabled/mode bits"',
          f'{SEED_R2D} Status table: "Code Start ....x... 0: Running, 1: Initializing"',
          f'{SEED_D2R} Control table: FMS Connected 0x08')),
    Case("R04", "Battery is XX + YY/256 volts",
         "The battery is a u16 read as high byte volts plus low byte / 256; a robot on a 12 V battery "
         "reads 4.5-16 V (not BCD, not a raw ADC count).",
         (f'{SEED_R2D} "Battery": "Received as a uint16, XXYY ... XX + YY/256"', f"{TRAPS}: battery read "
          "as b*12/0x12 instead of BCD (2010)")),
    Case("R05", "Asks for the date until it has it",
         "A roboRIO sets request-date (0x01) until the DS has sent date and time zone, and clears it "
         "after. A robot whose trace says it is no roboRIO (a simulator has its host's clock) need not "
         "ask.",
         (f'{ROBOT_SIDE}: "request-date 0x01 until the DS has sent date and timezone, 0x00 after"',
          f'{SEED_R2D} "Request Date? 0x01 when first connecting"',
          f'{CAPTURE}: the date tag in the packet after request-date (see {CORRECTIONS} "Date tag")')),
    Case("R06", "No joystick tags: no joysticks",
         "A packet with no joystick tags means no joystick is attached: robot code sees six empty slots.",
         (f'{CORRECTIONS} "No joystick attached: the real DS sent no joystick tags at all"',
          f"{CAPTURE}: 3,118 six-byte control packets"), needs="a robot program that reports"),
    Case("R07", "A slot no longer sent reads empty",
         "A real DS sends joystick tags only up to the last slot in use: when a slot's tag stops coming, "
         "robot code reads that slot as empty, not its last values (an unplugged stick must not keep "
         "driving).",
         (f'{DS_DETAILS}: "Up to 6 joystick tags, in slot order"', f'{CORRECTIONS} "No joystick attached"'),
         needs="a robot program that reports"),
    Case("R08", "Six joystick tags keep their slot numbers",
         "Joystick tags come in slot order and an empty slot is still sent, so the sixth tag is slot 5.",
         (f'{DS_DETAILS}: "a slot with no joystick is still sent (empty tag) so slots keep their numbers"',
          f"{SEED_D2R} Joystick 0x0c"), needs="a robot program that reports"),
    Case("R09", "Twelve axes, int8 scaled /128 and /127",
         "Axes are int8; negative values read /128, positive /127; up to 12 axes.",
         (f'{DS_DETAILS}: "axes are int8; a peer scales negative values by /128 and positive by /127"',
          f"{SEED_D2R} Joystick 0x0c", f"{TRAPS}: more than 12 axes written past an array"),
         needs="a robot program that reports"),
    Case("R10", "Buttons: ceil(n/8) bytes, button 1 in the last byte",
         "Buttons are ceil(count/8) bytes read as one big-endian integer, bit 0 = button 1 (12 and 32 "
         "buttons checked).",
         (f'{DS_DETAILS}: "Buttons: ceil(count/8) bytes, read as one big-endian integer, bit 0 = button 1"',
          f'{SEED_D2R} "Button": "Stored LSB 0"', f"{TRAPS}: a button word built with j*j"),
         needs="a robot program that reports"),
    Case("R11", "One POV",
         "POVs are int16 degrees, -1 when centred.",
         (f'{DS_DETAILS}: "POVs are int16 degrees, -1 when centred"', f"{SEED_D2R} Joystick 0x0c"),
         needs="a robot program that reports"),
    Case("R12", "Four POVs, each in its place",
         "POV i is the i-th int16 after the POV count.",
         (f'{DS_DETAILS}: "POVs are int16 degrees"', f"{SEED_D2R} Joystick 0x0c",
          f'{CORRECTIONS} "WPILib\'s 2026 simulator reads POV i from povs[2*i]"',
          f"{TRAPS}: POVs after the first read as 0"), needs="a robot program that reports"),
    Case("R13", "Joystick descriptors over TCP 1740",
         "Frame 0x02 (slot, is-Xbox, type, u8-length name, axis types, buttons, POVs) names each slot's "
         "device; robot code sees the name (and the type and Xbox flag where it reports them).",
         (f'{DS_DETAILS}: "joystick descriptors (0x02) on connect and on any change, one per slot"',
          f"{SEED_D2R} TCP Joystick Descriptor 0x02"), needs="a robot program that reports"),
    Case("R14", "Match info and game data over TCP 1740",
         "Frame 0x07 carries the u8-length competition name, match type, u16 match number and u8 replay; "
         "frame 0x0e the game data as text to the end of the frame.",
         (f'{CORRECTIONS} "Match info 0x07 ... has the u16 match number and u8 replay after the type, as '
          'WPILib reads it"', f"{SEED_D2R} TCP Match Info 0x07 and Game Data 0x0e"),
         needs="a robot program that reports"),
    Case("R15", "Disables within 125 ms of silence",
         "With no DS packet for about 100 ms the robot disables (the FPGA watchdog is 125 ms).",
         (f'{ROBOT_SIDE}: "Disables outputs when no DS packet has come for about 100 ms (the FPGA watchdog '
          'is 125 ms)"',), needs="a robot program that reports; the robot enabled"),
    Case("R16", "Answers on UDP 1115 too",
         "A robot takes the DS on UDP 1110 and on 1115, where a DS attached to an FMS sends.",
         (f'{ROBOT_SIDE}: "Accepts the DS on UDP 1110 and on 1115 (the port used while an FMS is attached)"',
          f'{SEED_D2R}: "UDP port 1110 (port 1115 when connected to FMS)"')),
    Case("R17", "E-stop latched until the code restarts",
         "An e-stop latches: later packets without the e-stop bit neither clear it nor enable the robot; "
         "restarting the robot code (request 0x04) clears it.",
         (f'{ROBOT_SIDE}: "An e-stop latches until the robot code restarts or the roboRIO reboots"',
          f'{DS_DETAILS}: "Request byte: 0x08 reboot roboRIO, 0x04 restart code"'),
         needs="the robot enabled"),
    Case("R18", "A malformed tag costs only that tag",
         "A control packet whose joystick tag has LibDS's wrong size byte still has its header applied: "
         "enabled packets with it enable a disabled robot, which answers them and goes on.",
         (f'{CORRECTIONS} "A malformed tag: WPILib\'s robot side applies the header (enable, mode, station) '
          'before it walks the tags. LibDS ... writes joystick tags with a wrong size byte"',),
         needs="the robot enabled"),
    Case("R19", "Every tag and frame the robot sent walks cleanly",
         "Every status packet decodes, each known tag laid out as documented (joystick output 1 or 9 "
         "bytes, at most six; disk, CPU, RAM, PDP, CAN), and every TCP 1740 frame decodes.",
         (f"{SEED_R2D} Tags", f'{CORRECTIONS}: "CPU tag 0x05", "Disk 0x04"', f"{ROBOT_SIDE}: TCP 1740")),
    # R20-R24: at and past the limits a real DS sends. A robot keeps answering, reads what it can
    # hold, and harms nothing else; one that stops answering is said to, with the packet it was sent.
    Case("R20", "Six joysticks at the limits",
         "Six joystick tags of 12 axes, 32 buttons and 12 POVs each, the most a real DS sends: the robot "
         "answers every packet and robot code reads every value as sent, each in its slot.",
         (f'{DS_DETAILS}: "Counts are bounded: WPILib\'s HAL holds at most 12 axes, 32 buttons and 12 POVs per '
          'stick and 6 sticks"', f'{CORRECTIONS}: "WPILib\'s 2026 simulator reads POV i from povs[2*i] ... more than '
          '6 POVs write past its array"')),
    Case("R21", "More POVs than a robot holds",
         "A stick with 13 POVs, then 125 (the most a tag's size byte lets through), beside a stick in slot 1: "
         "the robot keeps answering, robot code reads the first 12 POVs as sent (or more), and slot 1 and "
         "every slot's descriptor read as before. A robot that stops answering fails, with the packets.",
         (f'{TRAPS}: "Every count read from the wire must be bounded"', f'{CORRECTIONS}: "WPILib\'s 2026 '
          'simulator reads POV i from povs[2*i]"')),
    Case("R22", "More axes than a robot holds",
         "A stick with 13 axes, then 251 (the most a tag's size byte lets through), beside a stick in slot 1: "
         "the robot keeps answering, robot code reads the first 12 axes as sent (or more), and slot 1 and "
         "every slot's descriptor read as before.",
         (f'{TRAPS}: "more than 12 axes written past an array"', f"{DS_DETAILS}: Counts are bounded")),
    Case("R23", "A seventh joystick tag",
         "Seven joystick tags, the seventh at every limit: the robot keeps answering and robot code reads "
         "slots 0-5 as sent and each descriptor as before (the seventh overwrites nothing).",
         (f'{TRAPS}: "a seventh joystick tag overwriting other state"', f'{DS_DETAILS}: "at most six joystick '
          'tags, in slot order"')),
    Case("R24", "A joystick descriptor for slot 6 or more",
         "Descriptor frames (0x02) for slots 6 and 255 on TCP 1740, after one naming slot 0: the robot keeps "
         "answering and robot code still reads slot 0's name, and every other slot's, as before.",
         (f'{DS_DETAILS}: "joystick descriptors (0x02) ... one per slot"', f"{SEED_D2R} TCP Joystick Descriptor "
          "0x02", f'{TRAPS}: "Every count read from the wire must be bounded"')),
)

#: LibDS's joystick tag (6 axes, 12 buttons, 1 POV) with its 2015/2016 size byte, payload + 2:
#: 0x0f where the layout needs 0x0e, so the tag runs one byte past the packet's end.
#: Source: docs/protocol.md#malformed-tag (LibDS, QDriverStation's engine).
LIBDS_JOYSTICK_TAG = bytes.fromhex("0f0c06000000000000000c000001ffff")
#: What a robot program reports for a slot without a joystick.
EMPTY: dict[str, list[Any]] = {"axes": [], "buttons": [], "povs": []}
#: Axis values that cover both scalings and both ends (int8).
TWELVE_AXES = (-128, -127, -64, -1, 0, 1, 63, 64, 126, 127, -100, 100)
FOUR_POVS = (90, 180, 270, 45)  # none 0 or -1: a POV read from the wrong place shows
AXIS_TOLERANCE = 0.0011  # reports round to 4 decimals
#: Cases that measure time get a second try when they fail (see model.judge); R15 takes the
#: better of two silences itself.
TIMED = {"R01": 1, "R16": 1, "R18": 1}
#: R15's allowance: generous, for the report's own way (the robot's loop, a print, TCP or a
#: pipe) and a busy host come on top of the robot's timeout.
R15_REPORT = 0.400
R15_TIMEOUT = 0.250
#: The most a joystick tag's size byte (a u8 counting the id) lets through: 251 axes with no
#: buttons or POVs, or 125 POVs with no axes or buttons (R21, R22).
TAG_MOST_AXES = 255 - 4
TAG_MOST_POVS = (255 - 4) // 2
#: Packets each step of R20-R24 sends; a robot that answers fewer than half of them, and none
#: for CRASH_WAIT seconds after, has stopped answering.
LIMIT_PACKETS = 25
CRASH_WAIT = 3.0
#: Seconds a TCP frame may stay begun and unfinished (R19): a robot writes a frame at once, and
#: even a lossy link's retransmissions take less.
UNFINISHED_FRAME = 2.0


@dataclass
class RobotOptions:
    address: str
    bind: str = "0.0.0.0"
    ds_port: int = DS_UDP
    udp_port: int = ROBOT_UDP
    fms_port: int = ROBOT_UDP_FMS
    tcp_port: int = ROBOT_TCP
    station: AllianceStation = AllianceStation.RED1
    launch: str | None = None
    launch_cwd: str | None = None
    wait: float = 30.0  # for the robot's first answer (a simulator takes seconds to start)
    enable: bool = True
    cases: frozenset[str] | None = None


# -- evidence helpers ---------------------------------------------------------------------------
def _sent(run: Run, s: Sent, note: str) -> Evidence:
    return Evidence("sent", run.since(s.at), note, "ds-to-rio", s.data)


def _got(run: Run, r: Reply, note: str) -> Evidence:
    return Evidence("received", run.since(r.at), note, "rio-to-ds", r.data)


def _line(run: Run, report: Report | None, note: str, slots: range | list[int] | tuple[int, ...] = ()) -> Evidence:
    """A report line as evidence; with ``slots``, the note says what those slots read."""
    if report is None:
        return Evidence("received", run.now(), note, text="(no report)")
    read = "; ".join(describe_stick(s, report.stick(s)) for s in slots)
    return Evidence("received", run.since(report.at), f"{note}: {read}" if read else note, text=report.line)


def describe_stick(slot: int, seen: dict[str, Any]) -> str:
    """``slot 1: axes -1.0 1.0, buttons 2, POVs 180`` (or ``slot 1: empty``)."""
    def words(key: str) -> str:
        value = seen.get(key)
        return " ".join(str(v) for v in value) if isinstance(value, list) else repr(value)
    if not seen.get("axes") and not seen.get("buttons") and not seen.get("povs"):
        return f"slot {slot}: empty"
    return f"slot {slot}: axes {words('axes') or '-'}, buttons {words('buttons') or '-'}, POVs {words('povs') or '-'}"


def expected_stick(j: Joystick) -> dict[str, Any]:
    return {"axes": [round(int8_to_axis(a), 4) for a in j.axes],
            "buttons": [b + 1 for b in range(j.button_count) if j.buttons >> b & 1], "povs": list(j.povs)}


def stick_differences(slot: int, seen: dict[str, Any], want: dict[str, Any]) -> list[str]:
    """What the robot reads that differs from what was sent, in words."""
    out: list[str] = []
    axes = seen.get("axes") if isinstance(seen.get("axes"), list) else None
    if axes is None:
        return [f"slot {slot}: the report has no axes"]
    if len(axes) != len(want["axes"]):
        out.append(f"slot {slot}: {len(axes)} axes read, {len(want['axes'])} sent")
    for k, (a, w) in enumerate(zip(axes, want["axes"])):
        if not isinstance(a, (int, float)) or abs(a - w) > AXIS_TOLERANCE:
            out.append(f"slot {slot} axis {k}: robot reads {a!r}, sent {w:+.4f}")
    buttons = seen.get("buttons")
    if buttons != want["buttons"]:
        out.append(f"slot {slot}: buttons down read {buttons!r}, sent {want['buttons']!r}")
    povs = seen.get("povs")
    if not isinstance(povs, list) or len(povs) != len(want["povs"]):
        out.append(f"slot {slot}: POVs read {povs!r}, sent {want['povs']!r}")
    else:
        for k, (p, w) in enumerate(zip(povs, want["povs"])):
            if p != w:
                out.append(f"slot {slot} POV {k}: robot reads {p!r}, sent {w}")
    return out


@dataclass(frozen=True)
class RawStick:
    """A joystick tag built by hand, whatever its counts: protocol.ds_to_rio refuses to encode
    more than a robot holds, and R21-R23 send exactly that."""

    axes: tuple[int, ...] = ()
    buttons: int = 0
    button_count: int = 0
    povs: tuple[int, ...] = ()

    def tag(self) -> bytes:
        n_bytes = (self.button_count + 7) // 8
        body = (bytes((TAG_JOYSTICK, len(self.axes))) + struct.pack(f">{len(self.axes)}b", *self.axes)
                + bytes((self.button_count,)) + self.buttons.to_bytes(n_bytes, "big") + bytes((len(self.povs),))
                + struct.pack(f">{len(self.povs)}h", *self.povs))
        assert len(body) <= 255, "more than a tag's size byte counts"
        return bytes((len(body),)) + body

    def expected(self) -> dict[str, Any]:
        return {"axes": [round(int8_to_axis(a), 4) for a in self.axes],
                "buttons": [b + 1 for b in range(self.button_count) if self.buttons >> b & 1], "povs": list(self.povs)}

    def words(self) -> str:
        return f"{len(self.axes)} axes, {self.button_count} buttons, {len(self.povs)} POVs"


def limit_stick(k: int, n_axes: int = MAX_AXES, n_povs: int = MAX_POVS) -> RawStick:
    """A stick at (or past) the limits whose values differ from slot to slot and from axis to
    axis, so a value read from the wrong place shows."""
    axes = tuple(((k * 37 + 11 * a) % 255) - 127 for a in range(n_axes))
    povs = tuple((45 * ((k + p) % 8)) for p in range(n_povs))
    buttons = (0x5A5A5A5A >> k | 1 << (31 - k)) & 0xFFFFFFFF
    return RawStick(axes, buttons, MAX_BUTTONS, povs)


def prefix_differences(slot: int, seen: dict[str, Any], want: dict[str, Any], limits: dict[str, int]) -> list[str]:
    """What robot code reads in a slot sent past a limit that is wrong: each list in ``limits``
    (axes, POVs) must read at least the first ``limit`` values as sent (more is fine, never more
    than were sent); the rest exactly as sent."""
    out: list[str] = []
    for key in ("axes", "povs"):
        read, sent = seen.get(key), want[key]
        least = min(limits.get(key, len(sent)), len(sent))
        if not isinstance(read, list) or not least <= len(read) <= len(sent):
            shown = f"{len(read)} read" if isinstance(read, list) else f"{read!r} read"
            out.append(f"slot {slot}: {shown} of {len(sent)} {'axes' if key == 'axes' else 'POVs'} sent"
                       + (f" (at least the first {least} expected)" if least < len(sent) else ""))
            continue
        tol = AXIS_TOLERANCE if key == "axes" else 0
        for k, (a, w) in enumerate(zip(read, sent)):
            if not isinstance(a, (int, float)) or abs(a - w) > tol:
                out.append(f"slot {slot} {'axis' if key == 'axes' else 'POV'} {k}: robot reads {a!r}, sent {w}")
                break
    if seen.get("buttons") != want["buttons"]:
        out.append(f"slot {slot}: buttons down read {seen.get('buttons')!r}, sent {want['buttons']!r}")
    return out


def descriptors_changed(before: Report | None, after: Report) -> list[str]:
    """Each slot's name, type and Xbox flag that robot code reads differently from ``before``:
    a count past a limit written past an array lands in state like this."""
    out: list[str] = []
    if before is None:
        return out
    for slot in range(MAX_JOYSTICKS):
        for key in ("name", "type", "xbox"):
            was, now = before.stick(slot).get(key), after.stick(slot).get(key)
            if was != now:
                out.append(f"slot {slot}: {key} reads {now!r}, {was!r} before")
    return out


def describe_exit(code: int | None) -> str:
    """``killed by SIGSEGV (signal 11)`` or ``exit code 1``."""
    if code is None:
        return "still running"
    if code < 0:
        try:
            name = signal.Signals(-code).name
        except ValueError:
            name = "an unknown signal"
        return f"killed by {name} (signal {-code})"
    return f"exit code {code}"


def last_words(lines: list[str], n: int = 3) -> list[str]:
    """What a program that died said last, without the stack dumps after it (Python's
    faulthandler lists every thread's frames) or its report lines: the lines that say why."""
    said = [t for t in lines if t.strip() and not t[:1].isspace() and not t.startswith(
        ("Thread 0x", "Current thread 0x", "Fatal Python error", REPORT_PREFIX))]
    return said[-n:]


def _battery_ok(volts: float) -> bool:
    return 4.5 <= volts <= 16.0


# -- the run ------------------------------------------------------------------------------------
class RobotConformance:
    def __init__(self, opts: RobotOptions, run: Run, err: Any = None) -> None:
        self.o = opts
        self.run = run
        self.err = err or sys.stderr
        self.udp: UdpPort | None = None
        self.ds: DsDriver | None = None
        self.launched: Launched | None = None
        self.readback = Readback()
        self.tcp: FrameStream | None = None
        self.tcp_streams: list[FrameStream] = []
        self.tcp_error: str = ""
        self._tcp_task: asyncio.Task | None = None
        self.comms = False
        self.code = False
        self.has_readback = False
        self.crashed: str | None = None  # the case in which the robot stopped answering (R20-R24)
        self.limit_report: Report | None = None  # what robot code read in the last step of R20-R24

    @property
    def driver(self) -> DsDriver:
        """The DS fieldbox plays, made in setup: every case drives the robot through it."""
        assert self.ds is not None
        return self.ds

    # -- plumbing --------------------------------------------------------------------------------
    async def execute(self) -> Run:
        run = self.run
        try:
            await self._setup()
            await self._cases()
        finally:
            await self._teardown()
        run.finish("not run")
        return run

    async def _setup(self) -> None:
        o, run = self.o, self.run
        try:
            o.address = await resolve(o.address)
        except OSError as exc:
            raise SetupError(f"cannot find the robot {o.address}: {exc.strerror or exc}") from None
        try:
            self.udp = await UdpPort.open("ds", o.bind, o.ds_port)
        except OSError as exc:
            raise SetupError(f"cannot bind UDP {o.bind}:{o.ds_port}, where the robot answers: "
                             f"{exc.strerror or exc}") from None
        run.notes.append(f"fieldbox plays the DS on UDP {o.bind}:{o.ds_port}, sending to "
                         f"{o.address}:{o.udp_port} every 20 ms")
        if o.launch:
            try:
                self.launched = await Launched.start(o.launch, o.launch_cwd)
            except (OSError, ValueError) as exc:
                raise SetupError(f"cannot launch {o.launch!r}: {exc}") from None
            self.launched.listeners.append(lambda at, text: self.readback.add_text(at, text, "its stdout"))
            run.notes.append(f"launched: {o.launch}")
        self.ds = DsDriver(self.udp, o.address, o.station)
        self.ds.start()
        self._tcp_task = asyncio.get_running_loop().create_task(self._tcp_loop())

    async def _teardown(self) -> None:
        if self.ds is not None:
            await self.ds.stop()
        if self._tcp_task is not None:
            self._tcp_task.cancel()
            await asyncio.gather(self._tcp_task, return_exceptions=True)
        for s in self.tcp_streams:
            await s.wait_closed()
        if self.launched is not None:
            tail = self.launched.tail(5)
            await self.launched.stop()
            if self.launched.process.returncode not in (None, 0, -2, 130, -9):
                self.run.notes.append(f"the launched program ended with {self.launched.process.returncode}; "
                                      f"its last lines: {' | '.join(tail)}")
        if self.udp is not None:
            self.udp.close()

    async def _tcp_loop(self) -> None:
        """Keep a TCP 1740 connection up (the robot may restart); read its console."""
        o = self.o
        while True:
            if self.tcp is None or not self.tcp.is_open:
                try:
                    stream = await connect("robot-tcp", (o.address, o.tcp_port),
                                           local_host=None if o.bind in ("0.0.0.0", "") else o.bind)
                except (OSError, asyncio.TimeoutError) as exc:
                    self.tcp_error = f"{type(exc).__name__}: {exc}"
                else:
                    stream.listeners.append(self._on_frame)
                    self.tcp = stream
                    self.tcp_streams.append(stream)
                    del self.tcp_streams[:-32]
                    self.tcp_error = ""
                    self._send_tcp_hello()
            await asyncio.sleep(1.0)

    def _on_frame(self, frame) -> None:
        try:
            message = rio_to_ds.decode_tcp(frame.data)
        except ProtocolError:
            return  # judged in R19
        if type(message) is rio_to_ds.StdoutMessage:
            self.readback.add_text(frame.at, message.text, "the DS console (TCP 1740)")
        elif type(message) is rio_to_ds.VersionInfo:
            versions = self.run.peer.setdefault("versions", {})
            if len(versions) < 16 and message.name:
                versions[message.name[:64]] = message.version[:64]

    def _send_tcp_hello(self) -> None:
        """What a DS sends on connect: a descriptor for each slot (all empty here)."""
        for slot in range(6):
            self._tcp_send(JoystickDescriptor(slot).encode())

    def _tcp_send(self, frame: bytes) -> bool:
        return self.tcp is not None and self.tcp.send(frame)

    async def _guard(self, cid: str, step: Callable[[], Any], retries: int = 0) -> None:
        await judge(self.run, cid, step, self.err, retries)

    # -- the cases in order --------------------------------------------------------------------------
    async def _cases(self) -> None:
        await self._first_contact()
        if not self.comms:
            return
        steps = [("R01", self.r01), ("R02", self.r02), ("R03", self.r03), ("R04", self.r04), ("R05", self.r05),
                 ("R06", self.r06), ("R07", self.r07), ("R08", self.r08), ("R09", self.r09), ("R10", self.r10),
                 ("R11", self.r11), ("R12", self.r12), ("R13", self.r13), ("R14", self.r14), ("R15", self.r15),
                 ("R16", self.r16), ("R17", self.r17), ("R18", self.r18), ("R20", self.r20), ("R21", self.r21),
                 ("R22", self.r22), ("R23", self.r23), ("R24", self.r24)]
        for cid, step in steps:
            await self._guard(cid, step, TIMED.get(cid, 0))
            self._neutral()
        await self._guard("R19", self.r19)

    def _neutral(self) -> None:
        i = self.driver.intent
        i.enabled = i.estop = i.fms = False
        i.mode, i.port, i.override = Mode.TELEOP, self.o.udp_port, None

    async def _first_contact(self) -> None:
        ds, run = self.driver, self.run
        t0 = time.monotonic()
        self.comms = await until(lambda: ds.good_replies() or ds.replies, self.o.wait, 0.02)
        if not self.comms:
            why = (f"no answer from {self.o.address}:{self.o.udp_port} to {len(ds.log)} control packets in "
                   f"{self.o.wait:g} s")
            if self.launched is not None and not self.launched.running:
                why += f"; the launched program ended ({self.launched.process.returncode}): " + \
                       " | ".join(self.launched.tail(5))
            ev = [_sent(run, ds.log[-1], "the last control packet sent")] if ds.log else []
            run.failed("R01", why, evidence=ev)
            run.finish("no robot comms: nothing to check")
            return
        run.peer["first_answer_s"] = round(time.monotonic() - t0, 2)

        def code_runs() -> bool:
            good = ds.good_replies()
            return bool(good) and good[-1].pkt.robot_code and not good[-1].pkt.code_initializing

        def garbled() -> bool:  # only answers that do not decode, for 3 s: no code to wait for (see R19)
            return not ds.good_replies() and time.monotonic() - t1 > 3.0
        t1 = time.monotonic()
        await until(lambda: code_runs() or garbled(), 20.0, 0.02)
        self.code = code_runs()
        good = ds.good_replies()
        if good:
            p = good[-1].pkt
            run.peer.update(trace=f"0x{p.trace_byte:02x}", is_roborio=p.is_roborio, robot_code=p.robot_code)
        # A report from the robot program: its first line may take a few seconds (code start).
        self.has_readback = await until(lambda: self.readback.reports, 10.0 if self.code else 1.0, 0.05)
        run.peer["readback"] = (f"robot program reports on {self.readback.reports[0].source}"
                                if self.has_readback else "none")
        if not self.has_readback:
            run.notes.append(
                "no robot program reported what it sees: the cases that need it are not applicable. Run the "
                f"robot with {FIELDBOX_PROGRAM} (fieldbox --robot-program) or {WPILIB_PROGRAM} (RobotPy, "
                "with --launch)")

    # -- small tools -------------------------------------------------------------------------------
    def _needs_readback(self, cid: str) -> bool:
        if not self.has_readback:
            self.run.not_applicable(cid, "no robot program reports what the robot sees (run "
                                         f"{FIELDBOX_PROGRAM.name} or {WPILIB_PROGRAM.name}, see the README)")
            return False
        return True

    def _needs_enable(self, cid: str) -> bool:
        if not self.o.enable:
            self.run.not_applicable(cid, "--no-enable: this case enables the robot")
            return False
        if not self.code:
            self.run.not_applicable(cid, "the robot reports no robot code (trace bit 0x20): it cannot be enabled")
            return False
        return True

    async def _window(self, n: int) -> tuple[int, int]:
        """Let ``n`` packets go out as the intent says; their sequence range, once every one is
        answered or a second has passed (an answer later than that is no answer: R01)."""
        ds = self.driver
        first = ds.mark()
        await ds.beats(n)
        last = ds.mark()
        seqs = [s.seq for s in ds.between(first, last)]
        await until(lambda: all(q in ds.reply_to for q in seqs), 1.0, 0.01)
        return first, last

    async def _see(self, check: Callable[[Report], list[str]], since: float,
                   timeout: float = 3.0) -> tuple[Report | None, list[str]]:
        """The first report after ``since`` that ``check`` finds nothing wrong with, or the
        last report and what is wrong with it."""
        found: list[Report] = []

        def ok() -> bool:
            for r in self.readback.since(since):
                if not check(r):
                    found.append(r)
                    return True
            return False
        if await until(ok, timeout, 0.02):
            return found[0], []
        last = self.readback.since(since)
        if not last:
            return None, [f"no report from the robot program in {timeout:g} s"]
        return last[-1], check(last[-1])

    async def _read_sticks(self, joysticks: tuple[Joystick, ...], slots: range | list[int],
                           what: str) -> tuple[list[str], list[Evidence]]:
        """Send ``joysticks`` and wait for robot code to read ``slots`` as sent (a slot past
        the tags sent as empty); what differs, and the packets that show it."""
        ds, run = self.driver, self.run
        ds.intent.joysticks = joysticks
        first = ds.mark()
        await ds.beats(1)
        since = time.monotonic()
        wants = {s: expected_stick(joysticks[s]) if s < len(joysticks) else dict(EMPTY) for s in slots}

        def check(r: Report) -> list[str]:
            diffs: list[str] = []
            for s, want in wants.items():
                diffs += stick_differences(s, r.stick(s), want)
            return diffs
        report, diffs = await self._see(check, since)
        packet = ds.sent.get(first)
        evidence = ([_sent(run, packet, f"the control packet: {what}")] if packet else []) + \
            [_line(run, report, "what robot code reads", list(wants))]
        return diffs, evidence

    async def _sticks_case(self, cid: str, joysticks: tuple[Joystick, ...], slots: range | list[int],
                           what: str) -> None:
        if not self._needs_readback(cid):
            return
        diffs, evidence = await self._read_sticks(joysticks, slots, what)
        if diffs:
            self.run.failed(cid, "; ".join(diffs[:8]), evidence=evidence)
        else:
            self.run.passed(cid, f"robot code reads {what} as sent")

    # -- R01 ---------------------------------------------------------------------------------------
    async def r01(self) -> None:
        ds, run = self.driver, self.run
        first, last = await self._window(100)
        packets = ds.between(first, last)
        answered = [(s, ds.reply_to.get(s.seq)) for s in packets]
        got = [(s, r) for s, r in answered if r is not None]
        latencies = sorted((r.at - s.at) * 1000 for s, r in got)
        figures: dict[str, Any] = {"sent": len(packets), "answered": len(got)}
        if latencies:
            figures.update(reply_ms_median=round(median(latencies), 2),
                           reply_ms_p99=round(latencies[min(len(latencies) - 1, int(0.99 * len(latencies)))], 2))
        bad = [r for r in ds.replies if r.packet is not None and r.packet.comm_version != 0x01]
        strange = [r for r in ds.replies if r.packet is not None and r.packet.sequence not in ds.sent]
        figures["rule"] = "every packet answered; allowed: 98 % (a lossy network), each within 1 s"
        if len(got) < 0.98 * len(packets):
            missing = next((s for s, r in answered if r is None), None)
            garbled = sum(1 for r in ds.replies if r.packet is None)
            why = f"{len(packets) - len(got)} of {len(packets)} control packets got no answer"
            if garbled:
                why += f" that decodes ({garbled} answers do not decode: see R19)"
            run.failed("R01", why,
                       figures, [_sent(run, missing, "a control packet never answered")] if missing else [])
        elif bad:
            run.failed("R01", f"comm version 0x{bad[0].pkt.comm_version:02x} in {len(bad)} status packets, "
                              "0x01 expected", figures, [_got(run, bad[0], "a status packet")])
        elif strange:
            run.failed("R01", f"{len(strange)} status packets echo a sequence number fieldbox never sent",
                       figures, [_got(run, strange[0], "its sequence was never sent")])
        elif latencies and latencies[len(latencies) // 2] > 1000:
            run.failed("R01", f"the median answer took {latencies[len(latencies) // 2]:.0f} ms", figures)
        else:
            run.passed("R01", f"{len(got)} of {len(packets)} control packets answered, each echoing its "
                              "sequence with comm version 0x01", figures)

    # -- R02, R03 ----------------------------------------------------------------------------------------
    async def _steady(self, n: int = 12, keep: int = 5) -> list[tuple[Sent, Reply | None]]:
        """Send the intent for ``n`` packets; the last ``keep`` with their answers."""
        first, last = await self._window(n)
        packets = self.driver.between(first, last)[-keep:]
        return [(s, self.driver.reply_to.get(s.seq)) for s in packets]

    async def r02(self) -> None:
        ds, run = self.driver, self.run
        if not self._needs_enable("R02"):
            return
        steps = [(False, Mode.TELEOP), (False, Mode.AUTONOMOUS), (False, Mode.TEST), (True, Mode.TELEOP),
                 (True, Mode.AUTONOMOUS), (False, Mode.TELEOP)]
        checked = mismatched = 0
        unanswered: list[str] = []  # the steps with no answer to judge
        for enabled, mode in steps:
            ds.intent.enabled, ds.intent.mode = enabled, mode
            wrongs = []
            answers = [(sent, reply) for sent, reply in await self._steady() if reply is not None]
            if not answers:
                unanswered.append(f"{'enabled' if enabled else 'disabled'} {mode.label}")
            for sent, reply in answers:
                p = reply.pkt
                wrong = []
                if p.mode != mode:
                    wrong.append(f"mode {p.mode.label} echoed for {mode.label}")
                if p.enabled != enabled:
                    wrong.append(f"{'enabled' if p.enabled else 'disabled'} echoed for "
                                 f"{'enabled' if enabled else 'disabled'}")
                if p.estop:
                    wrong.append("e-stop set, never sent")
                if not p.robot_code:
                    wrong.append("trace without robot code (0x20) while its code runs")
                if wrong:
                    wrongs.append((wrong, sent, reply))
            checked += len(answers)
            mismatched += len(wrongs)
            # Most answers must echo: one taken up late by a robot on a busy host may rightly say
            # the state it applies then (a robot obeys nothing late).
            if wrongs and (len(wrongs) * 2 > len(answers)):
                wrong, sent, reply = wrongs[-1]
                run.failed("R02", f"{len(wrongs)} of {len(answers)} answers: " + "; ".join(wrong),
                           {"checked": checked}, [_sent(run, sent, "the control packet"), _got(run, reply, "its answer")])
                ds.intent.enabled = False
                return
        ds.intent.enabled = False
        figures = {"checked": checked, "not_echoed": mismatched, "steps_unanswered": unanswered}
        if not checked:  # nothing to judge is never a pass
            bad = len([r for r in ds.replies if r.packet is None])
            why = f" ({bad} datagrams from the robot do not decode: R19 says why)" if bad else ""
            run.not_applicable("R02", f"no status packet that decodes answered a control packet in any of the "
                                      f"{len(steps)} steps: nothing to judge{why}", figures)
            return
        gaps = f"; no answer to judge in {', '.join(unanswered)}" if unanswered else ""
        run.passed("R02", f"{checked - mismatched} of {checked} answers over disabled/enabled teleop, auto and test "
                          f"echo mode and enable, trace 0x20 set{gaps}", figures)

    async def r03(self) -> None:
        ds, run = self.driver, self.run
        if not self.code:
            run.not_applicable("R03", "the robot reports no robot code: status bit 0x08 may rightly be set")
            return
        ds.intent.fms = True
        pairs = await self._steady()
        for sent, reply in pairs:
            if reply is not None and reply.pkt.code_initializing and reply.pkt.robot_code:
                run.failed("R03", "status bit 0x08 (code initializing) set in answer to control 0x08 (FMS "
                                  "attached) while the trace says robot code runs: the whole control byte is "
                                  "echoed", evidence=[_sent(run, sent, "control packet with FMS attached (0x08)"),
                                                      _got(run, reply, "its answer")])
                return
        if not any(r for _, r in pairs):
            run.not_applicable("R03", "no answer to the packets with the FMS bit")
            return
        run.passed("R03", "status bit 0x08 stays clear when the DS says FMS attached")

    # -- R04 -------------------------------------------------------------------------------------------
    async def r04(self) -> None:
        ds, run = self.driver, self.run
        good = ds.good_replies()
        volts = [r.pkt.battery for r in good]
        if not volts:
            run.not_applicable("R04", f"none of the {len(ds.replies)} answers decodes: no battery to read (see R19)")
            return
        figures = {"answers": len(volts), "volts_min": round(min(volts), 3), "volts_max": round(max(volts), 3),
                   "rule": "4.5 <= volts <= 16 (a 12 V robot battery)"}
        off = next((r for r in good if not _battery_ok(r.pkt.battery)), None)
        if off is not None:
            raw = off.data[5:7]
            bcd = ""
            if all((b >> 4) < 10 and (b & 15) < 10 for b in raw):
                bcd = f" (as BCD these bytes read {raw[0]:x}.{raw[1]:02x} V: BCD, as the 2010 protocol had it?)"
            run.failed("R04", f"battery {off.pkt.battery:.3f} V (bytes {raw.hex(' ')}){bcd}", figures,
                       [_got(run, off, "a status packet")])
            return
        run.passed("R04", f"battery {figures['volts_min']}-{figures['volts_max']} V over {len(volts)} answers",
                   figures)

    # -- R05 -------------------------------------------------------------------------------------------
    async def r05(self) -> None:
        ds, run = self.driver, self.run
        good = ds.good_replies()
        if not good:
            run.not_applicable("R05", f"none of the {len(ds.replies)} answers decodes: no request-date to read "
                                      "(see R19)")
            return
        asked = next((r for r in good if r.pkt.request_date), None)
        roborio = any(r.pkt.is_roborio for r in good)
        if asked is None:
            if roborio:
                run.failed("R05", f"request-date never set in {len(good)} answers, though the trace says it is "
                                  "a roboRIO (0x10)", evidence=[_got(run, good[-1], "the last answer")])
            else:
                run.not_applicable("R05", f"request-date never set in {len(good)} answers; the trace says it is "
                                          "no roboRIO (a simulator has its host's clock)")
            return
        now = _dt.datetime.now(_dt.timezone.utc)
        ds.once = [Date.from_datetime(now), Timezone("UTC")]
        first = ds.mark()
        await ds.beats(1)
        date_packet = ds.sent.get(first)
        sent_at = date_packet.at if date_packet else time.monotonic()
        await asyncio.sleep(1.5)
        after = [r for r in ds.good_replies() if r.at >= sent_at + 1.0]
        still = next((r for r in after if r.pkt.request_date), None)
        evidence = [_sent(run, date_packet, "the date and time zone, sent once")] if date_packet else []
        if not after:
            run.failed("R05", "no answer after the date was sent", evidence=evidence)
        elif still is not None:
            run.failed("R05", "request-date still set more than 1 s after the date and time zone were sent",
                       evidence=evidence + [_got(run, still, "an answer still asking")])
        else:
            run.passed("R05", "request-date set until the date and time zone came, clear after",
                       evidence=evidence[:0])

    # -- R06-R12: joysticks ------------------------------------------------------------------------
    async def r06(self) -> None:
        if not self._needs_readback("R06"):
            return
        ds, run = self.driver, self.run
        ds.intent.joysticks = ()
        since = time.monotonic()

        def check(r: Report) -> list[str]:
            out = []
            for s in range(6):
                out += stick_differences(s, r.stick(s), EMPTY)
            return out
        report, diffs = await self._see(check, since)
        if diffs:
            run.failed("R06", "; ".join(diffs[:8]), evidence=[_sent(run, ds.log[-1], "a control packet, no tags"),
                                                              _line(run, report, "what robot code reads", range(6))])
        else:
            run.passed("R06", "six empty slots read while no joystick tag is sent")

    async def r07(self) -> None:
        if not self._needs_readback("R07"):
            return
        ds, run = self.driver, self.run
        two = (Joystick((64, -64), 0b1, 4, (90,)), Joystick((-128, 127), 0b10, 4, (180,)))
        ds.intent.joysticks = two
        await ds.beats(1)
        since = time.monotonic()
        report, diffs = await self._see(
            lambda r: stick_differences(0, r.stick(0), expected_stick(two[0]))
            + stick_differences(1, r.stick(1), expected_stick(two[1])), since)
        if diffs:
            run.not_applicable("R07", "robot code did not read two joysticks to begin with: "
                                      + "; ".join(diffs[:4]))
            return
        ds.intent.joysticks = two[:1]
        first = ds.mark()
        await ds.beats(1)
        since = time.monotonic() + 0.1
        report, diffs = await self._see(
            lambda r: stick_differences(0, r.stick(0), expected_stick(two[0]))
            + stick_differences(1, r.stick(1), EMPTY), since, 2.0)
        packet = ds.sent.get(first)
        if diffs:
            run.failed("R07", "after slot 1's tag stopped coming, robot code still reads: " + "; ".join(diffs[:6]),
                       evidence=([_sent(run, packet, "slot 0 only from here on")] if packet else [])
                       + [_line(run, report, "what robot code reads", [0, 1])])
        else:
            run.passed("R07", "slot 1 reads empty once its tag stops coming")

    async def r08(self) -> None:
        sticks = tuple([Joystick()] * 5 + [Joystick((-128, 0, 127), 0b1001, 4, (270,))])
        await self._sticks_case("R08", sticks, range(6), "five empty slots then slot 5")

    async def r09(self) -> None:
        await self._sticks_case("R09", (Joystick(TWELVE_AXES),), [0], "twelve axes " + " ".join(map(str, TWELVE_AXES)))

    async def r10(self) -> None:
        if not self._needs_readback("R10"):
            return
        buttons32 = 0
        for b in (1, 2, 8, 9, 16, 17, 24, 25, 31, 32):
            buttons32 |= 1 << (b - 1)
        for what, joy in (("12 buttons, 1 and 12 down", Joystick((), (1 << 0) | (1 << 11), 12)),
                          ("32 buttons, 1 2 8 9 16 17 24 25 31 32 down", Joystick((), buttons32, 32))):
            diffs, evidence = await self._read_sticks((joy,), [0], what)
            if diffs:
                self.run.failed("R10", f"{what}: " + "; ".join(diffs[:8]), evidence=evidence)
                return
        self.run.passed("R10", "12 buttons (2 bytes, button 1 in the last) and 32 buttons read as sent")

    async def r11(self) -> None:
        await self._sticks_case("R11", (Joystick((0,), 0, 0, (90,)),), [0], "one POV at 90")

    async def r12(self) -> None:
        await self._sticks_case("R12", (Joystick((0,), 0, 0, FOUR_POVS),), [0],
                                "four POVs " + " ".join(map(str, FOUR_POVS)))

    # -- R13, R14: TCP 1740 ----------------------------------------------------------------------------
    async def _tcp_needed(self, cid: str) -> bool:
        if await until(lambda: self.tcp is not None and self.tcp.is_open, 3.0, 0.05):
            return True
        self.run.failed(cid, f"no TCP connection to {self.o.address}:{self.o.tcp_port}: {self.tcp_error or '?'}")
        return False

    async def r13(self) -> None:
        if not self._needs_readback("R13") or not await self._tcp_needed("R13"):
            return
        ds, run = self.driver, self.run
        name = "fieldbox conform pad"
        desc = JoystickDescriptor(0, True, JoystickType.XINPUT_GAMEPAD, name,
                                  (AxisType.X, AxisType.Y, AxisType.Z, AxisType.Z, AxisType.X, AxisType.Y), 10, 1)
        frame = desc.encode()
        ds.intent.joysticks = (Joystick((0,) * 6, 0, 10, (-1,)),)
        await ds.beats(1)
        self._tcp_send(frame)
        since = time.monotonic()

        def check(r: Report) -> list[str]:
            s = r.stick(0)
            out = []
            if s.get("name") != name:
                out.append(f"name {s.get('name')!r}, sent {name!r}")
            if s.get("type") is not None and s.get("type") != int(JoystickType.XINPUT_GAMEPAD):
                out.append(f"type {s.get('type')!r}, sent {int(JoystickType.XINPUT_GAMEPAD)} (XInput gamepad)")
            if s.get("xbox") is not None and s.get("xbox") is not True:
                out.append(f"is-Xbox {s.get('xbox')!r}, sent 1")
            return out
        report, diffs = await self._see(check, since)
        ev = [Evidence("sent", run.since(since), "the descriptor frame", "ds-to-rio-tcp", frame)]
        if diffs:
            run.failed("R13", "; ".join(diffs), evidence=ev + [_line(run, report, "what robot code reads")])
        else:
            extra = " (type and Xbox flag too)" if report is not None and report.stick(0).get("type") is not None else ""
            run.passed("R13", f"robot code reads the descriptor's name{extra}")
        for slot in range(6):
            self._tcp_send(JoystickDescriptor(slot).encode())

    async def r14(self) -> None:
        if not self._needs_readback("R14") or not await self._tcp_needed("R14"):
            return
        run = self.run
        info = MatchInfo("CONFORM", MatchType.QUALIFICATION, 42, 1)
        frames = [info.encode(), GameData("LRL").encode()]
        since = time.monotonic()
        for f in frames:
            self._tcp_send(f)

        def check(r: Report) -> list[str]:
            out = []
            m = r.state.get("match")
            want = {"event": "CONFORM", "type": 2, "number": 42, "replay": 1}
            if not isinstance(m, dict):
                out.append("the robot program reports no match info")
            else:
                for key, value in want.items():
                    if m.get(key) != value:
                        out.append(f"match {key} {m.get(key)!r}, sent {value!r}")
            if r.state.get("game_data") != "LRL":
                out.append(f"game data {r.state.get('game_data')!r}, sent 'LRL'")
            return out
        report, diffs = await self._see(check, since)
        ev = [Evidence("sent", run.since(since), "match info", "ds-to-rio-tcp", frames[0]),
              Evidence("sent", run.since(since), "game data", "ds-to-rio-tcp", frames[1])]
        if diffs:
            run.failed("R14", "; ".join(diffs), evidence=ev + [_line(run, report, "what robot code reads")])
        else:
            run.passed("R14", "event CONFORM, qualification 42, replay 1 and game data LRL reach robot code")

    # -- R15 -------------------------------------------------------------------------------------------
    async def r15(self) -> None:
        if not self._needs_readback("R15") or not self._needs_enable("R15"):
            return
        run = self.run
        # A busy host can hold the report of one silence back: the better of two silences is judged
        # (a robot that is slow every time fails both).
        tries = []
        for _ in range(2):
            outcome = await self._silence()
            if outcome is None:
                return
            tries.append(outcome)
            if outcome[0] <= R15_REPORT or outcome[0] - outcome[1] <= R15_TIMEOUT:
                break
        took, shows, last, report = min(tries, key=lambda t: t[0] - t[1])
        figures = {"disabled_report_after_ms": [round(t[0] * 1000, 1) for t in tries],
                   "enable_report_after_ms": [round(t[1] * 1000, 1) for t in tries],
                   "timeout_ms": round((took - shows) * 1000, 1), "rule_ms": 125,
                   "allowed": f"the disabled report within {R15_REPORT * 1000:.0f} ms of the last packet, or the "
                              f"timeout (the disabled report's delay less the enabled report's) within "
                              f"{R15_TIMEOUT * 1000:.0f} ms; the better of two silences"}
        if took <= R15_REPORT or took - shows <= R15_TIMEOUT:
            run.passed("R15", f"robot code read itself disabled {took * 1000:.0f} ms after the last packet (a "
                              f"{(took - shows) * 1000:.0f} ms timeout, less what a report takes to come)", figures)
        else:
            run.failed("R15", f"robot code read itself disabled {took * 1000:.0f} ms after the last packet; a change "
                              f"shows in its reports {shows * 1000:.0f} ms after the packet: a "
                              f"{(took - shows) * 1000:.0f} ms timeout", figures,
                       [_sent(run, last, "the last control packet"), _line(run, report, "the first report disabled")])

    async def _silence(self) -> tuple[float, float, Sent, Report] | None:
        """Enable, then go silent: (disabled report's delay, enabled report's delay, the last
        packet, the disabled report), or None with the verdict already given."""
        ds, run = self.driver, self.run
        ds.intent.joysticks = ()
        ds.intent.enabled, ds.intent.mode = True, Mode.TELEOP
        first = ds.mark()
        await ds.beats(1)
        since = time.monotonic()
        report, diffs = await self._see(lambda r: [] if r.state.get("enabled") is True else ["not enabled"], since)
        if diffs:
            ds.intent.enabled = False
            run.not_applicable("R15", "robot code never read itself enabled: " + "; ".join(diffs))
            return None
        assert report is not None  # nothing wrong: a report passed the check (_see)
        # How long a change takes to show in a report (the robot's loop, the report's way to us):
        # measured on the enable, so the timeout can be told from the report's own delay.
        enabled_at = ds.sent[first].at if first in ds.sent else since
        shows = max(0.0, report.at - enabled_at)
        await ds.beats(10)
        ds.paused = True
        await asyncio.sleep(0.001)
        last = ds.log[-1]
        report, diffs = await self._see(lambda r: [] if r.state.get("enabled") is False else ["still enabled"],
                                        last.at, 1.5)
        ds.intent.enabled = False
        ds.paused = False
        if diffs:
            run.failed("R15", "robot code still read itself enabled 1.5 s after the last control packet: nothing told "
                              "it the DS had fallen silent",
                       evidence=[_sent(run, last, "the last control packet before the silence"),
                                 _line(run, report, "what robot code reads")])
            return None
        assert report is not None  # nothing wrong: a report passed the check (_see)
        await ds.beats(10)  # disabled packets: the robot back, disabled, before any second try
        return report.at - last.at, shows, last, report

    # -- R16 -------------------------------------------------------------------------------------------
    async def r16(self) -> None:
        ds, run = self.driver, self.run
        ds.intent.port, ds.intent.fms = self.o.fms_port, True
        first, last = await self._window(50)
        ds.intent.port, ds.intent.fms = self.o.udp_port, False
        packets = ds.between(first, last)
        got = [s for s in packets if s.seq in ds.reply_to]
        figures = {"sent": len(packets), "answered": len(got)}
        if not packets:
            run.not_applicable("R16", "no control packet went out to judge by", figures)
        elif len(got) < 0.98 * len(packets):
            run.failed("R16", f"{len(packets) - len(got)} of {len(packets)} control packets sent to UDP "
                              f"{self.o.fms_port} got no answer", figures,
                       [_sent(run, next(s for s in packets if s.seq not in ds.reply_to), f"sent to port {self.o.fms_port}")])
        else:
            run.passed("R16", f"{len(got)} of {len(packets)} packets to UDP {self.o.fms_port} answered", figures)

    # -- R17 -------------------------------------------------------------------------------------------
    async def r17(self) -> None:
        if not self._needs_enable("R17"):
            return
        ds, run = self.driver, self.run
        ds.intent.enabled, ds.intent.mode = True, Mode.TELEOP
        await self._steady(10)
        ds.intent.estop = True
        stop = await self._steady(5, 5)
        ds.intent.estop = False
        after = await self._steady(50, 45)  # enabled, no e-stop bit: the latch must hold
        echoed = next((r for _, r in stop if r is not None and r.pkt.estop), None)
        if echoed is None:
            run.failed("R17", "no answer shows the e-stop (status 0x80) while the DS sent it",
                       evidence=[_sent(run, stop[-1][0], "control with e-stop")]
                       + ([_got(run, stop[-1][1], "its answer")] if stop[-1][1] else []))
            ds.intent.enabled = False
            return
        broken = next(((s, r) for s, r in after if r is not None and (not r.pkt.estop or r.pkt.enabled)), None)
        ds.intent.enabled = False
        if broken is not None:
            s, r = broken
            what = "enabled again" if r.pkt.enabled else "e-stop cleared"
            run.failed("R17", f"{what} by a later packet without the e-stop bit: the e-stop does not latch",
                       evidence=[_sent(run, stop[-1][0], "the e-stop"), _sent(run, s, "a later packet, no e-stop"),
                                 _got(run, r, "its answer")])
            await self._restart_code()
            return
        t0 = time.monotonic()
        ds.intent.restart_left = 10
        cleared = await until(lambda: any(not r.pkt.estop for r in ds.good_replies() if r.at > t0 + 0.05), 15.0)
        if not cleared:
            run.failed("R17", "the e-stop held through 50 packets but did not clear within 15 s of a restart-code "
                              "request (0x04)", evidence=[_sent(run, ds.log[-1], "a packet after the restart request")])
            return
        took = next(r.at for r in ds.good_replies() if r.at > t0 + 0.05 and not r.pkt.estop) - t0
        await self._wait_code()
        run.passed("R17", "the e-stop held through 45 enabled packets without it, and cleared when the code "
                          f"restarted ({took:.2f} s after the request)", {"cleared_after_s": round(took, 2)})

    async def _restart_code(self) -> None:
        self.driver.intent.restart_left = 10
        await self.driver.beats(12)
        await self._wait_code()

    async def _wait_code(self) -> None:
        def running() -> bool:
            good = self.driver.good_replies()
            return bool(good) and good[-1].pkt.robot_code and not good[-1].pkt.code_initializing \
                and not good[-1].pkt.estop
        await until(running, 30.0, 0.02)  # a real roboRIO's Java code takes seconds to restart

    # -- R18 -------------------------------------------------------------------------------------------
    async def r18(self) -> None:
        if not self._needs_enable("R18"):
            return
        ds, run = self.driver, self.run
        station = int(self.o.station)

        def malformed(seq: int) -> bytes:
            # header: sequence, comm version 1, enabled teleop, request 0x10, station; then LibDS's tag
            return struct.pack(">HBBBB", seq, 0x01, 0x04, 0x10, station) + LIBDS_JOYSTICK_TAG
        # Disabled first: only a header that is applied can enable the robot now.
        ds.intent.enabled, ds.intent.mode = False, Mode.TELEOP
        await self._steady(10)
        ds.intent.override = malformed
        pairs = await self._steady(30, 20)
        ds.intent.override = None
        after = await self._steady(25, 20)
        answered = [(s, r) for s, r in pairs if r is not None]
        figures = {"sent": len(pairs), "answered": len(answered),
                   "enabled": sum(1 for _, r in answered if r.pkt.enabled)}
        if len(answered) < 0.9 * len(pairs):
            missing = next(s for s, r in pairs if r is None)
            run.failed("R18", f"{len(pairs) - len(answered)} of {len(pairs)} packets with the malformed tag got no "
                              "answer", figures, [_sent(run, missing, "a packet with LibDS's joystick tag, unanswered")])
            return
        if figures["enabled"] * 2 <= len(answered):
            s, r = next((s, r) for s, r in answered if not r.pkt.enabled)
            run.failed("R18", f"the header of a packet with a malformed tag was not applied: enabled was sent, "
                              f"{len(answered) - figures['enabled']} of {len(answered)} answers say disabled", figures,
                       [_sent(run, s, "enabled, LibDS's joystick tag"), _got(run, r, "its answer")])
            return
        if sum(1 for _, r in after if r is None) > 2:
            run.failed("R18", "the robot stopped answering after the packets with the malformed tag", figures,
                       [_sent(run, pairs[-1][0], "the last malformed packet")])
            return
        run.passed("R18", f"{figures['enabled']} of {len(answered)} answers to enabled packets with LibDS's joystick "
                          "tag say enabled (the header applied); the robot went on answering", figures)

    # -- R20-R24: at and past the limits ---------------------------------------------------------------
    def _header(self, seq: int) -> bytes:
        """A control packet's header: disabled teleop, DS attached (0x10), the station."""
        return struct.pack(">HBBBB", seq, 0x01, 0x00, 0x10, int(self.o.station))

    def _still_up(self, cid: str) -> bool:
        if self.crashed is not None:
            self.run.not_applicable(cid, f"the robot stopped answering in {self.crashed} (see there): nothing to judge")
            return False
        return True

    async def _limit_step(self, cid: str, what: str, tags: bytes, check: Callable[[Report], list[str]] | None,
                          shown: tuple[Evidence, ...] = ()) -> bool:
        """Send ``tags`` after a disabled header in LIMIT_PACKETS packets: whether the robot kept
        answering, with its code running, and robot code (if a program reports) reads what
        ``check`` wants. ``shown``: what else was sent (TCP frames), put first in a fail's evidence. When not, the verdict is given: a robot that stops answering is said
        to, with the packets it was sent and, if conform started it, how its process ended."""
        ds, run = self.driver, self.run
        before_code = self.code
        ds.intent.enabled = False
        ds.intent.override = lambda seq: self._header(seq) + tags
        first = ds.mark()
        await ds.beats(1)
        since = time.monotonic()
        await ds.beats(LIMIT_PACKETS - 1)
        last = ds.mark()
        packets = ds.between(first, last)
        await until(lambda: all(s.seq in ds.reply_to for s in packets), 1.0, 0.01)
        pairs = [(s, ds.reply_to.get(s.seq)) for s in packets]
        answered = [(s, r) for s, r in pairs if r is not None]
        figures: dict[str, Any] = {"sent": len(pairs), "answered": len(answered)}
        if not pairs:
            run.not_applicable(cid, "no control packet went out to judge by", figures)
            return False
        if len(answered) * 2 < len(pairs) or all(r is None for _, r in pairs[-5:]):
            # Neutral packets now: a robot that answers them only ignores what it cannot read;
            # one that answers nothing has stopped.
            ds.intent.override = None
            back_from = time.monotonic()
            back = await until(lambda: any(r.at > back_from for r in ds.good_replies()), CRASH_WAIT, 0.02)
            silent = next(s for s, r in pairs if r is None)
            last_sent = pairs[-1][0]
            figures["last_packet_sent"] = last_sent.data.hex()
            evidence = [*shown, _sent(run, silent, f"the first packet it did not answer ({what})"),
                        _sent(run, last_sent, f"the last packet sent with {what}")]
            if back:
                run.failed(cid, f"{len(pairs) - len(answered)} of {len(pairs)} packets with {what} got no answer "
                                "(packets without it are answered)", figures, evidence)
                return False
            self.crashed = cid
            why = (f"the robot stopped answering after {what}: no answer to {len(pairs) - len(answered)} of the "
                   f"{len(pairs)} packets sent with it, nor to any packet in the {CRASH_WAIT:g} s after")
            if self.launched is not None and not self.launched.running:
                code = self.launched.process.returncode
                figures["exit"] = describe_exit(code)
                why += f"; its process ended, {describe_exit(code)}"
                said = last_words(self.launched.tail(80))
                if said:
                    figures["last_lines"] = said
                    why += f", saying {said[-1][:300]!r}"
            run.failed(cid, why + f". The last packet sent: {last_sent.data.hex(' ')}", figures, evidence)
            return False
        no_code = [(s, r) for s, r in answered if not r.pkt.robot_code]
        if before_code and len(no_code) * 2 > len(answered):
            s, r = no_code[-1]
            run.failed(cid, f"after {what} the trace says no robot code (0x20 clear) in {len(no_code)} of "
                            f"{len(answered)} answers: the robot code stopped", figures,
                       [*shown, _sent(run, s, f"a packet with {what}"), _got(run, r, "its answer")])
            return False
        if check is None or not self.has_readback:
            return True
        report, diffs = await self._see(check, since)
        self.limit_report = report
        if diffs:
            packet = ds.sent.get(first)
            run.failed(cid, f"{what}: " + "; ".join(diffs[:8]), figures,
                       [*shown] + ([_sent(run, packet, f"the control packet: {what}")] if packet else [])
                       + [_line(run, report, "what robot code reads")])
            return False
        return True

    def _limit_pass(self, cid: str, what: str) -> None:
        seen = ("robot code reads " + what) if self.has_readback else \
            (what + " (no robot program reports what robot code reads: judged on the answers alone)")
        self.run.passed(cid, "the robot answered every step and " + seen)

    async def r20(self) -> None:
        if not self._still_up("R20"):
            return
        sticks = [limit_stick(k) for k in range(MAX_JOYSTICKS)]
        before = self.readback.last

        def check(r: Report) -> list[str]:
            out = []
            for k, stick in enumerate(sticks):
                out += prefix_differences(k, r.stick(k), stick.expected(), {})
            return out + descriptors_changed(before, r)
        what = f"six joysticks of {sticks[0].words()}"
        if await self._limit_step("R20", what, b"".join(st.tag() for st in sticks), check):
            self._limit_pass("R20", "every value of the six as sent, each in its slot")

    async def _past_limit(self, cid: str, key: str, limit: int, steps: list[RawStick]) -> None:
        """Slot 0 past a limit (each of ``steps``), slot 1 a plain stick: slot 0 reads at least
        its first ``limit`` values of ``key`` as sent, slot 1 and the descriptors as before."""
        if not self._still_up(cid):
            return
        run = self.run
        beside = RawStick((-128, 127), 0b1001, 4, (270,))
        failure = None
        read: list[str] = []
        for stick in steps:
            before = self.readback.last

            def check(r: Report, stick: RawStick = stick, before: Report | None = before) -> list[str]:
                return (prefix_differences(0, r.stick(0), stick.expected(), {key: limit})
                        + prefix_differences(1, r.stick(1), beside.expected(), {}) + descriptors_changed(before, r))
            sent = len(getattr(stick, key))
            if await self._limit_step(cid, f"a joystick of {stick.words()} in slot 0", stick.tag() + beside.tag(), check):
                seen = self.limit_report.stick(0).get(key) if self.limit_report is not None else None
                read.append(f"{len(seen)} of {sent}" if isinstance(seen, list) else f"? of {sent}")
                continue
            # A misreading is a finding, and the bigger step still runs: a robot that dies of
            # it is the graver one, and the crash is the verdict then.
            result = run.results.get(cid)
            if self.crashed is not None or result is None or result.verdict is not Verdict.FAIL:
                if failure is not None and result is not None:
                    result.figures["before"] = f"fail: {failure.reason}"
                return
            run.results.pop(cid)
            if failure is None:
                failure = result
            else:
                failure.figures.setdefault("then", []).append(result.reason)
        if failure is not None:
            run.results[cid] = failure
            return
        what = "POVs" if key == "povs" else "axes"
        self._limit_pass(cid, f"{' and '.join(read)} {what} as sent (at least the first {limit} wanted), slot 1 "
                              "and every descriptor as before")

    async def r21(self) -> None:
        povs = [RawStick((), 0, 0, tuple(45 * ((3 * p + 1) % 8) for p in range(n))) for n in (MAX_POVS + 1, TAG_MOST_POVS)]
        await self._past_limit("R21", "povs", MAX_POVS, povs)

    async def r22(self) -> None:
        axes = [RawStick(tuple(((11 * a + 5) % 255) - 127 for a in range(n))) for n in (MAX_AXES + 1, TAG_MOST_AXES)]
        await self._past_limit("R22", "axes", MAX_AXES, axes)

    async def r23(self) -> None:
        if not self._still_up("R23"):
            return
        six = [RawStick((20 * k - 50,), 1 << k, 8, (45 * k,)) for k in range(MAX_JOYSTICKS)]
        seventh = limit_stick(6)
        before = self.readback.last

        def check(r: Report) -> list[str]:
            out = []
            for k, stick in enumerate(six):
                out += prefix_differences(k, r.stick(k), stick.expected(), {})
            return out + descriptors_changed(before, r)
        tags = b"".join(st.tag() for st in six) + seventh.tag()
        if await self._limit_step("R23", f"seven joystick tags, the seventh of {seventh.words()}", tags, check):
            self._limit_pass("R23", "slots 0-5 as sent and every descriptor as before")

    async def r24(self) -> None:
        if not self._still_up("R24") or not await self._tcp_needed("R24"):
            return
        ds, run = self.driver, self.run
        name = "conform R24 slot 0"
        stick = RawStick((64, -64), 0b11, 2, (90,))
        ds.intent.enabled, ds.intent.override = False, lambda seq: self._header(seq) + stick.tag()
        self._tcp_send(JoystickDescriptor(0, False, JoystickType.HID_JOYSTICK, name, (AxisType.X, AxisType.Y), 2, 1).encode())
        await ds.beats(1)
        before: Report | None = None
        if self.has_readback:
            before, diffs = await self._see(lambda r: [] if r.stick(0).get("name") == name else
                                            [f"slot 0's name reads {r.stick(0).get('name')!r}"], time.monotonic())
            if diffs:
                run.not_applicable("R24", f"robot code did not read slot 0's descriptor to begin with ({diffs[0]}; "
                                          "R13 judges descriptors)")
                return
        try:
            # slot 6 first (just past the six), then 255 (as far as the byte goes): a robot that
            # dies of one is said to have died of that one
            for index in (6, 255):
                frame = JoystickDescriptor(index, True, JoystickType.XINPUT_GAMEPAD, f"conform R24 slot {index}",
                                           tuple(AxisType.Z for _ in range(12)), 32, 12).encode()
                shown = Evidence("sent", run.now(), f"a descriptor for slot {index}", "ds-to-rio-tcp", frame)
                self._tcp_send(frame)

                def check(r: Report, before: Report | None = before) -> list[str]:
                    return prefix_differences(0, r.stick(0), stick.expected(), {}) + descriptors_changed(before, r)
                if not await self._limit_step("R24", f"a descriptor for slot {index} on TCP 1740", stick.tag(), check,
                                              (shown,)):
                    return
                before = self.limit_report or before
            self._limit_pass("R24", "slot 0's name, and every other slot's descriptor, as before, after descriptors "
                                    "for slots 6 and 255")
        finally:
            for slot in range(MAX_JOYSTICKS):
                self._tcp_send(JoystickDescriptor(slot).encode())

    # -- R19 -------------------------------------------------------------------------------------------
    async def r19(self) -> None:
        ds, run = self.driver, self.run
        tags: dict[str, int] = {}
        known = {rio_to_ds.TAG_JOYSTICK_OUTPUT, rio_to_ds.TAG_DISK_INFO, rio_to_ds.TAG_CPU_INFO,
                 rio_to_ds.TAG_RAM_INFO, rio_to_ds.TAG_PDP_LOG, rio_to_ds.TAG_CAN_METRICS}
        for r in ds.replies:
            if r.packet is None:
                run.failed("R19", f"a status packet does not decode: {r.error}", evidence=[_got(run, r, "bad packet")])
                return
            outputs = 0
            for tag in r.packet.tags:
                name = type(tag).__name__
                tags[name] = tags.get(name, 0) + 1
                if type(tag) is UnknownTag and tag.tag_id in known:
                    run.failed("R19", f"tag 0x{tag.tag_id:02x} is not laid out as documented",
                               {"tags": tags}, [_got(run, r, "the status packet")])
                    return
                outputs += type(tag) is rio_to_ds.JoystickOutput
            if outputs > 6:
                run.failed("R19", f"{outputs} joystick output tags in one packet: six slots at most",
                           {"tags": tags}, [_got(run, r, "the status packet")])
                return
        frames: dict[str, int] = {}
        for stream in self.tcp_streams:
            for f in stream.frames:
                try:
                    message = rio_to_ds.decode_tcp(f.data)
                except ProtocolError as exc:
                    run.failed("R19", f"a TCP 1740 frame does not decode: {exc}", {"tags": tags},
                               [Evidence("received", run.since(f.at), "bad frame", "rio-to-ds-tcp", f.data)])
                    return
                name = type(message).__name__
                frames[name] = frames.get(name, 0) + 1
            if stream.error is not None:
                run.failed("R19", f"TCP 1740 framing error: {stream.error}", {"tags": tags, "frames": frames})
                return
            unfinished = stream.unfinished()
            if unfinished is not None and unfinished[1] > UNFINISHED_FRAME:
                held, seconds = unfinished
                what = (f"a TCP 1740 frame begun {seconds:.1f} s ago is not finished" if stream.is_open else
                        f"the TCP 1740 connection closed {seconds:.1f} s into a frame it never finished")
                run.failed("R19", f"{what} ({held} bytes of it came): a robot writes a frame at once",
                           {"tags": tags, "frames": frames, "allowed_s": UNFINISHED_FRAME})
                return
        slowest = max((s.slowest_frame for s in self.tcp_streams), default=0.0)
        run.passed("R19", f"{len(ds.replies)} status packets and {sum(frames.values())} TCP frames walk cleanly",
                   {"status_tags": tags, "tcp_frames": frames, "slowest_frame_s": round(slowest, 2)})


async def conform_robot(opts: RobotOptions, err: Any = None) -> Run:
    run = Run("robot", opts.address, list(CASES), selected=opts.cases)
    return await RobotConformance(opts, run, err).execute()
