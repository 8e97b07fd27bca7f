"""Screenshots (issue 20): Textual saves to ~/Downloads, which an SSH session often lacks; the
app saves to the run's log folder (else the current folder) and says where."""

from __future__ import annotations

import time
from pathlib import Path

from roles.runtime.field import FieldConfig

from fieldbox.app import FieldboxApp, engine_factory

from .helpers import make_app, one_team


async def _saved(pilot, app) -> str:
    end = time.monotonic() + 20
    while time.monotonic() < end:
        said = [str(n.message) for n in app._notifications if "screenshot" in str(n.message).lower()]
        if said:
            return said[-1]
        await pilot.pause(0.05)
    raise AssertionError("no notification about the screenshot")


async def test_a_screenshot_goes_to_the_runs_log_folder(tmp_path, monkeypatch):
    monkeypatch.setenv("HOME", str(tmp_path / "home"))  # no Downloads folder, as over SSH
    config = FieldConfig(team=254, plan="ephemeral", log_dir=str(tmp_path / "logs"))
    app = FieldboxApp(engine_factory("process"), config, animate=False)
    async with app.run_test(size=(100, 30)) as pilot:
        folder = app.engine.log_folder
        assert folder and Path(folder).parent == tmp_path / "logs"
        app.deliver_screenshot()
        said = await _saved(pilot, app)
        assert "Saved screenshot to" in said and folder in said
        [svg] = Path(folder).glob("*.svg")
        assert svg.read_text().startswith("<svg")


async def test_without_log_files_a_screenshot_goes_to_the_current_folder(tmp_path, monkeypatch):
    monkeypatch.setenv("HOME", str(tmp_path / "home"))
    monkeypatch.chdir(tmp_path)
    app, _ = make_app(one_team())  # a field on a fake clock: no log files
    async with app.run_test(size=(100, 30)) as pilot:
        app.deliver_screenshot()
        said = await _saved(pilot, app)
        assert "Saved screenshot to" in said and str(tmp_path) in said
        assert list(tmp_path.glob("*.svg"))
