"""Reading FRC packets out of a capture file: pcap or pcapng, as Wireshark, tcpdump and
fieldbox's own recordings write them (``fieldbox decode --pcap``).

The file is read record by record (never whole): a record over :data:`MAX_RECORD` bytes, or
one whose length runs past the end of the file, is a :class:`CaptureError` naming its offset.
Link types: Ethernet (with 802.1Q tags), raw IP (fieldbox's recordings), Linux cooked SLL and
SLL2 (``tcpdump -i any``), BSD loopback (null and loop). Network: IPv4 (fragments are not
reassembled: they count as other packets) and IPv6 (no extension headers).

A packet is FRC by its ports, as fieldbox's roles use them (UDP by destination port; TCP by
which side is the server port), and its kind is one of :mod:`protocol.kinds`. TCP is put back
in order per direction by sequence number (out-of-order segments wait, bounded) and split
into frames by :class:`protocol.framing.FrameDecoder`; a frame's time is that of the segment
that completed it.
"""

from __future__ import annotations

import ipaddress
import struct
from dataclasses import dataclass, field
from typing import BinaryIO, Iterator

from protocol.framing import FrameDecoder

#: The largest record (pcap packet record or pcapng block) read: no FRC packet is near it, and
#: a corrupt length must not make the reader allocate gigabytes.
MAX_RECORD = 256 * 1024
#: Out-of-order TCP segments held per direction, and their bytes, before a hole is given up
#: on (a segment the capture never got): the rest of that direction is then not framed.
MAX_PENDING_SEGMENTS = 64
MAX_PENDING_BYTES = 256 * 1024
#: TCP directions followed at once; past it the one opened longest ago is forgotten (a scan
#: of many connections must not grow memory without end).
MAX_STREAMS = 1024

_PCAP_MICRO, _PCAP_NANO = 0xA1B2C3D4, 0xA1B23C4D
_SHB, _IDB, _OPB, _SPB, _EPB = 0x0A0D0D0A, 0x00000001, 0x00000002, 0x00000003, 0x00000006
_BYTE_ORDER_MAGIC = 0x1A2B3C4D

LINKTYPE_NULL, LINKTYPE_ETHERNET, LINKTYPE_RAW, LINKTYPE_LOOP = 0, 1, 101, 108
LINKTYPE_LINUX_SLL, LINKTYPE_IPV4, LINKTYPE_IPV6, LINKTYPE_LINUX_SLL2 = 113, 228, 229, 276

_TCP, _UDP = 6, 17
_FIN, _SYN, _RST = 0x01, 0x02, 0x04

#: UDP destination port -> kind (today's protocol; see :func:`udp_kind` for the 2010 one).
UDP_PORTS = {1110: "ds-to-rio", 1115: "ds-to-rio", 1150: "rio-to-ds", 1160: "ds-to-fms",
             1120: "fms-to-ds", 1121: "fms-to-ds", 1165: "legacy-dashboard", 6666: "legacy-netconsole"}
#: TCP server port -> (kind of what the client sends, kind of what the server sends).
TCP_PORTS = {1740: ("ds-to-rio-tcp", "rio-to-ds-tcp"), 1750: ("ds-to-fms-tcp", "fms-to-ds-tcp")}
#: Kind -> (sender's role, receiver's role).
ROLES = {"ds-to-rio": ("ds", "robot"), "ds-to-rio-tcp": ("ds", "robot"), "legacy-ds-to-robot": ("ds", "robot"),
         "rio-to-ds": ("robot", "ds"), "rio-to-ds-tcp": ("robot", "ds"), "legacy-robot-to-ds": ("robot", "ds"),
         "ds-to-fms": ("ds", "fms"), "ds-to-fms-tcp": ("ds", "fms"),
         "fms-to-ds": ("fms", "ds"), "fms-to-ds-tcp": ("fms", "ds"),
         "legacy-dashboard": ("ds", "dashboard"), "legacy-netconsole": ("robot", "console")}

#: The 2010 protocol's packets are fixed sizes (protocol/legacy_control.py, protocol/legacy.py).
_LEGACY_CONTROL_SIZES = (1024,)
_LEGACY_STATUS_SIZES = (1024, 1152)

Address = tuple[str, int]


class CaptureError(ValueError):
    """The file is not a capture this reader can read, or it is cut short or corrupt."""


@dataclass(frozen=True, slots=True)
class Record:
    """One captured packet as the file holds it."""

    offset: int  # in the file, of its record / block
    time: float  # Unix seconds
    linktype: int
    data: bytes


