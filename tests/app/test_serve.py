"""``fieldbox serve``: the browser server starts, serves its page, stops; without
textual-serve it says what to install."""

from __future__ import annotations

import os
import re
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

from fieldbox.serve import (INSTALL_HINT, MAX_HEIGHT, MAX_WIDTH, TAB_ENV, app_command, replay_command,
                            replay_refusal, screen_size, tab_allows_path, tab_allows_plan)

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


def test_a_replay_tab_runs_fieldbox_replay_of_the_capture_with_the_theme_only():
    argv = shlex.split(replay_command(run_options(theme="projector-light"), "/srv/class/match 1.pcapng"))
    assert argv == [sys.executable, "-m", "fieldbox", "--theme", "projector-light", "replay", "/srv/class/match 1.pcapng"]
    assert shlex.split(replay_command(run_options(), "/x.pcap"))[3:] == ["replay", "/x.pcap"]
    # serve --replay F --speed 5 --paused: every tab opens paused, at 5x
    assert shlex.split(replay_command(run_options(speed=5.0, paused=True), "/x.pcap"))[3:] == [
        "replay", "/x.pcap", "--speed", "5.0", "--paused"]
    assert shlex.split(replay_command(run_options(speed=1.0, paused=False), "/x.pcap"))[3:] == ["replay", "/x.pcap"]
    assert replay_refusal(run_options(theme="alliance")) is None
    why = replay_refusal(run_options(classroom=True, net="real", legacy_2010=True))
    assert why is not None and "runs no field: leave out --classroom, --net and --legacy-2010 " in why


def test_a_terminal_size_is_what_a_screen_shows_or_none():
    assert screen_size(100, 30) == (100, 30)
    assert screen_size(3000, 3000) == (MAX_WIDTH, MAX_HEIGHT) == (500, 200)
    assert screen_size(0, -5) == (1, 1) and screen_size("120", 40.9) == (120, 40)
    for width, height in ((None, 30), ("wide", 30), (True, 30), (float("inf"), 30), ([1], 2)):
        assert screen_size(width, height) is None, (width, height)


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
        # a classroom is often offline: the page asks no other host for anything (textual-serve's
        # own asked fonts.googleapis.com for its font); an SVG's namespace is a name, not a fetch
        hosts = set(re.findall(r"(?:https?|wss?)://([^/\"'\s:]+)", re.sub(r'xmlns="[^"]*"', "", page)))
        assert hosts == {"127.0.0.1"}, hosts
        fonts = re.findall(r'url\("([^"]+\.ttf)"\)', page)
        assert fonts and all(http_status(font) == 200 for font in fonts), fonts  # the font, from the server
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


TEAMS = "254,1114,2056,118,148,1678"


def classroom_urls(lines: Lines) -> dict[str, str]:
    """The three URLs ``serve --classroom`` prints: students, watch only, teacher."""
    return {name: re.search(r"http\S+", lines.wait_for(words, timeout=60 if name == "students" else 20)).group(0)
            for name, words in (("students", "students"), ("observer", "watch only"), ("teacher", "teacher ("))}


async def screen_until(sock, *wanted: bytes, timeout: float = 60) -> bytes:
    """What a tab draws, until every one of ``wanted`` is in it (or the tab closes, or a hang
    guard of ``timeout`` seconds passes: the caller's asserts then say what is missing)."""
    import asyncio

    import aiohttp

    seen = b""
    deadline = time.monotonic() + timeout
    while not all(w in seen for w in wanted):
        try:
            msg = await asyncio.wait_for(sock.receive(), max(deadline - time.monotonic(), 0.01))
        except asyncio.TimeoutError:
            break
        if msg.type not in (aiohttp.WSMsgType.BINARY, aiohttp.WSMsgType.TEXT):
            break
        seen += msg.data if isinstance(msg.data, bytes) else msg.data.encode()
    return seen


