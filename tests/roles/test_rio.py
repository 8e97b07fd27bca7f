"""The fake roboRIO core on a fake clock: real encoded DS packets in, decoded replies out."""

from __future__ import annotations

import json
from collections import defaultdict

import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from protocol import ds_to_rio, rio_to_ds
from protocol.ds_to_rio import (ControlPacket, Countdown, Date, GameData, Joystick, JoystickDescriptor,
                                MatchInfo, Timezone)
from protocol.enums import MatchType, Mode
from protocol.errors import ProtocolError
from protocol.framing import FrameDecoder
from protocol.rio_to_ds import (CanMetrics, CpuInfo, DisableFaults, DiskInfo, ErrorMessage, PdpLog,
                                RailFaults, RamInfo, StdoutMessage, UsageReport, VersionInfo)
from roles.cores.battery import Battery
from roles.cores.core import Close, CommandError, Datagram, StreamSend
from roles.cores.rio import (BEAT, CODE_NONE, CODE_REBOOTING, CODE_RUNNING, CODE_STARTING, Rio, RioConfig,
                             RioWire, wire_for)
from roles.cores.rio_program import (CallProgram, CheckProgram, Ended, Loaded, Loading, Message, ProgramOutputs,
                                     Result, StartProgram, StopProgram)
from roles.runtime.program_host import CodeHost

DS = ("127.0.0.5", 50123)
OTHER_DS = ("127.0.0.6", 50999)

# A control packet our DS probe sent to WPILib's simulated roboRIO
# (/work/interop/captures/probe_run.json, phase "enabled_teleop", "sent_example"):
# sequence 0x00e0, comm 0x01, control 0x04 (enabled, teleop), request 0x10, station R1,
# one joystick: 3 axes 7f 80 00, 12 buttons 0x0101 (buttons 1 and 9), 1 POV 0x005a (90).
ENABLED_TELEOP_HEX = "00e0010410000b0c037f80000c010101005a"


def packet(seq=1, *, enabled=False, mode=Mode.TELEOP, estop=False, restart=False, reboot=False,
           tags=(), fms=False) -> bytes:
    return ControlPacket(sequence=seq, estop=estop, enabled=enabled, mode=mode, restart_code=restart,
                         reboot_roborio=reboot, fms_attached=fms, tags=tuple(tags)).encode()


class Bench:
    """A fake clock, a Rio and everything it sent, decoded."""

    def __init__(self, **kwargs) -> None:
        self.now = kwargs.pop("now", 0.0)
        self.code = kwargs.pop("host", None) or CodeHost()  # runs the program inline, as a fake-clock field does
        self.rio = Rio(RioConfig(**kwargs), self.code, now=self.now)
        self.replies: list[Datagram] = []
        self.tcp: dict = defaultdict(list)  # conn -> decoded frames
        self.closed: dict = {}
        self.seq = 0

    def take(self, actions) -> list:
        for a in actions:
            if isinstance(a, Datagram):
                self.replies.append(a)
            elif isinstance(a, StreamSend):
                for frame in FrameDecoder().feed(a.data):
                    self.tcp[a.conn].append(rio_to_ds.decode_tcp(frame))
            elif isinstance(a, Close):
                self.closed[a.conn] = a.reason
        return actions

    def run_until(self, t: float) -> None:
        """Poll at every deadline up to ``t``, then at ``t``."""
        for _ in range(1_000_000):
            deadline = self.rio.next_deadline()
            if deadline is None or deadline > t:
                break
            self.now = max(self.now, deadline)
            self.take(self.rio.poll(self.now))
        self.now = t
        self.take(self.rio.poll(t))

    def send(self, data: bytes, *, channel="ds", source=DS):
        """Deliver a datagram now; the decoded reply or None."""
        actions = self.take(self.rio.datagram(channel, data, source, self.now))
        replies = [a for a in actions if isinstance(a, Datagram)]
        assert len(replies) <= 1
        return rio_to_ds.decode_status(replies[0].data) if replies else None

    def drive(self, seconds: float, *, source=DS, **kw):
        """A DS at 50 Hz for ``seconds``, polling between packets; the last reply."""
        reply = None
        end = self.now + seconds
        while self.now + BEAT <= end + 1e-9:
            self.run_until(self.now + BEAT)
            self.seq = (self.seq + 1) & 0xFFFF
            reply = self.send(packet(self.seq, **kw), source=source)
        return reply

    def connect(self, conn="c1", host="127.0.0.5"):
        return self.take(self.rio.stream_opened(conn, (host, 40000), self.now))

    def stdout(self, conn="c1") -> list[str]:
        return [f.text for f in self.tcp[conn] if isinstance(f, StdoutMessage)]


def joystick(axes=(), buttons=0, count=0, povs=()) -> Joystick:
    return Joystick(tuple(axes), buttons, count, tuple(povs))


# -- the reply --------------------------------------------------------------------------
def test_reply_to_a_known_control_packet():
    b = Bench()
    b.now = 0.005
    actions = b.rio.datagram("ds", bytes.fromhex(ENABLED_TELEOP_HEX), DS, b.now)
    [reply] = actions
    assert reply.channel == "ds" and reply.dest == ("127.0.0.5", 1150) and reply.kind == "rio-to-ds"
    status = rio_to_ds.decode_status(reply.data)
    assert status.sequence == 0x00E0
    assert status.comm_version == 0x01
    assert status.enabled and status.mode == Mode.TELEOP and not status.estop
    assert status.status_byte == 0x04  # an echo: enabled, teleop
    assert status.robot_code and status.is_roborio
    assert status.trace_byte & 0x30 == 0x30
    assert status.user_disabled  # the program last ran while disabled: the packet had not come yet
    assert status.battery == pytest.approx(12.6, abs=0.2)
    assert status.request_date
    assert status.joystick_outputs == ()  # one slot sent, nothing set yet: no tag, as a real roboRIO
    # after the next 20 ms beat the program ran enabled in teleop: trace bits follow
    b.run_until(0.03)
    status = b.send(bytes.fromhex(ENABLED_TELEOP_HEX))
    assert status.user_teleop and not status.user_disabled
    assert status.trace_byte == 0x20 | 0x10 | 0x02
    assert status.joystick_outputs[0].outputs == 0x0101  # buttons 1 and 9 echoed
    assert status.joystick_outputs[0].left_rumble == 0xFFFF  # button 1
    assert status.joystick_outputs[0].right_rumble == 0  # button 2 is up


def test_trace_mode_bits_follow_the_program():
    b = Bench()
    for mode, attr, bit in ((Mode.TELEOP, "user_teleop", 0x02), (Mode.AUTONOMOUS, "user_auto", 0x04),
                            (Mode.TEST, "user_test", 0x08)):
        status = b.drive(0.1, enabled=True, mode=mode)
        assert getattr(status, attr) and status.trace_byte & 0x0F == bit
        assert status.mode == mode and status.enabled
    status = b.drive(0.1, enabled=False, mode=Mode.TEST)
    assert status.user_disabled and status.trace_byte & 0x0F == 0x01 and not status.enabled


def test_request_date_until_date_and_timezone():
    b = Bench()
    assert b.send(packet(1)).request_date
    date = Date(0, 1, 2, 3, 4, 5, 125)
    assert b.send(packet(2, tags=[date])).request_date  # the date alone is not enough
    assert b.send(packet(3)).request_date
    assert not b.send(packet(4, tags=[Timezone("UTC")])).request_date
    assert not b.send(packet(5)).request_date  # and it stays off
    assert b.rio.inputs.ds_timezone == "UTC" and b.rio.inputs.ds_date.year == 2025


# LibDS (QDriverStation's engine), src/protocols/frc_2015.c: enabled teleop, request 0x80, R1,
# one joystick whose size byte is one more than the 12 bytes that follow (get_joystick_size:
# 2 + 3 + (4 + 1) + (2 + 1) = 13; PROTOCOL-NOTES "Corrections"). The joystick has 4 axes at
# full stick and button 1 down: read right, it would move the robot.
LIBDS_2015 = "0d 0c 04 7f 7f 7f 7f 0c 0001 01 ffff"


