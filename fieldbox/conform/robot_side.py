"""The robot fieldbox plays for ``conform ds``: it answers the DS under test as a roboRIO
does and keeps every control packet the DS sent, with its arrival time and port.

It answers from the port a packet came to (1110 or 1115), to the DS's address on UDP 1150:
the sequence echoed, e-stop/enabled/mode echoed, robot code running, "is a roboRIO",
12.5 V, and request-date until the DS has sent its date and time zone. ``silent`` stops the
answers (the comms-loss case). TCP 1740 takes the DS's connection and keeps its frames.
"""

from __future__ import annotations

import functools
import time
from collections import deque
from dataclasses import dataclass

from protocol import ds_to_rio
from protocol.ds_to_rio import ControlPacket, Date, Timezone
from protocol.errors import ProtocolError
from protocol.rio_to_ds import StatusPacket

from .net import Arrival, FrameServer, UdpPort

ROBOT_UDP = 1110
ROBOT_UDP_FMS = 1115
ROBOT_TCP = 1740
DS_UDP = 1150
ROBOT_VOLTS = 12.5  # what the robot reports: 0x0c80


@dataclass(frozen=True, slots=True)
class Control:
    """A control packet the DS sent, as it arrived."""

    at: float
    data: bytes
    port: int  # 1110 or 1115
    packet: ControlPacket | None
    error: str | None

    @property
    def pkt(self) -> ControlPacket:
        """The packet of a control that decoded: those :meth:`FakeRobot.good` gives, the ones
        the cases read."""
        assert self.packet is not None, "a control that did not decode"
        return self.packet


class FakeRobot:
    """Answers the DS as a roboRIO does; keeps every control packet. ``silent`` stops the answers."""

    def __init__(self, ds_host: str, reply_port: int) -> None:
        self.ds_host = ds_host
        self.reply_port = reply_port
        self.controls: deque[Control] = deque(maxlen=30_000)
        self.foreign = 0
        self.silent = False
        self.date_at: float | None = None  # when date and time zone had both come
        self.asked_until: float | None = None
        self.last_reply: float | None = None
        self.ports: dict[int, UdpPort] = {}
        self.tcp = FrameServer("robot-tcp")

    async def start(self, host: str) -> None:
        for port in (ROBOT_UDP, ROBOT_UDP_FMS):
            udp = await UdpPort.open(f"robot {port}", host, port)
            udp.listeners.append(functools.partial(self._on_control, port=port))
            self.ports[port] = udp
        await self.tcp.start(host, ROBOT_TCP)

    def close(self) -> None:
        for udp in self.ports.values():
            udp.close()

    @property
    def request_date(self) -> bool:
        return self.date_at is None

    def _on_control(self, a: Arrival, port: int) -> None:
        if a.source[0] != self.ds_host:
            self.foreign += 1
            return
        try:
            packet, error = ds_to_rio.decode_control(a.data), None
        except ProtocolError as exc:
            packet, error = None, str(exc)
        self.controls.append(Control(a.at, a.data, port, packet, error))
        if packet is None:
            return
        tags = {type(t) for t in packet.tags}
        if self.date_at is None and Date in tags and Timezone in tags:
            self.date_at = a.at
        if self.silent:
            return
        status = StatusPacket(packet.sequence, 0x01, estop=packet.estop, enabled=packet.enabled and not packet.estop,
                              mode=packet.mode, robot_code=True, is_roborio=True, battery=ROBOT_VOLTS,
                              request_date=self.request_date)
        self.ports[port].send(status.encode(), (a.source[0], self.reply_port))
        self.last_reply = time.monotonic()

    def good(self, since: float = 0.0) -> list[Control]:
        return [c for c in self.controls if c.packet is not None and c.at >= since]
