"""Whole fields: on the fake clock (a match in milliseconds) and over loopback sockets, six
teams each on their own 127.TE.AM.x addresses with the real ports."""

from __future__ import annotations

import asyncio
import heapq
import math
import time
import types

import pytest

from protocol import fms_to_ds
from protocol.enums import AllianceStation, Mode
from roles.runtime.field import Field, FieldConfig, StationRoles
from roles.runtime.shell import START_SPREAD, RoleSpec, Runtime, _Timers
from roles.sim.simnet import SimNetwork

from .cheesy_fms import CheesyLikeFms

TEAMS = [254, 1114, 2056, 118, 148, 1678]


def test_full_match_on_the_fake_clock():
    net = SimNetwork()
    fms_packets = []
    net.taps.append(lambda r: fms_packets.append((r.time, fms_to_ds.decode_control(r.data)))
                    if r.kind == "fms-to-ds" and r.direction == "out" else None)
    field = Field(FieldConfig(teams=list(TEAMS), plan="ephemeral"))
    field.start_sim(net)
    net.run_for(3.0)
    fms = field.fms
    assert all(st.ds.fms.status == "good" and st.ds.link.robot_comms for st in field.stations)
    assert fms.start_refusals() == []
    net.command("fms", lambda: fms.start_match(net.now))
    net.run_for(1.0)
    assert fms.phase.value == "auto"
    assert all(st.ds.enabled and st.ds.mode is Mode.AUTONOMOUS and st.rio.control.enabled for st in field.stations)
    net.run_for(20.0)  # into the pause
    assert fms.phase.value == "pause"
    assert not any(st.rio.control.enabled for st in field.stations)
    net.run_for(4.0)
    assert fms.phase.value == "teleop"
    assert all(st.rio.control.enabled and st.rio.control.mode is Mode.TELEOP for st in field.stations)
    # A station e-stop disables that robot within one FMS control packet (sent at once).
    blue2 = field.stations[4]
    net.command("fms", lambda: fms.estop(AllianceStation.BLUE2, net.now))
    t0 = net.now
    net.run_for(0.1)
    assert not blue2.rio.control.enabled and blue2.rio.control.estopped and blue2.ds.arbiter.estopped
    assert all(st.rio.control.enabled for st in field.stations if st is not blue2)
    net.run_for(140.0)
    assert fms.phase.value == "post-match"
    assert not any(st.rio.control.enabled for st in field.stations)
    # Remaining time counts the current period; control packets at least every 500 ms.
    teleop = [p for now, p in fms_packets if p.enabled and p.mode is Mode.TELEOP]
    assert max(p.remaining_seconds for p in teleop) == 140
    to_blue2 = [(now, p) for now, p in fms_packets if p.station is AllianceStation.BLUE2 and now >= t0]
    assert any(now - t0 < 0.01 and p.estop and not p.enabled for now, p in to_blue2)
    assert not any(st.ds.link.echoes.lost_packets for st in field.stations)
    assert not any(sum(s.bad_packets for s in st.ds.stats.values()) for st in field.stations)


