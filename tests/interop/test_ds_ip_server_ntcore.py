"""WPILib's own client asks our DS where the robot is: robotpy's ntcore (pyntcore, a dependency
of wpilib), started as a dashboard in "Driver Station" mode is (``startClient4`` then
``startDSClient``), must end up connecting to the robot fieldbox names.

ntcore's DsClient asks 127.0.0.1:1742, fixed in its code, so the test runs in a private network
namespace (``unshare -rn``, as tests/roles/test_safety.py does) where 1742 is ours whatever
runs on this computer. There, fieldbox runs headless for team 254 (the loopback plan: its
robot is 127.2.54.2), and a listener on 127.2.54.2 stands in for the robot's NetworkTables
server: ntcore connecting to it is what a user sees as "the dashboard found the robot".
"""

from __future__ import annotations

import importlib.util
import json
import os
import shutil
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from ..netns import run_in_netns

pytestmark = pytest.mark.interop

ROOT = Path(__file__).resolve().parents[2]

PROBE = textwrap.dedent("""
    import json, socket, subprocess, sys
    subprocess.run(["ip", "link", "set", "lo", "up"], check=True)
    # ntcore looks the robot's address up with AI_ADDRCONFIG, which finds nothing where this
    # namespace has only loopback addresses: give it one more (this namespace's own, on lo).
    subprocess.run(["ip", "addr", "add", "192.0.2.1/32", "dev", "lo"], check=True)
    nt_server = socket.create_server(("127.2.54.2", 5810))  # the robot's NetworkTables, as ntcore sees it
    nt_server.settimeout(float(sys.argv[1]))
    args = sys.argv[2:]
    proc = subprocess.Popen([sys.executable, "-m", "fieldbox", "--headless", "--no-log-files", "--team", "254",
                             "--roles", "ds,rio,fms", *args], stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    bound = []
    while True:
        line = proc.stdout.readline()
        if not line.startswith("bound "):
            break
        bound.append(line.strip())
    import ntcore
    inst = ntcore.NetworkTableInstance.create()
    inst.startClient4("fieldbox-test")
    inst.startDSClient(5810)
    try:
        conn, peer = nt_server.accept()
        found = peer[0] + " -> " + "%s:%d" % conn.getsockname()
        conn.close()
    except OSError as exc:
        found = repr(exc)
    inst.stopDSClient()
    inst.stopClient()
    ntcore.NetworkTableInstance.destroy(inst)
    proc.stdin.write("quit\\n"); proc.stdin.flush()
    code = proc.wait(10)
    print(json.dumps({"found": found, "bound": bound, "rc": code, "stderr": proc.stderr.read()}))
""")


def _run(tmp_path: Path, wait: float, *args: str) -> dict:
    if importlib.util.find_spec("ntcore") is None:
        pytest.skip("robotpy's ntcore (pyntcore) is not installed: pip install 'fieldbox[interop]'")
    # (a namespace of its own: ntcore asks the fixed 127.0.0.1:1742)
    return run_in_netns(tmp_path, PROBE, str(wait), *args)


def test_ntcore_in_driver_station_mode_connects_to_the_robot_fieldbox_names(tmp_path):
    result = _run(tmp_path, 20, "--roles", "ds,rio")  # 20 s: a hang guard
    assert result["rc"] == 0, result["stderr"]
    assert "bound ds-ip-server: tcp 127.0.0.1:1742" in result["bound"]
    # ntcore asked our DS, was told 127.2.54.2 (team 254's robot), and connected there.
    assert result["found"].endswith("-> 127.2.54.2:5810"), result


def test_with_the_server_off_ntcore_finds_no_robot(tmp_path):
    # The same run without the service: nothing tells ntcore where to go in 5 s (ten of its
    # 500 ms retries), so the test above could not pass by accident.
    result = _run(tmp_path, 5, "--roles", "ds,rio", "--ds-ip-server", "off")
    assert result["rc"] == 0, result["stderr"]
    assert "timed out" in result["found"], result
