"""The Driver Station core against a fake clock, a fake robot and real encoded packets.

The harness and the fake robot here are shared with test_ds_fms.py and test_practice.py.
"""

from __future__ import annotations

import datetime as dt
import json
import math
import random

import pytest
from hypothesis import assume, given
from hypothesis import strategies as st

from protocol import ds_to_rio, rio_to_ds
from protocol.ds_to_rio import ControlPacket, Date, JoystickDescriptor, Timezone, decode_control
from protocol.enums import AllianceStation, JoystickType, MatchType, Mode
from protocol.errors import ProtocolError
from protocol.rio_to_ds import StatusPacket
from roles.cores.core import Close, CommandError, Connect, Datagram, StreamSend
from roles.cores.ds import (COMMS_TIMEOUT, PERIOD, REQUEST_PACKETS, DriverStation, robot_codec)

ROBOT_HOST = "127.2.54.2"
ROBOT_UDP = (ROBOT_HOST, 1110)
ROBOT_TCP = (ROBOT_HOST, 1740)
WALL = dt.datetime(2024, 3, 15, 12, 30, 45, 123456, tzinfo=dt.timezone.utc)


def make_ds(**kw) -> DriverStation:
    kw.setdefault("clock", lambda: WALL)
    kw.setdefault("timezone_name", "America/Chicago")
    return DriverStation(254, ROBOT_UDP, ROBOT_TCP, **kw)


class FakeRobot:
    """Answers every control packet the way PROTOCOL-NOTES says a roboRIO does: sequence
    echoed, status bits echoed, robot code running, request-date until date+timezone came."""

    def __init__(self) -> None:
        self.online = True
        self.code = True
        self.battery = 12.5
        self.request_date = True
        self.drop_every = 0  # drop every n-th reply
        self.tags: tuple = ()
        self.brownout = False
        self.estop_latched = False  # a robot whose own e-stop latch is set
        self.received: list[ControlPacket] = []
        self.dests: list = []
        self.is_roborio = True  # False: WPILib's simulator, whose trace byte is 0x20 alone

    def reply(self, data: bytes, dest) -> bytes | None:
        pkt = decode_control(data)
        self.received.append(pkt)
        self.dests.append(dest)
        if not self.online:
            return None
        if any(isinstance(t, Date) for t in pkt.tags) and any(isinstance(t, Timezone) for t in pkt.tags):
            self.request_date = False
        if self.drop_every and len(self.received) % self.drop_every == 0:
            return None
        return StatusPacket(pkt.sequence, 0x01, pkt.estop or self.estop_latched, self.brownout, False, pkt.enabled, pkt.mode,
                            robot_code=self.code, is_roborio=self.is_roborio, user_disabled=not pkt.enabled,
                            user_teleop=pkt.enabled and pkt.mode == Mode.TELEOP,
                            battery=self.battery, request_date=self.request_date, tags=self.tags).encode()


class Harness:
    """Drives a DS on a fake clock: polls at its deadlines, routes control packets to the fake
    robot (replies arrive ``latency`` later), opens/refuses TCP connections, records output."""

    def __init__(self, ds: DriverStation, robot: FakeRobot | None = None, t: float = 100.0,
                 latency: float = 0.0005) -> None:
        self.ds = ds
        self.robot = robot if robot is not None else FakeRobot()
        self.t = t
        self.latency = latency
        self.tcp_up = {"robot-tcp": True, "fms-tcp": False}
        self.open: set = set()
        self.datagrams: list[tuple[float, Datagram]] = []
        self.streams: dict[str, list[bytes]] = {}
        self.connects: list[tuple[float, str]] = []
        self.closes: list[Close] = []
        self.timers: list[list] = []  # [next_at, period, fn]
        self.on_fms_tcp = None  # fn(t) called when fms-tcp opens

    # -- output routing ---------------------------------------------------------------------
    def handle(self, actions) -> None:
        for a in actions:
            if isinstance(a, Datagram):
                self.datagrams.append((self.t, a))
                if a.channel == "robot":
                    reply = self.robot.reply(a.data, a.dest)
                    if reply is not None:
                        self.t += self.latency
                        self.handle(self.ds.datagram("robot", reply, (ROBOT_HOST, 1110), self.t))
            elif isinstance(a, StreamSend):
                assert a.conn in self.open, f"send on closed {a.conn}"
                self.streams.setdefault(a.conn, []).append(a.data)
            elif isinstance(a, Connect):
                self.connects.append((self.t, a.conn))
                if self.tcp_up.get(a.conn):
                    self.open.add(a.conn)
                    self.handle(self.ds.stream_opened(a.conn, a.address, self.t))
                    if a.conn == "fms-tcp" and self.on_fms_tcp:
                        self.on_fms_tcp(self.t)
                else:
                    self.handle(self.ds.stream_closed(a.conn, "connect failed: refused", self.t))
            elif isinstance(a, Close):
                self.closes.append(a)
                if a.conn in self.open:
                    self.open.discard(a.conn)
                    self.handle(self.ds.stream_closed(a.conn, a.reason, self.t))

    def every(self, period: float, fn, first: float | None = None) -> list:
        timer = [self.t if first is None else first, period, fn]
        self.timers.append(timer)
        return timer

    def run_until(self, end: float) -> None:
        while True:
            d = self.ds.next_deadline()
            d = math.inf if d is None else max(d, self.t)
            timer = min(self.timers, key=lambda x: x[0], default=None)
            if timer is not None and timer[0] <= d and timer[0] <= end:
                self.t = max(self.t, timer[0])
                timer[0] += timer[1]
                timer[2](self.t)
                continue
            if d > end:
                break
            self.t = d
            self.handle(self.ds.poll(self.t))
        self.t = max(self.t, end)

    def run(self, seconds: float) -> None:
        self.run_until(self.t + seconds)

    # -- reading what went out --------------------------------------------------------------
    def controls(self, since: float = -math.inf) -> list[ControlPacket]:
        return [decode_control(d.data) for t, d in self.datagrams if d.channel == "robot" and t >= since]

    def last_control(self) -> ControlPacket:
        return next(decode_control(d.data) for _, d in reversed(self.datagrams) if d.channel == "robot")

    def tcp_frames(self, conn: str = "robot-tcp") -> list[bytes]:
        from protocol.framing import split_frames
        return split_frames(b"".join(self.streams.get(conn, [])))

    def rio_tcp(self, *frames: bytes) -> None:
        self.handle(self.ds.stream_data("robot-tcp", b"".join(frames), self.t))


