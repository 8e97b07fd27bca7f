"""Captured packets as a classic pcap file Wireshark and tshark open.

Magic ``a1b2c3d4``, ``LINKTYPE_RAW``: each packet in a synthetic IPv4 + UDP or TCP header
with the addresses its tap gave (fieldbox/capture.py's :class:`Endpoints`), correct checksums,
and TCP sequence numbers that grow per stream direction. Written incrementally and flushed,
so a recording loses nothing if the app dies.
"""

from __future__ import annotations

import functools
import ipaddress
import struct
import time
import zlib
from dataclasses import dataclass
from pathlib import Path
from typing import Any, BinaryIO, Iterable

from .capture import Address, CapturedPacket, Endpoints, Route, is_tcp_kind

PCAP_MAGIC = 0xA1B2C3D4
LINKTYPE_RAW = 101  # raw IPv4/IPv6, no link-layer header
SNAPLEN = 0xFFFF
IPPROTO_TCP = 6
IPPROTO_UDP = 17
TCP_PSH_ACK = 0x18


def checksum(data: bytes) -> int:
    """The internet checksum (RFC 1071)."""
    if len(data) % 2:
        data += b"\x00"
    total = sum(struct.unpack(f"!{len(data) // 2}H", data))
    while total >> 16:
        total = (total & 0xFFFF) + (total >> 16)
    return ~total & 0xFFFF


def ipv4_header(src: str, dst: str, proto: int, payload_len: int, ident: int) -> bytes:
    total = 20 + payload_len
    header = struct.pack("!BBHHHBBH4s4s", 0x45, 0, total, ident & 0xFFFF, 0x4000, 64, proto, 0,
                         _packed(src), _packed(dst))
    return header[:10] + struct.pack("!H", checksum(header)) + header[12:]


def _pseudo(src: str, dst: str, proto: int, length: int) -> bytes:
    return _packed(src) + _packed(dst) + struct.pack("!BBH", 0, proto, length)


@functools.lru_cache(maxsize=256)
def _packed(address: str) -> bytes:
    return ipaddress.IPv4Address(address).packed


def udp_datagram(src: Address, dst: Address, payload: bytes, ident: int) -> bytes:
    length = 8 + len(payload)
    header = struct.pack("!HHHH", src[1], dst[1], length, 0)
    check = checksum(_pseudo(src[0], dst[0], IPPROTO_UDP, length) + header + payload) or 0xFFFF
    udp = header[:6] + struct.pack("!H", check) + payload
    return ipv4_header(src[0], dst[0], IPPROTO_UDP, length, ident) + udp


def tcp_segment(src: Address, dst: Address, payload: bytes, seq: int, ack: int, ident: int) -> bytes:
    header = struct.pack("!HHIIBBHHH", src[1], dst[1], seq & 0xFFFFFFFF, ack & 0xFFFFFFFF, 5 << 4,
                         TCP_PSH_ACK, 0xFFFF, 0, 0)
    length = len(header) + len(payload)
    check = checksum(_pseudo(src[0], dst[0], IPPROTO_TCP, length) + header + payload)
    tcp = header[:16] + struct.pack("!H", check) + header[18:] + payload
    return ipv4_header(src[0], dst[0], IPPROTO_TCP, length, ident) + tcp


def _isn(src: Address, dst: Address) -> int:
    """A deterministic initial sequence number per stream direction."""
    return zlib.crc32(f"{src[0]}:{src[1]}>{dst[0]}:{dst[1]}".encode()) & 0x7FFFFFFF


