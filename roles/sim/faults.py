"""Faults on purpose: loss, latency, jitter, duplication, reordering, corruption and cuts,
per link, for the asyncio shell (roles/runtime/shell.py) and the fake-clock network (roles/sim/simnet.py).

Pure: no sockets, no clocks. A shell asks :class:`Faults` what to do with each datagram it is
about to send (``datagram()`` -> copies and their delays) and hands TCP data to an in-order
line per connection direction (``stream_push`` / ``stream_take`` / ``stream_deadline``).

Links, named as on the field (a packet's link comes from its protocol kind, see
:func:`link_for_kind`), each faulted in both directions:

=============  ====================================================
``ds-rio``     DS <-> roboRIO UDP (control packets, status packets)
``ds-rio-tcp`` DS <-> roboRIO TCP 1740
``ds-fms``     DS <-> FMS UDP (status, control packets)
``ds-fms-tcp`` DS <-> FMS TCP 1750
=============  ====================================================

The spec language (``--fault SPEC``, the headless ``fault SPEC`` command)::

    ds-rio:loss=10%,delay=30ms~10ms,dup=1%,reorder=5%,corrupt=1%
    ds-rio:cut          pull the cable: nothing passes either way
    ds-rio:uncut        put it back (the other settings stay)
    ds-rio:clear        no faults on that link
    ds-rio+ds-rio-tcp:cut   several links;  all:cut   every link;  clear   everything

A spec sets the knobs it names and keeps the others (``loss=0`` turns one off).

What each knob does:

* UDP: ``loss`` drops; ``corrupt`` flips one to three bits; ``delay=D~J`` delays by D plus
  or minus up to J (uniformly), keeping the order of one flow (jitter alone never reorders);
  ``reorder`` holds a packet back by 1.5 times the flow's packet interval, so the next one
  overtakes it; ``dup`` sends a second copy right after; a cut drops everything.
* TCP stays ordered and reliable, as TCP is: a lost or corrupted segment shows as a
  retransmission delay (200 ms, doubling while the retransmissions are lost too); ``dup``
  and ``reorder`` have no visible effect (the receiver's TCP sorts them out); ``delay``
  delays in order; a cut holds everything, released in order when the cut ends, and new
  connections cannot be made while it lasts.

Every link has plain counters (:class:`FaultCounters`) saying what its faults did, for the
app's faults panel. The random numbers come from one seeded :class:`random.Random`.
"""

from __future__ import annotations

import math
import random
from collections import deque
from dataclasses import dataclass, field, fields, replace
from typing import Any, Callable, Hashable, Iterable

from ..cores.views import FaultCountersView, FaultsView

LINKS = ("ds-rio", "ds-rio-tcp", "ds-fms", "ds-fms-tcp")
TCP_LINKS = frozenset({"ds-rio-tcp", "ds-fms-tcp"})

#: protocol kind (RoleSpec.kinds, Datagram.kind) -> link
KIND_LINKS = {
    "ds-to-rio": "ds-rio", "rio-to-ds": "ds-rio",
    "ds-to-rio-tcp": "ds-rio-tcp", "rio-to-ds-tcp": "ds-rio-tcp",
    "ds-to-fms": "ds-fms", "fms-to-ds": "ds-fms",
    "ds-to-fms-tcp": "ds-fms-tcp", "fms-to-ds-tcp": "ds-fms-tcp",
    "legacy-ds-to-robot": "ds-rio", "legacy-robot-to-ds": "ds-rio", "legacy-netconsole": "ds-rio",
}

#: A TCP segment lost (or corrupted: the checksum catches it) comes again after the
#: retransmission timeout; Linux's floor is 200 ms, doubled per further loss.
TCP_RTO = 0.200
MAX_RETRANSMISSIONS = 6
#: A duplicated datagram's copy follows the original this much later.
DUP_GAP = 0.0005
#: Bounds of the hold-back of a reordered datagram.
REORDER_MIN = 0.001
REORDER_MAX = 1.0
#: Flows (one direction of one socket pair) remembered for order keeping and intervals.
MAX_FLOWS = 1024
#: The largest delay a spec may ask (a larger one is a typo).
MAX_DELAY = 10.0

Flow = Hashable


class FaultSpecError(ValueError):
    """A fault spec that does not parse; the message says what is wrong."""


