"""roboRIO -> Driver Station: the UDP status packet (port 1150) and its tags. The TCP 1740
frames (stdout, errors and warnings, versions, faults, usage report) live in
:mod:`protocol.rio_to_ds_tcp`; this module re-exports them and registers both kinds.

Source: docs/protocol.md#rio-to-ds (the seed rio_to_ds.rst), settled by
docs/protocol.md#rio-behaviour (how a real roboRIO and WPILib's simulator behave). Where a
real peer or a real decoder differs from the seed, the code follows the peer and a comment
names both.

The status packet is the 50 Hz hot path, so it has two decoders: ``walk_status`` is the
reference (a :class:`~protocol.wire.Reader` walk that names field and offset on failure and
records spans for ``annotate``), and ``decode_status`` is a hand-unrolled fast path that
falls back to the walk on anything irregular. A property test holds them equal.
"""

from __future__ import annotations

import math
import struct
from dataclasses import dataclass
from typing import Any, Callable, Union

from .enums import MODE_TEXT, DeviceType, Mode  # DeviceType: re-exported, VersionInfo's enum
from .errors import ProtocolError
from .frames import MAX_TAGS, check_packet, keep_raw, walk_tag_header, walk_tags
from .kinds import Kind
# The TCP frames, re-exported: ``from protocol.rio_to_ds import ErrorMessage`` keeps working.
from .rio_to_ds_tcp import (
    END_OF_VERSION_LIST, ERROR_FLAG_IS_ERROR, ERROR_FLAG_LV_CODE, FRAME_DISABLE_FAULTS, FRAME_ERROR_MESSAGE,
    FRAME_RADIO_EVENTS, FRAME_RAIL_FAULTS, FRAME_STDOUT, FRAME_UNKNOWN_0D, FRAME_USAGE_REPORT,
    FRAME_VERSION_INFO, MAX_TCP_FRAME, TCP, DisableFaults, ErrorMessage, KeepAlive, RadioEvents, RailFaults, RioToDsFrame,
    StdoutMessage, Unknown0d, UnknownFrame, UsageReport, VersionInfo, annotate_tcp, decode_tcp, walk_tcp,
)
from .wire import (F32, U32, Irregular, Reader, Span, UnknownTag, annotate_with, check_f32, check_int,
                   over_bound, udp_tag, unchecked_constructor)

STATUS = "StatusPacket"

#: The largest status packet decoded; a longer one is refused by its length alone, before
#: anything is walked. By the layout a real roboRIO's is at most 177 bytes: the 8-byte header,
#: six joystick outputs (10 each), disk (10), CPU for its two cores (35), RAM (10), PDP (27),
#: tag 0x09 (11) and CAN (16); the real roboRIO of the 2021 capture sent 59 at most. UDP would
#: carry 65,507.
MAX_STATUS_SIZE = 1024
_STATUS_WHAT = "a status packet (a real roboRIO's is at most 177 bytes)"

# Status byte (seed table "Status"). Bits 0x60 are named by no document: kept in status_other.
STATUS_ESTOP = 0x80
STATUS_BROWNOUT = 0x10
STATUS_CODE_INITIALIZING = 0x08
STATUS_ENABLED = 0x04
STATUS_MODE = 0x03
STATUS_OTHER_MASK = 0x60
# Trace byte (seed table "Trace"). Bits 0xc0 are kept in trace_other.
TRACE_ROBOT_CODE = 0x20
TRACE_IS_ROBORIO = 0x10
TRACE_TEST = 0x08
TRACE_AUTONOMOUS = 0x04
TRACE_TELEOP = 0x02
TRACE_DISABLED = 0x01
TRACE_OTHER_MASK = 0xC0
# Request byte: 0x01 asks the DS for its date and time zone (tags 0x0f/0x10), once.
REQUEST_DATE = 0x01

TAG_JOYSTICK_OUTPUT = 0x01
TAG_DISK_INFO = 0x04
TAG_CPU_INFO = 0x05
TAG_RAM_INFO = 0x06
TAG_PDP_LOG = 0x08
TAG_UNKNOWN_09 = 0x09
TAG_CAN_METRICS = 0x0E

PDP_CHANNELS = 16
PDP_AMPS_PER_UNIT = 0.125  # 10-bit channel current in 1/8 A (open-ds, DSLog-Reader, ligerbots dslogparser)
MAX_PDP_RAW = 0x3FF


# -- battery --------------------------------------------------------------------------
def battery_to_raw(volts: float) -> int:
    """Volts to the wire's u16 ``XXYY`` (``XX + YY/256``), rounded to the nearest 1/256 V.

    Refuses (ProtocolError) anything that is not a number in ``0 <= volts < 256``.
    """
    if isinstance(volts, bool) or not isinstance(volts, (int, float)):
        raise ProtocolError(STATUS, "battery", None, f"{volts!r} is not a number of volts")
    if not 0.0 <= volts < 256.0:  # also refuses NaN
        raise ProtocolError(STATUS, "battery", None, f"{volts!r} V is outside 0 <= volts < 256")
    raw = round(volts * 256)
    return raw if raw <= 0xFFFF else 0xFFFF


