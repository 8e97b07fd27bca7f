"""What every role core shares: the actions it asks its shell to perform, per-link
counters, and the rate-limited log of bad input.

A role core is a sans-IO state machine (the aioquic shape, see docs/style.md#sans-io):

* the shell tells it what arrived (:class:`Core`, the one contract): ``datagram(channel, data,
  source, now, arrived, superseded)``,
  ``stream_opened(conn, peer, now)``, ``stream_data(conn, data, now)``,
  ``stream_closed(conn, reason, now)``;
* each of those returns the actions to perform at once (a status reply, a close), and
  ``poll(now)`` returns the actions that are due by time: :class:`Datagram`,
  :class:`StreamSend`, :class:`Connect`, :class:`Close`;
* ``next_deadline()`` says when it next wants ``poll`` called (absolute, the shell's clock).

Time is always a parameter, so tests run a whole match on a fake clock in milliseconds.
A core never raises on bad input: it counts, logs at most once a second per link, and drops.
It judges a datagram by its source before its bytes, and the decoders refuse a packet over
its kind's size bound by its length alone (issue 27): a flood of 64 KB datagrams, from anyone,
costs a comparison each.
"""

from __future__ import annotations

import datetime as _dt
import logging
import math
from collections import deque
from dataclasses import dataclass, field
from typing import Any, Callable, Generic, Hashable, Iterable, Iterator, Protocol, TypeVar

from .commands import Command
from .views import LinkStatsView, StreamView

T = TypeVar("T")
Address = tuple[str, int]

log = logging.getLogger("fieldbox.roles")


# -- actions a core asks of its shell ---------------------------------------------------
@dataclass(frozen=True, slots=True)
class Datagram:
    """Send ``data`` from the socket bound for ``channel`` to ``dest``."""

    channel: str
    data: bytes
    dest: Address
    kind: str = ""  # the protocol kind, for captures (``ds-to-rio``...)


@dataclass(frozen=True, slots=True)
class StreamSend:
    """Write ``data`` on TCP connection ``conn``."""

    conn: Hashable
    data: bytes
    kind: str = ""


@dataclass(frozen=True, slots=True)
class Connect:
    """Open TCP client connection ``conn`` to ``address`` (the shell reports the outcome
    with ``stream_opened`` or ``stream_closed``)."""

    conn: Hashable
    address: Address


@dataclass(frozen=True, slots=True)
class Close:
    """Close TCP connection ``conn``."""

    conn: Hashable
    reason: str = ""


Action = Datagram | StreamSend | Connect | Close


# -- the contract --------------------------------------------------------------------------
class Core(Protocol):
    """What the shell (roles/runtime/shell.py, roles/sim/simnet.py) calls on every core: the
    same events with the same signatures, whichever role it is.

    ``arrived`` is when the kernel received the datagram (the shell's clock; None: ``now``)
    and ``superseded`` whether a newer one from the same sender was already waiting behind
    it: the fake roboRIO obeys only the newest; a core that does not judge arrivals ignores
    both. ``view(now)`` is a plain copy of what a panel shows; ``apply(command, now)`` carries
    out a typed command (roles/cores/commands.py) or raises CommandError; ``shutdown()`` stops what the
    core has running outside itself (a robot program's process), or does nothing.
    """

    def datagram(self, channel: str, data: bytes, source: Address, now: float, arrived: float | None = None,
                 superseded: bool = False) -> list[Action]: ...

    def stream_opened(self, conn: Hashable, peer: Address, now: float) -> list[Action]: ...

    def stream_data(self, conn: Hashable, data: bytes, now: float) -> list[Action]: ...

    def stream_closed(self, conn: Hashable, reason: str, now: float) -> list[Action]: ...

    def poll(self, now: float) -> list[Action]: ...

    def next_deadline(self) -> float | None: ...

    def view(self, now: float) -> object: ...

    def apply(self, command: Command, now: float) -> None: ...

    def shutdown(self) -> None: ...


