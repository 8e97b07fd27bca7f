"""Robot code apart from the wire (roles/runtime/program_host.py): a program file in a process of its
own, reached without ever waiting for it; what it writes checked before the wire uses it.

These run real child processes on the real clock. They assert what a person would notice
(a reply to every packet, an e-stop in the reply to its own packet, a stuck program said,
a restart that kills it), never how long anything took: each wait is "until it happens",
with a bound generous enough for a loaded 2-core machine.
"""

from __future__ import annotations

import os
import signal
import time

import pytest

from protocol import rio_to_ds
from protocol.ds_to_rio import ControlPacket, Joystick
from protocol.enums import Mode
from roles.cores.core import Datagram
from roles.cores.rio import CODE_NONE, CODE_RUNNING, CODE_STARTING, CODE_STUCK, Rio, RioConfig
from roles.cores.robot_program import ControlState, ProgramError
from roles.runtime.program_host import (CodeHost, Ended, LoadFailed, Loaded, Message, ProcessHost, Result,
                                        check_program, sanitize_outputs)

DS = ("127.0.0.5", 50123)
PATIENCE = 30.0  # seconds a wait may take on a busy machine before the test gives up


def program(tmp_path, source: str, name: str = "robot.py") -> str:
    path = tmp_path / name
    path.write_text(source)
    return str(path)


# -- what crosses the channel ------------------------------------------------------------------
def test_outputs_are_checked_at_the_channel():
    good, problems = sanitize_outputs([1, 0, 0, 0, 0, 0xFFFFFFFF], [0.5] * 6, [0, 1, 0, 0, 0, 0], 0x81,
                                      ["hi"] * 6)
    assert problems == () and good.outputs[5] == 0xFFFFFFFF and good.left_rumble == (0.5,) * 6
    assert good.right_rumble[1] == 1.0 and good.digital_out == 0x81 and good.lcd == ("hi",) * 6
    nan = float("nan")
    out, problems = sanitize_outputs([-5, "x", None, 1 << 40, True, 3], [nan, -1.0, 2, None, float("inf"), 0.25],
                                     None, 300, ["é" * 30] * 6)
    assert out.outputs == (0, 0, 0, 0xFFFFFFFF, 0, 3)  # -5 and 2**40 clamped; "x" and True refused
    assert out.left_rumble == (0.0, 0.0, 1.0, 0.0, 0.0, 0.25)  # NaN and inf refused, -1 and 2 clamped
    assert out.right_rumble == (0.0,) * 6 and out.digital_out == 0xFF and out.lcd == ("?" * 21,) * 6
    text = "\n".join(problems)
    assert "robot.outputs[0] = -5 is out of range" in text and "robot.outputs[1] = 'x' is not a whole number" in text
    assert "robot.left_rumble[0] = nan is not a number" in text and "robot.right_rumble = None" in text
    # A None in a slot is said as any other refusal (it used to go out as 0 unsaid).
    assert "robot.outputs[2] = None is not a whole number 0..0xffffffff: sent as 0" in problems
    assert "robot.left_rumble[3] = None is not a number 0.0..1.0: sent as 0.0" in problems
    assert len(problems) == 12  # one per bad slot (5 + 5), the list that is not a list once, 300 once
    _, problems = sanitize_outputs(None, [0.0] * 6, [0.0] * 6, 0, "not six lines")
    assert any("robot.outputs = None" in p for p in problems) and any("robot.lcd" in p for p in problems)


def test_a_file_is_checked_without_running_it(tmp_path):
    check_program(program(tmp_path, "while True:\n    pass\ndef robot_periodic(state, robot):\n    pass\n"))
    with pytest.raises(ProgramError, match=r"robot.py, line \d+: SyntaxError"):
        check_program(program(tmp_path, "def robot_periodic(state, robot):\n  return (\n"))
    with pytest.raises(ProgramError, match="defines no robot_periodic"):
        check_program(program(tmp_path, "x = 1\n"))
    with pytest.raises(ProgramError, match="cannot read robot program"):
        check_program(tmp_path / "nope.py")