def raw_to_battery(raw: int) -> float:
    """The wire's u16 ``XXYY`` to volts (exact: every raw value is a float)."""
    check_int(STATUS, "battery", raw, 0, 0xFFFF)
    return raw / 256.0


# -- tags -----------------------------------------------------------------------------
@dataclass(frozen=True, slots=True)
class JoystickOutput:
    """Tag 0x01: the outputs and rumble the robot program set for one joystick slot.

    Wire order, as this library reads and writes it: ``[u32 outputs][u16 right][u16 left]``.
    WPILib's simulator (``halsim_ds_socket`` DSCommPacket.cpp ``SetupJoystickTag``) writes
    right rumble first, and a capture of it agrees (/work/interop/captures/probe_run.json:
    left 0.25 / right 0.75 went out as ``bfff 3fff``). The seed document's table says left
    comes first. We follow the real peer.

    An idle slot is the 1-byte tag ``01 01`` (size 1, no payload): ``idle=True``, every other
    field 0. Slots keep their numbers by position in the packet. A real roboRIO with nothing
    set sends no tag at all (none in the 4,352 status packets of the 2021 capture, a
    controller attached): a slot with no tag reads as nothing set.
    """

    outputs: int = 0  # bit n-1 = output n (LSB 0, as WPILib's setOutput numbers them)
    right_rumble: int = 0  # 0..65535
    left_rumble: int = 0  # 0..65535
    idle: bool = False

    def output(self, number: int) -> bool:
        """Whether output ``number`` (1-based, as WPILib numbers them) is on."""
        return 1 <= number <= 32 and bool(self.outputs >> (number - 1) & 1)


IDLE_JOYSTICK_OUTPUT = JoystickOutput(idle=True)


@dataclass(frozen=True, slots=True)
class DiskInfo:
    """Tag 0x04: free disk space in bytes.

    A real roboRIO sends 8 bytes, laid out like RAM info: a u32 block then the u32 free space
    (``09 04 00000000 084c4000``, the 2021 capture's frame 69), as open-ds ("Indices differ
    from documentation") and Creighton's Wireshark dissector (jcreigh/FRCDriverStation) read
    it. The seed's table gives 4 bytes (free space only); that form decodes too, with
    ``block`` None, so either re-encodes byte-identical.
    """

    free_bytes: int = 0
    block: int | None = None


@dataclass(frozen=True, slots=True)
class CpuLoad:
    """One CPU in tag 0x05: percentages of time by thread priority (f32 each)."""

    time_critical: float = 0.0
    above_normal: float = 0.0
    normal: float = 0.0
    low: float = 0.0


@dataclass(frozen=True, slots=True)
class CpuInfo:
    """Tag 0x05: a u8 number of CPUs, then four f32 per CPU.

    A real roboRIO writes ``22 05 02`` + 2 x 16 bytes (the 2021 capture, e.g. frame 55), and
    open-ds reads the count as one byte. The seed's table says the count is an f32 (2.0):
    no real roboRIO sends that, and a reader of the real form cannot walk past it. It still
    decodes, with ``f32_count`` True so it re-encodes byte-identical; encoding writes the
    real form unless asked.
    """

    cpus: tuple[CpuLoad, ...] = ()
    f32_count: bool = False  # the seed's form: the count as an f32


@dataclass(frozen=True, slots=True)
class RamInfo:
    """Tag 0x06: u32 block (meaning unknown) and u32 free bytes."""

    block: int = 0
    free_bytes: int = 0


@dataclass(frozen=True, slots=True)
class PdpLog:
    """Tag 0x08: 1 unknown byte, sixteen 10-bit channel currents in 21 bytes, 3 unknown bytes.

    Bit order: the 21 bytes are a big-endian u64 holding channels 0-5 (10 bits each, channel
    0 in the top bits) then 4 pad bits, a second u64 holding channels 6-11 then 4 pad bits,
    and a 40-bit big-endian group holding channels 12-15. That is the seed's struct read
    most-significant bit first, and how open-ds (ReceiveTag.PDP_LOG), DSLog-Reader and
    ligerbots/dslogparser unpack the same 25 bytes in the DS log (offsets 8, 18, ... 58,
    72 ... 122, 136 ... 166 in the 25). A Chief Delphi post puts the pad bits mid-group
    (channel 4 at 52); we follow the decoders. Pad bits are kept so a decode re-encodes
    byte-identical. ``currents`` are raw units of 1/8 A; :attr:`amps` scales them.
    """

    currents: tuple[int, ...] = (0,) * PDP_CHANNELS
    unknown_head: int = 0  # DS log parsers call it the PDP's id; nothing confirms it
    unknown_tail: bytes = b"\x00\x00\x00"  # dslogparser guesses resistance, voltage, temperature
    pad1: int = 0  # the 4 low bits of the first u64
    pad2: int = 0  # the 4 low bits of the second u64

    @property
    def amps(self) -> tuple[float, ...]:
        return tuple(c * PDP_AMPS_PER_UNIT for c in self.currents)