@dataclass(frozen=True, slots=True)
class FrcPacket:
    """One FRC datagram or TCP frame."""

    time: float
    kind: str
    src: Address
    dst: Address
    data: bytes
    offset: int  # of the record that carried it (the last segment, for a TCP frame)


@dataclass
class Counts:
    records: int = 0
    first_time: float | None = None  # of the first record: what relative times count from
    frc: int = 0  # datagrams and TCP frames yielded
    other: int = 0  # records that carried no FRC datagram or TCP byte
    tcp_lost: int = 0  # TCP directions given up on (a hole never filled, or a bad frame size)
    tcp_lost_bytes: int = 0  # bytes of those directions not framed
    notes: list[str] = field(default_factory=list)  # why, one line each (the first few)


# -- the file formats ---------------------------------------------------------------------------
def _read(f: BinaryIO, n: int, offset: int, what: str) -> bytes:
    data = f.read(n)
    if len(data) < n:
        raise CaptureError(f"cut short at offset {offset}: {what} needs {n} bytes, {len(data)} remain")
    return data


def records(f: BinaryIO) -> Iterator[Record]:
    """Every packet of a pcap or pcapng file, in file order, read as it goes."""
    head = f.read(4)
    if len(head) < 4:
        raise CaptureError(f"not a capture: {len(head)} bytes, a pcap or pcapng file begins with 4 magic bytes")
    if head == struct.pack("<I", _SHB):
        yield from _pcapng(f, head)
        return
    for endian in "<>":
        (magic,) = struct.unpack(endian + "I", head)
        if magic in (_PCAP_MICRO, _PCAP_NANO):
            yield from _pcap(f, endian, 1e-9 if magic == _PCAP_NANO else 1e-6)
            return
    raise CaptureError(f"not a pcap or pcapng file: magic {head.hex()} at offset 0")


def _pcap(f: BinaryIO, endian: str, resolution: float) -> Iterator[Record]:
    header = _read(f, 20, 4, "the pcap file header")
    linktype = struct.unpack(endian + "I", header[16:20])[0] & 0x0FFFFFFF  # upper bits: FCS length
    offset = 24
    while True:
        raw = f.read(16)
        if not raw:
            return
        if len(raw) < 16:
            raise CaptureError(f"cut short at offset {offset}: a packet record header needs 16 bytes, "
                               f"{len(raw)} remain")
        sec, frac, incl, _orig = struct.unpack(endian + "IIII", raw)
        if incl > MAX_RECORD:
            raise CaptureError(f"packet record at offset {offset} says {incl:,} bytes: over the "
                               f"{MAX_RECORD:,}-byte bound (a corrupt file?)")
        data = _read(f, incl, offset, f"the packet record ({incl} bytes)")
        yield Record(offset, sec + frac * resolution, linktype, data)
        offset += 16 + incl


@dataclass
class _Interface:
    linktype: int
    snaplen: int
    resolution: float = 1e-6
    ts_offset: int = 0  # seconds added to every timestamp (if_tsoffset)


