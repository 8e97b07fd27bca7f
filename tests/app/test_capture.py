"""The capture ring and the pcap writer, checked byte by byte and by tshark.

tshark comes from Debian's ``tshark`` package; the tshark tests skip when it is absent.
CI installs it with::

    echo "wireshark-common wireshark-common/install-setuid boolean false" | debconf-set-selections
    DEBIAN_FRONTEND=noninteractive apt-get install -y --no-install-recommends tshark
"""

from __future__ import annotations

import gc
import ipaddress
import shutil
import struct
import subprocess
import sys
import time
from collections import Counter, defaultdict
from pathlib import Path

import pytest

from fieldbox.capture import Address, CaptureRing, Endpoints, is_tcp_kind, link_label
from fieldbox.pcap import LINKTYPE_RAW, PCAP_MAGIC, PcapWriter, Recorder, checksum, udp_datagram, write_pcap
from roles.cores import addresses as A
from roles.runtime.engine import SimEngine, ThreadEngine
from roles.runtime.field import Field, FieldConfig
from roles.runtime.shell import TapRecord, link_name
from roles.sim.simnet import SimNetwork

from .helpers import ui_modules_after

TSHARK = shutil.which("tshark")
needs_tshark = pytest.mark.skipif(TSHARK is None, reason="tshark not installed (apt-get install tshark)")


class LoopbackSim(SimEngine):
    """The field on the fake network but on the loopback plan: the real ports (1110, 1740...)
    on 127.TE.AM.x, so a pcap shows what a capture on ``lo`` would."""

    def __init__(self, config: FieldConfig) -> None:
        self.net = SimNetwork(1000.0)
        self.field = Field(config)
        self.field.start_sim(self.net)


def run_field(engine_cls=SimEngine, seconds: float = 2.0, **config) -> tuple[SimEngine, CaptureRing]:
    engine = engine_cls(FieldConfig(team=254, **config))
    ring = CaptureRing()
    engine.add_tap(ring.tap)
    engine.advance(seconds)
    ring.drain()
    return engine, ring


def read_pcap(path: Path) -> tuple[tuple, list[bytes]]:
    raw = path.read_bytes()
    header = struct.unpack("<IHHiIII", raw[:24])
    frames, pos = [], 24
    while pos < len(raw):
        _, _, incl, orig = struct.unpack("<IIII", raw[pos:pos + 16])
        assert incl == orig
        frames.append(raw[pos + 16:pos + 16 + incl])
        pos += 16 + incl
    assert pos == len(raw)
    return header, frames


def tshark(path: Path, *fields: str, extra: tuple[str, ...] = ()) -> list[list[str]]:
    cmd = [TSHARK, "-n", "-r", str(path), "-o", "ip.check_checksum:TRUE", "-o", "udp.check_checksum:TRUE",
           "-o", "tcp.check_checksum:TRUE", *extra, "-T", "fields", "-E", "separator=|"]
    for f in fields:
        cmd += ["-e", f]
    out = subprocess.run(cmd, capture_output=True, text=True, timeout=60, check=True).stdout
    return [line.split("|") for line in out.splitlines()]


# -- the ring ----------------------------------------------------------------------------------
def test_tap_only_queues_and_drain_files_per_link():
    ring = CaptureRing()
    ring.tap(TapRecord("ds 1", "robot", "out", "ds-to-rio", b"\x00\x01\x01\x00\x10\x00", ("127.0.0.1", 1110),
             ("127.0.0.1", 1150), 5.0))
    assert ring.links == {} and len(ring) == 0  # the wire thread did nothing but append
    new = ring.drain()
    assert [p.key for p in new] == [("ds 1", "robot", "out", "ds-to-rio")]
    assert (new[0].remote, new[0].local) == (("127.0.0.1", 1110), ("127.0.0.1", 1150))
    assert new[0].index == 0 and new[0].seq == 1
    assert link_label(new[0].key) == "ds 1 robot out ds-to-rio"
    assert ring.drain() == []


