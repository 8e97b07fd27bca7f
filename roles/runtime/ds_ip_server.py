"""The Driver Station's robot-address service: dashboards ask the DS where the robot is.

WPILib's dashboards and tools (Shuffleboard, Glass, Elastic's "Driver Station" address mode,
any NetworkTables client started with ``startDSClient``) connect to TCP 127.0.0.1:1742 and read
flat JSON objects with ``"robotIP"``: the robot's IPv4 address as an unsigned integer, first
octet in the high byte; 0 when there is none (PROTOCOL-NOTES, "Dashboards ask the DS where the
robot is"). What the client does with them (WPILib's wpinet ``DsClient``):

* it skips to the first ``{`` and takes everything up to the next ``}`` as one object (the
  objects never nest), so any number of objects may come, one after another, with anything
  between them;
* a ``robotIP`` of 0 forgets the address; any other is the NetworkTables server it connects to;
* when the connection ends it forgets the address too, and connects again 500 ms later. It
  never sends anything.

So this server sends one object when a client connects, and another whenever the robot's
address changes (the client keeps the last one: nothing needs repeating). The address is the
one the DS resolves for its robot: 127.TE.AM.2 in the loopback plan, 127.0.0.1 for WPILib's
simulator, 10.TE.AM.2 or the address an mDNS name (``roboRIO-TEAM-FRC.local``) resolved to; 0
while a name is not resolved yet, or when the robot's address is not IPv4.

The NI DS runs one per computer, so one server per field: :func:`serving_station` says which
DS it speaks for. It binds 127.0.0.1 only (dashboards ask on this computer; nothing outside
it is told anything) and never more than :data:`MAX_CLIENTS` clients; it reads nothing from them
(what a client sends is counted and thrown away; past :data:`MAX_RECEIVED` bytes it is no
dashboard and is dropped), and a client that does not read its objects is dropped once
:data:`MAX_BUFFERED` bytes wait for it: nothing a client does can hold the wire's loop.

Only one program can own port 1742: when another (a Driver Station already running, another
fieldbox) has it, :meth:`DsIpServer.start` says so once (:data:`IN_USE_NOTE`) and the field runs
on without it.
"""

from __future__ import annotations

import asyncio
import errno
import ipaddress
import json
import logging
from typing import Any, Callable

log = logging.getLogger("fieldbox.ds-ip-server")

#: Where WPILib's DsClient asks (2026 and before; the 2027 FIRST DS moves it to 6770).
DS_IP_PORT = 1742
#: The only address it binds: dashboards ask on this computer.
HOST = "127.0.0.1"
#: Clients at once (a few dashboards and tools; the NI DS's own limit is not known).
MAX_CLIENTS = 16
#: Bytes a client may send in all before it is dropped (a DsClient sends none).
MAX_RECEIVED = 4096
#: Bytes that may wait for a client that does not read before it is dropped (an object is
#: about 25 bytes, and one goes only when the address changes).
MAX_BUFFERED = 4096
#: How often the robot's address is looked at while clients are connected (a change of
#: --robot, an mDNS name resolved, the robot's status from a new host).
CHECK_EVERY = 0.25

#: Said once (log, stderr in headless mode, the app's problems) when another program has the port.
IN_USE_NOTE = ("TCP {port} is in use (another Driver Station?): dashboards will not find the robot "
               "through this one")


def ipv4_number(host: str | None) -> int:
    """``"10.2.54.2"`` -> 0x0A023602; 0 for None, a name, an IPv6 address or 0.0.0.0."""
    if not host:
        return 0
    try:
        ip = ipaddress.ip_address(str(host).split("%", 1)[0])
    except ValueError:
        return 0
    if isinstance(ip, ipaddress.IPv6Address):
        mapped = ip.ipv4_mapped
        return int(mapped) if mapped is not None else 0
    return int(ip)


def message(robot_ip: int) -> bytes:
    """One object as dashboards read it: ``{"robotIP":2130837506}`` (flat, no nested braces)."""
    return json.dumps({"robotIP": int(robot_ip)}, separators=(",", ":")).encode("ascii")


def robot_ip_of(ds: Any, resolved: Callable[[str], str | None] = lambda host: None) -> int:
    """The robot address a DS core resolves, as :func:`ipv4_number`: the host its robot's status
    comes from once there is one (an mDNS name's real answer), else the host it sends control
    to (an IP literal, or a name as the runtime resolved it: ``resolved``)."""
    link = ds.link
    for host in (link.robot_source, link.robot_udp[0]):
        number = ipv4_number(host)
        if not number and host:
            number = ipv4_number(resolved(str(host)))
        if number:
            return number
    return 0


def serving_station(stations: list, team: int | None) -> Any:
    """Which station's DS the server speaks for: that of ``team`` (--team) when it has one on
    this field, else the first station with a DS (R1 onwards); None when no DS runs."""
    with_ds = [st for st in stations if st.ds is not None]
    for st in with_ds:
        if st.team == team:
            return st
    return with_ds[0] if with_ds else None