def test_a_malformed_joystick_tag_still_enables_and_reads_neutral():
    b = Bench()
    b.drive(0.1)  # code running, DS followed
    for _ in range(10):
        b.run_until(b.now + BEAT)
        b.seq += 1
        status = b.send(ControlPacket(sequence=b.seq, enabled=True).encode()[:6] + bytes.fromhex(LIBDS_2015))
    assert status.enabled and b.rio.control.enabled and b.rio.outputs_enabled
    assert b.rio.faults.malformed_tags == 10
    assert "13 byte(s) said, 12 left" in b.rio.stats["ds->rio"].last_error
    assert b.rio.stats["ds->rio"].bad_packets == 0  # the packets were obeyed, not dropped
    (stick,) = b.rio.inputs.joysticks  # the slot is there, neutral
    assert stick.axes == () and not stick.pressed
    # a malformed tag between good joysticks keeps the slots in order; 01 0c is an empty slot
    tags = [joystick(axes=(10,)), ds_to_rio.BARE_EMPTY_JOYSTICK]
    b.seq += 1
    good = ControlPacket(sequence=b.seq, enabled=True, tags=tuple(tags)).encode()
    b.run_until(b.now + BEAT)
    b.send(good[:6] + bytes.fromhex("04 0c 05 00 00") + good[6:])
    assert [j.axes for j in b.rio.inputs.joysticks] == [(), (10 / 127,), ()]
    assert b.rio.faults.malformed_tags == 11 and b.rio.control.enabled


def test_reply_port_none_answers_the_source_port_and_channel_is_kept():
    b = Bench(reply_port=None)
    b.send(packet(7), channel="ds-fms", source=("127.0.0.1", 61234))
    reply = b.replies[-1]
    assert reply.dest == ("127.0.0.1", 61234) and reply.channel == "ds-fms"
    assert rio_to_ds.decode_status(reply.data).sequence == 7


def test_output_tags_only_up_to_the_last_slot_with_something_set():
    # the real 2021 capture: 4,352 status packets with nothing set carried no output tag at all
    # (PROTOCOL-NOTES, "Idle joystick output tags"); an idle 01 01 only keeps a later slot's number
    def third_slot_rumbles(state, robot):
        robot.set_rumble(2, left=1.0)

    b = Bench(extra_tags=False)
    empties = [Joystick()] * 3
    status = b.drive(0.06, tags=empties)
    assert status.tags == () and rio_to_ds.decode_status(b.replies[-1].data).encode()[8:] == b""
    b = Bench(extra_tags=False, program=third_slot_rumbles)
    status = b.drive(0.06, tags=empties)
    assert status.tags[:2] == (rio_to_ds.IDLE_JOYSTICK_OUTPUT,) * 2 and status.tags[2].left_rumble == 0xFFFF
    assert b.replies[-1].data[8:12] == bytes.fromhex("0101" * 2)
    # a seventh joystick tag is not a seventh slot
    b.code.robot.set_rumble(5, left=1.0)
    status = b.drive(0.04, tags=[Joystick()] * 7)
    assert len(status.joystick_outputs) == 6 and len(b.rio.inputs.joysticks) == 6


def test_extra_tags_by_default_and_pdp_rises_when_enabled_with_axes():
    b = Bench()
    status = b.drive(0.1, tags=[joystick(axes=(0, 0))])
    kinds = [type(t) for t in status.tags]
    assert kinds == [DiskInfo, CpuInfo, RamInfo, PdpLog, CanMetrics]
    assert len(status.tags[1].cpus) == 2
    assert sum(status.tags[3].currents) == 0  # disabled: nothing drawn
    idle = b.drive(0.1, enabled=True, tags=[joystick(axes=(0, 0))]).tags[3]
    assert 0 < sum(idle.amps) < 10
    driving = b.drive(0.1, enabled=True, tags=[joystick(axes=(127, -128))]).tags[3]
    assert sum(driving.amps) > 200 and max(driving.amps) == pytest.approx(40.25, abs=0.2)
    assert driving.amps[8] == pytest.approx(0.25)


#: Payload sizes (after the id byte) as open-ds and the NI DS read a status packet's tags:
#: disk and RAM 8 bytes, PDP 25, CAN 14, a joystick output 8 (or 0 when idle); the CPU tag is
#: a u8 count then 16 bytes per CPU (PROTOCOL-NOTES "Corrections"; open-ds crashed on the
#: f32 count fieldbox wrote before).
_REAL_DS_SIZES = {0x04: {8}, 0x06: {8}, 0x08: {25}, 0x0E: {14}, 0x01: {0, 8}}


def _walk_like_a_real_ds(data: bytes) -> list[int]:
    """The ids of a status packet's tags, walked with the layouts a real DS reads (written
    apart from protocol/, so the codec cannot agree with itself by construction)."""
    ids, pos = [], 8
    while pos < len(data):
        size, tag_id = data[pos], data[pos + 1]
        payload = data[pos + 2:pos + 1 + size]
        assert len(payload) == size - 1, f"tag 0x{tag_id:02x} runs past the packet"
        if tag_id == 0x05:
            assert len(payload) == 1 + 16 * payload[0], f"CPU tag: {payload[0]} CPUs in {len(payload)} bytes"
        else:
            assert len(payload) in _REAL_DS_SIZES[tag_id], f"tag 0x{tag_id:02x} with {len(payload)} bytes"
        ids.append(tag_id)
        pos += 1 + size
    return ids


def test_a_real_ds_reads_every_status_tag():
    b = Bench()
    b.drive(0.1, enabled=True, tags=[joystick(axes=(0, 0))])
    assert _walk_like_a_real_ds(b.replies[-1].data)[-5:] == [0x04, 0x05, 0x06, 0x08, 0x0E]


def test_battery_sags_under_load_and_recovers_when_disabled():
    b = Bench(extra_tags=False)
    rest = b.drive(0.5).battery
    assert rest == pytest.approx(12.6 - 0.015 * 2.5, abs=0.01)  # the roboRIO and radio draw a little
    loaded = b.drive(1.0, enabled=True, tags=[joystick(axes=(127, 127, 127, 127))]).battery
    assert 7.0 < loaded < rest - 3.0
    recovered = b.drive(3.0).battery
    assert recovered > loaded + 3.0 and recovered == pytest.approx(12.6, abs=0.1)
    assert not b.rio.brownout


# -- the watchdog -----------------------------------------------------------------------
def test_watchdog_disables_100ms_after_the_last_packet_and_counts_a_comms_fault():
    b = Bench()
    b.connect()
    b.drive(0.2, enabled=True)
    assert b.rio.control.enabled
    last = b.now
    assert b.rio.next_deadline() <= last + 0.100 + 1e-9
    b.run_until(last + 0.099)
    assert b.rio.control.enabled and b.rio.faults.comms == 0
    b.run_until(last + 0.100)
    assert not b.rio.control.enabled and b.rio.control.watchdog_tripped and b.rio.faults.comms == 1
    assert DisableFaults(1, 0) in b.tcp["c1"]
    b.run_until(last + 0.5)
    assert b.rio.faults.comms == 1  # counted once
    # a packet after the timeout with enabled set is the fresh enable
    status = b.send(packet(99, enabled=True))
    assert status.enabled and b.rio.control.enabled and not b.rio.control.watchdog_tripped


def test_watchdog_does_not_count_when_already_disabled_and_is_configurable():
    b = Bench(watchdog=0.250)
    b.drive(0.1)
    last = b.now
    b.run_until(last + 0.249)
    assert not b.rio.control.watchdog_tripped
    b.run_until(last + 0.250)
    assert b.rio.control.watchdog_tripped and b.rio.faults.comms == 0


# -- e-stop, restart, reboot --------------------------------------------------------------
def test_estop_latches_until_restart_code():
    b = Bench(restart_time=1.0)
    b.drive(0.1, enabled=True)
    b.seq = 50
    status = b.send(packet(b.seq, enabled=True, estop=True))
    assert status.estop and not status.enabled and b.rio.control.estopped
    status = b.drive(0.5, enabled=True)  # the DS clears its e-stop bit and enables: no effect
    assert status.estop and not status.enabled
    assert b.rio.control.estopped
    b.seq += 1
    status = b.send(packet(b.seq, enabled=True, restart=True))
    assert not status.estop and status.code_initializing and not status.robot_code and not status.enabled
    b.drive(1.0, enabled=True)
    status = b.drive(0.1, enabled=True)
    assert not status.estop and status.enabled and status.robot_code and not status.code_initializing