async def test_full_field_over_loopback_sockets_on_team_addresses():
    runtime = Runtime()
    field = Field(FieldConfig(teams=list(TEAMS), plan="loopback"))
    try:
        await field.start(runtime)
        runtime.start()
        # Six teams, each on its own addresses with the real ports (docs/design.md#addresses).
        assert field.bound["rio 254"]["ds"] == ("127.2.54.2", 1110)
        assert field.bound["rio 1678"]["tcp"] == ("127.16.78.2", 1740)
        assert field.bound["ds 1114"]["robot"] == ("127.11.14.5", 1150)
        assert field.bound["fms"]["udp"] == ("127.0.100.5", 1160)
        deadline = time.monotonic() + 30  # a bound for a busy machine: each step below is "until"
        while time.monotonic() < deadline:
            if all(st.ds.link.robot_comms and st.ds.fms.status == "good" for st in field.stations) and all(
                    s.report.ds_address is not None and s.login.challenge == "right" for s in field.fms.stations):
                break
            await asyncio.sleep(0.05)
        assert [st.ds.fms.status for st in field.stations] == ["good"] * 6
        # Each DS's TCP login leaves from its own 127.TE.AM.5, where its status comes from
        # and its control packets go (the FMS takes status only from a station's login).
        assert [s.login.peer[0] for s in field.fms.stations] == \
            ["127.2.54.5", "127.11.14.5", "127.20.56.5", "127.1.18.5", "127.1.48.5", "127.16.78.5"]
        assert all(s.report.ds_address[0] == s.login.peer[0] and s.login.challenge == "right" for s in field.fms.stations)
        field.fms.set_timing(runtime.clock(), auto=1, pause=0.5, teleop=1)
        field.fms.start_match(runtime.clock())
        runtime.hosts["fms"].kick()
        await asyncio.sleep(0.5)
        assert all(st.rio.control.enabled and st.rio.control.mode is Mode.AUTONOMOUS for st in field.stations)
        await asyncio.sleep(2.5)
        assert field.fms.phase.value == "post-match"
        assert not any(st.rio.control.enabled for st in field.stations)
        assert all(st.ds.link.echoes.lost_packets == 0 for st in field.stations)
    finally:
        await runtime.close()


class _Polled:
    """A core that only notes when it is polled."""

    def __init__(self, name: str, polls: list) -> None:
        self.name, self.polls = name, polls

    def poll(self, now: float):
        self.polls.append((self.name, now))
        return ()

    def next_deadline(self):
        return None

    def shutdown(self) -> None:  # the one core contract (roles/cores/core.py): nothing runs outside it
        pass


class _Beat:
    """A core on a 20 ms grid from its first poll, noting each poll."""

    def __init__(self, name: str, polls: list, period: float = 0.02) -> None:
        self.name, self.polls, self.period = name, polls, period
        self.next: float | None = None
        self.called: list[float] = []  # every poll, due or not

    def poll(self, now: float):
        self.called.append(now)
        if self.next is None or now >= self.next:
            self.polls.append((self.name, now))
            self.next = (now if self.next is None else self.next) + self.period
        return ()

    def next_deadline(self):
        return self.next

    def shutdown(self) -> None:  # the one core contract (roles/cores/core.py): nothing runs outside it
        pass


async def test_one_timer_polls_the_roles_due_together_in_the_order_they_were_added():
    runtime = Runtime()
    polls: list[tuple[str, float]] = []
    try:
        late = _Beat("late", polls, period=0.05)
        robot, ds = _Beat("robot", polls), _Beat("ds", polls)
        for name, core in (("robot", robot), ("ds", ds), ("late", late)):
            await runtime.add(RoleSpec(name, core, group="one"))
        timers = runtime.timers()
        assert timers is not None and all(h._timers is timers for h in runtime.hosts.values())
        fired = []
        original = timers.fired
        timers.fired = lambda: (fired.append(1), original())
        runtime.start()
        late.next += 0.2  # its deadline moved later: the old one in the heap must not poll it
        runtime.hosts["late"].reschedule()
        deadline = time.monotonic() + 10
        while sum(1 for name, _ in polls if name == "ds") < 5 and time.monotonic() < deadline:
            await asyncio.sleep(0.01)
        beats = [(name, t) for name, t in polls if name in ("robot", "ds")]
        assert [name for name, _ in beats[:10]] == ["robot", "ds"] * 5
        assert robot.next == ds.next  # one grid
        assert len(fired) <= sum(1 for name, _ in polls if name == "ds") + 2  # one wake-up a beat for both
        assert all(t - late.called[0] >= 0.25 * 0.99 for t in late.called[1:])
    finally:
        await runtime.close()
    assert runtime._timers is None


