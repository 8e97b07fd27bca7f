"""The match: its phases as a table of ``(phase, input) -> (action, new phase)`` (the h2 shape,
docs/style.md), and the match clock that drives it on absolute, drift-free period boundaries.

Phases (docs/protocol.md#fms-phases): pre-match (auto mode, disabled), auto
(enabled), pause (disabled), teleop (enabled), post-match (disabled). The table is total:
every pair has an entry, so a test can walk all of them, and an input that makes no sense in
a phase is an explicit ``IGNORE`` (a timer with nothing running) or ``REFUSE`` (a user
command that cannot be carried out, with the reason the user reads).

Nothing here knows about stations, e-stops or sockets: :mod:`roles.cores.fms` asks the match
which phase it is in and what the control byte's mode and remaining time are.
"""

from __future__ import annotations

import enum
import math
from dataclasses import dataclass

from protocol.enums import Mode, TournamentLevel

from .core import CommandError


class Phase(str, enum.Enum):  # a str: a view holds its value, and compares equal to it
    PRE_MATCH = "pre-match"
    AUTO = "auto"
    PAUSE = "pause"
    TELEOP = "teleop"
    POST_MATCH = "post-match"


class Input(enum.Enum):
    START = "start"            # the user starts the match
    PERIOD_END = "period-end"  # the match clock reached the end of the current period
    ABORT = "abort"            # the user aborts the match
    RESET = "reset"            # back to pre-match: reset, replay or set up the next match


class Action(enum.Enum):
    BEGIN_AUTO = "begin-auto"
    BEGIN_PAUSE = "begin-pause"
    BEGIN_TELEOP = "begin-teleop"
    END_MATCH = "end-match"
    ABORT_MATCH = "abort-match"
    RESET_MATCH = "reset-match"
    IGNORE = "ignore"  # nothing happens (a period end with no period running)
    REFUSE = "refuse"  # a command that cannot be carried out here: see REFUSALS


P, I, A = Phase, Input, Action

#: The whole state machine. Every (phase, input) pair is here.
TABLE: dict[tuple[Phase, Input], tuple[Action, Phase]] = {
    (P.PRE_MATCH, I.START): (A.BEGIN_AUTO, P.AUTO),
    (P.PRE_MATCH, I.PERIOD_END): (A.IGNORE, P.PRE_MATCH),
    (P.PRE_MATCH, I.ABORT): (A.REFUSE, P.PRE_MATCH),
    (P.PRE_MATCH, I.RESET): (A.RESET_MATCH, P.PRE_MATCH),

    (P.AUTO, I.START): (A.REFUSE, P.AUTO),
    (P.AUTO, I.PERIOD_END): (A.BEGIN_PAUSE, P.PAUSE),
    (P.AUTO, I.ABORT): (A.ABORT_MATCH, P.POST_MATCH),
    (P.AUTO, I.RESET): (A.REFUSE, P.AUTO),

    (P.PAUSE, I.START): (A.REFUSE, P.PAUSE),
    (P.PAUSE, I.PERIOD_END): (A.BEGIN_TELEOP, P.TELEOP),
    (P.PAUSE, I.ABORT): (A.ABORT_MATCH, P.POST_MATCH),
    (P.PAUSE, I.RESET): (A.REFUSE, P.PAUSE),

    (P.TELEOP, I.START): (A.REFUSE, P.TELEOP),
    (P.TELEOP, I.PERIOD_END): (A.END_MATCH, P.POST_MATCH),
    (P.TELEOP, I.ABORT): (A.ABORT_MATCH, P.POST_MATCH),
    (P.TELEOP, I.RESET): (A.REFUSE, P.TELEOP),

    (P.POST_MATCH, I.START): (A.REFUSE, P.POST_MATCH),
    (P.POST_MATCH, I.PERIOD_END): (A.IGNORE, P.POST_MATCH),
    (P.POST_MATCH, I.ABORT): (A.REFUSE, P.POST_MATCH),
    (P.POST_MATCH, I.RESET): (A.RESET_MATCH, P.PRE_MATCH),
}

_RUNNING_REASON = "match already running"
#: Why each REFUSE entry refuses: what the user reads.
REFUSALS: dict[tuple[Phase, Input], str] = {
    (P.PRE_MATCH, I.ABORT): "no match running",
    (P.AUTO, I.START): _RUNNING_REASON,
    (P.PAUSE, I.START): _RUNNING_REASON,
    (P.TELEOP, I.START): _RUNNING_REASON,
    (P.AUTO, I.RESET): "match running: abort it first",
    (P.PAUSE, I.RESET): "match running: abort it first",
    (P.TELEOP, I.RESET): "match running: abort it first",
    (P.POST_MATCH, I.START): "match is over: reset it or set up the next match first",
    (P.POST_MATCH, I.ABORT): "no match running",
}

RUNNING = frozenset({P.AUTO, P.PAUSE, P.TELEOP})
#: Phases in which the match enables robots (each station may still be held back).
ENABLING = frozenset({P.AUTO, P.TELEOP})
#: What a phase change is called in events: "Match 12 auto started".
PHASE_EVENT = {
    A.BEGIN_AUTO: "auto started",
    A.BEGIN_PAUSE: "pause started",
    A.BEGIN_TELEOP: "teleop started",
    A.END_MATCH: "ended",
    A.ABORT_MATCH: "aborted",
    A.RESET_MATCH: "reset to pre-match",
}


def transition(phase: Phase, event: Input) -> tuple[Action, Phase]:
    """The table's entry for ``(phase, event)``."""
    return TABLE[(phase, event)]


