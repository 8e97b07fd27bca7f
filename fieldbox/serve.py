"""``fieldbox serve``: the app in a browser, through textual-serve.

textual-serve starts one process per browser tab, running a command. Here that command is
this same Python running ``fieldbox`` with the options given to ``serve``, on the
``ephemeral`` address plan unless ``--net`` was given: every tab is a field of its own on
OS-chosen ports, so thirty students' tabs never fight over port 1110.
"""

from __future__ import annotations

import os
import shlex
import sys
from pathlib import Path

INSTALL_HINT = "fieldbox serve needs textual-serve: pip install 'fieldbox[serve]'"

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
)


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


def serve(args) -> int:
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
    command = app_command(args)
    server = _server_class(Server)(command, host=args.host, port=args.port, title="fieldbox",
                                   public_url=args.public_url)
    try:
        server.serve()
    except OSError as exc:
        print(f"fieldbox serve: cannot listen on {args.host}:{args.port}: {exc.strerror or exc}",
              file=sys.stderr)
        return 1
    return 0


def _server_class(base):
    """textual-serve's server, plus: stopping it ends every tab's app at once (each is told
    to quit, as when its tab closes) instead of waiting up to a minute for the tabs to go."""
    import asyncio

    import textual_serve.server as textual_serve_server

    class TabApp(textual_serve_server.AppService):
        running: set = set()

        async def start(self, width: int, height: int) -> None:
            TabApp.running.add(self)
            await super().start(width, height)

        async def stop(self) -> None:
            TabApp.running.discard(self)
            await super().stop()

    # handle_websocket makes one AppService per tab by this module-level name.
    textual_serve_server.AppService = TabApp

    class FieldboxServer(base):
        async def on_shutdown(self, app) -> None:
            tabs = list(TabApp.running)
            if tabs:
                await asyncio.wait([asyncio.ensure_future(t.stop()) for t in tabs], timeout=5)

    return FieldboxServer
