"""A small pcapng reader for the tests that replay real captures (no third-party parser).

Reads the blocks a capture of one Ethernet interface holds (section header, interface
description, enhanced and simple packets; anything else is skipped by its length), then
IPv4 UDP datagrams and TCP segments, and puts each TCP direction back in order by sequence
number (retransmitted and overlapping bytes taken once). Frame numbers count every packet
block from 1, as Wireshark numbers them, so a test can name the frame a vector came from.

Only what the captures in ``../shared/captures/`` need: IPv4 over Ethernet (with or without
one 802.1Q tag), both byte orders of pcapng.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass
from pathlib import Path
from typing import Iterator

_SHB = 0x0A0D0D0A
_IDB = 0x00000001
_SPB = 0x00000003
_EPB = 0x00000006
_MAGIC = 0x1A2B3C4D
_ETHERNET = 1


class PcapngError(ValueError):
    """The file is not a pcapng capture this reader understands."""


@dataclass(frozen=True, slots=True)
class Frame:
    number: int  # 1-based, as Wireshark numbers frames
    time: float  # seconds (the interface's resolution; microseconds unless it says otherwise)
    data: bytes  # the link-layer frame


@dataclass(frozen=True, slots=True)
class Udp:
    number: int
    time: float
    src: tuple[str, int]
    dst: tuple[str, int]
    payload: bytes


@dataclass(frozen=True, slots=True)
class Segment:
    number: int
    time: float
    src: tuple[str, int]
    dst: tuple[str, int]
    seq: int
    flags: int
    payload: bytes


def frames(path: str | Path) -> Iterator[Frame]:
    """Every packet of an Ethernet capture, in file order."""
    data = Path(path).read_bytes()
    pos, number, endian = 0, 0, "<"
    resolution: dict[int, float] = {}
    interfaces = 0
    while pos + 12 <= len(data):
        block_type = struct.unpack_from(endian + "I", data, pos)[0]
        if block_type == _SHB:
            magic = data[pos + 8:pos + 12]
            endian = "<" if magic == struct.pack("<I", _MAGIC) else ">" if magic == struct.pack(">I", _MAGIC) \
                else None
            if endian is None:
                raise PcapngError(f"bad byte-order magic at offset {pos}")
            resolution, interfaces = {}, 0
        length = struct.unpack_from(endian + "I", data, pos + 4)[0]
        if length < 12 or length % 4 or pos + length > len(data):
            raise PcapngError(f"block at offset {pos} has a bad length {length}")
        body = data[pos + 8:pos + length - 4]
        if block_type == _IDB:
            link_type = struct.unpack_from(endian + "H", body, 0)[0]
            if link_type != _ETHERNET:
                raise PcapngError(f"interface {interfaces} has link type {link_type}, not Ethernet")
            resolution[interfaces] = _ts_resolution(body[8:], endian)
            interfaces += 1
        elif block_type == _EPB:
            iface, hi, lo, captured = struct.unpack_from(endian + "IIII", body, 0)
            number += 1
            yield Frame(number, ((hi << 32) | lo) * resolution.get(iface, 1e-6), bytes(body[20:20 + captured]))
        elif block_type == _SPB:
            number += 1
            original = struct.unpack_from(endian + "I", body, 0)[0]
            yield Frame(number, 0.0, bytes(body[4:4 + original]))
        pos += length


def _ts_resolution(options: bytes, endian: str) -> float:
    """The if_tsresol option (code 9) of an interface block; microseconds by default."""
    pos = 0
    while pos + 4 <= len(options):
        code, length = struct.unpack_from(endian + "HH", options, pos)
        if code == 0:
            break
        if code == 9 and length >= 1:
            v = options[pos + 4]
            return 2.0 ** -(v & 0x7F) if v & 0x80 else 10.0 ** -v
        pos += 4 + ((length + 3) & ~3)
    return 1e-6


def _ip(b: bytes) -> str:
    return ".".join(str(x) for x in b)


def _ipv4(frame: Frame) -> tuple[int, str, str, bytes] | None:
    """(protocol, source, destination, payload) of an IPv4 packet, None for anything else."""
    d = frame.data
    if len(d) < 14:
        return None
    ethertype, off = struct.unpack_from(">H", d, 12)[0], 14
    if ethertype == 0x8100 and len(d) >= 18:
        ethertype, off = struct.unpack_from(">H", d, 16)[0], 18
    if ethertype != 0x0800 or len(d) < off + 20 or d[off] >> 4 != 4:
        return None
    ihl = (d[off] & 15) * 4
    total = struct.unpack_from(">H", d, off + 2)[0]
    frag = struct.unpack_from(">H", d, off + 6)[0]
    if frag & 0x3FFF:  # a fragment: none in these captures, and not reassembled here
        return None
    end = min(len(d), off + total)
    return d[off + 9], _ip(d[off + 12:off + 16]), _ip(d[off + 16:off + 20]), d[off + ihl:end]


def udp(path: str | Path) -> Iterator[Udp]:
    """Every IPv4 UDP datagram."""
    for f in frames(path):
        ip = _ipv4(f)
        if ip is None or ip[0] != 17 or len(ip[3]) < 8:
            continue
        proto, src, dst, p = ip
        sport, dport, length = struct.unpack_from(">HHH", p, 0)
        yield Udp(f.number, f.time, (src, sport), (dst, dport), bytes(p[8:max(8, min(length, len(p)))]))


def tcp(path: str | Path) -> Iterator[Segment]:
    """Every IPv4 TCP segment (with or without payload)."""
    for f in frames(path):
        ip = _ipv4(f)
        if ip is None or ip[0] != 6 or len(ip[3]) < 20:
            continue
        _, src, dst, p = ip
        sport, dport, seq, _ack, off_flags = struct.unpack_from(">HHIIH", p, 0)
        yield Segment(f.number, f.time, (src, sport), (dst, dport), seq, off_flags & 0x1FF,
                      bytes(p[(off_flags >> 12) * 4:]))


_SYN = 0x02


@dataclass
class Stream:
    """One direction of one TCP connection, its bytes in order."""

    src: tuple[str, int]
    dst: tuple[str, int]
    data: bytes
    first_frame: int


def streams(path: str | Path, port: int) -> list[Stream]:
    """Both directions of every TCP connection to or from ``port``, reassembled by sequence
    number, in the order they began. A direction whose SYN was not captured starts at its
    first segment; bytes after a hole (never captured) are left out."""
    records: list[dict] = []
    current: dict[tuple, dict] = {}
    for s in tcp(path):
        if port not in (s.src[1], s.dst[1]):
            continue
        key = (s.src, s.dst)
        st = current.get(key)
        if st is None or (s.flags & _SYN and st["chunks"]):  # a new connection on the same ports
            st = current[key] = {"key": key, "isn": None, "chunks": {}, "first": s.number}
            records.append(st)
        if s.flags & _SYN:
            st["isn"] = (s.seq + 1) & 0xFFFFFFFF
            continue
        if st["isn"] is None:
            st["isn"] = s.seq
        if s.payload:
            rel = (s.seq - st["isn"]) & 0xFFFFFFFF
            if rel < 0x80000000:  # bytes from before the stream's start are not ours
                old = st["chunks"].get(rel)
                if old is None or len(s.payload) > len(old):
                    st["chunks"][rel] = s.payload
    out = []
    for st in records:
        buf = bytearray()
        for rel in sorted(st["chunks"]):
            if rel > len(buf):
                break
            buf += st["chunks"][rel][len(buf) - rel:]
        out.append(Stream(st["key"][0], st["key"][1], bytes(buf), st["first"]))
    return out
