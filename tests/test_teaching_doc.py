"""The labs of docs/teaching.md name real commands and real keys: a teacher who types a lab's
command gets fieldbox, not a usage error, and a key the lab names does something.

Every ``fieldbox ...`` command in the document's code blocks must parse with fieldbox's own
argument parser (and pass the checks ``main`` makes before it runs anything), and every key
named on a ``Keys:`` line must be bound somewhere in the app: a binding of the app, a panel
or a widget (Textual's own included: Tab, the arrows), or a key of the keyboard joystick.

A step written for a feature not on this branch yet sits between ``<!-- needs: NAME -->`` and
``<!-- /needs -->``; it is checked as soon as ``fieldbox NAME`` exists, and skipped until then.
"""

from __future__ import annotations

import argparse
import builtins
import contextlib
import importlib
import io
import inspect
import pkgutil
import re
import shlex
import sys
from pathlib import Path
from unittest import mock

import pytest

import fieldbox
from fieldbox.cli import build_parser, main

ROOT = Path(__file__).resolve().parents[1]
DOC = ROOT / "docs" / "teaching.md"

NEEDS = re.compile(r"<!--\s*needs:\s*([a-z0-9_-]+)\s*-->")
NEEDS_END = re.compile(r"<!--\s*/needs\s*-->")
FENCE = re.compile(r"^\s*```")
KEYS_LINE = re.compile(r"^\s*Keys:(.*)$")
BACKTICKED = re.compile(r"`([^`]+)`")

#: How the document writes a key -> Textual's name for it.
KEY_NAMES = {
    "space": "space", "enter": "enter", "esc": "escape", "tab": "tab", "shift+tab": "shift+tab",
    "↑": "up", "↓": "down", "←": "left", "→": "right", "pgup": "pageup", "pgdn": "pagedown",
    "home": "home", "end": "end", "[": "left_square_bracket", "]": "right_square_bracket",
    "+": "plus", "-": "minus", ".": "full_stop", ",": "comma", "/": "slash", "=": "equals_sign", "<": "less_than_sign", ">": "greater_than_sign",
}


def _textual_key(written: str) -> str:
    lower = written.lower()
    if lower in KEY_NAMES:
        return KEY_NAMES[lower]
    if re.fullmatch(r"f\d{1,2}", lower) or lower.startswith(("ctrl+", "shift+")):
        return lower
    return written  # a letter or digit: Textual's name is the character (`R` is shift+r)


def subcommands() -> set[str]:
    parser = build_parser()
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            return set(action.choices)
    return set()


def doc_items(text: str, available: set[str]) -> tuple[list[tuple[int, str]], list[tuple[int, str]]]:
    """(line number, command) for every ``fieldbox`` command in a code block, and (line number,
    key as written) for every key on a ``Keys:`` line, but those in a section that needs a
    feature not in ``available``."""
    commands: list[tuple[int, str]] = []
    keys: list[tuple[int, str]] = []
    skipping = False
    in_code = False
    pending = ""
    for n, line in enumerate(text.splitlines(), 1):
        need = NEEDS.search(line)
        if need:
            skipping = need.group(1) not in available
            continue
        if NEEDS_END.search(line):
            skipping = False
            continue
        if FENCE.match(line):
            in_code = not in_code
            continue
        if skipping:
            continue
        if in_code:
            pending += line.rstrip("\\").strip() + " "
            if line.rstrip().endswith("\\"):
                continue
            for command in _fieldbox_commands(pending):
                commands.append((n, command))
            pending = ""
            continue
        match = KEYS_LINE.match(line)
        if match:
            for group in BACKTICKED.findall(match.group(1)):
                keys.extend((n, key) for key in group.split())
    return commands, keys


def _fieldbox_commands(line: str) -> list[str]:
    """The ``fieldbox ...`` parts of a shell line (split at pipes, ``;`` and ``&&``)."""
    found = []
    for part in re.split(r"\|\||&&|[|;()]", line):
        part = part.strip()
        if part.startswith("fieldbox ") or part == "fieldbox":
            found.append(part)
    return found


def command_problem(command: str) -> str | None:
    """Why ``fieldbox.cli.main`` refuses ``command`` (its parser, then the checks it makes
    before it runs anything), or None. Nothing runs: what ``main`` imports to run a command
    (fieldbox imports it there, so that ``--help`` stays quick) is replaced by a stub."""
    words = shlex.split(command)[1:]
    words = [w for i, w in enumerate(words)  # shell redirections are not fieldbox's
             if not re.fullmatch(r"\d?>>?(&\d)?", w) and not (i and re.fullmatch(r"\d?>>?", words[i - 1]))]
    err = io.StringIO()
    with mock.patch("builtins.__import__", _import_stubbing_main), contextlib.redirect_stderr(err), \
            contextlib.redirect_stdout(io.StringIO()):
        try:
            main(words)
        except SystemExit as e:
            if e.code:
                lines = err.getvalue().strip().splitlines()
                return lines[-1] if lines else f"exit status {e.code}"
    return None


