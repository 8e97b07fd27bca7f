"""The asyncio shell: real sockets around sans-IO role cores.

One :class:`Runtime` hosts any number of cores on one event loop. For each core it binds the
UDP channels and TCP servers its :class:`RoleSpec` names, feeds arrivals into the core,
performs the actions the core returns, and wakes the core at its ``next_deadline()`` on an
absolute schedule. The wire does not wait for anything else: the app runs the Runtime on a
thread of its own (:meth:`Runtime.start_thread`) so drawing never delays the 20 ms beat.

Every packet that crosses a socket can be seen by *taps* (the packet inspector and the
capture writer): each tap is called with one :class:`TapRecord`, with the (host, port) of
both ends as the sockets name them. TCP streams are tapped as whole frames.

Faults on purpose (roles/sim/faults.py): when ``Runtime.faults`` is set, every datagram and TCP
write is offered to it before it goes out (and what arrives from a peer outside this
process, so both directions of a link are faulted either way); delays use
``loop.call_later``, TCP data waits in an in-order line per connection direction.
"""

from __future__ import annotations

import asyncio
import functools
import heapq
import ipaddress
import itertools
import logging
import math
import os
import socket
import struct
import sys
import threading
import time
from concurrent.futures import Future
from dataclasses import dataclass, field
from typing import Any, Callable, Hashable

from protocol.errors import ProtocolError
from protocol.framing import FrameDecoder

from ..cores.core import Address, Close, Connect, Core, Datagram, StreamSend
from .program_host import CodeHost
from ..sim.faults import link_for_kind

log = logging.getLogger("fieldbox.shell")


@dataclass(frozen=True, slots=True)
class TapRecord:
    """One packet a role sent or received, as its socket saw it (what every tap is given)."""

    role: str                 # "ds 254", "rio 254", "fms"
    link: str                 # the role's channel or stream: "robot", "fms-tcp"
    direction: str            # "in" / "out", as the role saw it
    kind: str                 # protocol/kinds.py: "ds-to-rio"
    data: bytes               # one datagram, or one whole TCP frame
    remote: Address | None    # (host, port) of the other end, None where a socket would not say
    local: Address | None     # (host, port) of the role's own socket
    time: float               # the runtime's clock when it went out or came in


#: A tap: called on the wire's thread with each record; it must return quickly.
Tap = Callable[[TapRecord], None]

#: TCP connections a server accepts at once, per server: bad input must not exhaust us.
MAX_CONNECTIONS = 64
#: Bytes a TCP connection may have queued for writing before it is dropped as stuck.
MAX_WRITE_BUFFER = 256 * 1024
#: The first polls of a runtime's roles are spread over this long (one 20 ms beat), so the
#: stations of a field do not all beat at the same instant and queue behind each other (a
#: DS's round trip then waited for every other pair's work). A DS and its robot beat
#: together (``RoleSpec.group``): one wake-up serves both, and each wake-up of a sleeping
#: process costs tens of microseconds of CPU on a virtual machine (docs/figures.md).
START_SPREAD = 0.020
#: How long a TCP connect may take (also how long a connect into a cut link takes to fail).
CONNECT_TIMEOUT = 2.0
#: When a core whose ``next_deadline`` raised is polled again, seconds.
RETRY_AFTER_ERROR = 0.02
#: How often a runtime on a thread of its own says it is alive (``Runtime.alive_at``).
HEARTBEAT = 0.05


@dataclass
class RoleSpec:
    """How to host one core: what to bind and how to name what crosses each link."""

    name: str
    core: Core
    udp: dict[str, Address] = field(default_factory=dict)        # channel -> bind address
    tcp_servers: dict[str, Address] = field(default_factory=dict)  # server -> bind address
    kinds: dict[tuple[str, str], str] = field(default_factory=dict)  # (link, "in"/"out") -> kind
    aliases: dict[str, str] = field(default_factory=dict)  # channel -> channel whose socket it shares
    #: Roles with the same group start polling at the same instant (a station's DS and robot).
    group: Hashable | None = None
    #: A fake roboRIO's robot code (what runs it): what its process sent is read here, before
    #: each of the core's events, and handed to the core's ``program_events``.
    code: CodeHost | None = None

    def kind(self, link: Hashable, direction: str) -> str:
        key = link[0] if isinstance(link, tuple) else link
        return self.kinds.get((str(key), direction), "")


def link_name(link: Hashable) -> str:
    return f"{link[0]}#{link[1]}" if isinstance(link, tuple) else str(link)


#: Linux's SO_TIMESTAMPNS (the kernel's receive time of each datagram, CLOCK_REALTIME);
#: Python's socket module does not name it.
SO_TIMESTAMPNS = 35
#: Datagrams read from one socket in one go, at most (the rest wait for the next turn).
MAX_DRAIN = 256
_TIMESPEC = struct.Struct("@ll")


