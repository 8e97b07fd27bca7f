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
