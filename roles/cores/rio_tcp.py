"""The fake roboRIO's TCP side (port 1740): the DS's connections and what goes out on them.

Each connection gets one :class:`~protocol.framing.FrameDecoder` and, on opening, the version
list, the fault counters and the console backlog. The console (program output, warnings,
errors) goes to every client as it is written; fault counters when they move; a usage report
every ``usage_interval``. What the DS sends (descriptors, match info, game data) is handed back
to the Rio, which gives it to the robot program's inputs.

Clients are bounded (``max_clients``, and half of that from any one host); with every slot
taken, a newcomer evicts the oldest client that never sent a valid frame, else one silent for
over :data:`CLIENT_IDLE_EVICT`, else is refused; the host of the DS followed on UDP is always
served.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Callable, Hashable

from protocol import ds_to_rio, rio_to_ds
from protocol.enums import DeviceType
from protocol.framing import FrameDecoder
from protocol.rio_to_ds import DisableFaults, ErrorMessage, RailFaults, StdoutMessage, UsageReport, VersionInfo

from .core import Action, Address, Close, Events, Grid, LinkStats, Stream, StreamSend, Throttle, decode_frames
from .robot_program import MAX_TEXT
from .views import ConsoleLine

if TYPE_CHECKING:
    from .rio import RioFaults

# A program that prints in a tight loop must not flood the DS: messages past this many in
# one 20 ms beat are counted and dropped (with one warning saying so).
MAX_MESSAGES_PER_BEAT = 50
# The DS sends small frames (descriptors, match info, game data); a larger size field is a
# broken or hostile peer, closed at once rather than buffered.
MAX_DS_FRAME = 8192
# With every TCP slot taken, a newcomer evicts a client that never sent a valid frame (the
# oldest first), else one silent for longer than this (a DS that sent nothing new for a while
# is normal, so the bar is high): idle or half-sent connections cannot lock a DS out.
CLIENT_IDLE_EVICT = 5.0


@dataclass(slots=True)
class _Client:
    decoder: FrameDecoder
    opened: float
    host: str | None
    valid: float | None = None  # when it last sent a valid frame (a keep-alive too)


class TcpClients:
    """The DS connections on TCP 1740, the console and the frames sent on them."""

    def __init__(self, *, max_clients: int, usage_interval: float, image_version: str, lib_version: str,
                 console_size: int, backlog: int, kind: str, events: Events, faults: RioFaults,
                 link: LinkStats) -> None:
        self.max_clients = max_clients
        self.usage_interval = usage_interval
        self.image_version = image_version
        self.lib_version = lib_version
        self.kind = kind  # the protocol kind of what is sent, for captures
        self.events = events
        self.faults = faults
        self.link = link  # rio-tcp
        self.console: Stream[ConsoleLine] = Stream(console_size)
        self.outbox: list[Action] = []  # sends not yet handed to the shell
        self.wake_at: float | None = None  # when the first of them was queued
        self._clients: dict[Hashable, _Client] = {}
        self._log = Throttle()  # refused and evicted clients: logged once a second
        self._beat_messages = 0
        self._backlog: deque[bytes] = deque(maxlen=backlog)
        self.power_on()

    def power_on(self) -> None:
        """What a reboot forgets: the console backlog and sequence, the counters last sent."""
        self._backlog = deque(maxlen=self._backlog.maxlen)
        self._seq = 0
        self._sent_disable: tuple[int, int] | None = None
        self._sent_rails: tuple[int, int, int] | None = None
        self._usage: Grid | None = None  # usage reports, while a client is connected

    @property
    def count(self) -> int:
        return len(self._clients)

    @property
    def connections(self) -> dict[Hashable, str | None]:
        """Each client connected, with its peer's host."""
        return {conn: client.host for conn, client in self._clients.items()}

    def deadline(self) -> float | None:
        """When the next usage report is due (None: no client)."""
        return self._usage.next if self._clients and self._usage is not None else None

    # -- what goes out -------------------------------------------------------------------
    def queue(self, actions: list[Action], now: float) -> None:
        if actions:
            self.outbox.extend(actions)
            self.wake_at = now if self.wake_at is None else min(self.wake_at, now)

    def take(self) -> list[Action]:
        out, self.outbox = self.outbox, []
        self.wake_at = None
        return out

    def _send(self, conn: Hashable, frame: bytes) -> StreamSend:
        self.link.sent(len(frame))
        return StreamSend(conn, frame, self.kind)

    def _broadcast(self, frame: bytes, now: float) -> None:
        if self._clients:
            self.queue([self._send(conn, frame) for conn in self._clients], now)

    def new_beat(self) -> None:
        self._beat_messages = 0

    def write(self, kind: str, text: str, code: int, location: str, call_stack: str, bounded: bool,
              now: float, stamp: float) -> tuple[str, str] | None:
        """A console line or a diagnostic: kept in ``console``, sent to every client, stdout
        and errors sharing one sequence counter; ``stamp``: seconds since boot. Returns the
        line as written (kind, text), or None when the per-beat bound dropped it."""
        self._beat_messages += bounded
        if bounded and self._beat_messages > MAX_MESSAGES_PER_BEAT:
            self.faults.console_dropped += 1
            if self._beat_messages != MAX_MESSAGES_PER_BEAT + 1:
                return None
            kind, text, code, location, call_stack = (
                "warning", f"more than {MAX_MESSAGES_PER_BEAT} console messages in one 20 ms loop: "
                           "the rest of this loop's messages are dropped", 0, "", "")
        seq = self._seq
        self._seq = (seq + 1) & 0xFFFF
        text = _safe_text(text)
        if kind == "stdout":
            frame = StdoutMessage(stamp, seq, text).encode()
        else:
            frame = ErrorMessage(stamp, seq, 1, max(-0x80000000, min(0x7FFFFFFF, int(code))), kind == "error",
                                 False, text, _safe_text(location), _safe_text(call_stack)).encode()
        self.console.append(ConsoleLine(now, kind, text.rstrip("\n"), seq))
        self._backlog.append(frame)
        self._broadcast(frame, now)
        return kind, text

    def _counts(self) -> tuple[tuple[int, int], tuple[int, int, int]]:
        """The disable counts (frame 0x04) and the rail fault counts (0x05), as sent."""
        f = self.faults
        return ((min(f.comms, 0xFFFF), min(f.rail_12v, 0xFFFF)),
                (min(f.rail_6v, 0xFFFF), min(f.rail_5v, 0xFFFF), min(f.rail_3v3, 0xFFFF)))

    def housekeeping(self, now: float, team: int) -> None:
        """Fault counters to every client when they move; the usage report when it is due."""
        disable, rails = self._counts()
        if disable != self._sent_disable:
            if self._sent_disable is not None:
                self._broadcast(DisableFaults(*disable).encode(), now)
            self._sent_disable = disable
        if rails != self._sent_rails:
            if self._sent_rails is not None:
                self._broadcast(RailFaults(*rails).encode(), now)
            self._sent_rails = rails
        if not self._clients:
            self._usage = None
        elif self._usage is not None and self._usage.take(now) is not None:
            self._broadcast(UsageReport(min(max(team, 0), 0xFFFF), 0, b"").encode(), now)

    # -- the shell's events ----------------------------------------------------------------
    def open(self, conn: Hashable, peer: Address | None, now: float, ds_host: str | None) -> list[Action]:
        """A DS connects (``ds_host``: the host of the DS followed on UDP, always served)."""
        out: list[Action] = []
        if conn in self._clients:
            return out
        host = str(peer[0]) if peer else None
        # One host (a stray program, a scan) never holds more than half the slots; the host of
        # the DS followed on UDP is not held to that.
        per_host = max(1, self.max_clients // 2)
        limited = host is not None and host != ds_host

        def from_host() -> list[Hashable]:
            return [c for c, client in self._clients.items() if client.host == host]

        if limited and len(from_host()) >= per_host:
            out.extend(self._evict_for(now, host, ds_host, from_host()))
        if len(self._clients) >= self.max_clients:
            out.extend(self._evict_for(now, host, ds_host))
        over = limited and len(from_host()) >= per_host
        if len(self._clients) >= self.max_clients or over:
            self.faults.refused_clients += 1
            limit = f"{per_host} already connected from {host}" if over else f"{self.max_clients} already connected"
            held = self._log.due("refused", now)
            if held is not None:
                self.events.add(now, f"TCP: refused a client from {host}, {limit}{Throttle.suffix(held)}")
            out.append(Close(conn, f"too many clients ({limit})"))
            return out
        self._clients[conn] = _Client(FrameDecoder(ds_to_rio.TCP, MAX_DS_FRAME), now, host)
        self.link.connected = True
        where = f" from {peer[0]}:{peer[1]}" if peer else ""
        self.events.add(now, f"TCP: DS connected{where}")
        disable, rails = self._counts()
        frames = [
            VersionInfo(DeviceType.SOFTWARE, 0, 0, "roboRIO Image", self.image_version).encode(),
            VersionInfo(DeviceType.SOFTWARE, 0, 0, "FRC_Lib_Version", self.lib_version).encode(),
            rio_to_ds.END_OF_VERSION_LIST.encode(),
            DisableFaults(*disable).encode(),
            RailFaults(*rails).encode(),
            *self._backlog,
        ]
        for frame in frames:
            out.append(self._send(conn, frame))
        if self._usage is None:
            self._usage = Grid(self.usage_interval)
            self._usage.start(now + self.usage_interval)
        return out

    def receive(self, conn: Hashable, data: bytes, now: float,
                decode: Callable[[bytes], Any]) -> tuple[list[Any], Exception | None]:
        """The messages in ``data`` (each frame decoded with ``decode`` and counted), and the
        error that ends the connection, if any: the Rio handles the messages, then
        :meth:`drop` closes it."""
        client = self._clients.get(conn)
        if client is None:
            return [], None  # a connection we refused or already closed
        messages, error = decode_frames(client.decoder, data, decode, self.link, now, stop_on_bad=True)
        if messages:  # a valid frame (a keep-alive too): a sign of life
            client.valid = now
        return messages, error

    def drop(self, conn: Hashable, exc: Exception, now: float) -> Close:
        """A client that sent a bad frame (counted where it was read) is closed."""
        self._clients.pop(conn, None)
        self.link.connected = bool(self._clients)
        self.events.add(now, f"TCP: closed a DS connection that sent a bad frame: {exc}")
        return Close(conn, f"bad frame: {exc}")

    def closed(self, conn: Hashable, reason: str, now: float) -> None:
        if self._clients.pop(conn, None) is not None:
            self.events.add(now, f"TCP: DS disconnected ({reason or 'closed'})")
        self.link.connected = bool(self._clients)

    def close_all(self, reason: str) -> list[Close]:
        closes = [Close(conn, reason) for conn in self._clients]
        self._clients.clear()
        self.link.connected = False
        return closes

    def _evict_for(self, now: float, newcomer: str | None, ds_host: str | None,
                   among: list[Hashable] | None = None) -> list[Action]:
        """Make room for a new client from host ``newcomer`` (among ``among``, else every
        client): close the oldest client that never sent a valid frame; if none, the one
        silent the longest, if that is more than ``CLIENT_IDLE_EVICT`` seconds and it is not
        on ``ds_host``, the host of the DS followed on UDP. The DS's own host is always served:
        for it, else the longest-silent client on another host. Nothing (the newcomer is
        refused) when every client is healthy and, for the DS's host, on that host too."""
        pool = {conn: self._clients[conn] for conn in (among if among is not None else self._clients)}
        never = [(c.opened, conn) for conn, c in pool.items() if c.valid is None]
        if never:
            conn = min(never, key=lambda item: item[0])[1]
            why = "it never sent a valid frame"
        elif newcomer is not None and newcomer == ds_host:
            # (every client sent a valid frame: none is in `never`)
            elsewhere = [(c.valid, conn) for conn, c in pool.items() if c.host != ds_host and c.valid is not None]
            if not elsewhere:
                return []  # every slot is the DS's own host's, all healthy (the ephemeral plan's 127.0.0.1)
            conn = min(elsewhere, key=lambda item: item[0])[1]
            why = f"the DS at {ds_host} is always served"
        else:
            idle = [(c.valid, conn) for conn, c in pool.items()
                    if c.valid is not None and now - c.valid > CLIENT_IDLE_EVICT and c.host != ds_host]
            if not idle:
                return []
            conn = min(idle, key=lambda item: item[0])[1]
            why = f"no valid frame for more than {CLIENT_IDLE_EVICT:g} s"
        host = self._clients.pop(conn).host
        self.faults.evicted_clients += 1
        held = self._log.due("evicted", now)
        if held is not None:
            self.events.add(now, f"TCP: no room for a client from {newcomer}: closed one from {host} ({why})"
                                 f"{Throttle.suffix(held)}")
        return [Close(conn, f"evicted to make room for a new client: {why}")]


def _safe_text(text: str, limit: int = MAX_TEXT) -> str:
    """Text that encodes (lone surrogates replaced) and fits a frame."""
    text = str(text)[:limit]
    try:
        text.encode("utf-8", "surrogateescape")
    except UnicodeEncodeError:
        text = text.encode("utf-8", "replace").decode("utf-8")
    return text
