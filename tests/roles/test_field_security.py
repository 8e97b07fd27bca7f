"""Issue 17's attacks, each run by plain sockets on loopback against a field on real sockets
(``fieldbox field``: six stations on their 127.TE.AM.x addresses; ``--roles fms``: the FMS
alone, with our own DS and robot in a field of their own), and each failing: no e-stop, no
redirected control packet, the real DS attached throughout, no enabled packet to a wrong
challenge answer, the operator's disable hold kept, the DS back on its robot's and its
FMS's TCP port beside a dozen idle clients from elsewhere.

The outsider is any other loopback address (127.9.9.x): on Linux all of 127.0.0.0/8 is this
machine. Waits are for behaviour (a DS attached, a count reached), never timing limits.
"""

from __future__ import annotations

import asyncio
import math
import socket
import sys
import time

import pytest

from protocol import fms_to_ds
from protocol.ds_to_fms import ChallengeResponse, DsStatusPacket, TeamNumber
from protocol.fms_to_ds import ChallengeQuestion, FmsControlPacket
from protocol.enums import Mode
from protocol.framing import FrameDecoder
from roles.cores.fms import MatchStartRefused
from roles.runtime.field import Field, FieldConfig
from roles.runtime.shell import Runtime

from fieldbox.language import parse

from .cheesy_fms import CheesyLikeFms

pytestmark = pytest.mark.skipif(not sys.platform.startswith("linux"),
                                reason="needs all of 127.0.0.0/8 (Linux) for the outsider's address")

TEAMS = [254, 1114, 2056, 118, 148, 1678]
OUTSIDER = "127.9.9.9"
FMS_HOST = "127.0.100.5"


# -- helpers ------------------------------------------------------------------------------------
async def until(check, timeout: float = 10.0) -> bool:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if check():
            return True
        await asyncio.sleep(0.01)
    return check()


class ControlLog:
    """Every control packet the FMS sends: (destination, decoded packet)."""

    def __init__(self, runtime: Runtime) -> None:
        self.items: list[tuple[tuple, FmsControlPacket]] = []
        runtime.taps.append(self._tap)

    def _tap(self, r) -> None:
        if r.kind == "fms-to-ds" and r.direction == "out":
            self.items.append((tuple(r.remote), fms_to_ds.decode_control(r.data)))

    def to(self, host: str) -> list[FmsControlPacket]:
        return [p for dest, p in self.items if dest[0] == host]


def udp_socket(host: str, port: int = 0) -> socket.socket:
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.setblocking(False)
    sock.bind((host, port))
    return sock


def drain(sock: socket.socket) -> list[bytes]:
    out = []
    while True:
        try:
            out.append(sock.recv(2048))
        except BlockingIOError:
            return out


async def full_field() -> tuple[Runtime, Field]:
    """``fieldbox field --teams ...``: six DSes, six robots and the FMS, all good, a match running."""
    runtime = Runtime()
    field = Field(FieldConfig(teams=list(TEAMS), plan="loopback", log_files=False))
    await field.start(runtime)
    runtime.start()
    assert await until(lambda: field.fms.start_refusals() == []
                       and all(s.ds.link.robot_code for s in field.stations), 20), field.fms.start_refusals()
    return runtime, field


def start_match(runtime: Runtime, field: Field, teleop: float = 60.0) -> None:
    field.fms.set_timing(runtime.clock(), auto=1.0, pause=0.5, teleop=teleop)
    field.fms.start_match(runtime.clock())
    runtime.hosts[field.fms_name].kick()


def command(runtime: Runtime, field: Field, line: str) -> None:
    cmd = parse(line)
    field.execute(cmd, runtime.clock())
    host = field.host_for(cmd)
    if host:
        runtime.hosts[host].kick()


async def fms_alone_with_our_ds(teams=(254,)) -> tuple[Runtime, Field, Field]:
    """``fieldbox --roles fms --teams ...`` and, beside it, our own DS and robot pointed at it."""
    runtime = Runtime()
    fms_field = Field(FieldConfig(roles=frozenset({"fms"}), fms_teams=list(teams), plan="loopback",
                                  log_files=False))
    await fms_field.start(runtime)
    ours = Field(FieldConfig(roles=frozenset({"ds", "rio"}), team=254, plan="loopback", fms=FMS_HOST,
                             log_files=False))
    await ours.start(runtime)
    runtime.start()
    return runtime, fms_field, ours