def connected(seconds: float = 1.0, **kw) -> Harness:
    """A DS with robot comms and robot code, ``seconds`` in."""
    h = Harness(make_ds(**kw))
    h.run(seconds)
    assert h.ds.link.robot_comms and h.ds.link.robot_code
    return h


# -- the 20 ms grid -------------------------------------------------------------------------
def test_control_grid_has_no_drift_over_10000_packets_with_jittered_polls():
    ds = make_ds()
    rng = random.Random(1)
    start = 1000.0
    sent = []
    t = start
    ds.poll(t)  # slot 0
    sent.append(t)
    while len(sent) < 10_000:
        d = ds.next_deadline()
        assert d is not None
        # Wake up late by 0-15 ms, and sometimes early (a spurious wake-up): never a burst.
        t = max(t, d + rng.uniform(-0.004, 0.015))
        actions = ds.poll(t)
        packets = [a for a in actions if isinstance(a, Datagram) and a.channel == "robot"]
        assert len(packets) <= 1
        if packets:
            sent.append(t)
    for k, when in enumerate(sent):
        assert start + k * PERIOD - 1e-9 <= when < start + (k + 1) * PERIOD, k
    assert ds.link.missed_slots == 0
    assert ds.link.echoes.sent_packets == 10_000
    assert ds.next_deadline() == pytest.approx(start + 10_000 * PERIOD, abs=1e-9)


def test_a_late_poll_sends_once_and_stays_on_the_grid():
    ds = make_ds()
    ds.poll(50.0)
    assert ds.next_deadline() == pytest.approx(50.02)
    actions = ds.poll(50.0 + 0.085)  # slots 1..4 were due; 4 is the current one
    assert sum(isinstance(a, Datagram) and a.channel == "robot" for a in actions) == 1
    assert ds.link.missed_slots == 3
    assert ds.next_deadline() == pytest.approx(50.10)
    assert not [a for a in ds.poll(50.099) if isinstance(a, Datagram) and a.channel == "robot"]
    assert [a for a in ds.poll(50.100) if isinstance(a, Datagram) and a.channel == "robot"]
    assert ds.link.missed_slots == 3


def test_first_control_packet_bytes():
    ds = make_ds()
    actions = ds.poll(10.0)
    (pkt,) = [a for a in actions if isinstance(a, Datagram)]
    assert pkt.dest == ROBOT_UDP and pkt.kind == "ds-to-rio"
    # seed header: sequence 0, comm version 1, control 0 (disabled teleop), request 0x10
    # (PROTOCOL-NOTES "Send 0x10 in normal operation"), station 0 (R1); no joystick, so no
    # joystick tag (PROTOCOL-NOTES "Corrections": the real DS sent none in 3,118 packets).
    assert pkt.data == bytes.fromhex("0000 01 00 10 00")
    assert Connect("robot-tcp", ROBOT_TCP) in actions


def test_sequence_wraps_at_16_bits():
    ds = make_ds()
    ds.link._seq = 0xFFFF
    a = [x for x in ds.poll(1.0) if isinstance(x, Datagram)][0]
    b = [x for x in ds.poll(1.02) if isinstance(x, Datagram)][0]
    assert decode_control(a.data).sequence == 0xFFFF and decode_control(b.data).sequence == 0


# -- comms, enable, e-stop ------------------------------------------------------------------
def test_enable_sends_enabled_packets_in_the_chosen_mode():
    h = connected()
    h.ds.set_mode(Mode.AUTONOMOUS, h.t)
    h.ds.enable(h.t)
    h.run(0.1)
    pkt = h.last_control()
    assert pkt.enabled and pkt.mode == Mode.AUTONOMOUS and not pkt.estop and not pkt.fms_attached
    assert pkt.request_byte == 0x10
    assert h.ds.enabled
    assert any("robot enabled (auto)" in text for _, text in h.ds.events.items)


def test_comms_loss_disables_after_one_second_and_enable_needs_a_fresh_command():
    h = connected()
    h.ds.enable(h.t)
    h.run(0.5)
    assert h.last_control().enabled
    h.robot.online = False
    lost_at = h.t
    h.run(0.9)
    assert h.ds.link.robot_comms  # not yet: less than 1 s without status
    h.run(0.2)
    assert not h.ds.link.robot_comms and not h.ds.enabled
    assert h.ds.trip_ms is None and h.ds.link.battery is None and not h.ds.link.robot_code
    # the last packet the DS sent while comms were up is within 1 s of the last status
    last_enabled = max(t for t, d in h.datagrams if d.channel == "robot" and decode_control(d.data).enabled)
    assert last_enabled - lost_at <= COMMS_TIMEOUT + PERIOD
    assert any("comms lost" in text and "enable again" in text for _, text in h.ds.events.items)
    with pytest.raises(CommandError, match="no robot comms"):
        h.ds.enable(h.t)
    h.robot.online = True
    h.run(0.5)
    assert h.ds.link.robot_comms
    assert not h.ds.enabled and not h.last_control().enabled  # no enable without a fresh command
    h.ds.enable(h.t)
    h.run(0.1)
    assert h.last_control().enabled


def test_enable_is_refused_with_reasons_and_changes_nothing():
    h = Harness(make_ds())
    h.robot.online = False
    h.run(0.5)
    with pytest.raises(CommandError, match="no robot comms"):
        h.ds.enable(h.t)
    h.robot.online = True
    h.robot.code = False
    h.run(0.5)
    with pytest.raises(CommandError, match="no robot code"):
        h.ds.enable(h.t)
    h.robot.code = True
    h.run(0.1)
    h.ds.estop(h.t)
    with pytest.raises(CommandError, match="e-stopped"):
        h.ds.enable(h.t)
    assert not h.ds.arbiter.enabled_local


