"""Themes: TOML files loaded into :class:`textual.theme.Theme` objects.

The app's own themes ship in the ``themes`` package (``themes/*.toml``); a user adds or
overrides themes in ``platformdirs.user_config_dir("fieldbox")/themes``. A theme file::

    name = "fieldbox-dark"          # what --theme and the command palette call it
    dark = true
    primary = "#1f7ae0"             # and secondary, accent, background, surface, panel,
                                    # error, warning, success, foreground (all optional
                                    # but primary)
    [fieldbox]                      # the field's own colours, as $fb-... CSS variables
    enabled = "#2ecc71"
    disabled = "#8a8f98"
    estop = "#ff3030"
    alliance-red = "#ed1c24"
    alliance-blue = "#0066b3"

A file that does not parse, names a key that does not exist or gives a colour Textual cannot
read is left out, with one message naming the file and every problem in it: the app shows it
as one notification and starts anyway. Only a regular file of at most :data:`MAX_THEME_BYTES`
is read (never a FIFO that would wait for a writer, nor /dev/zero behind a symlink), without
ever blocking on it, and a parse that recurses too deep is a bad file like any other.
"""

from __future__ import annotations

import os
import stat
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Iterable

DEFAULT_THEME = "fieldbox-dark"

#: Colour keys of a theme file, as textual.theme.Theme names them.
COLOUR_KEYS = ("primary", "secondary", "accent", "background", "surface", "panel", "boost",
               "error", "warning", "success", "foreground")
OTHER_KEYS = ("name", "dark", "description", "fieldbox")

#: The ``[fieldbox]`` table: CSS variable ``$fb-KEY``, and its value when a theme (a
#: Textual built-in, say) does not set it.
FIELDBOX_VARIABLES: dict[str, str] = {
    "enabled": "#2ecc71",
    "disabled": "#8a8f98",
    "estop": "#ff3030",
    "alliance-red": "#ed1c24",
    "alliance-blue": "#1e6fd9",
    "comms-ok": "#2ecc71",
    "comms-bad": "#ff3030",
}
VARIABLE_PREFIX = "fb-"
#: A theme file larger than this is not a theme (a few hundred bytes is usual).
MAX_THEME_BYTES = 1 << 20


def variable_defaults() -> dict[str, str]:
    """The ``$fb-...`` variables with their fallback values (App.get_theme_variable_defaults)."""
    return {VARIABLE_PREFIX + k: v for k, v in FIELDBOX_VARIABLES.items()}


@dataclass
class ThemeLoad:
    """What loading found: the good themes (by name) and one message per bad file."""

    themes: dict[str, Any] = field(default_factory=dict)
    sources: dict[str, Path] = field(default_factory=dict)
    problems: list[str] = field(default_factory=list)


def builtin_theme_dir() -> Path:
    import themes

    return Path(themes.__file__).parent


def user_theme_dir() -> Path:
    import platformdirs

    return Path(platformdirs.user_config_dir("fieldbox")) / "themes"


def _colour_problem(value: Any) -> str | None:
    from textual.color import Color, ColorParseError

    if not isinstance(value, str):
        return f"is {type(value).__name__}, not a colour string"
    try:
        Color.parse(value)
    except ColorParseError:
        return f"{value!r} is not a colour (use #rrggbb, rgb(r,g,b) or a colour name)"
    return None


def theme_from_toml(data: dict[str, Any], source: str = "<theme>"):
    """A Theme from a parsed TOML table. Raises ValueError naming the file and every problem."""
    from textual.theme import Theme

    problems: list[str] = []
    for key in data:
        if key not in COLOUR_KEYS and key not in OTHER_KEYS:
            problems.append(f"unknown key {key!r} (theme keys: {', '.join(COLOUR_KEYS + OTHER_KEYS)})")
    name = data.get("name")
    if not isinstance(name, str) or not name.strip():
        problems.append("'name' is missing (a theme needs a name = \"...\")")
    elif any(c.isspace() for c in name):
        problems.append(f"'name' {name!r} has spaces (use dashes: it is typed after --theme)")
    if "primary" not in data:
        problems.append("'primary' is missing")
    dark = data.get("dark", True)
    if not isinstance(dark, bool):
        problems.append(f"'dark' must be true or false, not {dark!r}")
    colours: dict[str, str] = {}
    for key in COLOUR_KEYS:
        if key in data:
            why = _colour_problem(data[key])
            if why:
                problems.append(f"{key!r} {why}")
            else:
                colours[key] = data[key]
    variables: dict[str, str] = {}
    table = data.get("fieldbox", {})
    if not isinstance(table, dict):
        problems.append("'fieldbox' must be a table ([fieldbox])")
        table = {}
    for key, value in table.items():
        if key not in FIELDBOX_VARIABLES:
            problems.append(f"unknown key 'fieldbox.{key}' (one of {', '.join(FIELDBOX_VARIABLES)})")
            continue
        why = _colour_problem(value)
        if why:
            problems.append(f"'fieldbox.{key}' {why}")
        else:
            variables[VARIABLE_PREFIX + key] = value
    if problems:
        raise ValueError(f"{source}: " + "; ".join(problems))
    assert isinstance(name, str)  # else a problem above
    # colours holds only Theme's colour parameters, each a str
    return Theme(name=name.strip(), dark=dark, variables=variables, **colours)  # type: ignore[arg-type]


