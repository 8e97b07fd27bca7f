"""The packet capture behind the inspector: a bounded ring fed by an engine tap, and a pcap
writer Wireshark and tshark open.

Three parts, no textual:

* :class:`CaptureRing` -- ``ring.tap`` is the engine tap. It runs on the WIRE thread, so all it
  does is append a tuple to a deque (atomic in CPython, no lock). The app thread calls
  :meth:`CaptureRing.drain` about ten times a second: that numbers the packets, splits TCP
  chunks into frames, files them per link and bounds memory (``per_link`` packets per link,
  ``total`` in all).
* :class:`Endpoints` -- the addresses a packet really travelled between. A tap gives the
  peer of a UDP datagram; the local side comes from ``engine.field.bound``; TCP taps carry no
  address at all, so a stream's ends are found from the cores (the DS's server addresses, the
  FMS's connection table) or, on real sockets, from the socket itself.
* :class:`PcapWriter` -- classic pcap (magic ``a1b2c3d4``, ``LINKTYPE_RAW``): each packet in a
  synthetic IPv4 + UDP or TCP header with the real addresses and ports, correct checksums,
  and TCP sequence numbers that grow per stream direction. Written incrementally and
  flushed, so a recording loses nothing if the app dies.

When two roles in this process talk to each other, each packet is tapped twice (sent by one,
received by the other); a pcap holds it once, as a capture on the loopback interface would.
"""

from __future__ import annotations

import functools
import ipaddress
import struct
import time
import zlib
from collections import deque
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, BinaryIO, Callable, Iterable, NamedTuple

from protocol import kinds as protocol_kinds
from protocol.errors import ProtocolError
from protocol.framing import FrameDecoder

#: Packets kept per link, and in all: a six-station field sends ~1500 packets a second.
PER_LINK = 10_000
TOTAL = 50_000

PCAP_MAGIC = 0xA1B2C3D4
LINKTYPE_RAW = 101  # raw IPv4/IPv6, no link-layer header
SNAPLEN = 0xFFFF
IPPROTO_TCP = 6
IPPROTO_UDP = 17
TCP_PSH_ACK = 0x18

LinkKey = tuple[str, str, str, str]  # (role, link, direction, kind)
Address = tuple[str, int]


class CapturedPacket(NamedTuple):
    seq: int          # capture order over all links, from 1
    index: int        # order on its own link, from 0
    time: float       # engine clock
    role: str
    link: str
    direction: str    # "in" / "out", as the role saw it
    kind: str
    data: bytes
    peer: Address | None

    @property
    def key(self) -> LinkKey:
        return (self.role, self.link, self.direction, self.kind)


def link_label(key: LinkKey) -> str:
    """``ds 254 robot out ds-to-rio``: role, link, direction, kind."""
    role, link, direction, kind = key
    return f"{role} {link} {direction} {kind or '?'}"


def is_tcp_kind(kind: str) -> bool:
    try:
        return protocol_kinds.get(kind).tcp
    except KeyError:
        return kind.endswith("-tcp")


@functools.lru_cache(maxsize=256)
def _address(ip: Any, port: Any) -> Address:
    """One tuple per address for the whole ring (a field has a handful; a tuple per packet
    was 2.8 MB of a full ring)."""
    return (str(ip), int(port))


def _gc_untrack() -> Callable[[object], None]:
    """CPython's ``PyObject_GC_UnTrack``: the cyclic collector stops looking at an object.

    A full ring is 50 000 packets, a quarter of the objects the collector tracks in the
    app's process, and each full collection walked them all (the app stopped meanwhile).
    A packet holds only numbers, strings, bytes and an address tuple, so it can never be
    part of a reference cycle: reference counting frees it when the ring drops it. CPython
    untracks plain tuples like it by itself, but not named tuples. Elsewhere than CPython
    (no ``ctypes.pythonapi``): nothing, the packets stay tracked."""
    try:
        import ctypes

        untrack = ctypes.pythonapi.PyObject_GC_UnTrack
    except (ImportError, AttributeError, OSError):  # pragma: no cover - not CPython
        return lambda obj: None
    untrack.argtypes = (ctypes.py_object,)
    untrack.restype = None
    return untrack


#: ``untrack_plain(obj)``: untrack an object that holds only numbers, strings, bytes and
#: plain tuples of them (the inspector's packets, the console panel's lines).
untrack_plain = _gc_untrack()


