"""The command line says what each command takes, and refuses what makes no sense with a
reason, before anything starts (issue 31, item 6)."""

import pytest

from fieldbox.cli import build_parser, main


def _refusal(argv, capsys) -> str:
    with pytest.raises(SystemExit) as exc:
        main(argv)
    assert exc.value.code == 2
    return capsys.readouterr().err.strip().splitlines()[-1]


@pytest.mark.parametrize("argv,said", [
    (["serve", "--headless"], "serve takes no --headless: serve shows the app in browser tabs"),
    (["--headless", "serve"], "serve takes no --headless"),  # given before the command, too
    (["serve", "--json"], "serve takes no --json"),
    (["--json"], "--json is for --headless"),
    (["field", "--json"], "--json is for --headless"),
    (["run", "x.fbx", "--theme", "dark"], "run takes no --theme"),
    (["run", "x.fbx", "--join", "/tmp/s"], "run takes no --join"),
    (["serve", "--paused"], "serve takes --speed and --paused only with --replay FILE"),
    (["serve", "--speed", "5"], "serve takes --speed and --paused only with --replay FILE"),
])
def test_options_that_make_no_sense_together_are_refused_with_the_reason(argv, said, capsys):
    assert said in _refusal(argv, capsys)


def _help(*argv: str) -> str:
    parser = build_parser()
    if not argv:
        return parser.format_help()
    sub = next(a for a in parser._actions if a.dest == "command")
    return sub.choices[argv[0]].format_help()  # type: ignore[index]


def test_a_subcommand_lists_only_its_own_options():
    run = _help("run").split("options:")[1]
    for option in ("--theme", "--join", "--wire", "--headless"):
        assert option not in run
    assert "instead of TAP" in run  # run's own --json
    serve = _help("serve").split("options:")[1]
    assert "--headless" not in serve and "--json" not in serve and "--classroom" in serve


def test_field_has_a_description_and_the_command_is_optional():
    assert "six fake roboRIOs and the FMS" in " ".join(_help("field").split("options:")[0].split())
    usage = _help().split("\n\n")[0]
    assert "[COMMAND] ..." in usage