async def target(kind: str) -> tuple[Runtime, Field, Field]:
    """(runtime, the field running the FMS, the field running team 254's DS and robot), all
    linked and good: ``fieldbox field`` (one field) or ``--roles fms`` beside our own DS."""
    if kind == "field":
        runtime, field = await full_field()
        return runtime, field, field
    runtime, fms_field, ours = await fms_alone_with_our_ds()
    assert await until(lambda: fms_field.fms.start_refusals() == [] and ours.stations[0].ds.link.robot_code, 20)
    return runtime, fms_field, ours


# -- attacks on UDP status ------------------------------------------------------------------------------
@pytest.mark.parametrize("kind", ["field", "fms"])
async def test_status_from_an_outsider_never_estops_nor_redirects_control_packets(kind):
    runtime, field, ours = await target(kind)
    control = ControlLog(runtime)
    attacker = udp_socket(OUTSIDER, 1121)  # where redirected control packets would land
    try:
        fms, r1 = field.fms, field.fms.stations[0]
        real_ds, robot = ours.stations[0].ds, ours.stations[0].rio
        start_match(runtime, field)
        assert await until(lambda: robot.control.enabled)
        fms_udp = field.bound[field.fms_name]["udp"]
        # One datagram claiming "team 254, e-stop".
        attacker.sendto(DsStatusPacket(team=254, estop=True, robot_comms=True).encode(), fms_udp)
        assert await until(lambda: r1.link.foreign_packets == 1)
        # Then status for 254 at 50 Hz for a second and a half.
        for seq in range(75):
            attacker.sendto(DsStatusPacket(sequence=seq, team=254, robot_comms=True, battery=6.0).encode(),
                            fms_udp)
            await asyncio.sleep(0.02)
        assert await until(lambda: r1.link.foreign_packets == 76)
        await asyncio.sleep(0.6)  # at least one more control packet on the 500 ms grid
        assert not r1.commands.estop and not real_ds.arbiter.estopped and not robot.control.estopped
        assert r1.commands.enabled and robot.control.enabled and r1.report.battery != 6.0
        assert control.to(OUTSIDER) == [] and drain(attacker) == []
        assert len(control.to("127.2.54.5")) >= 4
        assert all(dest == ("127.2.54.5", 1121) for dest, p in control.items if p.station == 0)
        # (a DS's status that beat its login at start is refused too, and counted apart)
        unclaimed = sum(s.unclaimed_status for s in fms.stations)
        assert fms.refused_status - unclaimed == 76 and fms.udp_stats.foreign_packets - unclaimed == 76
        said = [text for _, text in fms.match_log if "refused" in text and "from 127.9.9.9" in text]
        assert said[0] == "status (e-stop) for 254 from 127.9.9.9 refused: its DS is 127.2.54.5"
        assert len(said) <= 3  # once a second at most
        # Every other station went on as before.
        assert all(s.rio.control.enabled for s in ours.stations)
    finally:
        attacker.close()
        await runtime.close()


@pytest.mark.parametrize("kind", ["field", "fms"])
async def test_a_relogin_from_another_address_every_half_second_never_detaches_the_real_ds(kind):
    runtime, field, ours = await target(kind)
    fms, r1, real_ds = field.fms, field.fms.stations[0], ours.stations[0].ds
    host, port = field.bound[field.fms_name]["tcp"]
    detached = []
    real_ds.events.listeners.append(lambda t, text: detached.append(text) if "FMS lost" in text
                                    or "FMS TCP closed" in text else None)
    try:
        start_match(runtime, field)
        conn = r1.login.conn
        closed = 0
        for i in range(8):
            reader, writer = await asyncio.open_connection(host, port, local_addr=(OUTSIDER, 0))
            writer.write(TeamNumber(254).encode())
            await writer.drain()
            if await reader.read(100) == b"":  # closed without a reply
                closed += 1
            writer.close()
            assert real_ds.fms.attached and r1.login.conn == conn and r1.login.peer[0] == "127.2.54.5"
            await asyncio.sleep(0.5)
        assert closed == 8 and fms.logins.refused_logins == 8 and r1.refused_logins == 8
        assert r1.last_refused == OUTSIDER and detached == []
        said = [text for _, text in fms.match_log if text.startswith("login as 254")]
        assert said[0] == "login as 254 from 127.9.9.9 refused: its DS 127.2.54.5 is live"
        assert r1.commands.enabled and ours.stations[0].rio.control.enabled
    finally:
        await runtime.close()


