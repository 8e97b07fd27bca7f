"""``fieldbox decode --pcap FILE``: every FRC packet of a capture, one a line.

Read from a real NI DS <-> roboRIO capture (``../shared/captures``, skipped when absent), from
pcap files fieldbox records itself, and from pcap and pcapng files built here byte by byte in
the layouts Wireshark and tcpdump write (both byte orders, nanosecond stamps, Linux cooked
headers, VLAN tags, IPv6, TCP segments out of order).
"""

from __future__ import annotations

import io
import json
import os
import struct
import subprocess
import sys
from pathlib import Path

import pytest

from fieldbox.capture import Endpoints
from fieldbox.decode_cmd import run_pcap
from fieldbox.pcap import tcp_segment, udp_datagram, write_pcap

from .app.test_capture import LoopbackSim, run_field
from .test_real_capture import CAPTURE

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
CONTROL = bytes.fromhex("0001 01 04 10 00 10 0c 04 9c ce 00 4b 0c 0a b2 03 0032 0064 0f00")  # enabled teleop R1
STATUS = bytes.fromhex("0001 01 04 32 0c80 00 01 01")
GAME_DATA = bytes.fromhex("0005 0e 57434243")  # DS -> roboRIO TCP: game data "WCBC"
STDOUT = bytes.fromhex("000a 0c 3f800000 0001 686921")  # roboRIO -> DS TCP: "hi!"
DS, RIO = ("10.2.54.5", 57000), ("10.2.54.2", 1110)


def decode(path: Path, as_json: bool = False) -> tuple[int, list, str]:
    out, err = io.StringIO(), io.StringIO()
    code = run_pcap(str(path), as_json=as_json, out=out, err=err)
    lines = out.getvalue().splitlines()
    return code, [json.loads(line) for line in lines] if as_json else lines, err.getvalue()


# -- files built here ---------------------------------------------------------------------------
def pcap(records: list[tuple[float, bytes]], linktype: int, endian: str = "<", nano: bool = False) -> bytes:
    out = struct.pack(endian + "IHHiIII", 0xA1B23C4D if nano else 0xA1B2C3D4, 2, 4, 0, 0, 0xFFFF, linktype)
    for t, frame in records:
        sec = int(t)
        frac = round((t - sec) * (1e9 if nano else 1e6))
        out += struct.pack(endian + "IIII", sec, frac, len(frame), len(frame)) + frame
    return out


def _block(endian: str, block_type: int, body: bytes) -> bytes:
    body += b"\0" * (-len(body) % 4)
    length = len(body) + 12
    return struct.pack(endian + "II", block_type, length) + body + struct.pack(endian + "I", length)


def pcapng(interfaces: list[tuple[int, int | None]], packets: list[tuple[int, int, bytes]], endian: str) -> bytes:
    """A section of ``interfaces`` (link type, if_tsresol or None) and enhanced packet blocks
    (interface, timestamp in its units, frame); an interface index of -1 writes a simple
    packet block (no timestamp) for interface 0."""
    out = _block(endian, 0x0A0D0D0A, struct.pack(endian + "IHHq", 0x1A2B3C4D, 1, 0, -1))
    for linktype, tsresol in interfaces:
        options = b""
        if tsresol is not None:
            options = struct.pack(endian + "HH", 9, 1) + bytes([tsresol, 0, 0, 0]) + struct.pack(endian + "HH", 0, 0)
        out += _block(endian, 1, struct.pack(endian + "HHI", linktype, 0, 0) + options)
    for iface, stamp, frame in packets:
        if iface < 0:
            out += _block(endian, 3, struct.pack(endian + "I", len(frame)) + frame)
        else:
            out += _block(endian, 6, struct.pack(endian + "IIIII", iface, stamp >> 32, stamp & 0xFFFFFFFF,
                                                 len(frame), len(frame)) + frame)
    return out


def ethernet(ip: bytes, vlan: bool = False, ethertype: int = 0x0800) -> bytes:
    head = b"\x00\x80\x2f\x00\x00\x01" + b"\x00\x1b\x21\x00\x00\x02"
    if vlan:
        head += struct.pack(">HH", 0x8100, 7)
    return head + struct.pack(">H", ethertype) + ip


def sll2(ip: bytes) -> bytes:
    return struct.pack(">HHIHBB", 0x0800, 0, 2, 1, 0, 6) + b"\x00\x1b\x21\x00\x00\x02\x00\x00" + ip