@dataclass(frozen=True, slots=True)
class Unknown09:
    """Tag 0x09: 9 bytes no document explains (the seed's "Unknown"), kept raw."""

    data: bytes = bytes(9)


@dataclass(frozen=True, slots=True)
class CanMetrics:
    """Tag 0x0e: CAN bus utilisation and error counters."""

    utilization: float = 0.0  # percent, as the seed reads it (open-ds: a fraction; unsettled)
    bus_off: int = 0
    tx_full: int = 0
    rx_errors: int = 0
    tx_errors: int = 0


StatusTag = Union[JoystickOutput, DiskInfo, CpuInfo, RamInfo, PdpLog, Unknown09, CanMetrics, UnknownTag]


# -- the status packet ----------------------------------------------------------------
@dataclass(frozen=True, slots=True)
class StatusPacket:
    """roboRIO -> DS UDP, in answer to every control packet."""

    sequence: int = 0
    comm_version: int = 0x01
    # status byte: mostly an echo of the DS's control byte
    estop: bool = False
    brownout: bool = False
    code_initializing: bool = False  # seed "Code Start": 0 running, 1 initializing
    enabled: bool = False
    mode: Mode = Mode.TELEOP
    # trace byte: what the robot program reports about itself
    robot_code: bool = False
    is_roborio: bool = False
    user_test: bool = False
    user_auto: bool = False
    user_teleop: bool = False
    user_disabled: bool = False
    battery: float = 0.0  # volts, a multiple of 1/256 after decoding
    request_date: bool = False
    tags: tuple[StatusTag, ...] = ()
    status_other: int = 0  # status bits no document names (0x60), kept for byte identity
    trace_other: int = 0  # trace bits no document names (0xc0)
    request_other: int = 0  # request bits besides 0x01

    @property
    def joystick_outputs(self) -> tuple[JoystickOutput, ...]:
        """The joystick output tags in slot order (idle slots included)."""
        return tuple(t for t in self.tags if type(t) is JoystickOutput)

    @property
    def status_byte(self) -> int:
        return ((STATUS_ESTOP if self.estop else 0) | (STATUS_BROWNOUT if self.brownout else 0)
                | (STATUS_CODE_INITIALIZING if self.code_initializing else 0)
                | (STATUS_ENABLED if self.enabled else 0) | (int(self.mode) & 3) | self.status_other)

    @property
    def trace_byte(self) -> int:
        return ((TRACE_ROBOT_CODE if self.robot_code else 0) | (TRACE_IS_ROBORIO if self.is_roborio else 0)
                | (TRACE_TEST if self.user_test else 0) | (TRACE_AUTONOMOUS if self.user_auto else 0)
                | (TRACE_TELEOP if self.user_teleop else 0) | (TRACE_DISABLED if self.user_disabled else 0)
                | self.trace_other)

    @property
    def request_byte(self) -> int:
        return (REQUEST_DATE if self.request_date else 0) | self.request_other

    @property
    def battery_raw(self) -> int:
        return battery_to_raw(self.battery)

    def encode(self) -> bytes:
        try:
            mode = self.mode
            if (self.status_other & ~STATUS_OTHER_MASK or self.trace_other & ~TRACE_OTHER_MASK
                    or self.request_other & ~0xFE or not 0 <= mode <= 3):
                raise ValueError("bits out of place")
            head = _HEADER.pack(self.sequence, self.comm_version, self.status_byte, self.trace_byte,
                                battery_to_raw(self.battery), self.request_byte)
            if not self.tags:
                return head
            parts = [head]
            for tag in self.tags:
                parts.append(_ENCODERS[type(tag)](tag))
            data = b"".join(parts)
        except (struct.error, TypeError, ValueError, OverflowError, KeyError, AttributeError) as exc:
            self._validate()
            raise ProtocolError(STATUS, "?", None, str(exc)) from None
        if len(data) > MAX_STATUS_SIZE or len(self.tags) > MAX_TAGS:
            check_packet(STATUS, data, len(self.tags), MAX_STATUS_SIZE, _STATUS_WHAT)
        return data

    def _validate(self) -> None:
        check_int(STATUS, "sequence", self.sequence, 0, 0xFFFF)
        check_int(STATUS, "comm_version", self.comm_version, 0, 0xFF)
        check_int(STATUS, "mode", self.mode, 0, 3)
        if check_int(STATUS, "status_other", self.status_other, 0, 0xFF) & ~STATUS_OTHER_MASK:
            raise ProtocolError(STATUS, "status_other", None, "may only hold bits 0x60")
        if check_int(STATUS, "trace_other", self.trace_other, 0, 0xFF) & ~TRACE_OTHER_MASK:
            raise ProtocolError(STATUS, "trace_other", None, "may only hold bits 0xc0")
        if check_int(STATUS, "request_other", self.request_other, 0, 0xFF) & REQUEST_DATE:
            raise ProtocolError(STATUS, "request_other", None, "may not hold the request-date bit 0x01")
        battery_to_raw(self.battery)
        for i, tag in enumerate(self.tags):
            _validate_tag(tag, f"tags[{i}]")