def test_restart_code_shows_code_starting_then_running_with_a_fresh_program():
    b = Bench(restart_time=0.5)
    b.connect()
    b.drive(0.1)
    assert b.stdout().count("Robot program started (fieldbox built-in program)\n") == 1
    status = b.send(packet(10, restart=True, enabled=True))
    assert status.status_byte & 0x08 and not status.trace_byte & 0x20 and not status.enabled
    assert b.rio.program.code_state == CODE_STARTING
    b.run_until(b.now + 0.499)
    assert b.rio.program.code_state == CODE_STARTING
    assert b.send(packet(11, restart=True, enabled=True)).code_initializing  # a held bit: no new restart
    b.run_until(b.now + 0.002)
    assert b.rio.program.code_state == CODE_RUNNING
    status = b.drive(0.06, enabled=True)
    assert status.robot_code and not status.code_initializing and status.enabled
    assert b.stdout().count("Robot program started (fieldbox built-in program)\n") == 2
    assert b.rio.program.restart_time == 0.5


def test_reboot_is_silent_then_back_with_fresh_state():
    b = Bench(reboot_time=3.0, restart_time=1.0)
    b.connect("c1")
    b.connect("c2")
    b.send(packet(1, tags=[Date(0, 0, 0, 0, 1, 0, 125), Timezone("UTC")]))
    b.send(packet(2, enabled=True, estop=True))
    b.rio.inject_rail_fault("5v", b.now)
    assert not b.rio.inputs.request_date and b.rio.control.estopped
    b.now += 0.01
    actions = b.take(b.rio.datagram("ds", packet(3, reboot=True), DS, b.now))
    assert not [a for a in actions if isinstance(a, Datagram)]  # no reply
    assert set(b.closed) == {"c1", "c2"} and b.rio.tcp.count == 0
    assert b.rio.program.code_state == CODE_REBOOTING
    start = b.now
    b.run_until(start + 1.0)
    assert b.send(packet(4)) is None
    assert b.rio.stream_opened("c3", None, b.now) == [Close("c3", "the roboRIO is rebooting")]
    b.run_until(start + 2.999)
    assert b.send(packet(5)) is None
    b.run_until(start + 3.0)
    status = b.send(packet(6, enabled=True))
    assert status is not None and status.sequence == 6
    assert status.request_date and not status.estop and status.code_initializing and not status.enabled
    assert b.rio.faults.rail_5v == 0  # counters start again at boot
    b.connect("c4")
    assert "c4" not in b.closed
    b.run_until(start + 4.01)
    status = b.send(packet(7, enabled=True))
    assert status.robot_code and status.enabled


def test_restart_and_reboot_commands():
    b = Bench(reboot_time=2.0, restart_time=0.2)
    b.connect()
    b.rio.restart_code(b.now)
    assert b.rio.program.code_state == CODE_STARTING
    b.run_until(0.25)
    assert b.rio.program.code_state == CODE_RUNNING
    b.rio.reboot(b.now)
    assert b.rio.next_deadline() <= b.now
    b.run_until(b.now)
    assert "c1" in b.closed
    with pytest.raises(CommandError):
        b.rio.reboot(b.now)
    with pytest.raises(CommandError):
        b.rio.restart_code(b.now)
    b.run_until(b.now + 2.3)
    assert b.rio.program.code_state == CODE_RUNNING


# -- one DS at a time -------------------------------------------------------------------------
def test_one_ds_at_a_time():
    b = Bench()
    b.drive(0.1, enabled=True)
    assert b.rio.control.ds_address == DS
    assert b.send(packet(500, estop=True), source=OTHER_DS) is None
    assert b.rio.faults.foreign_packets == 1 and not b.rio.control.estopped
    b.drive(0.5, enabled=True)
    assert b.send(packet(501), source=OTHER_DS) is None
    assert b.rio.faults.foreign_packets == 2
    # the first DS falls silent for a second: the next sender is followed
    b.run_until(b.now + 1.0)
    assert not b.rio.control.ds_connected
    status = b.send(packet(502), source=OTHER_DS)
    assert status.sequence == 502 and b.rio.control.ds_address == OTHER_DS
    assert b.send(packet(3), source=DS) is None


def test_a_ds_that_recreates_its_socket_is_answered_and_obeyed_throughout():
    # Issue 30: LibDS re-creates its socket (a new source port) each time its 1 s watchdog
    # expires. Followed by (IP, port), the robot took the new port for a second DS until the
    # old one timed out: it answered 726 of 2,216 packets and disabled between. A real roboRIO
    # answers the DS's host on UDP 1150 whatever the source port: so does this one.
    b = Bench()
    b.drive(0.2, enabled=True)
    assert b.rio.control.enabled
    before = len(b.rio.events.items)
    answered = 0
    for port in (50124, 61000, 50123, 40001):  # a new socket, its sequence going on
        for _ in range(15):  # 0.3 s from each port
            b.run_until(b.now + BEAT)
            b.seq += 1
            actions = b.take(b.rio.datagram("ds", packet(b.seq, enabled=True), (DS[0], port), b.now))
            [reply] = [a for a in actions if isinstance(a, Datagram)]
            assert reply.dest == (DS[0], 1150)  # where the DS listens, not where it sent from
            status = rio_to_ds.decode_status(reply.data)
            assert status.sequence == b.seq and status.enabled
            answered += 1
        assert b.rio.control.ds_address == (DS[0], port) and b.rio.control.enabled and b.rio.control.ds_connected
    assert answered == 60
    assert b.rio.faults.foreign_packets == 0 and b.rio.faults.comms == 0
    assert b.rio.faults.stale_packets == 0
    texts = [text for _, text in list(b.rio.events.items)[before:]]
    assert f"the DS at {DS[0]} now sends from port 50124 (was {DS[1]})" in texts
    assert not any(text.startswith(("following the DS", "watchdog", "robot disabled")) for text in texts)
    # its e-stop from yet another port is the DS's e-stop: it latches
    b.run_until(b.now + BEAT)
    assert b.send(packet(b.seq + 1, estop=True), source=(DS[0], 33333)).estop
    assert b.rio.control.estopped and not b.rio.control.enabled


def test_a_ds_on_a_new_socket_with_a_new_sequence_waits_for_a_disabled_packet():
    # a DS that re-creates its socket and counts from 0 again is a restarted DS (issue 17):
    # answered every time, taken again once the watchdog trips, enabled only after a disabled packet
    b = Bench()
    b.seq = 5000
    b.drive(0.2, enabled=True)
    new = (DS[0], 40404)
    replies = []
    for seq in range(10):
        b.run_until(b.now + BEAT)
        replies.append(b.send(packet(seq, enabled=True), source=new))
    assert all(r is not None for r in replies) and [r.sequence for r in replies] == list(range(10))
    assert not b.rio.control.enabled and b.rio.faults.foreign_packets == 0
    assert b.rio.faults.stale_packets >= 1  # within the watchdog: older than #5010, not obeyed
    assert b.rio.control.ds_address == new and b.rio.control.last_sequence == 9
    assert b.send(packet(10), source=new) is not None
    b.run_until(b.now + BEAT)
    assert b.send(packet(11, enabled=True), source=new).enabled and b.rio.control.enabled


def test_in_the_ephemeral_plan_the_ds_is_its_port():
    # every role on 127.0.0.1, each answered at its source port: there another port is another DS
    b = Bench(reply_port=None)
    me = ("127.0.0.1", 50001)
    b.drive(0.1, enabled=True, source=me)
    assert b.send(packet(900, estop=True), source=("127.0.0.1", 50002)) is None
    assert b.rio.faults.foreign_packets == 1 and not b.rio.control.estopped
    status = b.drive(0.1, enabled=True, source=me)
    assert status.enabled and b.replies[-1].dest == me


