"""Conformance runs bind the real FRC ports on loopback addresses of their own (127.99.x.x,
teams 99xx of the loopback plan), which only Linux routes to this machine."""

from __future__ import annotations

import socket
import sys

import pytest


def loopback_free(*addresses: tuple[str, int, int]) -> bool:
    """Whether each (host, port, SOCK_*) can be bound now."""
    for host, port, kind in addresses:
        s = socket.socket(socket.AF_INET, kind)
        s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            s.bind((host, port))
        except OSError:
            return False
        finally:
            s.close()
    return True


@pytest.fixture
def linux_loopback():
    if not sys.platform.startswith("linux"):
        pytest.skip("these runs use 127.99.x.x addresses, which only Linux routes to this machine")


async def station_blind_fms(host: str):
    """A wrong-station-blind FMS on TCP 1750 at ``host``: every login gets station info
    status 0 (good) at R1, as Cheesy Arena answers a login from an address that is not a
    field's 10.TE.AM.x. Returns the asyncio server (close it)."""
    import asyncio

    async def serve(reader, writer):
        try:
            await reader.readexactly(5)  # 00 03 18 hi lo, the login
            writer.write(bytes.fromhex("0003190000"))
            await writer.drain()
            await reader.read()
        except (OSError, asyncio.IncompleteReadError):
            pass
        finally:
            writer.close()

    return await asyncio.start_server(serve, host, 1750)
