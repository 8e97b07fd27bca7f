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

from fieldbox.serve import INSTALL_HINT, TAB_ENV, app_command, tab_allows_path, tab_allows_plan

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
    # a robot program given to serve is every tab's (and only one given to serve)
    argv = shlex.split(app_command(run_options(robot_program="/srv/class/robot.py")))
    assert argv[argv.index("--robot-program") + 1] == "/srv/class/robot.py"
    assert "--robot-program" not in app_command(run_options())


def test_a_browser_tab_binds_no_other_plan_and_writes_only_captures(monkeypatch, tmp_path):
    monkeypatch.delenv(TAB_ENV, raising=False)
    assert all(tab_allows_plan(p) for p in ("loopback", "real", "ephemeral"))  # not a tab: anything
    assert tab_allows_path(tmp_path / "x.pcap", tmp_path / "captures")
    monkeypatch.setenv(TAB_ENV, "ephemeral")  # serve started without --net
    assert tab_allows_plan("loopback") and tab_allows_plan("ephemeral") and not tab_allows_plan("real")
    captures = tmp_path / "captures"
    assert tab_allows_path(captures / "a.pcap", captures)
    for elsewhere in (tmp_path / "a.pcap", captures / ".." / "a.pcap", Path.home() / ".bashrc"):
        assert not tab_allows_path(elsewhere, captures)
    monkeypatch.setenv(TAB_ENV, "real")  # serve --net real: the server was started that way
    assert tab_allows_plan("real")


class Lines:
    """A process's stdout lines, read on a thread (a pipe read never blocks the test)."""

    def __init__(self, stream) -> None:
        import queue
        import threading

        self.lines: queue.Queue = queue.Queue()
        threading.Thread(target=lambda: [self.lines.put(line) for line in stream], daemon=True).start()

    def wait_for(self, words: str, timeout: float = 20) -> str:
        import queue

        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            try:
                line = self.lines.get(timeout=0.1)
            except queue.Empty:
                continue
            if words in line:
                return line
        pytest.fail(f"no line with {words!r}")


def wait_for_page(proc: subprocess.Popen, port: int, query: str = "") -> str:
    deadline = time.monotonic() + 20
    while time.monotonic() < deadline:
        try:
            with urllib.request.urlopen(f"http://127.0.0.1:{port}/{query}", timeout=2) as reply:
                assert reply.status == 200
                return reply.read().decode()
        except (urllib.error.URLError, ConnectionError):
            if proc.poll() is not None:
                pytest.fail(f"fieldbox serve exited: {proc.communicate()[1]}")
            time.sleep(0.1)
    pytest.fail("no answer from fieldbox serve")