_MOVE = re.compile(rb"\x1b\[(\d+);(\d+)H")
_ESCAPE = re.compile(r"\x1b\[[0-9;:?$]*[A-Za-z]|\x1b\][^\x07]*\x07|[\r\n]")


def whole_screens(output: bytes) -> list[tuple[int, int]]:
    """The size, (columns, rows), of each whole screen a tab drew: Textual repaints a whole
    screen as a move to the first column of row 1, its cells, then row 2, ... to the last row;
    a screen is whole when a move anywhere else comes after it."""
    from rich.cells import cell_len

    moves = list(_MOVE.finditer(output))
    screens, run = [], []  # run: the visible width of each row of the screen being drawn
    for move, after in zip(moves, moves[1:]):
        row, column = int(move.group(1)), int(move.group(2))
        if column == 1 and row == len(run) + 1:
            text = output[move.end():after.start()].decode(errors="replace")
            run.append(cell_len(_ESCAPE.sub("", text)))
            continue
        if run:
            screens.append((max(run), len(run)))
        run = [cell_len(_ESCAPE.sub("", output[move.end():after.start()].decode(errors="replace")))] \
            if (row, column) == (1, 1) else []
    return screens


async def whole_screen(sock, fits, timeout: float = 60) -> tuple[int, int]:
    """The first whole screen a tab draws from now on whose size ``fits``: (columns, rows)."""
    import asyncio

    import aiohttp

    seen = b""
    deadline = time.monotonic() + timeout  # a hang guard: the tab keeps drawing what it shows
    while True:
        msg = await asyncio.wait_for(sock.receive(), max(deadline - time.monotonic(), 0.01))
        assert msg.type == aiohttp.WSMsgType.BINARY, msg
        seen += msg.data
        for size in whole_screens(seen):
            if fits(*size):
                return size


def test_a_classroom_tab_has_the_seat_of_its_token_whatever_its_url_says():
    """serve --classroom prints three URLs, each with a token of its own: the students' drives a
    free station, the observers' watches, the teacher's runs the FMS. The seat is the token's:
    an observer's URL edited (a seat in the websocket's path or in the query, as ``as=`` once
    did) still watches, and a token the server did not give gets nothing. Each tab says which
    seat it has; its title says what the field is (the classroom's teams, not the joining
    app's defaults); Ctrl+C ends the tabs and the field."""
    pytest.importorskip("textual_serve")
    import asyncio

    import aiohttp

    port = free_port()
    proc = fieldbox("serve", "--classroom", "--teams", TEAMS, "--host", "127.0.0.1", "--port", str(port),
                    start_new_session=True)
    try:
        urls = classroom_urls(Lines(proc.stdout))
        base = f"http://127.0.0.1:{port}"
        tokens = {name: url.removeprefix(f"{base}/?token=") for name, url in urls.items()}
        assert all(url == f"{base}/?token={tokens[name]}" for name, url in urls.items()), urls  # nothing else in them
        assert len(set(tokens.values())) == 3 and all(int(t, 16) >= 0 for t in tokens.values())
        assert len(tokens["students"]) == len(tokens["observer"]) == 48 and len(tokens["teacher"]) == 32
        ws = f"ws://127.0.0.1:{port}/ws"
        for name, token in tokens.items():  # each page's websocket carries its own token, no seat
            page = wait_for_page(proc, port, f"?token={token}&as=driver")
            assert f'"{ws}/{token}"' in page, name
        assert http_status(f"{base}/?token={'0' * 48}&as=observer") == 403

        async def tab(session, url: str, *wanted: bytes, **headers) -> bytes | int:
            try:
                async with session.ws_connect(url, headers=headers) as sock:
                    return await screen_until(sock, b"classroom: you", *wanted)
            except aiohttp.WSServerHandshakeError as exc:
                return exc.status

        size = "width=120&height=40"
        title = f"classroom ds+rio+fms team {TEAMS} ephemeral".encode()

        async def tabs() -> list:
            async with aiohttp.ClientSession() as session:
                return await asyncio.gather(
                    tab(session, f"{ws}/{tokens['teacher']}?{size}", title),
                    tab(session, f"{ws}/{tokens['students']}?{size}", b"team 254"),
                    tab(session, f"{ws}/{tokens['observer']}?{size}", title),
                    # the observer's URL edited: the seat asked for in the query, in the path
                    tab(session, f"{ws}/{tokens['observer']}?{size}&as=driver&seat=driver"),
                    tab(session, f"{ws}/{tokens['observer']}/driver?{size}"),
                    tab(session, f"{ws}?{size}&as=driver", Cookie=f"fieldbox-token-{port}={tokens['observer']}"),
                    tab(session, f"{ws}/{tokens['students']}/teacher-{tokens['teacher']}?{size}"),
                    tab(session, f"{ws}/{'0' * 48}?{size}"))

        teacher, driver, observer, edited, seat_in_path, cookie, old_teacher, wrong = asyncio.run(tabs())
        assert b"classroom: you are the teacher" in teacher
        assert b"classroom: you drive team 254" in driver
        for watching in (observer, edited, cookie):  # the observer's token, wherever it is shown
            assert b"classroom: you watch" in watching and b"classroom: you drive" not in watching
        assert (seat_in_path, old_teacher, wrong) == (403, 403, 403)  # no seat but the token's: refused
        # the title says what the field is: its teams, not "team 1 loopback" (the joining
        # command line's defaults)
        assert title in teacher and title in observer
        assert b"team 1 loopback" not in teacher
        proc.send_signal(signal.SIGINT)
        assert proc.wait(timeout=20) == 0
        assert "left: driver of team 254" in proc.stderr.read()  # the field saw its driver go
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()