def test_estop_latches_through_comms_loss_and_reconnect_until_restart_code():
    h = connected()
    h.ds.enable(h.t)
    h.run(0.2)
    h.ds.estop(h.t)
    h.run(0.1)
    assert h.last_control().estop and not h.last_control().enabled
    h.robot.online = False
    h.run(2.0)
    h.robot.online = True
    h.run(1.0)
    assert h.ds.link.robot_comms and h.ds.arbiter.estopped and h.last_control().estop
    with pytest.raises(CommandError, match="e-stopped"):
        h.ds.enable(h.t)
    # the only way out: restart the code (or reboot). The request packets carry no e-stop.
    since = h.t
    h.ds.restart_code(h.t)
    assert not h.ds.arbiter.estopped
    h.run(0.5)
    sent = h.controls(since)
    assert [p.restart_code for p in sent[:REQUEST_PACKETS + 1]] == [True] * REQUEST_PACKETS + [False]
    assert not any(p.estop for p in sent)
    assert not any(p.reboot_roborio for p in sent)
    assert all(p.request_byte & 0x10 for p in sent)
    h.ds.enable(h.t)
    h.run(0.1)
    assert h.last_control().enabled


def test_reboot_request_clears_estop_and_sends_reboot_bits():
    h = connected()
    h.ds.estop(h.t)
    h.run(0.1)
    since = h.t
    h.ds.reboot_roborio(h.t)
    h.run(0.5)
    sent = h.controls(since)
    assert sum(p.reboot_roborio for p in sent) == REQUEST_PACKETS
    assert sent[0].request_byte == 0x18 and not sent[0].estop
    assert not h.ds.arbiter.estopped


def test_restart_request_stops_once_the_robot_shows_its_code_restarting():
    h = connected()
    since = h.t
    h.ds.restart_code(h.t)
    h.run(0.021)  # one request packet out
    h.robot.code = False  # the robot's status now shows no code: the restart happened
    h.run(0.3)
    assert 1 <= sum(p.restart_code for p in h.controls(since)) < REQUEST_PACKETS


def test_restart_and_reboot_need_robot_comms():
    ds = make_ds()
    for cmd in (ds.restart_code, ds.reboot_roborio):
        with pytest.raises(CommandError, match="no robot comms"):
            cmd(0.0)
    assert ds.link._restart_left == ds.link._reboot_left == 0


def test_enable_is_refused_while_the_robot_still_reports_an_estop():
    h = connected()
    h.robot.estop_latched = True
    h.run(0.1)
    assert h.ds.link.robot_estopped and not h.ds.arbiter.estopped
    with pytest.raises(CommandError, match="robot still reports an e-stop"):
        h.ds.enable(h.t)
    h.robot.estop_latched = False
    h.run(0.1)
    h.ds.enable(h.t)


def refusal(h: Harness) -> str | None:
    """What enable() says now (None: it enabled; then disabled again, as it was)."""
    try:
        h.ds.enable(h.t)
    except CommandError as exc:
        return str(exc)
    h.ds.disable(h.t)
    return None


def test_the_view_says_what_blocks_an_enable_in_the_words_enable_is_refused_with():
    """The DS tab's note is the view's ``enable_blocker``: computed once, by the core that refuses."""
    h = Harness(make_ds())
    h.robot.online = False
    h.run(0.5)
    seen = []

    def look(kind: str | None) -> None:
        view = h.ds.view(h.t)
        assert (view.enable_blocker, view.enable_refusal) == ((kind, refusal(h)) if kind else (None, None))
        seen.append(kind)

    look("comms")
    h.robot.online, h.robot.code = True, False
    h.run(0.5)
    look("code")
    h.robot.code = True
    h.run(0.1)
    look(None)
    h.ds.start_practice(h.t)
    h.run(0.1)
    look("practice")
    h.ds.stop_practice(h.t)
    h.robot.estop_latched = True  # a robot whose own latch is set
    h.run(0.1)
    look("robot-estop")
    h.ds.restart_code(h.t)  # while its request goes out, the robot still reports the e-stop
    h.run(0.021)
    assert h.ds.link._restart_left and h.ds.estop_kind == ""
    look("robot-estop")
    h.robot.estop_latched = False
    h.run(0.5)
    h.ds.estop(h.t)
    look("estop")
    assert seen == ["comms", "code", None, "practice", "robot-estop", "robot-estop", "estop"]


def test_a_view_is_a_value_the_core_never_changes_afterwards():
    """A panel may hold a view while the wire goes on: nothing the core does later shows in it
    (a view once shared the core's console deque and its joysticks' axis lists)."""
    import copy

    h = connected(0.5)
    h.ds.set_joystick(0, 2, 4, 1, h.t, name="pad")
    h.ds.add_console_line(h.t, "stdout", "before")
    h.run(0.2)
    view = h.ds.view(h.t)
    kept = copy.deepcopy(view)
    assert view == kept and view.sticks.slots[0].axes == (0.0, 0.0) and view.tcp.console.end == 1
    h.ds.set_axis(0, 1, 0.5, h.t)
    h.ds.set_button(0, 2, True, h.t)
    h.ds.set_pov(0, 0, 90, h.t)
    h.ds.add_console_line(h.t, "error", "after")
    h.rio_tcp(rio_to_ds.DisableFaults(3, 1).encode(),
              rio_to_ds.VersionInfo(rio_to_ds.DeviceType.SOFTWARE, 0, 0, "FRC_Lib_Version", "2026.1").encode())
    h.ds.estop(h.t)
    h.run(1.0)
    assert h.ds.view(h.t) != kept
    assert view == kept  # the first view still says what it said
    assert view.sticks.slots[0].axes == (0.0, 0.0) and view.tcp.console.end == 1 and not view.arbiter.estopped


def test_disable_always_works():
    h = connected()
    h.ds.enable(h.t)
    h.run(0.1)
    h.ds.disable(h.t)
    h.run(0.05)
    assert not h.last_control().enabled
    h.ds.disable(h.t)  # idempotent, no error