def test_ring_is_bounded_per_link_and_in_all():
    ring = CaptureRing(per_link=5, total=8)
    for i in range(20):
        ring.tap(TapRecord("ds 1", "robot", "out", "ds-to-rio", bytes([0, i]), None, None, float(i)))
        ring.tap(TapRecord("rio 1", "ds", "in", "ds-to-rio", bytes([0, i]), None, None, float(i)))
        ring.drain()
    assert len(ring) <= 8
    for packets in ring.links.values():
        assert len(packets) <= 5
        assert [p.index for p in packets] == sorted(p.index for p in packets)
    # the newest survive
    assert ring.links[("ds 1", "robot", "out", "ds-to-rio")][-1].data == bytes([0, 19])
    assert ring.counts[("ds 1", "robot", "out", "ds-to-rio")] == 20


def test_the_collector_does_not_walk_the_ring_and_a_packet_dropped_is_held_by_nothing():
    # A full ring is 50 000 packets, a quarter of what the collector tracked in the app's
    # process: each full collection (the app stopped meanwhile) walked them all. A packet
    # is plain data, in no cycle: reference counting frees it when the ring drops it.
    ring = CaptureRing(per_link=5, total=5)
    for i in range(5):
        ring.tap(TapRecord("ds 254", "robot", "out", "ds-to-rio", bytes([0, i]), ("127.0.0.1", 1110), None, i * 0.02))
    new = ring.drain()
    assert len(new) == 5
    if sys.implementation.name == "cpython":  # elsewhere the ring does not untrack
        assert not any(gc.is_tracked(p) for p in new)
    first = new[0]
    del new
    ring.tap(TapRecord("ds 254", "robot", "out", "ds-to-rio", bytes([0, 5]), None, None, 0.1))
    ring.drain()  # the ring holds 5: the first packet leaves it
    # only this test holds it: as many references as an object held by one local variable
    # (2 up to CPython 3.13, the argument counted; 1 from 3.14, which borrows it)
    lone = object()
    assert sys.getrefcount(first) == sys.getrefcount(lone)
    last = ring.links[first.key][-1]
    assert (last.seq, last.index, last.data, last.remote) == (6, 5, bytes([0, 5]), None)
    assert ring.links[first.key][0].remote == ("127.0.0.1", 1110)


def test_incoming_queue_overflow_is_counted():
    ring = CaptureRing(per_link=10, total=10)
    for i in range(25):
        ring.tap(TapRecord("ds 1", "robot", "out", "ds-to-rio", bytes([0, i]), None, None, float(i)))
    ring.drain()
    assert ring.overflowed == 15


def test_tcp_chunks_are_split_into_frames():
    ring = CaptureRing()
    two = bytes.fromhex("0001 1c") + bytes.fromhex("0003 18 00fe")
    ring.tap(TapRecord("ds 1", "fms-tcp", "out", "ds-to-fms-tcp", two, None, None, 1.0))
    ring.tap(TapRecord("ds 1", "fms-tcp", "out", "ds-to-fms-tcp", b"\x00\x09\x01", None, None, 1.0))  # a cut frame: whole
    new = ring.drain()
    assert [p.data.hex() for p in new] == ["00011c", "00031800fe", "000901"]


