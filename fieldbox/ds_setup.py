"""Changes to a Driver Station core that the command language has no words for, run on the
wire's side through ``CoreCall`` (they cross to a wire in another process by name: this
module imports no textual, so the wire's process stays free of it).
"""

from __future__ import annotations

import dataclasses
from typing import Any

from roles.cores.core import CommandError


def set_practice_timing(ds: Any, **lengths: float) -> None:
    """The DS's practice match timing, for the next practice run (``countdown``, ``auto``,
    ``pause``, ``teleop`` in seconds, 0..3600). A bad value is refused, nothing changed."""
    try:
        ds.arbiter.practice_timing = dataclasses.replace(ds.arbiter.practice_timing, **lengths)
    except (TypeError, ValueError) as exc:
        raise CommandError(str(exc)) from None
