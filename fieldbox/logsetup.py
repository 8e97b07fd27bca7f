"""Where fieldbox writes its log: ``--log-file``, else the user log folder."""

from __future__ import annotations

import logging
import os
import sys
from pathlib import Path

FORMAT = "%(asctime)s %(levelname)s %(name)s: %(message)s"


def default_log_dir() -> Path:
    from platformdirs import user_log_dir

    return Path(user_log_dir("fieldbox", appauthor=False))


def setup_logging(log_file: str | None, *, headless: bool) -> Path | None:
    """File log at INFO (the given file, or fieldbox.log in the user log folder); headless
    mode also prints warnings on stderr. Returns the log file path (None if it cannot be
    opened: then only stderr, and a warning says why)."""
    root = logging.getLogger()
    root.setLevel(logging.INFO)
    path = Path(log_file) if log_file else default_log_dir() / "fieldbox.log"
    problem = None
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        handler: logging.Handler | None = logging.FileHandler(path, encoding="utf-8")
    except OSError as exc:
        handler, problem = None, f"cannot write the log file {path}: {exc.strerror or exc}"
    if handler is not None:
        handler.setFormatter(logging.Formatter(FORMAT))
        root.addHandler(handler)
    if headless or handler is None:
        err = logging.StreamHandler(sys.stderr)
        err.setLevel(logging.WARNING)
        err.setFormatter(logging.Formatter("%(levelname)s %(name)s: %(message)s"))
        root.addHandler(err)
    if problem:
        logging.getLogger("fieldbox").warning("%s", problem)
        return None
    logging.getLogger("fieldbox").info("fieldbox %s started, pid %d", _version(), os.getpid())
    return path


def _version() -> str:
    from . import __version__

    return __version__