def link_for_kind(kind: str) -> str | None:
    """The link a protocol kind travels on (``ds-to-rio`` -> ``ds-rio``), or None."""
    return KIND_LINKS.get(kind)


# -- settings ------------------------------------------------------------------------------
@dataclass(frozen=True)
class LinkFault:
    """What one link suffers. Probabilities are fractions 0..1, times are seconds."""

    loss: float = 0.0
    delay: float = 0.0
    jitter: float = 0.0
    dup: float = 0.0
    reorder: float = 0.0
    corrupt: float = 0.0
    cut: bool = False

    @property
    def active(self) -> bool:
        return self != _NONE

    def describe(self) -> str:
        """``loss=10%,delay=30ms~10ms,cut`` (the spec language), or ``none``."""
        parts = []
        if self.cut:
            parts.append("cut")
        if self.loss:
            parts.append(f"loss={_pct(self.loss)}")
        if self.delay or self.jitter:
            parts.append(f"delay={_ms(self.delay)}" + (f"~{_ms(self.jitter)}" if self.jitter else ""))
        for name in ("dup", "reorder", "corrupt"):
            value = getattr(self, name)
            if value:
                parts.append(f"{name}={_pct(value)}")
        return ",".join(parts) or "none"


_NONE = LinkFault()


@dataclass
class FaultCounters:
    """What one link's faults did (plain counters, read by panels at ~10 Hz).

    ``seen``: packets (datagrams, or TCP writes) that met an active fault; ``dropped``:
    datagrams lost or cut; ``delayed``: delivered later than sent; ``duplicated``: extra
    copies sent; ``reordered``: held back so a later one overtook; ``corrupted``: bits
    flipped (UDP) or a segment the checksum rejected (TCP); ``retransmitted``: TCP writes
    delayed by a retransmission; ``held``: TCP writes held by a cut; ``refused_connects``:
    TCP connections that could not be made during a cut.
    """

    seen: int = 0
    dropped: int = 0
    delayed: int = 0
    duplicated: int = 0
    reordered: int = 0
    corrupted: int = 0
    retransmitted: int = 0
    held: int = 0
    refused_connects: int = 0

    def total(self) -> int:
        return sum(getattr(self, f.name) for f in fields(self) if f.name != "seen")


# -- the spec language -------------------------------------------------------------------
@dataclass(frozen=True)
class FaultChange:
    """A parsed spec: the links it names and the operations, in order. Operations are
    ``("clear", None)``, ``("cut", True/False)`` or ``(knob, value)``."""

    links: tuple[str, ...]
    ops: tuple[tuple[str, Any], ...]
    text: str = ""


_PERCENT_KNOBS = {"loss": "loss", "drop": "loss", "dup": "dup", "duplicate": "dup", "reorder": "reorder",
                  "corrupt": "corrupt", "corruption": "corrupt"}
_USAGE = ("use LINK:SETTINGS, e.g. ds-rio:loss=10%,delay=30ms~10ms,dup=1%,reorder=5%,corrupt=1% "
          "or ds-rio:cut / ds-rio:uncut / ds-rio:clear (links: " + ", ".join(LINKS) + ", all)")