_HEADER = struct.Struct(">HBBBHB")
_JOY_OUT_TAG = struct.Struct(">BBIHH")
_JOY_OUT = struct.Struct(">IHH")
_II = struct.Struct(">II")
_CAN = struct.Struct(">fIIBB")
_CAN_TAG = struct.Struct(">BBfIIBB")
_RAM_TAG = struct.Struct(">BBII")
_DISK4_TAG = struct.Struct(">BBI")
_PDP_HEAD = struct.Struct(">BBBQQ")
_Q = struct.Struct(">Q")
_CPU_STRUCTS: dict[int, struct.Struct] = {}
_IDLE_TAG = bytes((1, TAG_JOYSTICK_OUTPUT))


def _cpu_struct(n: int) -> struct.Struct:
    st = _CPU_STRUCTS.get(n)
    if st is None:
        st = _CPU_STRUCTS[n] = struct.Struct(f">{4 * n}f")
    return st


def _encode_joystick_output(tag: JoystickOutput) -> bytes:
    if tag.idle:
        if tag.outputs or tag.right_rumble or tag.left_rumble:
            raise ValueError("an idle joystick output carries no values")
        return _IDLE_TAG
    return _JOY_OUT_TAG.pack(9, TAG_JOYSTICK_OUTPUT, tag.outputs, tag.right_rumble, tag.left_rumble)


def _encode_disk(tag: DiskInfo) -> bytes:
    if tag.block is None:
        return _DISK4_TAG.pack(5, TAG_DISK_INFO, tag.free_bytes)
    return _RAM_TAG.pack(9, TAG_DISK_INFO, tag.block, tag.free_bytes)


def _encode_cpu(tag: CpuInfo) -> bytes:
    n = len(tag.cpus)
    values: list[float] = []
    for c in tag.cpus:
        values += (c.time_critical, c.above_normal, c.normal, c.low)
    count = F32.pack(float(n)) if tag.f32_count else bytes((n,))
    return udp_tag(STATUS, "cpu", TAG_CPU_INFO, count + _cpu_struct(n).pack(*values))


def _encode_ram(tag: RamInfo) -> bytes:
    return _RAM_TAG.pack(9, TAG_RAM_INFO, tag.block, tag.free_bytes)


def _encode_pdp(tag: PdpLog) -> bytes:
    c = tag.currents
    if len(c) != PDP_CHANNELS or max(c) > MAX_PDP_RAW or min(c) < 0 or len(tag.unknown_tail) != 3 \
            or not 0 <= tag.pad1 <= 15 or not 0 <= tag.pad2 <= 15:
        raise ValueError("PDP log out of range")
    g0 = c[0] << 54 | c[1] << 44 | c[2] << 34 | c[3] << 24 | c[4] << 14 | c[5] << 4 | tag.pad1
    g1 = c[6] << 54 | c[7] << 44 | c[8] << 34 | c[9] << 24 | c[10] << 14 | c[11] << 4 | tag.pad2
    g2 = c[12] << 30 | c[13] << 20 | c[14] << 10 | c[15]
    return (_PDP_HEAD.pack(26, TAG_PDP_LOG, tag.unknown_head, g0, g1) + g2.to_bytes(5, "big")
            + tag.unknown_tail)


def _encode_unknown09(tag: Unknown09) -> bytes:
    return udp_tag(STATUS, "unknown09", TAG_UNKNOWN_09, tag.data)


def _encode_can(tag: CanMetrics) -> bytes:
    return _CAN_TAG.pack(15, TAG_CAN_METRICS, tag.utilization, tag.bus_off, tag.tx_full,
                         tag.rx_errors, tag.tx_errors)


def _encode_unknown(tag: UnknownTag) -> bytes:
    return udp_tag(STATUS, "unknown", tag.tag_id, tag.data)


_ENCODERS: dict[type, Callable[[Any], bytes]] = {
    JoystickOutput: _encode_joystick_output, DiskInfo: _encode_disk, CpuInfo: _encode_cpu,
    RamInfo: _encode_ram, PdpLog: _encode_pdp, Unknown09: _encode_unknown09, CanMetrics: _encode_can,
    UnknownTag: _encode_unknown,
}

MAX_CPUS = (0xFE - 4) // 16  # what a u8 tag size leaves room for, either count form


def _check_bytes(where: str, value: object, lo: int, hi: int) -> None:
    if not isinstance(value, (bytes, bytearray, memoryview)):
        raise ProtocolError(STATUS, where, None, f"{value!r} is not bytes")
    if not lo <= len(value) <= hi:
        want = f"exactly {lo}" if lo == hi else f"{lo}..{hi}"
        raise ProtocolError(STATUS, where, None, f"{len(value)} bytes, {want} allowed")


