"""Theme files: the shipped ones load, bad ones are one clear notification, --theme picks one,
the command palette switches."""

from __future__ import annotations

import os
from pathlib import Path

import pytest
from textual.color import Color

from fieldbox.themes import (DEFAULT_THEME, FIELDBOX_VARIABLES, MAX_THEME_BYTES, builtin_theme_dir,
                             load_theme_file, load_themes, user_theme_dir)

from .helpers import make_app, one_team


@pytest.fixture(autouse=True)
def user_themes(tmp_path, monkeypatch) -> Path:
    """A user config folder of our own (platformdirs follows XDG_CONFIG_HOME on Linux)."""
    monkeypatch.setenv("XDG_CONFIG_HOME", str(tmp_path / "config"))
    folder = user_theme_dir()
    assert str(folder).startswith(str(tmp_path))
    folder.mkdir(parents=True)
    return folder


def test_shipped_themes_load_and_are_complete():
    loaded = load_themes([builtin_theme_dir()])
    assert loaded.problems == []
    assert {"fieldbox-dark", "projector-light", "alliance"} <= set(loaded.themes)
    light = loaded.themes["projector-light"]
    assert light.dark is False
    assert Color.parse(light.background).brightness > 0.9 and Color.parse(light.foreground).brightness < 0.1
    for theme in loaded.themes.values():
        assert set(theme.variables) == {f"fb-{k}" for k in FIELDBOX_VARIABLES}
        assert theme.primary and theme.background and theme.error
    alliance = loaded.themes["alliance"]
    red, blue = Color.parse(alliance.variables["fb-alliance-red"]), Color.parse(alliance.variables["fb-alliance-blue"])
    assert red.r > 200 and red.b < 80 and blue.b > 180 and blue.r < 80


def test_themes_ship_in_the_package():
    # pyproject packages `themes` with package-data *.toml: the files must sit in the package.
    assert (builtin_theme_dir() / "__init__.py").exists()
    assert len(list(builtin_theme_dir().glob("*.toml"))) >= 3


@pytest.mark.parametrize("text, words", [
    ('name = "x"\nprimary = "#123456"\nprimray = "#fff"\n', ["primray", "unknown key"]),
    ('name = "x"\nprimary = "#12345g"\n', ["'primary'", "#12345g", "not a colour"]),
    ('name = "x"\nprimary = "#123456"\n[fieldbox]\nestop = "bright"\n', ["fieldbox.estop", "bright"]),
    ('name = "x"\nprimary = "#123456"\n[fieldbox]\nsparkle = "#fff"\n', ["fieldbox.sparkle", "unknown key"]),
    ('primary = "#123456"\n', ["'name' is missing"]),
    ('name = "x"\nprimary = "#123456"\ndark = "yes"\n', ["'dark'"]),
    ('name = "x"\nprimary = \n', ["not valid TOML"]),
])
def test_a_bad_file_names_the_file_and_the_key(tmp_path, text, words):
    path = tmp_path / "bad.toml"
    path.write_text(text)
    with pytest.raises(ValueError) as err:
        load_theme_file(path)
    message = str(err.value)
    assert str(path) in message
    for word in words:
        assert word in message


async def test_default_theme_and_variables_apply():
    app, _ = make_app(one_team())
    async with app.run_test(size=(100, 30)) as pilot:
        await pilot.pause()
        assert app.theme == DEFAULT_THEME
        variables = app.get_css_variables()
        assert variables["fb-estop"].lower() == "#ff3030"
        assert variables["background"].lower() == "#101418"


async def test_theme_option_picks_a_theme():
    app, _ = make_app(one_team(), theme_name="projector-light")
    async with app.run_test(size=(100, 30)) as pilot:
        await pilot.pause()
        assert app.theme == "projector-light"
        assert app.current_theme.dark is False
        assert app.screen.styles.background.brightness > 0.9


async def test_unknown_theme_name_is_one_notification_and_the_default(user_themes):
    app, _ = make_app(one_team(), theme_name="no-such-theme")
    async with app.run_test(size=(100, 30)) as pilot:
        await pilot.pause()
        assert app.theme == DEFAULT_THEME
        messages = [n.message for n in app._notifications]
        assert len(messages) == 1 and "no-such-theme" in messages[0] and "projector-light" in messages[0]


async def test_bad_user_theme_is_one_notification_and_good_user_theme_loads(user_themes):
    (user_themes / "broken.toml").write_text('name = "broken"\nprimary = "#zzz"\naccnt = "#fff"\n')
    (user_themes / "mine.toml").write_text('name = "mine"\nprimary = "#884400"\ndark = false\n'
                                          '[fieldbox]\nestop = "#aa0000"\n')
    app, _ = make_app(one_team(), theme_name="mine")
    async with app.run_test(size=(100, 30)) as pilot:
        await pilot.pause()
        assert app.theme == "mine"
        assert app.get_css_variables()["fb-estop"] == "#aa0000"
        assert app.get_css_variables()["fb-enabled"] == FIELDBOX_VARIABLES["enabled"]  # the default
        messages = [n.message for n in app._notifications]
        assert len(messages) == 1
        assert "broken.toml" in messages[0] and "'primary'" in messages[0] and "accnt" in messages[0]
        assert "broken" not in app.available_themes


async def test_command_palette_switches_theme_and_panel():
    app, _ = make_app(one_team())
    async with app.run_test(size=(100, 30)) as pilot:
        titles = [c.title for c in app.get_system_commands(app.screen)]
        assert {"Theme: alliance", "Theme: projector-light", "Panel: Inspector"} <= set(titles)
        # The palette finds our commands; choosing one with the mouse (the app's priority
        # Enter and Space keys, disable and e-stop, never reach the palette).
        await pilot.press("ctrl+p", *"allia")
        await pilot.pause(0.2)
        palette = app.screen
        results = palette.query_one("CommandList")
        assert any("Theme: alliance" in str(results.get_option_at_index(i).prompt)
                   for i in range(results.option_count))
        await pilot.click(results, offset=(4, 1))
        await pilot.pause(0.2)
        assert app.theme == "alliance"
        command = next(c for c in app.get_system_commands(app.screen) if c.title == "Panel: Inspector")
        command.callback()
        await pilot.pause()
        assert app.query_one("TabbedContent").active == "inspector"


async def test_a_fifo_a_deep_file_and_a_symlink_to_dev_zero_leave_the_app_starting(user_themes):
    # issue 16: a 50 000-deep TOML crashed the app (RecursionError), a FIFO hung it on a blank
    # screen, a symlink to /dev/zero ate memory: each is now one notification naming the file
    (user_themes / "deep.toml").write_text("a = " + "[" * 50_000 + "]" * 50_000 + "\n")
    os.mkfifo(user_themes / "fifo.toml")
    (user_themes / "zero.toml").symlink_to("/dev/zero")
    (user_themes / "huge.toml").write_text("# " + "x" * (MAX_THEME_BYTES + 10) + "\n")
    (user_themes / "mine.toml").write_text('name = "mine"\nprimary = "#884400"\n')
    app, _ = make_app(one_team(), theme_name="mine")
    async with app.run_test(size=(100, 30)) as pilot:
        await pilot.pause()
        assert app.theme == "mine"
        messages = [str(n.message) for n in app._notifications]
        assert len(messages) == 1  # one toast names every file (a small screen shows two at most)
        deep, fifo, huge, zero = sorted(messages[0].splitlines())
        assert "deep.toml: not valid TOML: nested too deep" in deep
        assert "fifo.toml: not a regular file" in fifo and "zero.toml: not a regular file" in zero
        assert "huge.toml" in huge and "more than a theme's" in huge
