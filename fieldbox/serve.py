"""``fieldbox serve``: the app in a browser, through textual-serve.

textual-serve starts one process per browser tab, running a command. Here that command is
this same Python running ``fieldbox`` with the options given to ``serve``, on the
``ephemeral`` address plan unless ``--net`` was given: every tab is a field of its own on
OS-chosen ports, so thirty students' tabs never fight over port 1110.

A tab is a process on the server, so the server asks for a token, as Jupyter does: a random
one per start, printed in the URL it shows (``--no-token`` goes without). The page and its
websocket need it (in the URL once; the page then keeps it in a cookie for this server), and
a websocket opened by a page from another site is refused whatever the token. In a tab, what
the app can reach on the server is limited to what the server was started with
(:func:`tab_allows_plan`, :func:`tab_allows_path`): no non-loopback address is bound unless
the server was started with ``--net real``, no file is written outside the capture folder,
and a robot program comes only from ``serve --robot-program``.

``serve --replay FILE`` serves a capture instead of a field: each tab runs ``fieldbox replay
FILE`` (fieldbox/replay.py), forked as a classroom's tabs are (fieldbox/tabfork.py): its own
replay from the first packet, paused, stepped and sped up on its own. No field runs, so the
options of a field are refused (:func:`replay_refusal`). The file is read once at the start,
so a bad one is one line there, as ``fieldbox replay`` says it, not a broken tab for each.

A tab ends when the server does, even a killed one (fieldbox/tabfork.py end_with_parent): it
watches the process that started it, the server itself (a tab not forked is started without a
shell between) or the fork server, which ends with the server.

``serve --classroom`` runs one field for every tab instead (roles/runtime/classroom.py): its own
process, which each tab's app joins with a seat. The seat comes from which token the URL
carries, never from anything else in it: the server prints three URLs, each with a token of
its own (the students' drives a free station, else watches; the observers' watches; the
teacher's runs the FMS), so a student who edits a URL can only lose the seat, not gain one.
The page's websocket carries the same token in its path (the page's script adds the
terminal's size as its query), and the server, not the page, turns it into the tab's command.

Each tab is a process, so the server runs at most ``--max-tabs`` (40: a class is 30) and
``--tabs-per-client`` from one address (8); more are refused with a page, or a websocket
close, that says so, and the field and the open tabs go on. A teacher's tab is never refused
for the field being full. A tab's terminal is at most :data:`MAX_WIDTH` x :data:`MAX_HEIGHT`
cells, whatever the browser asks: a 3000 x 3000 terminal took one tab to 959 MB.
"""

from __future__ import annotations

import collections
import contextvars
import hmac
import ipaddress
import logging
import os
import re
import secrets
import shlex
import sys
from pathlib import Path

INSTALL_HINT = "fieldbox serve needs textual-serve: pip install 'fieldbox[serve]'"

log = logging.getLogger("fieldbox.serve")

#: The most tabs the server runs at once (``--max-tabs``): each is a process, and 150 of them
#: started at once loaded the machine so that none drew its screen within 5 s. A class is 30;
#: the teacher's tabs are not counted, and never refused for it.
MAX_TABS = 40
#: The most tabs open from one client address (``--tabs-per-client``): a student's few tabs,
#: not a script's hundreds. Behind a proxy on this machine the client is the last address of
#: its X-Forwarded-For.
TABS_PER_CLIENT = 8
#: The largest terminal a tab draws, columns and rows, whatever the browser asks: more than a
#: 4K screen (3840 x 2160 pixels) shows with cells of 8 x 11 pixels, a font too small to read
#: from a seat. Each cell costs the app memory (a 3000 x 3000 terminal took a tab to 959 MB).
MAX_WIDTH, MAX_HEIGHT = 500, 200

#: Set in every tab's process to the address plan the server was started with: the app then
#: keeps to what that allows (see tab_allows_plan and tab_allows_path).
TAB_ENV = "FIELDBOX_BROWSER_TAB"
FORBIDDEN = ("fieldbox serve: this server needs its token. Open the URL it printed when it "
             "started (http://HOST:PORT/?token=...).\n")

