"""Sockets for a conformance run: UDP ports and framed TCP streams that keep what crossed
them, with arrival times, in bounded buffers.

A conformance check judges the peer by the rules, so it sees every byte as it came (no role
core in between to cope with it). Whatever a peer sends, these never grow without bound:
datagrams and frames are kept in rings (of :data:`MAX_KEPT_BYTES` at most: a peer sending 64 KB
datagrams keeps the newest few hundred), a TCP frame above ``max_frame`` ends that stream (a
framing error is a finding, kept with the bytes before it), a frame begun and not finished is
timed (a peer that drips or never ends a frame is a finding too), and a server takes at most
``max_connections`` at once.
"""

from __future__ import annotations

import asyncio
import socket
import time
from collections import deque
from dataclasses import dataclass
from typing import Awaitable, Callable

from protocol.errors import ProtocolError
from protocol.framing import FrameDecoder

Address = tuple[str, int]

#: Datagrams kept per port: 400 s at 50 Hz, longer than any role's cases run.
MAX_DATAGRAMS = 20_000
#: Bytes of datagrams kept per port (the newest): real ones are a few hundred bytes, so only a
#: peer sending huge ones reaches it.
MAX_KEPT_BYTES = 32 * 1024 * 1024
#: Frames kept per TCP stream.
MAX_FRAMES = 5_000
#: The largest TCP frame taken: every real frame is a few KiB at most (an error with a call stack).
MAX_FRAME = 0x8000


@dataclass(frozen=True, slots=True)
class Arrival:
    at: float  # time.monotonic() when it came
    data: bytes
    source: Address


class UdpPort(asyncio.DatagramProtocol):
    """A bound UDP socket that keeps every datagram it receives (the newest MAX_DATAGRAMS)."""

    def __init__(self, name: str) -> None:
        self.name = name
        self.received: deque[Arrival] = deque(maxlen=MAX_DATAGRAMS)
        self.kept_bytes = 0  # of the datagrams in ``received``
        self.total = 0
        self.transport: asyncio.DatagramTransport | None = None
        self.errors: deque[str] = deque(maxlen=20)
        self.listeners: list[Callable[[Arrival], None]] = []

    @classmethod
    async def open(cls, name: str, host: str, port: int) -> "UdpPort":
        loop = asyncio.get_running_loop()
        sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        try:
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
            sock.bind((host, port))
        except OSError:
            sock.close()
            raise
        sock.setblocking(False)
        _, proto = await loop.create_datagram_endpoint(lambda: cls(name), sock=sock)
        return proto

    @property
    def address(self) -> Address:
        assert self.transport is not None
        host, port = self.transport.get_extra_info("sockname")[:2]
        return host, port

    def connection_made(self, transport: asyncio.BaseTransport) -> None:
        self.transport = transport  # type: ignore[assignment]

    def datagram_received(self, data: bytes, addr: tuple) -> None:
        arrival = Arrival(time.monotonic(), bytes(data), (str(addr[0]), int(addr[1])))
        ring = self.received
        if len(ring) == ring.maxlen:
            self.kept_bytes -= len(ring[0].data)
        ring.append(arrival)
        self.kept_bytes += len(arrival.data)
        while self.kept_bytes > MAX_KEPT_BYTES and len(ring) > 1:
            self.kept_bytes -= len(ring.popleft().data)
        self.total += 1
        for listener in self.listeners:
            listener(arrival)

    def error_received(self, exc: Exception) -> None:
        self.errors.append(f"{type(exc).__name__}: {exc}")

    def send(self, data: bytes, dest: Address) -> None:
        if self.transport is not None and not self.transport.is_closing():
            self.transport.sendto(data, dest)

    def since(self, t: float) -> list[Arrival]:
        return [a for a in self.received if a.at >= t]

    def close(self) -> None:
        if self.transport is not None:
            self.transport.close()


@dataclass(frozen=True, slots=True)
class Frame:
    at: float
    data: bytes  # one whole frame, its u16 size included


