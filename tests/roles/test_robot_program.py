"""The robot program hook: the state it reads, the API it writes, loading files, the built-in."""

from __future__ import annotations

import pytest

from roles.cores.robot_program import (BuiltinProgram, ControlState, JoystickState, ProgramError, RobotApi,
                                       describe_exception)
from roles.runtime.program_host import load_program


class Recorder:
    """An emit callback that keeps what the program sent."""

    def __init__(self) -> None:
        self.sent: list[tuple] = []

    def __call__(self, kind, text, code=0, location="", call_stack=""):
        self.sent.append((kind, text, code, location))

    @property
    def lines(self) -> list[str]:
        return [text for kind, text, *_ in self.sent if kind == "stdout"]


def test_joystick_state_reads_like_wpilib():
    joy = JoystickState(axes=(0.5, -1.0), buttons=0b101, button_count=3, povs=(90,), name="pad")
    assert joy.button(1) and not joy.button(2) and joy.button(3)
    assert not joy.button(0) and not joy.button(4)
    assert joy.axis(1) == -1.0 and joy.axis(7) == 0.0 and joy.axis(7, default=0.3) == 0.3
    assert joy.pov() == 90 and joy.pov(3) == -1
    assert joy.pressed == (1, 3)
    assert joy.readout() == "axes +0.50 -1.00 buttons 1,3 pov 90"
    assert JoystickState().is_empty and JoystickState().readout() == "empty"
    state = ControlState(joysticks=(joy,))
    assert state.joystick(0) is joy and state.joystick(5).is_empty and state.joystick(-1).is_empty


def test_robot_api_outputs_and_rumble():
    robot = RobotApi()
    robot.set_outputs(2, 0xFFFFFFFF)
    robot.set_output(2, 1, False)
    robot.set_output(0, 32)
    assert robot.outputs[2] == 0xFFFFFFFE and robot.outputs[0] == 1 << 31
    robot.set_rumble(1, left=0.25)
    robot.set_rumble(1, right=1)
    assert (robot.left_rumble[1], robot.right_rumble[1]) == (0.25, 1.0)
    for bad in (lambda: robot.set_outputs(6, 0), lambda: robot.set_outputs(0, -1),
                lambda: robot.set_outputs(0, 1 << 32), lambda: robot.set_output(0, 0),
                lambda: robot.set_output(True, 1), lambda: robot.set_rumble(0, left=1.5),
                lambda: robot.set_rumble(0, right=float("nan")), lambda: robot.set_output(0, 3, None),
                lambda: robot.set_output(0, 3, "off"), lambda: robot.set_output(0, 3, float("nan"))):
        with pytest.raises(ValueError):
            bad()
    assert robot.outputs[0] == 1 << 31  # a refused set_output left it as it was
    robot.set_output(0, 3, 1)
    robot.set_output(0, 32, 0)
    assert robot.outputs[0] == 0b100  # a number: 0 is off, anything else on
    robot.reset()
    assert robot.outputs == [0] * 6 and robot.left_rumble == [0.0] * 6


def test_robot_api_print_warning_error_go_to_the_emitter():
    rec = Recorder()
    robot = RobotApi(rec)
    robot.print("a", 1, sep="-")
    robot.warning("careful")
    robot.error("broken", code=-44)
    assert rec.sent[0] == ("stdout", "a-1\n", 0, "")
    kind, text, code, location = rec.sent[1]
    assert (kind, text, code) == ("warning", "careful", 0) and location.startswith("test_robot_program.py:")
    assert rec.sent[2][:3] == ("error", "broken", -44)


def test_load_program_and_its_print(tmp_path):
    path = tmp_path / "robot.py"
    path.write_text("calls = []\n"
                    "def robot_periodic(state, robot):\n"
                    "    calls.append(state.time)\n"
                    "    print('t =', state.time)\n")
    rec = Recorder()
    robot = RobotApi(rec)
    hook = load_program(path, console=robot.print)
    hook(ControlState(time=1.5), robot)
    assert rec.lines == ["t = 1.5\n"]
    assert hook.__globals__["calls"] == [1.5]
    # each load is a fresh module: a restart starts from scratch
    again = load_program(str(path))
    assert again.__globals__["calls"] == [] and again is not hook


