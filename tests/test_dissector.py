"""``fieldbox dissector``: the Wireshark Lua plugin made from protocol/, held to ``fieldbox
decode --pcap --json`` field by field with tshark.

tshark is needed (CI's .ci/run installs it; ``sudo apt-get install -y tshark`` here); point
FIELDBOX_TSHARK at one that is not on the PATH. Without it these tests are skipped, saying so.
"""

from __future__ import annotations

import io
import json
import math
import os
import shutil
import struct
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest

from fieldbox import capread
from fieldbox.decode_cmd import run_pcap
from fieldbox.dissector import build_kind, expected_fields, value_abbrevs
from fieldbox.pcap import tcp_segment, udp_datagram
from protocol import ds_to_fms, fms_to_ds, rio_to_ds
from protocol.enums import AllianceStation, StationStatus

from .test_real_capture import CAPTURE

ROOT = Path(__file__).resolve().parent.parent
TSHARK = os.environ.get("FIELDBOX_TSHARK") or shutil.which("tshark")

pytestmark = pytest.mark.skipif(TSHARK is None, reason="tshark is not installed (CI installs it; "
                                "`sudo apt-get install -y tshark`, or set FIELDBOX_TSHARK)")


@pytest.fixture(scope="module")
def plugin(tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("lua") / "frc.lua"
    result = subprocess.run([sys.executable, "-m", "fieldbox", "dissector", "-o", str(path)], cwd=ROOT,
                            capture_output=True, text=True, timeout=300)
    assert result.returncode == 0, result.stderr
    assert f"wrote {path}" in result.stderr
    return path


# -- reading both sides ---------------------------------------------------------------------------
def tshark_json(plugin: Path, capture: Path) -> list[dict[str, Any]]:
    result = subprocess.run([TSHARK, "-r", str(capture), "-X", f"lua_script:{plugin}", "-T", "json",
                             "--no-duplicate-keys", "-o", "tcp.desegment_tcp_streams:TRUE"],
                            capture_output=True, encoding="utf-8", errors="replace", timeout=600)
    assert "Lua" not in result.stderr, result.stderr  # the plugin loaded ...
    assert "Lua Error" not in result.stdout and "dissector error" not in result.stdout  # ... and never raised
    return json.loads(result.stdout)


def frc_values(layers: dict[str, Any]) -> tuple[list[tuple[str, str]], list[tuple[str, str]]]:
    """The ``frc.*`` fields of one frame in tree order, and its expert infos (name, message)."""
    values: list[tuple[str, str]] = []
    experts: list[tuple[str, str]] = []

    def walk(obj: Any) -> None:
        if isinstance(obj, list):
            for v in obj:
                walk(v)
        elif isinstance(obj, dict):
            if "_ws.expert.message" in obj:
                names = [k for k in obj if k.startswith("frc.") and k in ("frc.error", "frc.malformed",
                                                                           "frc.warning", "frc.not_dissected")]
                messages = obj["_ws.expert.message"]
                for name, msg in zip(names * len(messages) if isinstance(messages, list) else names,
                                     messages if isinstance(messages, list) else [messages]):
                    experts.append((name, msg))
            for k, v in obj.items():
                if k.startswith("frc.") and isinstance(v, (str, list)) and not k.endswith("_tree"):
                    for one in v if isinstance(v, list) else [v]:
                        if isinstance(one, str):
                            values.append((k, one))
                        else:
                            walk(one)
                elif isinstance(v, (dict, list)):
                    walk(v)

    walk(layers.get("frc", {}))
    return values, experts


def fieldbox_packets(capture: Path) -> dict[int, list[dict[str, Any]]]:
    """``fieldbox decode --pcap --json`` of the capture, by frame number (1-based)."""
    out, err = io.StringIO(), io.StringIO()
    assert run_pcap(str(capture), as_json=True, out=out, err=err) == 0, err.getvalue()
    with open(capture, "rb") as f:
        frame_of = {r.offset: n for n, r in enumerate(capread.records(f), 1)}
    by_frame: dict[int, list[dict[str, Any]]] = {}
    for line in out.getvalue().splitlines():
        obj = json.loads(line)
        if obj["type"] == "packet":
            by_frame.setdefault(frame_of[obj["offset"]], []).append(obj)
    return by_frame


_MODELS: dict[str, Any] = {}


def model(kind: str):
    if kind not in _MODELS:
        _MODELS[kind] = build_kind(kind)
    return _MODELS[kind]


def opaque_classes(m) -> set[str]:
    return {st.cls for st in m.structs.values() if st.opaque}


def _same(a: str, b: str) -> bool:
    b = b.replace("\x00", "\\0")  # the plugin shows a NUL as \0: a Wireshark string would end there
    if a == b or a.replace(":", "") == b:
        return True
    try:
        return math.isclose(float(a), float(b), rel_tol=1e-5, abs_tol=1e-9)  # tshark prints 6 digits
    except ValueError:
        return False


def compare(plugin: Path, capture: Path) -> tuple[dict[str, int], int]:
    """Assert that every frame's plugin fields equal fieldbox's, field by field: the number of
    packets compared, by kind, and of fields."""
    shown = {int(p["_source"]["layers"]["frame"]["frame.number"]): p["_source"]["layers"]
             for p in tshark_json(plugin, capture)}
    counted: dict[str, int] = {}
    fields_compared = 0
    for number, packets in fieldbox_packets(capture).items():
        values, experts = frc_values(shown[number])
        compared: set[str] = set()
        expected: list[tuple[str, str]] = []
        for p in packets:
            m = model(p["kind"])
            compared |= value_abbrevs(m)
            counted[p["kind"]] = counted.get(p["kind"], 0) + 1
            if "error" in p:
                assert any(name == "frc.error" for name, _ in experts), (number, p["error"], experts)
                continue
            expected += expected_fields(m, p["fields"])
            if p["fields"]["type"] not in opaque_classes(m):  # bytes only: nothing to warn about
                warned = [m for name, m in experts if name == "frc.warning"]
                assert len(warned) == len(p["warnings"]), (number, p["warnings"], warned)
        if all("error" not in p for p in packets):
            assert not [m for name, m in experts if name == "frc.error"], (number, experts)
        got = [(k, v) for k, v in values if k in compared]
        expected = [(k, v) for k, v in expected if k in compared]
        fields_compared += len(expected)
        mine = {k: [v for kk, v in got if kk == k] for k, _ in got + expected}
        theirs = {k: [v for kk, v in expected if kk == k] for k, _ in got + expected}
        for k in mine:
            assert len(mine[k]) == len(theirs[k]) and all(_same(a, b) for a, b in zip(mine[k], theirs[k])), \
                (number, k, mine[k], theirs[k])
    return counted, fields_compared


# -- captures --------------------------------------------------------------------------------------
def pcap(frames: list[bytes]) -> bytes:
    out = struct.pack("<IHHiIII", 0xA1B2C3D4, 2, 4, 0, 0, 0xFFFF, 101)  # raw IP, as fieldbox records
    for i, frame in enumerate(frames):
        out += struct.pack("<IIII", 100 + i // 100, i % 100 * 10000, len(frame), len(frame)) + frame
    return out


class Link:
    """One TCP connection's two directions, segment by segment, and UDP beside it."""

    def __init__(self, client: tuple[str, int], server: tuple[str, int]) -> None:
        self.client, self.server = client, server
        self.seq = {True: 1000, False: 900000}
        self.frames: list[bytes] = []

    def tcp(self, from_client: bool, data: bytes) -> None:
        src, dst = (self.client, self.server) if from_client else (self.server, self.client)
        self.frames.append(tcp_segment(src, dst, data, self.seq[from_client], self.seq[not from_client],
                                       len(self.frames)))
        self.seq[from_client] += len(data)

    def udp(self, src: tuple[str, int], dst: tuple[str, int], data: bytes) -> None:
        self.frames.append(udp_datagram(src, dst, data, len(self.frames)))


# -- the tests ---------------------------------------------------------------------------------------
@pytest.mark.skipif(not CAPTURE.exists(), reason=f"the real capture is not here ({CAPTURE}; see its README)")
def test_the_real_capture_shows_every_packet_as_fieldbox_decodes_it(plugin):
    counted, fields = compare(plugin, CAPTURE)
    # the README's counts: 5,067 DS -> roboRIO, 4,352 roboRIO -> DS, 1,670 TCP frames on 1740
    assert counted["ds-to-rio"] == 5067 and counted["rio-to-ds"] == 4352
    assert counted["ds-to-rio-tcp"] + counted["rio-to-ds-tcp"] == 1670
    assert fields > 150_000  # every joystick axis, button word, battery, CPU load ... compared (171,782)


@pytest.mark.parametrize("legacy", [False, True], ids=["today", "2010"])
def test_a_capture_fieldbox_records_shows_every_packet_as_fieldbox_decodes_it(plugin, tmp_path, legacy):
    from fieldbox.capture import Endpoints
    from fieldbox.pcap import write_pcap

    from .app.test_capture import LoopbackSim, run_field

    _, ring = run_field(LoopbackSim, legacy=legacy)
    path = tmp_path / "run.pcap"
    assert write_pcap(path, ring.packets(), Endpoints()) > 200
    counted, fields = compare(plugin, path)
    if legacy:  # the 2010 protocol on the same ports 1110/1150, told apart by length
        assert set(counted) == {"legacy-ds-to-robot", "legacy-robot-to-ds", "legacy-dashboard", "legacy-netconsole"}
    else:
        assert set(counted) == {"ds-to-rio", "rio-to-ds", "ds-to-rio-tcp", "rio-to-ds-tcp", "ds-to-fms", "fms-to-ds",
                                "ds-to-fms-tcp", "fms-to-ds-tcp"}
    # The 2010 packets field by field too (tests/test_dissector_2010.py has their corners): 10,088
    # fields, where bytes only would be about 300.
    assert fields > (9000 if legacy else 1000)


DS, FMS = ("10.2.54.5", 57000), ("10.0.100.5", 1750)
FMS_UDP = ("10.0.100.5", 50000)
# Cheesy Arena's control packet (tests/protocol/test_fms_to_ds.py CHEESY_CONTROL)
CONTROL = bytes.fromhex("0102 00 06 00 04 02 001c 01 000001f4 03 02 0d 0e 06 7d 000f")


def fms_link() -> Link:
    """The 2027 DS hello and every FMS tag and frame, split over segments as TCP may."""
    link = Link(DS, FMS)
    hello = ds_to_fms.DsHello.for_team(254, udp_port=1121).encode()
    link.tcp(True, hello[:3])  # a frame over two segments: reassembled
    link.tcp(True, hello[3:])
    link.tcp(False, fms_to_ds.HelloReply(AllianceStation.BLUE1, StationStatus.GOOD, 1, 254).encode()
             + fms_to_ds.EventCode("CMP").encode())  # two frames in one segment
    link.udp(FMS_UDP, ("10.2.54.5", 1120), CONTROL + fms_to_ds.GameDataTag("LRL").encode())  # FMS Lite
    link.udp(FMS_UDP, ("10.2.54.5", 1121), CONTROL + bytes.fromhex("0a20") + b"ABCDEFGHI")  # 9: kept raw
    link.udp(("10.2.54.5", 1145), ("10.0.100.5", 1160), ds_to_fms.DsStatusPacket(
        sequence=1, robot_comms=True, enabled=True, team=254, battery=12.5,
        tags=(ds_to_fms.CommsMetrics(3, 500, 14), ds_to_fms.EmptyTag(), ds_to_fms.LaptopMetrics(80, 12))).encode())
    link.tcp(True, ds_to_fms.LogData((ds_to_fms.LogRecord(10, 2, 12.25, ds_teleop=True, robot_teleop=True,
                                                          can_utilization=1.5, signal_db=20.5, bandwidth=3.0),)).encode())
    link.tcp(True, ds_to_fms.ErrorEventData((ds_to_fms.ErrorEvent(3_000_000_000, 123, "brownout"),)).encode()
             + ds_to_fms.DeviceVersion(2, "", "21.0").encode() + ds_to_fms.DsPing().encode() + b"\x00\x00")
    link.tcp(False, fms_to_ds.StationInfo(AllianceStation.RED1, StationStatus.WAITING).encode()
             + fms_to_ds.ChallengeQuestion().encode() + fms_to_ds.GameData("LRL").encode()
             + fms_to_ds.DeviceVersion(0, None, "2015 Update 6").encode())
    link.tcp(True, ds_to_fms.ChallengeResponse("R2-D2").encode() + ds_to_fms.TeamNumber(254).encode())
    return link


def test_the_2027_hello_and_every_fms_frame_show_as_fieldbox_decodes_them(plugin, tmp_path):
    path = tmp_path / "fms.pcap"
    path.write_bytes(pcap(fms_link().frames))
    counted, _ = compare(plugin, path)
    assert counted == {"ds-to-fms-tcp": 8, "fms-to-ds-tcp": 6, "fms-to-ds": 2, "ds-to-fms": 1}
    values, _ = frc_values(tshark_json(plugin, path)[1]["_source"]["layers"])
    assert ("frc.dsfmstcp.ds_hello.team_text", "254") in values  # reassembled from two segments
    assert ("frc.dsfmstcp.ds_hello.udp_port", "1121") in values
    values, _ = frc_values(tshark_json(plugin, path)[3]["_source"]["layers"])
    assert ("frc.fms.game_data_tag.text", "LRL") in values


# A roboRIO status with a PDP tag: sixteen 10-bit currents packed in 21 bytes (rio_to_ds.PdpLog)
PDP_STATUS = rio_to_ds.StatusPacket(sequence=7, battery=12.5, tags=(rio_to_ds.PdpLog(
    currents=tuple(k * 61 for k in range(16)), unknown_head=1, unknown_tail=b"\x0a\x0b\x0c", pad1=5, pad2=10),)).encode()


def test_a_pdp_tag_shows_each_of_its_sixteen_currents(plugin, tmp_path):
    link = Link(("10.2.54.2", 1110), ("10.2.54.5", 1150))
    link.udp(link.client, link.server, PDP_STATUS)
    path = tmp_path / "pdp.pcap"
    path.write_bytes(pcap(link.frames))
    assert compare(plugin, path)[0] == {"rio-to-ds": 1}
    values, _ = frc_values(tshark_json(plugin, path)[0]["_source"]["layers"])
    assert [v for k, v in values if k == "frc.rio.pdp_log.currents"] == [str(k * 61) for k in range(16)]
    assert ("frc.rio.pdp_log.pad2", "10") in values


# LibDS's control packet: a joystick tag whose size is one too big (tests/test_decode_cli.py)
LIBDS_2015 = bytes.fromhex("0010 01 04 80 00 0d 0c 04 00000000 0c 0001 01 ffff")


def test_a_malformed_tag_and_a_bad_packet_get_expert_info_not_a_lua_error(plugin, tmp_path):
    link = Link(DS, ("10.2.54.2", 1740))
    link.udp(DS, ("10.2.54.2", 1110), LIBDS_2015)
    link.udp(DS, ("10.2.54.2", 1110), bytes.fromhex("0001 01 04 10 07"))  # station 7: no such station
    link.udp(("10.2.54.2", 1110), ("10.2.54.5", 1150), bytes.fromhex("0001 01 04 32 3c80 00"))  # 60.5 V: a warning
    link.tcp(False, bytes.fromhex("0002 0c 00"))  # a stdout frame of 1 byte: no room for its time stamp
    path = tmp_path / "bad.pcap"
    path.write_bytes(pcap(link.frames))
    counted, _ = compare(plugin, path)  # the header and the fields around them still shown
    assert counted == {"ds-to-rio": 2, "rio-to-ds": 1, "rio-to-ds-tcp": 1}
    frames = [frc_values(p["_source"]["layers"]) for p in tshark_json(plugin, path)]
    malformed = [m for name, m in frames[0][1] if name == "frc.malformed"]
    assert malformed and "tags[0]" in malformed[0]
    assert ("frc.ds.enabled", "1") in frames[0][0] and ("frc.ds.type", "MalformedTag") in frames[0][0]
    assert any(name == "frc.error" and "station" in m for name, m in frames[1][1])
    assert any(name == "frc.warning" and "battery" in m for name, m in frames[2][1])
    assert any(name == "frc.error" for name, m in frames[3][1])


def test_the_command_writes_one_plugin_to_stdout_or_a_file_and_says_why_it_cannot(tmp_path):
    result = subprocess.run([sys.executable, "-m", "fieldbox", "dissector"], cwd=ROOT, capture_output=True,
                            text=True, timeout=300)
    assert result.returncode == 0 and result.stdout.startswith("-- FRC Driver Station")
    assert "Generated by `fieldbox dissector`" in result.stdout and "1110" in result.stdout
    assert 'DissectorTable.get("udp.port")' in result.stdout and "dissect_tcp_pdus" in result.stdout
    bad = subprocess.run([sys.executable, "-m", "fieldbox", "dissector", "-o", str(tmp_path / "no" / "frc.lua")],
                         cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert bad.returncode == 1 and bad.stderr.strip().count("\n") == 0
    assert "fieldbox dissector:" in bad.stderr and "No such file" in bad.stderr


def damaged_packets(seed: int, count: int) -> list[bytes]:
    """``count`` packets of every kind (tests/test_decode_cli.py's vectors, the 2027 tags, a
    LibDS joystick), each damaged one to three times: a byte set, a cut, bytes added (a TCP
    frame's size kept right, so its payload is what is damaged)."""
    from random import Random

    from .test_decode_cli import VECTORS

    rng = Random(seed)
    udp = {"ds-to-rio": 1110, "rio-to-ds": 1150, "ds-to-fms": 1160, "fms-to-ds": 1121}
    tcp = {"ds-to-rio-tcp": (True, 1740), "rio-to-ds-tcp": (False, 1740), "ds-to-fms-tcp": (True, 1750),
           "fms-to-ds-tcp": (False, 1750)}
    base = [(k, bytes.fromhex(v.replace(" ", ""))) for k, v in VECTORS.items() if k in udp or k in tcp] + [
        ("fms-to-ds", CONTROL + bytes.fromhex("04 20 4c524c")),
        ("ds-to-fms", bytes.fromhex("0001 00 24 00fe 0c80 06 01 0003 01f4 05 00 03 02 1122")),
        ("ds-to-fms-tcp", ds_to_fms.DsHello.for_team(254).encode()),
        ("fms-to-ds-tcp", fms_to_ds.HelloReply(AllianceStation.BLUE1, StationStatus.GOOD, 1, 254).encode()),
        ("ds-to-rio", LIBDS_2015), ("rio-to-ds", PDP_STATUS)]
    frames: list[bytes] = []
    for i in range(count):
        kind, good = base[rng.randrange(len(base))]
        data = bytearray(good)
        for _ in range(rng.randint(1, 3)):
            c = rng.random()
            if c < 0.5:
                data[rng.randrange(len(data))] = rng.randrange(256)
            elif c < 0.7:
                data = data[:max(1, rng.randrange(len(data) + 1))]  # Wireshark hands no empty datagram on
            else:
                data += bytes(rng.randrange(256) for _ in range(rng.randint(1, 6)))
        if kind in udp:
            link = Link(("10.2.54.5", 5000 + i), ("10.2.54.2", udp[kind]))
            link.udp(link.client, link.server, bytes(data))
        else:
            from_client, port = tcp[kind]
            if len(data) >= 2:
                data[0:2] = (len(data) - 2).to_bytes(2, "big")
            link = Link(("10.2.54.5", 6000 + i), ("10.2.54.2", port))
            link.tcp(from_client, bytes(data))
        frames += link.frames
    return frames


def test_damaged_packets_of_every_kind_show_as_fieldbox_decodes_them_or_as_an_error(plugin, tmp_path):
    # 400 packets, bytes set, cut and added: each either shows every field fieldbox decodes
    # from it (tags kept raw or malformed where it keeps them so) or, where fieldbox refuses
    # it, the plugin's error expert info: never a Lua error, never fields fieldbox would not show.
    path = tmp_path / "damaged.pcap"
    path.write_bytes(pcap(damaged_packets(seed=27, count=400)))
    counted, fields = compare(plugin, path)
    assert sum(counted.values()) > 350 and len(counted) == 8 and fields > 1000
