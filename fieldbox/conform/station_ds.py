"""The Driver Stations fieldbox plays for ``conform fms``: what each one does on a field.

Each logs in on TCP 1750 from its own address (its team's 127.TE.AM.5 on loopback), answers
the challenge, pings every 2 s, sends its status to UDP 1160 every 250 ms from its UDP 1121
and keeps every control packet that comes to 1121 or 1120, decoded with
:mod:`protocol.fms_to_ds` (one that does not decode is kept with its error). ``udp_silent``
and ``tcp_silent`` stop the status and the pings (the loss cases).
"""

from __future__ import annotations

import asyncio
import time
from collections import deque
from dataclasses import dataclass, field
from typing import Any

from protocol import ds_to_fms, fms_to_ds
from protocol.ds_to_fms import CommsMetrics, DsPing, DsStatusPacket, TeamNumber, challenge_answer
from protocol.enums import AllianceStation, Mode
from protocol.errors import ProtocolError
from protocol.fms_to_ds import ChallengeQuestion, FmsControlPacket, StationInfo

from .net import Arrival, FrameStream, UdpPort, connect

FMS_TCP = 1750
FMS_UDP = 1160
DS_FMS_UDP = 1121
DS_FMS_UDP_LITE = 1120
STATUS_PERIOD = 0.25
PING_PERIOD = 2.0


def team_host(team: int) -> str:
    return f"127.{team // 100}.{team % 100}.5"


@dataclass(frozen=True, slots=True)
class Received:
    at: float
    data: bytes
    port: int
    packet: FmsControlPacket | None
    error: str | None

    @property
    def pkt(self) -> FmsControlPacket:
        """The packet of a control that decoded: the only ones the cases read."""
        assert self.packet is not None, "a control that did not decode"
        return self.packet


@dataclass
class FakeDs:
    """One station's DS."""

    team: int
    station: AllianceStation  # each DS fieldbox plays has one (the spare team's login has none of its own)
    host: str
    fms: str
    udp: UdpPort | None = None
    udp_lite: UdpPort | None = None
    tcp: FrameStream | None = None
    controls: deque = field(default_factory=lambda: deque(maxlen=2000))
    udp_silent: bool = False
    tcp_silent: bool = False
    last_tcp_sent: float = 0.0
    login_at: float = float("inf")  # control packets before the login are another login's (F05's)
    seq: int = 0
    station_info: tuple[float, bytes] | None = None
    challenge: tuple[float, bytes, int] | None = None  # the question frame, its random value
    tasks: list = field(default_factory=list)

    async def bind(self) -> None:
        self.udp = await UdpPort.open(f"ds {self.team}", self.host, DS_FMS_UDP)
        self.udp.listeners.append(lambda a: self._control(a, DS_FMS_UDP))
        self.udp_lite = await UdpPort.open(f"ds {self.team} lite", self.host, DS_FMS_UDP_LITE)
        self.udp_lite.listeners.append(lambda a: self._control(a, DS_FMS_UDP_LITE))

    def _control(self, a: Arrival, port: int) -> None:
        try:
            packet, error = fms_to_ds.decode_control(a.data), None
        except ProtocolError as exc:
            packet, error = None, str(exc)
        self.controls.append(Received(a.at, a.data, port, packet, error))

    async def login(self) -> None:
        self.tcp = await connect(f"ds {self.team} fms-tcp", (self.fms, FMS_TCP), local_host=self.host)
        self.tcp.listeners.append(self._frame)
        self.login_at = time.monotonic()
        self._tcp_send(TeamNumber(self.team).encode())
        loop = asyncio.get_running_loop()
        self.tasks = [loop.create_task(self._status_loop()), loop.create_task(self._ping_loop())]

    def _tcp_send(self, data: bytes) -> None:
        if self.tcp is not None and self.tcp.send(data):
            self.last_tcp_sent = time.monotonic()

    def _frame(self, frame: Any) -> None:
        try:
            msg = fms_to_ds.decode_tcp(frame.data)
        except ProtocolError:
            return
        if type(msg) is StationInfo and self.station_info is None:
            self.station_info = (frame.at, frame.data)
        elif type(msg) is ChallengeQuestion and self.challenge is None:
            self.challenge = (frame.at, frame.data, msg.random_value)
            self._tcp_send(ds_to_fms.ChallengeResponse(challenge_answer(self.team, msg.random_value)).encode())

    async def _status_loop(self) -> None:
        while True:
            if not self.udp_silent and self.udp is not None:
                last = next((c.packet for c in reversed(self.controls) if c.packet is not None), None)
                enabled = bool(last and last.enabled)
                mode = last.mode if last else Mode.TELEOP
                status = DsStatusPacket(self.seq, 0x00, bool(last and last.estop), True, True, True, enabled, mode,
                                        self.team, 12.5, (CommsMetrics(0, self.seq, 1),))
                self.seq = (self.seq + 1) & 0xFFFF
                self.udp.send(status.encode(), (self.fms, FMS_UDP))
            await asyncio.sleep(STATUS_PERIOD)

    async def _ping_loop(self) -> None:
        while True:
            await asyncio.sleep(PING_PERIOD)
            if not self.tcp_silent:
                self._tcp_send(DsPing().encode())

    def mine(self) -> list[Received]:
        """Control packets since this DS logged in (before, its address may have been
        another login's: the wrong-station case's)."""
        return [c for c in self.controls if c.at >= self.login_at]

    def good(self, since: float = 0.0) -> list[Received]:
        return [c for c in self.mine() if c.packet is not None and c.at >= since]

    async def close(self) -> None:
        for t in self.tasks:
            t.cancel()
        await asyncio.gather(*self.tasks, return_exceptions=True)
        if self.tcp is not None:
            await self.tcp.wait_closed()
        for u in (self.udp, self.udp_lite):
            if u is not None:
                u.close()