def http_status(url: str, **headers) -> int:
    try:
        with urllib.request.urlopen(urllib.request.Request(url, headers=headers), timeout=5) as reply:
            return reply.status
    except urllib.error.HTTPError as exc:
        return exc.code


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
    proc = fieldbox("serve", "--host", "127.0.0.1", "--port", str(port), "--team", "4242", "--no-token",
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


def test_serve_asks_for_its_token_and_refuses_other_sites():
    """Like Jupyter: a random token per start, printed in the URL; the page and its websocket
    need it (or the cookie the page sets); a websocket from another site's page is refused."""
    pytest.importorskip("textual_serve")
    import asyncio

    import aiohttp

    port = free_port()
    proc = fieldbox("serve", "--host", "127.0.0.1", "--port", str(port), "--team", "4243", start_new_session=True)
    try:
        line = Lines(proc.stdout).wait_for("?token=")
        token = line.split("?token=", 1)[1].split()[0]
        assert len(token) == 48 and int(token, 16) >= 0
        assert f"http://127.0.0.1:{port}/?token={token}" in line
        base = f"http://127.0.0.1:{port}"
        page = wait_for_page(proc, port, f"?token={token}")
        assert f"ws://127.0.0.1:{port}/ws/{token}" in page
        assert http_status(f"{base}/") == 403
        assert http_status(f"{base}/?token={'0' * 48}") == 403
        assert http_status(f"{base}/", Cookie=f"fieldbox-token-{port}={token}") == 200
        assert http_status(f"{base}/static/js/textual.js") == 200  # the page's own script: public

        async def tabs() -> dict[str, object]:
            out: dict[str, object] = {}
            async with aiohttp.ClientSession() as session:
                for name, url, headers in (
                        ("no token", f"ws://127.0.0.1:{port}/ws?width=80&height=24", {}),
                        ("wrong token", f"ws://127.0.0.1:{port}/ws/{'1' * 48}?width=80&height=24", {}),
                        ("another site", f"ws://127.0.0.1:{port}/ws/{token}?width=80&height=24",
                         {"Origin": "http://evil.example"})):
                    try:
                        async with session.ws_connect(url, headers=headers):
                            out[name] = "open"
                    except aiohttp.WSServerHandshakeError as exc:
                        out[name] = exc.status
                async with session.ws_connect(f"ws://127.0.0.1:{port}/ws/{token}?width=100&height=30",
                                              headers={"Origin": base}) as ws:
                    seen = b""
                    while b"team 4243" not in seen:
                        msg = await asyncio.wait_for(ws.receive(), 15)
                        if msg.type not in (aiohttp.WSMsgType.BINARY, aiohttp.WSMsgType.TEXT):
                            break
                        seen += msg.data if isinstance(msg.data, bytes) else msg.data.encode()
                    out["with the token"] = b"team 4243" in seen
            return out

        assert asyncio.run(tabs()) == {"no token": 403, "wrong token": 403, "another site": 403,
                                       "with the token": True}
        proc.send_signal(signal.SIGINT)
        assert proc.wait(timeout=10) == 0
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()


def test_a_classroom_gives_each_tab_its_seat_on_one_field():
    """serve --classroom: one field; the plain URL drives a free station, ``as=observer``
    watches, the teacher's URL (its own key) runs the FMS, a wrong key watches. Each tab's
    app says which seat it has; Ctrl+C ends the tabs and the field."""
    pytest.importorskip("textual_serve")
    import asyncio
    import re

    import aiohttp

    port = free_port()
    proc = fieldbox("serve", "--classroom", "--teams", "254,1114,2056,118,148,1678", "--host", "127.0.0.1",
                    "--port", str(port), start_new_session=True)
    try:
        lines = Lines(proc.stdout)
        student = re.search(r"http\S+", lines.wait_for("students", timeout=60)).group(0)
        observer_url = re.search(r"http\S+", lines.wait_for("watch only")).group(0)
        teacher_url = re.search(r"http\S+", lines.wait_for("teacher (")).group(0)
        token = student.split("token=")[1]
        key = teacher_url.split("teacher=")[1]
        assert observer_url == f"{student}&as=observer" and teacher_url == f"{student}&teacher={key}"
        assert key != token and len(key) == 32
        ws = f"ws://127.0.0.1:{port}/ws/{token}"
        assert f"{ws}/driver" in wait_for_page(proc, port, f"?token={token}")
        assert f"{ws}/observer" in wait_for_page(proc, port, f"?token={token}&as=observer")
        assert f"{ws}/teacher-{key}" in wait_for_page(proc, port, f"?token={token}&teacher={key}")

        async def tab(session, path: str) -> bytes:
            async with session.ws_connect(f"{ws}/{path}?width=120&height=40") as sock:
                seen = b""
                while b"classroom: you" not in seen or b"team 254" not in seen:
                    msg = await asyncio.wait_for(sock.receive(), 60)
                    if msg.type not in (aiohttp.WSMsgType.BINARY, aiohttp.WSMsgType.TEXT):
                        break
                    seen += msg.data if isinstance(msg.data, bytes) else msg.data.encode()
                return seen

        async def tabs() -> list[bytes]:
            async with aiohttp.ClientSession() as session:
                return await asyncio.gather(*(tab(session, path) for path in (
                    f"teacher-{key}", "driver", "observer", f"teacher-{'0' * 32}")))

        teacher, driver, observer, wrong = asyncio.run(tabs())
        assert b"classroom: you are the teacher" in teacher
        assert b"classroom: you drive team 254" in driver
        assert b"classroom: you watch" in observer and b"classroom: you watch" in wrong
        proc.send_signal(signal.SIGINT)
        assert proc.wait(timeout=20) == 0
        assert "left: driver of team 254" in proc.stderr.read()  # the field saw its driver go
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()


async def test_in_a_browser_tab_the_picker_offers_no_real_plan_and_captures_stay_in_their_folder(
        monkeypatch, tmp_path):
    from textual.widgets import Select

    from fieldbox.panels import inspector
    from fieldbox.picker import RolePicker
    from roles.runtime.field import FieldConfig

    from .helpers import make_app, step

    monkeypatch.setenv(TAB_ENV, "ephemeral")
    captures = tmp_path / "captures"
    monkeypatch.setattr(inspector, "default_capture_dir", lambda: captures)
    app, _ = make_app(FieldConfig(team=254, plan="ephemeral"), "inspector")
    async with app.run_test(size=(120, 40)) as pilot:
        await step(pilot, 1.0)
        await pilot.press("f8")
        await pilot.pause()
        picker = app.screen
        assert isinstance(picker, RolePicker)
        plan = picker.query_one("#plan", Select)
        assert [value for _, value in plan._options if value is not Select.BLANK] == ["loopback", "ephemeral"]
        await pilot.press("escape")
        await pilot.pause()
        panel = app.query_one(inspector.InspectorPanel)
        assert panel.export(tmp_path / "elsewhere.pcap") is None and not (tmp_path / "elsewhere.pcap").exists()
        await pilot.pause()
        assert any("capture folder" in str(n.message) for n in app._notifications)
        assert panel.export(captures / "ok.pcap") is not None and (captures / "ok.pcap").exists()


def descendants(pid: int) -> set[int]:
    """Every process under ``pid``, from /proc."""
    children: dict[int, list[int]] = {}
    for entry in os.listdir("/proc"):
        if entry.isdigit():
            try:
                with open(f"/proc/{entry}/stat") as f:
                    ppid = int(f.read().rpartition(")")[2].split()[1])
            except (OSError, ValueError, IndexError):
                continue
            children.setdefault(ppid, []).append(int(entry))
    out, todo = set(), [pid]
    while todo:
        for child in children.get(todo.pop(), []):
            out.add(child)
            todo.append(child)
    return out


def name_of(pid: int) -> str:
    try:
        return Path(f"/proc/{pid}/comm").read_text().strip()
    except OSError:
        return "(gone)"


def alive(pid: int) -> bool:
    try:
        with open(f"/proc/{pid}/stat") as f:
            return f.read().rpartition(")")[2].split()[0] != "Z"
    except OSError:
        return False


@pytest.mark.skipif(not os.path.isdir("/proc"), reason="reads /proc")
def test_a_killed_server_leaves_no_field_and_no_tab_running():
    """The server dies without a word (SIGKILL, a crash) while a tab is open: the classroom's
    field and the tab's app notice their server is gone and end, not draw and drive for ever."""
    pytest.importorskip("textual_serve")
    import asyncio
    import re

    import aiohttp

    port = free_port()
    proc = fieldbox("serve", "--classroom", "--teams", "254,1114,2056,118,148,1678", "--host", "127.0.0.1",
                    "--port", str(port), start_new_session=True)
    try:
        lines = Lines(proc.stdout)
        token = re.search(r"http\S+", lines.wait_for("students", timeout=60)).group(0).split("token=")[1]
        wait_for_page(proc, port, f"?token={token}")

        async def tab_then_kill() -> set[int]:
            async with aiohttp.ClientSession() as session:
                async with session.ws_connect(f"ws://127.0.0.1:{port}/ws/{token}/driver?width=100&height=30") as sock:
                    seen = b""
                    while b"classroom: you" not in seen:
                        msg = await asyncio.wait_for(sock.receive(), 60)
                        assert msg.type in (aiohttp.WSMsgType.BINARY, aiohttp.WSMsgType.TEXT), msg
                        seen += msg.data if isinstance(msg.data, bytes) else msg.data.encode()
                    left = descendants(proc.pid)
                    names = {pid: name_of(pid) for pid in left}
                    os.kill(proc.pid, signal.SIGKILL)
                    return left, names

        left, names = asyncio.run(tab_then_kill())
        # the tab's app, forked from the classroom's warm interpreter (fieldbox/tabfork.py)
        assert "fb-tab-driver" in names.values(), names
        deadline = time.monotonic() + 60
        while any(alive(pid) for pid in left) and time.monotonic() < deadline:
            time.sleep(0.2)
        still = {pid: names[pid] for pid in left if alive(pid)}
        assert not still, still
    finally:
        try:
            os.killpg(proc.pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
        proc.wait()
