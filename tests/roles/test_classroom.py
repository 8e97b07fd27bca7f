"""One field for a classroom (roles/runtime/classroom.py): apps that join it see the same live
packets; each seat may do what it is for and nothing more; a driver that goes leaves its
DS disabled; bad input on the seats' socket harms no one."""

from __future__ import annotations

import pickle
import socket
import threading
import time
from dataclasses import replace

import pytest

from roles.cores.commands import (DeclareJoystick, ReplayMatch, SetGameData, SetMatchTiming, SetUpMatch,
                                  UpdateJoysticks)
from roles.cores.core import CommandError
from roles.cores.fms import MatchStartRefused
from roles.runtime.classroom import ClassroomProcess, JoinedEngine, Seat, TakeBack, wanted_seat
from roles.runtime.field import FieldConfig
from roles.runtime.wireproc import Call, Join

from fieldbox.language import parse

TEAMS = [254, 1114, 2056, 118, 148, 1678]


def until(check, timeout: float = 20.0) -> bool:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if check():
            return True
        time.sleep(0.05)
    return bool(check())


@pytest.fixture
def classroom():
    host = ClassroomProcess(FieldConfig(teams=list(TEAMS), plan="ephemeral", log_files=False))
    host.start()
    joined: list[JoinedEngine] = []

    def join(want) -> JoinedEngine:
        engine = JoinedEngine(host.path, want)
        engine.start()
        joined.append(engine)
        return engine

    try:
        yield host, join
    finally:
        for engine in joined:
            engine.stop()
        assert host.stop() == 0  # the field stopped on its own when asked


def match_started(engine: JoinedEngine) -> bool:
    """Start the match once every station is ready (on a busy machine six DSes take a while
    to connect to the FMS: the start is refused, saying which are not, until they have)."""
    try:
        engine.execute(parse("match start"))
    except MatchStartRefused as exc:
        assert "not connected" in str(exc)
        return False
    return True


def station(engine: JoinedEngine, team: int):
    return next(st for st in engine.field.stations if st.team == team)


def test_three_joined_apps_see_the_same_live_packets(classroom):
    host, join = classroom
    apps = [join(("teacher", host.teacher_key)), join("driver"), join("observer")]
    assert [a.seat for a in apps] == [Seat("teacher"), Seat("driver", 254), Seat("observer")]
    seen: list[set] = [set() for _ in apps]
    lock = threading.Lock()
    for app, got in zip(apps, seen):
        def tap(r, got=got):
            if r.role == "rio 254" and r.kind == "ds-to-rio":
                with lock:
                    got.add(bytes(r.data))  # each DS->roboRIO packet carries its own sequence number
        app.add_tap(tap)

    def common() -> set:
        with lock:
            return set.intersection(*seen)

    assert until(lambda: len(common()) >= 5), [len(s) for s in seen]
    # the same bytes, not just as many: a control packet of the 2015+ protocol (tag 0x01)
    assert all(len(p) >= 6 and p[2] == 0x01 for p in common())
    # and the same field on every screen: every DS talks to its robot in every seat's views
    assert until(lambda: all(st.ds.link.robot_comms for a in apps for st in a.field.stations))


def test_each_seat_does_what_it_is_for_and_nothing_more(classroom):
    host, join = classroom
    teacher, driver, observer = join(("teacher", host.teacher_key)), join("driver"), join("observer")
    second = join("driver")
    assert second.seat == Seat("driver", 1114)  # the next free station
    assert join(("teacher", "not the key")).seat == Seat("observer")  # a wrong key watches
    with pytest.raises(CommandError, match="you watch"):
        observer.execute(parse("disable"))
    with pytest.raises(CommandError, match="not 1114"):
        driver.execute(parse("@1114 disable"))
    with pytest.raises(CommandError, match="teacher's"):
        driver.execute(parse("match start"))
    with pytest.raises(CommandError, match="teacher"):
        driver.call(TakeBack(1114))
    assert until(lambda: match_started(teacher))  # the FMS is the teacher's
    assert until(lambda: all(st.ds.enabled for st in observer.field.stations))
    driver.execute(parse("estop"))  # its own robot: a driver may always stop it, and every screen shows it
    assert until(lambda: station(observer, 254).ds.arbiter.estopped and station(teacher, 254).ds.link.robot_estopped)
    assert not station(observer, 1114).ds.arbiter.estopped and station(observer, 1114).ds.enabled


