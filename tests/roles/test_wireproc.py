"""The wire in a process of its own (roles/runtime/wireproc.py): a real child on loopback sockets."""

from __future__ import annotations

import os
import signal
import socket
import textwrap
import time

import pytest

from roles.cores.commands import DeclareJoystick, ReplayMatch, SetGameData, SetMatchTiming, UpdateJoysticks
from roles.cores.core import CommandError
from roles.runtime.engine import SimEngine, ThreadEngine
from roles.runtime.field import FieldConfig
from roles.runtime.shell import TapRecord
from roles.runtime.wireproc import ProcessEngine

from fieldbox.language import parse


def _config(tmp_path, **kw) -> FieldConfig:
    kw.setdefault("roles", frozenset({"ds", "rio"}))
    return FieldConfig(team=254, plan="ephemeral", log_dir=str(tmp_path), **kw)


def _wait(predicate, timeout: float = 20.0) -> bool:
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if predicate():
            return True
        time.sleep(0.02)
    return predicate()


@pytest.fixture
def engine(tmp_path):
    engine = ProcessEngine(_config(tmp_path))
    engine.start()
    yield engine
    engine.stop()


def test_the_views_show_the_ds_talking_to_its_robot(engine):
    st = engine.field.stations[0]
    assert (st.team, st.ds_name, st.rio_name) == (254, "ds 254", "rio 254")
    assert set(engine.field.bound) == {"ds 254", "rio 254"}
    assert _wait(lambda: engine.field.stations[0].ds.link.robot_comms)
    first = engine.field.stations[0].ds
    before = engine.updates
    assert _wait(lambda: engine.updates > before + 3)
    assert st.ds is first  # a FieldView is frozen: the newer views come in a new one
    ds = engine.field.stations[0].ds
    assert ds is not first and ds.at > first.at  # a newer view, made later on the wire's clock
    assert engine.now() - ds.at < 5.0
    assert engine.problems == []


def test_execute_enables_and_the_views_show_it_at_once(engine):
    assert _wait(lambda: engine.field.stations[0].ds.link.robot_comms)
    engine.execute(parse("enable"))
    assert engine.field.stations[0].ds.enabled  # the reply carried the station's snapshot
    engine.execute(parse("disable"))
    assert not engine.field.stations[0].ds.enabled


def test_errors_come_back_as_command_errors(engine):
    with pytest.raises(CommandError, match="team 1 is not on this field"):
        engine.execute(parse("@1 enable"))
    with pytest.raises(CommandError, match="no FMS"):
        engine.execute(parse("match start"))
    with pytest.raises(TypeError, match="only a command goes"):
        engine.call(lambda: None)


#: A joystick plugged into slot 0 of team 254's DS, as the joystick tab sends it.
PAD = UpdateJoysticks((DeclareJoystick(0, "pad", 6, 12, 1),), team=254)


def test_a_panels_command_runs_in_the_child(engine):
    engine.execute(PAD)
    assert engine.field.stations[0].ds.sticks.slots[0] is not None
    with pytest.raises(CommandError, match="no FMS"):
        engine.execute(ReplayMatch())


def test_the_child_takes_commands_only(engine):
    """Whatever reaches the child's pipe, only a command changes the field: anything else is
    refused in words, and the child goes on."""
    for payload in (print, ("enable",), "enable"):
        refused = engine._request(payload)
        with pytest.raises(CommandError, match="takes commands only"):
            engine._wait(refused)
    engine.execute(PAD)  # the child still answers
    assert engine.field.stations[0].ds.sticks.slots[0] is not None


def test_taps_arrive_with_the_childs_receive_times(engine):
    seen = []
    engine.add_tap(lambda record: seen.append((time.monotonic(), record)))
    def wanted(r: TapRecord) -> bool:  # a control datagram (its TCP may come first)
        return r.role == "rio 254" and r.direction == "in" and r.kind == "ds-to-rio"
    assert _wait(lambda: any(wanted(r) for _, r in seen))
    got, record = next((t, r) for t, r in seen if wanted(r))
    assert isinstance(record, TapRecord)
    link, kind, data, remote, local, now = (record.link, record.kind, record.data, record.remote,
                                            record.local, record.time)
    assert kind == "ds-to-rio" and isinstance(data, bytes) and remote[0] == "127.0.0.1"
    bound = engine.field.bound  # both ends, as the child's sockets name them
    assert local == tuple(bound["rio 254"][link]) and remote == tuple(bound["ds 254"]["robot"])
    assert 0 <= got - now < 1.0  # the child's time.monotonic: the same clock here
    engine.remove_tap(engine._taps[0])
    time.sleep(0.15)
    n = len(seen)
    time.sleep(0.2)
    assert len(seen) == n


