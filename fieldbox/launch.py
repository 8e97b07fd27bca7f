"""Start what the command line asked for: headless, the app, or the browser server."""

from __future__ import annotations

import asyncio


def run(args, parser) -> int:
    from .headless import config_from_args

    try:
        config = config_from_args(args)
    except ValueError as exc:
        parser.error(str(exc))
    _setup_logging(args)
    if args.command == "run":
        from .script import run_script

        try:
            return asyncio.run(run_script(config, args.script, launch=args.launch, as_json=args.json,
                                          junit_path=args.junit))
        except KeyboardInterrupt:
            return 130
    if args.headless:
        from .headless import run as run_headless

        try:
            return asyncio.run(run_headless(config, as_json=args.json, exit_guard=True, realtime=True))
        except KeyboardInterrupt:
            return 0
    if args.command == "serve":
        from .serve import serve

        return serve(args, config)
    if getattr(args, "join", None):
        from .app import FieldboxApp
        from roles.runtime.classroom import JoinedEngine

        from roles.runtime.classroom import wanted_seat

        try:
            want = wanted_seat(args.join_as)
        except ValueError as exc:
            parser.error(str(exc))

        def joined(cfg):
            engine = JoinedEngine(args.join, want, cfg)
            engine.start()
            return engine

        FieldboxApp(joined, config, theme_name=args.theme, hold_collector=True).run()
        return 0
    from .app import run_app, wire_kind

    try:
        wire_kind(args)
    except ValueError as exc:
        parser.error(f"FIELDBOX_WIRE: {exc}")
    return run_app(config, args)


def _setup_logging(args) -> None:
    from .logsetup import setup_logging

    setup_logging(args.log_file, headless=args.headless)