class _Udp:
    """One bound UDP socket, read by the loop without asyncio's datagram transport.

    Each readiness drains the socket (up to :data:`MAX_DRAIN`) and says, for each datagram,
    when the kernel received it and whether a newer one from the same sender was already
    waiting behind it: a process that stalled (a loaded laptop, SIGSTOP) then finds its
    backlog marked old, and a core that takes arrivals (the fake roboRIO) obeys only the
    newest. Sends never wait: a full socket buffer drops the datagram (counted), as UDP may.
    """

    def __init__(self, host: "RoleHost", channel: str, sock: socket.socket) -> None:
        self.host = host
        self.channel = channel
        self.sock = sock
        self.closed = False
        self.stamped = _stamp(sock)
        self._anc = socket.CMSG_SPACE(_TIMESPEC.size) if self.stamped else 0
        self._drained_at = time.monotonic()

    def sendto(self, data: bytes, dest: Address) -> None:
        self.sock.sendto(data, dest)

    def is_closing(self) -> bool:
        return self.closed

    def close(self) -> None:
        if not self.closed:
            self.closed = True
            try:
                self.host.runtime.loop.remove_reader(self.sock.fileno())
            except Exception:  # the loop is already closed
                pass
            self.sock.close()

    def readable(self) -> None:
        batch = []
        mono, real = time.monotonic(), time.time()
        floor: float | None = self._drained_at  # nothing in this batch waited longer: the last drain emptied it
        for _ in range(MAX_DRAIN):
            try:
                data, anc, _flags, addr = self.sock.recvmsg(65535, self._anc)
            except (BlockingIOError, InterruptedError):
                break
            except OSError:
                # ICMP port unreachable on loopback when a peer is not up yet: normal, not fatal
                self.host.udp_errors += 1
                continue
            arrived = mono
            for level, kind, value in anc:
                if level == socket.SOL_SOCKET and kind == SO_TIMESTAMPNS and len(value) >= _TIMESPEC.size:
                    sec, nsec = _TIMESPEC.unpack_from(value)
                    # the kernel's wall-clock time, on the monotonic clock; a wall clock that was
                    # stepped cannot make a datagram older than the last drain, nor newer than now
                    arrived = min(mono, max(floor, mono - (real - (sec + nsec * 1e-9))))
            batch.append((data, (addr[0], addr[1]), arrived))
        else:
            floor = None  # the drain stopped at its bound: the next batch may hold older datagrams
        self._drained_at = mono if floor is not None else float("-inf")
        if batch:
            self.host.on_batch(self.channel, batch)


def _stamp(sock: socket.socket) -> bool:
    """Ask the kernel for each datagram's receive time; False where it cannot."""
    if not sys.platform.startswith("linux"):
        return False
    try:
        sock.setsockopt(socket.SOL_SOCKET, SO_TIMESTAMPNS, 1)
    except OSError:
        return False
    return True


class _Stream(asyncio.Protocol):
    def __init__(self, host: "RoleHost", conn: Hashable | None) -> None:
        self.host = host
        self.conn = conn
        self.transport: asyncio.Transport | None = None
        self.framer: FrameDecoder | None = None
        self.closed = False
        self.peer: Address | None = None
        self.local: Address | None = None

    def connection_made(self, transport) -> None:
        self.transport = transport
        # Both ends once, here: every tap of the stream carries them.
        self.peer = _name(transport.get_extra_info("peername"))
        self.local = _name(transport.get_extra_info("sockname"))
        if self.conn is None:  # accepted by a server
            self.conn = self.host.accept(self, self.peer)
            if self.conn is None:
                transport.abort()
                return
        else:
            self.host.connected(self, self.peer)

    def data_received(self, data: bytes) -> None:
        if self.conn is not None and not self.closed:
            self.host.on_stream_data(self, data)

    def connection_lost(self, exc) -> None:
        if self.conn is not None and not self.closed:
            self.closed = True
            self.host.on_stream_closed(self, "peer closed" if exc is None else str(exc))


def _name(sockaddr) -> Address | None:
    """A socket name as (host, port) (an IPv6 one has four parts)."""
    return (sockaddr[0], sockaddr[1]) if sockaddr else None