def _pcapng(f: BinaryIO, first: bytes) -> Iterator[Record]:
    offset = 0
    endian = "<"
    interfaces: list[_Interface] = []
    last_time = 0.0
    raw_type: bytes | None = first
    while True:
        if raw_type is None:
            raw_type = f.read(4)
            if not raw_type:
                return
            if len(raw_type) < 4:
                raise CaptureError(f"cut short at offset {offset}: a block header needs 8 bytes, "
                                   f"{len(raw_type)} remain")
        raw_len = _read(f, 4, offset, "a block header")
        if raw_type == struct.pack("<I", _SHB):  # the section header says the byte order
            bom = _read(f, 4, offset, "a section header")
            if bom == struct.pack("<I", _BYTE_ORDER_MAGIC):
                endian = "<"
            elif bom == struct.pack(">I", _BYTE_ORDER_MAGIC):
                endian = ">"
            else:
                raise CaptureError(f"section header at offset {offset} has a bad byte-order magic {bom.hex()}")
            pre = bom
            interfaces = []
        else:
            pre = b""
        (block_type,) = struct.unpack(endian + "I", raw_type)
        (length,) = struct.unpack(endian + "I", raw_len)
        if length < 12 or length % 4:
            raise CaptureError(f"block at offset {offset} has a bad length {length} (a corrupt file?)")
        if length > MAX_RECORD:
            raise CaptureError(f"block at offset {offset} says {length:,} bytes: over the {MAX_RECORD:,}-byte "
                               "bound (a corrupt file?)")
        rest = pre + _read(f, length - 8 - len(pre), offset, f"the block ({length} bytes)")
        body = rest[:-4]
        if struct.unpack(endian + "I", rest[-4:])[0] != length:
            raise CaptureError(f"block at offset {offset}: its trailing length does not match {length}")
        raw_type = None
        if block_type == _IDB:
            if len(body) < 8:
                raise CaptureError(f"interface block at offset {offset} is too short")
            linktype, _, snaplen = struct.unpack_from(endian + "HHI", body, 0)
            iface = _Interface(linktype, snaplen)
            _interface_options(iface, body[8:], endian)
            interfaces.append(iface)
        elif block_type in (_EPB, _OPB):
            if block_type == _EPB:
                if len(body) < 20:
                    raise CaptureError(f"packet block at offset {offset} is too short")
                index, hi, lo, captured, _orig = struct.unpack_from(endian + "IIIII", body, 0)
            else:
                if len(body) < 20:
                    raise CaptureError(f"packet block at offset {offset} is too short")
                index, _drops, hi, lo, captured, _orig = struct.unpack_from(endian + "HHIIII", body, 0)
            if index >= len(interfaces):
                raise CaptureError(f"packet block at offset {offset} names interface {index}, "
                                   f"{len(interfaces)} described")
            if 20 + captured > len(body):
                raise CaptureError(f"packet block at offset {offset}: {captured} captured bytes do not fit "
                                   f"its {length}-byte block")
            iface = interfaces[index]
            last_time = ((hi << 32) | lo) * iface.resolution + iface.ts_offset
            yield Record(offset, last_time, iface.linktype, bytes(body[20:20 + captured]))
        elif block_type == _SPB:  # no timestamp: it is given the time of the packet before
            if not interfaces or len(body) < 4:
                raise CaptureError(f"simple packet block at offset {offset} without an interface")
            (orig,) = struct.unpack_from(endian + "I", body, 0)
            captured = min(orig, len(body) - 4, interfaces[0].snaplen or orig)
            yield Record(offset, last_time, interfaces[0].linktype, bytes(body[4:4 + captured]))
        offset += length


def _interface_options(iface: _Interface, options: bytes, endian: str) -> None:
    pos = 0
    while pos + 4 <= len(options):
        code, length = struct.unpack_from(endian + "HH", options, pos)
        if code == 0:
            break
        value = options[pos + 4:pos + 4 + length]
        if code == 9 and length >= 1:  # if_tsresol: a power of ten, or of two with the top bit
            v = value[0]
            iface.resolution = 2.0 ** -(v & 0x7F) if v & 0x80 else 10.0 ** -v
        elif code == 14 and length == 8:  # if_tsoffset
            iface.ts_offset = struct.unpack(endian + "q", value)[0]
        pos += 4 + ((length + 3) & ~3)


# -- link and network layers ----------------------------------------------------------------------
def ip_payload(linktype: int, data: bytes) -> tuple[int, str, str, bytes] | None:
    """(IP protocol, source, destination, transport bytes), or None for anything else."""
    if linktype == LINKTYPE_ETHERNET:
        if len(data) < 14:
            return None
        ethertype, off = struct.unpack_from(">H", data, 12)[0], 14
        while ethertype in (0x8100, 0x88A8) and len(data) >= off + 4:  # VLAN tags
            ethertype, off = struct.unpack_from(">H", data, off + 2)[0], off + 4
        return _ip(ethertype, data[off:])
    if linktype in (LINKTYPE_RAW, LINKTYPE_IPV4, LINKTYPE_IPV6):
        if not data:
            return None
        return _ip(0x0800 if data[0] >> 4 == 4 else 0x86DD if data[0] >> 4 == 6 else 0, data)
    if linktype == LINKTYPE_LINUX_SLL:
        return _ip(struct.unpack_from(">H", data, 14)[0], data[16:]) if len(data) >= 16 else None
    if linktype == LINKTYPE_LINUX_SLL2:
        return _ip(struct.unpack_from(">H", data, 0)[0], data[20:]) if len(data) >= 20 else None
    if linktype in (LINKTYPE_NULL, LINKTYPE_LOOP):
        if len(data) < 4:
            return None
        # The address family, in the capturing host's byte order (null) or big-endian (loop).
        family = struct.unpack_from(">I" if linktype == LINKTYPE_LOOP else "<I", data, 0)[0]
        if family > 0xFFFF:
            family = struct.unpack_from(">I", data, 0)[0]
        return _ip(0x0800 if family == 2 else 0x86DD if family in (10, 23, 24, 28, 30) else 0, data[4:])
    return None