#: Options of the app passed through to every tab's process: (dest, flag, kind).
_PASSED = (
    ("roles", "--roles", "value"),
    ("team", "--team", "value"),
    ("station", "--station", "value"),
    ("robot", "--robot", "value"),
    ("fms", "--fms", "value"),
    ("net", "--net", "value"),
    ("teams", "--teams", "value"),
    ("legacy_2010", "--legacy-2010", "flag"),
    ("theme", "--theme", "value"),
    ("fault", "--fault", "repeat"),
    ("wire", "--wire", "value"),
    ("robot_program", "--robot-program", "value"),
)


def in_browser_tab() -> bool:
    """Whether this process is a browser tab's app, started by ``fieldbox serve``."""
    return bool(os.environ.get(TAB_ENV))


def tab_allows_plan(plan: str) -> bool:
    """Whether this process may bind ``plan``'s addresses: anything outside a browser tab; in
    one, the loopback-only plans, and ``real`` (every interface) only if the server was
    started with ``--net real``."""
    started = os.environ.get(TAB_ENV)
    return not started or plan in ("loopback", "ephemeral") or plan == started


def tab_allows_path(path: str | os.PathLike, folder: str | os.PathLike) -> bool:
    """Whether this process may write ``path``: anything outside a browser tab; in one, only
    inside ``folder`` (the capture folder), so a tab never writes where code is loaded from."""
    if not in_browser_tab():
        return True
    try:
        target = Path(path).expanduser().resolve()
        return target.is_relative_to(Path(folder).expanduser().resolve())
    except (OSError, ValueError):
        return False


def new_token() -> str:
    """A random token, 48 hex digits, as Jupyter's."""
    return secrets.token_hex(24)


def screen_size(width, height) -> tuple[int, int] | None:
    """A terminal size a browser asked for, within what a screen shows: 1 to :data:`MAX_WIDTH`
    columns, 1 to :data:`MAX_HEIGHT` rows; None if it is not a size at all."""
    if isinstance(width, bool) or isinstance(height, bool):
        return None
    try:
        columns, rows = int(width), int(height)
    except (TypeError, ValueError, OverflowError):
        return None
    return min(max(columns, 1), MAX_WIDTH), min(max(rows, 1), MAX_HEIGHT)


def app_command(args) -> str:
    """The shell command textual-serve runs for each tab."""
    argv = [sys.executable, "-m", "fieldbox"]
    if getattr(args, "net", None) is None:
        argv += ["--net", "ephemeral"]
    for dest, flag, kind in _PASSED:
        value = getattr(args, dest, None)
        if value is None or value is False:
            continue
        if kind == "flag":
            argv.append(flag)
        elif kind == "repeat":
            for item in value:
                argv += [flag, str(item)]
        else:
            argv += [flag, str(value)]
    return " ".join(shlex.quote(a) for a in argv)


#: The command of the tab being opened (classroom: it depends on the seat its token gives).
_TAB_COMMAND: contextvars.ContextVar[str | None] = contextvars.ContextVar("fieldbox_tab_command", default=None)


def classroom_command(args, path: str, seat: str) -> str:
    """The command of a classroom tab: the app joining the field at ``path`` as ``seat``
    (the teacher's key, when it is the teacher, comes from the environment: roles/runtime/classroom.py)."""
    argv = [sys.executable, "-m", "fieldbox", "--join", path, "--join-as", seat]
    if getattr(args, "theme", None):
        argv += ["--theme", str(args.theme)]
    return " ".join(shlex.quote(a) for a in argv)


#: What ``serve --replay`` cannot go with: a replay runs no field. (dest, flag).
_NOT_WITH_REPLAY = (
    ("classroom", "--classroom"), ("roles", "--roles"), ("team", "--team"), ("station", "--station"),
    ("robot", "--robot"), ("fms", "--fms"), ("no_fms", "--no-fms"), ("ds_hello", "--ds-hello"),
    ("net", "--net"), ("teams", "--teams"), ("legacy_2010", "--legacy-2010"), ("dashboard", "--dashboard"),
    ("ds_ip_server", "--ds-ip-server"), ("robot_program", "--robot-program"), ("fault", "--fault"),
    ("any_ds", "--any-ds"), ("wire", "--wire"), ("log_dir", "--log-dir"), ("no_log_files", "--no-log-files"),
    ("dslog_version", "--dslog-version"),
)