# -- addresses ----------------------------------------------------------------------------
def test_routes_come_from_the_taps_addresses_and_a_local_senders_copy_is_kept():
    ring = CaptureRing()
    ds, rio = ("127.2.54.5", 1150), ("127.2.54.2", 1110)
    ring.tap(TapRecord("rio 254", "ds", "in", "ds-to-rio", bytes([0, 0]), ds, rio, 0.9))  # its send was not tapped
    ring.tap(TapRecord("ds 254", "robot", "out", "ds-to-rio", bytes([0, 1]), rio, ds, 1.0))
    ring.tap(TapRecord("rio 254", "ds", "in", "ds-to-rio", bytes([0, 1]), ds, rio, 1.0))
    # a wildcard bind sends from the loopback address here
    ring.tap(TapRecord("rio 254", "ds", "out", "rio-to-ds", bytes([0, 1]), ds, ("0.0.0.0", 1110), 1.0))
    ring.tap(TapRecord("ds 254", "robot", "in", "rio-to-ds", bytes([0, 1]), ("127.0.0.1", 1110), ds, 1.0))
    endpoints = Endpoints()
    routes = [endpoints.route(p) for p in ring.drain()]
    assert [(r.src, r.dst, r.duplicate) for r in routes] == [
        (ds, rio, False), (ds, rio, False), (ds, rio, True),
        (("127.0.0.1", 1110), ds, False), (("127.0.0.1", 1110), ds, True)]


# -- pcap bytes -----------------------------------------------------------------------------
def test_udp_frame_has_valid_ipv4_and_udp_checksums():
    frame = udp_datagram(("127.2.54.5", 1150), ("127.2.54.2", 1110), b"\x00\x01\x01\x00\x10\x00", 7)
    ip, udp = frame[:20], frame[20:]
    assert ip[0] == 0x45 and ip[9] == 17 and struct.unpack("!H", ip[2:4])[0] == len(frame)
    assert checksum(ip) == 0  # a correct header sums to 0xffff
    assert ipaddress.IPv4Address(ip[12:16]) == ipaddress.IPv4Address("127.2.54.5")
    sport, dport, length, _ = struct.unpack("!HHHH", udp[:8])
    assert (sport, dport, length) == (1150, 1110, 14)
    pseudo = ip[12:20] + struct.pack("!BBH", 0, 17, length)
    assert checksum(pseudo + udp) == 0


def test_pcap_of_a_sim_run_holds_each_wire_packet_once(tmp_path):
    engine, ring = run_field()
    path = tmp_path / "run.pcap"
    n = write_pcap(path, ring.packets(), Endpoints(), clock_offset=1_700_000_000.0 - 1000.0)
    header, frames = read_pcap(path)
    assert header == (PCAP_MAGIC, 2, 4, 0, 0, 0xFFFF, LINKTYPE_RAW)
    assert path.read_bytes()[:4] == bytes.fromhex("d4c3b2a1")  # a1b2c3d4, little-endian file
    # every role is in this process: each datagram / frame was tapped by its sender and its
    # receiver, and the pcap keeps the sender's copy (the receiver's of the ones in flight).
    outs = [p for p in ring.packets() if p.direction == "out"]
    assert n == len(frames) == len(outs)
    for frame in frames:
        assert checksum(frame[:20]) == 0


@needs_tshark
def test_tshark_reads_the_real_ports_and_good_checksums(tmp_path):
    engine, ring = run_field(LoopbackSim)
    path = tmp_path / "loopback.pcap"
    n = write_pcap(path, ring.packets(), Endpoints(), clock_offset=1_700_000_000.0 - 1000.0)
    rows = tshark(path, "frame.len", "ip.src", "ip.dst", "ip.checksum.status", "udp.dstport",
                  "udp.checksum.status", "tcp.srcport", "tcp.dstport", "tcp.checksum.status")
    assert len(rows) == n > 150
    assert all(r[3] == "1" for r in rows), "IPv4 header checksums good"
    udp = [r for r in rows if r[4]]
    tcp = [r for r in rows if r[6]]
    assert udp and tcp and len(udp) + len(tcp) == n
    assert all(r[5] == "1" for r in udp) and all(r[8] == "1" for r in tcp)
    udp_ports = Counter(int(r[4]) for r in udp)
    # DS -> robot control (1110 alone, 1115 once the FMS attaches it), robot -> DS 1150,
    # DS -> FMS 1160, FMS -> DS 1121
    assert udp_ports[A.ROBOT_UDP] + udp_ports[A.ROBOT_UDP_FMS] > 50
    assert udp_ports[A.DS_UDP] > 50
    assert udp_ports[A.FMS_UDP] >= 2 and udp_ports[A.DS_FMS_UDP] >= 2
    tcp_ports = {int(r[6]) for r in tcp} | {int(r[7]) for r in tcp}
    assert {A.ROBOT_TCP, A.FMS_TCP} <= tcp_ports
    addresses = {r[1] for r in rows} | {r[2] for r in rows}
    assert {"127.2.54.2", "127.2.54.5", "127.0.100.5"} <= addresses
    # frame.len is the IPv4 packet: 20 + 8 + payload for UDP
    first_udp = next(p for p in ring.packets() if p.direction == "out" and not p.kind.endswith("tcp"))
    assert int(udp[0][0]) == 28 + len(first_udp.data)