def test_a_flood_from_another_address_is_dropped_before_it_is_decoded():
    # Issue 27: 65 KB of zeros ten times a second froze a field (210 ms a decode). The source
    # is checked first: from anyone but the DS followed, a datagram is counted as foreign as
    # it stands, bad or good, 64 KB or not, and nothing is decoded or answered.
    b = Bench()
    b.drive(0.1, enabled=True)
    flood = [bytes(65507), b"\xff" * 65507, packet(700, estop=True) + bytes(65507 - 6), b"\x00",
             packet(701, estop=True)]
    for data in flood:
        assert b.send(data, source=("127.9.9.9", 1150)) is None
        assert b.send(data, source=("127.0.0.6", DS[1])) is None  # another host, the DS's port
    link = b.rio.stats["ds->rio"]
    assert b.rio.faults.foreign_packets == link.foreign_packets == 2 * len(flood)
    assert link.bad_packets == 0 and not b.rio.control.estopped
    assert b.drive(0.1, enabled=True).enabled


def test_a_datagram_over_the_size_bound_from_the_ds_followed_is_counted_bad_and_changes_nothing():
    b = Bench()
    b.drive(0.1, enabled=True)
    big = packet(b.seq + 1, estop=True) + bytes(65507 - 6)  # an e-stop, but 64 KB: not a real DS's
    assert b.send(big) is None
    link = b.rio.stats["ds->rio"]
    assert link.bad_packets == 1 and "over the 1024-byte bound" in link.last_error
    assert not b.rio.control.estopped and b.rio.control.enabled
    assert b.drive(0.1, enabled=True).enabled  # the next packets are obeyed as before


def test_single_ds_can_be_turned_off():
    b = Bench(single_ds=False)
    assert b.send(packet(1), source=DS).sequence == 1
    assert b.send(packet(2), source=OTHER_DS).sequence == 2
    assert b.rio.faults.foreign_packets == 0


# -- packets out of order ---------------------------------------------------------------------
def test_a_stale_enabled_packet_is_answered_but_not_obeyed():
    b = Bench()
    b.drive(0.2, enabled=True)  # sequences 1..10
    assert b.rio.control.enabled and b.rio.control.last_sequence == 10
    b.run_until(b.now + BEAT)
    assert not b.send(packet(11, enabled=False)).enabled
    # #9 (enabled) was delayed on the way: answered with #9 and the state applied now
    status = b.send(packet(9, enabled=True))
    assert status.sequence == 9 and not status.enabled
    assert not b.rio.control.enabled and not b.rio.control.ds_enabled and b.rio.control.last_sequence == 11
    assert b.rio.faults.stale_packets == 1 and b.rio.stats["ds->rio"].stale_packets == 1
    assert b.rio.stats["ds->rio"].bad_packets == 0
    assert not any(text.startswith("robot enabled") for t, text in b.rio.events.items if t >= b.now)
    # a duplicate is stale too, and so is the mirror of the window (32768 ahead)
    assert b.send(packet(11, enabled=True)).sequence == 11
    assert b.send(packet(11 + 0x8000, enabled=True)).sequence == 11 + 0x8000
    assert b.rio.faults.stale_packets == 3 and not b.rio.control.enabled
    # the next one in order is obeyed
    assert b.send(packet(12, enabled=True)).enabled and b.rio.control.enabled


def test_stale_packets_neither_feed_the_watchdog_nor_act_on_requests():
    b = Bench(restart_time=0.2)
    b.drive(0.1, enabled=True)  # 1..5
    b.run_until(b.now + BEAT)
    b.send(packet(50, enabled=True))
    for k in range(4):  # replays of older packets, the last asking for a restart
        b.run_until(b.now + BEAT)
        b.send(packet(40 + k, enabled=True, restart=k == 3, estop=False))
    b.run_until(b.now + BEAT + 0.001)
    assert b.rio.control.watchdog_tripped and not b.rio.control.enabled and b.rio.faults.comms == 1
    assert b.rio.program.code_state == CODE_RUNNING and b.rio.faults.stale_packets == 4
    # once the watchdog has tripped, the sender is taken again from where it is (a restarted
    # DS), but a replayed enabled packet does not enable the robot: a disabled one must come first
    for k in range(4, 8):
        b.send(packet(40 + k, enabled=True))
        b.run_until(b.now + BEAT)
    assert b.rio.control.last_sequence == 47 and not b.rio.control.enabled and b.rio.control.ds_enabled
    assert b.rio.program.code_state == CODE_RUNNING and b.rio.faults.stale_packets == 4
    b.send(packet(48))
    assert b.send(packet(49, enabled=True)).enabled


def test_the_sequence_wraps_around():
    b = Bench()
    b.seq = 0xFFFD
    b.drive(0.1, enabled=True)  # 0xfffe, 0xffff, 0, 1, 2
    assert b.rio.control.enabled and b.rio.control.last_sequence == 2 and b.rio.faults.stale_packets == 0
    assert b.send(packet(0xFFFF, enabled=False)).sequence == 0xFFFF  # older, across the wrap
    assert b.rio.control.ds_enabled and b.rio.faults.stale_packets == 1


def test_a_restarted_ds_counting_from_zero_is_followed_once_the_watchdog_trips_disabled():
    # issue 17: a DS that restarts (sequence back to 0) is taken again within 100 ms, disabled
    b = Bench()
    b.seq = 5000
    b.drive(0.1, enabled=True)
    b.run_until(b.now + 0.07)
    b.send(packet(0))  # the DS restarted 70 ms after its last packet: within the watchdog
    assert b.rio.control.last_sequence == 5005 and b.rio.faults.stale_packets == 1
    b.run_until(b.now + 0.04)
    assert not b.rio.control.enabled  # the watchdog (100 ms from #5005's arrival)
    assert not b.send(packet(1, enabled=True)).enabled  # taken, but not before a disabled packet
    assert b.rio.control.last_sequence == 1 and b.rio.faults.stale_packets == 1
    b.send(packet(2))
    assert b.send(packet(3, enabled=True)).enabled


def test_a_new_sender_starts_its_own_sequence():
    b = Bench(single_ds=False)
    b.seq = 5000
    b.drive(0.1)
    assert b.send(packet(3, enabled=True), source=OTHER_DS).enabled
    assert b.rio.control.ds_address == OTHER_DS and b.rio.faults.stale_packets == 0


# -- the built-in program and TCP -----------------------------------------------------------
def test_builtin_program_echoes_buttons_in_the_next_reply():
    b = Bench(extra_tags=False)
    b.drive(0.1, enabled=True, tags=[joystick(), joystick(buttons=0b0, count=10)])
    b.run_until(b.now + BEAT)
    status = b.send(packet(6, enabled=True, tags=[Joystick(), joystick(buttons=0b1000000011, count=10)]))
    assert status.joystick_outputs == ()  # the program has not run since the packet came
    b.run_until(b.now + BEAT)
    status = b.send(packet(7, enabled=True, tags=[Joystick(), joystick(buttons=0b1000000011, count=10)]))
    out = status.joystick_outputs[1]
    assert out.outputs == 0b1000000011 and out.output(1) and out.output(2) and out.output(10)
    assert out.left_rumble == 0xFFFF and out.right_rumble == 0xFFFF
    assert status.joystick_outputs[0].idle
    assert b.rio.outputs[1] == 0b1000000011 and b.rio.rumble[1] == (1.0, 1.0)
    b.run_until(b.now + BEAT)
    b.send(packet(8, enabled=True, tags=[Joystick(), joystick(buttons=0b10, count=10)]))
    b.run_until(b.now + BEAT)
    out = b.send(packet(9, enabled=True, tags=[Joystick(), joystick(buttons=0b10, count=10)])).joystick_outputs[1]
    assert out.outputs == 0b10 and out.left_rumble == 0 and out.right_rumble == 0xFFFF


def test_connect_sends_versions_then_faults_then_backlog():
    b = Bench()
    b.run_until(0.1)
    b.connect()
    frames = b.tcp["c1"]
    assert frames[0] == VersionInfo(0, 0, 0, "roboRIO Image", b.rio.tcp.image_version)
    assert frames[1].name == "FRC_Lib_Version"
    assert frames[2].is_end_of_list
    assert frames[3] == DisableFaults(0, 0)
    assert frames[4] == RailFaults(0, 0, 0)
    assert [f.text for f in frames[5:]] == ["Robot program started (fieldbox built-in program)\n",
                                            "Robot disabled\n"]