def test_a_classroom_refuses_tabs_over_its_caps_and_the_open_ones_play_on():
    """Each tab is a process: ``--max-tabs`` in all and ``--tabs-per-client`` from one address
    (here 3 and 2, for a light test). One more is refused with a page, or a websocket close,
    that says why; the open tabs and the field go on; the teacher still gets in; a tab that
    closes frees its place."""
    pytest.importorskip("textual_serve")
    import asyncio

    import aiohttp

    port = free_port()
    proc = fieldbox("serve", "--classroom", "--teams", TEAMS, "--host", "127.0.0.1", "--port", str(port),
                    "--max-tabs", "3", "--tabs-per-client", "2", start_new_session=True)
    try:
        lines = Lines(proc.stdout)
        urls = classroom_urls(lines)
        student, teacher_token = urls["students"].split("token=")[1], urls["teacher"].split("token=")[1]
        ws = f"ws://127.0.0.1:{port}/ws"
        wait_for_page(proc, port, f"?token={student}")

        async def refused(session) -> tuple[int | None, bytes]:
            """A tab that is refused: how its websocket closed, and what it showed."""
            async with session.ws_connect(f"{ws}/{student}?width=100&height=30") as sock:
                shown = await screen_until(sock, b"classroom: you")  # until it closes, or (not refused) its seat
                return sock.close_code, shown

        async def run() -> dict[str, object]:
            out: dict[str, object] = {}
            # three client addresses, all loopback (the whole of 127.0.0.0/8 is)
            one, two, three = (aiohttp.ClientSession(connector=aiohttp.TCPConnector(local_addr=(f"127.0.0.{n}", 0)))
                               for n in (1, 2, 3))
            try:
                first = await one.ws_connect(f"{ws}/{student}?width=100&height=30")
                second = await one.ws_connect(f"{ws}/{student}?width=100&height=30")
                out["first"] = await screen_until(first, b"classroom: you drive")
                out["second"] = await screen_until(second, b"classroom: you drive")
                out["third from one address"] = await refused(one)
                async with one.get(f"http://127.0.0.1:{port}/?token={student}") as page:
                    out["its page"] = page.status, await page.text()
                other = await two.ws_connect(f"{ws}/{student}?width=100&height=30")
                out["from another address"] = await screen_until(other, b"classroom: you drive")
                out["fourth in all"] = await refused(three)
                teacher = await three.ws_connect(f"{ws}/{teacher_token}?width=100&height=30")
                out["teacher"] = await screen_until(teacher, b"classroom: you are the teacher")
                # the first tab still answers: a new size, drawn
                await first.send_str('["resize", {"width": 90, "height": 27}]')
                out["first, resized"] = await whole_screen(first, lambda columns, rows: columns == 90)
                await second.close()  # its place is free again
                deadline = time.monotonic() + 20
                while time.monotonic() < deadline:
                    again = await one.ws_connect(f"{ws}/{student}?width=100&height=30")
                    shown = await screen_until(again, b"classroom: you")
                    if b"classroom: you drive" in shown:
                        break
                    await again.close()  # still counted: the server had not seen the other go
                out["after one closed"] = shown
                for sock in (first, other, teacher, again):
                    await sock.close()
            finally:
                for session in (one, two, three):
                    await session.close()
            return out

        out = asyncio.run(run())
        drivers = {re.search(rb"you drive team (\d+)", out[tab]).group(1) for tab in ("first", "second")}
        assert drivers == {b"254", b"1114"}
        code, shown = out["third from one address"]
        assert code == 1013 and b"2 tabs are open from your address" in shown, out["third from one address"]
        status, text = out["its page"]
        assert status == 503 and "2 tabs are open from your address" in text
        assert b"you drive team 2056" in out["from another address"]
        code, shown = out["fourth in all"]
        assert code == 1013 and b"3 tabs are open in this classroom" in shown, out["fourth in all"]
        assert b"you are the teacher" in out["teacher"]  # never refused for the field being full
        assert out["first, resized"] == (90, 27)
        assert b"classroom: you drive team" in out["after one closed"]  # its place was free again
        # the server's console says whom it refused, and why
        assert "2 tabs are open from your address" in lines.wait_for("refused a tab from 127.0.0.1")
        lines.wait_for("refused a tab from 127.0.0.3")
        proc.send_signal(signal.SIGINT)
        assert proc.wait(timeout=20) == 0
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()