# -- date and time zone ------------------------------------------------------------------------
def test_date_and_timezone_are_sent_once_after_request_date():
    h = Harness(make_ds())
    h.robot.request_date = False
    h.run(0.5)
    assert not any(isinstance(t, (Date, Timezone)) for p in h.controls() for t in p.tags)
    h.robot.request_date = True
    h.run(1.0)
    carrying = [p for p in h.controls() if any(isinstance(t, Date) for t in p.tags)]
    assert len(carrying) == 1
    (date,) = [t for t in carrying[0].tags if isinstance(t, Date)]
    (tz,) = [t for t in carrying[0].tags if isinstance(t, Timezone)]
    # month 0-based, year since 1900, hour UTC (PROTOCOL-NOTES)
    assert (date.year, date.month, date.day, date.hour, date.minute, date.second) == (124, 2, 15, 12, 30, 45)
    assert date.microseconds == 123456
    assert date.to_datetime() == WALL
    assert tz.name == "America/Chicago"


def test_date_is_sent_again_to_a_robot_that_came_back_and_asks_again():
    h = Harness(make_ds())
    h.run(0.5)
    h.robot.online = False
    h.run(1.5)
    h.robot.online = True
    h.robot.request_date = True
    h.run(0.5)
    assert sum(any(isinstance(t, Date) for t in p.tags) for p in h.controls()) == 2


def test_date_uses_an_aware_local_clock_converted_to_utc():
    here = dt.timezone(dt.timedelta(hours=-5))
    h = Harness(make_ds(clock=lambda: dt.datetime(2024, 1, 1, 0, 30, tzinfo=here)))
    h.run(0.2)
    (date,) = [t for p in h.controls() for t in p.tags if isinstance(t, Date)]
    assert (date.year, date.month, date.day, date.hour, date.minute) == (124, 0, 1, 5, 30)


def test_a_failing_wall_clock_does_not_stop_the_beat():
    def broken():
        raise RuntimeError("no clock")
    h = Harness(make_ds(clock=broken))
    h.run(0.5)
    assert h.ds.link.echoes.sent_packets >= 25
    assert any("date not sent" in text for _, text in h.ds.events.items)
    h2 = Harness(make_ds(clock=lambda: dt.datetime(1800, 1, 1)))
    h2.run(0.2)
    assert not any(isinstance(t, Date) for p in h2.controls() for t in p.tags)


def test_bad_timezone_name_is_refused_at_construction():
    with pytest.raises(ValueError):
        make_ds(timezone_name="x" * 300)


# -- joysticks ---------------------------------------------------------------------------------
def test_joystick_slots_keep_their_numbers():
    h = connected()
    h.ds.set_joystick(2, 4, 12, 1, h.t, name="Gamepad", is_xbox=True,
                      joystick_type=JoystickType.XINPUT_GAMEPAD)
    h.ds.set_axis(2, 0, -1.0, h.t)
    h.ds.set_axis(2, 3, 1.0, h.t)
    h.ds.set_axis(2, 1, 0.5, h.t)
    h.ds.set_button(2, 1, True, h.t)
    h.ds.set_button(2, 10, True, h.t)
    h.ds.set_pov(2, 0, 90, h.t)
    h.run(0.05)
    joys = h.last_control().joysticks
    assert len(joys) == 3  # up to the last slot in use; the empty ones before it keep the numbers
    assert [j.is_empty for j in joys] == [True, True, False]
    j = joys[2]
    assert j.axes == (-128, 64, 0, 127)  # negative /128, positive /127
    assert j.button_count == 12 and j.pressed(1) and j.pressed(10) and not j.pressed(2)
    assert j.buttons == (1 << 0) | (1 << 9)
    assert j.povs == (90,)
    h.ds.set_button(2, 1, False, h.t)
    h.ds.set_pov(2, 0, -1, h.t)
    h.ds.clear_joystick(2, h.t)
    h.ds.set_joystick(5, 1, 0, 0, h.t)
    h.run(0.05)
    assert [j.is_empty for j in h.last_control().joysticks] == [True] * 5 + [False]
    assert h.ds.sticks.in_use


def test_wpilib_simulator_gets_one_pov_per_stick_and_all_six_slots():
    # PROTOCOL-NOTES "Corrections": WPILib's 2026 simulator reads POV i from povs[2*i] and
    # writes past its array beyond 6 POVs. Its status trace is 0x20 alone: no roboRIO bit.
    robot = FakeRobot()
    robot.is_roborio = False
    h = Harness(make_ds(), robot)
    h.ds.set_joystick(0, 2, 4, 4, h.t)
    h.ds.set_pov(0, 0, 90, h.t)
    h.ds.set_pov(0, 1, 180, h.t)
    h.run(0.2)
    assert h.ds.link.drives_simulator
    joys = h.last_control().joysticks
    assert [j.povs for j in joys] == [(90,)] + [()] * 5  # six slots: it keeps what it is not sent
    said = [text for _, text in h.ds.events.items if "WPILib's simulator" in text]
    assert len(said) == 1 and "POV" in said[0]
    # a roboRIO answering instead gets every POV, and only the slots in use
    robot.is_roborio = True
    h.run(0.1)
    assert not h.ds.link.drives_simulator and h.last_control().joysticks[0].povs == (90, 180, -1, -1)
    assert len(h.last_control().joysticks) == 1


def test_a_presumed_simulator_until_the_robot_says_it_is_a_roborio():
    h = Harness(make_ds(simulator=True))
    h.robot.online = False
    h.ds.set_joystick(0, 0, 0, 3, h.t)
    h.run(0.1)
    assert h.ds.link.drives_simulator and h.robot.received[-1].joysticks[0].povs == (-1,)
    h.robot.online = True
    h.run(0.1)
    assert not h.ds.link.drives_simulator and h.robot.received[-1].joysticks[0].povs == (-1, -1, -1)