def parse_port(text: str | None, plan: str) -> int | None:
    """``--ds-ip-server``: ``PORT`` or ``off``; None/empty is 1742 (in the ephemeral plan of
    the tests, a port the OS picks). None: no server."""
    if text is None or not str(text).strip():
        return 0 if plan == "ephemeral" else DS_IP_PORT
    text = str(text).strip().lower()
    if text in ("off", "none", "no"):
        return None
    try:
        port = int(text)
    except ValueError:
        raise ValueError(f"bad --ds-ip-server {text!r}: use PORT or off") from None
    if not 0 <= port <= 65535:
        raise ValueError(f"bad --ds-ip-server port {port}: 0..65535 (0: the OS picks)")
    return port


class _Client(asyncio.Protocol):
    def __init__(self, server: "DsIpServer") -> None:
        self.server = server
        self.transport: asyncio.Transport | None = None
        self.received = 0

    def connection_made(self, transport) -> None:
        self.transport = transport
        self.server._opened(self)

    def data_received(self, data: bytes) -> None:
        self.received += len(data)
        self.server.discarded += len(data)
        if self.received > MAX_RECEIVED:
            self.server._drop(self, f"it sent {self.received} bytes (a dashboard sends none)")

    def connection_lost(self, exc) -> None:
        self.server._closed(self)


class DsIpServer:
    """The service on an asyncio loop (the wire's): ``robot_ip`` says the address now, read on
    that loop only (it reads a DS core)."""

    def __init__(self, robot_ip: Callable[[], int], port: int = DS_IP_PORT, host: str = HOST) -> None:
        self.robot_ip = robot_ip
        self.port = port
        self.host = host
        self.address: tuple[str, int] | None = None  # where it listens, once started
        self.note: str | None = None  # why it does not run (the port is taken, ...)
        self.clients: set[_Client] = set()
        self.last_ip = 0  # what every client was last told
        # counters, for the curious and the tests
        self.accepted = 0
        self.refused = 0  # over MAX_CLIENTS
        self.dropped = 0  # sent too much, or read too little
        self.sent = 0  # objects
        self.discarded = 0  # bytes clients sent, thrown away
        self._server: asyncio.AbstractServer | None = None
        self._loop: asyncio.AbstractEventLoop | None = None
        self._check: asyncio.TimerHandle | None = None

    async def start(self) -> bool:
        """Listen; False (with :attr:`note` said once) when the port is taken or cannot be had."""
        self._loop = asyncio.get_running_loop()
        try:
            self._server = await self._loop.create_server(lambda: _Client(self), self.host, self.port,
                                                          reuse_address=True)
        except OSError as exc:
            if exc.errno == errno.EADDRINUSE:
                self.note = IN_USE_NOTE.format(port=self.port)
            else:
                self.note = (f"cannot listen on TCP {self.host}:{self.port} ({exc.strerror or exc}): "
                             "dashboards will not find the robot through this Driver Station")
            log.warning("%s", self.note)
            return False
        name = self._server.sockets[0].getsockname()
        self.address = (name[0], name[1])
        return True

    async def close(self) -> None:
        if self._check is not None:
            self._check.cancel()
            self._check = None
        for client in list(self.clients):
            if client.transport is not None:
                client.transport.abort()
        self.clients.clear()
        if self._server is not None:
            self._server.close()
            await self._server.wait_closed()
            self._server = None

    # -- clients -------------------------------------------------------------------------
    def _opened(self, client: _Client) -> None:
        if len(self.clients) >= MAX_CLIENTS:
            self.refused += 1
            if self.refused == 1 or self.refused % 100 == 0:
                log.warning("dashboards: %d at once already; one more refused (%d in all)", MAX_CLIENTS,
                            self.refused)
            assert client.transport is not None  # connection_made sets it before calling here
            client.transport.abort()
            return
        self.accepted += 1
        if self.clients:
            self.check()  # those connected already learn a change first: all are told the same
        else:
            self.last_ip = self._current()
        self.clients.add(client)
        self._send(client, message(self.last_ip))
        self._schedule()

    def _closed(self, client: _Client) -> None:
        self.clients.discard(client)

    def _drop(self, client: _Client, why: str) -> None:
        if client in self.clients:
            self.clients.discard(client)
            self.dropped += 1
            log.info("dashboards: a client dropped: %s", why)
        if client.transport is not None:
            client.transport.abort()

    def _send(self, client: _Client, data: bytes) -> None:
        transport = client.transport
        if transport is None or transport.is_closing():
            return
        transport.write(data)
        self.sent += 1
        if transport.get_write_buffer_size() > MAX_BUFFERED:
            self._drop(client, "it does not read what it is sent")

    # -- the robot's address ---------------------------------------------------------------
    def _current(self) -> int:
        try:
            return int(self.robot_ip())
        except Exception:  # noqa: BLE001 - a broken lookup tells dashboards "no robot", never ends the loop
            log.exception("dashboards: cannot say the robot's address")
            return 0

    def _schedule(self) -> None:
        if self._check is None and self.clients and self._loop is not None:
            self._check = self._loop.call_later(CHECK_EVERY, self._on_check)

    def _on_check(self) -> None:
        self._check = None
        self.check()
        self._schedule()

    def check(self) -> None:
        """Tell every client the robot's address if it changed since they were last told."""
        if not self.clients:
            return
        ip = self._current()
        if ip != self.last_ip:
            self.last_ip = ip
            data = message(ip)
            for client in list(self.clients):
                self._send(client, data)


__all__ = ["DS_IP_PORT", "DsIpServer", "IN_USE_NOTE", "ipv4_number", "message", "parse_port", "robot_ip_of",
           "serving_station"]