def test_a_tab_is_never_bigger_than_a_screen():
    """A terminal size from the URL or from the page's ``resize`` is clamped to what a screen
    shows (MAX_WIDTH x MAX_HEIGHT): 3000 x 3000 asked, 500 x 200 drawn (3000 x 3000 took one
    tab to 959 MB); a size that fits is kept."""
    pytest.importorskip("textual_serve")
    import asyncio
    import json

    import aiohttp

    assert (MAX_WIDTH, MAX_HEIGHT) == (500, 200)
    port = free_port()
    proc = fieldbox("serve", "--host", "127.0.0.1", "--port", str(port), "--roles", "ds", "--team", "4244",
                    "--no-token", start_new_session=True)

    async def tab() -> list[tuple[int, int]]:
        async with aiohttp.ClientSession() as session:
            async with session.ws_connect(f"ws://127.0.0.1:{port}/ws?width=3000&height=3000", max_msg_size=0) as sock:
                sizes = [await whole_screen(sock, lambda columns, rows: True)]  # its first: a whole screen
                await sock.send_str(json.dumps(["resize", {"width": 100, "height": 30}]))
                sizes.append(await whole_screen(sock, lambda columns, rows: columns == 100))
                # what no page sends is dropped, and the tab plays on (a resize without a width
                # ended the tab, with a traceback in textual-serve's loop)
                for junk in ('["resize", {"height": 30}]', "not json", '{"resize": 1}', '["stdin", 5]', "[]",
                             '["resize", "big"]', '["resize", {"width": "x", "height": 1e400}]'):
                    await sock.send_str(junk)
                await sock.send_str(json.dumps(["resize", {"width": 90, "height": 27}]))
                sizes.append(await whole_screen(sock, lambda columns, rows: columns == 90))
                await sock.send_str(json.dumps(["resize", {"width": 3000, "height": 3000}]))
                sizes.append(await whole_screen(sock, lambda columns, rows: rows > 30))  # the first bigger one
                return sizes

    try:
        wait_for_page(proc, port)
        assert asyncio.run(tab()) == [(500, 200), (100, 30), (90, 27), (500, 200)]
        proc.send_signal(signal.SIGINT)
        assert proc.wait(timeout=10) == 0
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