# -- attacks on the challenge ------------------------------------------------------------------------
async def _login(host: str, port: int, answer: str | None, team: int = 254, source: str = OUTSIDER):
    reader, writer = await asyncio.open_connection(host, port, local_addr=(source, 0))
    writer.write(TeamNumber(team).encode())
    decoder, frames = FrameDecoder("fms"), []
    while not any(isinstance(f, ChallengeQuestion) for f in frames):
        data = await asyncio.wait_for(reader.read(4096), 5)
        assert data, "closed before the question"
        frames += [fms_to_ds.decode_tcp(f) for f in decoder.feed(data)]
    if answer is not None:
        writer.write(ChallengeResponse(answer).encode())
        await writer.drain()
    return reader, writer


async def test_an_impostor_with_a_wrong_answer_is_never_enabled_against_the_fms_alone():
    runtime, fms_field, ours = await fms_alone_with_our_ds()
    fms = fms_field.fms
    control = ControlLog(runtime)
    r1 = fms.stations[0]
    ds, robot = ours.stations[0].ds, ours.stations[0].rio
    host, port = fms_field.bound[fms_field.fms_name]["tcp"]
    impostor = udp_socket(OUTSIDER, 1121)
    try:
        # Our DS first: it answers right, the match starts, the robot runs.
        assert await until(lambda: fms.start_refusals() == [] and ds.link.robot_code)
        assert r1.login.challenge == "right" and r1.login.peer[0] == "127.2.54.5"
        start_match(runtime, fms_field)
        assert await until(lambda: robot.control.enabled)
        # Our DS goes away (its laptop dies); the impostor logs in once it is lost.
        await runtime.remove(ours.stations[0].ds_name)
        assert await until(lambda: r1.login.conn is None and not r1.report.udp_link, 5)
        reader, writer = await _login(host, port, "Not A Robot")
        fms_udp = fms_field.bound[fms_field.fms_name]["udp"]
        for seq in range(50):
            impostor.sendto(DsStatusPacket(sequence=seq, team=254, robot_comms=True).encode(), fms_udp)
            await asyncio.sleep(0.02)
        assert r1.login.peer[0] == OUTSIDER and r1.login.challenge == "wrong" and r1.report.udp_link
        assert fms.running and not r1.commands.enabled
        to_impostor = [fms_to_ds.decode_control(d) for d in drain(impostor)]
        assert to_impostor and not any(p.enabled for p in to_impostor)
        assert control.to(OUTSIDER) and not any(p.enabled for p in control.to(OUTSIDER))
        assert any("WRONG challenge answer 'Not A Robot' from 127.9.9.9" in t for _, t in fms.match_log)
        # After the match, a start says why not while the impostor holds the station.
        fms.abort_match(runtime.clock())
        fms.next_match(runtime.clock())
        with pytest.raises(MatchStartRefused) as info:
            fms.start_match(runtime.clock())
        assert info.value.reasons == ["R1 (254): its DS answered the challenge wrong; not bypassed"]
        writer.close()
    finally:
        impostor.close()
        await runtime.close()


async def test_no_answer_within_5_s_is_a_wrong_answer_and_bypass_still_starts():
    runtime = Runtime()
    field = Field(FieldConfig(roles=frozenset({"fms"}), fms_teams=[254], plan="loopback", log_files=False))
    await field.start(runtime)
    runtime.start()
    fms, r1 = field.fms, field.fms.stations[0]
    host, port = field.bound[field.fms_name]["tcp"]
    impostor = udp_socket("127.2.54.5", 1121)
    try:
        reader, writer = await _login(host, port, None, source="127.2.54.5")
        fms_udp = field.bound[field.fms_name]["udp"]
        for seq in range(300):  # status and keep-alives for six seconds, never an answer
            impostor.sendto(DsStatusPacket(sequence=seq, team=254, robot_comms=True).encode(), fms_udp)
            if seq % 50 == 0:
                writer.write(bytes.fromhex("0001 1d"))
            await asyncio.sleep(0.02)
            if r1.login.challenge == "late":
                break
        assert r1.login.challenge == "late" and r1.ds_link
        with pytest.raises(MatchStartRefused) as info:
            fms.start_match(runtime.clock())
        assert info.value.reasons == ["R1 (254): its DS did not answer the challenge within 5 s; not bypassed"]
        fms.set_bypass("R1", True, runtime.clock())
        fms.start_match(runtime.clock())
        runtime.hosts[field.fms_name].kick()
        await asyncio.sleep(0.6)
        assert not any(fms_to_ds.decode_control(d).enabled for d in drain(impostor))
        writer.close()
    finally:
        impostor.close()
        await runtime.close()