class CaptureRing:
    """Every tapped packet, per link, bounded. ``tap`` is the only method the wire calls."""

    def __init__(self, per_link: int = PER_LINK, total: int = TOTAL) -> None:
        self.per_link = per_link
        self.total = total
        # Filled on the wire thread; bounded so a stalled app cannot eat memory.
        self._incoming: deque[tuple] = deque(maxlen=total)
        self.links: dict[LinkKey, deque[CapturedPacket]] = {}
        self.counts: dict[LinkKey, int] = {}  # packets ever seen per link
        self._order: deque[CapturedPacket] = deque()
        self.seq = 0           # packets ever filed
        self.evicted = 0       # filed, then pushed out by the bounds
        self.overflowed = 0    # lost before filing (the app did not drain for too long)
        self._tapped = 0
        self._popped = 0

    # -- the wire side ------------------------------------------------------------------
    def tap(self, role: str, link: str, direction: str, kind: str, data: bytes, peer: Any,
            now: float) -> None:
        self._tapped += 1
        self._incoming.append((now, role, link, direction, kind, data, peer))

    # -- the app side -------------------------------------------------------------------
    def drain(self) -> list[CapturedPacket]:
        """File what the tap collected since the last call; return the new packets."""
        incoming = self._incoming
        n = len(incoming)
        if not n:
            return []
        new: list[CapturedPacket] = []
        popleft = incoming.popleft
        for _ in range(n):
            now, role, link, direction, kind, data, peer = popleft()
            data = bytes(data)
            peer = _address(peer[0], peer[1]) if peer else None
            if is_tcp_kind(kind):
                for frame in _frames(data):
                    new.append(self._file(now, role, link, direction, kind, frame, peer))
            else:
                new.append(self._file(now, role, link, direction, kind, data, peer))
        self._popped += n
        # The deque drops its oldest when full: what was tapped and neither popped nor held.
        self.overflowed = max(self.overflowed, self._tapped - self._popped - len(incoming))
        return new

    def _file(self, now, role, link, direction, kind, data, peer) -> CapturedPacket:
        key = (role, link, direction, kind)
        ring = self.links.get(key)
        if ring is None:
            ring = self.links[key] = deque()
            self.counts[key] = 0
        self.seq += 1
        packet = CapturedPacket(self.seq, self.counts[key], now, role, link, direction, kind, data, peer)
        untrack_plain(packet)  # plain data: never in a cycle (_gc_untrack)
        self.counts[key] += 1
        ring.append(packet)
        if len(ring) > self.per_link:
            ring.popleft()
            self.evicted += 1
        order = self._order
        order.append(packet)
        if len(order) > self.total:
            old = order.popleft()
            old_ring = self.links[old.key]
            if old_ring and old_ring[0] is old:
                old_ring.popleft()
                self.evicted += 1
        return packet

    def previous(self, packet: CapturedPacket) -> CapturedPacket | None:
        """The packet before ``packet`` on its own link, if the ring still holds it."""
        ring = self.links.get(packet.key)
        if not ring:
            return None
        at = packet.index - 1 - ring[0].index
        if 0 <= at < len(ring) and ring[at].index == packet.index - 1:
            return ring[at]
        return None

    def packets(self) -> list[CapturedPacket]:
        """Everything still held, in capture order."""
        return sorted((p for ring in self.links.values() for p in ring), key=lambda p: p.seq)

    def __len__(self) -> int:
        return sum(len(r) for r in self.links.values())

    def clear(self) -> None:
        self._popped += len(self._incoming)
        self._incoming.clear()
        self.links.clear()
        self.counts.clear()
        self._order.clear()


def _frames(data: bytes) -> list[bytes]:
    """A TCP chunk as whole frames (the sim network taps what a core wrote at once, which
    may be several frames); a chunk that does not frame is kept as it is."""
    if len(data) >= 2 and ((data[0] << 8) | data[1]) + 2 == len(data):
        return [data]
    try:
        decoder = FrameDecoder("capture")
        frames = decoder.feed(data)
    except ProtocolError:
        return [data]
    if decoder.buffered or not frames:
        return [data]
    return frames


# -- addresses ------------------------------------------------------------------------------
@functools.lru_cache(maxsize=256)  # a field has a handful of addresses; this runs per packet
def _ipv4(host: str) -> str:
    """An address for an IPv4 header: anything that is not an IPv4 literal becomes 0.0.0.0."""
    try:
        ip = ipaddress.ip_address(host)
    except ValueError:
        return "0.0.0.0"
    if ip.version == 4:
        return str(ip)
    mapped = getattr(ip, "ipv4_mapped", None)
    return str(mapped) if mapped else "0.0.0.0"


