"""One exchange across the FMS, a Driver Station and its roboRIO, from the inspector's capture.

Every packet of an exchange passes through the Driver Station: the FMS and the roboRIO never
speak to each other. So the timeline is what one DS sent and received, on every link, as its
own taps saw it (the time it sent a packet, the time one arrived), drawn between three lanes:
the FMS (in 2010 mode, which has no FMS, the dashboard the DS sends to), the DS and the
roboRIO. It works the same when the robot or the FMS is elsewhere. Where no DS runs here, the
roboRIO's taps (or the FMS's) stand in for it.

:func:`hops` takes the last packets of each link (a 50 Hz link would drown a 2 Hz one if the
newest packets were taken over all links) and puts them in time order. :func:`delivery` finds,
when both ends of a link run here, how long a packet took from one tap to the other. No
textual here.
"""

from __future__ import annotations

import itertools
from collections import OrderedDict
from dataclasses import dataclass
from typing import Any, Iterable, Reversible, cast

from .capture import CapturedPacket, CaptureRing, LinkKey
from .packet_text import summarize

#: The lanes, left to right.
LANES = ("fms", "ds", "rio")

#: Where each kind of packet goes: (from lane, to lane, short name of a UDP packet).
_ROUTES = {
    "ds-to-rio": ("ds", "rio", "control"),
    "rio-to-ds": ("rio", "ds", "status"),
    "fms-to-ds": ("fms", "ds", "FMS control"),
    "ds-to-fms": ("ds", "fms", "DS status"),
    "ds-to-rio-tcp": ("ds", "rio", ""),
    "rio-to-ds-tcp": ("rio", "ds", ""),
    "fms-to-ds-tcp": ("fms", "ds", ""),
    "ds-to-fms-tcp": ("ds", "fms", ""),
    "legacy-ds-to-robot": ("ds", "rio", "control"),
    "legacy-robot-to-ds": ("rio", "ds", "status"),
    "legacy-netconsole": ("rio", "ds", "NetConsole"),
    "legacy-dashboard": ("ds", "fms", "dashboard"),  # 2010: no FMS, the left lane is the dashboard
}

#: Summaries kept (a screen shows a few dozen hops; each summary is a decode).
SUMMARIES = 256


@dataclass(frozen=True)
class Hop:
    """One packet between two lanes."""

    packet: CapturedPacket
    src: str
    dst: str
    tcp: bool
    name: str     # "control #612", "stdout #3", "ds ping"
    detail: str   # what else the packet says

    @property
    def time(self) -> float:
        return self.packet.time


def route(kind: str) -> tuple[str, str, str] | None:
    return _ROUTES.get(kind)


def center_role(engine: Any, team: int | None) -> tuple[str | None, str]:
    """The role whose taps tell the exchange: the selected team's DS, else its roboRIO, else
    the FMS; and its lane."""
    field = getattr(engine, "field", None)
    stations = list(getattr(field, "stations", []) or [])
    st = next((s for s in stations if s.team == team), stations[0] if stations else None)
    if st is not None and st.ds is not None:
        return st.ds_name, "ds"
    if st is not None and st.rio is not None:
        return st.rio_name, "rio"
    if field is not None and field.fms is not None:
        return field.fms_name, "fms"
    return None, "ds"


def last_packets(ring: CaptureRing, key: LinkKey, n: int) -> list[CapturedPacket]:
    """The newest ``n`` packets of one link, oldest first (no copy of the whole ring)."""
    packets = ring.links.get(key)
    if not packets or n <= 0:
        return []
    return list(itertools.islice(reversed(packets), n))[::-1]


class Summaries:
    """Packet summaries, by capture number, the latest used kept."""

    def __init__(self, size: int = SUMMARIES) -> None:
        self.size = size
        self._kept: OrderedDict[int, str] = OrderedDict()

    def __call__(self, p: CapturedPacket) -> str:
        text = self._kept.get(p.seq)
        if text is None:
            text = self._kept[p.seq] = summarize(p.kind, p.data)
            if len(self._kept) > self.size:
                self._kept.popitem(last=False)
        else:
            self._kept.move_to_end(p.seq)
        return text


def split_summary(summary: str, udp_name: str) -> tuple[str, str]:
    """A summary as (a short name for the arrow, the rest): ``ControlPacket #612: no e-stop``
    gives ``("control #612", "no e-stop")``; a TCP frame's ``stdout #3: text hi`` gives
    ``("stdout #3", "text hi")``."""
    bad = ""
    if summary.startswith("BAD "):
        bad, _, summary = summary.partition(" | ")
        bad += " | "
    head, _, rest = summary.partition(": ")
    number = next((w for w in head.split() if w.startswith("#")), "")
    name = udp_name or head.split(" ")[0].replace("_", " ")
    return (f"{name} {number}".strip(), bad + rest)


def hops(ring: CaptureRing, role: str | None, per_link: int, summaries: Summaries | None = None) -> list[Hop]:
    """The last ``per_link`` packets of each of ``role``'s links, in time order."""
    if role is None:
        return []
    summaries = summaries or Summaries()
    out: list[Hop] = []
    for key in list(ring.links):
        if key[0] != role:
            continue
        r = route(key[3])
        if r is None:
            continue
        src, dst, udp_name = r
        for p in last_packets(ring, key, per_link):
            name, detail = split_summary(summaries(p), udp_name)
            out.append(Hop(p, src, dst, key[3].endswith("-tcp"), name, detail))
    out.sort(key=lambda h: (h.packet.time, h.packet.seq))
    return out


def last_time(ring: CaptureRing, key: LinkKey) -> float | None:
    packets = ring.links.get(key)
    return packets[-1].time if packets else None


def delivery(ring: CaptureRing, sent: LinkKey, got: LinkKey, within: float = 1.0) -> float | None:
    """Seconds from the newest packet of link ``got`` back to the same bytes on link ``sent``
    (both ends running here), or None."""
    arrived = ring.links.get(got)
    if not arrived:
        return None
    p = arrived[-1]
    for q in _newest_first(ring.links.get(sent, ()), 200):
        if q.time < p.time - within:
            break
        if q.data == p.data and q.time <= p.time:
            return p.time - q.time
    return None


def _newest_first(packets: Iterable[CapturedPacket], n: int) -> Iterable[CapturedPacket]:
    if not hasattr(packets, "__reversed__"):
        return ()
    return itertools.islice(reversed(cast(Reversible[CapturedPacket], packets)), n)
