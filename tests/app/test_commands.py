"""A key reaches the core as a typed command (roles/cores/commands.py), never as a line of the
command language: key -> typed command -> core -> control bit. Each test breaks the language's
parser first, records what the engine is asked to carry out, and checks the packets."""

from __future__ import annotations

import pytest

from protocol.enums import TournamentLevel
from roles.cores.commands import Disable, Enable, EStop, SetMatchTiming, SetUpMatch
from roles.runtime.field import FieldConfig

from .helpers import SIZE, Harness, one_team


@pytest.fixture
def no_text(monkeypatch):
    """The command language's parser, broken: a key that still went through text fails."""

    def refuse(line):
        raise AssertionError(f"a key went through the command language: {line!r}")

    monkeypatch.setattr("fieldbox.language.parse", refuse)
    monkeypatch.setattr("fieldbox.app.parse", refuse)


def recorded(h: Harness, monkeypatch) -> list:
    """The commands the app hands the engine from now on (they still go on to the field)."""
    sent: list = []
    engine = h.engine
    real = engine.submit_command

    def submit_command(command):
        sent.append(command)
        return real(command)

    monkeypatch.setattr(engine, "submit_command", submit_command)
    return sent


async def test_the_robot_keys_send_typed_commands_that_set_the_control_bits(no_text, monkeypatch):
    h = Harness(one_team())
    async with h.app.run_test(size=SIZE) as pilot:
        h.run(1.0)
        sent = recorded(h, monkeypatch)
        await pilot.press("e", "e")
        h.run(0.3)
        assert sent == [Enable()] and sent[0].issued is not None  # stamped: a late one is refused
        assert h.engine.field.stations[0].ds.enabled and h.wire.last_control().enabled
        await pilot.press("enter")
        h.run(0.3)
        assert sent[-1] == Disable() and not h.wire.last_control().enabled
        await pilot.press("space")
        h.run(0.3)
        assert sent[-1] == EStop() and h.wire.last_control().estop


async def test_the_fms_panels_keys_send_typed_commands_the_fms_obeys(no_text, monkeypatch):
    h = Harness(FieldConfig(team=254), panel="fms")
    async with h.app.run_test(size=SIZE) as pilot:
        h.run(1.0)
        sent = recorded(h, monkeypatch)
        fms = h.engine.field.fms
        number = fms.match.number
        await pilot.press("t")  # the next match type, the same number
        h.run(1.0)
        assert sent == [SetUpMatch(TournamentLevel.QUALIFICATION, number)]
        assert sent[0].team is None  # the FMS's: not the selected team's DS
        packet = h.wire.fms_control()[-1]
        assert (packet.tournament_level, packet.match_number) == (TournamentLevel.QUALIFICATION, number)
        await pilot.press("d", "ctrl+a", *"7", "enter")  # the auto period's box: 7 s
        h.run(0.2)
        assert sent[-1] == SetMatchTiming(auto=7.0) and fms.match.timing.auto == 7.0