def replay_refusal(args) -> str | None:
    """Why these options cannot go with ``--replay`` (None: they can): each tab replays the
    capture and runs no field, so the options of a field, or of a classroom's, mean nothing."""
    given = [flag for dest, flag in _NOT_WITH_REPLAY if getattr(args, dest, None) not in (None, False)]
    if not given:
        return None
    listed = ", ".join(given[:-1]) + (" and " if len(given) > 1 else "") + given[-1]
    return (f"serve --replay plays a capture in each tab and runs no field: leave out {listed} "
            "(only --theme and the server's own options go with it)")


def replay_command(args, path: str) -> str:
    """The command of a ``serve --replay`` tab: ``fieldbox replay`` of the capture at ``path``."""
    argv = [sys.executable, "-m", "fieldbox"]
    if getattr(args, "theme", None):
        argv += ["--theme", str(args.theme)]
    argv += ["replay", path]
    if getattr(args, "speed", None) not in (None, 1.0):
        argv += ["--speed", str(args.speed)]
    if getattr(args, "paused", False):
        argv.append("--paused")
    return " ".join(shlex.quote(a) for a in argv)


def serve(args, config=None) -> int:
    try:
        from textual_serve.server import Server
    except ImportError:
        print(INSTALL_HINT, file=sys.stderr)
        return 1
    if getattr(args, "headless", False):
        print("fieldbox serve: --headless makes no sense in a browser; leave it out", file=sys.stderr)
        return 2
    replay = None  # with --replay: the line that says what a tab gets
    if getattr(args, "replay", None) is not None:
        why = replay_refusal(args)  # the command line says it first (fieldbox/cli.py), before any field is built
        if why is not None:
            print(f"fieldbox {why}", file=sys.stderr)
            return 2
        from .replay import ReplayError, load

        # read whole now, as fieldbox replay does: a bad file is one line here, not a broken tab each
        path = os.path.abspath(args.replay)
        try:
            capture = load(path)
        except ReplayError as exc:
            print(f"fieldbox serve: {exc}", file=sys.stderr)
            return 1
        if capture.cut is not None:
            print(f"fieldbox serve: {path}: {capture.cut}: the {len(capture.packets):,} FRC packets before it "
                  "are replayed", file=sys.stderr)
        packets = f"the capture's {len(capture.packets):,} FRC packets ({capture.duration:.1f} s)"
        pace = f" at {args.speed:g}x" if getattr(args, "speed", None) not in (None, 1.0) else ""
        start = (f"opens {packets} paused at the first{pace}" if getattr(args, "paused", False)
                 else f"plays {packets} from the start{pace}")
        replay = (f"fieldbox serve --replay {os.path.basename(path)}: every tab {start}, on its own: "
                  "p pauses and plays, . steps, < > slower and faster, b from the start")
        del capture  # each tab reads it again: the server keeps none of it
    if getattr(args, "net", None) not in (None, "ephemeral"):
        print(f"note: --net {args.net} binds fixed ports: only the first browser tab will start "
              "its field", file=sys.stderr)
    # The tab processes must import this fieldbox even when it is not installed.
    root = str(Path(__file__).resolve().parent.parent)
    path = os.environ.get("PYTHONPATH", "")
    if root not in path.split(os.pathsep):
        os.environ["PYTHONPATH"] = root + (os.pathsep + path if path else "")
    os.environ.setdefault("TEXTUAL_ANIMATIONS", "none")
    os.environ[TAB_ENV] = getattr(args, "net", None) or "ephemeral"  # what every tab may bind
    for option, flag in (("max_tabs", "--max-tabs"), ("tabs_per_client", "--tabs-per-client")):
        if getattr(args, option, 1) < 1:
            print(f"fieldbox serve: {flag} must be 1 or more", file=sys.stderr)
            return 2
    command = app_command(args) if replay is None else replay_command(args, os.path.abspath(args.replay))
    token = None if getattr(args, "no_token", False) else new_token()
    classroom = None
    if getattr(args, "classroom", False):
        from roles.runtime.classroom import KEY_ENV, ClassroomProcess

        if config is None:
            from .headless import config_from_args

            config = config_from_args(args)
        if getattr(args, "net", None) is None:
            config.plan = "ephemeral"
        classroom = ClassroomProcess(config)
        try:
            classroom.start()
        except OSError as exc:
            print(f"fieldbox serve: {exc}", file=sys.stderr)
            return 1
        os.environ[KEY_ENV] = classroom.teacher_key  # for the teacher's tab (never in a command line)
        command = classroom_command(args, classroom.path, "driver")
    forks = None
    own_folder = None  # the fork server's, when no classroom gives one
    if classroom is not None or replay is not None:
        # A class opens its tabs at once: forked from one warm interpreter, they share its
        # imports instead of each importing Python, Textual and fieldbox (fieldbox/tabfork.py).
        import tempfile

        from .tabfork import ForkServer

        if classroom is not None:
            forks = ForkServer(classroom.folder)
        else:
            own_folder = tempfile.mkdtemp(prefix="fieldbox-tabs-")  # 0700: this user's
            forks = ForkServer(own_folder)
        if not forks.start():
            forks = None
    server_class = _server_class(Server)
    server_class.tab_forks(forks)
    server = server_class(command, host=args.host, port=args.port, title="fieldbox",
                          public_url=args.public_url)
    server.token = token
    server.classroom = classroom
    if classroom is not None:
        server.observer_token = new_token()
    server.max_tabs = getattr(args, "max_tabs", MAX_TABS)
    server.tabs_per_client = getattr(args, "tabs_per_client", TABS_PER_CLIENT)
    server.args = args
    server.replay = replay
    try:
        server.serve()
    except OSError as exc:
        print(f"fieldbox serve: cannot listen on {args.host}:{args.port}: {exc.strerror or exc}",
              file=sys.stderr)
        return 1
    finally:
        if forks is not None:
            forks.stop()
        if own_folder is not None:
            try:
                os.rmdir(own_folder)
            except OSError:
                pass
        if classroom is not None:
            classroom.stop()
    return 0