class RoleHost:
    """One core, its sockets and its timer."""

    def __init__(self, runtime: "Runtime", spec: RoleSpec) -> None:
        self.runtime = runtime
        self.spec = spec
        self.core = spec.core
        self.udp: dict[str, _Udp] = {}
        self.servers: dict[str, asyncio.base_events.Server] = {}
        self.streams: dict[Hashable, _Stream] = {}
        self.bound: dict[str, Address] = {}
        self._timer: asyncio.TimerHandle | None = None
        self._timer_at: float | None = None
        self._timers: _Timers | None = None  # the runtime's one timerfd, where there is one
        self.closed = False
        self.rank = next(runtime._ranks)  # due at the same moment, the host added first polls first
        self._next_conn = 0
        self.udp_errors = 0
        self.send_errors = 0
        self._resolved: dict[str, str | None] = {}
        self._literals: set[str] = set()  # hosts already seen to be IP addresses (parsed once)
        self._pumps: dict[tuple, asyncio.TimerHandle] = {}  # fault lines' timers, by flow

    # -- setup -----------------------------------------------------------------------
    async def bind(self) -> None:
        loop = self.runtime.loop
        for channel, addr in self.spec.udp.items():
            if channel in self.spec.aliases:
                continue
            sock = await _udp_socket(loop, addr)
            proto = _Udp(self, channel, sock)
            self.udp[channel] = proto
            loop.add_reader(sock.fileno(), proto.readable)
            name = sock.getsockname()
            self.bound[channel] = (name[0], name[1])
        for channel, target in self.spec.aliases.items():
            self.udp[channel] = self.udp[target]
            self.bound[channel] = self.bound[target]
        for name, addr in self.spec.tcp_servers.items():
            server = await loop.create_server(functools.partial(_ServerStream, self, name), addr[0], addr[1],
                                              reuse_address=True, backlog=16)
            self.servers[name] = server
            sock = server.sockets[0].getsockname()
            self.bound[name] = (sock[0], sock[1])
        self.runtime._local.update(self.bound.values())
        if self.runtime.clock is time.monotonic:
            self._timers = self.runtime.timers()

    async def close(self) -> None:
        try:
            self.core.shutdown()  # what a core has run outside itself (a robot program's process)
            if self.spec.code is not None:
                self.spec.code.shutdown()
        except Exception:
            log.exception("%s: shutdown failed", self.spec.name)
        self.closed = True  # polled no more: a stream's last callback may still reschedule
        if self._timer:
            self._timer.cancel()
        self._timer_at = None  # out of the runtime's timers (its entry there is stale)
        for flow, timer in self._pumps.items():
            timer.cancel()
            if self.runtime.faults is not None:
                self.runtime.faults.stream_closed(flow)
        self._pumps.clear()
        self.runtime._local.difference_update(self.bound.values())
        for stream in list(self.streams.values()):
            if stream.transport:
                stream.transport.abort()
        for proto in set(self.udp.values()):
            proto.close()
        for server in self.servers.values():
            server.close()
        for server in self.servers.values():
            try:
                await asyncio.wait_for(server.wait_closed(), 1.0)
            except (asyncio.TimeoutError, Exception):
                pass

    # -- arrivals ----------------------------------------------------------------------
    def on_batch(self, channel: str, batch: list[tuple[bytes, Address, float]]) -> None:
        """Datagrams drained from one socket at once: ``(data, source, arrived)``, oldest first."""
        last = {source: i for i, (_, source, _) in enumerate(batch)}  # each sender's newest
        for i, (data, source, arrived) in enumerate(batch):
            self.on_datagram(channel, data, source, arrived, superseded=last[source] != i)
        self.reschedule()

    def on_datagram(self, channel: str, data: bytes, source: Address, arrived: float | None = None,
                    superseded: bool = False) -> None:
        faults = self.runtime.faults
        if faults is not None and faults.any_active and not self.runtime.is_local(source):
            link = link_for_kind(self.spec.kind(channel, "in"))
            if faults.active(link):  # from a peer outside this process: fault it on arrival
                for delay, copy in faults.datagram(link, (self.spec.name, channel, source, "in"), data,
                                                   self.runtime.clock()):
                    if delay <= 0:
                        self._deliver_datagram(channel, copy, source, arrived, superseded)
                    else:  # a delay on the way: it arrives when it is delivered
                        self.runtime.loop.call_later(delay, self._deliver_late, channel, copy, source)
                return
        self._deliver_datagram(channel, data, source, arrived, superseded)

    def _deliver_late(self, channel: str, data: bytes, source: Address) -> None:
        if self.runtime.hosts.get(self.spec.name) is self:  # not removed while a fault delayed it
            self._deliver_datagram(channel, data, source)
            self.reschedule()

    def _deliver_datagram(self, channel: str, data: bytes, source: Address, arrived: float | None = None,
                          superseded: bool = False) -> None:
        now = self.runtime.clock()
        if self.runtime.taps:  # none, as headless without log files: no record made per datagram
            self.runtime.tap(self.spec.name, channel, "in", self.spec.kind(channel, "in"), data, source,
                             self.bound.get(channel), now)
        self.perform(self._call(self.core.datagram, channel, data, source, now,
                                now if arrived is None else arrived, superseded))

    def accept(self, stream: _Stream, peer) -> Hashable | None:
        server = stream.server_name  # type: ignore[attr-defined]
        if sum(1 for c in self.streams if isinstance(c, tuple) and c[0] == server) >= MAX_CONNECTIONS:
            log.warning("%s: refusing TCP connection from %s: %d already open", self.spec.name, peer,
                        MAX_CONNECTIONS)
            return None
        self._next_conn += 1
        conn = (server, self._next_conn)
        self.streams[conn] = stream
        stream.conn = conn
        self._opened(stream, peer)
        return conn

    def connected(self, stream: _Stream, peer) -> None:
        self.streams[stream.conn] = stream
        if stream.local:
            self.runtime._local.add(stream.local)
        self._opened(stream, peer)

    def _opened(self, stream: _Stream, peer) -> None:
        # Always framed for the taps, even with none yet: the inspector may attach later, and
        # a tap must see whole frames from the stream's start (TCP is low-rate: cheap).
        stream.framer = FrameDecoder(link_name(stream.conn))
        peer_addr = (peer[0], peer[1]) if peer else ("?", 0)
        self.perform(self._call(self.core.stream_opened, stream.conn, peer_addr, self.runtime.clock()))
        self.reschedule()

    def on_stream_data(self, stream: _Stream, data: bytes) -> None:
        faults = self.runtime.faults
        if faults is not None and faults.any_active and stream.peer is not None \
                and not self.runtime.is_local(stream.peer):
            flow = (self.spec.name, stream.conn, "in")
            link = link_for_kind(self.spec.kind(stream.conn, "in"))
            if faults.stream_involved(link, flow):  # from a peer outside this process
                if faults.stream_queued(flow) > MAX_WRITE_BUFFER:
                    self.close_stream(stream.conn, "too much data held by a fault")
                    return
                faults.stream_push(link, flow, data, self.runtime.clock())
                self.pump(stream.conn, "in")
                return
        self._deliver_stream(stream, data)

    def _deliver_stream(self, stream: _Stream, data: bytes) -> None:
        now = self.runtime.clock()
        if stream.framer is not None:
            try:
                for frame in stream.framer.feed(data):
                    self.runtime.tap(self.spec.name, link_name(stream.conn), "in",
                                     self.spec.kind(stream.conn, "in"), frame, stream.peer, stream.local, now)
            except ProtocolError:
                stream.framer = None  # the core will close it; stop tapping garbage
        self.perform(self._call(self.core.stream_data, stream.conn, data, now))
        self.reschedule()

    def on_stream_closed(self, stream: _Stream, reason: str) -> None:
        if self.streams.get(stream.conn) is stream:
            del self.streams[stream.conn]
        self._forget_stream(stream)
        self.perform(self._call(self.core.stream_closed, stream.conn, reason, self.runtime.clock()))
        self.reschedule()

    def _call(self, fn, *args):
        try:
            if self.spec.code is not None:  # what the robot program did since the last event, first
                self.spec.code.pump(self.runtime.clock())
            return fn(*args) or ()
        except Exception:  # a core bug must not take the field down: log it loudly
            log.exception("%s: %s failed", self.spec.name, getattr(fn, "__name__", fn))
            return ()

    # -- actions -----------------------------------------------------------------------
    def perform(self, actions) -> None:
        for action in actions:
            t = type(action)
            if t is Datagram:
                self.send_datagram(action)
            elif t is StreamSend:
                self.send_stream(action)
            elif t is Connect:
                self.connect(action)
            elif t is Close:
                self.close_stream(action.conn, action.reason)

    def send_datagram(self, action: Datagram) -> None:
        proto = self.udp.get(action.channel)
        if proto is None:
            self.send_errors += 1
            return
        dest = self._resolve(action.dest)
        if dest is None:
            self.send_errors += 1
            return
        kind = action.kind or self.spec.kind(action.channel, "out")
        faults = self.runtime.faults
        if faults is not None and faults.any_active:
            link = link_for_kind(kind)
            if faults.active(link):
                for delay, copy in faults.datagram(link, (self.spec.name, action.channel, dest), action.data,
                                                   self.runtime.clock()):
                    if delay <= 0:
                        self._sendto(proto, action.channel, copy, dest, kind)
                    else:
                        self.runtime.loop.call_later(delay, self._sendto, proto, action.channel, copy, dest, kind)
                return
        self._sendto(proto, action.channel, action.data, dest, kind)

    def _sendto(self, proto: _Udp, channel: str, data: bytes, dest: Address, kind: str) -> None:
        if proto.is_closing():
            self.send_errors += 1
            return
        try:
            proto.sendto(data, dest)
        except OSError:  # a full buffer (never waited for), an unreachable address
            self.send_errors += 1
            return
        if self.runtime.taps:
            self.runtime.tap(self.spec.name, channel, "out", kind, data, dest, self.bound.get(channel),
                             self.runtime.clock())

    def send_stream(self, action: StreamSend) -> None:
        stream = self.streams.get(action.conn)
        if stream is None or stream.transport is None or stream.closed:
            return
        kind = action.kind or self.spec.kind(action.conn, "out")
        faults = self.runtime.faults
        if faults is not None and faults.any_active:
            flow = (self.spec.name, action.conn, "out")
            link = link_for_kind(kind)
            if faults.stream_involved(link, flow):
                if faults.stream_queued(flow) > MAX_WRITE_BUFFER:  # held data is bounded too
                    log.warning("%s: %s: too much data held by a fault; dropping it", self.spec.name,
                                link_name(action.conn))
                    self.close_stream(action.conn, "too much data held by a fault")
                    return
                faults.stream_push(link, flow, action.data, self.runtime.clock())
                self.pump(action.conn, "out")
                return
        self._write(stream, action.conn, action.data, kind)

    def _write(self, stream: _Stream, conn: Hashable, data: bytes, kind: str) -> None:
        if stream.transport is None or stream.closed:
            return
        if stream.transport.get_write_buffer_size() > MAX_WRITE_BUFFER:
            log.warning("%s: %s is not reading; dropping it", self.spec.name, link_name(conn))
            self.close_stream(conn, "peer not reading")
            return
        stream.transport.write(data)
        if self.runtime.taps:
            now, name, ends = self.runtime.clock(), link_name(conn), (stream.peer, stream.local)
            # A core may write several frames at once; tap each.
            try:
                for frame in FrameDecoder().feed(data):
                    self.runtime.tap(self.spec.name, name, "out", kind, frame, *ends, now)
            except ProtocolError:
                self.runtime.tap(self.spec.name, name, "out", kind, data, *ends, now)

    def pump(self, conn: Hashable, direction: str) -> None:
        """Move what a fault line released for ``conn`` (``"out"``: to the socket, ``"in"``:
        to the core), and wake up again when the next write is due."""
        faults = self.runtime.faults
        flow = (self.spec.name, conn, direction)
        timer = self._pumps.pop(flow, None)
        if timer is not None:
            timer.cancel()
        if faults is None:
            return
        stream = self.streams.get(conn)
        if stream is None or stream.closed:
            faults.stream_closed(flow)
            return
        kind = self.spec.kind(conn, direction)
        for data in faults.stream_take(flow, self.runtime.clock()):
            if stream.closed:
                break
            if direction == "out":
                self._write(stream, conn, data, kind)
            else:
                self._deliver_stream(stream, data)
        if stream.closed:
            faults.stream_closed(flow)
            return
        deadline = faults.stream_deadline(flow)
        if deadline is not None:
            self._pumps[flow] = self.runtime.loop.call_at(deadline, self.pump, conn, direction)

    def _forget_stream(self, stream: _Stream) -> None:
        faults = self.runtime.faults
        for direction in ("out", "in"):
            flow = (self.spec.name, stream.conn, direction)
            timer = self._pumps.pop(flow, None)
            if timer is not None:
                timer.cancel()
            if faults is not None and faults.any_active:
                faults.stream_closed(flow)
        if stream.local and not isinstance(stream, _ServerStream):
            self.runtime._local.discard(stream.local)

    def connect(self, action: Connect) -> None:
        old = self.streams.get(action.conn)
        if old is not None and not old.closed:
            return
        faults = self.runtime.faults
        if faults is not None and not faults.connect_allowed(link_for_kind(self.spec.kind(action.conn, "out"))):
            # the cable is out: the SYN goes nowhere, the attempt times out
            self.runtime.loop.call_later(CONNECT_TIMEOUT, self._connect_failed, action.conn,
                                         "connect failed: timeout (link cut by a fault)")
            return
        self.runtime.loop.create_task(self._connect(action.conn, action.address))

    def _connect_failed(self, conn: Hashable, reason: str) -> None:
        if self.runtime.hosts.get(self.spec.name) is not self:
            return
        self.perform(self._call(self.core.stream_closed, conn, reason, self.runtime.clock()))
        self.reschedule()

    async def _connect(self, conn: Hashable, address: Address) -> None:
        dest = self._resolve(address)
        try:
            if dest is None:
                raise OSError(f"cannot resolve {address[0]}")
            await asyncio.wait_for(
                self.runtime.loop.create_connection(lambda: _Stream(self, conn), dest[0], dest[1],
                                                    local_addr=self._tcp_source(dest[0])),
                CONNECT_TIMEOUT)
        except (OSError, asyncio.TimeoutError) as exc:
            self.perform(self._call(self.core.stream_closed, conn, f"connect failed: {exc or 'timeout'}",
                                    self.runtime.clock()))
            self.reschedule()

    def _tcp_source(self, dest_host: str) -> Address | None:
        """Where this role's TCP connections leave from: in the loopback plan, its own 127.x
        address (as a real DS connects from its 10.TE.AM.5), so a peer sees one address for
        it on TCP and UDP (the FMS takes a station's status only from its DS's TCP login);
        the in-memory network does the same. Anywhere else the OS picks."""
        hosts = {addr[0] for addr in self.bound.values()}
        if len(hosts) != 1:
            return None
        host = hosts.pop()
        try:
            ours, theirs = ipaddress.ip_address(host), ipaddress.ip_address(dest_host)
        except ValueError:
            return None
        if ours.is_loopback and theirs.is_loopback and ours.version == theirs.version:
            return (host, 0)
        return None

    def close_stream(self, conn: Hashable, reason: str) -> None:
        stream = self.streams.pop(conn, None)
        if stream is None:
            return
        stream.closed = True
        self._forget_stream(stream)
        if stream.transport:
            stream.transport.abort()
        self.perform(self._call(self.core.stream_closed, conn, reason or "closed", self.runtime.clock()))

    def _resolve(self, address: Address) -> Address | None:
        host = address[0]
        if host in self._literals:  # every send passes here: 50 a second per peer
            return address
        try:
            ipaddress.ip_address(host)
            if len(self._literals) < 1024:
                self._literals.add(host)
            return address
        except ValueError:
            pass
        if host not in self._resolved:
            self._resolved[host] = None
            self.runtime.loop.create_task(self._lookup(host))
        ip = self._resolved.get(host)
        return (ip, address[1]) if ip else None

    def resolved(self, host: str) -> str | None:
        """The address a host name this role sends to resolved to (None: not yet, or not at all)."""
        return self._resolved.get(host)

    async def _lookup(self, host: str) -> None:
        try:
            infos = await asyncio.wait_for(self.runtime.loop.getaddrinfo(host, None, type=socket.SOCK_DGRAM), 5)
            self._resolved[host] = str(infos[0][4][0]) if infos else None  # (the address, a str)
        except (OSError, asyncio.TimeoutError):
            self._resolved[host] = None
        if self._resolved[host] is None:
            log.warning("%s: cannot resolve %s; will retry", self.spec.name, host)
            self.runtime.loop.call_later(5.0, self._resolved.pop, host, None)

    # -- time ----------------------------------------------------------------------------
    def reschedule(self) -> None:
        if self.closed:
            return
        try:
            deadline = self.core.next_deadline()
        except Exception:  # a core bug: logged, and asked again a beat later, never forgotten
            log.exception("%s: next_deadline failed", self.spec.name)
            deadline = self.runtime.clock() + RETRY_AFTER_ERROR
        if deadline is None:
            if self._timer:
                self._timer.cancel()
                self._timer = None
            self._timer_at = None  # an entry in the runtime's timers is now stale
            return
        if self._timer_at == deadline:
            return
        self._timer_at = deadline
        if self._timers is not None:  # to the microsecond, on the runtime's one timerfd
            self._timers.add(self, deadline)
            return
        if self._timer:
            self._timer.cancel()
        self._timer = self.runtime.loop.call_at(deadline, self._on_timer)

    def _on_timer(self) -> None:
        self._timer = None
        self._timer_at = None
        self.perform(self._call(self.core.poll, self.runtime.clock()))
        self.reschedule()

    def kick(self, now: float | None = None) -> None:
        """Poll now (after a command changed the core's state)."""
        self.perform(self._call(self.core.poll, self.runtime.clock() if now is None else now))
        self.reschedule()