@pytest.mark.parametrize("call,reason", [
    (lambda ds: ds.set_joystick(6, 1, 1, 1, 0.0), "joystick slot"),
    (lambda ds: ds.set_joystick(-1, 1, 1, 1, 0.0), "joystick slot"),
    (lambda ds: ds.set_joystick(0, 13, 1, 1, 0.0), "axis count"),
    (lambda ds: ds.set_joystick(0, 1, 33, 1, 0.0), "button count"),
    (lambda ds: ds.set_joystick(0, 1, 1, 13, 0.0), "POV count"),
    (lambda ds: ds.set_joystick(0, 2, 1, 1, 0.0, axis_types=[0]), "axis types"),
    (lambda ds: ds.set_joystick(0, 1, 1, 1, 0.0, axis_types=[300]), "axis type"),
    (lambda ds: ds.set_joystick(0, 1, 1, 1, 0.0, name="n" * 300), "name"),
    (lambda ds: ds.set_joystick(0, 1, 1, 1, 0.0, joystick_type=200), "joystick type"),
    (lambda ds: ds.set_axis(1, 0, 0.5, 0.0), "no joystick in slot 1"),
    (lambda ds: ds.set_axis(0, 2, 0.5, 0.0), "axis"),
    (lambda ds: ds.set_axis(0, 0, 1.5, 0.0), "-1.0..1.0"),
    (lambda ds: ds.set_axis(0, 0, float("nan"), 0.0), "-1.0..1.0"),
    (lambda ds: ds.set_axis(0, 0, "0.5", 0.0), "-1.0..1.0"),
    (lambda ds: ds.set_axis(0, True, 0.5, 0.0), "axis"),
    (lambda ds: ds.set_button(0, 0, True, 0.0), "button"),
    (lambda ds: ds.set_button(0, 3, True, 0.0), "button"),
    (lambda ds: ds.set_button(0, 1, 2, 0.0), "pressed"),
    (lambda ds: ds.set_pov(0, 1, 90, 0.0), "POV"),
    (lambda ds: ds.set_pov(0, 0, 360, 0.0), "POV angle"),
    (lambda ds: ds.set_pov(0, 0, -2, 0.0), "POV angle"),
    (lambda ds: ds.set_pov(0, 0, 45.0, 0.0), "POV angle"),
    (lambda ds: ds.clear_joystick(9, 0.0), "joystick slot"),
])
def test_bad_joystick_commands_say_why_and_change_nothing(call, reason):
    ds = make_ds()
    ds.set_joystick(0, 2, 2, 1, 0.0)
    ds.sticks.take_descriptors()
    before = (repr(ds.sticks.slots), ds.sticks.tags(simulator=True))
    with pytest.raises(CommandError, match=reason):
        call(ds)
    assert (repr(ds.sticks.slots), ds.sticks.tags(simulator=True)) == before
    assert not ds.sticks.descriptors_dirty


def test_slot_without_axes_buttons_or_povs_says_so():
    ds = make_ds()
    ds.set_joystick(0, 0, 0, 0, 0.0)
    for call in (lambda: ds.set_axis(0, 0, 0.0, 0.0), lambda: ds.set_button(0, 1, True, 0.0),
                 lambda: ds.set_pov(0, 0, 0, 0.0)):
        with pytest.raises(CommandError, match="has no"):
            call()


def test_descriptors_on_connect_and_resent_on_every_change():
    h = Harness(make_ds())
    h.ds.set_joystick(1, 2, 10, 1, h.t, name="Stick", joystick_type=JoystickType.HID_JOYSTICK,
                      axis_types=[0, 1])
    h.run(0.1)
    frames = h.tcp_frames()
    # on connect, as a real NI DS: six descriptors, then match info and game data, empty
    # here (00 06 07 00 00 0000 00 and 00 01 0e, the 2021 capture, stream from frame 2695)
    assert frames[6:] == [bytes.fromhex("0006 07 00 00 0000 00"), bytes.fromhex("0001 0e")]
    frames = frames[:6]
    descriptors = [ds_to_rio.decode_tcp(f) for f in frames]
    assert [d.index for d in descriptors] == [0, 1, 2, 3, 4, 5]  # empty slots included
    assert descriptors[1] == JoystickDescriptor(1, False, JoystickType.HID_JOYSTICK, "Stick", (0, 1), 10, 1)
    assert descriptors[0] == JoystickDescriptor(0, False, JoystickType.UNKNOWN, "", (), 0, 0)
    # values are not descriptor changes
    h.ds.set_axis(1, 0, 0.3, h.t)
    h.run(0.1)
    assert len(h.tcp_frames()) == 8
    # a new joystick and a removal: resent, all six, once per poll however many changes
    h.ds.set_joystick(4, 1, 1, 0, h.t, name="Wheel")
    h.ds.clear_joystick(1, h.t)
    h.run(0.1)
    again = [ds_to_rio.decode_tcp(f) for f in h.tcp_frames()[8:]]
    assert [d.index for d in again] == [0, 1, 2, 3, 4, 5]
    assert again[1].name == "" and again[4].name == "Wheel"
    h.ds.clear_joystick(3, h.t)  # already empty: no change, nothing resent
    h.run(0.1)
    assert len(h.tcp_frames()) == 14


def test_game_data_and_match_info_follow_descriptors_on_connect():
    h = Harness(make_ds())
    h.tcp_up["robot-tcp"] = False
    h.run(0.1)
    h.ds.set_game_data("LRL", h.t)
    h.ds.tcp.set_match_info(ds_to_rio.MatchInfo("WCBC", MatchType.QUALIFICATION, 18, 1))
    h.tcp_up["robot-tcp"] = True
    h.run(1.1)
    msgs = [ds_to_rio.decode_tcp(f) for f in h.tcp_frames()]
    assert [type(m).__name__ for m in msgs] == ["JoystickDescriptor"] * 6 + ["MatchInfo", "GameData"]
    assert msgs[6].encode() == bytes.fromhex("000a 07 04") + b"WCBC" + bytes.fromhex("02 0012 01")
    assert msgs[7] == ds_to_rio.GameData("LRL")
    h.ds.set_game_data("RRR", h.t)
    h.run(0.05)
    assert ds_to_rio.decode_tcp(h.tcp_frames()[-1]) == ds_to_rio.GameData("RRR")
    with pytest.raises(CommandError):
        h.ds.set_game_data("x" * 300, h.t)


