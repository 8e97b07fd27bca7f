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

``serve --classroom`` runs one field for every tab instead (roles/runtime/classroom.py): its own
process, which each tab's app joins with a seat chosen by the URL it was opened with. The
plain URL drives (a free station, else watches), ``&as=observer`` watches, and the teacher's
URL (``&teacher=KEY``, a second random key the server prints) runs the FMS. The seat travels
in the websocket's path (the page's script adds the terminal's size as its query), and the
server, not the page, turns it into the tab's command.
"""

from __future__ import annotations

import contextvars
import hmac
import os
import secrets
import shlex
import sys
from pathlib import Path

INSTALL_HINT = "fieldbox serve needs textual-serve: pip install 'fieldbox[serve]'"

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


#: The command of the tab being opened (classroom: it depends on the seat its URL asked for).
_TAB_COMMAND: contextvars.ContextVar[str | None] = contextvars.ContextVar("fieldbox_tab_command", default=None)
SEATS = ("driver", "observer", "teacher")


def classroom_command(args, path: str, seat: str) -> str:
    """The command of a classroom tab: the app joining the field at ``path`` as ``seat``
    (the teacher's key, when it is the teacher, comes from the environment: roles/runtime/classroom.py)."""
    argv = [sys.executable, "-m", "fieldbox", "--join", path, "--join-as", seat]
    if getattr(args, "theme", None):
        argv += ["--theme", str(args.theme)]
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
    command = app_command(args)
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
    if classroom is not None:
        from .tabfork import ForkServer

        forks = ForkServer(classroom.folder)
        if not forks.start():
            forks = None
    server_class = _server_class(Server)
    server_class.tab_forks(forks)
    server = server_class(command, host=args.host, port=args.port, title="fieldbox",
                          public_url=args.public_url)
    server.token = token
    server.classroom = classroom
    server.args = args
    try:
        server.serve()
    except OSError as exc:
        print(f"fieldbox serve: cannot listen on {args.host}:{args.port}: {exc.strerror or exc}",
              file=sys.stderr)
        return 1
    finally:
        if forks is not None:
            forks.stop()
        if classroom is not None:
            classroom.stop()
    return 0


def _server_class(base):
    """textual-serve's server, plus: stopping it ends every tab's app at once (each is told
    to quit, as when its tab closes) instead of waiting up to a minute for the tabs to go."""
    import asyncio

    import textual_serve.server as textual_serve_server

    class TabApp(textual_serve_server.AppService):
        running: set = set()

        def __init__(self, command: str, *args, **kwargs) -> None:
            super().__init__(_TAB_COMMAND.get() or command, *args, **kwargs)

        forks = None  # fieldbox.tabfork.ForkServer, with --classroom

        async def start(self, width: int, height: int) -> None:
            TabApp.running.add(self)
            await super().start(width, height)

        async def _open_app_process(self, width: int = 80, height: int = 24):
            if TabApp.forks is not None:  # a classroom's tab: forked from a warm interpreter
                from .tabfork import open_forked

                process = await open_forked(TabApp.forks, self.command, self._build_environment(width, height))
                if process is not None:
                    self._process, self._stdin = process, process.stdin
                    return process
            return await super()._open_app_process(width, height)

        async def stop(self) -> None:
            TabApp.running.discard(self)
            await super().stop()

    # handle_websocket makes one AppService per tab by this module-level name.
    textual_serve_server.AppService = TabApp

    from urllib.parse import urlsplit

    import aiohttp_jinja2
    from aiohttp import web

    class FieldboxServer(base):
        token: str | None = None
        classroom = None  # roles.runtime.classroom.ClassroomProcess, with --classroom
        args = None

        @staticmethod
        def tab_forks(forks) -> None:
            """Fork the tabs' apps from ``forks`` (fieldbox.tabfork), or start each afresh (None)."""
            TabApp.forks = forks

        @property
        def cookie(self) -> str:
            return f"fieldbox-token-{self.port}"  # cookies ignore ports: one name per server

        @property
        def url(self) -> str:
            """The URL to open: with the token, when there is one."""
            return f"{self.public_url}/" + (f"?token={self.token}" if self.token else "")

        async def _make_app(self):
            app = await super()._make_app()
            app.middlewares.append(self._guard)
            app.router.add_get("/ws/{token}", self.handle_websocket)
            app.router.add_get("/ws/{token}/{seat}", self.handle_websocket)
            return app

        def seat_asked(self, request) -> str:
            """The page's seat (classroom): "teacher-KEY" with the teacher's key, "observer"
            with ``as=observer``, else "driver"."""
            key = request.query.get("teacher")
            if key and self.classroom is not None:
                return f"teacher-{key}"
            return "observer" if request.query.get("as") == "observer" else "driver"

        def seat_given(self, request) -> str:
            """The seat a websocket gets: what its path asked, the teacher's only with the key."""
            asked = request.match_info.get("seat", "driver")
            if asked.startswith("teacher-"):
                key = self.classroom.teacher_key.encode() if self.classroom is not None else b""
                return "teacher" if key and hmac.compare_digest(asked[8:].encode(), key) else "observer"
            return asked if asked in SEATS else "observer"

        async def handle_websocket(self, request):
            if self.classroom is not None:
                _TAB_COMMAND.set(classroom_command(self.args, self.classroom.path, self.seat_given(request)))
            return await base.handle_websocket(self, request)

        def _has_token(self, request) -> str | None:
            """How the request shows the token: "query", "path", "cookie", or None."""
            for how, given in (("path", request.match_info.get("token")), ("query", request.query.get("token")),
                               ("cookie", request.cookies.get(self.cookie))):
                if given and hmac.compare_digest(str(given).encode(), self.token.encode()):
                    return how
            return None

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
            how = self._has_token(request) if self.token else "none"
            if how is None:
                return web.Response(status=403, text=FORBIDDEN)
            response = await handler(request)
            if how == "query" and isinstance(response, web.Response):
                response.set_cookie(self.cookie, self.token, httponly=True, samesite="Strict", path="/")
            return response

        @aiohttp_jinja2.template("app_index.html")
        async def handle_index(self, request):
            context = await base.handle_index.__wrapped__(self, request)
            if self.token:  # the page's websocket carries the token in its path
                context["app_websocket_url"] += f"/{self.token}"
            if self.classroom is not None:  # and the seat after it
                context["app_websocket_url"] += ("" if self.token else "/-") + f"/{self.seat_asked(request)}"
            return context

        async def on_startup(self, app) -> None:
            if self.classroom is not None:
                more = "&" if self.token else "?"
                self.console.print("fieldbox serve --classroom: one field for every tab", highlight=False)
                self.console.print(f"  students (drive a free station, else watch): [bold]{self.url}[/bold]",
                                   highlight=False, soft_wrap=True)
                self.console.print(f"  watch only: [bold]{self.url}{more}as=observer[/bold]", highlight=False,
                                   soft_wrap=True)
                self.console.print(f"  teacher (FMS, hands stations out; keep it to yourself): "
                                   f"[bold]{self.url}{more}teacher={self.classroom.teacher_key}[/bold]",
                                   highlight=False, soft_wrap=True)
            else:
                self.console.print(f"fieldbox serve: open [bold]{self.url}[/bold]", highlight=False, soft_wrap=True)
            if not self.token:
                self.console.print("(--no-token: anyone who can reach this port gets a fieldbox)", highlight=False)
            self.console.print("[cyan]Press Ctrl+C to quit", highlight=False)

        async def on_shutdown(self, app) -> None:
            tabs = list(TabApp.running)
            if tabs:
                await asyncio.wait([asyncio.ensure_future(t.stop()) for t in tabs], timeout=5)

    return FieldboxServer