class _Flaky(_Beat):
    """A beat whose next_deadline raises once, on its third poll."""

    def next_deadline(self):
        if len(self.called) == 3 and not getattr(self, "raised", False):
            self.raised = True
            raise RuntimeError("a core bug")
        return self.next


async def test_a_role_whose_deadline_raises_once_keeps_its_beat_and_so_does_its_partner(caplog):
    runtime = Runtime()
    polls: list[tuple[str, float]] = []
    try:
        robot, ds = _Flaky("robot", polls), _Beat("ds", polls)
        await runtime.add(RoleSpec("robot", robot, group="one"))
        await runtime.add(RoleSpec("ds", ds, group="one"))
        runtime.start()
        deadline = time.monotonic() + 10
        while (len(robot.called) < 10 or len(ds.called) < 10) and time.monotonic() < deadline:
            await asyncio.sleep(0.01)
        assert robot.raised and len(robot.called) >= 10 and len(ds.called) >= 10
        assert "next_deadline failed" in caplog.text
    finally:
        await runtime.close()


def test_moved_deadlines_dropped_while_the_timer_fires_leave_every_beat_on_time():
    # The heap drops deadlines that moved once it holds many; done while a beat is being
    # polled, the timer must still be armed for the earliest deadline left, including one a
    # role due in the same wake-up pushed after the drop.
    class Alarm:
        deadline = math.inf

        def arm(self, deadline):
            self.deadline = deadline

    class Host:
        def __init__(self, rank, period, runtime):
            self.rank, self.period, self.runtime = rank, period, runtime
            self._timer_at = None

        def _on_timer(self):
            at, self._timer_at = self._timer_at, None
            self._timer_at = at + self.period
            timers.add(self, self._timer_at)

    runtime = types.SimpleNamespace(hosts={"slow": None, "fast": None})
    timers = _Timers(Alarm())
    now = time.monotonic()
    slow, fast = Host(0, 5.0, runtime), Host(1, 0.02, runtime)
    for host in (slow, fast):  # both due now; the slow one polls first and drops the moved deadlines
        host._timer_at = now - 0.001
        timers.add(host, host._timer_at)
    for i in range(200):
        heapq.heappush(timers.heap, (now + 100 + i, slow.rank, slow))  # deadlines it moved away from
    timers.fired()
    assert timers.alarm.deadline == fast._timer_at  # the fast beat's, not the slow one's 5 s away
    assert len(timers.heap) < 200


async def test_a_stations_ds_and_robot_start_their_beats_together_and_stations_spread():
    # Each wake-up of a sleeping process costs CPU (tens of microseconds on a virtual
    # machine): a DS and its robot whose grids start at one instant share one wake-up a
    # beat, the robot's program first so the DS's packet is answered at once; the stations
    # stay spread over the beat so no DS's round trip waits for the others.
    runtime = Runtime()
    polls: list[tuple[str, float]] = []
    try:
        for name, group in (("rio 1", "s1"), ("rio 2", "s2"), ("fms", None), ("ds 1", "s1"), ("ds 2", "s2")):
            await runtime.add(RoleSpec(name, _Polled(name, polls), group=group))
        assert Field(FieldConfig(teams=[1, 2], plan="ephemeral"))._make("ds", StationRoles(AllianceStation.RED1, 1)).group \
            == ("station", AllianceStation.RED1)
        runtime.start()
        deadline = time.monotonic() + 10
        while len(polls) < 5 and time.monotonic() < deadline:
            await asyncio.sleep(0.01)
        order = [name for name, _ in polls]
        assert order == ["rio 1", "ds 1", "rio 2", "ds 2", "fms"]  # a robot's beat, then its DS's packet
        when = dict(polls)
        assert when["rio 1"] == when["ds 1"] and when["rio 2"] == when["ds 2"]  # one instant: one grid
        assert when["ds 2"] - when["ds 1"] >= START_SPREAD / 3 * 0.99  # three groups over one beat
        assert when["fms"] - when["ds 1"] >= START_SPREAD * 2 / 3 * 0.99
    finally:
        await runtime.close()