class _ServerStream(_Stream):
    def __init__(self, host: RoleHost, server_name: str) -> None:
        super().__init__(host, None)
        self.server_name = server_name


class _Alarm:
    """A one-shot Linux timerfd watched by the loop: wakes it at an absolute
    ``time.monotonic()`` deadline to the microsecond.

    asyncio's own timers wait in ``epoll_wait``, whose timeout is whole milliseconds rounded
    up: a 20 ms beat on ``loop.call_at`` fired 0-2 ms late (median 1 ms), and the intervals a
    roboRIO saw had a median of 20.3 ms and a p99 of 21.5 ms. A timerfd readable at the
    deadline wakes the same ``epoll_wait`` at once. Elsewhere (or with an injected clock)
    the host keeps ``loop.call_at``.

    Its calls keep the GIL (``ctypes.PyDLL``, no ``os.read``): they take microseconds, and
    under the app every call that lets the GIL go costs the wire up to a switch interval to
    get it back from the drawing thread.
    """

    _api: Any = None  # (timerfd_create, timerfd_settime, itimerspec type) once loaded; False: none

    def __init__(self, loop: asyncio.AbstractEventLoop, fd: int, callback: Callable[[], None]) -> None:
        self.loop = loop
        self.fd = fd
        self.callback = callback
        self.spec = self._api[2]()
        self.deadline = math.inf
        self._armed = False  # armed again since it last fired
        loop.add_reader(fd, self._fired)

    @classmethod
    def _load(cls) -> Any:
        if cls._api is None:
            cls._api = False
            if sys.platform.startswith("linux"):
                try:
                    import ctypes

                    class timespec(ctypes.Structure):
                        _fields_ = [("tv_sec", ctypes.c_long), ("tv_nsec", ctypes.c_long)]

                    class itimerspec(ctypes.Structure):
                        _fields_ = [("it_interval", timespec), ("it_value", timespec)]

                    libc = ctypes.PyDLL(None, use_errno=True)
                    create, settime = libc.timerfd_create, libc.timerfd_settime
                    create.argtypes = [ctypes.c_int, ctypes.c_int]
                    settime.argtypes = [ctypes.c_int, ctypes.c_int, ctypes.POINTER(itimerspec), ctypes.c_void_p]
                    cls._api = (create, settime, itimerspec)
                except (ImportError, OSError, AttributeError):
                    cls._api = False
        return cls._api

    @classmethod
    def create(cls, loop: asyncio.AbstractEventLoop, callback: Callable[[], None]) -> "_Alarm | None":
        api = cls._load()
        if not api:
            return None
        fd = api[0](1, os.O_NONBLOCK | os.O_CLOEXEC)  # CLOCK_MONOTONIC, TFD_NONBLOCK | TFD_CLOEXEC
        if fd < 0:
            return None
        try:
            return cls(loop, fd, callback)
        except Exception:  # a loop without add_reader (Windows' proactor): keep call_at
            os.close(fd)
            return None

    def arm(self, deadline: float) -> "_Alarm":
        if not deadline < math.inf:  # never (or not a number): as loop.call_at(inf) would
            self.cancel()
            return self
        # ns rounded up (never early) and at least 1 ns: an all-zero time would disarm
        ns = max(1, math.ceil(deadline * 1e9)) if deadline > 0 else 1
        value = self.spec.it_value
        value.tv_sec, value.tv_nsec = divmod(ns, 1_000_000_000)
        self._api[1](self.fd, 1, self.spec, None)  # TFD_TIMER_ABSTIME; also makes it unreadable
        self.deadline = deadline
        self._armed = True
        return self

    def cancel(self) -> None:
        value = self.spec.it_value
        value.tv_sec = value.tv_nsec = 0
        self._api[1](self.fd, 1, self.spec, None)
        self.deadline = math.inf

    def _fired(self) -> None:
        if time.monotonic() < self.deadline - 1e-6:  # re-armed or cancelled since it became readable
            return
        self._armed = False
        self.callback()  # arms the next deadline, which also makes the timerfd unreadable
        if not self._armed:
            self.cancel()  # unreadable again without a read()

    def close(self) -> None:
        if self.fd >= 0:
            try:
                self.loop.remove_reader(self.fd)
            except Exception:  # the loop is already closed
                pass
            os.close(self.fd)
            self.fd = -1


