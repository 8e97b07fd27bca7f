"""An in-memory network on a fake clock: the same role cores and specs as the asyncio shell,
with datagrams and TCP streams delivered by a scheduler instead of sockets.

Tests run a whole field, a whole match, minutes of traffic, in milliseconds, and see every
byte. Faults (loss, delay, cuts) can be applied per link through ``SimNetwork.filters``,
or through ``SimNetwork.faults`` (a :class:`roles.sim.faults.Faults`, the same object and the
same decisions as the asyncio shell's ``Runtime.faults``).
"""

from __future__ import annotations

import heapq
import itertools
import logging
from dataclasses import dataclass, field
from typing import Any, Callable, Hashable, cast

from ..cores.core import Address, Close, Connect, Datagram, StreamSend
from ..runtime.shell import CONNECT_TIMEOUT, MAX_WRITE_BUFFER, RoleSpec, Tap, TapRecord, link_name
from .faults import Faults, link_for_kind

log = logging.getLogger("fieldbox.simnet")

#: One-way delivery time on the fake wire (loopback-like).
DEFAULT_LATENCY = 0.0002


@dataclass
class SimHost:
    net: "SimNetwork"
    spec: RoleSpec
    bound: dict[str, Address] = field(default_factory=dict)
    next_poll: float | None = None

    @property
    def core(self) -> Any:
        return self.spec.core