# -- the process host alone --------------------------------------------------------------------
def collect_until(host: ProcessHost, predicate, events: list) -> list:
    end = time.monotonic() + PATIENCE
    while time.monotonic() < end:
        events.extend(host.collect(time.monotonic()))
        if predicate(events):
            return events
        time.sleep(0.005)
    raise AssertionError(f"not seen within {PATIENCE} s: {events!r}")


def test_a_process_host_runs_a_call_and_streams_what_it_prints(tmp_path):
    host = ProcessHost(program(tmp_path, "import sys\nprint('loading')\n"
                                         "def robot_periodic(state, robot):\n"
                                         "    robot.print('t', state.time)\n"
                                         "    sys.stdout.write('raw ')\n    sys.stdout.write('line\\n')\n"
                                         "    robot.set_rumble(1, left=0.5)\n"
                                         "    robot.set_digital_output(2)\n"
                                         "    robot.warning('careful')\n"), time.monotonic())
    try:
        events = collect_until(host, lambda ev: any(isinstance(e, Loaded) for e in ev), [])
        assert Message("stdout", "loading\n") in events and host.idle
        assert host.offer(ControlState(time=1.5), (0, (0, 0, 0, 0)), time.monotonic())
        assert not host.idle and host.busy_since is not None
        assert not host.offer(ControlState(time=2.0), (0, (0, 0, 0, 0)), time.monotonic())  # one at a time
        events = collect_until(host, lambda ev: any(isinstance(e, Result) for e in ev), [])
        texts = [(e.kind, e.text) for e in events if isinstance(e, Message)]
        assert texts[:3] == [("stdout", "t 1.5\n"), ("stdout", "raw line\n"), ("warning", "careful")]
        [result] = [e for e in events if isinstance(e, Result)]
        assert result.error is None and result.problems == ()
        assert result.outputs.left_rumble[1] == 0.5 and result.outputs.digital_out == 0b10
        assert host.idle and host.busy_since is None
    finally:
        host.stop()


@pytest.mark.parametrize("raised", ["KeyboardInterrupt", "SystemExit(3)", "Custom('mine')", "GeneratorExit"])
def test_every_exception_a_program_raises_is_a_result(tmp_path, raised):
    host = ProcessHost(program(tmp_path, "class Custom(BaseException):\n    pass\n"
                                         f"def robot_periodic(state, robot):\n    raise {raised}\n"),
                       time.monotonic())
    try:
        collect_until(host, lambda ev: any(isinstance(e, Loaded) for e in ev), [])
        for _ in range(2):  # and the process goes on taking calls
            host.offer(ControlState(), (0, (0, 0, 0, 0)), time.monotonic())
            events = collect_until(host, lambda ev: any(isinstance(e, Result) for e in ev), [])
            [result] = [e for e in events if isinstance(e, Result)]
            assert result.error is not None and raised.split("(")[0] in result.error[0]
            assert result.error[1] == "robot.py:4"
    finally:
        host.stop()


def test_os_exit_a_crash_and_a_forged_frame_end_the_host_with_a_reason(tmp_path):
    cases = {
        "import os\ndef robot_periodic(state, robot):\n    os._exit(7)\n": "exited with code 7",
        "import os, signal\ndef robot_periodic(state, robot):\n    os.kill(os.getpid(), signal.SIGSEGV)\n":
            "killed by SIGSEGV",
        # a program that writes into its own channel: the wire reads a frame that is not JSON
        "import sys\ndef robot_periodic(state, robot):\n"
        "    sys.stdout.channel.sock.sendall(b'\\x00\\x00\\x00\\x05hello')\n": "malformed message",
        "import sys\ndef robot_periodic(state, robot):\n"
        "    sys.stdout.channel.sock.sendall(b'\\xff\\xff\\xff\\xff')\n": "too large",
    }
    for source, reason in cases.items():
        host = ProcessHost(program(tmp_path, source), time.monotonic())
        try:
            collect_until(host, lambda ev: any(isinstance(e, Loaded) for e in ev), [])
            host.offer(ControlState(), (0, (0, 0, 0, 0)), time.monotonic())
            events = collect_until(host, lambda ev: any(isinstance(e, Ended) for e in ev), [])
            [ended] = [e for e in events if isinstance(e, Ended)]
            assert reason in ended.text, (source, ended.text)
            assert not host.idle and host.collect(time.monotonic()) == []
        finally:
            host.stop()