class _Timers:
    """Every host's next deadline, on one :class:`_Alarm` per runtime.

    The hosts due at one moment are polled in one wake-up, the host added first polling
    first: a station's robot (its program's beat) and then its DS (its control packet), whose
    grids start at the same instant (:meth:`Runtime.start`). Each wake-up of a sleeping
    process costs CPU, on a virtual machine tens of microseconds and cold caches
    (docs/figures.md): a timerfd per host woke the wire twice a station each beat.
    A deadline that moved is left in the heap and skipped when it comes up.
    """

    def __init__(self, alarm: _Alarm) -> None:
        self.alarm = alarm
        self.heap: list[tuple[float, int, RoleHost]] = []

    def add(self, host: RoleHost, deadline: float) -> None:
        heap = self.heap
        heapq.heappush(heap, (deadline, host.rank, host))
        if len(heap) > 64 + 8 * len(host.runtime.hosts):  # deadlines that moved, dropped now and then
            heap[:] = [entry for entry in heap if entry[2]._timer_at == entry[0]]  # in place: fired() holds it
            heapq.heapify(heap)
        if deadline < self.alarm.deadline:
            self.alarm.arm(deadline)

    def fired(self) -> None:
        heap = self.heap
        now = time.monotonic()
        due = []
        while heap and heap[0][0] <= now:
            entry = heapq.heappop(heap)
            if entry[2]._timer_at == entry[0]:
                due.append(entry[2])
        for host in due:  # a deadline due again at once waits for the next turn of the loop
            if host._timer_at is not None and host._timer_at <= now:
                try:
                    host._on_timer()
                except Exception:  # a bug in one role must not stop the others' timers
                    log.exception("%s: its timer failed", host.spec.name)
                    host._timer_at = None
                    host.reschedule()
        while heap and heap[0][2]._timer_at != heap[0][0]:
            heapq.heappop(heap)
        if heap:
            self.alarm.arm(heap[0][0])

    def close(self) -> None:
        self.heap.clear()
        self.alarm.close()