def test_mode_changes_printed_over_tcp_with_one_shared_sequence():
    calls = []

    def program(state, robot):
        calls.append(state)
        if len(calls) == 3:
            robot.warning("low pressure")
        if len(calls) == 4:
            robot.error("arm stalled", code=-1029)

    b = Bench(program=program)
    b.connect()
    b.drive(0.2, enabled=True, mode=Mode.AUTONOMOUS)
    b.drive(0.1)
    messages = [f for f in b.tcp["c1"] if isinstance(f, (StdoutMessage, ErrorMessage))]
    assert [m.sequence for m in messages] == list(range(len(messages)))
    warning, error = messages
    assert not warning.is_error and warning.details == "low pressure" and warning.location.startswith("test_rio.py:")
    assert error.is_error and error.error_code == -1029

    b = Bench()
    b.connect()
    b.drive(0.2, enabled=True, mode=Mode.AUTONOMOUS)
    b.drive(0.1)
    b.drive(0.1, enabled=True)
    b.send(packet(900, estop=True))
    b.run_until(b.now + 0.05)
    texts = b.stdout()
    assert texts[1:] == ["Robot disabled\n", "Robot enabled in auto\n", "Robot disabled\n",
                         "Robot enabled in teleop\n", "Robot e-stopped\n"]
    seqs = [f.sequence for f in b.tcp["c1"] if isinstance(f, StdoutMessage)]
    assert seqs == list(range(len(seqs)))
    assert [line.text for line in b.rio.tcp.console][-1] == "Robot e-stopped"


def test_joystick_readouts_on_change_rate_limited():
    b = Bench()
    b.connect()
    for k in range(50):  # the stick moves every packet for a second
        b.drive(0.02, tags=[joystick(axes=(k, -k), buttons=k & 1, count=2)])
    readouts = [t for t in b.stdout() if t.startswith("Joystick 0:")]
    assert 2 <= len(readouts) <= 3  # at most one per half second
    b.drive(1.0, tags=[joystick(axes=(49, -49), buttons=1, count=2)])
    settled = [t for t in b.stdout() if t.startswith("Joystick 0:")]
    assert settled[-1] == "Joystick 0: axes +0.39 -0.38 buttons 1\n"  # the latest value, once
    b.drive(1.0, tags=[joystick(axes=(49, -49), buttons=1, count=2)])
    assert [t for t in b.stdout() if t.startswith("Joystick 0:")] == settled


def test_tcp_from_the_ds_is_decoded_and_kept_and_game_data_reaches_the_program():
    seen = []
    b = Bench(program=lambda state, robot: seen.append((state.game_data, state.match_info,
                                                        state.joystick(1).name, state.countdown)))
    b.connect()
    stream = (JoystickDescriptor(1, True, 1, "Xbox Controller", (0, 1), 10, 1).encode()
              + MatchInfo("FIELDBOX", MatchType.QUALIFICATION, 12, 1).encode()
              + GameData("LRL").encode() + b"\x00\x00")
    for i in range(len(stream)):  # one byte at a time
        b.take(b.rio.stream_data("c1", stream[i:i + 1], b.now))
    assert b.rio.inputs.descriptors[1].name == "Xbox Controller"
    assert b.rio.inputs.match_info.match_number == 12 and b.rio.inputs.game_data == "LRL"
    b.send(packet(1, tags=[Joystick(), joystick(axes=(1,)), Countdown(15.0)]))
    b.run_until(b.now + 0.05)
    assert seen[-1] == ("LRL", MatchInfo("FIELDBOX", MatchType.QUALIFICATION, 12, 1), "Xbox Controller", 15.0)
    assert not b.closed


def test_usage_report_now_and_then_and_rail_faults_when_they_change():
    b = Bench(team=254, usage_interval=5.0)
    b.connect()
    b.run_until(12.0)
    reports = [f for f in b.tcp["c1"] if isinstance(f, UsageReport)]
    assert len(reports) == 2 and reports[0].team == 254
    b.rio.inject_rail_fault("3.3V", b.now)
    b.run_until(b.now)
    assert b.tcp["c1"][-1] == RailFaults(0, 0, 1)
    with pytest.raises(CommandError):
        b.rio.inject_rail_fault("9v", b.now)


def test_client_bound_refuses_the_ninth_when_all_eight_are_healthy():
    b = Bench(max_clients=8)
    for i in range(8):
        b.connect(f"c{i}", f"127.0.1.{i}")
        b.take(b.rio.stream_data(f"c{i}", ds_to_rio.KeepAlive().encode(), b.now))  # a valid frame
    assert not b.closed
    assert b.connect("c8", "127.0.1.8") == [Close("c8", "too many clients (8 already connected)")]
    assert b.rio.tcp.count == 8 and b.rio.faults.refused_clients == 1 and b.rio.faults.evicted_clients == 0
    b.take(b.rio.stream_closed("c0", "eof", b.now))
    assert "c9" not in b.closed and b.connect("c9", "127.0.1.9")[-1].conn == "c9"


def test_a_newcomer_evicts_the_oldest_client_that_never_sent_a_valid_frame():
    """Idle and half-sent connections cannot fill the slots and lock a reconnecting DS out."""
    b = Bench(max_clients=8)
    b.connect("ds")
    b.take(b.rio.stream_data("ds", JoystickDescriptor(0, False, 20, "pad", (0, 1), 10, 1).encode(), b.now))
    for i in range(7):  # hostile: idle, or a frame that never ends
        b.run_until(b.now + 0.1)
        b.connect(f"h{i}", f"127.9.9.{i}")
        if i % 2:
            b.take(b.rio.stream_data(f"h{i}", b"\x00\x40\x02", b.now))
    b.run_until(b.now + 0.1)
    actions = b.connect("new-ds")
    assert actions[0] == Close("h0", "evicted to make room for a new client: it never sent a valid frame")
    assert actions[-1].conn == "new-ds" and "new-ds" not in b.closed
    assert b.rio.tcp.count == 8 and b.rio.faults.evicted_clients == 1 and b.rio.faults.refused_clients == 0
    # the next newcomer evicts the next oldest silent one (h1, half a frame), never the DS
    assert b.connect("other", "127.9.9.99")[0].conn == "h1"
    assert "ds" not in b.closed and b.rio.faults.evicted_clients == 2


def test_a_client_silent_for_over_5s_is_evicted_only_when_none_never_spoke():
    b = Bench(max_clients=2)
    keepalive = ds_to_rio.KeepAlive().encode()
    b.connect("a", "127.0.0.1")
    b.take(b.rio.stream_data("a", keepalive, b.now))
    b.run_until(1.0)
    b.connect("b", "127.0.0.2")
    b.take(b.rio.stream_data("b", keepalive, b.now))
    b.run_until(5.5)  # a: silent 5.5 s, b: 4.5 s
    assert b.connect("c", "127.0.0.3")[0] == \
        Close("a", "evicted to make room for a new client: no valid frame for more than 5 s")
    b.take(b.rio.stream_data("c", keepalive, b.now))
    b.run_until(7.0)  # b: silent 6 s, c: 1.5 s (no DS is followed on UDP here)
    assert b.connect("d", "127.0.0.4")[0].conn == "b"
    b.take(b.rio.stream_data("d", keepalive, b.now))
    b.run_until(8.0)  # c: 2.5 s, d: 1 s: both healthy
    assert b.connect("e", "127.0.0.6") == [Close("e", "too many clients (2 already connected)")]
    assert b.rio.faults.evicted_clients == 2 and b.rio.faults.refused_clients == 1


def test_a_silent_client_on_the_followed_ds_host_is_not_evicted():
    b = Bench(max_clients=1)
    b.take(b.rio.stream_opened("ds", DS, b.now))  # the DS's own TCP, from its host
    b.take(b.rio.stream_data("ds", ds_to_rio.KeepAlive().encode(), b.now))
    b.drive(6.0)  # UDP keeps coming from the DS; TCP silent for 6 s
    assert b.connect("other", "127.9.9.9") == [Close("other", "too many clients (1 already connected)")]
    assert "ds" not in b.closed