def test_a_file_whose_top_level_fails_says_why(tmp_path):
    host = ProcessHost(program(tmp_path, "raise ImportError('no module named wpilib')\n"
                                         "def robot_periodic(state, robot):\n    pass\n"), time.monotonic())
    try:
        events = collect_until(host, lambda ev: any(isinstance(e, LoadFailed) for e in ev), [])
        [failed] = [e for e in events if isinstance(e, LoadFailed)]
        assert "line 1: error while loading: ImportError: no module named wpilib" in failed.text
    finally:
        host.stop()


def test_memory_without_end_is_a_memory_error_in_the_program_not_the_machine(tmp_path):
    host = ProcessHost(program(tmp_path, "hoard = []\n"
                                         "def robot_periodic(state, robot):\n"
                                         "    while True:\n        hoard.append(bytearray(10 << 20))\n"),
                       time.monotonic(), memory_limit=400 << 20)
    try:
        collect_until(host, lambda ev: any(isinstance(e, Loaded) for e in ev), [])
        host.offer(ControlState(), (0, (0, 0, 0, 0)), time.monotonic())
        events = collect_until(host, lambda ev: any(isinstance(e, (Result, Ended)) for e in ev), [])
        [result] = [e for e in events if isinstance(e, Result)]
        assert "MemoryError" in result.error[0]
    finally:
        host.stop()


# -- the fake roboRIO with its program apart ----------------------------------------------------
class Live:
    """A fake roboRIO on the real clock, its program in a process of its own, and a DS that
    sends a control packet every 20 ms from this thread."""

    def __init__(self, path: str, **kwargs) -> None:
        self.code = CodeHost()
        self.rio = Rio(RioConfig(program=path, isolate=True, restart_time=0.1, **kwargs), self.code,
                       now=time.monotonic())
        self.code.deliver = self.rio.program_events  # as the shell hands it over (roles/runtime/shell.py)
        self.seq = 0
        self.replies: list[rio_to_ds.StatusPacket] = []
        self.next_send = time.monotonic()

    def send(self, **kw) -> rio_to_ds.StatusPacket:
        """One control packet now; the reply the core returned for it, at once."""
        self.seq = (self.seq + 1) & 0xFFFF
        data = ControlPacket(sequence=self.seq, tags=(Joystick((0, 0), 0, 2, ()),), **kw).encode()
        self.code.pump(time.monotonic())
        actions = self.rio.datagram("ds", data, DS, time.monotonic())
        [reply] = [a for a in actions if isinstance(a, Datagram)]
        status = rio_to_ds.decode_status(reply.data)
        assert status.sequence == self.seq
        self.replies.append(status)
        return status

    def run_until(self, predicate, **kw) -> None:
        """Packets every 20 ms, the core polled at its deadlines, until ``predicate()``."""
        end = time.monotonic() + PATIENCE
        while time.monotonic() < end:
            now = time.monotonic()
            if now >= self.next_send:
                self.send(**kw)
                self.next_send = max(self.next_send + 0.020, now)
            self.code.pump(time.monotonic())
            self.rio.poll(time.monotonic())
            if predicate():
                return
            time.sleep(max(0.0, min(self.next_send, self.rio.next_deadline() or 0.0) - time.monotonic()))
        raise AssertionError(f"not seen within {PATIENCE} s; code {self.rio.program.code_state}, "
                             f"console {[c.text for c in self.rio.tcp.console][-5:]}")

    def console(self) -> list[str]:
        return [c.text for c in self.rio.tcp.console]

    def close(self) -> None:
        self.rio.shutdown()


