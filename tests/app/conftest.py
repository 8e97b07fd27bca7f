"""Fixtures of the app tests (the shared helpers are plain functions in helpers.py)."""

from __future__ import annotations

import pytest


@pytest.fixture
def no_real_joysticks(monkeypatch, tmp_path):
    """A joystick plugged into the test machine must not matter, nor the user's own themes.
    A module asks for it with ``pytestmark = pytest.mark.usefixtures("no_real_joysticks")``."""
    monkeypatch.setenv("FIELDBOX_JOYSTICKS", "off")
    monkeypatch.setenv("XDG_CONFIG_HOME", str(tmp_path))