def test_robot_tcp_is_retried_every_second_while_closed():
    h = Harness(make_ds())
    h.tcp_up["robot-tcp"] = False
    h.run(3.5)
    times = [t for t, c in h.connects if c == "robot-tcp"]
    assert len(times) == 4
    assert [round(b - a, 3) for a, b in zip(times, times[1:])] == [1.0, 1.0, 1.0]
    h.tcp_up["robot-tcp"] = True
    h.run(1.0)
    assert h.ds.tcp.state == "open" and h.ds.stats["robot-tcp"].connected
    n = len(h.connects)
    h.run(3.0)
    assert len(h.connects) == n  # no reconnects while open
    h.open.discard("robot-tcp")
    h.handle(h.ds.stream_closed("robot-tcp", "peer closed", h.t))
    h.run(1.05)
    assert len(h.connects) == n + 1


def test_robot_address_setter_reconnects_to_the_new_robot():
    h = connected()
    new_tcp = ("127.0.0.9", 1740)
    h.ds.set_robot_addresses(h.t, robot_udp=("127.0.0.9", 1110), robot_tcp=new_tcp)
    h.run(0.1)
    assert any(isinstance(c, Close) for c in h.closes)
    assert h.connects[-1][1] == "robot-tcp"
    assert h.ds.tcp.address == new_tcp
    assert h.robot.dests[-1] == ("127.0.0.9", 1110)
    assert h.ds.link.robot_udp_fms == ("127.0.0.9", 1115)
    h.ds.set_robot_addresses(h.t, robot_udp=("127.0.0.1", 40000))
    assert h.ds.link.robot_udp_fms == ("127.0.0.1", 40000)  # ephemeral port: no 1115 to guess


# -- robot TCP frames --------------------------------------------------------------------------
def test_robot_tcp_frames_are_decoded_and_kept():
    h = connected()
    frames = [
        rio_to_ds.StdoutMessage(1.5, 1, "Robot program starting\n").encode(),
        rio_to_ds.ErrorMessage(2.0, 2, 1, -44, True, False, "CAN timeout", "frc.Robot", "at Robot.java:12").encode(),
        rio_to_ds.ErrorMessage(2.5, 3, 1, 0, False, False, "Loop overrun", "", "").encode(),
        rio_to_ds.VersionInfo(rio_to_ds.DeviceType.SOFTWARE, 0, 0, "FRC_Lib_Version", "2024.3.2").encode(),
        rio_to_ds.END_OF_VERSION_LIST.encode(),
        rio_to_ds.DisableFaults(3, 7).encode(),
        rio_to_ds.RailFaults(1, 2, 4).encode(),
        rio_to_ds.UsageReport(254, 0, b"\x01\x02").encode(),
        rio_to_ds.RadioEvents("Warning <Code> 44008").encode(),
        rio_to_ds.Unknown0d(bytes.fromhex("00 00 04 04 04 04")).encode(),
        b"\x00\x00",  # keep-alive
    ]
    stream = b"".join(frames)
    for i in range(len(stream)):  # any chunking: one byte at a time
        h.handle(h.ds.stream_data("robot-tcp", stream[i:i + 1], h.t))
    levels = [(lvl, text) for _, lvl, text in h.ds.tcp.console]
    assert levels == [("stdout", "Robot program starting"), ("error", "[-44] CAN timeout (frc.Robot)"),
                      ("warning", "Loop overrun"), ("radio", "Warning <Code> 44008")]
    assert h.ds.tcp.console_total == 4
    assert h.ds.tcp.versions == {"FRC_Lib_Version": "2024.3.2"}
    assert h.ds.tcp.faults == {"comms": 3, "12v": 7, "6v": 1, "5v": 2, "3.3v": 4}
    assert h.ds.tcp.usage_reports == 1 and h.ds.tcp.unknown_frames == 1
    assert h.ds.stats["robot-tcp"].packets_in == len(frames)
    assert h.ds.stats["robot-tcp"].bad_packets == 0


def test_console_and_versions_are_bounded():
    h = connected()
    ds = h.ds
    for i in range(2500):
        h.rio_tcp(rio_to_ds.StdoutMessage(0.0, i & 0xFFFF, "x" * 5000 if i == 2499 else f"line {i}").encode())
    assert len(ds.tcp.console) == 2000 and ds.tcp.console_total == 2500
    assert len(ds.tcp.console[-1][2]) <= 4097
    for i in range(100):
        h.rio_tcp(rio_to_ds.VersionInfo(0, 0, 0, f"dev{i}", "1").encode())
    assert len(ds.tcp.versions) == 64


def test_a_bad_frame_content_is_counted_and_dropped_the_connection_stays():
    h = connected()
    bad = bytes.fromhex("0003 04 0001")  # disable faults needs 4 bytes, has 2
    h.rio_tcp(bad, rio_to_ds.StdoutMessage(0.0, 1, "after").encode())
    assert h.ds.stats["robot-tcp"].bad_packets == 1
    assert h.ds.tcp.faults["comms"] == 0
    assert h.ds.tcp.console[-1][2] == "after"
    assert h.ds.tcp.state == "open"


def test_a_framing_error_closes_only_the_robot_tcp_connection():
    h = connected()
    h.rio_tcp(bytes.fromhex("ffff 0c"))  # a frame over the 32 KiB bound
    assert h.ds.stats["robot-tcp"].bad_packets == 1
    assert [c.conn for c in h.closes] == ["robot-tcp"]
    assert h.ds.tcp.state == "closed"
    assert h.ds.link.robot_comms  # nothing else noticed
    h.run(1.1)
    assert h.ds.tcp.state == "open"  # reconnected, with a fresh frame decoder
    h.rio_tcp(rio_to_ds.StdoutMessage(0.0, 1, "fresh").encode())
    assert h.ds.tcp.console[-1][2] == "fresh"