def ipv6_udp(src: str, dst: str, sport: int, dport: int, payload: bytes) -> bytes:
    import ipaddress

    udp = struct.pack(">HHHH", sport, dport, 8 + len(payload), 0) + payload
    return (struct.pack(">IHBB", 6 << 28, len(udp), 17, 64) + ipaddress.IPv6Address(src).packed
            + ipaddress.IPv6Address(dst).packed + udp)


# -- the real capture -----------------------------------------------------------------------------
@pytest.mark.skipif(not CAPTURE.is_file(), reason=f"the real capture is not at {CAPTURE}")
def test_the_real_capture_prints_every_frc_packet_its_readme_counts():
    code, objs, err = decode(CAPTURE, as_json=True)
    assert code == 0 and err == ""
    packets, summary = objs[:-1], objs[-1]
    by_kind: dict[str, int] = {}
    for p in packets:
        by_kind[p["kind"]] = by_kind.get(p["kind"], 0) + 1
    # the README: 5,067 DS -> roboRIO on 1110, 4,352 roboRIO -> DS on 1150, about 1,670 TCP
    # frames on 1740 (tests/test_real_capture.py counts exactly 1,670); no FMS
    assert by_kind["ds-to-rio"] == 5067 and by_kind["rio-to-ds"] == 4352
    assert by_kind["ds-to-rio-tcp"] + by_kind["rio-to-ds-tcp"] == 1670 and len(by_kind) == 4
    assert summary["type"] == "summary" and summary["frc"] == len(packets) and summary["bad"] == 0
    assert summary["other"] > 0 and summary["tcp_lost"] == 0  # the laptop's other traffic, counted
    first = packets[0]
    assert (first["src"][0], first["dst"], first["from"], first["to_team"]) == \
        ("10.64.43.231", ["10.64.43.2", 1110], "ds", 6443)
    assert first["time"] == 0 and first["utc"].startswith("2021-06-01T20:0")
    assert [p["time"] for p in packets] == sorted(p["time"] for p in packets)
    # a TCP frame: the JSON fields `fieldbox decode --json` gives the same bytes
    version = next(p for p in packets if p["kind"] == "rio-to-ds-tcp" and p["fields"]["type"] == "VersionInfo")
    assert version["from"] == "robot" and version["src"][1] == 1740
    code, lines, _ = decode(CAPTURE)
    assert code == 0 and len(lines) == summary["frc"] + 1
    assert "10.64.43.231:60970 -> 10.64.43.2:1110 (ds 6443 -> robot 6443)  ds-to-rio  ControlPacket #2897" in lines[0]
    assert lines[-1].startswith("11,089 FRC packets (5,067 ds-to-rio, 4,352 rio-to-ds") and \
        lines[-1].endswith(f"{summary['other']:,} other packets (not printed)")


# -- fieldbox's own recordings ------------------------------------------------------------------
def test_a_pcap_fieldbox_records_prints_every_packet_it_holds_with_its_kind(tmp_path):
    # the loopback plan, as the app runs: the real ports on 127.TE.AM.x (packets are found by
    # their ports, so a run on made-up ports would print nothing and count every packet other)
    _, ring = run_field(LoopbackSim)
    path = tmp_path / "run.pcap"
    endpoints = Endpoints()
    written = [p for p in ring.packets() if not endpoints.route(p).duplicate]
    assert write_pcap(path, ring.packets(), Endpoints()) == len(written)
    code, objs, err = decode(path, as_json=True)
    assert code == 0 and err == ""
    printed = objs[:-1]
    assert [(p["kind"], p["length"]) for p in printed] == [(p.kind, len(p.data)) for p in written]
    kinds = {p["kind"] for p in printed}
    assert {"ds-to-rio", "rio-to-ds", "ds-to-rio-tcp", "rio-to-ds-tcp", "fms-to-ds", "ds-to-fms"} <= kinds
    assert all("error" not in p for p in printed)
    control = next(p for p in printed if p["kind"] == "ds-to-rio")
    assert (control["from"], control["from_team"], control["to"], control["to_team"]) == ("ds", 254, "robot", 254)
    assert objs[-1]["frc"] == len(written) and objs[-1]["other"] == 0


