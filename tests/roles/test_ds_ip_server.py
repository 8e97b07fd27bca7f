"""Dashboards ask our DS where the robot is (roles/runtime/ds_ip_server.py): the JSON they read
over TCP, a robot that moves, the bounds, and a port another program has. WPILib's own
client (ntcore's startDSClient) is in tests/interop/test_ds_ip_server_ntcore.py."""

from __future__ import annotations

import asyncio
import ipaddress
import json
import logging
import os
import shutil
import socket
import subprocess
import sys
import textwrap
import time
from pathlib import Path
from types import SimpleNamespace

import pytest

from protocol.enums import AllianceStation
from roles.runtime import ds_ip_server as D
from roles.runtime.field import Field, FieldConfig, StationRoles
from roles.runtime.shell import Runtime

from ..netns import run_in_netns

ROOT = Path(__file__).resolve().parents[2]


def _number(ip: str) -> int:
    return int(ipaddress.IPv4Address(ip))


async def _read_object(reader: asyncio.StreamReader) -> dict:
    """One object as WPILib's DsClient splits them: from a ``{`` to the next ``}``."""
    data = await asyncio.wait_for(reader.readuntil(b"}"), 10)
    return json.loads(data[data.index(b"{"):])


async def _field(**config) -> tuple[Runtime, Field]:
    runtime = Runtime()
    field = Field(FieldConfig(plan="ephemeral", **config))
    await field.start(runtime)
    runtime.start()
    return runtime, field


async def test_a_dashboard_reads_the_robots_address_as_a_number_and_again_when_it_moves():
    runtime, field = await _field(roles=frozenset({"ds"}), team=254, robot="127.2.54.2")
    try:
        host, port = field.ds_ip_server.address
        assert host == "127.0.0.1" and port > 0  # the OS's port in the ephemeral plan, said:
        assert f"ds-ip-server: tcp 127.0.0.1:{port}" in field.describe_bound()
        reader, writer = await asyncio.open_connection(host, port)
        assert await _read_object(reader) == {"robotIP": _number("127.2.54.2")}  # 0x7F023602
        # The operator points the DS at another robot: every dashboard is told, unasked.
        ds = field.stations[0].ds
        ds.set_robot_addresses(runtime.clock(), robot_udp=("127.11.14.2", 1110))
        assert await _read_object(reader) == {"robotIP": _number("127.11.14.2")}
        # A second dashboard gets the address now on connecting.
        reader2, writer2 = await asyncio.open_connection(host, port)
        assert await _read_object(reader2) == {"robotIP": _number("127.11.14.2")}
        for w in (writer, writer2):
            w.close()
    finally:
        await runtime.close()
    # Closed with the field: no dashboard is told a stale address.
    with pytest.raises(OSError):
        socket.create_connection((host, port), timeout=2).close()


async def test_the_bounds_sixteen_dashboards_and_one_that_talks_too_much_is_dropped():
    runtime, field = await _field(roles=frozenset({"ds"}), team=254, robot="10.2.54.2")
    streams = []
    try:
        host, port = field.ds_ip_server.address
        for _ in range(D.MAX_CLIENTS):
            reader, writer = await asyncio.open_connection(host, port)
            assert await _read_object(reader) == {"robotIP": _number("10.2.54.2")}
            streams.append((reader, writer))
        # The seventeenth is closed unanswered; the sixteen stay.
        reader, writer = await asyncio.open_connection(host, port)
        assert await asyncio.wait_for(reader.read(100), 10) == b""
        writer.close()
        assert field.ds_ip_server.refused == 1 and len(field.ds_ip_server.clients) == D.MAX_CLIENTS
        # One sends more than a dashboard ever would: it is dropped, its bytes never kept.
        talker_reader, talker = streams[0]
        talker.write(b"x" * (D.MAX_RECEIVED + 1))
        await talker.drain()
        assert await asyncio.wait_for(talker_reader.read(100), 10) == b""
        assert field.ds_ip_server.dropped == 1
        # ... which frees a place for a dashboard.
        reader, writer = await asyncio.open_connection(host, port)
        assert await _read_object(reader) == {"robotIP": _number("10.2.54.2")}
        streams.append((reader, writer))
    finally:
        for _, w in streams:
            w.close()
        await runtime.close()


async def test_a_port_another_program_has_is_said_once_and_the_field_runs_on(caplog):
    taken = socket.create_server(("127.0.0.1", 0))  # another Driver Station
    port = taken.getsockname()[1]
    caplog.set_level(logging.WARNING)
    runtime, field = await _field(team=254, roles=frozenset({"ds", "rio"}), ds_ip_server=str(port))
    try:
        note = f"TCP {port} is in use (another Driver Station?): dashboards will not find the robot through this one"
        assert field.ds_ip_server is None and field.ds_ip_note == note
        assert [r.getMessage() for r in caplog.records if r.levelno >= logging.WARNING] == [note]
        ds = field.stations[0].ds
        deadline = time.monotonic() + 20  # a hang guard on a busy machine
        while not ds.link.robot_comms and time.monotonic() < deadline:
            await asyncio.sleep(0.05)
        assert ds.link.robot_comms  # the DS drives its robot all the same
    finally:
        await runtime.close()
        taken.close()


async def test_off_and_the_2010_ds_serve_no_dashboards():
    for config in ({"ds_ip_server": "off"}, {"legacy": True}):
        runtime, field = await _field(team=254, roles=frozenset({"ds"}), **config)
        try:
            assert field.ds_ip_server is None and field.ds_ip_note is None
            assert not any(line.startswith("ds-ip-server") for line in field.describe_bound())
        finally:
            await runtime.close()