async def _udp_socket(loop: asyncio.AbstractEventLoop, addr: Address) -> socket.socket:
    """A non-blocking UDP socket bound to ``addr`` (a name is looked up first)."""
    family = _family(addr[0])
    infos = await loop.getaddrinfo(addr[0], addr[1], family=family, type=socket.SOCK_DGRAM,
                                   flags=socket.AI_PASSIVE)
    if not infos:
        raise OSError(f"cannot resolve {addr[0]}")
    fam, kind, proto, _, sockaddr = infos[0]
    sock = socket.socket(fam, kind, proto)
    try:
        sock.setblocking(False)
        sock.bind(sockaddr)
    except OSError:
        sock.close()
        raise
    return sock


def _family(host: str) -> int:
    try:
        return socket.AF_INET6 if ipaddress.ip_address(host).version == 6 else socket.AF_INET
    except ValueError:
        return socket.AF_UNSPEC


class Runtime:
    """Any number of role hosts on one event loop, optionally on a thread of its own."""

    def __init__(self, clock: Callable[[], float] = time.monotonic) -> None:
        self.clock = clock
        self.hosts: dict[str, RoleHost] = {}
        self.taps: list[Tap] = []
        # None until start(): typed as set, as the role hosts and timers that use it exist only after.
        self.loop: asyncio.AbstractEventLoop = None  # type: ignore[assignment]
        self._thread: threading.Thread | None = None
        self._stopped: asyncio.Event | None = None
        self._faults = None
        self._local: set[Address] = set()  # every address a socket of this runtime has
        self._ranks = itertools.count()
        self._timers: _Timers | None = None
        #: When the loop last ran (a heartbeat of :data:`HEARTBEAT`): how old what a reader
        #: on another thread sees may be.
        self.alive_at = clock()
        #: Other servers on the loop, each with an async ``close()`` (the DS's robot-address
        #: service, roles/runtime/ds_ip_server.py): closed with the runtime.
        self.services: list[Any] = []

    # -- faults on purpose -----------------------------------------------------------------
    @property
    def faults(self):
        """A :class:`roles.sim.faults.Faults` every send consults, or None. Change it on the
        wire's side (``Runtime.call``): a cut's end releases held TCP data at once."""
        return self._faults

    @faults.setter
    def faults(self, faults) -> None:
        if self._faults is not None and self._faults_changed in self._faults.listeners:
            self._faults.listeners.remove(self._faults_changed)
        self._faults = faults
        if faults is not None:
            faults.listeners.append(self._faults_changed)

    def _faults_changed(self) -> None:
        if self.loop is None:
            return
        if self._thread is not None and threading.current_thread() is not self._thread:
            self.loop.call_soon_threadsafe(self._pump_all)
        else:
            self._pump_all()

    def _pump_all(self) -> None:
        faults = self._faults
        if faults is None:
            return
        for flow in faults.waiting_flows():
            host = self.hosts.get(flow[0])
            if host is None:
                faults.stream_closed(flow)
            else:
                host.pump(flow[1], flow[2])

    def timers(self) -> _Timers | None:
        """The runtime's one timerfd for its hosts' deadlines (None where Linux's timerfd is
        not to be had: each host then keeps ``loop.call_at``)."""
        if self._timers is None or self._timers.alarm.fd < 0:
            self._timers = None
            holder: list[_Timers] = []
            alarm = _Alarm.create(self.loop, lambda: holder[0].fired())
            if alarm is not None:
                self._timers = _Timers(alarm)
                holder.append(self._timers)
        return self._timers

    def is_local(self, address) -> bool:
        """Whether ``address`` is a socket of this runtime (a packet between two of our own
        roles is faulted once, when sent)."""
        try:
            key = (address[0], address[1])
        except (TypeError, IndexError):
            return False
        local = self._local
        return key in local or ("0.0.0.0", key[1]) in local or ("::", key[1]) in local

    def tap(self, role: str, link: str, direction: str, kind: str, data: bytes, remote, local,
            now: float) -> None:
        record = TapRecord(role, link, direction, kind, data, remote, local, now)
        for tap in self.taps:
            try:
                tap(record)
            except Exception:
                log.exception("tap failed")

    async def add(self, spec: RoleSpec) -> RoleHost:
        """Bind a role's sockets (on the running loop). Raises OSError if a bind fails."""
        if self.loop is None:
            self.loop = asyncio.get_running_loop()
        host = RoleHost(self, spec)
        try:
            await host.bind()
        except OSError:
            await host.close()
            raise
        self.hosts[spec.name] = host
        return host

    def start(self) -> None:
        """Begin polling every core (call on the loop, after ``add``): the first group at
        once, the others spread over :data:`START_SPREAD`. A group's roles are first polled
        at one instant (their grids start together), in the order they were added: a
        station's robot beats, then its DS sends."""
        groups: dict[Hashable, list[RoleHost]] = {}
        for host in self.hosts.values():
            groups.setdefault(host.spec.name if host.spec.group is None else host.spec.group, []).append(host)
        ordered = list(groups.values())
        if not ordered:
            return
        self._first_poll(ordered[0])
        t0 = self.loop.time()
        for i, hosts in enumerate(ordered[1:], 1):
            self.loop.call_at(t0 + i * START_SPREAD / len(ordered), self._first_poll, hosts)

    def _first_poll(self, hosts: list[RoleHost]) -> None:
        now = self.clock()
        for host in hosts:
            if self.hosts.get(host.spec.name) is host:  # not removed meanwhile
                host.kick(now)

    async def remove(self, name: str) -> None:
        host = self.hosts.pop(name, None)
        if host:
            await host.close()

    async def close(self) -> None:
        for name in list(self.hosts):
            await self.remove(name)
        services, self.services = self.services, []
        for service in services:
            await service.close()
        if self._timers is not None:
            self._timers.close()
            self._timers = None

    # -- thread mode -----------------------------------------------------------------------
    def start_thread(self, setup: Callable[["Runtime"], Any]) -> None:
        """Run the wire on a thread of its own; ``setup`` is an async function of this
        runtime that adds roles. Returns once setup finished (re-raising its error)."""
        ready: Future = Future()

        def main() -> None:
            loop = asyncio.new_event_loop()
            self.loop = loop
            asyncio.set_event_loop(loop)
            self._stopped = stopped = asyncio.Event()

            async def boot() -> None:
                try:
                    await setup(self)
                    self.start()
                    self._heartbeat()
                except BaseException as exc:  # noqa: BLE001 - handed to the caller
                    ready.set_exception(exc)
                    return
                ready.set_result(None)
                await stopped.wait()
                await self.close()

            try:
                loop.run_until_complete(boot())
            finally:
                loop.close()

        self._thread = threading.Thread(target=main, name="fieldbox-wire", daemon=True)
        self._thread.start()
        try:
            ready.result()
        except BaseException:
            self.stop_thread()
            raise

    def _heartbeat(self) -> None:
        self.alive_at = self.clock()
        if self.loop is not None and not self.loop.is_closed():
            self.loop.call_later(HEARTBEAT, self._heartbeat)

    def call(self, fn: Callable[[], Any], host: str | None = None) -> Future:
        """Run ``fn`` on the wire's loop (from any thread); then poll ``host`` at once."""
        result: Future = Future()

        def run() -> None:
            try:
                value = fn()
            except BaseException as exc:  # noqa: BLE001 - handed to the caller
                result.set_exception(exc)
            else:
                result.set_result(value)
            if host is not None and host in self.hosts:
                self.hosts[host].kick()

        if self._thread is not None and threading.current_thread() is not self._thread:
            assert self.loop is not None
            self.loop.call_soon_threadsafe(run)
        else:
            run()
        return result

    def stop_thread(self, timeout: float = 3.0) -> None:
        if self._thread is None:
            return
        if self.loop is not None and self._stopped is not None:
            try:
                self.loop.call_soon_threadsafe(self._stopped.set)
            except RuntimeError:  # the loop already ended (setup failed)
                pass
        self._thread.join(timeout)
        self._thread = None