class FrameStream:
    """One TCP connection read as frames (``[u16 size][id][payload]``), every frame kept."""

    def __init__(self, name: str, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        self.name = name
        self.reader = reader
        self.writer = writer
        peer = writer.get_extra_info("peername") or ("?", 0)
        local = writer.get_extra_info("sockname") or ("?", 0)
        self.peer: Address = (str(peer[0]), int(peer[1]))
        self.local: Address = (str(local[0]), int(local[1]))
        self.opened = time.monotonic()
        self.frames: deque[Frame] = deque(maxlen=MAX_FRAMES)
        self.total = 0
        self.bytes_in = 0
        self.decoder = FrameDecoder(name, MAX_FRAME)
        #: When the first byte of the frame not yet finished came (None: none pending), and the
        #: longest a frame took from its first byte to its last.
        self.partial_since: float | None = None
        self.slowest_frame = 0.0
        self.error: ProtocolError | None = None
        self.error_at: float | None = None
        self.closed_at: float | None = None
        self.close_reason = ""
        self.listeners: list[Callable[[Frame], None]] = []
        self._task = asyncio.get_running_loop().create_task(self._read())

    async def _read(self) -> None:
        try:
            while True:
                chunk = await self.reader.read(65536)
                if not chunk:
                    self._closed("closed by the peer")
                    return
                self.bytes_in += len(chunk)
                frames, error = self.decoder.feed_until_error(chunk)
                now = time.monotonic()
                if frames:  # the frame pending before this chunk (if any) is whole now
                    if self.partial_since is not None:
                        self.slowest_frame = max(self.slowest_frame, now - self.partial_since)
                    self.partial_since = None
                if self.decoder.buffered and self.partial_since is None:
                    self.partial_since = now
                for data in frames:
                    frame = Frame(now, data)
                    self.frames.append(frame)
                    self.total += 1
                    for listener in self.listeners:
                        listener(frame)
                if error is not None:
                    self.error, self.error_at = error, now
                    self.close(f"framing error: {error}")
                    return
        except (ConnectionError, OSError) as exc:
            self._closed(f"{type(exc).__name__}: {exc}")
        except asyncio.CancelledError:
            self._closed("closed by fieldbox")
            raise

    def _closed(self, reason: str) -> None:
        if self.closed_at is None:
            self.closed_at = time.monotonic()
            self.close_reason = reason

    @property
    def is_open(self) -> bool:
        return self.closed_at is None

    def unfinished(self) -> tuple[int, float] | None:
        """(bytes held, seconds since its first byte came, to the close or now) of a frame
        begun and not finished; None if there is none (or the stream broke on a bad size)."""
        if self.partial_since is None or self.error is not None or not self.decoder.buffered:
            return None
        end = self.closed_at if self.closed_at is not None else time.monotonic()
        return self.decoder.buffered, max(0.0, end - self.partial_since)

    def send(self, data: bytes) -> bool:
        if self.closed_at is not None or self.writer.is_closing():
            return False
        try:
            self.writer.write(data)
        except (ConnectionError, OSError, RuntimeError):
            return False
        return True

    def close(self, reason: str = "closed by fieldbox") -> None:
        self._closed(reason)
        try:
            self.writer.close()
        except (ConnectionError, OSError, RuntimeError):
            pass
        if not self._task.done() and asyncio.current_task() is not self._task:
            self._task.cancel()

    async def wait_closed(self) -> None:
        self.close()
        await asyncio.gather(self._task, return_exceptions=True)


async def connect(name: str, address: Address, *, local_host: str | None = None,
                  timeout: float = 2.0) -> FrameStream:
    """A TCP connection to ``address`` (from ``local_host`` when given), read as frames.
    Raises OSError (or asyncio.TimeoutError) when it cannot be opened."""
    local = (local_host, 0) if local_host else None
    reader, writer = await asyncio.wait_for(
        asyncio.open_connection(address[0], address[1], local_addr=local, limit=MAX_FRAME * 2), timeout)
    return FrameStream(name, reader, writer)


class FrameServer:
    """A TCP server whose connections are FrameStreams (at most ``max_connections`` open)."""

    def __init__(self, name: str, max_connections: int = 16,
                 on_open: Callable[[FrameStream], Awaitable[None] | None] | None = None) -> None:
        self.name = name
        self.max_connections = max_connections
        self.streams: list[FrameStream] = []
        self.refused = 0
        self.on_open = on_open
        self.server: asyncio.AbstractServer | None = None

    async def start(self, host: str, port: int) -> None:
        self.server = await asyncio.start_server(self._accepted, host, port, reuse_address=True,
                                                 limit=MAX_FRAME * 2)

    async def _accepted(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        if sum(1 for s in self.streams if s.is_open) >= self.max_connections:
            self.refused += 1
            writer.close()
            return
        stream = FrameStream(f"{self.name} #{len(self.streams) + 1}", reader, writer)
        self.streams.append(stream)
        del self.streams[:-64]  # the newest connections only: a peer reconnecting forever stays bounded
        if self.on_open is not None:
            outcome = self.on_open(stream)
            if asyncio.iscoroutine(outcome):
                await outcome

    def open_streams(self) -> list[FrameStream]:
        return [s for s in self.streams if s.is_open]

    async def close(self) -> None:
        if self.server is not None:
            self.server.close()
        for s in self.streams:
            s.close()
        await asyncio.gather(*(s.wait_closed() for s in self.streams), return_exceptions=True)


async def resolve(host: str) -> str:
    """The IPv4 address of ``host`` (a name like roboRIO-254-FRC.local, or an address), looked
    up once: datagrams go to it, and what comes back is matched to it. OSError if unknown."""
    try:
        socket.inet_aton(host)
        return host
    except OSError:
        pass
    infos = await asyncio.get_running_loop().getaddrinfo(host, None, family=socket.AF_INET,
                                                           type=socket.SOCK_DGRAM)
    if not infos:
        raise OSError(f"no IPv4 address for {host}")
    return str(infos[0][4][0])


async def until(check: Callable[[], object], timeout: float, step: float = 0.01) -> bool:
    """Poll ``check`` until it is true or ``timeout`` seconds pass; whether it came true."""
    deadline = time.monotonic() + timeout
    while True:
        if check():
            return True
        if time.monotonic() >= deadline:
            return False
        await asyncio.sleep(step)