def command_line(pid: int) -> str:
    try:
        return Path(f"/proc/{pid}/cmdline").read_bytes().replace(b"\0", b" ").decode(errors="replace")
    except OSError:
        return "(gone)"


def cpu_seconds(pid: int) -> float:
    try:
        with open(f"/proc/{pid}/stat") as f:
            fields = f.read().rpartition(")")[2].split()
        return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")
    except (OSError, ValueError, IndexError):
        return 0.0


@pytest.mark.skipif(not os.path.isdir("/proc"), reason="reads /proc")
@pytest.mark.parametrize("mode", ["classroom", "fields", "replay"])
def test_a_killed_server_leaves_no_field_and_no_tab_running(tmp_path, mode):
    """The server dies without a word (SIGKILL, a crash) while a tab is open: every process it
    started (the classroom's field, its fork server, the tabs' apps and their wire processes)
    notices its server is gone and ends, not draw and drive for ever (orphaned tabs once spun
    at 55 % of a core each for an hour). With --classroom, a tab's app is forked from the fork
    server; without, each tab is the server's child, running a field of its own or a replay."""
    pytest.importorskip("textual_serve")
    import asyncio

    import aiohttp

    given, drawn = {
        "classroom": (["--classroom", "--teams", "254,1114,2056,118,148,1678"], b"classroom: you"),
        "fields": (["--team", "4242"], b"ephemeral"),
        "replay": (["--replay", str(replay_source("recorded", tmp_path)[0])], b"REPLAY run.pcap"),
    }[mode]
    port = free_port()
    proc = fieldbox("serve", *given, "--host", "127.0.0.1", "--port", str(port), start_new_session=True)
    try:
        lines = Lines(proc.stdout)
        token = re.search(r"http\S+", lines.wait_for("students" if mode == "classroom" else "open", timeout=60)
                          ).group(0).split("token=")[1]
        wait_for_page(proc, port, f"?token={token}")

        async def tab_then_kill() -> tuple[set[int], dict[int, str], dict[int, str]]:
            async with aiohttp.ClientSession() as session:
                async with session.ws_connect(f"ws://127.0.0.1:{port}/ws/{token}?width=100&height=30") as sock:
                    seen = b""
                    while drawn not in seen:
                        msg = await asyncio.wait_for(sock.receive(), 60)
                        assert msg.type in (aiohttp.WSMsgType.BINARY, aiohttp.WSMsgType.TEXT), msg
                        seen += msg.data if isinstance(msg.data, bytes) else msg.data.encode()
                    left = descendants(proc.pid)
                    names = {pid: name_of(pid) for pid in left}
                    lines = {pid: command_line(pid) for pid in left}
                    os.kill(proc.pid, signal.SIGKILL)
                    return left, names, lines

        left, names, lines = asyncio.run(tab_then_kill())
        if mode != "fields":  # the tab's app, forked from a warm interpreter (fieldbox/tabfork.py)
            assert {"classroom": "fb-tab-driver", "replay": "fb-tab-replay"}[mode] in names.values(), names
        else:  # the tab's app, started with the options given to serve
            assert any(" --team 4242" in line for line in lines.values()), lines
        deadline = time.monotonic() + 20  # a hang guard: each is told at once (Linux) or within a second
        while any(alive(pid) for pid in left) and time.monotonic() < deadline:
            time.sleep(0.2)
        still = {pid: f"{names[pid]}, {cpu_seconds(pid):.1f} s of CPU" for pid in left if alive(pid)}
        assert not still, f"still running after their server was killed: {still}"
    finally:
        try:
            os.killpg(proc.pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
        proc.wait()


# -- serve --replay (issue 32, item 2) -------------------------------------------------------------
def replay_source(which: str, tmp_path: Path) -> tuple[Path, str]:
    """A capture to serve, and the link a tab's inspector names for its DS: the real NI capture
    (skipped when absent, never copied), or a pcap fieldbox records here."""
    from .test_replay import CAPTURE, recording

    if which == "real":
        if not CAPTURE.is_file():
            pytest.skip(f"the real capture is not at {CAPTURE}")
        return CAPTURE, "ds 6443"  # its DS is 10.64.43.x
    path, _ = recording(tmp_path)
    return path, "ds 254"  # fieldbox's own loopback field: 127.2.54.x


async def replay_screen(sock, total: int, *wanted: bytes, timeout: float = 60,
                        played: bool = True) -> tuple[int, bytes]:
    """What a replay tab draws, until its status line says a packet of the ``total`` has played
    (``played``) and every one of ``wanted`` is drawn: (the last position shown, what was drawn)."""
    import asyncio

    import aiohttp

    seen, position = b"", 0
    played = re.compile(rb"packet ([\d,]+) of " + f"{total:,}".encode())
    deadline = time.monotonic() + timeout  # a hang guard: the caller's asserts say what is missing
    while not ((position > 0 or not played) and all(w in seen for w in wanted)):
        try:
            msg = await asyncio.wait_for(sock.receive(), max(deadline - time.monotonic(), 0.01))
        except asyncio.TimeoutError:
            break
        if msg.type not in (aiohttp.WSMsgType.BINARY, aiohttp.WSMsgType.TEXT):
            break
        seen += msg.data if isinstance(msg.data, bytes) else msg.data.encode()
        shown = played.findall(seen)
        position = int(shown[-1].replace(b",", b"")) if shown else 0
    return position, seen


@pytest.mark.parametrize("which", ["recorded", "real"])
def test_serve_replay_gives_each_tab_its_own_replay_of_the_capture(tmp_path, which):
    """serve --replay FILE: the server says what a tab gets; a tab's app plays the capture's
    packets into its Inspector (the status line counts them, the DS's link is listed); a tab
    paused with p stays paused while a tab opened after it plays: each tab has its own replay."""
    pytest.importorskip("textual_serve")
    import asyncio

    import aiohttp

    from fieldbox.replay import load

    path, link = replay_source(which, tmp_path)
    total = len(load(str(path)).packets)
    port = free_port()
    proc = fieldbox("serve", "--replay", str(path), "--host", "127.0.0.1", "--port", str(port),
                    start_new_session=True)
    try:
        lines = Lines(proc.stdout)
        said = lines.wait_for("serve --replay", timeout=60)
        assert f"every tab plays the capture's {total:,} FRC packets" in said and "p pauses" in said, said
        token = re.search(r"http\S+", lines.wait_for("open")).group(0).split("token=")[1]
        wait_for_page(proc, port, f"?token={token}")

        async def two_tabs() -> dict[str, tuple[int, bytes]]:
            out = {}
            async with aiohttp.ClientSession() as session:
                url = f"ws://127.0.0.1:{port}/ws/{token}?width=160&height=50"
                async with session.ws_connect(url) as first:
                    out["first"] = await replay_screen(first, total, f"REPLAY {path.name}".encode(),
                                                       link.encode(), b"playing")
                    await first.send_json(["stdin", "p"])  # the replay's pause key, typed in this tab
                    out["first paused"] = await replay_screen(first, total, b"PAUSED")
                    async with session.ws_connect(url) as second:
                        out["second"] = await replay_screen(second, total, f"REPLAY {path.name}".encode(),
                                                            link.encode(), b"playing")
            return out

        out = asyncio.run(two_tabs())
        position, seen = out["first"]
        assert position > 0 and f"REPLAY {path.name}".encode() in seen and link.encode() in seen, seen[-2000:]
        assert b"PAUSED" in out["first paused"][1], out["first paused"][1][-2000:]
        position, seen = out["second"]
        assert position > 0 and b"playing" in seen and link.encode() in seen, seen[-2000:]
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()


def test_serve_replay_paused_opens_every_tab_paused_at_the_first_packet(tmp_path):
    """serve --replay FILE --paused --speed 5: the server says so, and a tab opens at packet 0,
    paused at 5x, and stays there until its p (a teacher starts the class together)."""
    pytest.importorskip("textual_serve")
    import asyncio

    import aiohttp

    from fieldbox.replay import load

    path, _ = replay_source("recorded", tmp_path)
    total = len(load(str(path)).packets)
    port = free_port()
    proc = fieldbox("serve", "--replay", str(path), "--paused", "--speed", "5", "--host", "127.0.0.1",
                    "--port", str(port), start_new_session=True)
    try:
        lines = Lines(proc.stdout)
        said = lines.wait_for("serve --replay", timeout=60)
        assert f"every tab opens the capture's {total:,} FRC packets" in said and "paused at the first at 5x" in said
        token = re.search(r"http\S+", lines.wait_for("open")).group(0).split("token=")[1]
        wait_for_page(proc, port, f"?token={token}")

        async def one_tab() -> tuple[tuple[int, bytes], tuple[int, bytes]]:
            async with aiohttp.ClientSession() as session:
                url = f"ws://127.0.0.1:{port}/ws/{token}?width=160&height=50"
                async with session.ws_connect(url) as tab:
                    opened = await replay_screen(tab, total, f"packet 0 of {total:,}".encode(), b"5x", b"PAUSED",
                                                 played=False)
                    later = await replay_screen(tab, total, b"(nothing: a second of a paused tab)", timeout=1.5)
                    return opened, later

        (position, seen), (later, _) = asyncio.run(one_tab())
        assert f"packet 0 of {total:,}".encode() in seen and b"PAUSED" in seen, seen[-2000:]
        assert position == 0 and later == 0
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()


def test_serve_replay_says_a_bad_file_or_a_field_s_option_in_one_line_before_serving(tmp_path):
    """A file that is no capture is one line and exit code 1, as fieldbox replay says it, and no
    server starts; a field's options (a replay runs none) are refused by name."""
    notes = tmp_path / "notes.txt"
    notes.write_text("hello, this is not a capture\n")
    port = free_port()
    done = subprocess.run([sys.executable, "-m", "fieldbox", "serve", "--replay", str(notes), "--port", str(port)],
                          cwd=ROOT, env=dict(os.environ, PYTHONPATH=str(ROOT)), capture_output=True, text=True,
                          timeout=60)
    assert done.returncode == 1 and done.stdout == ""
    assert done.stderr.splitlines() == [f"fieldbox serve: {notes}: not a pcap or pcapng file: magic 68656c6c "
                                        "at offset 0"], done.stderr
    for given, named in ((["--classroom", "--teams", "254,1114,2056,118,148,1678"], "--classroom and --teams"),
                         (["--roles", "ds,rio,fms"], "--roles"), (["--team", "254", "--fault", "all:cut"],
                                                                   "--team and --fault")):
        done = subprocess.run([sys.executable, "-m", "fieldbox", "serve", "--replay", str(notes), *given,
                               "--port", str(port)],
                              cwd=ROOT, env=dict(os.environ, PYTHONPATH=str(ROOT)), capture_output=True,
                              text=True, timeout=60)
        assert done.returncode == 2 and done.stdout == "", given
        assert (f"serve --replay plays a capture in each tab and runs no field: leave out {named} "
                in done.stderr.splitlines()[-1]), done.stderr