# -- robot status ------------------------------------------------------------------------------
def test_every_status_tag_is_decoded_and_kept():
    h = connected()
    pdp = rio_to_ds.PdpLog(tuple(range(16)))
    h.robot.tags = (rio_to_ds.JoystickOutput(0b101, 0xFFFF, 0x1234), rio_to_ds.IDLE_JOYSTICK_OUTPUT,
                    rio_to_ds.DiskInfo(1_000_000), rio_to_ds.CpuInfo((rio_to_ds.CpuLoad(1.0, 2.0, 3.0, 4.0),) * 2),
                    rio_to_ds.RamInfo(0, 5_000_000), pdp, rio_to_ds.Unknown09(),
                    rio_to_ds.CanMetrics(42.5, 1, 2, 3, 4)) + (rio_to_ds.IDLE_JOYSTICK_OUTPUT,) * 6
    h.robot.battery = 11.75
    h.run(0.1)
    ds = h.ds
    assert ds.link.battery == 11.75 and ds.telemetry.battery_history[-1][1] == 11.75
    assert ds.sticks.outputs[0] == rio_to_ds.JoystickOutput(0b101, 0xFFFF, 0x1234)
    assert ds.sticks.outputs[0].output(1) and ds.sticks.outputs[0].output(3)
    assert ds.sticks.outputs[1].idle
    assert len(ds.sticks.outputs) == 6  # a 7th and 8th output tag overwrite nothing
    assert ds.telemetry.disk.free_bytes == 1_000_000 and ds.telemetry.ram.free_bytes == 5_000_000
    assert len(ds.telemetry.cpu.cpus) == 2 and ds.telemetry.pdp == pdp and ds.telemetry.can.utilization == 42.5
    assert ds.link.program_mode == "disabled"
    h.robot.brownout = True
    h.run(0.1)
    assert ds.telemetry.brownout and ds.telemetry.brownouts == 1
    h.robot.brownout = False
    h.run(0.1)
    h.robot.brownout = True
    h.run(0.1)
    assert ds.telemetry.brownouts == 2
    snap = ds.snapshot()
    assert snap["brownout"] and snap["battery"] == 11.75


def test_trip_time_and_lost_packets():
    h = Harness(make_ds(), latency=0.005)
    h.run(2.0)
    assert h.ds.trip_ms == pytest.approx(5.0)
    assert h.ds.link.echoes.lost_packets == 0
    h.robot.drop_every = 10
    before = h.ds.link.echoes.sent_packets
    h.run(4.0)
    sent = h.ds.link.echoes.sent_packets - before
    h.robot.drop_every = 0
    h.run(1.1)  # let the last echoes time out
    assert h.ds.link.echoes.lost_packets == pytest.approx(sent / 10, abs=2)
    assert h.ds.stats["ds->rio"].lost_packets == h.ds.link.echoes.lost_packets
    # packets sent to a robot that is not there are not "lost": only the last second's are
    h.robot.online = False
    lost = h.ds.link.echoes.lost_packets
    h.run(10.0)
    assert lost < h.ds.link.echoes.lost_packets <= lost + 1.0 / PERIOD + 1


def test_stale_and_duplicated_echoes_are_counted_not_timed():
    h = connected()
    dup = StatusPacket(0, robot_code=True, battery=12.0).encode()  # sequence 0 was echoed long ago
    h.handle(h.ds.datagram("robot", dup, (ROBOT_HOST, 1110), h.t))
    assert h.ds.link.echoes.stale_echoes == 1


# -- whose status is taken ---------------------------------------------------------------------
def test_status_from_another_address_is_counted_foreign_and_dropped():
    h = connected()
    h.robot.online = False  # the robot is gone; someone else keeps "answering"
    spoof = StatusPacket(0, robot_code=True, battery=13.0).encode()
    for k in range(60):
        h.run(0.02)
        h.handle(h.ds.datagram("robot", spoof, ("127.0.0.9", 1110), h.t))
        h.handle(h.ds.datagram("robot", spoof, ("127.2.54.3", 1110), h.t))  # the robot's neighbour
    assert not h.ds.link.robot_comms and h.ds.link.battery is None
    assert h.ds.link.foreign_packets == 120 and h.ds.stats["rio->ds"].foreign_packets == 120
    assert h.ds.stats["rio->ds"].bad_packets == 0 and h.ds.link.robot_source is None
    # the robot itself is heard again, from any port of its host
    h.robot.online = True
    h.run(0.1)
    h.handle(h.ds.datagram("robot", spoof, (ROBOT_HOST, 1115), h.t))
    assert h.ds.link.robot_comms and h.ds.link.robot_source == ROBOT_HOST and h.ds.link.foreign_packets == 120


def test_a_flood_on_the_robot_port_is_judged_by_its_source_before_its_bytes():
    # Issue 27: from anywhere but the robot's host a datagram is counted as foreign as it
    # stands, never decoded (64 KB of zeros or not); from the robot's host, any port (a real
    # roboRIO sends from ephemeral ports), one over the size bound is counted bad, and the
    # robot's own status keeps the link up.
    h = connected()
    flood = [bytes(65507), b"\xff" * 65507, b"\x01", StatusPacket(0, estop=True).encode()]
    for data in flood:
        h.handle(h.ds.datagram("robot", data, ("127.9.9.9", 1110), h.t))
    link = h.ds.stats["rio->ds"]
    assert h.ds.link.foreign_packets == link.foreign_packets == len(flood) and link.bad_packets == 0
    said = [text for _, text in h.ds.events.items if "robot status from 127.9.9.9" in text]
    assert said == [f"robot status from 127.9.9.9:1110 ignored: the robot is {ROBOT_HOST}"]  # once a second
    h.handle(h.ds.datagram("robot", bytes(65507), (ROBOT_HOST, 47926), h.t))
    assert link.bad_packets == 1 and "over the 1024-byte bound" in link.last_error
    h.run(0.5)
    assert h.ds.link.robot_comms and not h.ds.link.robot_estopped and h.ds.link.foreign_packets == len(flood)