def test_a_port_in_use_is_a_clear_oserror(tmp_path):
    import roles.cores.addresses as A

    address = (A.ds_address(254, "loopback"), A.port(A.DS_UDP, "loopback"))
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as taken:
        taken.bind(address)
        engine = ProcessEngine(FieldConfig(roles=frozenset({"ds"}), team=254, plan="loopback",
                                           log_dir=str(tmp_path)))
        with pytest.raises(OSError, match=r"ds 254: cannot bind UDP 127\.2\.54\.5:1150.*in use"):
            engine.start()
        assert engine.proc.poll() is not None
        engine.stop()


def test_a_killed_child_is_a_problem_not_a_hang(engine):
    assert _wait(lambda: engine.field.stations[0].ds.link.robot_comms)
    engine.execute(parse("enable"))
    assert engine.field.stations[0].ds.enabled
    os.kill(engine.proc.pid, signal.SIGKILL)
    assert _wait(lambda: engine.problems)
    assert "wire process ended" in engine.problems[0]
    # its views of the field no longer show comms nor an enable that nothing sends
    ds = engine.field.stations[0].ds
    assert not ds.link.robot_comms and not ds.enabled and not ds.link.robot_code
    assert "wire process ended (killed by SIGKILL): no robot comms, disabled" in ds.events.items[-1][1]
    assert engine.end_reason == "the wire process ended (killed by SIGKILL)"
    rio = engine.field.stations[0].rio  # nor a roboRIO that runs and is enabled
    assert not rio.enabled and rio.code_state == "state unknown"
    refused = engine.submit_command(parse("enable"))  # refused at once: no wait for a reply
    assert refused.done() and isinstance(refused.exception(), CommandError)
    assert "wire process has ended" in str(refused.exception())
    engine.stop()
    assert engine.proc.poll() is not None


def test_stop_leaves_no_child(tmp_path):
    engine = ProcessEngine(_config(tmp_path))
    engine.start()
    pid = engine.proc.pid
    engine.stop()
    assert engine.proc.poll() is not None
    with pytest.raises(ProcessLookupError):
        os.kill(pid, 0)  # reaped, not a zombie
    assert engine.problems == []


def test_a_full_field_shows_the_fms(tmp_path):
    engine = ProcessEngine(FieldConfig(teams=[254, 1114, 2056, 118, 148, 1678], plan="ephemeral",
                                       log_dir=str(tmp_path)))
    engine.start()
    try:
        assert engine.field.fms is not None and len(engine.field.stations) == 6
        assert _wait(lambda: all(st.ds.link.robot_comms for st in engine.field.stations))
        engine.execute(SetMatchTiming(auto=5.0))
        assert engine.field.fms.match.timing.auto == 5.0
    finally:
        engine.stop()


@pytest.mark.parametrize("kind", ["sim", "thread"])
def test_commands_work_on_the_other_engines(tmp_path, kind):
    config = _config(tmp_path, log_files=False)
    if kind == "sim":
        engine = SimEngine(config)
    else:
        engine = ThreadEngine(config)
        engine.start()
    try:
        engine.execute(PAD)
        assert engine.field.stations[0].ds.sticks.slots[0] is not None
    finally:
        engine.stop()


def test_the_console_of_the_views_is_read_once(engine):
    """Every view brings a new view object: the console follower counts, never repeats."""
    from fieldbox.console_feed import ConsoleFollower

    ds = lambda: engine.field.stations[0].ds  # noqa: E731 - the latest view
    follower = ConsoleFollower(lambda: ds().tcp, 254)
    got = []
    end = time.monotonic() + 1.5
    while time.monotonic() < end:
        got += follower.new_entries()
        time.sleep(0.05)
    got += follower.new_entries()
    assert ds().tcp.console_total >= 1
    assert len(got) == len(set(got)) == ds().tcp.console_total
    assert follower.missed == 0