def _validate_tag(tag: object, where: str) -> None:
    if type(tag) is JoystickOutput:
        check_int(STATUS, f"{where}.outputs", tag.outputs, 0, 0xFFFFFFFF)
        check_int(STATUS, f"{where}.right_rumble", tag.right_rumble, 0, 0xFFFF)
        check_int(STATUS, f"{where}.left_rumble", tag.left_rumble, 0, 0xFFFF)
        if tag.idle and (tag.outputs or tag.right_rumble or tag.left_rumble):
            raise ProtocolError(STATUS, f"{where}.idle", None,
                                "an idle slot is the bare tag 01 01: outputs and rumble must be 0")
    elif type(tag) is DiskInfo:
        check_int(STATUS, f"{where}.free_bytes", tag.free_bytes, 0, 0xFFFFFFFF)
        if tag.block is not None:
            check_int(STATUS, f"{where}.block", tag.block, 0, 0xFFFFFFFF)
    elif type(tag) is CpuInfo:
        if len(tag.cpus) > MAX_CPUS:
            raise ProtocolError(STATUS, f"{where}.cpus", None, f"{len(tag.cpus)} CPUs, at most {MAX_CPUS}")
        if type(tag.f32_count) is not bool:
            raise ProtocolError(STATUS, f"{where}.f32_count", None, f"{tag.f32_count!r} is not a bool")
        for j, cpu in enumerate(tag.cpus):
            if type(cpu) is not CpuLoad:
                raise ProtocolError(STATUS, f"{where}.cpus[{j}]", None, f"{cpu!r} is not a CpuLoad")
            for name in ("time_critical", "above_normal", "normal", "low"):
                check_f32(STATUS, f"{where}.cpus[{j}].{name}", getattr(cpu, name))
    elif type(tag) is RamInfo:
        check_int(STATUS, f"{where}.block", tag.block, 0, 0xFFFFFFFF)
        check_int(STATUS, f"{where}.free_bytes", tag.free_bytes, 0, 0xFFFFFFFF)
    elif type(tag) is PdpLog:
        if len(tag.currents) != PDP_CHANNELS:
            raise ProtocolError(STATUS, f"{where}.currents", None,
                                f"{len(tag.currents)} channels, exactly {PDP_CHANNELS} needed")
        for j, c in enumerate(tag.currents):
            check_int(STATUS, f"{where}.currents[{j}]", c, 0, MAX_PDP_RAW)
        check_int(STATUS, f"{where}.unknown_head", tag.unknown_head, 0, 0xFF)
        _check_bytes(f"{where}.unknown_tail", tag.unknown_tail, 3, 3)
        check_int(STATUS, f"{where}.pad1", tag.pad1, 0, 15)
        check_int(STATUS, f"{where}.pad2", tag.pad2, 0, 15)
    elif type(tag) is Unknown09:
        _check_bytes(f"{where}.data", tag.data, 0, 0xFE)
    elif type(tag) is CanMetrics:
        check_f32(STATUS, f"{where}.utilization", tag.utilization)
        check_int(STATUS, f"{where}.bus_off", tag.bus_off, 0, 0xFFFFFFFF)
        check_int(STATUS, f"{where}.tx_full", tag.tx_full, 0, 0xFFFFFFFF)
        check_int(STATUS, f"{where}.rx_errors", tag.rx_errors, 0, 0xFF)
        check_int(STATUS, f"{where}.tx_errors", tag.tx_errors, 0, 0xFF)
    elif type(tag) is UnknownTag:
        check_int(STATUS, f"{where}.tag_id", tag.tag_id, 0, 0xFF)
        _check_bytes(f"{where}.data", tag.data, 0, 0xFE)
    else:
        raise ProtocolError(STATUS, where, None, f"{type(tag).__name__} is not a status packet tag")


# -- decoding: the reference walk ----------------------------------------------------
def _status_text(b: int) -> str:
    words = ["E-STOPPED" if b & STATUS_ESTOP else "no e-stop",
             "BROWNOUT" if b & STATUS_BROWNOUT else "voltage normal",
             "code initializing" if b & STATUS_CODE_INITIALIZING else "code running",
             "enabled" if b & STATUS_ENABLED else "disabled",
             MODE_TEXT[b & 3]]
    if b & STATUS_OTHER_MASK:
        words.append(f"other bits 0x{b & STATUS_OTHER_MASK:02x}")
    return ", ".join(words)


def _trace_text(b: int) -> str:
    words = ["robot code" if b & TRACE_ROBOT_CODE else "NO robot code",
             "is a roboRIO" if b & TRACE_IS_ROBORIO else "not a roboRIO (simulator?)"]
    running = [name for bit, name in ((TRACE_DISABLED, "disabled"), (TRACE_TELEOP, "teleop"),
                                      (TRACE_AUTONOMOUS, "auto"), (TRACE_TEST, "test")) if b & bit]
    words.append(f"program in {'/'.join(running)} code" if running else "program reports no mode")
    if b & TRACE_OTHER_MASK:
        words.append(f"other bits 0x{b & TRACE_OTHER_MASK:02x}")
    return ", ".join(words)