# -- the DS's side: forged control packets ---------------------------------------------------------------
async def test_a_forged_disabled_packet_does_not_clear_the_operators_hold():
    runtime = Runtime()
    field = Field(FieldConfig(team=254, plan="loopback", log_files=False))
    await field.start(runtime)
    runtime.start()
    ds, robot = field.stations[0].ds, field.stations[0].rio
    forger = udp_socket(FMS_HOST)  # the FMS's own address, another port
    try:
        assert await until(lambda: field.fms.start_refusals() == [] and ds.link.robot_code)
        start_match(runtime, field)
        assert await until(lambda: robot.control.enabled and field.fms.phase.value == "teleop", 10)
        command(runtime, field, "disable")
        assert await until(lambda: not robot.control.enabled)
        dest = field.bound[field.stations[0].ds_name]["fms"]
        forged = FmsControlPacket(sequence=1, enabled=False, mode=Mode.TELEOP).encode()
        forger.sendto(forged, dest)
        assert await until(lambda: ds.fms.foreign_packets == 1)
        await asyncio.sleep(1.2)  # the real FMS's next packets say "enabled"
        assert ds.fms.attached and ds.fms.hold_disabled and not ds.enabled and not robot.control.enabled
        assert field.fms.stations[0].commands.enabled  # the FMS did enable it all along
        assert any(f"FMS control from {FMS_HOST}:" in t and "refused" in t for _, t in ds.events.items)
    finally:
        forger.close()
        await runtime.close()


async def test_forged_enabled_packets_from_another_address_never_enable_the_robot():
    runtime, fms_field, ours = await fms_alone_with_our_ds()
    ds, robot = ours.stations[0].ds, ours.stations[0].rio
    forger = udp_socket(OUTSIDER)
    try:
        assert await until(lambda: ds.fms.attached and ds.link.robot_code)
        dest = ours.bound[ours.stations[0].ds_name]["fms"]
        for seq in range(20):
            forger.sendto(FmsControlPacket(sequence=seq, enabled=True, estop=seq == 10,
                                           mode=Mode.TELEOP).encode(), dest)
            await asyncio.sleep(0.01)
        assert await until(lambda: ds.fms.foreign_packets == 20)
        await asyncio.sleep(0.1)
        assert not ds.enabled and not robot.control.enabled and not ds.arbiter.estopped and ds.fms.attached
        assert ds.stats["fms-udp"].foreign_packets == 20
    finally:
        forger.close()
        await runtime.close()


# -- TCP ports keep room for the real peer --------------------------------------------------------------
async def test_the_ds_gets_back_on_its_robots_and_its_fms_tcp_ports_beside_a_dozen_idle_clients():
    runtime, fms_field, ours = await fms_alone_with_our_ds()
    ds, robot, fms = ours.stations[0].ds, ours.stations[0].rio, fms_field.fms
    idle: list[socket.socket] = []
    try:
        assert await until(lambda: ds.fms.status == "good" and ds.tcp.state == "open")
        # Both connections drop (as when the DS's cable is pulled and put back) ...
        rio_host = runtime.hosts[ours.stations[0].rio_name]
        dropped = [c for c, s in rio_host.streams.items() if s.peer and s.peer[0] == "127.2.54.5"]
        for conn in dropped:
            rio_host.close_stream(conn, "test: dropped")
        dropped.append(fms.stations[0].login.conn)
        runtime.hosts[fms_field.fms_name].close_stream(fms.stations[0].login.conn, "test: dropped")
        # ... and before the DS tries again, strangers take every free slot: a dozen idle
        # clients on the robot's 1740 (8 slots), forty on the FMS's 1750 (32). The FMS's listen
        # backlog holds 16, so the rest come in on the kernel's SYN retry a second later, as the
        # DS's own retry does: the DS's FMS login waits until they are all in (else it could win
        # a free slot and no stranger need make room: a race the test is not about).
        assert await until(lambda: ds.fms.tcp_state == "closed", 5)
        ds.fms._retry_at = math.inf
        for target, count in ((ours.bound[ours.stations[0].rio_name]["tcp"], 12),
                              (fms_field.bound[fms_field.fms_name]["tcp"], 40)):
            for i in range(count):
                sock = socket.socket()
                sock.bind((f"127.9.{9 + i // 200}.{i % 200 + 1}", 0))
                sock.setblocking(False)
                try:
                    sock.connect(target)
                except BlockingIOError:
                    pass
                idle.append(sock)
        assert await until(lambda: robot.tcp.count == robot.tcp.max_clients
                           and len(fms.logins.connections) == fms.logins.max_connections, 5)
        ds.fms._retry_at = -math.inf  # the DS tries its FMS again now, every slot taken
        runtime.hosts[ours.stations[0].ds_name].reschedule()
        # The DS's own address is always served: it is back on both.
        assert await until(lambda: ds.tcp.state == "open" and ds.fms.status == "good"
                           and fms.stations[0].login.conn not in (None, *dropped), 10)
        assert fms.stations[0].login.peer[0] == "127.2.54.5" and fms.stations[0].login.challenge == "right"
        assert [c for c, host in robot.tcp.connections.items() if host == "127.2.54.5" and c not in dropped]
        assert robot.faults.evicted_clients >= 1 and fms.logins.evicted_connections >= 1
        assert robot.tcp.count <= robot.tcp.max_clients and len(fms.logins.connections) <= fms.logins.max_connections
    finally:
        for sock in idle:
            sock.close()
        await runtime.close()