def read_small_file(path: Path | str, limit: int = MAX_THEME_BYTES, what: str = "a theme") -> bytes:
    """The bytes of a regular file of at most ``limit`` bytes (``what`` the file is, for the
    message); ValueError saying why not. Opened without blocking (a FIFO would wait for a
    writer, deaf to Ctrl+C) and checked once open (a symlink may lead anywhere, and the file
    may change between a look and the open). Themes and ``fieldbox run``'s scripts."""
    try:
        fd = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_NOCTTY", 0))
    except OSError as exc:
        raise ValueError(f"{path}: cannot read: {exc.strerror or exc}") from None
    try:
        info = os.fstat(fd)
        if not stat.S_ISREG(info.st_mode):
            raise ValueError(f"{path}: not a regular file")
        if info.st_size > limit:
            raise ValueError(f"{path}: {info.st_size} bytes, more than {what}'s {limit} at most")
        with os.fdopen(fd, "rb", closefd=False) as f:
            data = f.read(limit + 1)
    except OSError as exc:
        raise ValueError(f"{path}: cannot read: {exc.strerror or exc}") from None
    finally:
        os.close(fd)
    if len(data) > limit:
        raise ValueError(f"{path}: more than {what}'s {limit} bytes")
    return data


def load_theme_file(path: Path):
    """One theme file; ValueError (naming the file) if it is bad."""
    data = read_small_file(path)
    try:
        table = tomllib.loads(data.decode("utf-8"))
    except UnicodeDecodeError as exc:
        raise ValueError(f"{path}: not UTF-8 text: {exc}") from None
    except tomllib.TOMLDecodeError as exc:
        raise ValueError(f"{path}: not valid TOML: {exc}") from None
    except (RecursionError, MemoryError):
        raise ValueError(f"{path}: not valid TOML: nested too deep") from None
    return theme_from_toml(table, str(path))


def load_themes(dirs: Iterable[Path] | None = None) -> ThemeLoad:
    """Every ``*.toml`` in the built-in then the user folder; later files override earlier
    ones of the same name."""
    result = ThemeLoad()
    if dirs is None:
        dirs = []
        try:
            dirs.append(builtin_theme_dir())
        except ImportError:  # a broken install: the app still starts, on Textual's theme
            result.problems.append("the built-in themes are missing (the 'themes' package)")
        dirs.append(user_theme_dir())
    for folder in dirs:
        try:
            files = sorted(Path(folder).glob("*.toml"))
        except OSError:
            continue
        for path in files:
            try:
                theme = load_theme_file(path)
            except ValueError as exc:
                result.problems.append(str(exc))
                continue
            except Exception as exc:  # noqa: BLE001 - whatever a file holds, the app starts
                result.problems.append(f"{path}: cannot be used as a theme: {type(exc).__name__}: {exc}")
                continue
            result.themes[theme.name] = theme
            result.sources[theme.name] = path
    return result


def install_themes(app, theme_name: str | None, dirs: Iterable[Path] | None = None) -> list[str]:
    """Register the themes on ``app`` and pick ``theme_name`` (or the default). Returns the
    messages to show (one per bad file, one for an unknown name); never raises for a theme."""
    loaded = load_themes(dirs)
    for theme in loaded.themes.values():
        app.register_theme(theme)
    problems = list(loaded.problems)
    wanted = theme_name or DEFAULT_THEME
    if wanted not in app.available_themes:
        if theme_name:
            names = ", ".join(sorted(loaded.themes)) or "(none loaded)"
            problems.append(f"no theme called {theme_name!r}; themes: {names}")
        wanted = DEFAULT_THEME if DEFAULT_THEME in app.available_themes else "textual-dark"
    app.theme = wanted
    return problems


def fieldbox_theme_names(app) -> list[str]:
    """The themes from files (not Textual's built-ins), for the command palette."""
    from textual.theme import BUILTIN_THEMES

    return sorted(n for n in app.available_themes if n not in BUILTIN_THEMES)
