"""The DS side of the robot link for ``conform robot``: control packets on a drift-free
20 ms grid, each one and each answer kept with its time.

What the packets say is an :class:`Intent` the cases change as they go; each packet is
built byte by byte with :mod:`protocol.ds_to_rio` (or by hand, for the malformed tag).
Answers count only from the robot's host; each is decoded with :mod:`protocol.rio_to_ds`,
and one that does not decode is kept with its error (a finding, never a crash). An answer
longer than :data:`MAX_STATUS` is one too, kept by its head: a real status packet is a few
hundred bytes, and a robot answering 50 times a second with 64 KB must not fill memory.
"""

from __future__ import annotations

import asyncio
import time
from collections import OrderedDict, deque
from dataclasses import dataclass
from typing import Any, Callable

from protocol import rio_to_ds
from protocol.ds_to_rio import ControlPacket, Joystick
from protocol.enums import AllianceStation, Mode
from protocol.errors import ProtocolError
from protocol.rio_to_ds import StatusPacket

from .net import Arrival, UdpPort, until

ROBOT_UDP = 1110
ROBOT_UDP_FMS = 1115
DS_UDP = 1150
ROBOT_TCP = 1740
PERIOD = 0.020
#: The longest answer taken as a status packet (a real one, every tag included, is a few hundred
#: bytes); a longer one is an answer that does not decode, its first MAX_STATUS bytes kept.
MAX_STATUS = 4096


@dataclass(frozen=True, slots=True)
class Sent:
    seq: int
    at: float
    data: bytes
    port: int


@dataclass(frozen=True, slots=True)
class Reply:
    at: float
    data: bytes
    source: tuple[str, int]
    packet: StatusPacket | None
    error: str | None

    @property
    def pkt(self) -> StatusPacket:
        """The packet of a reply that decoded: those :meth:`DsDriver.good_replies` gives, the
        ones the cases read."""
        assert self.packet is not None, "a reply that did not decode"
        return self.packet


@dataclass
class Intent:
    """What the next control packets say."""

    enabled: bool = False
    mode: Mode = Mode.TELEOP
    estop: bool = False
    fms: bool = False
    restart_left: int = 0
    joysticks: tuple[Joystick, ...] = ()
    port: int = ROBOT_UDP
    override: Callable[[int], bytes] | None = None  # a hand-made packet (the malformed tag)


class DsDriver:
    """Control packets on a drift-free 20 ms grid; every packet and every reply kept."""

    def __init__(self, udp: UdpPort, robot_host: str, station: AllianceStation) -> None:
        self.udp = udp
        self.robot_host = robot_host
        self.station = station
        self.intent = Intent()
        self.once: list[Any] = []  # tags for the next packet only (the date and time zone)
        self.paused = False
        self.seq = 0
        self.sent: OrderedDict[int, Sent] = OrderedDict()
        self.log: deque[Sent] = deque(maxlen=20_000)
        self.replies: deque[Reply] = deque(maxlen=20_000)
        self.reply_to: dict[int, Reply] = {}
        self.foreign = 0  # datagrams from anywhere but the robot's host: not answers
        udp.listeners.append(self._on_datagram)
        self._task: asyncio.Task | None = None

    def start(self) -> None:
        self._task = asyncio.get_running_loop().create_task(self._beat())

    async def stop(self) -> None:
        if self._task is not None:
            self._task.cancel()
            await asyncio.gather(self._task, return_exceptions=True)

    async def _beat(self) -> None:
        start = time.monotonic()
        k = 0
        while True:
            if not self.paused:
                self._send()
            k = max(k + 1, int((time.monotonic() - start) / PERIOD) + 1)  # late: skip, never burst
            await asyncio.sleep(max(0.0, start + k * PERIOD - time.monotonic()))

    def packet(self, seq: int) -> bytes:
        i = self.intent
        if i.override is not None:
            return i.override(seq)
        tags = tuple(i.joysticks) + tuple(self.once)
        return ControlPacket(seq, 0x01, i.estop, i.fms, i.enabled, i.mode, False, i.restart_left > 0,
                             self.station, tags).encode()

    def _send(self) -> None:
        seq = self.seq
        self.seq = (seq + 1) & 0xFFFF
        data = self.packet(seq)
        self.once = []
        if self.intent.restart_left:
            self.intent.restart_left -= 1
        sent = Sent(seq, time.monotonic(), data, self.intent.port)
        self.sent.pop(seq, None)
        self.sent[seq] = sent
        while len(self.sent) > 8192:
            old, _ = self.sent.popitem(last=False)
            self.reply_to.pop(old, None)
        self.reply_to.pop(seq, None)
        self.log.append(sent)
        self.udp.send(data, (self.robot_host, self.intent.port))

    def _on_datagram(self, a: Arrival) -> None:
        if a.source[0] != self.robot_host:
            self.foreign += 1
            return
        data = a.data
        if len(data) > MAX_STATUS:
            packet, error = None, (f"{len(data)} bytes, longer than any status packet (a real one is a few "
                                   f"hundred; the first {MAX_STATUS} kept)")
            data = data[:MAX_STATUS]
        else:
            try:
                packet, error = rio_to_ds.decode_status(data), None
            except ProtocolError as exc:
                packet, error = None, str(exc)
        reply = Reply(a.at, data, a.source, packet, error)
        self.replies.append(reply)
        if packet is not None and packet.sequence in self.sent and packet.sequence not in self.reply_to:
            self.reply_to[packet.sequence] = reply

    def mark(self) -> int:
        """The sequence number the next packet will carry."""
        return self.seq

    def between(self, first: int, last: int) -> list[Sent]:
        """The packets sent from sequence ``first`` up to (not including) ``last``."""
        n = (last - first) & 0xFFFF
        return [self.sent[(first + k) & 0xFFFF] for k in range(n) if (first + k) & 0xFFFF in self.sent]

    def good_replies(self) -> list[Reply]:
        return [r for r in self.replies if r.packet is not None]

    async def beats(self, n: int) -> None:
        """Let ``n`` packets go out."""
        target = (self.seq + n) & 0xFFFF
        await until(lambda: ((self.seq - target) & 0xFFFF) < 0x8000, n * PERIOD * 3 + 1.0, 0.005)