@pytest.fixture
def live_factory():
    made = []

    def make(path: str, **kwargs) -> Live:
        live = Live(path, **kwargs)
        made.append(live)
        return live

    yield make
    for live in made:
        live.close()


def test_a_slow_program_never_delays_a_reply_and_the_estop_is_in_the_reply_to_its_packet(tmp_path, live_factory):
    # issue 16: a 30 ms-a-call program made the fake roboRIO obey an e-stop 12 s late
    b = live_factory(program(tmp_path, "import time\n"
                                       "def robot_periodic(state, robot):\n    time.sleep(0.030)\n"))
    b.run_until(lambda: b.rio.program.code_state == CODE_RUNNING)
    b.run_until(lambda: b.rio.faults.program_overruns >= 10 and b.rio.control.enabled, enabled=True)
    assert any(t.startswith("Loop time of 0.02s overrun") for t in b.console())
    status = b.send(enabled=True, estop=True)  # the DS's first e-stop packet
    assert status.estop and not status.enabled and b.rio.control.estopped
    first = len(b.replies)
    b.run_until(lambda: len(b.replies) > first + 20, enabled=True)  # the DS clears its bit: still latched
    assert not any(r.enabled for r in b.replies[first - 1:]) and all(r.estop for r in b.replies[first - 1:])
    assert b.rio.faults.stale_packets == 0  # every packet was the newest: obeyed, and answered at once


def test_an_endless_loop_is_reported_stuck_while_the_robot_answers_and_restart_kills_it(tmp_path, live_factory):
    b = live_factory(program(tmp_path, "def robot_periodic(state, robot):\n"
                                       "    if state.enabled:\n        while True:\n            pass\n"))
    b.run_until(lambda: b.rio.program.code_state == CODE_RUNNING)
    b.run_until(lambda: b.rio.program.code_state == CODE_STUCK, enabled=True)
    stuck_at = len(b.replies)
    b.run_until(lambda: len(b.replies) > stuck_at + 10, enabled=True)
    # a real roboRIO whose user code hangs: the network side still answers, code still there
    assert all(r.robot_code and r.enabled for r in b.replies[stuck_at:])
    assert any("robot program stuck: robot_periodic has not returned" in t for t in b.console())
    assert b.rio.snapshot()["code_state"] == "stuck"
    pid = b.code.host.proc.pid
    b.rio.restart_code(time.monotonic())
    assert b.rio.program.code_state == CODE_STARTING and not b.send().enabled
    b.run_until(lambda: b.rio.program.code_state == CODE_RUNNING)  # a fresh process, disabled
    end = time.monotonic() + PATIENCE
    while time.monotonic() < end and _alive(pid):
        time.sleep(0.01)
    assert not _alive(pid), "the stuck program's process was not killed"


def _alive(pid: int) -> bool:
    try:
        with open(f"/proc/{pid}/stat") as f:
            return f.read().split(")")[-1].split()[0] != "Z"
    except FileNotFoundError:
        return False


@pytest.mark.parametrize("body", ["raise KeyboardInterrupt", "raise SystemExit", "raise Mine()"])
def test_base_exceptions_are_counted_and_stop_the_code_and_nothing_escapes(tmp_path, live_factory, body):
    b = live_factory(program(tmp_path, "class Mine(BaseException):\n    pass\n"
                                       f"def robot_periodic(state, robot):\n    {body}\n"), max_failures=3)
    b.run_until(lambda: b.rio.program.code_state == CODE_NONE)
    assert b.rio.faults.program_errors == 3
    assert any(t.startswith("Robot code stopped after 3 consecutive errors") for t in b.console())
    assert not b.send().robot_code  # the robot still answers: no code


