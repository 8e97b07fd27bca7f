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
from collections import Counter, defaultdict
from pathlib import Path

import pytest

from fieldbox.capture import (LINKTYPE_RAW, PCAP_MAGIC, CaptureRing, Endpoints, PcapWriter, Recorder,
                              _checksum, link_label, udp_datagram, write_pcap)
from roles import addresses as A
from roles.engine import SimEngine
from roles.field import Field, FieldConfig
from roles.simnet import SimNetwork

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
    ring.tap("ds 1", "robot", "out", "ds-to-rio", b"\x00\x01\x01\x00\x10\x00", ("127.0.0.1", 1110), 5.0)
    assert ring.links == {} and len(ring) == 0  # the wire thread did nothing but append
    new = ring.drain()
    assert [p.key for p in new] == [("ds 1", "robot", "out", "ds-to-rio")]
    assert new[0].peer == ("127.0.0.1", 1110) and new[0].index == 0 and new[0].seq == 1
    assert link_label(new[0].key) == "ds 1 robot out ds-to-rio"
    assert ring.drain() == []


def test_ring_is_bounded_per_link_and_in_all():
    ring = CaptureRing(per_link=5, total=8)
    for i in range(20):
        ring.tap("ds 1", "robot", "out", "ds-to-rio", bytes([0, i]), None, float(i))
        ring.tap("rio 1", "ds", "in", "ds-to-rio", bytes([0, i]), None, float(i))
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
        ring.tap("ds 254", "robot", "out", "ds-to-rio", bytes([0, i]), ("127.0.0.1", 1110), i * 0.02)
    new = ring.drain()
    assert len(new) == 5
    if sys.implementation.name == "cpython":  # elsewhere the ring does not untrack
        assert not any(gc.is_tracked(p) for p in new)
    first = new[0]
    del new
    ring.tap("ds 254", "robot", "out", "ds-to-rio", bytes([0, 5]), None, 0.1)
    ring.drain()  # the ring holds 5: the first packet leaves it
    # only this test holds it: as many references as an object held by one local variable
    # (2 up to CPython 3.13, the argument counted; 1 from 3.14, which borrows it)
    lone = object()
    assert sys.getrefcount(first) == sys.getrefcount(lone)
    last = ring.links[first.key][-1]
    assert (last.seq, last.index, last.data, last.peer) == (6, 5, bytes([0, 5]), None)
    assert ring.links[first.key][0].peer == ("127.0.0.1", 1110)


def test_incoming_queue_overflow_is_counted():
    ring = CaptureRing(per_link=10, total=10)
    for i in range(25):
        ring.tap("ds 1", "robot", "out", "ds-to-rio", bytes([0, i]), None, float(i))
    ring.drain()
    assert ring.overflowed == 15


def test_tcp_chunks_are_split_into_frames():
    ring = CaptureRing()
    two = bytes.fromhex("0001 1c") + bytes.fromhex("0003 18 00fe")
    ring.tap("ds 1", "fms-tcp", "out", "ds-to-fms-tcp", two, None, 1.0)
    ring.tap("ds 1", "fms-tcp", "out", "ds-to-fms-tcp", b"\x00\x09\x01", None, 1.0)  # a cut frame stays whole
    new = ring.drain()
    assert [p.data.hex() for p in new] == ["00011c", "00031800fe", "000901"]


# -- pcap bytes -----------------------------------------------------------------------------
def test_udp_frame_has_valid_ipv4_and_udp_checksums():
    frame = udp_datagram(("127.2.54.5", 1150), ("127.2.54.2", 1110), b"\x00\x01\x01\x00\x10\x00", 7)
    ip, udp = frame[:20], frame[20:]
    assert ip[0] == 0x45 and ip[9] == 17 and struct.unpack("!H", ip[2:4])[0] == len(frame)
    assert _checksum(ip) == 0  # a correct header sums to 0xffff
    assert ipaddress.IPv4Address(ip[12:16]) == ipaddress.IPv4Address("127.2.54.5")
    sport, dport, length, _ = struct.unpack("!HHHH", udp[:8])
    assert (sport, dport, length) == (1150, 1110, 14)
    pseudo = ip[12:20] + struct.pack("!BBH", 0, 17, length)
    assert _checksum(pseudo + udp) == 0


def test_pcap_of_a_sim_run_holds_each_wire_packet_once(tmp_path):
    engine, ring = run_field()
    path = tmp_path / "run.pcap"
    n = write_pcap(path, ring.packets(), Endpoints(engine), clock_offset=1_700_000_000.0 - 1000.0)
    header, frames = read_pcap(path)
    assert header == (PCAP_MAGIC, 2, 4, 0, 0, 0xFFFF, LINKTYPE_RAW)
    assert path.read_bytes()[:4] == bytes.fromhex("d4c3b2a1")  # a1b2c3d4, little-endian file
    # every role is in this process: each datagram / frame was tapped by its sender and its
    # receiver, and the pcap keeps the sender's copy (the receiver's of the ones in flight).
    outs = [p for p in ring.packets() if p.direction == "out"]
    assert n == len(frames) == len(outs)
    for frame in frames:
        assert _checksum(frame[:20]) == 0


@needs_tshark
def test_tshark_reads_the_real_ports_and_good_checksums(tmp_path):
    engine, ring = run_field(LoopbackSim)
    path = tmp_path / "loopback.pcap"
    n = write_pcap(path, ring.packets(), Endpoints(engine), clock_offset=1_700_000_000.0 - 1000.0)
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
    write_pcap(path, ring.packets(), Endpoints(engine))
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
    recorder = Recorder.start(path, Endpoints(engine), 0.0)
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
    writer = PcapWriter.open(path, Endpoints(engine))
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