# -- counters ---------------------------------------------------------------------------
@dataclass
class LinkStats:
    """Plain counters for one link, written by the core, read by panels at ~10 Hz."""

    name: str
    packets_in: int = 0
    packets_out: int = 0
    bytes_in: int = 0
    bytes_out: int = 0
    bad_packets: int = 0
    lost_packets: int = 0
    stale_packets: int = 0  # well-formed but out of order (older than one already taken): not obeyed
    foreign_packets: int = 0  # from an address this link does not follow: dropped before it is decoded
    last_rx: float | None = None
    last_error: str = ""
    connected: bool = False
    _last_log: float = field(default=float("-inf"), repr=False)
    _unlogged: int = field(default=0, repr=False)

    def view(self) -> LinkStatsView:
        return LinkStatsView(self.name, self.packets_in, self.packets_out, self.bytes_in, self.bytes_out,
                             self.bad_packets, self.lost_packets, self.stale_packets, self.foreign_packets,
                             self.last_rx, self.last_error, self.connected)

    def received(self, n: int, now: float) -> None:
        self.packets_in += 1
        self.bytes_in += n
        self.last_rx = now

    def sent(self, n: int) -> None:
        self.packets_out += 1
        self.bytes_out += n

    def bad(self, error: Exception | str, now: float) -> None:
        """Count a dropped packet or frame; log at most once a second for this link."""
        self.bad_packets += 1
        self.last_error = str(error)
        self._unlogged += 1
        if now - self._last_log >= 1.0:
            extra = f" ({self._unlogged} since the last report)" if self._unlogged > 1 else ""
            log.warning("%s: bad input dropped%s: %s", self.name, extra, self.last_error)
            self._last_log = now
            self._unlogged = 0


class Throttle:
    """At most one report per ``period`` seconds per key: a flood of refusals is counted
    where it happens and logged once a second, never line by line. Keys must be bounded
    (a kind of refusal and a station, say), never an address a peer chooses."""

    __slots__ = ("period", "_last", "_held")

    def __init__(self, period: float = 1.0) -> None:
        self.period = period
        self._last: dict[Hashable, float] = {}
        self._held: dict[Hashable, int] = {}

    def due(self, key: Hashable, now: float) -> int | None:
        """None: held back (counted). Else report now; the int says how many were held back
        since the last report."""
        last = self._last.get(key)
        if last is not None and 0 <= now - last < self.period:
            self._held[key] = self._held.get(key, 0) + 1
            return None
        self._last[key] = now
        return self._held.pop(key, 0)

    @staticmethod
    def suffix(held: int) -> str:
        return f" (and {held} more since the last report)" if held else ""


class Grid:
    """Slots at ``origin + k * period`` on an absolute clock (no drift): the DS's 20 ms sends,
    the robot program's beat, the FMS's control packets. A late look takes the newest slot
    due and counts the ones it skipped: never a burst of catch-up sends."""

    __slots__ = ("period", "origin", "k")

    def __init__(self, period: float) -> None:
        self.period = period
        self.origin: float | None = None
        self.k = 0  # the next slot's index

    def start(self, now: float) -> None:
        """Slot 0 is due at ``now``."""
        self.origin, self.k = now, 0

    def stop(self) -> None:
        """No slot is due until the next ``start``."""
        self.origin, self.k = None, 0

    @property
    def next(self) -> float | None:
        """When the next slot is due (None before ``start``)."""
        return None if self.origin is None else self.origin + self.k * self.period

    def take(self, now: float) -> int | None:
        """None if no slot is due at ``now``; else take the newest due one and return how many
        slots before it were skipped."""
        due = self.next
        if due is None or now < due:
            return None
        assert self.origin is not None  # as due is not None
        latest = max(self.k, next_on_grid(self.origin, self.period, now) - 1)
        skipped = latest - self.k
        self.k = latest + 1
        return skipped


def next_on_grid(origin: float, period: float, now: float) -> int:
    """The index of the first slot ``origin + k * period`` strictly after ``now``."""
    k = max(0, math.floor((now - origin) / period) + 1)
    while origin + k * period <= now:  # float rounding: never a slot at or before now
        k += 1
    while k > 0 and origin + (k - 1) * period > now:
        k -= 1
    return k