def test_one_host_holds_at_most_half_the_slots_and_the_ds_host_is_always_served():
    """Issue 17: the DS gets back on TCP 1740 beside a dozen clients from elsewhere, idle or
    sending keep-alives."""
    b = Bench(max_clients=8)
    keepalive = ds_to_rio.KeepAlive().encode()
    b.drive(0.1)  # the DS (127.0.0.5) is followed on UDP
    for i in range(12):  # one stranger host: four slots at most, its own oldest silent one goes
        b.connect(("idle", i), "127.9.9.9")
    assert sum(1 for c in b.rio.tcp.connections if c[0] == "idle") == 4
    assert b.rio.faults.evicted_clients == 8
    for i in range(12):  # a dozen healthy strangers on a dozen hosts: the idle ones go first
        b.connect(("busy", i), f"127.9.8.{i}")
        b.take(b.rio.stream_data(("busy", i), keepalive, b.now))
    assert b.rio.tcp.count == 8 and all(c[0] == "busy" for c in b.rio.tcp.connections)
    assert b.rio.faults.evicted_clients == 12 and b.rio.faults.refused_clients == 4
    b.drive(0.5)
    # The DS's own host is always served: the longest-silent stranger makes room.
    actions = b.connect("ds", DS[0])
    assert isinstance(actions[0], Close) and actions[0].conn[0] == "busy"
    assert "ds" not in b.closed and b.rio.tcp.count == 8
    assert actions[0].reason == "evicted to make room for a new client: the DS at 127.0.0.5 is always served"
    # Refusals and evictions are logged once a second at most.
    logged = [t for _, t in b.rio.events.items if t.startswith("TCP: refused") or t.startswith("TCP: no room")]
    assert len(logged) <= 4


# -- the user's program --------------------------------------------------------------------
def test_user_hook_that_raises_is_reported_counted_then_stops(tmp_path):
    path = tmp_path / "robot.py"
    path.write_text("count = 0\n"
                    "def robot_periodic(state, robot):\n"
                    "    global count\n"
                    "    count += 1\n"
                    "    print('tick', count)\n"
                    "    if state.enabled:\n"
                    "        raise RuntimeError('motor on fire')\n")
    b = Bench(program=path, max_failures=3)
    b.connect()
    b.drive(0.1)
    assert b.rio.faults.program_errors == 0 and "tick 1\n" in b.stdout()
    b.drive(0.1, enabled=True)
    errors = [f for f in b.tcp["c1"] if isinstance(f, ErrorMessage)]
    assert errors[0].details == "Unhandled exception in the robot program: RuntimeError: motor on fire"
    assert errors[0].location == "robot.py:7" and "RuntimeError" in errors[0].call_stack
    assert errors[0].is_error
    assert b.rio.faults.program_errors == 3  # three in a row stop the code
    assert errors[-1].details.startswith("Robot code stopped after 3 consecutive errors")
    assert b.rio.program.code_state == CODE_NONE
    status = b.drive(0.1, enabled=True)
    assert not status.robot_code and not status.enabled and status.trace_byte & 0x2F == 0
    seqs = [f.sequence for f in b.tcp["c1"] if isinstance(f, (StdoutMessage, ErrorMessage))]
    assert seqs == list(range(len(seqs)))
    # restart code: the file is loaded again (count starts over) and runs
    b.seq += 1
    b.send(packet(b.seq, restart=True))
    b.drive(1.1)
    assert b.rio.program.code_state == CODE_RUNNING and b.stdout()[-1].startswith("tick ")
    assert "tick 1\n" in b.stdout()[5:]


def test_errors_inside_the_program_are_only_counted_while_consecutive(tmp_path):
    flaky = []

    def program(state, robot):
        flaky.append(1)
        if len(flaky) % 2:
            raise ValueError("every other call")

    b = Bench(program=program, max_failures=2)
    b.drive(1.0)
    assert b.rio.program.code_state == CODE_RUNNING and b.rio.faults.program_errors >= 20


class ApartHost:
    """A host whose program runs elsewhere (as in a process of its own): it keeps what the core
    asked and answers nothing at once; the test says what the program did."""

    def __init__(self) -> None:
        self.asked: list = []

    def __call__(self, request, now):
        self.asked.append(request)
        return [Loading()] if isinstance(request, StartProgram) else []


def test_the_core_asks_for_each_call_and_takes_what_the_program_did_as_input():
    host = ApartHost()
    b = Bench(host=host, program="robot.py", isolate=True)  # a file the core never opens: the host runs it
    assert [type(r) for r in host.asked] == [CheckProgram, StopProgram, StartProgram]
    assert host.asked[-1].source.path == "robot.py" and b.rio.program.code_state == CODE_STARTING
    b.rio.program_events([Loaded()], 0.001)
    b.connect()
    status = b.drive(0.04, enabled=True, tags=[joystick(buttons=1, count=1)])
    assert b.rio.program.code_state == CODE_RUNNING and status.enabled
    calls = [r for r in host.asked if isinstance(r, CallProgram)]
    assert len(calls) == 1 and calls[0].state.joysticks == ()  # the last call has not returned: no second
    # the program answers, late (took 35 ms: an overrun), with button 1 lit and a line printed
    outputs = ProgramOutputs(outputs=(1, 0, 0, 0, 0, 0))
    b.rio.program_events([Message("stdout", "hello from apart\n"), Result(0.035, outputs, (), None)], b.now)
    status = b.drive(1.1, enabled=True, tags=[joystick(buttons=1, count=1)])
    assert status.joystick_outputs[0].outputs == 1
    assert "hello from apart\n" in b.stdout()
    assert any(f.details.startswith("Loop time of 0.02s overrun: 1 call") for f in b.tcp["c1"]
               if isinstance(f, ErrorMessage))
    assert b.rio.faults.program_overruns == 1
    calls = [r for r in host.asked if isinstance(r, CallProgram)]
    assert len(calls) == 2 and calls[1].state.enabled and calls[1].state.joystick(0).button(1)
    # that second call has not come back for over a second: stuck, and the robot still answers
    assert b.rio.program.code_state == "stuck" and status.robot_code and status.enabled
    # the program's process dies: no code, the robot disables, the DS reads why
    b.rio.program_events([Ended("the robot program's process was killed by SIGKILL")], b.now)
    status = b.drive(0.04, enabled=True)
    assert b.rio.program.code_state == CODE_NONE and not status.robot_code and not status.enabled
    assert any("Robot code ended: the robot program's process was killed by SIGKILL" in f.details
               for f in b.tcp["c1"] if isinstance(f, ErrorMessage))
    assert isinstance(host.asked[-1], StopProgram)


def test_load_program_command_refuses_a_broken_file_and_changes_nothing(tmp_path):
    bad = tmp_path / "bad.py"
    bad.write_text("def robot_periodic(state, robot):\n    return (\n")
    b = Bench()
    with pytest.raises(CommandError, match=r"bad.py, line \d+: SyntaxError"):
        b.rio.load_program(bad, b.now)
    assert b.rio.program.name == "built-in" and b.rio.program.code_state == CODE_RUNNING
    good = tmp_path / "good.py"
    good.write_text("def robot_periodic(state, robot):\n    robot.set_outputs(0, 7)\n")
    b.rio.load_program(good, b.now)
    assert b.rio.program.code_state == CODE_STARTING and b.rio.program.name == "good.py"
    b.send(packet(1, tags=[Joystick()]))
    b.run_until(1.1)
    assert b.send(packet(2, tags=[Joystick()])).joystick_outputs[0].outputs == 7
    # the file breaks before the next restart: the code does not start, and says why
    good.write_text("raise ImportError('no module named wpilib')\n")
    b.connect()
    b.rio.restart_code(b.now)
    b.run_until(b.now + 1.1)
    assert b.rio.program.code_state == CODE_NONE
    assert "Robot code failed to start" in [f for f in b.tcp["c1"] if isinstance(f, ErrorMessage)][-1].details
    b.rio.use_builtin_program(b.now)
    b.run_until(b.now + 1.1)
    assert b.rio.program.code_state == CODE_RUNNING and b.rio.program.name == "built-in"