def walk_status(r: Reader) -> StatusPacket:
    seq = r.u16("sequence", "sequence number, echoed from the DS's control packet")
    ver = r.u8("comm_version", "comm version (0x01 on every real roboRIO)")
    st = r.u8("status")
    r.explain(f"0x{st:02x}", f"status: {_status_text(st)}")
    tr = r.u8("trace")
    r.explain(f"0x{tr:02x}", f"trace: {_trace_text(tr)}")
    raw = r.u16("battery")
    volts = raw / 256.0
    r.explain(f"{volts:.2f} V", f"battery: {volts:.2f} V (XX + YY/256 = {raw >> 8} + {raw & 0xFF}/256)")
    req = r.u8("request_date")
    r.explain(f"0x{req:02x}", "request: DS, send date and time zone (0x01)" if req & REQUEST_DATE
              else "request: nothing asked" if not req else f"request: other bits 0x{req:02x}")
    r.refuse_over(MAX_STATUS_SIZE, _STATUS_WHAT)
    tags = walk_tags(r, _walk_tag)
    return StatusPacket(seq, ver, bool(st & STATUS_ESTOP), bool(st & STATUS_BROWNOUT),
                        bool(st & STATUS_CODE_INITIALIZING), bool(st & STATUS_ENABLED), Mode(st & 3),
                        bool(tr & TRACE_ROBOT_CODE), bool(tr & TRACE_IS_ROBORIO), bool(tr & TRACE_TEST),
                        bool(tr & TRACE_AUTONOMOUS), bool(tr & TRACE_TELEOP), bool(tr & TRACE_DISABLED),
                        volts, bool(req & REQUEST_DATE), tags, st & STATUS_OTHER_MASK,
                        tr & TRACE_OTHER_MASK, req & 0xFE)


def _walk_tag(r: Reader, where: str) -> StatusTag:
    t, tag_id = walk_tag_header(r, where)
    size = t.remaining() + 1  # the size byte counts the id byte
    start, kept = t.pos, len(t.spans) if t.spans is not None else 0
    try:
        return _walk_known_tag(t, tag_id, size)
    except ProtocolError as exc:
        # A tag that is whole (its size fits the packet) but not laid out as documented is
        # kept raw instead of failing the packet: a real roboRIO's tag variant must not cost
        # the DS its status packets (the CPU and disk tags are read differently by different
        # decoders). Only a broken tag frame makes the packet bad.
        t.pos = start
        if t.spans is not None:
            del t.spans[kept:]
        return UnknownTag(tag_id, t.rest("data", f"tag 0x{tag_id:02x} not laid out as documented "
                                                 f"({exc.field}: {exc.reason}); kept raw"))


def _walk_known_tag(t: Reader, tag_id: int, size: int) -> StatusTag:
    if tag_id == TAG_JOYSTICK_OUTPUT:
        if size == 1:
            t.explain("joystick_output (idle)", "tag 0x01: joystick output, idle slot (size 1, no data)")
            return IDLE_JOYSTICK_OUTPUT
        t.explain("joystick_output", "tag 0x01: joystick outputs and rumble for the next slot")
        outputs = t.u32("outputs")
        on = [str(b + 1) for b in range(32) if outputs >> b & 1]
        t.explain(f"0x{outputs:08x}", f"HID outputs, bit 0 = output 1; on: {', '.join(on) or 'none'}")
        right = t.u16("right_rumble")
        t.explain(None, f"right rumble {right / 65535:.0%} (read right-first as WPILib's simulator "
                        "writes it; the seed's table calls this u16 the LEFT rumble)")
        left = t.u16("left_rumble")
        t.explain(None, f"left rumble {left / 65535:.0%} (read right-first as WPILib's simulator "
                        "writes it; the seed's table calls this u16 the RIGHT rumble)")
        value: StatusTag = JoystickOutput(outputs, right, left)
    elif tag_id == TAG_DISK_INFO:
        t.explain("disk_info", "tag 0x04: disk info")
        block = None
        if t.remaining() == 8:
            block = t.u32("block", "unknown u32 (a real roboRIO sends 8 bytes, as open-ds reads them; "
                                   "the seed's table has 4)")
        free = t.u32("free_bytes")
        t.explain(None, f"free disk space: {free:,} bytes")
        value = DiskInfo(free, block)
    elif tag_id == TAG_CPU_INFO:
        t.explain("cpu_info", "tag 0x05: CPU usage")
        value = _walk_cpu(t)
    elif tag_id == TAG_RAM_INFO:
        t.explain("ram_info", "tag 0x06: RAM info")
        block = t.u32("block", "unknown u32 (the seed calls it block)")
        free = t.u32("free_bytes")
        t.explain(None, f"free RAM: {free:,} bytes")
        value = RamInfo(block, free)
    elif tag_id == TAG_PDP_LOG:
        t.explain("pdp_log", "tag 0x08: PDP channel currents")
        value = _walk_pdp(t)
    elif tag_id == TAG_UNKNOWN_09:
        t.explain("unknown_09", "tag 0x09: not documented (9 bytes in the seed), kept raw")
        return Unknown09(t.rest("data", "undocumented tag 0x09 data"))
    elif tag_id == TAG_CAN_METRICS:
        t.explain("can_metrics", "tag 0x0e: CAN bus metrics")
        util = t.f32("utilization")
        # Read as a percentage, as the seed has it; open-ds multiplies it by 100 (a fraction).
        # No capture of a loaded bus settles which: the fake roboRIO writes percent.
        t.explain(None, f"CAN bus utilisation: {util:.1f} % (a percentage as the seed says; open-ds reads a "
                        "fraction and shows x100: unsettled)")
        value = CanMetrics(util, t.u32("bus_off", "bus-off count"), t.u32("tx_full", "transmit-buffer-full count"),
                           t.u8("rx_errors", "receive error count"), t.u8("tx_errors", "transmit error count"))
    else:
        return keep_raw(t, UnknownTag, "tag", tag_id, "undocumented tag data")
    t.expect_end()
    return value


