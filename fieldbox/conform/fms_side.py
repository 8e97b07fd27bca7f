"""The FMS fieldbox plays for ``conform ds``: it answers the DS's login as a real FMS does
(station info, event code, game data, a challenge question) and, once a case asks, sends
control packets every 500 ms, and at once when they change, from UDP 1160 to the DS's
UDP 1121 (or 1120, "FMS Lite"), at the address of the DS's TCP login, as Cheesy Arena does.

A DS that logs in as the 2027 FIRST Driver Station (the hello, tag 30) is answered as Cheesy
Arena's "new DS" path does (docs/protocol.md#cheesy-2027): the hello reply (tag 31) in place of
station info, the event code, no game data frame and no challenge (Cheesy asks none), and the
control packets go to the port the hello named, game data as their tag 32.
"""

from __future__ import annotations

import asyncio
import datetime as _dt
import functools
import random
import time
from collections import deque
from dataclasses import dataclass
from typing import Any

from protocol import ds_to_fms
from protocol.ds_to_fms import DsHello, TeamNumber
from protocol.enums import AllianceStation, Mode, StationStatus, TournamentLevel
from protocol.errors import ProtocolError
from protocol.fms_to_ds import (ChallengeQuestion, EventCode, FmsControlPacket, FmsDate, GameData, GameDataTag,
                                HelloReply, StationInfo)

from .net import FrameServer, FrameStream, UdpPort

FMS_TCP = 1750
FMS_UDP = 1160
DS_FMS_UDP = 1121
DS_FMS_UDP_LITE = 1120
EVENT_CODE = "CONFORM"
GAME_DATA = "RBR"
MATCH_NUMBER = 7


@dataclass
class FmsState:
    """What the FMS's control packets say now (None: send none)."""

    mode: Mode = Mode.AUTONOMOUS
    enabled: bool = False
    estop: bool = False
    astop: bool = False
    remaining: int = 15
    port: int = DS_FMS_UDP


class FakeFms:
    def __init__(self, team: int, station: AllianceStation, ds_host: str) -> None:
        self.team = team
        self.station = station
        self.ds_host = ds_host
        self.tcp = FrameServer("fms-tcp", on_open=self._opened)
        self.udp: UdpPort | None = None
        self.state: FmsState | None = None
        self.sent: deque[tuple[float, bytes, int]] = deque(maxlen=5000)
        self.challenges: dict[int, int] = {}  # id(stream) -> random value
        self.login: FrameStream | None = None
        self.hello: DsHello | None = None  # the login's 2027 hello, when it was one
        self.seq = 0
        self.rng = random.Random()
        self._task: asyncio.Task | None = None

    async def start(self, host: str) -> None:
        self.udp = await UdpPort.open("fms", host, FMS_UDP)
        await self.tcp.start(host, FMS_TCP)
        self._task = asyncio.get_running_loop().create_task(self._beat())

    async def close(self) -> None:
        if self._task is not None:
            self._task.cancel()
            await asyncio.gather(self._task, return_exceptions=True)
        await self.tcp.close()
        if self.udp is not None:
            self.udp.close()

    def _opened(self, stream: FrameStream) -> None:
        stream.listeners.append(functools.partial(self._frame, stream))

    def _frame(self, stream: FrameStream, frame) -> None:
        if stream.total != 1:
            return
        try:
            msg = ds_to_fms.decode_tcp(frame.data)
        except ProtocolError:
            msg = None
        if type(msg) is DsHello:
            self._hello(stream, msg)
            return
        if type(msg) is not TeamNumber:
            stream.close("first frame is not a team number")  # as a real FMS does
            return
        if msg.team != self.team:
            stream.send(StationInfo(AllianceStation.RED1, StationStatus.WAITING).encode())
            return
        self.login = stream
        value = self.rng.randint(1000, 2000)
        self.challenges[id(stream)] = value
        for f in (StationInfo(self.station, StationStatus.GOOD), EventCode(EVENT_CODE), GameData(GAME_DATA),
                  ChallengeQuestion(random_value=value)):
            stream.send(f.encode())

    def _hello(self, stream: FrameStream, msg: DsHello) -> None:
        team = msg.team
        if team != self.team:  # another team, or no team number at all: waiting (status 2), as Cheesy
            stream.send(HelloReply(AllianceStation.RED1, StationStatus.WAITING, 0, team or 0).encode())
            return
        self.login, self.hello = stream, msg
        for f in (HelloReply(self.station, StationStatus.GOOD, 0, team), EventCode(EVENT_CODE)):
            stream.send(f.encode())

    def control_port(self, port: int) -> int:
        """Where control goes: the port a 2027 hello named, else ``port`` (1121 or 1120)."""
        return self.hello.udp_port if self.hello is not None else port

    def control_host(self) -> str:
        return self.login.peer[0] if self.login is not None else self.ds_host

    def set(self, **changes: Any) -> None:
        """Change what the control packets say, and send one at once (a phase change)."""
        if self.state is None:
            self.state = FmsState()
        for k, v in changes.items():
            setattr(self.state, k, v)
        self._send()

    async def _beat(self) -> None:
        while True:
            await asyncio.sleep(0.5)
            if self.state is not None:
                self._send()

    def _send(self) -> None:
        s = self.state
        if s is None or self.udp is None:
            return
        tags = (GameDataTag(GAME_DATA),) if self.hello is not None else ()  # a 2027 DS's game data
        data = FmsControlPacket(self.seq, 0x00, s.estop, s.astop, s.enabled and not s.estop, s.mode, 0,
                                self.station, TournamentLevel.QUALIFICATION, MATCH_NUMBER, 1,
                                FmsDate.from_datetime(_dt.datetime.now(_dt.timezone.utc)), s.remaining,
                                tags).encode()
        self.seq = (self.seq + 1) & 0xFFFF
        port = self.control_port(s.port)
        self.udp.send(data, (self.control_host(), port))
        self.sent.append((time.monotonic(), data, port))