@needs_tshark
def test_tshark_sees_tcp_streams_with_growing_sequence_numbers(tmp_path):
    engine, ring = run_field(LoopbackSim, seconds=3.0)
    path = tmp_path / "tcp.pcap"
    write_pcap(path, ring.packets(), Endpoints())
    rows = tshark(path, "tcp.stream", "tcp.srcport", "tcp.seq_raw", "tcp.len", extra=("-Y", "tcp"))
    assert rows
    nxt: dict[tuple[str, str], int] = {}
    streams = defaultdict(int)
    for stream, sport, seq, length in rows:
        key = (stream, sport)
        if key in nxt:
            assert int(seq) == nxt[key], "each segment starts where the last one of its direction ended"
        nxt[key] = (int(seq) + int(length)) & 0xFFFFFFFF
        streams[stream] += 1
    assert len(streams) == 2  # DS <-> roboRIO 1740 and DS <-> FMS 1750, one conversation each
    flagged = tshark(path, "frame.number", extra=("-Y", "tcp.analysis.flags && !tcp.analysis.window_update"))
    assert flagged == [], "no retransmissions, gaps or duplicates"


@needs_tshark
def test_recording_is_readable_while_it_runs(tmp_path):
    engine = LoopbackSim(FieldConfig(team=254, roles=frozenset({"ds", "rio"})))
    ring = CaptureRing()
    engine.add_tap(ring.tap)
    path = tmp_path / "rec" / "live.pcap"
    recorder = Recorder.start(path, Endpoints(), 0.0)
    counts = []
    for _ in range(3):
        engine.advance(0.5)
        recorder.feed(ring.drain())
        counts.append(len(tshark(path, "frame.number")))  # flushed: complete on disk now
    assert counts[0] > 0 and counts[0] < counts[1] < counts[2]
    assert counts[-1] == recorder.writer.written
    assert recorder.stop() == counts[-1]


def test_writer_is_incremental(tmp_path):
    engine, ring = run_field(seconds=0.5)
    path = tmp_path / "inc.pcap"
    writer = PcapWriter.open(path, Endpoints())
    packets = ring.packets()
    writer.write(packets[:10])
    writer.flush()
    size = path.stat().st_size
    writer.write(packets[10:])
    writer.close()
    assert 24 < size < path.stat().st_size
    _, frames = read_pcap(path)
    assert len(frames) == writer.written


def test_capture_imports_without_textual():
    assert ui_modules_after("import fieldbox.capture") == []
    assert ui_modules_after("import fieldbox.pcap") == []


# -- real sockets --------------------------------------------------------------------------
def _socket_names(engine: ThreadEngine) -> dict[tuple[str, str], tuple]:
    """What the sockets themselves say, read on the wire's thread: a UDP channel's name, and a
    TCP link's (peer name, socket name)."""
    def read() -> dict:
        names = {}
        for role, host in engine.runtime.hosts.items():
            for channel, proto in host.udp.items():
                names[(role, channel)] = proto.sock.getsockname()[:2]
            for conn, stream in host.streams.items():
                sock = stream.transport.get_extra_info("socket")
                names[(role, link_name(conn))] = (sock.getpeername()[:2], sock.getsockname()[:2])
        return names
    return engine.runtime.call(read).result(timeout=5)