def test_bad_outputs_are_refused_reported_once_and_the_replies_stay_valid(tmp_path, live_factory):
    b = live_factory(program(tmp_path, "def robot_periodic(state, robot):\n"
                                       "    robot.left_rumble[0] = float('nan')\n"
                                       "    robot.right_rumble[0] = -5\n"
                                       "    robot.outputs = None\n"))
    b.run_until(lambda: b.rio.program.code_state == CODE_RUNNING)
    b.run_until(lambda: b.rio.faults.output_problems >= 3 and b.replies[-1].enabled, enabled=True)
    calls = b.rio.beats
    b.run_until(lambda: b.rio.beats > calls + 50 and b.replies[-1].enabled, enabled=True)  # a second more
    assert b.rio.program.code_state == CODE_RUNNING and b.rio.faults.program_errors == 0
    assert b.replies[-1].joystick_outputs == ()  # nothing valid set: no output tag
    warnings = [t for t in b.console() if t.startswith("robot program output not sent as written")]
    assert len(warnings) == 3 and b.rio.faults.output_problems == 3  # once each, not 50 a second


def test_none_written_to_an_output_or_a_rumble_is_said_once_each_and_sent_as_off(tmp_path, live_factory):
    b = live_factory(program(tmp_path, "def robot_periodic(state, robot):\n"
                                       "    robot.outputs[1] = None\n"
                                       "    robot.left_rumble[2] = None\n"
                                       "    robot.outputs[0] = 5\n"))
    b.run_until(lambda: b.rio.program.code_state == CODE_RUNNING)
    b.run_until(lambda: b.rio.faults.output_problems >= 2 and b.replies[-1].enabled, enabled=True)
    calls = b.rio.beats
    b.run_until(lambda: b.rio.beats > calls + 50 and b.replies[-1].enabled, enabled=True)  # a second more
    warnings = [t for t in b.console() if t.startswith("robot program output not sent as written")]
    assert sorted(warnings) == [
        "robot program output not sent as written: robot.left_rumble[2] = None is not a number 0.0..1.0: sent as 0.0",
        "robot program output not sent as written: robot.outputs[1] = None is not a whole number 0..0xffffffff: "
        "sent as 0"]
    assert b.rio.faults.output_problems == 2 and b.rio.program.code_state == CODE_RUNNING
    assert b.rio.program.program_out.outputs[:2] == (5, 0) and b.rio.program.program_out.left_rumble[2] == 0.0


def test_a_program_that_exits_ends_the_code_and_says_so(tmp_path, live_factory):
    b = live_factory(program(tmp_path, "import os\ndef robot_periodic(state, robot):\n"
                                       "    if state.enabled:\n        os._exit(3)\n"))
    b.run_until(lambda: b.rio.program.code_state == CODE_RUNNING)
    b.run_until(lambda: b.rio.program.code_state == CODE_NONE, enabled=True)
    assert any("Robot code ended: the robot program's process exited with code 3" in t for t in b.console())
    status = b.send(enabled=True)
    assert not status.robot_code and not status.enabled


def test_prints_of_a_stuck_program_still_arrive_bounded(tmp_path, live_factory):
    b = live_factory(program(tmp_path, "def robot_periodic(state, robot):\n"
                                       "    while state.enabled:\n        print('spinning')\n"))
    b.run_until(lambda: b.rio.program.code_state == CODE_RUNNING)
    b.run_until(lambda: b.rio.program.code_state == CODE_STUCK and b.console().count("spinning") > 100,
                enabled=True)
    assert len(b.rio.tcp.console) <= b.rio.tcp.console.capacity