def test_a_drivers_panel_commands_reach_its_own_station_only(classroom):
    """What a driver's panels send (a joystick, game data) goes to its own station's DS; for
    another station, or for the FMS, it is refused in words, and nothing else comes in."""
    host, join = classroom
    teacher, driver, observer = join(("teacher", host.teacher_key)), join("driver"), join("observer")
    assert driver.seat == Seat("driver", 254)
    pad = UpdateJoysticks((DeclareJoystick(0, "pad", 6, 12, 1),))
    with pytest.raises(CommandError, match="you drive team 254, not 1114"):
        driver.execute(replace(pad, team=1114))
    with pytest.raises(CommandError, match="you drive team 254, not 1114"):
        driver.execute(SetGameData("LRL", team=1114))
    for fms_command in (ReplayMatch(), SetUpMatch(number=7), SetMatchTiming(auto=5.0)):
        with pytest.raises(CommandError, match="teacher's"):
            driver.execute(fms_command)
    with pytest.raises(CommandError, match="takes commands only"):  # a call by name, as panels once sent
        driver._wait(driver._request(print))
    driver.execute(pad)  # no team: its own
    assert until(lambda: station(observer, 254).ds.sticks.slots[0] is not None)
    assert station(observer, 1114).ds.sticks.slots[0] is None
    assert observer.field.fms.match.timing.auto != 5.0 and observer.field.fms.match.number != 7
    teacher.execute(SetMatchTiming(auto=5.0))  # the teacher's panel may
    assert until(lambda: observer.field.fms.match.timing.auto == 5.0)


def test_a_driver_that_goes_or_is_taken_back_leaves_its_ds_disabled(classroom):
    host, join = classroom
    teacher, observer = join(("teacher", host.teacher_key)), join("observer")
    first, second = join("driver"), join("driver")
    assert (first.seat.team, second.seat.team) == (254, 1114)
    assert until(lambda: match_started(teacher))
    assert until(lambda: all(st.ds.enabled for st in observer.field.stations))
    first.stop()  # the tab closed
    assert until(lambda: not station(observer, 254).ds.enabled)
    assert station(observer, 1114).ds.enabled  # the others play on
    assert join("driver").seat == Seat("driver", 254)  # the station is free again
    assert teacher.call(TakeBack(1114)) == "team 1114 is free"
    assert until(lambda: second.seat == Seat("observer"))
    assert until(lambda: not station(observer, 1114).ds.enabled)
    with pytest.raises(CommandError, match="you watch"):
        second.execute(parse("disable"))
    with pytest.raises(CommandError, match="nobody drives"):
        teacher.call(TakeBack(1114))


def test_garbage_on_the_seats_socket_is_dropped_and_harms_no_one(classroom):
    host, join = classroom
    observer = join("observer")
    for junk in (b"\x00" * 64, b"\xff\xff\xff\xff not a message", b"\x00\x00\x00\x05hello"):
        with socket.socket(socket.AF_UNIX) as raw:
            raw.connect(host.path)
            raw.sendall(junk)
    # a join, then a call that is not one, the FMS's command, and a message the wire never takes
    with socket.socket(socket.AF_UNIX) as raw:
        raw.connect(host.path)
        for msg in (Join("driver"), Call(1, "not a command"), Call(2, parse("match start")), ("call",)):
            data = pickle.dumps(msg)
            raw.sendall(len(data).to_bytes(4, "big") + data)
        time.sleep(0.5)
    heard = observer.heard_at
    assert until(lambda: observer.heard_at > heard)  # the stream goes on
    assert join("driver").seat == Seat("driver", 254)  # and the garbage holds no station
    assert not any(st.ds.enabled for st in observer.field.stations)  # nor started a match
    assert host.process.poll() is None


def test_join_as_says_what_it_takes(monkeypatch):
    assert wanted_seat("driver") == "driver" and wanted_seat("observer") == "observer"
    assert wanted_seat("teacher:abc") == ("teacher", "abc")
    monkeypatch.setenv("FIELDBOX_CLASSROOM_KEY", "k1")
    assert wanted_seat("teacher") == ("teacher", "k1")
    monkeypatch.delenv("FIELDBOX_CLASSROOM_KEY")
    with pytest.raises(ValueError, match="key"):
        wanted_seat("teacher")
    with pytest.raises(ValueError, match="driver, observer"):
        wanted_seat("pilot")


def test_joining_nothing_says_so(tmp_path):
    engine = JoinedEngine(str(tmp_path / "none.sock"), "driver")
    with pytest.raises(OSError, match="cannot join the classroom's field"):
        engine.start(timeout=2)


def test_a_seat_whose_views_went_wrong_gets_them_whole_and_stays(classroom):
    """A joined app that cannot apply views asks for them whole (as the wire process's own
    app does), and goes on watching: it is not closed as sending garbage."""
    host, join = classroom
    observer = join("observer")
    ds = lambda: station(observer, 254).ds  # noqa: E731 - the latest view
    assert until(lambda: ds().link.echoes.trip.samples)
    observer._views._streams.clear()  # its copies of the streams lost: the next part cannot join
    seen = ds().link.echoes.trip.last_ms
    assert until(lambda: ds().link.echoes.trip.last_ms != seen)
    assert until(lambda: ds().link.echoes.trip.samples and ds().link.echoes.trip.samples[-1] == ds().link.echoes.trip.last_ms)
    assert not observer.ended