def _ip_frames(path: Path) -> list[tuple[int, Address, Address]]:
    """(protocol, source, destination) of each frame of a raw-IPv4 pcap."""
    out = []
    for frame in read_pcap(path)[1]:
        ihl = (frame[0] & 0x0F) * 4
        sport, dport = struct.unpack("!HH", frame[ihl:ihl + 4])
        out.append((frame[9], (str(ipaddress.IPv4Address(frame[12:16])), sport),
                    (str(ipaddress.IPv4Address(frame[16:20])), dport)))
    return out


def test_real_sockets_tap_both_their_ends_and_the_pcap_shows_them(tmp_path):
    # A DS, a fake roboRIO and an FMS on their loopback addresses (127.94.61.x, 127.0.100.5),
    # the real ports, on the app's wire thread.
    engine = ThreadEngine(FieldConfig(team=9461, plan="loopback", log_files=False))
    ring = CaptureRing()
    engine.add_tap(ring.tap)  # from the first packet: every arrival's sender was tapped too
    engine.start()
    try:
        def settled() -> bool:
            ds = engine.field.stations[0].ds
            tcp = [v for v in _socket_names(engine).values() if isinstance(v[0], tuple)]
            return ds.link.robot_comms and ds.fms.attached and len(tcp) == 4
        deadline = time.monotonic() + 20
        while time.monotonic() < deadline and not settled():
            time.sleep(0.05)
        time.sleep(0.5)
        assert settled()
        names = _socket_names(engine)
        engine.remove_tap(ring.tap)
    finally:
        engine.stop()
    packets = ring.drain()
    by_link: dict[tuple[str, str], list] = defaultdict(list)
    for p in packets:
        by_link[(p.role, p.link)].append(p)
    tcp_links = {key for key, value in names.items() if isinstance(value[0], tuple)}
    assert {("ds 9461", "robot-tcp"), ("ds 9461", "fms-tcp")} <= tcp_links and len(tcp_links) == 4
    for key, ps in by_link.items():
        if key in tcp_links:
            peername, sockname = names[key]
            assert {(p.remote, p.local) for p in ps} == {(peername, sockname)}, key
        else:
            assert {p.local for p in ps} == {names[key]}, key
    # the roboRIO saw as its peer the very socket the DS sent from
    ds_udp = names[("ds 9461", "robot")]
    assert ds_udp[0] == "127.94.61.5" and ds_udp[1] == A.DS_UDP
    control_in = [p for p in by_link[("rio 9461", "ds")] if p.direction == "in"]
    assert control_in and {p.remote for p in control_in} == {ds_udp}
    ds_tcp = names[("ds 9461", "robot-tcp")]
    rio_side = [key for key in tcp_links if key[0] == "rio 9461"]
    assert len(rio_side) == 1 and names[rio_side[0]] == (ds_tcp[1], ds_tcp[0])
    assert ds_tcp[0] == ("127.94.61.2", A.ROBOT_TCP) and ds_tcp[1][0] == "127.94.61.5"

    # The pcap: each packet once, from its sender's socket to where it went.
    path = tmp_path / "real.pcap"
    n = write_pcap(path, ring.packets(), Endpoints())
    frames = _ip_frames(path)
    outs = [p for p in ring.packets() if p.direction == "out"]
    assert n == len(frames) == len(outs)
    expected = Counter((6 if is_tcp_kind(p.kind) else 17, p.local, p.remote) for p in outs)
    assert Counter(frames) == expected
    assert (17, ds_udp, ("127.94.61.2", A.ROBOT_UDP)) in expected
    assert (6, ds_tcp[1], ds_tcp[0]) in expected and (6, ds_tcp[0], ds_tcp[1]) in expected
    fms_tcp = names[("ds 9461", "fms-tcp")]
    assert fms_tcp[0] == ("127.0.100.5", A.FMS_TCP) and (6, fms_tcp[1], fms_tcp[0]) in expected
