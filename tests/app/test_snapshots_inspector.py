"""Snapshots of the packet inspector on a SimEngine field at a fixed time (deterministic)."""

from __future__ import annotations

from fieldbox.app import FieldboxApp
from roles.engine import SimEngine
from roles.field import FieldConfig


def make_app(**kw):
    engines: list[SimEngine] = []

    def factory(cfg):
        e = SimEngine(cfg)
        engines.append(e)
        return e

    app = FieldboxApp(factory, FieldConfig(team=254, roles=frozenset({"ds", "rio"})), panel="inspector",
                      animate=False, **kw)
    return app, engines


def test_inspector_control_packet_annotated(snap_compare):
    """A DS control packet selected, the hex cursor on its control byte."""
    app, engines = make_app()

    async def run_before(pilot) -> None:
        engines[0].advance(1.0)
        app.refresh_views()
        await pilot.pause()
        await pilot.press("tab", "right", "right", "right")
        await pilot.pause()

    assert snap_compare(app, terminal_size=(120, 40), run_before=run_before)


def test_inspector_projector_theme(snap_compare):
    """The same view in the high-contrast light theme used on projectors."""
    app, engines = make_app(theme_name="projector-light")

    async def run_before(pilot) -> None:
        engines[0].advance(1.0)
        app.refresh_views()
        await pilot.pause()
        await pilot.press("tab", "right", "right", "right")
        await pilot.pause()

    assert snap_compare(app, terminal_size=(120, 40), run_before=run_before)