def _ip(ethertype: int, d: bytes) -> tuple[int, str, str, bytes] | None:
    if ethertype == 0x0800:
        if len(d) < 20 or d[0] >> 4 != 4:
            return None
        ihl = (d[0] & 15) * 4
        total, frag = struct.unpack_from(">H", d, 2)[0], struct.unpack_from(">H", d, 6)[0]
        if frag & 0x3FFF or ihl < 20:  # a fragment (not reassembled) or a bad header
            return None
        return d[9], str(ipaddress.IPv4Address(d[12:16])), str(ipaddress.IPv4Address(d[16:20])), \
            d[ihl:min(len(d), total)]
    if ethertype == 0x86DD:
        if len(d) < 40 or d[0] >> 4 != 6:
            return None
        length = struct.unpack_from(">H", d, 4)[0]
        return d[6], str(ipaddress.IPv6Address(d[8:24])), str(ipaddress.IPv6Address(d[24:40])), \
            d[40:min(len(d), 40 + length)]
    return None


def udp_kind(dst_port: int, payload: bytes) -> str | None:
    """The kind of a UDP datagram to ``dst_port``, or None if it is not FRC.

    The 2010 protocol shares ports 1110 and 1150 with today's. Its packets are fixed sizes,
    1024 bytes (control) and 1024 or 1152 (status), while today's are a few dozen bytes (a
    header and tags, 6 joysticks at most), so the length tells them apart, as fieldbox's roles
    do by the protocol they are set to speak. A packet that is neither decodes as today's and
    is printed with its error."""
    kind = UDP_PORTS.get(dst_port)
    if kind == "ds-to-rio" and dst_port == 1110 and len(payload) in _LEGACY_CONTROL_SIZES:
        return "legacy-ds-to-robot"
    if kind == "rio-to-ds" and len(payload) in _LEGACY_STATUS_SIZES:
        return "legacy-robot-to-ds"
    return kind


# -- TCP ----------------------------------------------------------------------------------------
@dataclass
class _Direction:
    kind: str
    next_seq: int
    decoder: FrameDecoder
    pending: dict[int, bytes] = field(default_factory=dict)
    pending_bytes: int = 0
    lost: bool = False