def test_program_class_is_instantiated_on_each_start():
    made = []

    class Program:
        def __init__(self):
            made.append(self)

        def __call__(self, state, robot):
            pass

    b = Bench(program=Program, restart_time=0.1)
    b.rio.restart_code(b.now)
    b.run_until(0.2)
    assert len(made) == 2


# -- brownout ---------------------------------------------------------------------------------
def test_brownout_sets_the_bit_disables_outputs_and_counts_a_12v_fault():
    b = Bench()
    b.connect()
    axes = [joystick(axes=(60, 60))]
    status = b.drive(0.1, enabled=True, tags=axes)
    assert sum(_tag(status, PdpLog).currents) > 0 and b.rio.outputs_enabled
    b.rio.set_battery(6.5, b.now)
    status = b.drive(0.04, enabled=True, tags=axes)
    assert status.brownout and status.status_byte & 0x10
    assert status.battery == pytest.approx(6.5, abs=0.01)
    assert sum(_tag(status, PdpLog).currents) == 0 and not b.rio.outputs_enabled
    assert b.rio.faults.rail_12v == 1
    assert DisableFaults(0, 1) in b.tcp["c1"]
    b.rio.set_battery(7.2, b.now)  # above the trigger but not above 7.5 V: still browned out
    assert b.drive(0.04, enabled=True, tags=axes).brownout
    b.rio.set_battery(None, b.now)  # the model again: 12.6 V at rest
    status = b.drive(0.1, enabled=True, tags=axes)
    assert not status.brownout and sum(_tag(status, PdpLog).currents) > 0
    assert b.rio.faults.rail_12v == 1
    with pytest.raises(CommandError):
        b.rio.set_battery(-1, b.now)
    with pytest.raises(CommandError):
        b.rio.set_battery_rest(float("nan"), b.now)


def test_battery_model_alone():
    bat = Battery(12.6, capacity_ah=None)
    assert bat.update(0.0, 0.0) == 12.6
    bat.update(1.0, 200.0)
    assert bat.volts == pytest.approx(12.6 - 0.015 * 200, abs=0.01)
    bat.update(1.02, 0.0)
    assert bat.volts < 12.0  # recovery is slower than sag
    bat.update(5.0, 0.0)
    assert bat.volts == pytest.approx(12.6, abs=0.01)
    bat.update(6.0, 500.0)  # 12.6 - 7.5 = 5.1 V: brownout
    assert bat.brownout and bat.brownouts == 1
    bat.update(10.0, 0.0)
    assert not bat.brownout and bat.brownouts == 1
    bat.set_voltage(11.9)
    assert bat.update(11.0, 0.0) == pytest.approx(11.9)
    noisy = Battery(12.0, noise=0.05, seed=7)
    again = Battery(12.0, noise=0.05, seed=7)
    a = [noisy.update(t * 0.02, 10.0) for t in range(50)]
    assert a == [again.update(t * 0.02, 10.0) for t in range(50)] and len(set(a)) > 40
    drained = Battery(12.6, capacity_ah=1.0, resistance=0.0)
    drained.update(0.0, 60.0)
    drained.update(60.0, 60.0)  # 1 Ah used: the whole capacity
    assert drained.volts == pytest.approx(12.6 - 1.2, abs=0.01)
    with pytest.raises(ValueError):
        Battery(30.0)


# -- time -----------------------------------------------------------------------------------
def test_beats_are_drift_free_and_late_polls_skip_and_count():
    ran = []
    b = Bench(program=lambda state, robot: ran.append(state.time))
    b.run_until(0.1)
    assert ran == pytest.approx([0.0, 0.02, 0.04, 0.06, 0.08, 0.10])
    b.take(b.rio.poll(0.175))  # slots 0.12, 0.14 and 0.16 are due: one run, two skipped
    assert len(ran) == 7 and b.rio.faults.missed_beats == 2
    assert b.rio.next_deadline() == pytest.approx(0.18)


def test_lazy_start_when_no_now_given():
    rio = Rio(RioConfig(), CodeHost())
    assert rio.next_deadline() == 0.0
    rio.poll(100.0)
    assert rio.program.code_state == CODE_RUNNING and rio.next_deadline() == pytest.approx(100.02)


def test_a_whole_match_takes_milliseconds():
    b = Bench(extra_tags=True)
    b.connect()
    b.drive(15.0, enabled=True, mode=Mode.AUTONOMOUS, tags=[joystick(axes=(20, 0, 0, 0, 0, 0), count=10)])
    b.drive(135.0, enabled=True, tags=[joystick(axes=(20, 0, 0, 0, 0, 0), count=10)])
    assert b.rio.control.enabled and b.rio.faults.missed_beats == 0 and b.rio.faults.comms == 0
    assert len(b.replies) == 7500  # (the time it takes is benchmarks/codec.py's to print, not a test's)


# -- state for panels ---------------------------------------------------------------------
def test_snapshot_is_json():
    b = Bench()
    b.connect()
    b.drive(0.2, enabled=True, tags=[joystick(axes=(5,), buttons=1, count=1, povs=(90,))])
    snap = b.rio.snapshot()
    json.dumps(snap, allow_nan=False)
    assert snap["enabled"] and snap["code_state"] == "running" and snap["mode"] == "teleop"
    assert snap["ds_address"] == list(DS) and snap["tcp_clients"] == 1
    assert snap["outputs"][0] == {"outputs": 1, "left_rumble": 1.0, "right_rumble": 0.0}
    assert snap["joysticks"][0]["povs"] == [90] and snap["stats"]["ds->rio"]["packets_in"] == 10
    assert snap["console"][-1]["kind"] == "stdout"
    assert any("enabled in teleop" in e["text"] for e in snap["events"])


def test_the_wire_is_chosen_in_one_place():
    assert isinstance(wire_for("2015"), RioWire)
    assert wire_for("2010").name == "2010"
    with pytest.raises(ValueError):
        Rio(RioConfig(wire="1999"), CodeHost())


# -- bad input ------------------------------------------------------------------------------
def _state(rio: Rio) -> dict:
    snap = rio.snapshot()
    for key in ("stats", "events"):
        snap.pop(key)
    return snap


@settings(max_examples=200)
@given(data=st.binary(max_size=80), channel=st.sampled_from(["ds", "ds-fms"]))
def test_bad_datagrams_are_counted_with_no_state_change(data, channel):
    try:
        ds_to_rio.decode_control(data)
        assume(False)
    except ProtocolError:
        pass
    b = Bench()
    b.drive(0.1, enabled=True, tags=[joystick(axes=(3,))])
    before = _state(b.rio)
    bad = b.rio.stats["ds->rio"].bad_packets
    assert b.rio.datagram(channel, data, DS, b.now) == []
    assert b.rio.stats["ds->rio"].bad_packets == bad + 1
    assert _state(b.rio) == before


def test_bad_datagram_examples_and_unknown_channel():
    b = Bench()
    b.drive(0.06, enabled=True)
    before = _state(b.rio)
    for data in (b"", b"\x00", b"\x00\x01\x01\x04\x10\x09"):  # short headers, station 9
        for channel in ("ds", "ds-fms"):
            assert b.rio.datagram(channel, data, DS, b.now) == []
    assert b.rio.datagram("bogus", packet(1), DS, b.now) == []
    assert b.rio.stats["ds->rio"].bad_packets == 7
    assert _state(b.rio) == before
    assert b.rio.stats["ds->rio"].last_error
    # A joystick tag cut short is not a bad packet: its header is obeyed (answered), the tag
    # dropped and counted.
    cut = packet(b.seq + 1, enabled=True, tags=[joystick(axes=(3,), count=12, povs=(90,))])[:-1]
    assert len(b.rio.datagram("ds", cut, DS, b.now)) == 1
    assert b.rio.stats["ds->rio"].bad_packets == 7 and b.rio.faults.malformed_tags == 1