def decode_frames(decoder: Any, data: bytes, decode: Callable[[bytes], Any], stats: LinkStats, now: float,
                  *, stop_on_bad: bool = False) -> tuple[list[Any], Exception | None]:
    """The messages of a framed TCP stream (``decoder``, a protocol.framing.FrameDecoder) in
    ``data``, each decoded with ``decode`` and counted on ``stats``: ``(messages, error)``.
    A frame that does not decode is counted bad and skipped, or (``stop_on_bad``) ends the
    read as a bad size field does: the error is returned, the frames before it come first."""
    frames, error = decoder.feed_until_error(data)
    messages: list[Any] = []
    for frame in frames:
        try:
            message = decode(frame)
        except ValueError as exc:  # ProtocolError: the one error a decoder raises
            stats.bad(exc, now)
            if stop_on_bad:
                return messages, exc
            continue
        stats.received(len(frame), now)
        messages.append(message)
    if error is not None:
        stats.bad(error, now)
    return messages, error


class TripTimer:
    """Round-trip times of sequence-numbered packets (DS control -> robot status echo)."""

    __slots__ = ("_sent", "samples", "last_ms", "_capacity")

    def __init__(self, capacity: int = 256) -> None:
        self._sent: dict[int, float] = {}
        self.samples: Stream[float] = Stream(capacity)
        self.last_ms: float | None = None
        self._capacity = capacity

    def sent(self, sequence: int, now: float) -> None:
        if len(self._sent) >= self._capacity:  # bounded: forget the oldest outstanding
            self._sent.pop(next(iter(self._sent)))
        self._sent[sequence] = now

    def echoed(self, sequence: int, now: float) -> float | None:
        t0 = self._sent.pop(sequence, None)
        if t0 is None:
            return None
        ms = (now - t0) * 1000.0
        self.samples.append(ms)
        self.last_ms = ms
        return ms

    @property
    def average_ms(self) -> float | None:
        return sum(self.samples) / len(self.samples) if self.samples else None

    def reset(self) -> None:
        self._sent.clear()


class Stream(Generic[T]):
    """A bounded append-only stream a core writes (its console, events, history): the newest
    ``capacity`` items, numbered from 0 by when they were appended, so a view of it
    (:class:`roles.cores.views.StreamView`) says which items it holds."""

    __slots__ = ("_items", "_total")

    def __init__(self, capacity: int) -> None:
        self._items: deque[T] = deque(maxlen=capacity)
        self._total = 0  # items ever appended

    def append(self, item: T) -> None:
        self._items.append(item)
        self._total += 1

    def extend(self, items: Iterable[T]) -> None:
        for item in items:
            self.append(item)

    def clear(self) -> None:
        """Forget the items kept; the numbering goes on."""
        self._items.clear()

    def restart(self, capacity: int) -> None:
        """Forget the items kept and keep the newest ``capacity`` from now on; the numbering
        goes on (a reader following by number sees the new items as new)."""
        self._items = deque(maxlen=capacity)

    @property
    def capacity(self) -> int | None:
        return self._items.maxlen

    @property
    def total(self) -> int:
        return self._total

    def view(self) -> StreamView[T]:
        return StreamView(self._total - len(self._items), tuple(self._items))

    def __len__(self) -> int:
        return len(self._items)

    def __iter__(self) -> Iterator[T]:
        return iter(self._items)

    def __reversed__(self) -> Iterator[T]:
        return reversed(self._items)

    def __getitem__(self, index: int) -> T:
        return self._items[index]

    def __bool__(self) -> bool:
        return bool(self._items)


def utc_now() -> _dt.datetime:
    """The wall clock, in UTC (a module-level function: a core holding it can be pickled)."""
    return _dt.datetime.now(_dt.timezone.utc)


class Events:
    """A bounded list of human-readable events (for panels, logs and headless status)."""

    def __init__(self, capacity: int = 500) -> None:
        self.items: Stream[tuple[float, str]] = Stream(capacity)
        self.listeners: list[Callable[[float, str], Any]] = []

    def add(self, now: float, text: str) -> None:
        self.items.append((now, text))
        log.info("%s", text)
        for listener in self.listeners:
            listener(now, text)


class CommandError(Exception):
    """A user command that cannot be carried out; the message says why. Nothing changed."""