# -- Cheesy-like FMS behaviour keeps working -----------------------------------------------------------
async def test_our_ds_follows_a_cheesy_like_fms_that_sends_from_its_own_socket_to_the_tcp_address():
    """Cheesy Arena: control packets to the DS's TCP address, port 1121, from one socket per DS
    connection on a port of the OS's; no challenge. Our DS logs in from its own address and
    obeys that socket, and nothing else on the FMS's host."""
    runtime = Runtime()
    ours = Field(FieldConfig(roles=frozenset({"ds", "rio"}), team=254, plan="loopback", fms=FMS_HOST,
                             log_files=False))
    fms = CheesyLikeFms(FMS_HOST, port=1121, socket_per_ds=True, period=0.05)
    await fms.start()
    forger = udp_socket(FMS_HOST)
    try:
        await ours.start(runtime)
        runtime.start()
        ds, robot = ours.stations[0].ds, ours.stations[0].rio
        assert await until(lambda: ds.fms.attached and robot.control.enabled, 10)
        assert [(team, dest) for _, team, dest in fms.logins] == [(254, ("127.2.54.5", 1121))]
        assert ds.mode is Mode.TELEOP and ds.fms.control_source[0] == FMS_HOST
        forger.sendto(FmsControlPacket(sequence=1, estop=True).encode(), ours.bound[ours.stations[0].ds_name]["fms"])
        assert await until(lambda: ds.fms.foreign_packets == 1)
        await asyncio.sleep(0.2)
        assert not ds.arbiter.estopped and robot.control.enabled
    finally:
        forger.close()
        await fms.close()
        await runtime.close()


# -- a DS that re-creates its socket ------------------------------------------------------------------
async def test_a_ds_that_sends_from_a_new_port_every_few_packets_is_answered_every_time():
    """Issue 30: LibDS opens a new socket (a new source port) each time its watchdog expires.
    The robot answers the DS's host on UDP 1150 whatever port its packets come from, as a real
    roboRIO does: no packet goes unanswered, none is taken for a second DS's."""
    from protocol.ds_to_rio import ControlPacket
    from protocol.rio_to_ds import decode_status

    team, ds_host = 9876, "127.98.76.5"
    runtime = Runtime()
    field = Field(FieldConfig(roles=frozenset({"rio"}), team=team, plan="loopback", log_files=False))
    listener = udp_socket(ds_host, 1150)  # where a DS hears its robot
    senders: list[socket.socket] = []
    try:
        await field.start(runtime)
        runtime.start()
        robot = field.stations[0].rio
        dest = field.bound[field.stations[0].rio_name]["ds"]
        answered: set[int] = set()
        seq = 0
        for n in range(5):  # a new socket every 15 packets (0.3 s), the sequence going on
            senders.append(udp_socket(ds_host))
            for _ in range(15):
                seq += 1
                senders[-1].sendto(ControlPacket(sequence=seq, enabled=seq > 5).encode(), dest)
                await asyncio.sleep(0.02)
                answered |= {decode_status(d).sequence for d in drain(listener)}
        assert await until(lambda: answered.update(decode_status(d).sequence for d in drain(listener))
                           or len(answered) == seq, 5)
        assert sorted(answered) == list(range(1, seq + 1))
        assert robot.faults.foreign_packets == 0 and robot.control.ds_address[1] == senders[-1].getsockname()[1]
    finally:
        for sock in (listener, *senders):
            sock.close()
        await runtime.close()