def _concrete(addr: Address | None) -> Address | None:
    """A wildcard bind (0.0.0.0) as the loopback address peers in this process reach it by."""
    if addr is None:
        return None
    host, port = str(addr[0]), int(addr[1])
    if host in ("0.0.0.0", "::", ""):
        host = "127.0.0.1"
    return (_ipv4(host), port)


@dataclass
class Route:
    """Where one tapped packet went: ``src -> dst``, and whether another role in this process
    tapped the same bytes (so a pcap holds it once)."""

    src: Address
    dst: Address
    duplicate: bool = False


@dataclass
class Endpoints:
    """Finds the real addresses of tapped packets from an engine's field (and, on real
    sockets, from the sockets). Read-only: it never changes a core."""

    engine: Any
    _tcp_cache: dict[tuple[str, str], tuple[Address, Address, bool]] = field(default_factory=dict)
    _udp_cache: tuple[tuple[int, int], set[Address]] | None = None

    # -- what this process binds ------------------------------------------------------------
    def _bound(self) -> dict[str, dict[str, Address]]:
        return getattr(self.engine.field, "bound", {}) or {}

    def _local_udp(self) -> set[Address]:
        bound = self._bound()
        key = (id(bound), sum(len(links) for links in bound.values()))
        if self._udp_cache is not None and self._udp_cache[0] == key:  # once per packet: cached
            return self._udp_cache[1]
        out = set()
        for links in bound.values():
            for addr in links.values():
                out.add((str(addr[0]), int(addr[1])))
        self._udp_cache = (key, out)
        return out

    def _is_local_udp(self, addr: Address) -> bool:
        for host, port in self._local_udp():
            if port == addr[1] and (host == addr[0] or (host in ("0.0.0.0", "::")
                                                         and addr[0].startswith("127."))):
                return True
        return False

    def _stations(self):
        return getattr(self.engine.field, "stations", [])

    def _socket_names(self, role: str, link: str) -> tuple[Address, Address] | None:
        """(local, remote) of a live TCP stream on real sockets, or None."""
        runtime = getattr(self.engine, "runtime", None)
        hosts = getattr(runtime, "hosts", None)
        if not hosts or role not in hosts:
            return None
        conn: Any = link
        if "#" in link:
            name, _, n = link.rpartition("#")
            conn = (name, int(n)) if n.isdigit() else link
        stream = hosts[role].streams.get(conn)
        transport = getattr(stream, "transport", None)
        if transport is None:
            return None
        try:
            local = transport.get_extra_info("sockname")
            remote = transport.get_extra_info("peername")
        except Exception:  # noqa: BLE001 - a closing transport
            return None
        if not local or not remote:
            return None
        return (_ipv4(local[0]), int(local[1])), (_ipv4(remote[0]), int(remote[1]))

    # -- TCP streams ----------------------------------------------------------------------------
    def _client_port(self, team: int, link: str) -> int:
        """A stable made-up source port for a client stream whose real port is unknown."""
        return 49152 + (team * 2 + (0 if link == "robot-tcp" else 1)) % 16384

    def _ds_client(self, st, link: str) -> tuple[Address, Address] | None:
        """(client, server) of a DS's TCP client stream."""
        ds = st.ds
        if ds is None:
            return None
        if link == "robot-tcp":
            server = _concrete(getattr(ds, "robot_tcp", None))
        else:
            server = _concrete(getattr(getattr(ds, "fms", None), "fms_tcp", None))
        if server is None:
            return None
        names = self._socket_names(st.ds_name, link)
        if names is not None:
            return names
        local_ip = _concrete(self._bound().get(st.ds_name, {}).get("robot", ("127.0.0.1", 0)))[0]
        port = None
        fms = self.engine.field.fms
        if link == "fms-tcp" and fms is not None:
            for conn in list(getattr(fms, "connections", {}).values()):
                if getattr(conn, "team", None) == st.team and conn.peer and conn.peer[1]:
                    port = int(conn.peer[1])
        return (local_ip, port or self._client_port(st.team, link)), server

    def _server_tcp(self, role: str) -> Address | None:
        return _concrete(self._bound().get(role, {}).get("tcp"))

    def tcp(self, role: str, link: str) -> tuple[Address, Address, bool]:
        """(local, remote, remote is a role in this process) of a tapped TCP link."""
        found = self._resolve_tcp(role, link)
        key = (role, link)
        if found is not None:
            self._tcp_cache[key] = found
            return found
        return self._tcp_cache.get(key, (("0.0.0.0", 0), ("0.0.0.0", 0), False))

    def _resolve_tcp(self, role: str, link: str) -> tuple[Address, Address, bool] | None:
        local_servers = {name: self._server_tcp(name) for name in self._bound()}
        for st in self._stations():
            if role == st.ds_name and link in ("robot-tcp", "fms-tcp"):
                ends = self._ds_client(st, link)
                if ends is None:
                    return None
                client, server = ends
                return client, server, server in local_servers.values()
        local = self._server_tcp(role)
        if local is None:
            return None
        names = self._socket_names(role, link)
        if names is not None:
            remote = names[1]
            clients = [self._ds_client(st, l) for st in self._stations() for l in ("robot-tcp", "fms-tcp")]
            return local, remote, any(c is not None and c[0] == remote for c in clients)
        # A local DS pointed at this server is the client (the sim network gives no names).
        fms = self.engine.field.fms
        is_fms = fms is not None and role == self.engine.field.fms_name
        if is_fms and "#" in link:
            name, _, n = link.rpartition("#")
            conn = fms.connections.get((name, int(n))) if n.isdigit() else None
            if conn is not None and conn.team is not None:
                for st in self._stations():
                    if st.team == conn.team and st.ds is not None:
                        ends = self._ds_client(st, "fms-tcp")
                        if ends is not None:
                            return local, ends[0], True
        for st in self._stations():
            for client_link in (("fms-tcp",) if is_fms else ("robot-tcp",)):
                ends = self._ds_client(st, client_link)
                if ends is not None and ends[1] == local:
                    return local, ends[0], True
        if is_fms and "#" in link:
            name, _, n = link.rpartition("#")
            conn = fms.connections.get((name, int(n))) if n.isdigit() else None
            if conn is not None and conn.peer:
                return local, (_ipv4(str(conn.peer[0])), int(conn.peer[1])), False
        return None

    # -- one packet ----------------------------------------------------------------------------
    def route(self, p: CapturedPacket) -> Route:
        if is_tcp_kind(p.kind):
            local, remote, remote_local = self.tcp(p.role, p.link)
            if p.direction == "out":
                return Route(local, remote)
            return Route(remote, local, duplicate=remote_local)
        local = _concrete(self._bound().get(p.role, {}).get(p.link)) or ("0.0.0.0", 0)
        peer = (_ipv4(p.peer[0]), p.peer[1]) if p.peer else ("0.0.0.0", 0)
        if p.direction == "out":
            return Route(local, peer)
        return Route(peer, local, duplicate=p.peer is not None and self._is_local_udp(p.peer))