#: textual-serve's page template asks fonts.googleapis.com for its font: a classroom is often
#: offline (and a school's network may block it), and a page should not tell Google who opens
#: it. The same font (Roboto Mono) is among textual-serve's static files, which the server
#: serves itself: the page takes it from there.
_FONT_LINK = re.compile(r"<link[^>]*fonts\.googleapis\.com[^>]*>", re.S)
_LOCAL_FONT = """<style>
      @font-face { font-family: "Roboto Mono"; font-style: normal;
        src: url("{{ config.static.url }}fonts/RobotoMono-VariableFont_wght.ttf") format("truetype"); }
      @font-face { font-family: "Roboto Mono"; font-style: italic;
        src: url("{{ config.static.url }}fonts/RobotoMono-Italic-VariableFont_wght.ttf") format("truetype"); }
    </style>"""


def offline_page(template: str) -> str:
    """textual-serve's page template with its font from the server's own static files instead
    of Google's (:data:`_FONT_LINK`). A template of another textual-serve release without that
    link is left as it is (tests/app/test_serve.py checks the page names no other host)."""
    return _FONT_LINK.sub(lambda _: _LOCAL_FONT, template)


def _server_class(base):
    """textual-serve's server, plus: the tokens and the seats they give, the caps on tabs,
    terminal sizes a screen can show, and stopping it ends every tab's app at once (each is
    told to quit, as when its tab closes) instead of waiting up to a minute for the tabs to go."""
    import asyncio

    import textual_serve.server as textual_serve_server

    class TabApp(textual_serve_server.AppService):
        running: set = set()
        bad_sizes = 0  # resizes that were not sizes at all, dropped

        def __init__(self, command: str, *args, **kwargs) -> None:
            super().__init__(_TAB_COMMAND.get() or command, *args, **kwargs)

        forks = None  # fieldbox.tabfork.ForkServer, with --classroom or --replay

        async def start(self, width: int, height: int) -> None:
            TabApp.running.add(self)
            await super().start(*(screen_size(width, height) or (80, 24)))

        async def set_terminal_size(self, width, height) -> None:
            """The page's ``resize``, within what a screen shows (the app gets no bigger)."""
            size = screen_size(width, height)
            if size is None:
                TabApp.bad_sizes += 1
                log.warning("fieldbox serve: a tab asked for a size that is none (%.40r x %.40r): dropped "
                            "(%d so far)", width, height, TabApp.bad_sizes)
                return
            await super().set_terminal_size(*size)

        async def _open_app_process(self, width: int = 80, height: int = 24):
            from .tabfork import PARENT_ENV, fieldbox_argv, open_forked, tab_argv

            if TabApp.forks is not None:  # a classroom's or a replay's tab: forked from a warm interpreter
                process = await open_forked(TabApp.forks, self.command, self._build_environment(width, height))
                if process is not None:
                    # duck-typed as the Process textual-serve reads
                    self._process, self._stdin = process, process.stdin  # type: ignore[assignment]
                    return process
            argv = fieldbox_argv(self.command)
            if argv is None:
                return await super()._open_app_process(width, height)
            # Started without a shell between: the tab is the server's own child, which it
            # watches (fieldbox/tabfork.py run_tab) to end with the server, even a killed one.
            env = self._build_environment(width, height)
            env[PARENT_ENV] = str(os.getpid())
            started = await asyncio.create_subprocess_exec(
                *tab_argv(argv), stdin=asyncio.subprocess.PIPE, stdout=asyncio.subprocess.PIPE,
                stderr=asyncio.subprocess.PIPE, env=env)
            self._process, self._stdin = started, started.stdin
            return started

        async def stop(self) -> None:
            TabApp.running.discard(self)
            await super().stop()

    # handle_websocket makes one AppService per tab by this module-level name.
    textual_serve_server.AppService = TabApp

    from urllib.parse import urlsplit

    import aiohttp_jinja2
    from aiohttp import WSCloseCode, web

    class FieldboxServer(base):
        token: str | None = None  # the students' (without --classroom: everyone's)
        observer_token: str | None = None  # with --classroom: the watch-only URL's
        classroom = None  # roles.runtime.classroom.ClassroomProcess, with --classroom
        replay: str | None = None  # with --replay: what a tab gets, said at the start
        args = None
        max_tabs = MAX_TABS
        tabs_per_client = TABS_PER_CLIENT

        def __init__(self, *args, **kwargs) -> None:
            super().__init__(*args, **kwargs)
            self.tabs: collections.Counter[str] = collections.Counter()  # open tabs by client
            self.counted = 0  # open tabs that count towards max_tabs (the teacher's do not)
            self.refused = 0

        @staticmethod
        def tab_forks(forks) -> None:
            """Fork the tabs' apps from ``forks`` (fieldbox.tabfork), or start each afresh (None)."""
            TabApp.forks = forks

        @property
        def cookie(self) -> str:
            return f"fieldbox-token-{self.port}"  # cookies ignore ports: one name per server

        def url_with(self, token: str | None) -> str:
            """The URL to open with ``token`` (none: the plain address)."""
            return f"{self.public_url}/" + (f"?token={token}" if token else "")

        @property
        def url(self) -> str:
            """The students' URL (without --classroom, everyone's): with the token, when there is one."""
            return self.url_with(self.token)

        def seat_tokens(self) -> list[tuple[str, str]]:
            """(seat, token) for each token this server gave out: the seat is the token's."""
            pairs: list[tuple[str, str | None]] = [("driver", self.token)] if self.token else []
            if self.classroom is not None:
                pairs += [("observer", self.observer_token), ("teacher", self.classroom.teacher_key)]
            return [(seat, token) for seat, token in pairs if token]

        async def _make_app(self):
            app = await super()._make_app()
            app.middlewares.append(self._guard)
            app.router.add_get("/ws/{token}", self.handle_websocket)
            # the page from fieldbox's own copy of textual-serve's: no font from Google
            import jinja2

            template = (Path(self.templates_path) / "app_index.html").read_text(encoding="utf-8")
            aiohttp_jinja2.setup(app, loader=jinja2.DictLoader({"app_index.html": offline_page(template)}))
            return app

        def _presented(self, request) -> tuple[str, str, str] | None:
            """(how, seat, token) of the first of this server's tokens the request shows: in
            its path (a websocket), its query (the URL) or the cookie; None if it shows none."""
            pairs = self.seat_tokens()
            for how, given in (("path", request.match_info.get("token")), ("query", request.query.get("token")),
                               ("cookie", request.cookies.get(self.cookie))):
                if not given:
                    continue
                for seat, token in pairs:
                    if hmac.compare_digest(str(given).encode(), token.encode()):
                        return how, seat, token
            return None

        @staticmethod
        def client_of(request) -> str:
            """Whose tab this is, for the cap per client: its address, or behind a proxy on this
            machine (a loopback peer) the last address of X-Forwarded-For, the one the proxy saw."""
            peer = request.remote or ""
            try:
                proxied = ipaddress.ip_address(peer).is_loopback
            except ValueError:
                proxied = False
            if proxied:
                forwarded = request.headers.get("X-Forwarded-For", "").split(",")[-1].strip()
                if forwarded:
                    return forwarded
            return peer

        def refusal(self, request, seat: str) -> str | None:
            """Why a new tab may not open now (the caps), or None."""
            client = self.client_of(request)
            if self.tabs[client] >= self.tabs_per_client:
                return (f"fieldbox serve: {self.tabs[client]} tabs are open from your address, the most "
                        "one address may have: close one, then reload")
            if seat != "teacher" and self.counted >= self.max_tabs:
                where = "this classroom" if self.classroom is not None else "this server"
                return (f"fieldbox serve: {self.counted} tabs are open in {where}, the most it runs "
                        "at once: reload when one closes")
            return None

        def _refused(self, request, why: str) -> None:
            """Said on the server's console (whoever runs the class sees it) and in the log."""
            self.refused += 1
            said = (f"refused a tab from {self.client_of(request)} ({self.refused} so far): "
                    f"{why.removeprefix('fieldbox serve: ')}")
            self.console.print(f"fieldbox serve: {said}", highlight=False, soft_wrap=True)
            log.warning("%s", said)

        async def handle_websocket(self, request):
            seat = request.get("fieldbox_seat", "driver")
            why = self.refusal(request, seat)
            if why is not None:
                self._refused(request, why)
                websocket = web.WebSocketResponse()
                await websocket.prepare(request)
                await websocket.send_bytes(f"\r\n{why}\r\n".encode())  # on the terminal, for whoever reads it
                await websocket.close(code=WSCloseCode.TRY_AGAIN_LATER, message=why.encode()[:123])
                return websocket
            client = self.client_of(request)
            counted = seat != "teacher"
            self.tabs[client] += 1
            self.counted += counted
            try:
                if self.classroom is not None:
                    _TAB_COMMAND.set(classroom_command(self.args, self.classroom.path, seat))
                return await base.handle_websocket(self, request)
            finally:
                self.counted -= counted
                self.tabs[client] -= 1
                if self.tabs[client] <= 0:
                    del self.tabs[client]

        bad_messages = 0  # websocket messages that were not what a page sends, dropped

        async def _process_messages(self, websocket, app_service) -> None:
            """A tab's messages to its app, as textual-serve's page sends them (``["stdin",
            text]``, ``["resize", {"width", "height"}]``, ``["ping", data]``, ``["blur"]``,
            ``["focus"]``). Anything else (not JSON, not that shape) is dropped, counted and
            logged: textual-serve's own loop ended the tab with a traceback on a resize that
            had no width."""
            from aiohttp import WSMsgType

            async for message in websocket:
                if message.type != WSMsgType.TEXT:
                    continue
                try:
                    envelope = message.json()
                    kind, data = envelope[0], (envelope[1] if len(envelope) > 1 else None)
                    if kind == "stdin" and isinstance(data, str):
                        await app_service.send_bytes(data.encode("utf-8"))
                    elif kind == "resize" and isinstance(data, dict):
                        await app_service.set_terminal_size(data.get("width"), data.get("height"))
                    elif kind == "ping":
                        await websocket.send_json(["pong", data])
                    elif kind == "blur":
                        await app_service.blur()
                    elif kind == "focus":
                        await app_service.focus()
                    else:
                        raise ValueError(f"no message {str(kind)[:40]!r} with {type(data).__name__}")
                except (ValueError, TypeError, KeyError, IndexError, AttributeError) as exc:
                    FieldboxServer.bad_messages += 1
                    log.warning("fieldbox serve: a tab sent a message that is none of a page's (%.80s): "
                                "dropped (%d so far)", exc, FieldboxServer.bad_messages)

        def _same_origin(self, request) -> bool:
            """A browser says which page opened a websocket: only this server's own pages."""
            origin = request.headers.get("Origin")
            if origin is None:
                return True  # not a browser page (a script, a test): the token decides
            mine = {f"{request.scheme}://{request.host}".lower()}
            public = urlsplit(self.public_url)
            mine.add(f"{public.scheme}://{public.netloc}".lower())
            return origin.rstrip("/").lower() in mine

        @web.middleware
        async def _guard(self, request, handler):
            path = request.path
            if path.startswith("/static/"):
                return await handler(request)  # the page's scripts and styles: nothing private
            if path.startswith("/ws") and not self._same_origin(request):
                return web.Response(status=403, text="fieldbox serve: a websocket from another site\n")
            shown = self._presented(request)
            if shown is None:
                if self.token:
                    return web.Response(status=403, text=FORBIDDEN)
                shown = ("none", "driver", None)  # --no-token: the students' seat for anyone
            how, seat, token = shown
            request["fieldbox_seat"], request["fieldbox_token"] = seat, token
            response = await handler(request)
            if how == "query" and isinstance(response, web.Response):
                response.set_cookie(self.cookie, token, httponly=True, samesite="Strict", path="/")
            return response

        @aiohttp_jinja2.template("app_index.html")
        async def handle_index(self, request):
            why = self.refusal(request, request.get("fieldbox_seat", "driver"))
            if why is not None:  # the page says so; its websocket would be refused the same
                self._refused(request, why)
                return web.Response(status=503, text=why + "\n")
            context = await base.handle_index.__wrapped__(self, request)
            token = request.get("fieldbox_token")
            if token:  # the page's websocket carries the token it was opened with: its seat
                context["app_websocket_url"] += f"/{token}"
            return context

        async def on_startup(self, app) -> None:
            if self.classroom is not None:
                self.console.print("fieldbox serve --classroom: one field for every tab", highlight=False)
                self.console.print(f"  students (drive a free station, else watch): [bold]{self.url}[/bold]",
                                   highlight=False, soft_wrap=True)
                self.console.print(f"  watch only: [bold]{self.url_with(self.observer_token)}[/bold]",
                                   highlight=False, soft_wrap=True)
                self.console.print(f"  teacher (FMS, hands stations out; keep it to yourself): "
                                   f"[bold]{self.url_with(self.classroom.teacher_key)}[/bold]",
                                   highlight=False, soft_wrap=True)
            else:
                if self.replay is not None:
                    self.console.print(self.replay, highlight=False, soft_wrap=True)
                self.console.print(f"fieldbox serve: open [bold]{self.url}[/bold]", highlight=False, soft_wrap=True)
            if not self.token:
                self.console.print("(--no-token: anyone who can reach this port gets a fieldbox)", highlight=False)
            self.console.print(f"(at most {self.max_tabs} tabs, {self.tabs_per_client} from one address: "
                               "--max-tabs, --tabs-per-client)", highlight=False)
            self.console.print("[cyan]Press Ctrl+C to quit", highlight=False)

        async def on_shutdown(self, app) -> None:
            tabs = list(TabApp.running)
            if tabs:
                await asyncio.wait([asyncio.ensure_future(t.stop()) for t in tabs], timeout=5)

    return FieldboxServer