def test_a_tcp_client_that_sends_a_bad_frame_is_closed_and_others_are_unaffected():
    b = Bench()
    b.connect("bad")
    b.connect("good")
    b.take(b.rio.stream_data("good", GameData("L").encode()[:3], b.now))  # a frame cut short
    before = _state(b.rio)
    actions = b.take(b.rio.stream_data("bad", b"\xff\xff\x02", b.now))  # a size over the bound
    assert actions == [Close("bad", actions[0].reason)] and "bad frame" in actions[0].reason
    assert b.rio.stats["rio-tcp"].bad_packets == 1
    after = _state(b.rio)
    assert after["tcp_clients"] == 1
    before["tcp_clients"] = 1
    assert after == before
    assert b.rio.stream_data("bad", GameData("R").encode(), b.now) == []  # gone: ignored
    # the good client's half frame is intact
    b.take(b.rio.stream_data("good", GameData("L").encode()[3:], b.now))
    assert b.rio.inputs.game_data == "L"
    b.connect("bad2")
    malformed = b"\x00\x04\x02\x00\x01\x05"  # a joystick descriptor cut inside its name
    actions = b.take(b.rio.stream_data("bad2", malformed, b.now))
    assert [type(a) for a in actions] == [Close] and b.rio.inputs.descriptors == [None] * 6
    b.drive(0.1)
    assert b.stdout("good") and "good" not in b.closed


@settings(max_examples=200)
@given(chunks=st.lists(st.binary(max_size=40), max_size=6))
def test_random_tcp_bytes_never_raise_and_never_touch_the_other_client(chunks):
    b = Bench()
    b.connect("fuzz")
    b.connect("other")
    b.take(b.rio.stream_data("other", MatchInfo("E", 1, 3).encode(), b.now))
    bad = b.rio.stats["rio-tcp"].bad_packets
    for chunk in chunks:
        actions = b.take(b.rio.stream_data("fuzz", chunk, b.now))
        assert all(isinstance(a, Close) and a.conn == "fuzz" for a in actions)
    if "fuzz" in b.closed:
        assert b.rio.stats["rio-tcp"].bad_packets == bad + 1
    assert b.rio.inputs.match_info == MatchInfo("E", 1, 3) or "fuzz" not in b.closed
    assert "other" not in b.closed and b.rio.tcp.count >= 1
    b.run_until(b.now + 0.05)
    assert b.rio.program.code_state == CODE_RUNNING


def test_a_program_that_prints_in_a_loop_is_bounded_per_beat():
    def chatty(state, robot):
        for i in range(500):
            robot.print("spam", i)

    b = Bench(program=chatty)
    b.run_until(0.01)  # the first beat, before anyone listens
    b.connect()
    b.run_until(0.05)  # two more
    assert [line.kind for line in b.rio.tcp.console] == (["stdout"] * 50 + ["warning"]) * 3
    assert len(b.stdout()) == 49 + 2 * 50  # the 50-frame backlog, then live
    warnings = [f for f in b.tcp["c1"] if isinstance(f, ErrorMessage)]
    assert len(warnings) == 3 and not warnings[0].is_error and "dropped" in warnings[0].details
    assert b.rio.faults.console_dropped == 3 * 450
    seqs = [f.sequence for f in b.tcp["c1"] if isinstance(f, (StdoutMessage, ErrorMessage))]
    assert seqs == list(range(1, 153))


def test_descriptor_for_a_slot_past_six_is_counted_and_dropped():
    b = Bench()
    b.connect()
    before = _state(b.rio)
    b.take(b.rio.stream_data("c1", JoystickDescriptor(6, False, 20, "seventh").encode(), b.now))
    assert b.rio.stats["rio-tcp"].bad_packets == 1 and "c1" not in b.closed
    assert _state(b.rio) == before


# -- nothing obeyed late: arrival times, backlogs, sequence jumps (issues 16 and 17) -----------------
def test_a_packet_taken_up_late_is_not_obeyed_but_its_estop_latches():
    b = Bench()
    b.drive(0.1, enabled=True)
    b.seq += 1  # a disable that waited 150 ms in the robot's socket (its process stalled)
    actions = b.take(b.rio.datagram("ds", packet(b.seq), DS, b.now, arrived=b.now - 0.15))
    status = rio_to_ds.decode_status(actions[-1].data)
    assert status.sequence == b.seq and b.rio.faults.stale_packets == 1
    assert b.rio.control.ds_enabled  # not obeyed: what it says is old
    b.seq += 1
    actions = b.take(b.rio.datagram("ds", packet(b.seq, enabled=True, estop=True), DS, b.now,
                                    arrived=b.now - 0.15))
    assert rio_to_ds.decode_status(actions[-1].data).estop and b.rio.control.estopped and not b.rio.control.enabled


def test_the_watchdog_counts_from_arrival_not_from_when_the_packet_was_taken_up():
    b = Bench()
    b.drive(0.1, enabled=True)
    b.seq += 1
    arrived = b.now + 0.001
    b.now += 0.06  # the packet waited 59 ms before the core saw it: young enough to obey
    b.take(b.rio.datagram("ds", packet(b.seq, enabled=True), DS, b.now, arrived=arrived))
    assert b.rio.control.enabled and b.rio.next_deadline() <= arrived + 0.100 + 1e-9
    b.run_until(arrived + 0.1 + 1e-6)
    assert not b.rio.control.enabled and b.rio.control.watchdog_tripped


def test_of_a_backlog_only_the_newest_packet_is_obeyed():
    # after a stall the shell drains the socket: every packet but each sender's last is superseded
    b = Bench()
    b.drive(0.1, enabled=True)
    statuses = []
    for k, enabled in enumerate([True, True, False, False, True]):
        b.seq += 1
        actions = b.take(b.rio.datagram("ds", packet(b.seq, enabled=enabled), DS, b.now, arrived=b.now,
                                        superseded=k < 4))
        statuses.append(rio_to_ds.decode_status(actions[-1].data))
    assert [s.sequence for s in statuses] == list(range(b.seq - 4, b.seq + 1))  # each answered
    assert b.rio.faults.stale_packets == 4 and b.rio.control.last_sequence == b.seq and b.rio.control.enabled


def test_a_far_ahead_sequence_is_counted_and_the_real_ds_is_followed_on_its_estop_included():
    # issue 17: one forged packet with a far-ahead sequence threw the real DS's e-stop away
    b = Bench()
    b.drive(0.2, enabled=True)
    forged = b.send(packet(b.seq + 30000, enabled=True))
    assert forged.sequence == b.seq + 30000 and b.rio.faults.sequence_jumps == 1
    assert b.rio.control.last_sequence == b.seq  # not taken as the newest
    status = b.drive(0.04, enabled=True)
    assert status.enabled and b.rio.faults.stale_packets == 0
    b.seq += 1
    assert b.send(packet(b.seq, enabled=True, estop=True)).estop and b.rio.control.estopped
    # a jump that does not even pretend to be newer: the e-stop in it latches all the same
    b2 = Bench()
    b2.drive(0.2, enabled=True)
    assert b2.send(packet(b2.seq + 30000, enabled=True, estop=True)).estop and b2.rio.control.estopped


def test_a_ds_losing_packets_for_a_while_is_followed_on_without_a_resync():
    b = Bench()
    b.drive(0.2, enabled=True)
    b.run_until(b.now + 0.5)  # 25 packets lost on the way
    b.seq += 25
    assert b.send(packet(b.seq, enabled=True)).enabled  # a fresh enable, in sequence: obeyed


def test_on_one_host_for_everyone_a_newcomer_never_evicts_the_healthy_ds():
    """The ephemeral plan: the DS and anything else share 127.0.0.1. Newcomers from there may
    use every slot, evict only silent ones, and never the DS's healthy connection."""
    b = Bench(max_clients=4)
    keepalive = ds_to_rio.KeepAlive().encode()
    b.drive(0.1)  # the DS at 127.0.0.5 is followed on UDP
    b.connect("ds", DS[0])
    b.take(b.rio.stream_data("ds", keepalive, b.now))
    for i in range(3):  # past half the slots: the DS's host is not held to that
        b.connect(("other", i), DS[0])
        b.take(b.rio.stream_data(("other", i), keepalive, b.now))
    assert b.rio.tcp.count == 4 and not b.closed
    assert b.connect("late", DS[0]) == [Close("late", "too many clients (4 already connected)")]
    assert "ds" not in b.closed and b.rio.faults.evicted_clients == 0


def _tag(status, kind):
    """The status packet's one tag of ``kind``."""
    [tag] = [t for t in status.tags if isinstance(t, kind)]
    return tag
