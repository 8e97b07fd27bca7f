"""The 2010 legacy protocol, DS -> robot: the 1024-byte control packet (UDP 1110) with its four
joysticks, analog inputs, checksums and the dynamic blocks after 0x73.

See :mod:`protocol.legacy` for the sources and the decisions; it re-exports everything here.
The control packet goes out every 20 ms, so it has a fast path beside the reference walk.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass
from typing import Union

from .ds_to_rio import int8_to_axis
from .enums import AllianceStation
from .errors import ProtocolError
from .frames import MALFORMED
from .legacy_common import (CONTROL_AUTONOMOUS, CONTROL_CRIO_CHECKSUM, CONTROL_ENABLED, CONTROL_FMS_ATTACHED,
                            CONTROL_FPGA_CHECKSUM, CONTROL_NOT_ESTOP, CONTROL_RESET, CONTROL_RESYNC,
                            DEFAULT_DS_VERSION, ZERO4, bits_text, check_raw, check_size, control_byte_text,
                            crc_span, fixed_text, reserved_span, verify_crc, with_crc, zero_run)
from .wire import (TEXT_ENCODING, TEXT_ERRORS, Irregular, Reader, Span, annotate_with, check_int,
                   unchecked_constructor)

CONTROL = "LegacyControlPacket"
CONTROL_SIZE = 1024

# Control packet layout.
_DYNAMIC_START = 0x73
_DYNAMIC_END = 0x3F8
_CONTROL_RESERVED = 0x3F8
_CONTROL_CRC = 0x3FC
_UNKNOWN_0X50_LEN = _DYNAMIC_START - 0x50  # 35
MAX_BLOCK_DATA = 0xFE  # the size byte counts the id byte too

# Dynamic block ids named in NI's FRCComm.h (kFRC_NetworkCommunication_DynamicType_*).
DYNAMIC_BLOCK_NAMES = {
    17: "DS Enhanced I/O input", 18: "DS Enhanced I/O output", 19: "Kinect header",
    20: "Kinect extra 1", 21: "Kinect vertices 1", 22: "Kinect extra 2",
    23: "Kinect vertices 2", 24: "Kinect joystick", 25: "Kinect custom",
}


@dataclass(frozen=True, slots=True)
class LegacyJoystick:
    """One of four joysticks: six int8 axes, a u16 button word (12 used, bit 0 = button 1)."""

    axes: tuple[int, ...] = (0, 0, 0, 0, 0, 0)
    buttons: int = 0

    def pressed(self, button: int) -> bool:
        """Whether button ``button`` (1-based) is down."""
        return 1 <= button <= 16 and bool(self.buttons >> (button - 1) & 1)

    def axis(self, k: int) -> float:
        """Axis ``k`` (0-based) as -1.0..1.0 (negative /128, positive /127)."""
        return int8_to_axis(self.axes[k])


EMPTY_LEGACY_JOYSTICK = LegacyJoystick()


@dataclass(frozen=True, slots=True)
class DynamicBlock:
    """A dynamic block after 0x73: ``[u8 size of what follows][u8 id][data]``, kept raw."""

    block_id: int
    data: bytes = b""

    @property
    def name(self) -> str:
        return DYNAMIC_BLOCK_NAMES.get(self.block_id, f"block 0x{self.block_id:02x}")


_STATION_BYTES = {s: (b"R" if s.value < 3 else b"B") + str(s.position).encode() for s in AllianceStation}
_STATION_FROM_BYTES = {v: k for k, v in _STATION_BYTES.items()}


@dataclass(frozen=True, slots=True)
class LegacyControlPacket:
    """DS -> robot, UDP 1110, 1024 bytes every 20 ms."""

    packet_index: int = 0
    reset: bool = False
    estop: bool = False  # the wire has the inverse: bit 0x40 "not e-stop", set normally
    enabled: bool = False
    autonomous: bool = False
    fms_attached: bool = False
    resync: bool = False
    crio_checksum_bit: bool = False
    fpga_checksum_bit: bool = False
    ds_digital_in: int = 0  # bit 0 = input 1
    team: int = 0
    # AllianceStation when the two ASCII bytes name one ('R'/'B', '1'-'3'), else the raw pair.
    station: Union[AllianceStation, bytes] = AllianceStation.RED1
    joysticks: tuple[LegacyJoystick, ...] = (EMPTY_LEGACY_JOYSTICK,) * 4
    analog: tuple[int, ...] = (0, 0, 0, 0)  # 10-bit, right-justified
    crio_checksum: bytes = bytes(8)
    fpga_checksums: tuple[bytes, ...] = (ZERO4,) * 4
    ds_version: str = DEFAULT_DS_VERSION
    unknown_0x50: bytes = bytes(_UNKNOWN_0X50_LEN)
    dynamic_blocks: tuple[DynamicBlock, ...] = ()
    # What follows the blocks up to 0x3f7, trailing zeros stripped (b"" = all zero). When not
    # empty it starts with the 0 size byte that ends the blocks, or it is a malformed block
    # (its size runs past 0x3f7) and everything after it, kept as it came.
    dynamic_padding: bytes = b""
    reserved: bytes = ZERO4  # 0x3f8-0x3fb, zero per the seed

    @property
    def blocks_malformed(self) -> bool:
        """Whether a dynamic block's size runs past 0x3f7. The control data before it still
        holds (the CRC covers the whole packet); only the blocks from there on are lost."""
        return bool(self.dynamic_padding) and self.dynamic_padding[0] != 0

    @property
    def control_byte(self) -> int:
        return ((CONTROL_RESET if self.reset else 0) | (0 if self.estop else CONTROL_NOT_ESTOP)
                | (CONTROL_ENABLED if self.enabled else 0)
                | (CONTROL_AUTONOMOUS if self.autonomous else 0)
                | (CONTROL_FMS_ATTACHED if self.fms_attached else 0)
                | (CONTROL_RESYNC if self.resync else 0)
                | (CONTROL_CRIO_CHECKSUM if self.crio_checksum_bit else 0)
                | (CONTROL_FPGA_CHECKSUM if self.fpga_checksum_bit else 0))

    def encode(self) -> bytes:
        """The 1024 bytes, CRC included. Raises ProtocolError naming the bad field."""
        try:
            return self._encode_fast()
        except (Irregular, struct.error, TypeError, ValueError, OverflowError, AttributeError):
            self._validate()
            raise ProtocolError(CONTROL, "?", None, "cannot encode this packet") from None

    def _encode_fast(self) -> bytes:
        st = self.station
        st_bytes = _STATION_BYTES.get(st) if type(st) is AllianceStation else st
        if not isinstance(st_bytes, (bytes, bytearray)) or len(st_bytes) != 2:
            raise Irregular
        sticks = self.joysticks
        if len(sticks) != 4:
            raise Irregular
        args = [self.packet_index, self.control_byte, self.ds_digital_in, self.team, st_bytes]
        for stick in sticks:
            axes = stick.axes
            if type(stick) is not LegacyJoystick or len(axes) != 6:
                raise Irregular
            args.extend(axes)
            args.append(stick.buttons)
        analog = self.analog
        if len(analog) != 4:
            raise Irregular
        for a in analog:
            if not 0 <= a <= 1023:
                raise Irregular
        args.extend(analog)
        fpga = self.fpga_checksums
        if len(self.crio_checksum) != 8 or len(fpga) != 4 or any(len(f) != 4 for f in fpga):
            raise Irregular
        version = self.ds_version.encode(TEXT_ENCODING, TEXT_ERRORS)
        if len(version) != 8:
            raise Irregular
        args.append(self.crio_checksum)
        args.append(b"".join(fpga))
        args.append(version)
        if len(self.unknown_0x50) != _UNKNOWN_0X50_LEN or len(self.reserved) != 4:
            raise Irregular
        parts = [_CONTROL_HEAD.pack(*args), self.unknown_0x50]
        for block in self.dynamic_blocks:
            data = block.data
            if type(block) is not DynamicBlock or len(data) > MAX_BLOCK_DATA:
                raise Irregular
            parts.append(bytes((len(data) + 1, block.block_id)))
            parts.append(data)
        padding = self.dynamic_padding
        body = b"".join(parts)
        if padding and padding[0] and len(body) + 1 + padding[0] <= _DYNAMIC_END:
            raise Irregular  # a size byte that fits would be a block, not padding
        body += padding
        fill = _DYNAMIC_END - len(body)
        if fill < 0:
            raise Irregular
        body = b"".join((body, bytes(fill), self.reserved))
        return with_crc(body)

    def _validate(self) -> None:
        check_int(CONTROL, "packet_index", self.packet_index, 0, 0xFFFF)
        check_int(CONTROL, "ds_digital_in", self.ds_digital_in, 0, 0xFF)
        check_int(CONTROL, "team", self.team, 0, 0xFFFF)
        if not isinstance(self.station, AllianceStation):
            check_raw(CONTROL, "station", self.station, 2)
        if not isinstance(self.joysticks, tuple) or len(self.joysticks) != 4:
            raise ProtocolError(CONTROL, "joysticks", None, "must be a tuple of exactly 4 LegacyJoystick")
        for i, stick in enumerate(self.joysticks):
            if not isinstance(stick, LegacyJoystick):
                raise ProtocolError(CONTROL, f"joysticks[{i}]", None,
                                    f"{type(stick).__name__} is not a LegacyJoystick")
            if not isinstance(stick.axes, tuple) or len(stick.axes) != 6:
                raise ProtocolError(CONTROL, f"joysticks[{i}].axes", None, "must be a tuple of exactly 6 axes")
            for k, a in enumerate(stick.axes):
                check_int(CONTROL, f"joysticks[{i}].axes[{k}]", a, -128, 127)
            check_int(CONTROL, f"joysticks[{i}].buttons", stick.buttons, 0, 0xFFFF)
        if not isinstance(self.analog, tuple) or len(self.analog) != 4:
            raise ProtocolError(CONTROL, "analog", None, "must be a tuple of exactly 4 inputs")
        for i, a in enumerate(self.analog):
            check_int(CONTROL, f"analog[{i}]", a, 0, 1023)
        check_raw(CONTROL, "crio_checksum", self.crio_checksum, 8)
        if not isinstance(self.fpga_checksums, tuple) or len(self.fpga_checksums) != 4:
            raise ProtocolError(CONTROL, "fpga_checksums", None, "must be a tuple of exactly 4 x 4 bytes")
        for i, f in enumerate(self.fpga_checksums):
            check_raw(CONTROL, f"fpga_checksums[{i}]", f, 4)
        fixed_text(CONTROL, "ds_version", self.ds_version, 8)
        check_raw(CONTROL, "unknown_0x50", self.unknown_0x50, _UNKNOWN_0X50_LEN)
        if not isinstance(self.dynamic_blocks, (tuple, list)):
            raise ProtocolError(CONTROL, "dynamic_blocks", None, "must be a tuple of DynamicBlock")
        pos = _DYNAMIC_START
        for i, block in enumerate(self.dynamic_blocks):
            if not isinstance(block, DynamicBlock):
                raise ProtocolError(CONTROL, f"dynamic_blocks[{i}]", None,
                                    f"{type(block).__name__} is not a DynamicBlock")
            check_int(CONTROL, f"dynamic_blocks[{i}].block_id", block.block_id, 0, 0xFF)
            data = check_raw(CONTROL, f"dynamic_blocks[{i}].data", block.data, None)
            if len(data) > MAX_BLOCK_DATA:
                raise ProtocolError(CONTROL, f"dynamic_blocks[{i}].data", None,
                                    f"{len(data)} bytes, at most {MAX_BLOCK_DATA} (u8 size counts the id)")
            pos += 2 + len(data)
            if pos > _DYNAMIC_END:
                raise ProtocolError(CONTROL, f"dynamic_blocks[{i}]", None,
                                    f"ends at 0x{pos:03x}, past the dynamic area (0x073-0x3f7)")
        padding = check_raw(CONTROL, "dynamic_padding", self.dynamic_padding, None)
        if len(padding) > _DYNAMIC_END - pos:
            raise ProtocolError(CONTROL, "dynamic_padding", None,
                                f"{len(padding)} bytes, only {_DYNAMIC_END - pos} left before 0x3f8")
        if padding and padding[0] and pos + 1 + padding[0] <= _DYNAMIC_END:
            raise ProtocolError(CONTROL, "dynamic_padding", None,
                                "must start with the 0 size byte that ends the blocks, or with a "
                                "block size that runs past 0x3f7")
        check_raw(CONTROL, "reserved", self.reserved, 4)


# 0x00 index, control, digital in, team, alliance+position; 4 x (6 axes, buttons) from 0x08;
# 4 analog from 0x28; cRIO checksum 0x30; FPGA checksums 0x38; DS version 0x48-0x4f.
_CONTROL_HEAD = struct.Struct(">HBBH2s" + "6bH" * 4 + "4H8s16s8s")
assert _CONTROL_HEAD.size == 0x50


def _ascii_value(b: int) -> str:
    return repr(chr(b)) if 0x20 <= b < 0x7F else f"0x{b:02x}"


def walk_legacy_control(r: Reader) -> LegacyControlPacket:
    """The reference walk. Does not refuse a bad CRC: the ``crc`` span says expected/found."""
    index = r.u16("packet_index", "packet index, counts up every packet; the robot echoes it at 0x1e")
    ctl = r.u8("control")
    r.explain(f"0x{ctl:02x}", f"control: {control_byte_text(ctl)}")
    r.refuse_over(CONTROL_SIZE, f"a 2010 control packet (exactly {CONTROL_SIZE} bytes)")
    din = r.u8("ds_digital_in")
    r.explain(f"0x{din:02x}", bits_text(din, "DS digital inputs"))
    team = r.u16("team", "team number")
    a = r.u8("alliance")
    r.explain(_ascii_value(a), {0x52: "alliance 'R': red", 0x42: "alliance 'B': blue"}.get(
        a, "alliance: not 'R' or 'B', kept raw"))
    p = r.u8("position")
    r.explain(_ascii_value(p), f"position {chr(p)} (ASCII '1'-'3')" if 0x31 <= p <= 0x33
              else "position: not ASCII '1'-'3', kept raw")
    pair = bytes((a, p))
    station = _STATION_FROM_BYTES.get(pair, pair)
    sticks = []
    for i in range(4):
        axes = []
        for k in range(6):
            v = r.i8(f"joysticks[{i}].axes[{k}]")
            r.explain(None, f"joystick {i + 1} axis {k + 1}: {int8_to_axis(v):+.3f} "
                            "(int8; negative /128, positive /127)")
            axes.append(v)
        buttons = r.u16(f"joysticks[{i}].buttons")
        down = [str(b + 1) for b in range(16) if buttons >> b & 1]
        extra = " (bits 12-15 are unused)" if buttons >> 12 else ""
        r.explain(f"0x{buttons:04x}", f"joystick {i + 1} buttons, bit 0 = button 1: down "
                                      f"{', '.join(down) or 'none'}{extra}")
        sticks.append(LegacyJoystick(tuple(axes), buttons))
    analog = []
    for i in range(4):
        v = r.u16(f"analog[{i}]")
        if v > 1023:
            r.fail(f"analog[{i}]", f"{v} is not a 10-bit value (0..1023)", r.pos - 2)
        r.explain(None, f"DS analog input {i + 1}: {v}/1023 (10-bit, right-justified)")
        analog.append(v)
    crio = r.raw(8, "crio_checksum", "cRIO checksum (kept raw)")
    fpga = tuple(r.raw(4, f"fpga_checksums[{i}]", f"FPGA checksum {i} (kept raw)") for i in range(4))
    version = r.text(8, "ds_version")
    r.explain(None, f"DS version {'.'.join(version[k:k + 2] for k in range(0, 8, 2))} "
                    "(ASCII; 10020800 is the 2010 DS 1.1)")
    unknown = r.raw(_UNKNOWN_0X50_LEN, "unknown_0x50")
    zero_run(r, unknown, "bytes 0x050-0x072, not documented")
    r.need(_DYNAMIC_END - r.pos, "dynamic_blocks")
    blocks, padding = _walk_dynamic(r)
    reserved = reserved_span(r, _CONTROL_RESERVED)
    crc_span(r, _CONTROL_CRC)
    r.expect_end()
    return LegacyControlPacket(
        index, bool(ctl & CONTROL_RESET), not ctl & CONTROL_NOT_ESTOP, bool(ctl & CONTROL_ENABLED),
        bool(ctl & CONTROL_AUTONOMOUS), bool(ctl & CONTROL_FMS_ATTACHED), bool(ctl & CONTROL_RESYNC),
        bool(ctl & CONTROL_CRIO_CHECKSUM), bool(ctl & CONTROL_FPGA_CHECKSUM), din, team, station,
        tuple(sticks), tuple(analog), crio, fpga, version, unknown, blocks, padding, reserved)


def _walk_dynamic(r: Reader) -> tuple[tuple[DynamicBlock, ...], bytes]:
    blocks: list[DynamicBlock] = []
    while r.pos < _DYNAMIC_END:
        where = f"dynamic_blocks[{len(blocks)}]"
        size = r.data[r.pos]
        if size == 0:
            break
        if r.pos + 1 + size > _DYNAMIC_END:
            # The CRC held, so the control data above is what the DS sent: keep it, and keep
            # this block and the rest of the area raw (the robot drops them).
            rest = r.raw(_DYNAMIC_END - r.pos, f"{where}.{MALFORMED}")
            r.explain(None, f"MALFORMED: block size {size} runs past 0x3f7 ({len(rest) - 1} byte(s) left); "
                            "the control data still applies, this block and the rest of the area are dropped")
            return tuple(blocks), rest.rstrip(b"\0")
        r.u8(f"{where}.size", f"block size: {size} byte(s) follow (id + {size - 1} data)")
        block_id = r.u8(f"{where}.id")
        name = DYNAMIC_BLOCK_NAMES.get(block_id)
        r.explain(None, f"block id {block_id}: {name}" if name else f"block id {block_id}: not documented")
        blocks.append(DynamicBlock(block_id, r.raw(size - 1, f"{where}.data", "block data, kept raw")))
    padding = r.raw(_DYNAMIC_END - r.pos, "dynamic_padding")
    if padding:
        if not padding.strip(b"\0"):
            r.explain(f"00 x {len(padding)}", "size byte 0: no more blocks; zeros up to 0x3f7")
        else:
            r.explain(None, "size byte 0: no more blocks; then bytes up to 0x3f7, NOT all zero, kept raw")
    return tuple(blocks), padding.rstrip(b"\0")


_new_joystick = unchecked_constructor(LegacyJoystick)
_new_control = unchecked_constructor(LegacyControlPacket)
_new_block = unchecked_constructor(DynamicBlock)


def decode_legacy_control(data: bytes, *, check_crc: bool = True) -> LegacyControlPacket:
    """Decode a 2010 DS -> robot packet. Raises only ProtocolError (size, crc, a field).

    ``check_crc=False`` is for the inspector: decode what is there even if the CRC is bad.
    """
    if type(data) is not bytes:
        data = bytes(data)
    check_size(CONTROL, data, (CONTROL_SIZE,))
    if check_crc:
        verify_crc(CONTROL, data, _CONTROL_CRC)
    try:
        return _fast_control(data)
    except Irregular:
        return walk_legacy_control(Reader(data, CONTROL))


def _fast_control(data: bytes) -> LegacyControlPacket:
    v = _CONTROL_HEAD.unpack_from(data, 0)
    ctl = v[1]
    pair = v[4]
    analog = v[33:37]
    if max(analog) > 1023:
        raise Irregular
    f = v[38]
    blocks = []
    pos = _DYNAMIC_START
    while pos < _DYNAMIC_END:
        size = data[pos]
        if size == 0:
            break
        end = pos + 1 + size
        if end > _DYNAMIC_END:
            raise Irregular
        blocks.append(_new_block(data[pos + 1], data[pos + 2:end]))
        pos = end
    return _new_control(
        v[0], ctl & 0x80 != 0, ctl & 0x40 == 0, ctl & 0x20 != 0, ctl & 0x10 != 0, ctl & 0x08 != 0,
        ctl & 0x04 != 0, ctl & 0x02 != 0, ctl & 0x01 != 0, v[2], v[3], _STATION_FROM_BYTES.get(pair, pair),
        (_new_joystick(v[5:11], v[11]), _new_joystick(v[12:18], v[18]),
         _new_joystick(v[19:25], v[25]), _new_joystick(v[26:32], v[32])),
        analog, v[37], (f[0:4], f[4:8], f[8:12], f[12:16]), v[39].decode(TEXT_ENCODING, TEXT_ERRORS),
        data[0x50:_DYNAMIC_START], tuple(blocks), data[pos:_DYNAMIC_END].rstrip(b"\0"),
        data[_CONTROL_RESERVED:_CONTROL_CRC])


def annotate_legacy_control(data: bytes) -> list[Span]:
    return annotate_with(walk_legacy_control, CONTROL, bytes(data))