class PcapWriter:
    """Classic pcap, raw IPv4, written packet by packet.

    ``clock_offset`` turns the engine's clock into Unix time (``time.time() - engine.now()``
    at the start of a capture). ``keep_duplicates`` writes both taps of a packet that two
    local roles saw.
    """

    path: Path  # the file, when :meth:`open` made it

    def __init__(self, out: BinaryIO, endpoints: Endpoints, clock_offset: float = 0.0, *,
                 keep_duplicates: bool = False) -> None:
        self.out = out
        self.endpoints = endpoints
        self.clock_offset = clock_offset
        self.keep_duplicates = keep_duplicates
        self.written = 0
        self.bytes = 0
        self._ident = 0
        self._next_seq: dict[tuple[Address, Address], int] = {}
        out.write(struct.pack("<IHHiIII", PCAP_MAGIC, 2, 4, 0, 0, SNAPLEN, LINKTYPE_RAW))
        self.bytes += 24

    @classmethod
    def open(cls, path: str | Path, endpoints: Endpoints, clock_offset: float = 0.0, **kw) -> "PcapWriter":
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        writer = cls(open(path, "wb"), endpoints, clock_offset, **kw)
        writer.path = path
        return writer

    def frame(self, p: CapturedPacket, route: Route) -> bytes:
        self._ident += 1
        if is_tcp_kind(p.kind):
            fwd, back = (route.src, route.dst), (route.dst, route.src)
            seq = self._next_seq.get(fwd)
            if seq is None:
                seq = _isn(*fwd)
            ack = self._next_seq.get(back, _isn(*back))
            self._next_seq[fwd] = (seq + len(p.data)) & 0xFFFFFFFF
            return tcp_segment(route.src, route.dst, p.data, seq, ack, self._ident)
        return udp_datagram(route.src, route.dst, p.data, self._ident)

    def write(self, packets: Iterable[CapturedPacket]) -> int:
        """Append packets (duplicates left out); returns how many were written."""
        n = 0
        out = self.out
        for p in packets:
            route = self.endpoints.route(p)
            if route.duplicate and not self.keep_duplicates:
                continue
            frame = self.frame(p, route)
            t = p.time + self.clock_offset
            sec = int(t)
            usec = min(int(round((t - sec) * 1e6)), 999_999)
            record = struct.pack("<IIII", sec & 0xFFFFFFFF, usec, len(frame), len(frame)) + frame
            out.write(record)
            self.bytes += len(record)
            n += 1
        self.written += n
        return n

    def flush(self) -> None:
        self.out.flush()

    def close(self) -> None:
        try:
            self.out.flush()
        finally:
            self.out.close()


def clock_offset_for(engine: Any) -> float:
    """Seconds to add to the engine clock to get Unix time. A replay's clock counts from its
    capture's first packet (fieldbox/replay.py): what it records keeps the capture's times."""
    offset = getattr(engine, "capture_start", None)
    if isinstance(offset, float):
        return offset
    try:
        return time.time() - float(engine.now())
    except Exception:  # noqa: BLE001 - an engine without a clock yet
        return 0.0


def write_pcap(path: str | Path, packets: Iterable[CapturedPacket], endpoints: Endpoints,
               clock_offset: float = 0.0, **kw) -> int:
    """Write packets to a new pcap file; returns how many were written."""
    writer = PcapWriter.open(path, endpoints, clock_offset, **kw)
    try:
        return writer.write(packets)
    finally:
        writer.close()


def default_capture_dir() -> Path:
    import platformdirs

    return Path(platformdirs.user_data_dir("fieldbox")) / "captures"


def default_capture_path(prefix: str = "fieldbox", when: float | None = None) -> Path:
    stamp = time.strftime("%Y%m%d-%H%M%S", time.localtime(when if when is not None else time.time()))
    return default_capture_dir() / f"{prefix}-{stamp}.pcap"


@dataclass
class Recorder:
    """Recording to a pcap file as packets arrive: each batch is written and flushed."""

    writer: PcapWriter
    path: Path
    errors: int = 0

    @classmethod
    def start(cls, path: str | Path, endpoints: Endpoints, clock_offset: float) -> "Recorder":
        writer = PcapWriter.open(path, endpoints, clock_offset)
        writer.flush()
        return cls(writer, Path(path))

    def feed(self, packets: list[CapturedPacket]) -> None:
        if packets:
            self.writer.write(packets)
            self.writer.flush()

    def stop(self) -> int:
        self.writer.close()
        return self.writer.written