def test_status_from_an_ipv4_mapped_ipv6_address_of_the_robot_is_taken():
    h = connected()
    before = h.ds.stats["rio->ds"].packets_in
    h.handle(h.ds.datagram("robot", StatusPacket(0).encode(), (f"::ffff:{ROBOT_HOST}", 1110, 0, 0), h.t))
    assert h.ds.stats["rio->ds"].packets_in == before + 1 and h.ds.link.foreign_packets == 0


def test_a_robot_found_by_name_is_the_first_address_that_answers_until_comms_are_lost():
    ds = DriverStation(254, ("roboRIO-254-FRC.local", 1110), ("roboRIO-254-FRC.local", 1740))
    status = StatusPacket(0, robot_code=True, battery=12.0).encode()
    ds.poll(0.0)
    ds.datagram("robot", status, ("10.2.54.2", 1110), 0.01)
    assert ds.link.robot_comms and ds.link.robot_source == "10.2.54.2"
    ds.datagram("robot", status, ("10.2.54.66", 1110), 0.02)
    assert ds.link.foreign_packets == 1
    ds.poll(1.02)
    assert not ds.link.robot_comms and ds.link.robot_source is None
    ds.datagram("robot", status, ("10.2.54.66", 1110), 1.03)  # a new robot by that name
    assert ds.link.robot_comms and ds.link.robot_source == "10.2.54.66" and ds.link.foreign_packets == 1


# -- commands and state ------------------------------------------------------------------------
def test_mode_station_and_team_commands():
    h = connected()
    ds = h.ds
    ds.set_mode("auto", h.t)
    assert ds.mode == Mode.AUTONOMOUS
    with pytest.raises(CommandError, match="unknown mode"):
        ds.set_mode("dance", h.t)
    with pytest.raises(CommandError):
        ds.set_mode(Mode.RESERVED, h.t)
    ds.set_station("B2", h.t)
    ds.set_station(AllianceStation.RED3, h.t)
    with pytest.raises(CommandError):
        ds.set_station("G7", h.t)
    h.run(0.05)
    assert h.last_control().station == AllianceStation.RED3
    ds.enable(h.t)
    with pytest.raises(CommandError, match="disable"):
        ds.set_mode(Mode.TELEOP, h.t)
    with pytest.raises(CommandError, match="disable"):
        ds.set_team(1114, h.t)
    ds.disable(h.t)
    ds.set_team(1114, h.t)
    assert ds.team == 1114
    for bad in (0, 25600, "254", True):
        with pytest.raises(CommandError):
            ds.set_team(bad, h.t)
    assert ds.team == 1114


def test_snapshot_is_json_and_has_the_panel_fields():
    h = connected()
    h.ds.set_joystick(0, 1, 1, 0, h.t)
    h.run(0.1)
    snap = h.ds.snapshot()
    json.dumps(snap)
    for key in ("team", "station", "mode", "enabled", "estopped", "robot_comms", "robot_code",
                "joysticks_ok", "battery", "brownout", "trip_ms", "lost_packets", "sent_packets",
                "fms_attached", "fms_status"):
        assert key in snap
    assert snap["station"] == "R1" and snap["mode"] == "teleop" and snap["joysticks_ok"]
    assert snap["fms_status"] == "off" and snap["robot_tcp"]


def test_unexpected_connections_and_channels_are_ignored():
    ds = make_ds()
    assert ds.stream_opened(("x", 1), ("1.2.3.4", 5), 1.0) == [Close(("x", 1), "the Driver Station accepts no connections")]
    assert ds.datagram("nonsense", b"abc", ("1.2.3.4", 5), 1.0) == []
    assert ds.stream_data("nonsense", b"abc", 1.0) == []
    assert ds.stream_closed("nonsense", "x", 1.0) == []


def test_the_robot_codec_is_chosen_in_one_place():
    assert robot_codec().name == "2015+"
    assert robot_codec(True).name == "2010"
    assert make_ds(legacy=True)._codec.name == "2010"


# -- bad input ---------------------------------------------------------------------------------
def _state(ds: DriverStation):
    snap = ds.snapshot()
    snap.pop("bad_packets")
    return (snap, ds.link.status, list(ds.tcp.console), dict(ds.tcp.versions), ds.tcp.usage_reports, ds.tcp.unknown_frames,
            list(ds.sticks.outputs), ds.link._last_status, ds.link.echoes.stale_echoes, ds.tcp.state)


def _bad_status(data: bytes) -> bool:
    try:
        rio_to_ds.decode_status(data)
    except ProtocolError:
        return True
    return False


@given(st.binary(max_size=80))
def test_random_bytes_on_the_robot_channel_are_counted_and_change_nothing(data):
    assume(_bad_status(data))
    h = connected(0.1)
    before, bad = _state(h.ds), h.ds.stats["rio->ds"].bad_packets
    h.handle(h.ds.datagram("robot", data, (ROBOT_HOST, 1110), h.t))
    assert _state(h.ds) == before
    assert h.ds.stats["rio->ds"].bad_packets == bad + 1


def _bad_rio_frame(frame: bytes) -> bool:
    try:
        rio_to_ds.decode_tcp(frame)
    except ProtocolError:
        return True
    return False


@given(st.sampled_from([0x00, 0x01, 0x04, 0x05, 0x0A, 0x0B, 0x0C, 0x0D, 0x42]), st.binary(max_size=40))
def test_undecodable_robot_tcp_frames_are_counted_and_change_nothing(tag, payload):
    frame = (len(payload) + 1).to_bytes(2, "big") + bytes((tag,)) + payload
    assume(_bad_rio_frame(frame))
    h = connected(0.1)
    before, bad = _state(h.ds), h.ds.stats["robot-tcp"].bad_packets
    h.rio_tcp(frame)
    assert _state(h.ds) == before
    assert h.ds.stats["robot-tcp"].bad_packets == bad + 1


@given(st.binary(min_size=1, max_size=200))
def test_any_robot_tcp_bytes_never_raise(data):
    h = connected(0.1)
    h.rio_tcp(data)
    assert h.ds.link.robot_comms