def test_a_legacy_ds_netconsole_stream_keeps_its_numbering_across_views(tmp_path):
    """The legacy panel follows its NetConsole by number: each view from the wire process
    holds the stream's newest lines under the numbers the earlier views gave them."""
    engine = ProcessEngine(_config(tmp_path, legacy=True))
    engine.start()
    try:
        ds = lambda: engine.field.stations[0].ds  # noqa: E731 - the latest view
        assert ds().legacy is not None
        assert _wait(lambda: ds().link.robot_comms and ds().legacy.netconsole.end > 0)
        first = ds().legacy.netconsole
        before = engine.updates
        assert _wait(lambda: engine.updates > before + 5)
        later = ds().legacy.netconsole
        common = range(max(first.first_seq, later.first_seq), first.end)
        assert later.end >= first.end and len(common) > 0
        assert [first[i - first.first_seq] for i in common] == [later[i - later.first_seq] for i in common]
        assert ds().legacy.last_status is not None  # and it moves: the robot's status arrived
    finally:
        engine.stop()


def test_the_views_recover_when_the_two_sides_disagree(engine, caplog):
    """The app's copies of the streams lost (a bug, a message that failed): the engine asks for
    everything again and the views go on moving."""
    ds = lambda: engine.field.stations[0].ds  # noqa: E731 - the latest view
    assert _wait(lambda: ds().link.echoes.trip.samples)
    engine._views._streams.clear()
    seen = ds().link.echoes.trip.last_ms
    assert _wait(lambda: "asking for all of it" in caplog.text)
    assert _wait(lambda: ds().link.echoes.trip.last_ms != seen)
    assert _wait(lambda: ds().link.echoes.trip.samples[-1] == ds().link.echoes.trip.last_ms)
    assert not engine.ended and engine.problems == []


def test_a_stuck_child_times_out_and_stop_kills_it(engine, monkeypatch):
    import roles.runtime.wireproc as W

    monkeypatch.setattr(W, "CALL_TIMEOUT", 0.5)
    monkeypatch.setattr(W, "STOP_TIMEOUT", 0.5)
    os.kill(engine.proc.pid, signal.SIGSTOP)
    # kill() returns before every thread of the child has stopped: wait until the kernel says
    # it has (state T), or a command could still be answered in between
    assert _wait(lambda: open(f"/proc/{engine.proc.pid}/stat").read().rsplit(")", 1)[1].split()[0] == "T")
    try:
        with pytest.raises(CommandError, match="did not answer"):
            engine.execute(parse("enable"))
        engine.stop()  # "stop" unanswered, SIGTERM waits for a stopped process: SIGKILL
        assert engine.proc.poll() is not None
    finally:
        if engine.proc.poll() is None:
            os.kill(engine.proc.pid, signal.SIGCONT)


#: Loaded by the child at its start (on its PYTHONPATH): game data "break pickling" puts a
#: stream item in the DS's events that its view cannot carry. Only a command reaches the
#: child, so the fault is planted in the child's own code.
BREAK_PICKLING = """
    from roles.cores.commands import SetGameData
    from roles.cores.ds import DriverStation

    real = DriverStation.apply

    def breaking(ds, command, now):
        if not (isinstance(command, SetGameData) and command.text == "break pickling"):
            return real(ds, command, now)
        ds.events.items.append((0.0, lambda: None))

    DriverStation.apply = breaking
"""


def test_a_failing_snapshot_ends_the_child_and_says_so(tmp_path, monkeypatch):
    # a view that cannot be pickled any more: the child logs it and hangs up (a periodic
    # snapshot may find it before the call's own reply does: then the call is refused)
    plant = tmp_path / "plant"
    plant.mkdir()
    (plant / "sitecustomize.py").write_text(textwrap.dedent(BREAK_PICKLING))
    monkeypatch.setenv("PYTHONPATH", str(plant))
    engine = ProcessEngine(_config(tmp_path))
    engine.start()
    try:
        try:
            engine.execute(SetGameData("break pickling"))
        except CommandError:
            pass
        assert _wait(lambda: engine.problems)
        assert "wire process ended" in engine.problems[0]
    finally:
        engine.stop()


def test_a_robot_program_from_a_file_runs_in_the_child(tmp_path):
    program = tmp_path / "my_robot.py"
    program.write_text("def robot_periodic(state, robot):\n    robot.set_output(0, state.enabled)\n")
    engine = ProcessEngine(_config(tmp_path, program=str(program)))
    engine.start()
    try:
        assert _wait(lambda: engine.field.stations[0].rio.program_name == "my_robot.py"
                     and engine.field.stations[0].ds.link.robot_comms, 2.0)
        time.sleep(0.3)  # several rounds of snapshots
        assert engine.problems == [] and not engine.ended
    finally:
        engine.stop()