def test_the_program_reads_the_state_and_helpers_beside_it(tmp_path, live_factory):
    (tmp_path / "helper.py").write_text("def double(x):\n    return 2 * x\n")
    b = live_factory(program(tmp_path, "import helper\n"
                                       "def robot_periodic(state, robot):\n"
                                       "    robot.set_outputs(0, helper.double(3) if state.enabled else 0)\n"
                                       "    robot.set_rumble(0, left=1.0 if state.mode == 'auto' else 0.0)\n"))
    b.run_until(lambda: b.rio.program.code_state == CODE_RUNNING)
    b.run_until(lambda: b.rio.outputs[0] == 6 and b.rio.rumble[0][0] == 1.0, enabled=True, mode=Mode.AUTONOMOUS)
    b.run_until(lambda: b.replies[-1].joystick_outputs[:1] and b.replies[-1].joystick_outputs[0].outputs == 6,
                enabled=True, mode=Mode.AUTONOMOUS)
    assert b.rio.program.trace_mode == "auto"


# A program that forks a process which outlives it unless killed (60 s: bounded even if the
# host misses it; the test kills it by its pid in any case).
FORKS = """import os, time
def fork_sleeper():
    pid = os.fork()
    if pid == 0:
        time.sleep(60)
        os._exit(0)
    with open({pidfile!r}, "w") as f:
        f.write(str(pid))
"""


def _wait_gone(pid: int) -> bool:
    end = time.monotonic() + PATIENCE
    while time.monotonic() < end and _alive(pid):
        time.sleep(0.01)
    return not _alive(pid)


def _kill_if_left(pids: list[int]) -> None:
    for pid in pids:
        if _alive(pid):  # the host missed it: ours, ended here
            try:
                os.kill(pid, signal.SIGKILL)
            except (ProcessLookupError, PermissionError):
                pass


def test_restart_and_the_fields_end_kill_what_the_program_forked(tmp_path, live_factory):
    """A program that forks a process: a restart of the code kills it with the program, and
    so does the field's end (none left running with init as its parent)."""
    pidfile = tmp_path / "child.pid"
    b = live_factory(program(tmp_path, FORKS.format(pidfile=str(pidfile)) +
                             "fork_sleeper()\ndef robot_periodic(state, robot):\n    pass\n"))
    children: list[int] = []
    try:
        b.run_until(lambda: b.rio.program.code_state == CODE_RUNNING)
        children.append(int(pidfile.read_text()))
        assert _alive(children[0])
        pidfile.unlink()
        b.rio.restart_code(time.monotonic())
        assert _wait_gone(children[0]), "restart left the program's forked process running"
        b.run_until(lambda: b.rio.program.code_state == CODE_RUNNING and pidfile.exists())  # a fresh one forks again
        children.append(int(pidfile.read_text()))
        assert children[1] != children[0] and _alive(children[1])
        b.close()  # the field stops
        assert _wait_gone(children[1]), "the field's end left the program's forked process running"
    finally:
        _kill_if_left(children)


def test_a_program_that_exits_while_its_fork_holds_the_channel_ends_not_stuck(tmp_path, live_factory):
    """The program's process exits but a process it forked keeps the channel open (no end of
    file): the roboRIO says the code ended, with the exit code, never that it is stuck; the
    forked process is killed with it."""
    pidfile = tmp_path / "child.pid"
    b = live_factory(program(tmp_path, FORKS.format(pidfile=str(pidfile)) +
                             "def robot_periodic(state, robot):\n"
                             "    if state.enabled:\n        fork_sleeper()\n        os._exit(3)\n"))
    children: list[int] = []
    try:
        b.run_until(lambda: b.rio.program.code_state == CODE_RUNNING)
        b.run_until(lambda: b.rio.program.code_state in (CODE_NONE, CODE_STUCK), enabled=True)
        if pidfile.exists():
            children.append(int(pidfile.read_text()))
        assert b.rio.program.code_state == CODE_NONE, b.console()[-3:]
        assert any("Robot code ended: the robot program's process exited with code 3" in t for t in b.console())
        assert not any("stuck" in t for t in b.console())
        assert not b.send(enabled=True).robot_code
        assert children and _wait_gone(children[0])
    finally:
        _kill_if_left(children)