async def test_an_fms_that_answers_the_tcp_address_on_1120_enables_our_robot():
    # Issue 18: the DS's TCP connection left from 127.0.0.1, and the DS listened on 1121
    # only, so an FMS like Cheesy Arena in FMS Lite mode could never attach it.
    fms = CheesyLikeFms("127.0.100.77")
    await fms.start()
    runtime = Runtime()
    field = Field(FieldConfig(roles=frozenset({"ds", "rio"}), team=9973, plan="loopback", fms=fms.host))
    try:
        await field.start(runtime)
        runtime.start()
        st = field.stations[0]
        deadline = time.monotonic() + 10
        while time.monotonic() < deadline and not (st.ds.fms.attached and st.rio.control.enabled):
            await asyncio.sleep(0.05)
        # control goes to the DS's own address, on 1120; the login is team 9973
        assert fms.logins and all(dest == ("127.99.73.5", 1120) for _, _, dest in fms.logins)
        assert fms.logins[0][0] == bytes.fromhex("0003 18 26f5")
        assert st.ds.fms.attached and st.ds.enabled and st.rio.control.enabled and st.rio.control.fms_attached
        # the robot's TCP connection leaves from the DS's address as well
        assert [text for _, text in st.rio.events.items if text.startswith("TCP: DS connected from")] \
            and all(text.startswith("TCP: DS connected from 127.99.73.5:")
                    for _, text in st.rio.events.items if text.startswith("TCP: DS connected"))
    finally:
        await runtime.close()
        await fms.close()


def test_a_loopback_robot_is_presumed_to_be_wpilib_simulator():
    # docs/design.md#command-line: "fieldbox --roles ds --robot 127.0.0.1" drives WPILib's simulator.
    for robot, presumed in (("127.0.0.1", True), ("10.2.54.2", False), (None, False)):
        field = Field(FieldConfig(roles=frozenset({"ds"}), team=254, plan="ephemeral", robot=robot))
        field.start_sim(SimNetwork())
        assert field.stations[0].ds.link.presume_simulator is presumed, robot


def test_the_panels_commands_are_refused_in_words_and_change_nothing():
    """What the panels send goes through Field.execute like a typed command, and each
    refusal says why: a bad value, a part that does not run here."""
    from roles.cores.commands import (KeepRoundTrips, MatchControl, ReplayMatch, SetAnalogInput, SetGameData,
                                      SetMatchTiming, SetPracticeTiming, ToggleDigitalInput)
    from roles.cores.core import CommandError
    from roles.runtime.engine import SimEngine

    engine = SimEngine(FieldConfig(team=254))  # a DS, its robot and the FMS, on the fake clock
    ds, fms = engine.field.stations[0].ds, engine.field.fms
    engine.advance(1.0)
    refusals = {
        SetGameData("x" * 256): "at most 255 bytes",
        SetPracticeTiming(auto=-1.0): "practice auto must be 0..3600 seconds",
        SetMatchTiming(teleop=float("nan")): "teleop",
        ToggleDigitalInput(1): "not a 2010 one",
        SetAnalogInput(1, 512): "not a 2010 one",
        KeepRoundTrips(0): "round-trip samples must be 1..10000000",
    }
    for command, words in refusals.items():
        with pytest.raises(CommandError, match=words):
            engine.execute(command)
    assert ds.arbiter.practice_timing.auto == 15.0 and fms.match.timing.teleop > 0
    engine.execute(SetPracticeTiming(auto=5.0))  # the one phase named, the others kept
    assert (ds.arbiter.practice_timing.auto, ds.arbiter.practice_timing.teleop) == (5.0, 135.0)
    engine.execute(SetMatchTiming(auto=3.0))
    assert fms.match.timing.auto == 3.0
    engine.execute(MatchControl("start"))
    with pytest.raises(CommandError):  # not while a match runs: the FMS's own refusal
        engine.execute(ReplayMatch())


