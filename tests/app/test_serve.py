"""``fieldbox serve``: the browser server starts, serves its page, stops; without
textual-serve it says what to install."""

from __future__ import annotations

import os
import shlex
import signal
import socket
import subprocess
import sys
import time
import urllib.error
import urllib.request
from pathlib import Path
from types import SimpleNamespace

import pytest

from fieldbox.serve import INSTALL_HINT, app_command

ROOT = Path(__file__).resolve().parents[2]


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def fieldbox(*args: str, **kw) -> subprocess.Popen:
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    return subprocess.Popen([sys.executable, "-m", "fieldbox", *args], cwd=ROOT, env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, **kw)


def run_options(**given) -> SimpleNamespace:
    base = dict(roles=None, team=None, station=None, robot=None, fms=None, net=None, teams=None,
                legacy_2010=False, theme=None, fault=None, headless=False)
    return SimpleNamespace(**{**base, **given})


def test_each_tab_runs_fieldbox_on_ephemeral_ports_with_the_users_options():
    argv = shlex.split(app_command(run_options(team=254, roles="ds,rio", theme="projector-light",
                                               fault=["ds-rio:loss=10%"])))
    assert argv[:3] == [sys.executable, "-m", "fieldbox"]
    assert argv[3:5] == ["--net", "ephemeral"]
    assert argv[argv.index("--team") + 1] == "254"
    assert argv[argv.index("--roles") + 1] == "ds,rio"
    assert argv[argv.index("--theme") + 1] == "projector-light"
    assert argv[argv.index("--fault") + 1] == "ds-rio:loss=10%"
    # a --net the user chose is kept
    argv = shlex.split(app_command(run_options(net="real", robot="10.2.54.2")))
    assert argv.count("--net") == 1 and argv[argv.index("--net") + 1] == "real"


def wait_for_page(proc: subprocess.Popen, port: int) -> str:
    deadline = time.monotonic() + 20
    while time.monotonic() < deadline:
        try:
            with urllib.request.urlopen(f"http://127.0.0.1:{port}/", timeout=2) as reply:
                assert reply.status == 200
                return reply.read().decode()
        except (urllib.error.URLError, ConnectionError):
            if proc.poll() is not None:
                pytest.fail(f"fieldbox serve exited: {proc.communicate()[1]}")
            time.sleep(0.1)
    pytest.fail("no answer from fieldbox serve")


def test_serve_answers_http_runs_a_field_per_tab_and_stops():
    """One server on an OS-chosen port: the page, then a browser tab (a websocket) that gets
    its own fieldbox process on ephemeral ports, then Ctrl+C with the tab still open ends the
    server and the tab's app."""
    pytest.importorskip("textual_serve")
    if not os.path.isdir("/proc/self"):
        pytest.skip("finds the tabs' processes in /proc")
    import asyncio

    import aiohttp

    port = free_port()
    proc = fieldbox("serve", "--host", "127.0.0.1", "--port", str(port), "--team", "4242",
                    start_new_session=True)

    def tab_processes() -> list[str]:
        # each process's whole command line from /proc: ps cuts lines at the terminal's width
        found = []
        for entry in os.listdir("/proc"):
            try:
                with open(f"/proc/{entry}/cmdline", "rb") as f:
                    line = f.read().replace(b"\0", b" ").decode(errors="replace")
            except OSError:
                continue
            if "--team 4242" in line and " serve " not in line and "/bin/sh" not in line:
                found.append(f"{entry} {line}")
        return found

    async def browser_tab() -> tuple[bytes, list[str]]:
        async with aiohttp.ClientSession() as session:
            async with session.ws_connect(f"http://127.0.0.1:{port}/ws?width=100&height=30") as ws:
                seen = b""
                while b"ephemeral" not in seen:
                    msg = await asyncio.wait_for(ws.receive(), 15)
                    if msg.type not in (aiohttp.WSMsgType.BINARY, aiohttp.WSMsgType.TEXT):
                        break
                    seen += msg.data if isinstance(msg.data, bytes) else msg.data.encode()
                running = tab_processes()
                proc.send_signal(signal.SIGINT)  # Ctrl+C, with the tab still open
                return seen, running

    try:
        page = wait_for_page(proc, port)
        assert "<html" in page.lower() and f"ws://127.0.0.1:{port}/ws" in page and "fieldbox" in page
        seen, running = asyncio.run(browser_tab())
        assert b"team 4242" in seen and b"ephemeral" in seen  # the app's header, drawn in the tab
        assert len(running) == 1 and "--net ephemeral" in running[0]
        assert proc.wait(timeout=10) == 0
        deadline = time.monotonic() + 5
        while tab_processes() and time.monotonic() < deadline:
            time.sleep(0.1)
        assert tab_processes() == []
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()


def test_without_textual_serve_says_what_to_install():
    code = ("import sys; sys.modules['textual_serve'] = None; sys.modules['textual_serve.server'] = None\n"
            "from fieldbox.cli import main; sys.exit(main(['serve']))")
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    done = subprocess.run([sys.executable, "-c", code], cwd=ROOT, env=env, capture_output=True, text=True,
                          timeout=30)
    assert done.returncode == 1
    assert done.stderr.strip() == INSTALL_HINT
    assert "pip install 'fieldbox[serve]'" in done.stderr