def test_a_cut_recording_prints_what_it_holds_then_one_clear_error(tmp_path):
    path = tmp_path / "cut.pcap"
    frames = [udp_datagram(DS, RIO, CONTROL, 1), udp_datagram(("10.2.54.2", 40000), ("10.2.54.5", 1150), STATUS, 2)]
    whole = pcap([(100.0, frames[0]), (100.02, frames[1])], 101)
    path.write_bytes(whole[:-5])  # the last record cut short, as a recording the app died in
    result = subprocess.run([sys.executable, "-m", "fieldbox", "decode", "--pcap", str(path)], cwd=ROOT,
                            capture_output=True, text=True, timeout=60)
    assert result.returncode == 1
    assert "Traceback" not in result.stderr
    offset = 24 + 16 + len(frames[0])
    assert result.stderr.strip() == (f"fieldbox decode: {path}: cut short at offset {offset}: the packet record "
                                     f"({len(frames[1])} bytes) needs {len(frames[1])} bytes, "
                                     f"{len(frames[1]) - 5} remain")
    lines = result.stdout.splitlines()
    assert "ds-to-rio  ControlPacket #1" in lines[0] and lines[1].startswith("1 FRC packets")
    # a record length no capture holds is refused before anything is allocated
    path.write_bytes(whole[:24] + struct.pack("<IIII", 0, 0, 0x7FFFFFFF, 0x7FFFFFFF) + b"x" * 100)
    code, lines, err = decode(path)
    assert code == 1 and "packet record at offset 24 says 2,147,483,647 bytes: over the 262,144-byte bound" in err
    path.write_bytes(b"hello, not a capture")
    code, _, err = decode(path)
    assert code == 1 and "not a pcap or pcapng file: magic 68656c6c at offset 0" in err


# -- what Wireshark and tcpdump write --------------------------------------------------------------
def test_pcapng_both_byte_orders_nanoseconds_ethernet_vlan_and_linux_cooked(tmp_path):
    for endian in "<>":
        control = udp_datagram(DS, RIO, CONTROL, 1)
        status = udp_datagram(("10.2.54.2", 40000), ("10.2.54.5", 1150), STATUS, 2)
        other = udp_datagram(("10.2.54.5", 5353), ("224.0.0.251", 5353), b"mdns", 3)
        data = pcapng([(1, 9), (276, None)],  # Ethernet in nanoseconds, SLL2 in microseconds
                      [(0, 1_700_000_000_000_000_000, ethernet(control, vlan=True)),
                       (1, 1_700_000_000_250_000, sll2(status)),
                       (0, 1_700_000_000_500_000_000, ethernet(other)),
                       (-1, 0, ethernet(control))], endian)
        path = tmp_path / f"x{endian == '<'}.pcapng"
        path.write_bytes(data)
        code, objs, err = decode(path, as_json=True)
        assert code == 0 and err == ""
        assert [(p["kind"], p["time"], p["abs_time"]) for p in objs[:-1]] == [
            ("ds-to-rio", 0, 1_700_000_000.0), ("rio-to-ds", 0.25, 1_700_000_000.25),
            ("ds-to-rio", 0.5, 1_700_000_000.5)]  # a simple packet block: the time of the one before
        assert objs[0]["fields"]["enabled"] is True and objs[1]["fields"]["battery"] == 12.5
        assert (objs[-1]["frc"], objs[-1]["other"]) == (3, 1)


def test_pcap_big_endian_nanoseconds_sll_and_ipv6(tmp_path):
    sll = struct.pack(">HHH8sH", 0, 1, 6, b"\x00\x1b\x21\x00\x00\x02\x00\x00", 0x86DD)
    frame = sll + ipv6_udp("fe80::1", "fe80::2", 57000, 1150, STATUS)
    path = tmp_path / "v6.pcap"
    path.write_bytes(pcap([(5.123456789, frame)], 113, endian=">", nano=True))
    code, lines, err = decode(path)
    assert code == 0 and err == ""
    assert lines[0].startswith("   0.000000  [fe80::1]:57000 -> [fe80::2]:1150 (robot -> ds)  rio-to-ds  "
                               "StatusPacket #1")
    code, objs, _ = decode(path, as_json=True)
    assert objs[0]["abs_time"] == pytest.approx(5.123456789, abs=1e-9)


