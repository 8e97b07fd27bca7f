"""Practice mode: the DS times a match itself (countdown, auto, pause, teleop, end)."""

from __future__ import annotations

import pytest

from protocol.ds_to_rio import Countdown, decode_control
from protocol.enums import Mode
from roles.cores.core import CommandError
from roles.cores.practice import PracticePhase, PracticeRun, PracticeTiming

from .test_ds import Harness, connected, make_ds


def countdown_of(pkt) -> float | None:
    tags = [t.seconds for t in pkt.tags if isinstance(t, Countdown)]
    return tags[0] if tags else None


def test_practice_run_clock_is_pure_arithmetic():
    run = PracticeRun(PracticeTiming(), 10.0)
    assert run.phase_at(10.0) == (PracticePhase.COUNTDOWN, 3.0)
    assert run.phase_at(12.5) == (PracticePhase.COUNTDOWN, 0.5)
    assert run.phase_at(13.0) == (PracticePhase.AUTO, 15.0)
    assert run.phase_at(28.0) == (PracticePhase.PAUSE, 1.0)
    assert run.phase_at(29.0) == (PracticePhase.TELEOP, 135.0)
    assert run.phase_at(164.0) == (PracticePhase.ENDED, 0.0)
    assert run.next_boundary(10.0) == 13.0 and run.next_boundary(28.5) == 29.0
    assert run.next_boundary(200.0) is None
    assert PracticeTiming().total == 154.0
    # a 0 s phase is skipped
    run = PracticeRun(PracticeTiming(countdown=0, pause=0), 0.0)
    assert run.phase_at(0.0) == (PracticePhase.AUTO, 15.0)
    assert run.phase_at(15.0) == (PracticePhase.TELEOP, 135.0)


@pytest.mark.parametrize("bad", [-1, float("nan"), float("inf"), "3", True, 4000])
def test_practice_timing_is_validated(bad):
    with pytest.raises(ValueError):
        PracticeTiming(auto=bad)


def test_practice_phases_set_mode_enable_and_countdown():
    h = connected()
    h.ds.start_practice(h.t)
    start = h.ds.arbiter.practice.start
    seen = []  # (phase, enabled, mode) in the order the packets went out
    samples = {}
    h.run(160.0)
    for t, d in h.datagrams:
        if d.channel != "robot" or t < start:
            continue
        pkt = decode_control(d.data)
        left = countdown_of(pkt)
        key = (pkt.enabled, pkt.mode, left is not None)
        if not seen or seen[-1] != key:
            seen.append(key)
        samples[round(t - start, 2)] = (pkt.enabled, pkt.mode, left)
    assert seen == [
        (False, Mode.AUTONOMOUS, True),   # countdown
        (True, Mode.AUTONOMOUS, True),    # auto
        (False, Mode.TELEOP, True),       # pause
        (True, Mode.TELEOP, True),        # teleop
        (False, Mode.TELEOP, False),      # over: disabled, no countdown
    ]
    # the countdown tag is the seconds left in the CURRENT period
    assert samples[1.0][2] == pytest.approx(2.0, abs=0.021)
    assert samples[3.5][:2] == (True, Mode.AUTONOMOUS) and samples[3.5][2] == pytest.approx(14.5, abs=0.021)
    assert samples[10.0][2] == pytest.approx(8.0, abs=0.021)
    assert samples[18.5][:2] == (False, Mode.TELEOP) and samples[18.5][2] == pytest.approx(0.5, abs=0.021)
    assert samples[100.0][:2] == (True, Mode.TELEOP) and samples[100.0][2] == pytest.approx(54.0, abs=0.021)
    assert max(t for t, (en, _, _) in samples.items() if en) == pytest.approx(154.0, abs=0.021)
    assert h.ds.arbiter.practice is None and not h.ds.enabled
    texts = [text for _, text in h.ds.events.items]
    assert "practice run over" in texts
    assert any(text.startswith("practice: auto") for text in texts)


def test_practice_durations_are_configurable():
    h = connected(practice_timing=PracticeTiming(countdown=1, auto=2, pause=0.5, teleop=3))
    h.ds.start_practice(h.t)
    h.run(1.5)
    assert h.ds.arbiter.practice_phase is PracticePhase.AUTO and h.last_control().enabled
    assert h.ds.snapshot()["practice"] == "auto"
    h.run(2.1)
    assert h.ds.arbiter.practice_phase is PracticePhase.TELEOP
    h.run(3.0)
    assert h.ds.arbiter.practice is None and not h.last_control().enabled
    h.ds.start_practice(h.t, PracticeTiming(countdown=0, auto=0, pause=0, teleop=1))
    assert h.ds.arbiter.practice_phase is PracticePhase.TELEOP


def test_estop_ends_practice():
    h = connected()
    h.ds.start_practice(h.t)
    h.run(5.0)
    assert h.last_control().enabled
    h.ds.estop(h.t)
    h.run(0.05)
    assert h.ds.arbiter.practice is None and not h.last_control().enabled and h.last_control().estop
    assert countdown_of(h.last_control()) is None


def test_comms_loss_ends_practice_and_it_does_not_resume():
    h = connected()
    h.ds.start_practice(h.t)
    h.run(5.0)
    h.robot.online = False
    h.run(1.5)
    assert h.ds.arbiter.practice is None
    h.robot.online = True
    h.run(1.0)
    assert h.ds.link.robot_comms and not h.last_control().enabled
    assert any("robot comms lost" in text for _, text in h.ds.events.items)


def test_stop_and_disable_end_practice():
    h = connected()
    h.ds.start_practice(h.t)
    h.run(4.0)
    with pytest.raises(CommandError, match="practice"):
        h.ds.enable(h.t)
    with pytest.raises(CommandError, match="practice"):
        h.ds.set_mode(Mode.TEST, h.t)
    with pytest.raises(CommandError, match="already"):
        h.ds.start_practice(h.t)
    h.ds.stop_practice(h.t)
    h.run(0.05)
    assert h.ds.arbiter.practice is None and not h.last_control().enabled
    with pytest.raises(CommandError, match="no practice"):
        h.ds.stop_practice(h.t)
    h.ds.start_practice(h.t)
    h.run(4.0)
    h.ds.disable(h.t)
    h.run(0.05)
    assert h.ds.arbiter.practice is None and not h.last_control().enabled


def test_practice_needs_comms_and_no_estop():
    h = Harness(make_ds())
    h.robot.online = False
    h.run(0.5)
    with pytest.raises(CommandError, match="no robot comms"):
        h.ds.start_practice(h.t)
    h.robot.online = True
    h.run(0.5)
    h.ds.estop(h.t)
    with pytest.raises(CommandError, match="e-stopped"):
        h.ds.start_practice(h.t)
    assert h.ds.arbiter.practice is None