def parse_fault(text: str) -> FaultChange:
    """Parse one spec. Raises :class:`FaultSpecError` saying what is wrong."""
    if not isinstance(text, str):
        raise FaultSpecError(f"a fault spec is text, not {text!r}")
    spec = "".join(text.split()).lower()
    if not spec:
        raise FaultSpecError(f"empty fault spec: {_USAGE}")
    if spec in ("clear", "none", "off"):
        return FaultChange(LINKS, (("clear", None),), text.strip())
    if ":" not in spec:
        if spec in LINKS or spec == "all":
            raise FaultSpecError(f"{spec!r} says which link but not what fault: {_USAGE}")
        raise FaultSpecError(f"no ':' in {text.strip()!r}: {_USAGE}")
    names, body = spec.split(":", 1)
    links: list[str] = []
    for name in names.split("+"):
        if name == "all":
            links.extend(LINKS)
        elif name in LINKS:
            links.append(name)
        else:
            raise FaultSpecError(f"unknown link {name!r}: use " + ", ".join(LINKS) + " or all")
    links = list(dict.fromkeys(links))
    if not body:
        raise FaultSpecError(f"nothing after '{names}:': {_USAGE}")
    ops: list[tuple[str, Any]] = []
    seen: set[str] = set()
    for item in body.split(","):
        if not item:
            raise FaultSpecError(f"an empty setting in {body!r} (two commas?)")
        key, eq, value = item.partition("=")
        if key in ("cut", "uncut", "clear") and not value:
            op: tuple[str, float | bool | None] = ("clear", None) if key == "clear" else ("cut", key == "cut")
        elif key == "cut":
            if value not in ("on", "off", "1", "0", "yes", "no", "true", "false"):
                raise FaultSpecError(f"cut={value!r}: use cut, uncut, cut=on or cut=off")
            op = ("cut", value in ("on", "1", "yes", "true"))
        elif not eq and (key in _PERCENT_KNOBS or key in ("delay", "latency", "jitter")):
            example = "30ms" if key in ("delay", "latency", "jitter") else "10%"
            raise FaultSpecError(f"{key} needs a value, e.g. {key}={example}")
        elif key in _PERCENT_KNOBS:
            op = (_PERCENT_KNOBS[key], _percent(value, key))
        elif key == "delay" or key == "latency":
            base, tilde, jitter = value.partition("~")
            op = ("delay", _duration(base, "delay"))
            if tilde:
                if "jitter" in seen:
                    raise FaultSpecError("jitter given twice (delay=D~J and jitter=J)")
                seen.add("jitter")
                ops.append(("jitter", _duration(jitter, "jitter")))
        elif key == "jitter":
            op = ("jitter", _duration(value, "jitter"))
        else:
            raise FaultSpecError(f"unknown setting {key!r}: one of loss, delay, jitter, dup, reorder, "
                                 "corrupt, cut, uncut, clear")
        name = op[0]
        if name in seen:
            raise FaultSpecError(f"{name} given twice in {text.strip()!r}")
        seen.add(name)
        ops.append(op)
    return FaultChange(tuple(links), tuple(ops), text.strip())


def _percent(value: str, what: str) -> float:
    raw = value[:-1] if value.endswith("%") else value
    try:
        number = float(raw)
    except ValueError:
        raise FaultSpecError(f"{what} must be a percentage like 10%, not {value!r}") from None
    if not math.isfinite(number) or not 0.0 <= number <= 100.0:
        raise FaultSpecError(f"{what} must be 0..100%, not {value!r}")
    return number / 100.0


def _duration(value: str, what: str) -> float:
    units = (("ms", 1e-3), ("us", 1e-6), ("µs", 1e-6), ("s", 1.0))
    scale, raw = 1e-3, value  # a bare number is milliseconds
    for suffix, factor in units:
        if value.endswith(suffix):
            scale, raw = factor, value[: -len(suffix)]
            break
    try:
        number = float(raw) * scale
    except ValueError:
        raise FaultSpecError(f"{what} must be a time like 30ms or 0.5s, not {value!r}") from None
    if not math.isfinite(number) or not 0.0 <= number <= MAX_DELAY:
        raise FaultSpecError(f"{what} must be 0..{MAX_DELAY:g} s, not {value!r}")
    return number


def _pct(p: float) -> str:
    return f"{p * 100:g}%"


def _ms(seconds: float) -> str:
    return f"{seconds * 1000:g}ms"


# -- per-flow state ------------------------------------------------------------------------
@dataclass
class _Flow:
    last_sent: float | None = None
    interval: float | None = None  # smoothed time between packets
    watermark: float = -math.inf  # the latest delivery time handed out (order keeping)


@dataclass
class _Line:
    """One direction of one TCP connection: data waiting, in order, with its due time."""

    link: str | None
    items: deque = field(default_factory=deque)  # (due, data)
    size: int = 0
    watermark: float = -math.inf


