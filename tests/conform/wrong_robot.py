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


if __name__ == "__main__":
    from wrong_ds import run_with_bug  # beside this file, on the path of a script run

    sys.exit(run_with_bug(sys.argv[1:], install, __doc__))