def test_tcp_out_of_order_retransmitted_and_split_frames_print_once_each_in_order(tmp_path):
    rio = ("10.2.54.2", 1740)
    stream = GAME_DATA + b"\x00\x00" + GAME_DATA  # a frame, a keep-alive, a frame
    isn = 1000
    syn = tcp_segment(DS, rio, b"", isn, 0, 1)
    syn = syn[:33] + bytes([0x02]) + syn[34:]  # SYN instead of PSH|ACK (the checksum is not read)
    seg = [tcp_segment(DS, rio, stream[a:b], isn + 1 + a, 0, 2) for a, b in ((0, 4), (4, 9), (9, 16))]
    reply = tcp_segment(rio, DS, STDOUT, 5000, 0, 3)
    frames = [syn, seg[0], seg[2], seg[1], seg[2], seg[1], reply]  # out of order, then retransmitted
    path = tmp_path / "tcp.pcap"
    path.write_bytes(pcap([(10 + i / 10, f) for i, f in enumerate(frames)], 101))
    code, objs, err = decode(path, as_json=True)
    assert code == 0 and err == ""
    printed = [(p["kind"], p["time"], p["fields"]["type"]) for p in objs[:-1]]
    # the first frame and the keep-alive are whole when the late segment comes (the 4th
    # record, 0.3 s); the second frame then too: the segment held since 0.2 s completes it
    assert printed == [("ds-to-rio-tcp", 0.3, "GameData"), ("ds-to-rio-tcp", 0.3, "KeepAlive"),
                       ("ds-to-rio-tcp", 0.3, "GameData"), ("rio-to-ds-tcp", 0.6, "StdoutMessage")]
    assert objs[0]["fields"]["text"] == "WCBC" and objs[-1]["frc"] == 4
    assert objs[-1]["other"] == 1  # the SYN


def test_a_tcp_hole_never_filled_is_a_note_not_garbage(tmp_path):
    rio = ("10.2.54.2", 1740)
    records = [(1.0, tcp_segment(DS, rio, GAME_DATA, 1, 0, 1))]
    # the next segment is never captured; 70 later ones wait for it, then it is given up on
    records += [(2.0 + i, tcp_segment(DS, rio, GAME_DATA, 1 + len(GAME_DATA) * (i + 2), 0, 2 + i)) for i in range(70)]
    records.append((99.0, udp_datagram(DS, RIO, CONTROL, 99)))
    path = tmp_path / "hole.pcap"
    path.write_bytes(pcap(records, 101))
    code, lines, err = decode(path)
    assert code == 0
    assert [line.split("  ")[3] for line in lines[:2]] == ["ds-to-rio-tcp", "ds-to-rio"]
    assert lines[2].startswith("2 FRC packets")
    assert lines[3].startswith("TCP 10.2.54.5:57000 -> 10.2.54.2:1740: not framed from here on: a segment at "
                               "sequence number 8 never came (65 later segments held)")


def test_the_2010_protocol_on_the_same_ports_is_told_apart_by_length(tmp_path):
    from protocol.enums import AllianceStation
    from protocol.legacy import LegacyControlPacket, LegacyStatusPacket

    control = LegacyControlPacket(packet_index=5, enabled=True, team=294, station=AllianceStation.RED1).encode()
    status = LegacyStatusPacket(team=294, lcd=("hello",)).encode()
    path = tmp_path / "2010.pcap"
    path.write_bytes(pcap([(1.0, udp_datagram(("10.2.94.5", 1150), ("10.2.94.2", 1110), control, 1)),
                           (1.01, udp_datagram(("10.2.94.2", 1110), ("10.2.94.5", 1150), status, 2)),
                           (1.02, udp_datagram(DS, RIO, CONTROL, 3))], 101))
    code, objs, _ = decode(path, as_json=True)
    assert code == 0
    assert [(p["kind"], p["fields"].get("team")) for p in objs[:-1]] == [
        ("legacy-ds-to-robot", 294), ("legacy-robot-to-ds", 294), ("ds-to-rio", None)]
    assert (objs[0]["from"], objs[0]["from_team"]) == ("ds", 294)


def test_the_command_line_takes_pcap_or_as_and_hex_not_both(tmp_path):
    path = tmp_path / "one.pcap"
    path.write_bytes(pcap([(1.0, udp_datagram(DS, RIO, CONTROL, 1))], 101))
    both = subprocess.run([sys.executable, "-m", "fieldbox", "decode", "--pcap", str(path), "--as", "ds-to-rio"],
                          cwd=ROOT, capture_output=True, text=True, timeout=60)
    assert both.returncode == 2 and "--pcap reads packets from the capture" in both.stderr
    ok = subprocess.run([sys.executable, "-m", "fieldbox", "decode", "--pcap", str(path), "--json"],
                        cwd=ROOT, capture_output=True, text=True, timeout=60)
    assert ok.returncode == 0
    assert [json.loads(line)["type"] for line in ok.stdout.splitlines()] == ["packet", "summary"]
    missing = subprocess.run([sys.executable, "-m", "fieldbox", "decode", "--pcap", str(tmp_path / "nope.pcap")],
                             cwd=ROOT, capture_output=True, text=True, timeout=60)
    assert missing.returncode == 1 and "No such file" in missing.stderr and "Traceback" not in missing.stderr
