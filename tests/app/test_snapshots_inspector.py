"""Snapshots of the packet inspector on a SimEngine field at a fixed time (deterministic)."""

from __future__ import annotations

from .helpers import SIZE, make_app, one_team, step


async def select_the_control_byte(pilot) -> None:
    await step(pilot, 1.0)
    await pilot.press("tab", "right", "right", "right")
    await pilot.pause()


def test_inspector_control_packet_annotated(snap_compare):
    """A DS control packet selected, the hex cursor on its control byte."""
    app, _ = make_app(one_team(), "inspector")
    assert snap_compare(app, terminal_size=SIZE, run_before=select_the_control_byte)


def test_inspector_projector_theme(snap_compare):
    """The same view in the high-contrast light theme used on projectors."""
    app, _ = make_app(one_team(), "inspector", theme_name="projector-light")
    assert snap_compare(app, terminal_size=SIZE, run_before=select_the_control_byte)