def _walk_cpu(t: Reader) -> CpuInfo:
    # The count's width follows from the tag's size: 1 + 16n bytes left is the real roboRIO's
    # u8 count, 4 + 16n the seed's f32. No size is both.
    left = t.remaining()
    fits = left // 16
    f32_count = left % 16 == 4
    if f32_count:
        count = t.f32("cpu_count")
        # a whole, non-negative number (not -0.0, which would not re-encode identically)
        if not (count.is_integer() and count == fits and math.copysign(1.0, count) > 0):
            t.fail("cpu_count", f"{count!r} is not the {fits} CPU(s) this tag holds", t.pos - 4)
        n = int(count)
        t.explain(n, f"number of CPUs: {n}, as an f32 (the seed's form; a real roboRIO writes a u8)")
    elif left % 16 == 1:
        n = t.u8("cpu_count")
        if n != fits:
            t.fail("cpu_count", f"{n} is not the {fits} CPU(s) this tag holds", t.pos - 1)
        t.explain(n, f"number of CPUs: {n} (u8, as a real roboRIO writes it; 2 on a roboRIO)")
    else:
        t.fail("cpu_count", f"{left} byte(s) is neither a u8 nor an f32 count and 16 bytes per CPU")
    cpus = []
    for k in range(n):
        vals = [t.f32(f"cpus[{k}].{name}", f"CPU {k}: {label} % of time") for name, label in (
            ("time_critical", "time-critical priority"), ("above_normal", "above-normal priority"),
            ("normal", "normal priority"), ("low", "low priority"))]
        cpus.append(CpuLoad(*vals))
    return CpuInfo(tuple(cpus), f32_count)


def _amps(raw: int) -> str:
    return f"{raw * PDP_AMPS_PER_UNIT:.3f} A"


def _walk_pdp(t: Reader) -> PdpLog:
    head = t.u8("unknown_head", "unknown byte (DS log parsers call it the PDP id)")
    g0 = t.uint(8, "channels_0_5")
    c0 = [(g0 >> (54 - 10 * k)) & MAX_PDP_RAW for k in range(6)]
    t.explain(f"0x{g0:016x}", "channels 0-5, 10 bits each from the top bit, then 4 pad bits "
              f"(0x{g0 & 15:x}): " + ", ".join(f"{k}: {_amps(c)}" for k, c in enumerate(c0)))
    g1 = t.uint(8, "channels_6_11")
    c1 = [(g1 >> (54 - 10 * k)) & MAX_PDP_RAW for k in range(6)]
    t.explain(f"0x{g1:016x}", "channels 6-11, 10 bits each from the top bit, then 4 pad bits "
              f"(0x{g1 & 15:x}): " + ", ".join(f"{k + 6}: {_amps(c)}" for k, c in enumerate(c1)))
    g2 = t.uint(5, "channels_12_15")
    c2 = [(g2 >> (30 - 10 * k)) & MAX_PDP_RAW for k in range(4)]
    t.explain(f"0x{g2:010x}", "channels 12-15, 10 bits each from the top bit: "
              + ", ".join(f"{k + 12}: {_amps(c)}" for k, c in enumerate(c2)))
    tail = t.raw(3, "unknown_tail", "3 unknown bytes (dslogparser guesses resistance, voltage, temperature)")
    return PdpLog(tuple(c0 + c1 + c2), head, tail, g0 & 15, g1 & 15)


# -- decoding: the fast path ----------------------------------------------------------
_MODES = tuple(Mode)
_CPU_COUNT_BYTES = tuple(F32.pack(float(n)) for n in range(MAX_CPUS + 1))

_new_status = unchecked_constructor(StatusPacket)
_new_joy_out = unchecked_constructor(JoystickOutput)
_new_disk = unchecked_constructor(DiskInfo)
_new_ram = unchecked_constructor(RamInfo)
_new_can = unchecked_constructor(CanMetrics)
_new_pdp = unchecked_constructor(PdpLog)
_new_cpu = unchecked_constructor(CpuLoad)
_new_cpu_info = unchecked_constructor(CpuInfo)
_new_unknown09 = unchecked_constructor(Unknown09)


