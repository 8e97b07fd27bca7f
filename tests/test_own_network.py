"""The suite runs in a network namespace of its own (tests/conftest.py), so a fieldbox or a
simulator already running on the machine cannot take its ports, and nothing it sends leaves
the machine (issue 31, item 6)."""

import socket

import pytest


def test_the_suite_sees_only_its_own_loopback(pytestconfig):
    if not getattr(pytestconfig, "_fieldbox_own_network", False):
        pytest.skip("no network namespace could be made here (see the header of the run)")
    assert [name for _, name in socket.if_nameindex()] == ["lo"]
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:  # loopback is up: the FMS's address binds
        s.bind(("127.0.100.5", 1160))
