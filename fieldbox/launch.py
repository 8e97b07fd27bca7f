"""Start the roles the command line asked for: headless, the app, or the browser server."""

from __future__ import annotations

import sys


def run(args, parser) -> int:
    print("fieldbox: the roles and the app are not built yet; try `fieldbox decode --help`",
          file=sys.stderr)
    return 2