class Reader:
    """FRC packets out of capture records, with the counts of everything else."""

    def __init__(self) -> None:
        self.counts = Counts()
        self._streams: dict[tuple[Address, Address], _Direction] = {}

    def _note(self, text: str) -> None:
        if len(self.counts.notes) < 10:
            self.counts.notes.append(text)

    def packets(self, f: BinaryIO) -> Iterator[FrcPacket]:
        for record in records(f):
            self.counts.records += 1
            if self.counts.first_time is None:
                self.counts.first_time = record.time
            found = list(self.feed(record))
            if found:
                self.counts.frc += len(found)
                yield from found

    def feed(self, record: Record) -> Iterator[FrcPacket]:
        ip = ip_payload(record.linktype, record.data)
        if ip is None:
            self.counts.other += 1
            return
        proto, src_host, dst_host, p = ip
        if proto == _UDP and len(p) >= 8:
            sport, dport, length = struct.unpack_from(">HHH", p, 0)
            payload = bytes(p[8:max(8, min(length, len(p)))])
            kind = udp_kind(dport, payload)
            if kind is None:
                self.counts.other += 1
                return
            yield FrcPacket(record.time, kind, (src_host, sport), (dst_host, dport), payload, record.offset)
            return
        if proto == _TCP and len(p) >= 20:
            sport, dport, seq, _ack, off_flags = struct.unpack_from(">HHIIH", p, 0)
            if dport in TCP_PORTS:
                kind = TCP_PORTS[dport][0]  # to the server port: the client (DS) speaks
            elif sport in TCP_PORTS:
                kind = TCP_PORTS[sport][1]
            else:
                self.counts.other += 1
                return
            payload = bytes(p[(off_flags >> 12) * 4:])
            frames = list(self._segment(kind, (src_host, sport), (dst_host, dport), seq, off_flags & 0x3F,
                                        payload, record))
            if not payload:
                self.counts.other += 1  # a bare ACK, SYN or FIN: no FRC bytes
            yield from frames
            return
        self.counts.other += 1

    def _segment(self, kind: str, src: Address, dst: Address, seq: int, flags: int, payload: bytes,
                 record: Record) -> Iterator[FrcPacket]:
        key = (src, dst)
        st = self._streams.get(key)
        if flags & _SYN:  # a new connection: a new stream, framed from its first byte
            self._open(key, _Direction(kind, (seq + 1) & 0xFFFFFFFF, FrameDecoder(f"{kind} stream")))
            return
        if flags & _RST:
            self._streams.pop(key, None)
            return
        if st is None:  # its SYN was not captured: the stream starts at its first segment seen
            if not payload:
                return
            st = self._open(key, _Direction(kind, seq, FrameDecoder(f"{kind} stream")))
        if payload and not st.lost:
            ahead = (seq - st.next_seq) & 0xFFFFFFFF
            if ahead >= 0x80000000:  # starts before what is framed: a retransmission, maybe longer
                overlap = (st.next_seq - seq) & 0xFFFFFFFF
                payload, ahead = payload[overlap:], 0
            if ahead == 0 and payload:
                yield from self._frames(st, payload, src, dst, record)
                yield from self._drain(st, src, dst, record)
            elif payload:
                old = st.pending.get(seq)
                if old is None or len(payload) > len(old):
                    st.pending_bytes += len(payload) - len(old or b"")
                    st.pending[seq] = payload
                if len(st.pending) > MAX_PENDING_SEGMENTS or st.pending_bytes > MAX_PENDING_BYTES:
                    self._lose(st, src, dst, f"a segment at sequence number {st.next_seq} never came "
                               f"({len(st.pending)} later segments held)")
        elif payload:
            self.counts.tcp_lost_bytes += len(payload)
        if flags & _FIN:
            self._streams.pop(key, None)

    def _open(self, key: tuple[Address, Address], st: _Direction) -> _Direction:
        self._streams.pop(key, None)
        if len(self._streams) >= MAX_STREAMS:
            oldest = next(iter(self._streams))
            del self._streams[oldest]
            self._note(f"over {MAX_STREAMS} TCP streams at once: {_addr(oldest[0])} -> {_addr(oldest[1])} "
                       "forgotten")
        self._streams[key] = st
        return st

    def _drain(self, st: _Direction, src: Address, dst: Address, record: Record) -> Iterator[FrcPacket]:
        """Frame the held segments that now follow on; a held one partly behind the stream (a
        retransmission overlapping it) is trimmed first, one wholly behind is dropped."""
        while st.pending and not st.lost:
            data = st.pending.pop(st.next_seq, None)
            if data is None:
                for seq in list(st.pending):
                    behind = (st.next_seq - seq) & 0xFFFFFFFF
                    if 0 < behind < 0x80000000:
                        old = st.pending.pop(seq)
                        st.pending_bytes -= len(old)
                        if behind < len(old) and data is None or (data is not None and len(old) - behind > len(data)):
                            data = old[behind:]
                if data is None:
                    return  # a hole still: wait for it
            else:
                st.pending_bytes -= len(data)
            yield from self._frames(st, data, src, dst, record)

    def _frames(self, st: _Direction, data: bytes, src: Address, dst: Address,
                record: Record) -> Iterator[FrcPacket]:
        st.next_seq = (st.next_seq + len(data)) & 0xFFFFFFFF
        frames, error = st.decoder.feed_until_error(data)
        for frame in frames:
            yield FrcPacket(record.time, st.kind, src, dst, frame, record.offset)
        if error is not None:
            self._lose(st, src, dst, str(error))

    def _lose(self, st: _Direction, src: Address, dst: Address, why: str) -> None:
        st.lost = True
        self.counts.tcp_lost += 1
        self.counts.tcp_lost_bytes += st.pending_bytes + st.decoder.buffered
        st.pending.clear()
        st.pending_bytes = 0
        self._note(f"TCP {_addr(src)} -> {_addr(dst)}: not framed from here on: {why}")


# -- who is who -----------------------------------------------------------------------------------
def team_of(host: str) -> int | None:
    """The team of an address on the 10.TE.AM.x plan (or fieldbox's 127.TE.AM.x loopback plan)."""
    parts = host.split(".")
    if len(parts) != 4 or parts[0] not in ("10", "127") or not all(p.isdigit() for p in parts):
        return None
    te, am = int(parts[1]), int(parts[2])
    team = te * 100 + am
    return team if am < 100 and 0 < team <= 25599 else None


def _addr(a: Address) -> str:
    return f"[{a[0]}]:{a[1]}" if ":" in a[0] else f"{a[0]}:{a[1]}"


def link_text(p: FrcPacket) -> str:
    """``10.64.43.231:57659 -> 10.64.43.2:1110 (ds 6443 -> robot 6443)``."""
    return f"{_addr(p.src)} -> {_addr(p.dst)} ({roles_text(p)})"


def roles_text(p: FrcPacket) -> str:
    sender, receiver = ROLES.get(p.kind, ("?", "?"))
    return f"{_role(sender, p.src[0])} -> {_role(receiver, p.dst[0])}"


def _role(role: str, host: str) -> str:
    team = team_of(host) if role != "fms" else None
    return f"{role} {team}" if team is not None else role