@pytest.mark.parametrize("source,pattern", [
    ("def robot_periodic(state, robot):\n  return (\n", r"robot.py, line \d+: SyntaxError"),
    ("x = 1\n", r"robot.py: defines no robot_periodic\(state, robot\)"),
    ("robot_periodic = 3\n", r"robot_periodic is a int, not a function"),
    ("def robot_periodic(state):\n  pass\n", r"must take two arguments \(state, robot\)"),
    # CPython 3.14 words it "expected a nonnegative input, got -1.0"
    ("import math\n\nmath.sqrt(-1)\n",
     r"robot.py, line 3: error while loading: ValueError: (math domain error|expected a nonnegative input)"),
    ("import sys\nsys.exit(2)\n", r"line 2: error while loading: SystemExit"),
    ("x = '\0'\n", r"robot.py"),
])
def test_load_program_errors_are_clear(tmp_path, source, pattern):
    path = tmp_path / "robot.py"
    path.write_text(source)
    with pytest.raises(ProgramError, match=pattern):
        load_program(path)


def test_load_program_missing_file(tmp_path):
    with pytest.raises(ProgramError, match="cannot read robot program .*nope.py"):
        load_program(tmp_path / "nope.py")


def test_optional_arguments_are_fine(tmp_path):
    path = tmp_path / "robot.py"
    path.write_text("def robot_periodic(state, robot, extra=None, *rest):\n  pass\n")
    assert callable(load_program(path))


def test_describe_exception_names_the_line():
    def hook():
        raise KeyError("left_motor")

    try:
        hook()
    except KeyError as exc:
        details, location, stack = describe_exception(exc)
    assert details == "Unhandled exception in the robot program: KeyError: 'left_motor'"
    assert location.startswith("test_robot_program.py:") and "KeyError" in stack


def test_builtin_program_mode_changes_and_echo():
    rec = Recorder()
    robot = RobotApi(rec)
    program = BuiltinProgram()
    pad = JoystickState(axes=(0.0,), buttons=0b11, button_count=4)
    program(ControlState(time=0.0), robot)
    program(ControlState(time=0.02, enabled=True, mode="auto"), robot)
    program(ControlState(time=0.04, enabled=True, mode="auto", joysticks=(JoystickState(), pad)), robot)
    program(ControlState(time=0.06, estop=True, game_data="RLR"), robot)
    assert rec.lines == ["Robot program started (fieldbox built-in program)\n", "Robot disabled\n",
                         "Robot enabled in auto\n", "Joystick 1: axes +0.00 buttons 1,2\n",
                         "Robot e-stopped\n", "Game data: 'RLR'\n"]
    assert robot.outputs[:2] == [0, 0b11]
    assert (robot.left_rumble[1], robot.right_rumble[1]) == (1.0, 1.0)
    assert robot.left_rumble[0] == 0.0


def test_builtin_readouts_are_rate_limited_and_catch_up():
    rec = Recorder()
    robot = RobotApi(rec)
    program = BuiltinProgram(readout_interval=0.5)
    for k in range(26):  # a value per 20 ms for half a second
        program(ControlState(time=k * 0.02, joysticks=(JoystickState(axes=(k / 100,)),)), robot)
    readouts = [t for t in rec.lines if t.startswith("Joystick")]
    assert readouts == ["Joystick 0: axes +0.00\n", "Joystick 0: axes +0.25\n"]
    for k in range(26, 60):  # it stops moving
        program(ControlState(time=k * 0.02, joysticks=(JoystickState(axes=(0.3,)),)), robot)
    readouts = [t for t in rec.lines if t.startswith("Joystick")]
    assert readouts[-1] == "Joystick 0: axes +0.30\n" and len(readouts) == 3