def decode_status(data: bytes) -> StatusPacket:
    """Decode a roboRIO -> DS status packet. Raises only :class:`ProtocolError`: at once, for
    a packet over :data:`MAX_STATUS_SIZE`."""
    if len(data) > MAX_STATUS_SIZE:
        raise over_bound(STATUS, len(data), MAX_STATUS_SIZE, _STATUS_WHAT)
    try:
        return _fast_status(data)
    except (Irregular, IndexError, struct.error):
        return walk_status(Reader(data, STATUS))


def _fast_status(data: bytes) -> StatusPacket:
    seq, ver, st, tr, batt, req = _HEADER.unpack_from(data, 0)
    tags: list[StatusTag] = []
    append = tags.append
    pos = 8
    n = len(data)
    while pos < n:
        size = data[pos]
        end = pos + 1 + size
        if size == 0 or end > n or len(tags) == MAX_TAGS:
            raise Irregular
        tag_id = data[pos + 1]
        p = pos + 2
        if tag_id == TAG_JOYSTICK_OUTPUT:
            if size == 9:
                o, right, left = _JOY_OUT.unpack_from(data, p)
                append(_new_joy_out(o, right, left, False))
            elif size == 1:
                append(IDLE_JOYSTICK_OUTPUT)
            else:
                raise Irregular
        elif tag_id == TAG_CAN_METRICS:
            if size != 15:
                raise Irregular
            append(_new_can(*_CAN.unpack_from(data, p)))
        elif tag_id == TAG_PDP_LOG:
            if size != 26:
                raise Irregular
            g0 = _Q.unpack_from(data, p + 1)[0]
            g1 = _Q.unpack_from(data, p + 9)[0]
            g2 = int.from_bytes(data[p + 17:p + 22], "big")
            append(_new_pdp((g0 >> 54, g0 >> 44 & 1023, g0 >> 34 & 1023, g0 >> 24 & 1023, g0 >> 14 & 1023,
                             g0 >> 4 & 1023, g1 >> 54, g1 >> 44 & 1023, g1 >> 34 & 1023, g1 >> 24 & 1023,
                             g1 >> 14 & 1023, g1 >> 4 & 1023, g2 >> 30, g2 >> 20 & 1023, g2 >> 10 & 1023,
                             g2 & 1023),
                            data[p], bytes(data[p + 22:end]), g0 & 15, g1 & 15))
        elif tag_id == TAG_CPU_INFO:
            k, rem = divmod(size - 2, 16)
            if not rem and data[p] == k:  # a real roboRIO's u8 count
                f32_count, first = False, p + 1
            else:
                k, rem = divmod(size - 5, 16)
                if rem or k < 0 or data[p:p + 4] != _CPU_COUNT_BYTES[k]:
                    raise Irregular
                f32_count, first = True, p + 4  # the seed's f32 count
            v = _cpu_struct(k).unpack_from(data, first)
            append(_new_cpu_info(tuple(_new_cpu(*v[j:j + 4]) for j in range(0, 4 * k, 4)), f32_count))
        elif tag_id == TAG_RAM_INFO:
            if size != 9:
                raise Irregular
            append(_new_ram(*_II.unpack_from(data, p)))
        elif tag_id == TAG_DISK_INFO:
            if size == 5:
                append(_new_disk(U32.unpack_from(data, p)[0], None))
            elif size == 9:
                block, free = _II.unpack_from(data, p)
                append(_new_disk(free, block))
            else:
                raise Irregular
        elif tag_id == TAG_UNKNOWN_09:
            append(_new_unknown09(bytes(data[p:end])))
        else:
            append(UnknownTag(tag_id, bytes(data[p:end])))
        pos = end
    return _new_status(seq, ver, st & 0x80 != 0, st & 0x10 != 0, st & 0x08 != 0, st & 0x04 != 0, _MODES[st & 3],
                       tr & 0x20 != 0, tr & 0x10 != 0, tr & 0x08 != 0, tr & 0x04 != 0, tr & 0x02 != 0,
                       tr & 0x01 != 0, batt / 256.0, req & 1 != 0, tuple(tags), st & 0x60, tr & 0xC0, req & 0xFE)


def annotate_status(data: bytes) -> list[Span]:
    return annotate_with(walk_status, STATUS, data)


KINDS = (
    Kind("rio-to-ds", "roboRIO -> DS, UDP 1150", STATUS, walk_status, decode_status),
    Kind("rio-to-ds-tcp", "roboRIO -> DS, TCP 1740", TCP, walk_tcp, decode_tcp, tcp=True),
)

__all__ = [
    "CanMetrics", "CpuInfo", "CpuLoad", "DisableFaults", "DiskInfo", "END_OF_VERSION_LIST", "ErrorMessage",
    "IDLE_JOYSTICK_OUTPUT", "JoystickOutput", "KINDS", "KeepAlive", "MAX_STATUS_SIZE", "MAX_TCP_FRAME", "PdpLog", "RadioEvents", "RailFaults",
    "RamInfo", "StatusPacket", "StdoutMessage", "Unknown09", "Unknown0d", "UnknownFrame", "UnknownTag",
    "UsageReport", "VersionInfo", "annotate_status", "annotate_tcp", "battery_to_raw", "decode_status",
    "decode_tcp", "raw_to_battery", "walk_status", "walk_tcp",
]