# -- pcap -----------------------------------------------------------------------------------
def _checksum(data: bytes) -> int:
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
    return header[:10] + struct.pack("!H", _checksum(header)) + header[12:]


def _pseudo(src: str, dst: str, proto: int, length: int) -> bytes:
    return _packed(src) + _packed(dst) + struct.pack("!BBH", 0, proto, length)


@functools.lru_cache(maxsize=256)
def _packed(address: str) -> bytes:
    return ipaddress.IPv4Address(address).packed


def udp_datagram(src: Address, dst: Address, payload: bytes, ident: int) -> bytes:
    length = 8 + len(payload)
    header = struct.pack("!HHHH", src[1], dst[1], length, 0)
    checksum = _checksum(_pseudo(src[0], dst[0], IPPROTO_UDP, length) + header + payload) or 0xFFFF
    udp = header[:6] + struct.pack("!H", checksum) + payload
    return ipv4_header(src[0], dst[0], IPPROTO_UDP, length, ident) + udp


def tcp_segment(src: Address, dst: Address, payload: bytes, seq: int, ack: int, ident: int) -> bytes:
    header = struct.pack("!HHIIBBHHH", src[1], dst[1], seq & 0xFFFFFFFF, ack & 0xFFFFFFFF, 5 << 4,
                         TCP_PSH_ACK, 0xFFFF, 0, 0)
    length = len(header) + len(payload)
    checksum = _checksum(_pseudo(src[0], dst[0], IPPROTO_TCP, length) + header + payload)
    tcp = header[:16] + struct.pack("!H", checksum) + header[18:] + payload
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
    """Seconds to add to the engine clock to get Unix time."""
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
