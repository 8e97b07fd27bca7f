"""Practice mode: a match the Driver Station times itself, with no FMS.

The NI Driver Station's practice mode runs countdown, autonomous, a pause, teleop, then
stops. This module is only the clock: which phase a run is in at ``now`` and how many
seconds are left in it. The DS (``roles/cores/ds.py``) applies the phase (mode, enable) and sends
the seconds left as the control packet's countdown tag, and it ends the run on an e-stop
or a robot comms loss.
"""

from __future__ import annotations

import enum
import math
from dataclasses import dataclass

from protocol.enums import Mode


class PracticePhase(enum.Enum):
    """The phases of a practice run, in order, with the mode and enable each one asks for."""

    COUNTDOWN = "countdown"
    AUTO = "auto"
    PAUSE = "pause"
    TELEOP = "teleop"
    ENDED = "ended"

    @property
    def enabled(self) -> bool:
        return self in (PracticePhase.AUTO, PracticePhase.TELEOP)

    @property
    def mode(self) -> Mode:
        # Pre-match is autonomous and disabled, as on a field (docs/protocol.md#fms-phases), so a
        # robot program's disabledPeriodic sees the right mode before auto begins.
        if self in (PracticePhase.COUNTDOWN, PracticePhase.AUTO):
            return Mode.AUTONOMOUS
        return Mode.TELEOP


@dataclass(frozen=True)
class PracticeTiming:
    """Phase lengths in seconds (defaults: the NI DS's practice 3 s countdown, then the
    classic 15 s auto, 1 s pause, 135 s teleop). A phase of 0 s is skipped."""

    countdown: float = 3.0
    auto: float = 15.0
    pause: float = 1.0
    teleop: float = 135.0

    def __post_init__(self) -> None:
        for name in ("countdown", "auto", "pause", "teleop"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, float)) \
                    or not math.isfinite(value) or not 0 <= value <= 3600:
                raise ValueError(f"practice {name} must be 0..3600 seconds, not {value!r}")

    def phases(self) -> tuple[tuple[PracticePhase, float], ...]:
        return ((PracticePhase.COUNTDOWN, float(self.countdown)), (PracticePhase.AUTO, float(self.auto)),
                (PracticePhase.PAUSE, float(self.pause)), (PracticePhase.TELEOP, float(self.teleop)))

    @property
    def total(self) -> float:
        return sum(d for _, d in self.phases())


class PracticeRun:
    """One run, started at ``start`` (the DS's clock). Pure arithmetic on absolute times:
    phase boundaries are ``start + sum of the phases before``, so nothing drifts."""

    __slots__ = ("timing", "start", "_bounds")

    def __init__(self, timing: PracticeTiming, start: float) -> None:
        self.timing = timing
        self.start = start
        bounds = []
        t = start
        for phase, length in timing.phases():
            if length > 0:
                bounds.append((phase, t, t + length))
                t += length
        self._bounds = tuple(bounds)

    def phase_at(self, now: float) -> tuple[PracticePhase, float]:
        """The phase at ``now`` and the seconds left in it (0 once ended)."""
        for phase, begin, end in self._bounds:
            if now < end:
                return phase, end - max(now, begin)
        return PracticePhase.ENDED, 0.0

    def next_boundary(self, now: float) -> float | None:
        """When the phase next changes, or None once ended."""
        for _, _, end in self._bounds:
            if now < end:
                return end
        return None