class SimNetwork:
    def __init__(self, start: float = 1000.0, latency: float = DEFAULT_LATENCY) -> None:
        self.now = start
        self.latency = latency
        self.hosts: dict[str, SimHost] = {}
        self.taps: list[Tap] = []
        #: ``filter(host, link, dest, data, now) -> list of (delay, data)``: the fault hook.
        #: Return [] to drop, several entries to duplicate, a longer delay to delay.
        self.filters: list[Callable[[str, str, Any, bytes, float], list[tuple[float, bytes]]]] = []
        self._queue: list[tuple[float, int, Callable[[], None]]] = []
        self._seq = itertools.count()
        self._udp: dict[Address, tuple[SimHost, str]] = {}
        self._servers: dict[Address, tuple[SimHost, str]] = {}
        self._ports = itertools.count(40000)
        self._conn_ids = itertools.count(1)
        # (host name, conn) -> (peer host, peer conn)
        self._links: dict[tuple[str, Hashable], tuple[SimHost, Hashable]] = {}
        # (host name, conn) -> (remote, local): a stream's two ends, for its taps
        self._ends: dict[tuple[str, Hashable], tuple[Address, Address]] = {}
        self.dropped_unroutable = 0
        self._faults: Faults | None = None
        self._pump_at: dict[tuple, float] = {}

    @property
    def faults(self):
        """A :class:`roles.sim.faults.Faults` every send consults, or None."""
        return self._faults

    @faults.setter
    def faults(self, faults) -> None:
        if self._faults is not None and self._pump_all in self._faults.listeners:
            self._faults.listeners.remove(self._pump_all)
        self._faults = faults
        if faults is not None:
            faults.listeners.append(self._pump_all)

    def _pump_all(self) -> None:
        faults = self._faults
        if faults is None:
            return
        for flow in faults.waiting_flows():
            key = cast(tuple[str, Hashable, str], flow)  # this network's flows: (host, connection, "out")
            host = self.hosts.get(key[0])
            if host is None:
                faults.stream_closed(flow)
            else:
                self._pump(host, key[1])

    # -- setup ---------------------------------------------------------------------------
    def add(self, spec: RoleSpec) -> SimHost:
        host = SimHost(self, spec)
        for channel, addr in spec.udp.items():
            if channel in spec.aliases:
                continue
            addr = self._bind_addr(addr)
            if addr in self._udp:
                raise OSError(f"address in use: {addr}")
            self._udp[addr] = (host, channel)
            host.bound[channel] = addr
        for channel, target in spec.aliases.items():
            host.bound[channel] = host.bound[target]
        for name, addr in spec.tcp_servers.items():
            addr = self._bind_addr(addr)
            if addr in self._servers:
                raise OSError(f"address in use: {addr}")
            self._servers[addr] = (host, name)
            host.bound[name] = addr
        self.hosts[spec.name] = host
        self._schedule_poll(host, self.now)
        return host

    def _bind_addr(self, addr: Address) -> Address:
        return (addr[0], addr[1] or next(self._ports))

    # -- running ---------------------------------------------------------------------------
    def at(self, when: float, fn: Callable[[], None]) -> None:
        heapq.heappush(self._queue, (when, next(self._seq), fn))

    def _schedule_poll(self, host: SimHost, when: float | None) -> None:
        if when is None:
            host.next_poll = None
            return
        when = max(when, self.now)
        if host.next_poll is not None and host.next_poll <= when:
            return
        host.next_poll = when

        def fire(h=host, t=when) -> None:
            if h.next_poll != t or h.spec.name not in self.hosts:
                return  # superseded
            h.next_poll = None
            self._perform(h, h.core.poll(self.now))
            self._reschedule(h)

        self.at(when, fire)

    def _reschedule(self, host: SimHost) -> None:
        deadline = host.core.next_deadline()
        if deadline is not None:
            self._schedule_poll(host, deadline)

    def run_until(self, t: float) -> None:
        while self._queue and self._queue[0][0] <= t:
            when, _, fn = heapq.heappop(self._queue)
            self.now = max(self.now, when)
            fn()
        self.now = max(self.now, t)

    def run_for(self, seconds: float) -> None:
        self.run_until(self.now + seconds)

    def command(self, host_name: str, fn: Callable[[], Any]) -> Any:
        """Run a user command against a core, then poll it at once (as the shell does)."""
        host = self.hosts[host_name]
        value = fn()
        self._perform(host, host.core.poll(self.now))
        self._reschedule(host)
        return value

    # -- delivery ----------------------------------------------------------------------------
    def _tap(self, host: SimHost, link: str, direction: str, kind: str, data: bytes, remote, local) -> None:
        record = TapRecord(host.spec.name, link, direction, kind, data, remote, local, self.now)
        for tap in self.taps:
            tap(record)

    def _filtered(self, host: SimHost, link: str, dest, data: bytes) -> list[tuple[float, bytes]]:
        out = [(self.latency, data)]
        for f in self.filters:
            result = []
            for delay, d in out:
                for extra, d2 in f(host.spec.name, link, dest, d, self.now):
                    result.append((delay + extra, d2))
            out = result
        return out

    def _perform(self, host: SimHost, actions) -> None:
        for action in actions or ():
            t = type(action)
            if t is Datagram:
                self._send_datagram(host, action)
            elif t is StreamSend:
                self._send_stream(host, action)
            elif t is Connect:
                self._connect(host, action)
            elif t is Close:
                self._close(host, action.conn, action.reason)

    def _send_datagram(self, host: SimHost, action: Datagram) -> None:
        source = host.bound.get(action.channel)
        if source is None:
            return
        kind = action.kind or host.spec.kind(action.channel, "out")
        self._tap(host, action.channel, "out", kind, action.data, action.dest, source)
        # tuple(): an address that crossed a process boundary may be a list
        target = self._udp.get(cast(Address, tuple(action.dest))) or self._udp.get(("0.0.0.0", action.dest[1]))
        if target is None:
            self.dropped_unroutable += 1
            return
        dest_host, channel = target
        copies = [(0.0, action.data)]
        faults = self._faults
        if faults is not None and faults.any_active:
            link = link_for_kind(kind)
            if faults.active(link):
                copies = faults.datagram(link, (host.spec.name, action.channel, tuple(action.dest)), action.data,
                                         self.now)
        for extra, sent in copies:
            for delay, data in self._filtered(host, action.channel, action.dest, sent):
                def deliver(h=dest_host, ch=channel, d=data, src=source) -> None:
                    if h.spec.name not in self.hosts:
                        return
                    self._tap(h, ch, "in", h.spec.kind(ch, "in"), d, src, h.bound.get(ch))
                    self._perform(h, h.core.datagram(ch, d, src, self.now))
                    self._reschedule(h)
                self.at(self.now + extra + delay, deliver)

    def _connect(self, host: SimHost, action: Connect) -> None:
        key = (host.spec.name, action.conn)
        if key in self._links:
            return
        server = self._servers.get(cast(Address, tuple(action.address))) or self._servers.get(("0.0.0.0", action.address[1]))

        def refused(h=host, conn=action.conn) -> None:
            self._perform(h, h.core.stream_closed(conn, "connect failed: refused", self.now))
            self._reschedule(h)

        if server is None:
            self.at(self.now + self.latency, refused)
            return
        faults = self._faults
        if faults is not None and not faults.connect_allowed(link_for_kind(host.spec.kind(action.conn, "out"))):
            def timed_out(h=host, conn=action.conn) -> None:  # a cut link: the attempt times out
                if h.spec.name in self.hosts:
                    self._perform(h, h.core.stream_closed(conn, "connect failed: timeout (link cut by a fault)",
                                                          self.now))
                    self._reschedule(h)
            self.at(self.now + CONNECT_TIMEOUT, timed_out)
            return
        server_host, server_name = server
        server_conn = (server_name, next(self._conn_ids))
        client_addr = (next(iter(host.bound.values()), ("127.0.0.1", 0))[0], next(self._ports))

        def established() -> None:
            if server_host.spec.name not in self.hosts:
                refused()
                return
            self._links[key] = (server_host, server_conn)
            self._links[(server_host.spec.name, server_conn)] = (host, action.conn)
            server_addr = cast(Address, tuple(action.address))  # what the client dialled, as getsockname says
            self._ends[key] = (server_addr, client_addr)
            self._ends[(server_host.spec.name, server_conn)] = (client_addr, server_addr)
            self._perform(server_host, server_host.core.stream_opened(server_conn, client_addr, self.now))
            self._reschedule(server_host)
            self._perform(host, host.core.stream_opened(action.conn, tuple(action.address), self.now))
            self._reschedule(host)

        self.at(self.now + self.latency, established)

    def _send_stream(self, host: SimHost, action: StreamSend) -> None:
        peer = self._links.get((host.spec.name, action.conn))
        if peer is None:
            return
        kind = action.kind or host.spec.kind(action.conn, "out")
        faults = self._faults
        if faults is not None and faults.any_active:
            flow = (host.spec.name, action.conn, "out")
            link = link_for_kind(kind)
            if faults.stream_involved(link, flow):
                if faults.stream_queued(flow) > MAX_WRITE_BUFFER:  # as the shell bounds it
                    self._close(host, action.conn, "too much data held by a fault")
                    return
                faults.stream_push(link, flow, action.data, self.now)
                self._pump(host, action.conn)
                return
        self._stream_out(host, action.conn, action.data, kind)

    def _pump(self, host: SimHost, conn: Hashable) -> None:
        """Send what the faults' line released for ``conn``; come back when more is due."""
        faults = self._faults
        flow = (host.spec.name, conn, "out")
        if faults is None:
            return
        if (host.spec.name, conn) not in self._links:
            faults.stream_closed(flow)
            return
        kind = host.spec.kind(conn, "out")
        for data in faults.stream_take(flow, self.now):
            self._stream_out(host, conn, data, kind)
        deadline = faults.stream_deadline(flow)
        if deadline is None or self._pump_at.get(flow) == deadline:
            return
        self._pump_at[flow] = deadline

        def fire(t=deadline) -> None:
            if self._pump_at.get(flow) == t:
                del self._pump_at[flow]
                if host.spec.name in self.hosts:
                    self._pump(host, conn)
        self.at(deadline, fire)

    def _stream_out(self, host: SimHost, conn: Hashable, data: bytes, kind: str) -> None:
        peer = self._links.get((host.spec.name, conn))
        if peer is None:
            return
        peer_host, peer_conn = peer
        action = StreamSend(conn, data, kind)
        self._tap(host, link_name(action.conn), "out", kind, action.data, *self._ends[(host.spec.name, conn)])
        for delay, data in self._filtered(host, link_name(action.conn), None, action.data)[:1]:
            # A stream is ordered and reliable: faults may delay or cut it, never reorder it.
            def deliver(h=peer_host, c=peer_conn, d=data) -> None:
                if (h.spec.name, c) not in self._links:
                    return
                self._tap(h, link_name(c), "in", h.spec.kind(c, "in"), d, *self._ends[(h.spec.name, c)])
                self._perform(h, h.core.stream_data(c, d, self.now))
                self._reschedule(h)
            self.at(self.now + delay, deliver)

    def _close(self, host: SimHost, conn: Hashable, reason: str) -> None:
        peer = self._links.pop((host.spec.name, conn), None)
        self._ends.pop((host.spec.name, conn), None)
        if self._faults is not None:
            self._faults.stream_closed((host.spec.name, conn, "out"))
            if peer is not None:
                self._faults.stream_closed((peer[0].spec.name, peer[1], "out"))
        self._perform(host, host.core.stream_closed(conn, reason or "closed", self.now))
        self._reschedule(host)
        if peer is None:
            return
        peer_host, peer_conn = peer
        self._links.pop((peer_host.spec.name, peer_conn), None)
        self._ends.pop((peer_host.spec.name, peer_conn), None)

        def closed(h=peer_host, c=peer_conn) -> None:
            self._perform(h, h.core.stream_closed(c, "peer closed", self.now))
            self._reschedule(h)

        self.at(self.now + self.latency, closed)

    def remove(self, name: str) -> None:
        """Take a host off the network (a pulled cable, a crashed process)."""
        host = self.hosts.pop(name, None)
        if host is None:
            return
        for addr, (h, _) in list(self._udp.items()):
            if h is host:
                del self._udp[addr]
        for addr, (h, _) in list(self._servers.items()):
            if h is host:
                del self._servers[addr]
        for (hname, conn), (peer, pconn) in list(self._links.items()):
            if hname == name:
                self._links.pop((hname, conn), None)
                self._links.pop((peer.spec.name, pconn), None)
                self._ends.pop((hname, conn), None)
                self._ends.pop((peer.spec.name, pconn), None)
                def gone(p: SimHost = peer, c: Hashable = pconn) -> None:
                    self._perform(p, p.core.stream_closed(c, "peer gone", self.now))
                    self._reschedule(p)
                self.at(self.now + self.latency, gone)
