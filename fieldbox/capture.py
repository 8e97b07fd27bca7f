"""The packet capture behind the inspector: a bounded ring fed by an engine tap, and where
each packet went (the pcap file itself: fieldbox/pcap.py).

Two parts, no textual:

* :class:`CaptureRing` -- ``ring.tap`` is the engine tap. It runs on the WIRE thread, so all it
  does is append its :class:`~roles.runtime.shell.TapRecord` to a deque (atomic in CPython, no
  lock). The app thread calls
  :meth:`CaptureRing.drain` about ten times a second: that numbers the packets, splits TCP
  chunks into frames, files them per link and bounds memory (``per_link`` packets per link,
  ``total`` in all).
* :class:`Endpoints` -- the addresses a packet travelled between: each tap carries both ends
  as the sockets named them (roles/runtime/shell.py), so this only turns a wildcard bind into an
  address and finds the packets tapped twice.

When two roles in this process talk to each other, each packet is tapped twice (sent by one,
received by the other); a pcap holds it once, as a capture on the loopback interface would.
"""

from __future__ import annotations

import functools
import ipaddress
from collections import deque
from dataclasses import dataclass, field
from typing import Any, NamedTuple

from protocol import kinds as protocol_kinds
from protocol.errors import ProtocolError
from protocol.framing import FrameDecoder
from roles.runtime.process_tuning import untrack_plain
from roles.runtime.shell import TapRecord

#: Packets kept per link, and in all: a six-station field sends ~1500 packets a second.
PER_LINK = 10_000
TOTAL = 50_000

LinkKey = tuple[str, str, str, str]  # (role, link, direction, kind)
Address = tuple[str, int]


class CapturedPacket(NamedTuple):
    seq: int          # capture order over all links, from 1
    index: int        # type: ignore[assignment]  # order on its own link, from 0 (hides tuple.index)
    time: float       # engine clock
    role: str
    link: str
    direction: str    # "in" / "out", as the role saw it
    kind: str
    data: bytes
    remote: Address | None
    local: Address | None

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


class CaptureRing:
    """Every tapped packet, per link, bounded. ``tap`` is the only method the wire calls."""

    def __init__(self, per_link: int = PER_LINK, total: int = TOTAL) -> None:
        self.per_link = per_link
        self.total = total
        # Filled on the wire thread; bounded so a stalled app cannot eat memory.
        self._incoming: deque[TapRecord] = deque(maxlen=total)
        self.links: dict[LinkKey, deque[CapturedPacket]] = {}
        self.counts: dict[LinkKey, int] = {}  # packets ever seen per link
        self._order: deque[CapturedPacket] = deque()
        self.seq = 0           # packets ever filed
        self.evicted = 0       # filed, then pushed out by the bounds
        self.overflowed = 0    # lost before filing (the app did not drain for too long)
        self._tapped = 0
        self._popped = 0

    # -- the wire side ------------------------------------------------------------------
    def tap(self, record: TapRecord) -> None:
        self._tapped += 1
        self._incoming.append(record)

    # -- the app side -------------------------------------------------------------------
    def pending(self) -> int:
        """Packets tapped and not yet filed."""
        return len(self._incoming)

    def drain(self) -> list[CapturedPacket]:
        """File what the tap collected since the last call; return the new packets."""
        incoming = self._incoming
        n = len(incoming)
        if not n:
            return []
        new: list[CapturedPacket] = []
        popleft = incoming.popleft
        for _ in range(n):
            r = popleft()
            now, role, link, direction, kind = r.time, r.role, r.link, r.direction, r.kind
            data = bytes(r.data)
            remote = _address(r.remote[0], r.remote[1]) if r.remote else None
            local = _address(r.local[0], r.local[1]) if r.local else None
            if is_tcp_kind(kind):
                for frame in _frames(data):
                    new.append(self._file(now, role, link, direction, kind, frame, remote, local))
            else:
                new.append(self._file(now, role, link, direction, kind, data, remote, local))
        self._popped += n
        # The deque drops its oldest when full: what was tapped and neither popped nor held.
        self.overflowed = max(self.overflowed, self._tapped - self._popped - len(incoming))
        return new

    def _file(self, now, role, link, direction, kind, data, remote, local) -> CapturedPacket:
        key = (role, link, direction, kind)
        ring = self.links.get(key)
        if ring is None:
            ring = self.links[key] = deque()
            self.counts[key] = 0
        self.seq += 1
        packet = CapturedPacket(self.seq, self.counts[key], now, role, link, direction, kind, data, remote, local)
        # A full ring was a quarter of what the collector tracks in the app, walked at every full
        # collection; a packet holds only plain data, so reference counting frees it.
        untrack_plain(packet)
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
_WILDCARD = ("0.0.0.0", "::", "")


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


@functools.lru_cache(maxsize=256)
def _concrete(addr: Address | None) -> Address:
    """An address for a header; a wildcard bind (0.0.0.0) as the loopback address peers in
    this process reach it by."""
    if addr is None:
        return ("0.0.0.0", 0)
    host = str(addr[0])
    return ("127.0.0.1" if host in _WILDCARD else _ipv4(host), int(addr[1]))


@dataclass
class Route:
    """Where one tapped packet went: ``src -> dst``, and whether another role in this process
    tapped the same bytes (so a pcap holds it once)."""

    src: Address
    dst: Address
    duplicate: bool = False


@dataclass
class Endpoints:
    """The addresses of tapped packets, as their taps gave them. It learns this process's own
    sockets from the packets' local ends: a packet that arrives from one of them was tapped
    already when it was sent (taps run in order, the sender's first)."""

    _ours: set[Address] = field(default_factory=set)
    _wild_ports: set[int] = field(default_factory=set)  # ports bound to every address

    def _learn(self, local: Address) -> None:
        if local[0] in _WILDCARD:
            self._wild_ports.add(local[1])
        else:
            self._ours.add(local)

    def is_ours(self, addr: Address) -> bool:
        return addr in self._ours or (addr[1] in self._wild_ports and str(addr[0]).startswith("127."))

    def route(self, p: CapturedPacket) -> Route:
        if p.local is not None:
            self._learn(p.local)
        local, remote = _concrete(p.local), _concrete(p.remote)
        if p.direction == "out":
            return Route(local, remote)
        return Route(remote, local, duplicate=p.remote is not None and self.is_ours(p.remote))