def test_which_ds_a_full_field_serves_and_what_address_it_resolves():
    ds = SimpleNamespace(link=SimpleNamespace(robot_source=None, robot_udp=("roboRIO-254-FRC.local", 1110)))
    stations = [StationRoles(AllianceStation(i), t, ds=ds) for i, t in enumerate((254, 1114, 2056))]
    assert D.serving_station(stations, 1114).team == 1114  # --team's DS
    assert D.serving_station(stations, 9999).team == 254  # else R1's
    assert D.serving_station([StationRoles(AllianceStation.RED1, 254)], 254) is None  # no DS here
    # An mDNS name: 0 until the runtime resolves it, then its address; then where status comes from.
    assert D.robot_ip_of(ds) == 0
    assert D.robot_ip_of(ds, {"roboRIO-254-FRC.local": "10.2.54.2"}.get) == _number("10.2.54.2")
    ds.link.robot_source = "10.2.54.9"
    assert D.robot_ip_of(ds, {"roboRIO-254-FRC.local": "10.2.54.2"}.get) == _number("10.2.54.9")
    assert D.robot_ip_of(SimpleNamespace(link=SimpleNamespace(robot_source=None, robot_udp=("::1", 1110)))) == 0
    assert D.message(_number("10.2.54.2")) == b'{"robotIP":167917058}'
    with pytest.raises(ValueError, match="--ds-ip-server"):
        D.parse_port("17x", "loopback")
    assert (D.parse_port(None, "loopback"), D.parse_port(None, "ephemeral"), D.parse_port("off", "real")) == \
        (1742, 0, None)


SECOND_DS_PROBE = textwrap.dedent("""
    import json, subprocess, sys, time
    subprocess.run(["ip", "link", "set", "lo", "up"], check=True)

    def start(team):
        proc = subprocess.Popen([sys.executable, "-m", "fieldbox", "--headless", "--no-log-files", "--team", team,
                                 "--roles", "ds,rio"], stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                                stderr=subprocess.PIPE, text=True)
        bound = []
        while True:
            line = proc.stdout.readline()
            if not line.startswith("bound "):
                return proc, bound, line
            bound.append(line.strip())

    first, first_bound, _ = start("254")
    second, second_bound, status = start("1114")  # a status line: it runs
    for proc in (second, first):
        proc.stdin.write("quit\\n"); proc.stdin.flush()
    codes = [second.wait(10), first.wait(10)]
    print(json.dumps({"first": first_bound, "second": second_bound, "status": status, "codes": codes,
                      "second_stderr": second.stderr.read(), "first_stderr": first.stderr.read()}))
""")


def test_a_second_fieldbox_says_1742_is_taken_and_drives_its_robot_all_the_same(tmp_path):
    result = run_in_netns(tmp_path, SECOND_DS_PROBE, timeout=60)
    assert result["codes"] == [0, 0], result
    assert "bound ds-ip-server: tcp 127.0.0.1:1742" in result["first"]
    assert not any("ds-ip-server" in line for line in result["second"])
    assert any(line.startswith("bound ds 1114:") for line in result["second"])
    said = [line for line in result["second_stderr"].splitlines() if "1742" in line]
    assert len(said) == 1 and said[0].endswith(
        "TCP 1742 is in use (another Driver Station?): dashboards will not find the robot through this one")
    assert "1742" not in result["first_stderr"]
    assert result["status"].strip()  # it went on to its status lines


async def test_a_dashboard_that_does_not_read_is_dropped_and_the_others_are_told_on():
    robot = [_number("10.2.54.2")]
    server = D.DsIpServer(lambda: robot[0], port=0)
    assert await server.start()
    host, port = server.address
    try:
        reader, writer = await asyncio.open_connection(host, port)
        assert await _read_object(reader) == {"robotIP": robot[0]}
        stuck = socket.socket()  # a client that never reads, with small buffers on both sides
        stuck.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 1024)
        stuck.connect((host, port))
        deadline = time.monotonic() + 10
        while len(server.clients) < 2 and time.monotonic() < deadline:
            await asyncio.sleep(0.01)
        (stuck_side,) = [c for c in server.clients if c.transport.get_extra_info("peername") == stuck.getsockname()]
        stuck_side.transport.get_extra_info("socket").setsockopt(socket.SOL_SOCKET, socket.SO_SNDBUF, 1024)
        told = []
        for i in range(3000):  # the robot's address changes far more often than any robot's would
            robot[0] = _number("10.2.54.2") + i + 1
            told.append(robot[0])
            server.check()
            if stuck_side not in server.clients:
                break
            if i % 50 == 0:
                await asyncio.sleep(0)  # the reading dashboard reads meanwhile
        assert stuck_side not in server.clients and server.dropped == 1
        # The one that reads was told every address, in order; the loop never waited on the other.
        assert [(await _read_object(reader))["robotIP"] for _ in told] == told
        writer.close()
        stuck.close()
    finally:
        await server.close()


def test_the_app_is_told_the_port_is_taken_among_its_problems():
    from roles.runtime.engine import ThreadEngine

    taken = socket.create_server(("127.0.0.1", 0))
    port = taken.getsockname()[1]
    engine = ThreadEngine(FieldConfig(roles=frozenset({"ds", "rio"}), team=254, plan="ephemeral",
                                      ds_ip_server=str(port), log_files=False))
    try:
        engine.start()
        assert engine.problems == [D.IN_USE_NOTE.format(port=port)]
    finally:
        engine.stop()
        taken.close()
