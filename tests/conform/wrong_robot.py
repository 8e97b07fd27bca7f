"""Deliberately wrong robots for the conformance tests: fieldbox's own fake roboRIO, run
headless, with one bug of another implementation put in.

    python tests/conform/wrong_robot.py BUG -- FIELDBOX ARGS...

BUG is one of:

* ``crash-many-povs``: the process dies by SIGSEGV on a joystick tag with more than 6 POVs,
  as WPILib's simulator could: it writes POV i to ``povs[2*i]`` of a 12-entry array, so a
  seventh POV lands past its end (PROTOCOL-NOTES Corrections "WPILib's 2026 simulator").
"""

from __future__ import annotations

import os
import signal
import sys

BUGS = ("crash-many-povs",)


def install(bug: str) -> None:
    if bug == "crash-many-povs":
        from protocol.ds_to_rio import Joystick
        from roles.cores.rio_inputs import DsInputs

        take = DsInputs.take_tags

        def overflow(self, tags):
            if any(type(t) is Joystick and 2 * (len(t.povs) - 1) >= 12 for t in tags):
                os.kill(os.getpid(), signal.SIGSEGV)  # what writing past an array can end in
            return take(self, tags)
        DsInputs.take_tags = overflow
    else:
        raise SystemExit(f"unknown bug {bug!r}: one of {', '.join(BUGS)}")


def main(argv: list[str]) -> int:
    if len(argv) < 2 or argv[1] != "--":
        raise SystemExit(__doc__)
    install(argv[0])
    from fieldbox.cli import main as fieldbox

    return fieldbox(argv[2:])


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