def mode_for(phase: Phase) -> Mode:
    """The control byte's mode: auto in pre-match and auto, teleop from the pause on
    (docs/protocol.md#cheesy-arena; Cheesy Arena sends the pause as teleop, disabled)."""
    return Mode.AUTONOMOUS if phase in (P.PRE_MATCH, P.AUTO) else Mode.TELEOP


@dataclass(frozen=True)
class MatchTiming:
    """Period lengths in seconds (the current season's: auto 20, pause 3, teleop 140)."""

    auto: float = 20.0
    pause: float = 3.0
    teleop: float = 140.0

    def __post_init__(self) -> None:
        for name in ("auto", "pause", "teleop"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, float)) \
                    or not math.isfinite(value) or not 0 <= value <= 0xFFFF:
                raise ValueError(f"{name} duration must be 0..65535 s, not {value!r}")

    def duration(self, phase: Phase) -> float | None:
        return {P.AUTO: self.auto, P.PAUSE: self.pause, P.TELEOP: self.teleop}.get(phase)


class Match:
    """One match: the phase, the match clock and what the control packet says about it.

    Period boundaries are absolute: each period starts exactly where the last one ended,
    whenever ``advance`` happens to be called, so a late poll never stretches the match.
    """

    def __init__(self, timing: MatchTiming | None = None,
                 level: TournamentLevel = TournamentLevel.PRACTICE, number: int = 1,
                 play: int = 1) -> None:
        self.timing = timing or MatchTiming()
        self.phase = P.PRE_MATCH
        self.period_start: float | None = None  # when the current period began (running only)
        self.started_at: float | None = None    # when auto began
        self.ended_at: float | None = None      # when the match ended or was aborted
        self.aborted = False
        self.level: TournamentLevel | int = level  # an int: a level no document names
        self.number = number
        self.play = play
        self.setup(level, number, play)

    # -- what the panels and the control packet read -------------------------------------
    @property
    def running(self) -> bool:
        return self.phase in RUNNING

    @property
    def enabling(self) -> bool:
        return self.phase in ENABLING

    @property
    def mode(self) -> Mode:
        return mode_for(self.phase)

    @property
    def period_end(self) -> float | None:
        """When the current period ends (absolute), or None outside a running match."""
        duration = self.timing.duration(self.phase)
        if duration is None or self.period_start is None:
            return None
        return self.period_start + duration

    def remaining(self, now: float) -> float:
        """Seconds left in the CURRENT period (docs/protocol.md#fms-behaviour); pre-match shows the whole auto
        period, post-match 0."""
        if self.phase is P.PRE_MATCH:
            return float(self.timing.auto)
        end = self.period_end
        if end is None:
            return 0.0
        # end - now can come out a hair above the duration (float sums): clamp it.
        return min(float(self.timing.duration(self.phase) or 0.0), max(0.0, end - now))

    def remaining_seconds(self, now: float) -> int:
        """Whole seconds for the control packet, rounded up (a countdown shows 1 until 0);
        a microsecond of float noise above a whole second does not round up."""
        return min(0xFFFF, math.ceil(self.remaining(now) - 1e-6))

    @property
    def label(self) -> str:
        return f"Match {self.number}" + (f" (play {self.play})" if self.play > 1 else "")

    # -- setting up ---------------------------------------------------------------------------
    def setup(self, level: TournamentLevel | int, number: int, play: int = 1) -> None:
        """Set the match type, number and play number. Not while a match runs."""
        if self.running:
            raise CommandError(REFUSALS[(self.phase, I.RESET)])
        if isinstance(level, bool) or not isinstance(level, int) or not 0 <= int(level) <= 0xFF:
            raise CommandError(f"match type must be a tournament level 0-255, not {level!r}")
        if isinstance(number, bool) or not isinstance(number, int) or not 0 <= number <= 0xFFFF:
            raise CommandError(f"match number must be 0..65535, not {number!r}")
        if isinstance(play, bool) or not isinstance(play, int) or not 0 <= play <= 0xFF:
            raise CommandError(f"play number must be 0..255, not {play!r}")
        known: TournamentLevel | int = level
        try:
            known = TournamentLevel(level)
        except ValueError:
            pass  # a level no document names: kept as a plain int for the wire
        self.level, self.number, self.play = known, number, play

    def set_timing(self, timing: MatchTiming) -> None:
        if self.running:
            raise CommandError("cannot change period lengths while a match runs")
        self.timing = timing

    # -- driving the table ----------------------------------------------------------------------
    def handle(self, event: Input, now: float) -> Action:
        """Apply one input at time ``now``. A REFUSE entry raises CommandError, changing nothing."""
        action, new_phase = transition(self.phase, event)
        if action is A.REFUSE:
            raise CommandError(REFUSALS[(self.phase, event)])
        if action is A.IGNORE:
            return action
        if action is A.BEGIN_AUTO:
            self.started_at = now
            self.ended_at = None
            self.aborted = False
        elif action in (A.END_MATCH, A.ABORT_MATCH):
            self.ended_at = now
            self.aborted = action is A.ABORT_MATCH
        elif action is A.RESET_MATCH:
            self.started_at = self.ended_at = None
            self.aborted = False
        self.phase = new_phase
        self.period_start = now if new_phase in RUNNING else None
        return action

    def advance(self, now: float) -> list[tuple[float, Action]]:
        """End every period that is over by ``now``, each at its own boundary (never at
        ``now``): returns ``(boundary, action)`` per phase change, in order."""
        changes = []
        end = self.period_end
        while end is not None and now >= end:
            changes.append((end, self.handle(I.PERIOD_END, end)))
            end = self.period_end
        return changes


__all__ = ["ENABLING", "PHASE_EVENT", "REFUSALS", "RUNNING", "TABLE", "Action", "Input", "Match",
           "MatchTiming", "Phase", "mode_for", "transition"]
