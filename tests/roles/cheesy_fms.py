"""An FMS written in the tests to behave as Cheesy Arena does on real sockets (PROTOCOL-NOTES
"Corrections from real captures and peers"; docs/protocol.md#cheesy-2027): it takes a DS's
TCP login on 1750 (the NI DS's team number, 0x18, answered with station info 0x19; or the
2027 DS's hello, 0x1e, answered with the hello reply 0x1f, FMS Lite), asks no challenge, and
sends its control packets to the address of that TCP connection, never to where the DS's UDP
status comes from: on ``port`` after a team-number login (1120 in FMS Lite mode, 1121 at an
event), on the port the hello named after a hello.
"""

from __future__ import annotations

import asyncio
import socket

from protocol import ds_to_fms
from protocol.ds_to_fms import DsHello, TeamNumber
from protocol.enums import AllianceStation, Mode, StationStatus
from protocol.fms_to_ds import FmsControlPacket, GameDataTag, HelloReply, StationInfo


class CheesyLikeFms:
    """Cheesy Arena's login and control, for the DSes that log in to ``host``.

    ``socket_per_ds``: each DS's control packets leave from a UDP socket of its own on a port
    the OS chose (as Cheesy Arena's per-connection socket), else all from one. ``game_data``:
    sent as tag 32 in every control packet (the 2027 path)."""

    def __init__(self, host: str, *, port: int = 1120, station: AllianceStation = AllianceStation.RED1,
                 socket_per_ds: bool = False, game_data: str | None = None, period: float = 0.1) -> None:
        self.host = host
        self.port = port
        self.station = station
        self.socket_per_ds = socket_per_ds
        self.game_data = game_data
        self.period = period
        #: (the login frame's bytes, the team, where control goes), one per login
        self.logins: list[tuple[bytes, int, tuple[str, int]]] = []
        self._sockets: list[socket.socket] = []
        self.server: asyncio.base_events.Server | None = None
        self.udp: socket.socket | None = None
        self.task: asyncio.Task[None] | None = None

    async def start(self) -> None:
        self.server = await asyncio.start_server(self._client, self.host, 1750)
        self.udp = self._socket()
        self.task = asyncio.get_running_loop().create_task(self._send_control())

    def _socket(self) -> socket.socket:
        sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        sock.bind((self.host, 0))
        sock.setblocking(False)
        self._sockets.append(sock)
        return sock

    async def _client(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        peer = writer.get_extra_info("peername")[0]
        try:
            head = await reader.readexactly(3)
            data = head + await reader.readexactly(int.from_bytes(head[:2], "big") - 1)
            login = ds_to_fms.decode_tcp(data)
            if isinstance(login, DsHello):
                assert login.team is not None
                team, dest = login.team, (peer, login.udp_port)
                writer.write(HelloReply(self.station, StationStatus.GOOD, 1, team).encode())
            else:
                assert isinstance(login, TeamNumber)
                team, dest = login.team, (peer, self.port)
                writer.write(StationInfo(self.station).encode())
            self.logins.append((data, team, dest))
            while await reader.read(1024):  # keep the connection while the DS does
                pass
        except (asyncio.IncompleteReadError, ConnectionError):
            pass
        finally:
            writer.close()

    async def _send_control(self) -> None:
        seq = 0
        senders: dict[int, socket.socket] = {}  # login number -> its socket
        tags = (GameDataTag(self.game_data),) if self.game_data is not None else ()
        while True:
            for n, (_, _, dest) in enumerate(self.logins):
                if n not in senders:
                    senders[n] = self._socket() if self.socket_per_ds else self._default()
                seq = (seq + 1) & 0xFFFF
                packet = FmsControlPacket(sequence=seq, enabled=True, mode=Mode.TELEOP, station=self.station,
                                          remaining_seconds=100, tags=tags)
                senders[n].sendto(packet.encode(), dest)
            await asyncio.sleep(self.period)

    def _default(self) -> socket.socket:
        assert self.udp is not None
        return self.udp

    async def close(self) -> None:
        if self.task:
            self.task.cancel()
        if self.server:
            self.server.close()
            await self.server.wait_closed()
        for sock in self._sockets:
            sock.close()