def test_a_ds_keeps_more_round_trips_when_told_and_their_numbering_goes_on():
    from roles.cores.commands import KeepRoundTrips
    from roles.runtime.engine import SimEngine

    engine = SimEngine(FieldConfig(team=254, roles=frozenset({"ds", "rio"})))
    ds = engine.field.stations[0].ds
    engine.advance(2.0)
    before = ds.link.echoes.trip.samples.total
    assert before > 50
    engine.execute(KeepRoundTrips(100_000, team=254))
    assert len(ds.link.echoes.trip.samples) == 0 and ds.link.echoes.trip.samples.total == before
    engine.advance(8.0)  # 400 control packets: more than the 256 a DS keeps for its panel
    assert len(ds.link.echoes.trip.samples) > 256
    assert ds.link.echoes.trip.samples.view().first_seq == before


def test_every_command_is_carried_out_by_one_core_and_refused_by_the_others():
    """The core contract (roles/cores/core.py Core.apply): each typed command is carried out
    by the core it acts on; the others refuse it in words. A command added without a core
    that takes it fails here, not on a user's key press."""
    import dataclasses

    from roles.cores import commands as C
    from roles.cores.core import CommandError
    from roles.runtime.engine import SimEngine

    engine = SimEngine(FieldConfig(team=254))
    st = engine.field.stations[0]
    cores = {"ds": st.ds, "rio": st.rio, "fms": engine.field.fms}
    engine.advance(1.0)
    samples = {C.SetMode: C.SetMode("auto"), C.SetAxis: C.SetAxis(0, 0, 0.5), C.SetButton: C.SetButton(0, 1, True),
               C.SetPov: C.SetPov(0, 0, 90), C.DeclareJoystick: C.DeclareJoystick(1, "pad", 6, 12, 1),
               C.ClearJoystick: C.ClearJoystick(1), C.UpdateJoysticks: C.UpdateJoysticks(()),
               C.Practice: C.Practice("stop"), C.SetGameData: C.SetGameData("LRL"),
               C.ToggleDigitalInput: C.ToggleDigitalInput(1), C.SetAnalogInput: C.SetAnalogInput(1, 5),
               C.KeepRoundTrips: C.KeepRoundTrips(100), C.SetBattery: C.SetBattery(12.0),
               C.MatchControl: C.MatchControl("next"), C.Bypass: C.Bypass(AllianceStation.RED2),
               C.StationEStop: C.StationEStop(AllianceStation.RED3), C.StationAStop: C.StationAStop(AllianceStation.BLUE1)}
    kinds = [cls for cls in vars(C).values() if isinstance(cls, type) and issubclass(cls, C.Command)
             and cls is not C.Command and cls is not C.Fault]
    assert len(kinds) >= 25
    for cls in kinds:
        command = samples.get(cls) or cls()
        assert dataclasses.is_dataclass(command)
        takers = []
        for name, core in cores.items():
            try:
                core.apply(command, engine.now())
                takers.append(name)
            except CommandError as exc:
                if f"{command.verb} is not a" in str(exc):
                    continue
                takers.append(name)  # its own core, refusing in its own words (a 2010 input here)
        assert len(takers) == 1, (cls.__name__, takers)
    # a command that came whole but wrong (no parse checked it: a seat's, a script's) is
    # refused in words, never an IndexError, nor slot -1 read as the last one
    for bad in (C.SetAxis(-1, 0, 0.5), C.SetAxis(9, 0, 0.5), C.SetButton(6, 1, True), C.SetPov(-2, 0, 90)):
        with pytest.raises(CommandError, match="joystick slot"):
            st.ds.apply(bad, engine.now())