# -- the faults ----------------------------------------------------------------------------
class Faults:
    """The field's faults: settings and counters per link, and the decisions.

    ``links`` and ``counters`` are plain dicts keyed by link name (all four always present);
    ``listeners`` are called with no argument after every change (a shell releases what a
    cut held).
    """

    def __init__(self, seed: int | None = None, rng: random.Random | None = None) -> None:
        self.rng = rng if rng is not None else random.Random(seed)
        self.links: dict[str, LinkFault] = {name: _NONE for name in LINKS}
        self.counters: dict[str, FaultCounters] = {name: FaultCounters() for name in LINKS}
        self.listeners: list[Callable[[], Any]] = []
        self.changes = 0  # bumped on every change: a panel's cheap "anything new?"
        self._flows: dict[Flow, _Flow] = {}
        self._lines: dict[Flow, _Line] = {}
        self._any = False

    # -- settings --------------------------------------------------------------------------
    @property
    def any_active(self) -> bool:
        """Whether any link has a fault, or a TCP line still holds data."""
        return self._any or bool(self._lines)

    def active(self, link: str | None) -> bool:
        return link is not None and self.links.get(link, _NONE) is not _NONE

    def is_cut(self, link: str | None) -> bool:
        return link is not None and link in self.links and self.links[link].cut

    def apply(self, change: FaultChange | str) -> list[str]:
        """Apply a spec (text or parsed); returns one description line per link it named.
        Raises :class:`FaultSpecError` (nothing changed) for a bad spec."""
        if isinstance(change, str):
            change = parse_fault(change)
        for link in change.links:
            fault = self.links[link]
            for name, value in change.ops:
                if name == "clear":
                    fault = _NONE
                else:
                    fault = replace(fault, **{name: value})
            self._set(link, fault)
        self._changed()
        return [f"{link}: {self.links[link].describe()}" for link in change.links]

    def set(self, link: str, **knobs: Any) -> None:
        """Set knobs directly: ``set("ds-rio", loss=0.1, delay=0.03)`` (fractions, seconds)."""
        if link not in self.links:
            raise FaultSpecError(f"unknown link {link!r}: use " + ", ".join(LINKS))
        self._set(link, replace(self.links[link], **knobs))
        self._changed()

    def cut(self, link: str, on: bool = True) -> None:
        self.set(link, cut=on)

    def clear(self, link: str | None = None) -> None:
        for name in (LINKS if link is None else (link,)):
            if name not in self.links:
                raise FaultSpecError(f"unknown link {name!r}: use " + ", ".join(LINKS))
            self._set(name, _NONE)
        self._changed()

    def reset_counters(self) -> None:
        self.counters = {name: FaultCounters() for name in LINKS}
        self._changed()

    def _set(self, link: str, fault: LinkFault) -> None:
        self.links[link] = fault if fault.active else _NONE

    def _changed(self) -> None:
        self._any = any(f.active for f in self.links.values())
        if not self._any:
            self._flows.clear()
        self.changes += 1
        for listener in list(self.listeners):
            listener()

    def describe(self) -> list[str]:
        """One line per link: its settings and what they did."""
        lines = []
        for link in LINKS:
            c = self.counters[link]
            done = ", ".join(f"{f.name} {getattr(c, f.name)}" for f in fields(c) if getattr(c, f.name))
            lines.append(f"{link}: {self.links[link].describe()}" + (f" ({done})" if done else ""))
        return lines

    def view(self, now: float = 0.0) -> FaultsView:
        return FaultsView(at=now, links=dict(self.links),
                          counters={link: FaultCountersView(**vars(c)) for link, c in self.counters.items()})

    def snapshot(self) -> dict[str, Any]:
        return self.view().snapshot()

    # -- datagrams ---------------------------------------------------------------------------
    def datagram(self, link: str | None, flow: Flow, data: bytes, now: float) -> list[tuple[float, bytes]]:
        """What to do with one datagram about to go on ``link``: a list of (delay from now,
        bytes) to send; empty to drop it. ``flow`` names one direction of one socket pair
        (order is kept within a flow)."""
        if link is None or not self.active(link):
            return [(0.0, data)]
        fault = self.links[link]
        c = self.counters[link]
        c.seen += 1
        state = self._flow(flow, now)
        rng = self.rng
        if fault.cut or (fault.loss and rng.random() < fault.loss):
            c.dropped += 1
            return []
        if fault.corrupt and rng.random() < fault.corrupt and data:
            data = _flip_bits(data, rng)
            c.corrupted += 1
        due = now + fault.delay
        if fault.jitter:
            due += rng.uniform(-fault.jitter, fault.jitter)
        due = max(due, now, state.watermark)
        if fault.reorder and rng.random() < fault.reorder:
            gap = 1.5 * (state.interval if state.interval is not None else 0.020)
            due += min(max(gap, REORDER_MIN), REORDER_MAX)
            c.reordered += 1  # the watermark stays: the next packet may overtake this one
        else:
            state.watermark = due
        if due > now:
            c.delayed += 1
        out = [(due - now, data)]
        if fault.dup and rng.random() < fault.dup:
            out.append((due - now + DUP_GAP, data))
            c.duplicated += 1
        return out

    def _flow(self, key: Flow, now: float) -> _Flow:
        state = self._flows.get(key)
        if state is None:
            if len(self._flows) >= MAX_FLOWS:  # bounded: forget the oldest flow
                self._flows.pop(next(iter(self._flows)))
            state = self._flows[key] = _Flow()
        if state.last_sent is not None:
            gap = now - state.last_sent
            state.interval = gap if state.interval is None else 0.8 * state.interval + 0.2 * gap
        state.last_sent = now
        return state

    # -- TCP ----------------------------------------------------------------------------------
    def stream_involved(self, link: str | None, flow: Flow) -> bool:
        """Whether a write on ``flow`` must go through its line (the link has a fault, or
        earlier data still waits: order is kept)."""
        return flow in self._lines or self.active(link)

    def stream_push(self, link: str | None, flow: Flow, data: bytes, now: float) -> None:
        """Queue one write; take it with :meth:`stream_take` when due."""
        line = self._lines.get(flow)
        if line is None:
            line = self._lines[flow] = _Line(link)
        due = now
        if link is not None and self.active(link):
            fault = self.links[link]
            c = self.counters[link]
            c.seen += 1
            rng = self.rng
            due += fault.delay + (rng.uniform(-fault.jitter, fault.jitter) if fault.jitter else 0.0)
            lost = 0
            corrupted = False
            while lost < MAX_RETRANSMISSIONS:
                if fault.loss and rng.random() < fault.loss:
                    lost += 1
                elif fault.corrupt and rng.random() < fault.corrupt:
                    lost += 1
                    corrupted = True
                else:
                    break
            if lost:
                due += TCP_RTO * (2 ** lost - 1)
                c.retransmitted += 1
                c.corrupted += corrupted
            if fault.cut:
                c.held += 1
            if max(due, now) > now or fault.cut:
                c.delayed += 1
        due = max(due, now, line.watermark)
        line.watermark = due
        line.items.append((due, data))
        line.size += len(data)

    def stream_take(self, flow: Flow, now: float) -> list[bytes]:
        """The writes of ``flow`` due by ``now``, in order (nothing while its link is cut)."""
        line = self._lines.get(flow)
        if line is None or self.is_cut(line.link):
            return []
        out = []
        items = line.items
        while items and items[0][0] <= now:
            data = items.popleft()[1]
            line.size -= len(data)
            out.append(data)
        if not items:
            del self._lines[flow]
        return out

    def stream_deadline(self, flow: Flow) -> float | None:
        """When ``flow``'s next write is due (None: nothing waits, or its link is cut)."""
        line = self._lines.get(flow)
        if line is None or not line.items or self.is_cut(line.link):
            return None
        return line.items[0][0]

    def stream_queued(self, flow: Flow) -> int:
        """Bytes waiting on ``flow`` (a shell bounds this as it bounds a write buffer)."""
        line = self._lines.get(flow)
        return line.size if line is not None else 0

    def stream_closed(self, flow: Flow) -> None:
        """The connection is gone: what waited is lost with it."""
        self._lines.pop(flow, None)

    def waiting_flows(self) -> list[Flow]:
        """Flows with data waiting (a shell pumps them after a change, e.g. a cut ended)."""
        return list(self._lines)

    def connect_allowed(self, link: str | None) -> bool:
        """False while ``link`` is cut: the connection attempt is lost (counted)."""
        if self.is_cut(link):
            self.counters[link].refused_connects += 1  # type: ignore[index]
            return False
        return True


def _flip_bits(data: bytes, rng: random.Random) -> bytes:
    buf = bytearray(data)
    for _ in range(rng.randint(1, 3)):
        i = rng.randrange(len(buf) * 8)
        buf[i >> 3] ^= 1 << (i & 7)
    return bytes(buf)


def parse_faults(specs: Iterable[str]) -> list[FaultChange]:
    """Parse several specs (the command line's repeated ``--fault``)."""
    return [parse_fault(s) for s in specs]


__all__ = ["FaultChange", "FaultCounters", "FaultSpecError", "Faults", "KIND_LINKS", "LINKS", "LinkFault",
           "TCP_LINKS", "TCP_RTO", "link_for_kind", "parse_fault", "parse_faults"]