_real_import = builtins.__import__


class _Runner:
    """Stands for a module ``main`` imports: every name in it is a runner that does nothing."""

    def __getattr__(self, name: str):
        return lambda *args, **kwargs: 0


def _import_stubbing_main(name, globals=None, locals=None, fromlist=(), level=0):
    if level and globals and globals.get("__name__") == "fieldbox.cli" and sys._getframe(1).f_code.co_name == "main":
        return _Runner()
    return _real_import(name, globals, locals, fromlist, level)


def bound_keys() -> set[str]:
    """Every key bound anywhere in the app: each class of fieldbox's modules with ``BINDINGS``,
    with the classes it inherits from (Textual's Screen, OptionList...), and the keyboard
    joystick's keys."""
    from textual.binding import Binding
    from textual.screen import Screen

    from fieldbox.joystick_input.keyboard import KEYBOARD_KEYS

    classes: set[type] = {Screen}
    for info in pkgutil.walk_packages(fieldbox.__path__, "fieldbox."):
        if info.name.endswith("__main__"):
            continue
        module = importlib.import_module(info.name)
        for _, cls in inspect.getmembers(module, inspect.isclass):
            if cls.__module__ == module.__name__ and hasattr(cls, "BINDINGS"):
                classes.add(cls)
    keys = set(KEYBOARD_KEYS)
    for cls in classes:
        for klass in cls.__mro__:
            for binding in vars(klass).get("BINDINGS", ()):
                key = binding.key if isinstance(binding, Binding) else binding[0]
                keys.update(k.strip() for k in key.split(","))
    return keys


def test_every_command_of_the_labs_is_one_fieldbox_takes():
    available = subcommands()
    commands, _ = doc_items(DOC.read_text(encoding="utf-8"), available)
    assert len(commands) >= 15, commands  # the scan finds them
    problems = [f"docs/teaching.md:{n}: {command}: {problem}"
                for n, command in commands if (problem := command_problem(command))]
    assert not problems, "\n".join(problems)


def test_every_key_the_labs_name_is_bound():
    _, keys = doc_items(DOC.read_text(encoding="utf-8"), subcommands())
    assert len(keys) >= 30, keys
    bound = bound_keys()
    unbound = [f"docs/teaching.md:{n}: {key} (Textual: {_textual_key(key)})" for n, key in keys
               if _textual_key(key) not in bound]
    assert not unbound, "\n".join(unbound)


def test_checking_a_command_runs_nothing(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert command_problem("fieldbox dissector -o frc.lua") is None
    assert command_problem("fieldbox decode --pcap missing.pcapng") is None  # not read: no error
    assert list(tmp_path.iterdir()) == []


def test_the_checks_refuse_a_made_up_command_and_key():
    """The checks above can fail: a made-up option, a bad value, a refused combination, a
    made-up subcommand and an unbound key are caught; a section needing a missing feature is
    skipped, and checked once the feature is there."""
    assert command_problem("fieldbox decode --pcap x.pcapng --colour") is not None
    assert command_problem("fieldbox --net moon") is not None
    assert command_problem("fieldbox --json") is not None  # refused by main: --json is for --headless
    assert command_problem("fieldbox teleport x") is not None
    assert command_problem("fieldbox decode --as ds-to-rio") is not None  # no HEX
    assert command_problem("fieldbox decode --pcap x.pcapng --json > out.json") is None
    assert "f13" not in bound_keys() and "f6" in bound_keys()
    text = "\n".join(["<!-- needs: teleport -->", "```sh", "fieldbox teleport x", "```",
                      "Keys: `F13`", "<!-- /needs -->", "Keys: `F6` `e e`"])
    commands, keys = doc_items(text, subcommands())
    assert commands == [] and [k for _, k in keys] == ["F6", "e", "e"]
    commands, keys = doc_items(text, subcommands() | {"teleport"})
    assert commands == [(3, "fieldbox teleport x")] and "F13" in [k for _, k in keys]


@pytest.mark.parametrize("written, textual", [("F6", "f6"), ("shift+Tab", "shift+tab"), ("↑", "up"),
                                              ("[", "left_square_bracket"), ("R", "R"), ("Esc", "escape")])
def test_keys_are_read_as_textual_names_them(written, textual):
    assert _textual_key(written) == textual
