"""The match state machine: the (phase, input) table, every pair, and the match clock."""

from __future__ import annotations

import itertools

import pytest
from hypothesis import given
from hypothesis import strategies as st
from hypothesis.stateful import RuleBasedStateMachine, invariant, precondition, rule

from protocol.enums import Mode, TournamentLevel
from roles.cores.core import CommandError
from roles.cores.match import (ENABLING, PHASE_EVENT, REFUSALS, RUNNING, TABLE, Action, Input, Match,
                               MatchTiming, Phase, mode_for, transition)

PHASES = list(Phase)
INPUTS = list(Input)


def test_table_is_total():
    assert set(TABLE) == set(itertools.product(PHASES, INPUTS))


@given(st.sampled_from(PHASES), st.sampled_from(INPUTS))
def test_every_pair(phase, event):
    action, new = transition(phase, event)
    if action is Action.REFUSE:
        assert new is phase and REFUSALS[(phase, event)]
    else:
        assert (phase, event) not in REFUSALS
    if action is Action.IGNORE:
        assert new is phase
    if action not in (Action.REFUSE, Action.IGNORE):
        assert action in PHASE_EVENT
    # What each input may do, whatever the phase.
    if event is Input.ABORT:
        assert new is (Phase.POST_MATCH if phase in RUNNING else phase)
    if event is Input.START:
        assert (action is Action.BEGIN_AUTO) == (phase is Phase.PRE_MATCH)
    if event is Input.RESET:
        assert new is (phase if phase in RUNNING else Phase.PRE_MATCH)
    if event is Input.PERIOD_END:
        assert (phase in RUNNING) == (action not in (Action.IGNORE,))
    # Only a start enters a running match; nothing leaves post-match but a reset.
    if phase not in RUNNING and new in RUNNING:
        assert (phase, event) == (Phase.PRE_MATCH, Input.START) and new is Phase.AUTO
    if phase is Phase.POST_MATCH and new is not phase:
        assert event is Input.RESET


@given(st.sampled_from(PHASES), st.sampled_from(INPUTS), st.floats(0, 1e6))
def test_handle_follows_the_table(phase, event, now):
    m = Match(MatchTiming(2, 1, 3))
    m.phase = phase
    m.period_start = 0.0 if phase in RUNNING else None
    action, new = transition(phase, event)
    if action is Action.REFUSE:
        with pytest.raises(CommandError, match=REFUSALS[(phase, event)]):
            m.handle(event, now)
        assert m.phase is phase
    else:
        assert m.handle(event, now) is action
        assert m.phase is new
        if new in RUNNING and new is not phase:
            assert m.period_start == now


def test_modes_and_enabling_phases():
    assert ENABLING == {Phase.AUTO, Phase.TELEOP}
    assert [mode_for(p) for p in PHASES] == [Mode.AUTONOMOUS, Mode.AUTONOMOUS, Mode.TELEOP,
                                             Mode.TELEOP, Mode.TELEOP]


def test_a_whole_match_on_period_boundaries():
    m = Match(MatchTiming(20, 3, 140), TournamentLevel.QUALIFICATION, 12)
    assert m.remaining_seconds(0.0) == 20  # pre-match shows the auto period
    m.handle(Input.START, 100.0)
    assert m.remaining_seconds(100.0) == 20
    assert m.remaining_seconds(100.1) == 20  # rounded up: a countdown shows 1 until 0
    assert m.remaining_seconds(101.0) == 19
    assert m.advance(119.99) == []
    # Polled late, at 124.5: auto ended at 120 and the pause at 123, each at its boundary.
    assert m.advance(124.5) == [(120.0, Action.BEGIN_PAUSE), (123.0, Action.BEGIN_TELEOP)]
    assert m.phase is Phase.TELEOP and m.period_start == 123.0
    assert m.remaining_seconds(124.5) == 139  # the current period, not the whole match
    assert m.advance(263.0) == [(263.0, Action.END_MATCH)]
    assert m.phase is Phase.POST_MATCH and m.remaining_seconds(300.0) == 0
    assert m.ended_at == 263.0 and not m.aborted


def test_zero_length_periods_pass_through():
    m = Match(MatchTiming(0, 0, 1))
    m.handle(Input.START, 5.0)
    assert m.advance(5.0) == [(5.0, Action.BEGIN_PAUSE), (5.0, Action.BEGIN_TELEOP)]
    assert m.advance(6.0) == [(6.0, Action.END_MATCH)]


@pytest.mark.parametrize("bad", [-1, float("nan"), float("inf"), 70000, "20", True])
def test_timing_is_checked(bad):
    with pytest.raises(ValueError):
        MatchTiming(auto=bad)


def test_setup_refused_while_running_and_checked():
    m = Match()
    m.setup(TournamentLevel.PLAYOFF, 7, 2)
    assert (m.level, m.number, m.play, m.label) == (TournamentLevel.PLAYOFF, 7, 2, "Match 7 (play 2)")
    for bad in [(1, -1, 1), (1, 70000, 1), (1, 1, 300), (300, 1, 1)]:
        with pytest.raises(CommandError):
            m.setup(*bad)
    m.handle(Input.START, 0.0)
    with pytest.raises(CommandError, match="abort it first"):
        m.setup(TournamentLevel.PRACTICE, 8)
    with pytest.raises(CommandError):
        m.set_timing(MatchTiming())


class MatchMachine(RuleBasedStateMachine):
    """Random inputs and clock jumps: the clock never drifts and the table is obeyed."""

    def __init__(self) -> None:
        super().__init__()
        self.timing = MatchTiming(2.0, 0.5, 3.0)
        self.m = Match(self.timing)
        self.now = 0.0

    @rule(event=st.sampled_from([Input.START, Input.ABORT, Input.RESET]))
    def command(self, event):
        before = self.m.phase
        action, new = transition(before, event)
        if action is Action.REFUSE:
            with pytest.raises(CommandError):
                self.m.handle(event, self.now)
            assert self.m.phase is before
        else:
            self.m.handle(event, self.now)
            assert self.m.phase is new

    @rule(dt=st.floats(0, 4, allow_nan=False))
    def time_passes(self, dt):
        self.now += dt
        start = self.m.started_at
        for boundary, action in self.m.advance(self.now):
            assert boundary <= self.now
            if action is Action.BEGIN_PAUSE:
                assert boundary == start + self.timing.auto
            elif action is Action.BEGIN_TELEOP:
                assert boundary == start + self.timing.auto + self.timing.pause
            elif action is Action.END_MATCH:
                assert boundary == start + self.timing.auto + self.timing.pause + self.timing.teleop

    @precondition(lambda self: self.m.running)
    @invariant()
    def running_period_has_an_end_after_now(self):
        end = self.m.period_end
        assert end is not None
        assert 0 <= self.m.remaining(self.now) <= self.timing.duration(self.m.phase)

    @invariant()
    def phase_facts(self):
        m = self.m
        assert m.enabling == (m.phase in ENABLING)
        assert (m.period_end is None) == (m.phase not in RUNNING)
        if m.phase is Phase.POST_MATCH:
            assert m.remaining_seconds(self.now) == 0


TestMatchMachine = MatchMachine.TestCase
