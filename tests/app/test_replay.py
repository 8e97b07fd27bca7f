"""``fieldbox replay FILE``: a capture played into the Inspector and the Timeline (issue 32, item 2).

On the real NI DS <-> roboRIO capture (``shared/captures`` beside the repository, skipped when
absent, never copied), on a pcap fieldbox records in the test, and on hostile files. The app
runs on a fake wall clock: a test moves it and the replay plays that far.
"""

from __future__ import annotations

import struct
import subprocess
import sys
from pathlib import Path

import pytest

from fieldbox.capture import Endpoints
from fieldbox.panels.inspector import InspectorPanel
from fieldbox.panels.timeline import TimelineView
from fieldbox.pcap import write_pcap
from fieldbox.replay import ReplayApp, ReplayEngine, ReplayError, load

from .helpers import PC, ROOT
from .test_capture import LoopbackSim, run_field

pytestmark = pytest.mark.usefixtures("no_real_joysticks")

SIZE = (160, 50)
NAME = "ni-ds-roborio-2021.pcapng"
#: The real capture, found in shared/captures beside the repository (or beside the worktree
#: folder a repository's branch is checked out in).
CAPTURE = next((p / "shared" / "captures" / NAME for p in ROOT.parents
                if (p / "shared" / "captures" / NAME).is_file()), ROOT.parent / "shared" / "captures" / NAME)
needs_capture = pytest.mark.skipif(not CAPTURE.is_file(), reason=f"the real capture is not at {CAPTURE}")


class Clock:
    """The wall clock the replay reads, moved by the test."""

    def __init__(self) -> None:
        self.t = 1000.0

    def __call__(self) -> float:
        return self.t


def replay_app(path: Path, **kw) -> tuple[ReplayApp, ReplayEngine, Clock]:
    clock = Clock()
    engine = ReplayEngine(load(str(path)), clock=clock, **kw)
    return ReplayApp(engine, animate=False, pc_status=lambda: PC), engine, clock


async def play(app: ReplayApp, pilot, clock: Clock, seconds: float) -> None:
    """``seconds`` of wall time pass, and the app's refresh plays them."""
    clock.t += seconds
    app.refresh_views()
    await pilot.pause()


def screen_text(app: ReplayApp) -> str:
    return "\n".join("".join(segment.text for segment in strip) for strip in app.screen._compositor.render_strips())


def inspector(app: ReplayApp) -> InspectorPanel:
    return app.query_one("#panel-inspector", InspectorPanel)


def notes(app: ReplayApp) -> list[str]:
    return [n.message for n in app._notifications]


# -- the real capture -----------------------------------------------------------------------------
@needs_capture
async def test_the_real_capture_replays_whole_into_the_inspector():
    app, engine, clock = replay_app(CAPTURE)
    async with app.run_test(size=SIZE) as pilot:
        await pilot.pause()
        await play(app, pilot, clock, 200.0)  # the capture is 116 s long, at its recorded pace
        insp = inspector(app)
        ring = insp.ring
        assert engine.position == engine.total == 11_089
        assert ring.seq == 11_089 and len(ring) == 11_089
        by_kind: dict[str, int] = {}
        for key, packets in ring.links.items():
            by_kind[key[3]] = by_kind.get(key[3], 0) + len(packets)
        assert by_kind["ds-to-rio"] == 5_067 and by_kind["rio-to-ds"] == 4_352
        assert by_kind["ds-to-rio-tcp"] + by_kind["rio-to-ds-tcp"] == 11_089 - 5_067 - 4_352
        # the links as a live DS names them, its team from 10.64.43.x
        assert set(ring.links) == {("ds 6443", "robot", "out", "ds-to-rio"), ("ds 6443", "robot", "in", "rio-to-ds"),
                                   ("ds 6443", "robot-tcp", "out", "ds-to-rio-tcp"),
                                   ("ds 6443", "robot-tcp", "in", "rio-to-ds-tcp")}
        # the list of the link shown holds all of its packets, the last one 115.8 s in
        assert len(insp.packets.source) == 5_067
        assert "packet 11,089 of 11,089 · 115.8" in str(app.query_one("#status-line").render())
        # and the timeline draws the DS between its robot's lanes
        await pilot.press("f6")
        await pilot.pause()
        view = app.query_one(TimelineView)
        assert view.hops and {(h.src, h.dst) for h in view.hops} == {("ds", "rio"), ("rio", "ds")}
        assert view.names["ds"] == "DS 6443" and view.names["rio"] == "roboRIO 6443"
        assert str(app.query_one("#timeline-head").render()).startswith("REPLAY, a picture a second")


@needs_capture
async def test_a_user_at_160x50_reads_a_real_control_packet_byte_by_byte():
    app, engine, clock = replay_app(CAPTURE, paused=True)
    async with app.run_test(size=SIZE) as pilot:
        await pilot.pause()
        await pilot.press("full_stop")  # the capture's first FRC packet: the DS's control packet #2897
        await pilot.pause()
        text = screen_text(app)
        assert "REPLAY ni-ds-roborio-2021.pcapng   packet 1 of 11,089 · 0.000 s of 115.8 s · 1x · PAUSED" in text
        assert "ds 6443 robot out ds-to-rio" in text
        assert "Packets · ds 6443 robot out ds-to-rio · ControlPacket" in text
        assert "#2897: no e-stop, no FMS, disabled, teleop" in text
        assert "0b 51 01 00 10 04" in text  # the bytes, in the hex pane
        assert "sequence = 2897" in text and "station = B2" in text  # the fields
        assert "bytes 0-1  sequence = 2897  sequence number, echoed by the robot" in text  # the cursor's meaning
        assert "p Pause/play" in text and ". Step" in text and "< Slower" in text and "> Faster" in text


# -- the keys -------------------------------------------------------------------------------------
@needs_capture
async def test_pause_step_and_speed_keys_do_what_they_say():
    app, engine, clock = replay_app(CAPTURE, paused=True)
    times = [p.time for p in engine.tapped]
    async with app.run_test(size=SIZE) as pilot:
        await pilot.pause()
        await play(app, pilot, clock, 5.0)  # opened paused: nothing plays
        assert inspector(app).ring.seq == 0
        await pilot.press("full_stop", "full_stop", "full_stop")  # three steps: three packets
        await pilot.pause()
        insp = inspector(app)
        assert insp.ring.seq == 3 and engine.paused
        shown = insp.packets.selected()
        assert shown is not None and shown.seq == 3 and shown.time == times[2]  # the third, shown
        assert "packet 3 of 11,089" in str(app.query_one("#status-line").render())
        await play(app, pilot, clock, 5.0)  # still paused after a step
        assert insp.ring.seq == 3
        await pilot.press("p")  # plays: a second of wall time is a second of the capture
        await play(app, pilot, clock, 1.0)
        at = times[2] + 1.0
        assert insp.ring.seq == sum(1 for t in times if t <= at)
        await pilot.press("greater_than_sign")  # 2x: a second is two
        await play(app, pilot, clock, 1.0)
        assert engine.speed == 2.0
        assert insp.ring.seq == sum(1 for t in times if t <= at + 2.0)
        await pilot.press("greater_than_sign", "greater_than_sign")  # 5x, 10x
        await play(app, pilot, clock, 1.0)
        assert engine.speed == 10.0 and "10x · playing" in str(app.query_one("#status-line").render())
        assert insp.ring.seq == sum(1 for t in times if t <= at + 12.0)
        await pilot.press("p")
        seen = insp.ring.seq
        await play(app, pilot, clock, 30.0)
        assert insp.ring.seq == seen and "PAUSED" in str(app.query_one("#status-line").render())
        await pilot.press("less_than_sign")
        assert engine.speed == 5.0


@needs_capture
async def test_space_and_enter_say_there_is_no_robot_and_the_replay_goes_on():
    app, engine, clock = replay_app(CAPTURE)
    async with app.run_test(size=SIZE) as pilot:
        await pilot.pause()
        said: list[str] = []
        # one key at a time: a screen keeps only its newest toasts (fieldbox/toasts.py)
        for key in ("space", "enter", "e", "f1", "f8"):
            await pilot.press(key)
            await pilot.pause()
            said += notes(app)
        assert "a replay: no robot to e-stop" in said and "a replay: no robot to disable" in said
        assert any(n.startswith("a replay: no field runs") for n in said)
        await play(app, pilot, clock, 1.0)
        assert app.is_running and inspector(app).ring.seq > 0
        # only what makes sense: two tabs
        assert [p.ID for p in app.query("Panel")] == ["inspector", "timeline"]  # type: ignore[attr-defined]


# -- fieldbox's own recordings ----------------------------------------------------------------------
def recording(tmp_path: Path) -> tuple[Path, list]:
    _, ring = run_field(LoopbackSim)
    endpoints = Endpoints()
    written = [p for p in ring.packets() if not endpoints.route(p).duplicate]
    path = tmp_path / "run.pcap"
    write_pcap(path, ring.packets(), Endpoints())
    return path, written


async def test_a_recording_fieldbox_made_replays_with_its_team_and_links(tmp_path):
    path, written = recording(tmp_path)
    app, engine, clock = replay_app(path)
    async with app.run_test(size=SIZE) as pilot:
        await pilot.pause()
        await play(app, pilot, clock, 10.0)
        ring = inspector(app).ring
        assert ring.seq == len(written) > 100
        kinds = {key[3] for key in ring.links}
        assert {"ds-to-rio", "rio-to-ds", "ds-to-fms", "fms-to-ds", "ds-to-rio-tcp", "rio-to-ds-tcp"} <= kinds
        assert {key[0] for key in ring.links} == {"ds 254"}  # 127.2.54.x: team 254
        assert sorted(p.data for p in ring.packets()) == sorted(p.data for p in written)


# -- bad captures ---------------------------------------------------------------------------------
def run_cli(path: Path) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "fieldbox", "replay", str(path)], capture_output=True, text=True,
                          timeout=60, cwd=ROOT, stdin=subprocess.DEVNULL)


def pcap_header(linktype: int) -> bytes:
    return struct.pack("<IHHiIII", 0xA1B2C3D4, 2, 4, 0, 0, 0xFFFF, linktype)


@pytest.mark.parametrize("name, content, said", [
    ("notes.txt", b"hello, this is not a capture\n", "not a pcap or pcapng file: magic 68656c6c at offset 0"),
    ("empty.pcap", b"", "not a capture: 0 bytes"),
    ("header-only.pcap", pcap_header(1), "no packets in the capture"),
    ("wifi.pcap", pcap_header(105) + struct.pack("<IIII", 1, 0, 4, 4) + b"abcd",
     "link type 105 (IEEE 802.11 wireless): a replay reads Ethernet, Linux cooked, raw IP and loopback captures"),
    ("huge-record.pcap", pcap_header(1) + struct.pack("<IIII", 1, 0, 0x7FFFFFFF, 0x7FFFFFFF),
     "packet record at offset 24 says 2,147,483,647 bytes"),
    ("cut.pcap", pcap_header(1) + struct.pack("<IIII", 1, 0, 60, 60) + b"\0" * 10, "cut short at offset 24"),
])
def test_a_bad_capture_is_one_line_and_exit_code_1(tmp_path, name, content, said):
    path = tmp_path / name
    path.write_bytes(content)
    done = run_cli(path)
    assert done.returncode == 1
    lines = done.stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"fieldbox replay: {path}: ") and said in lines[0], done.stderr
    assert "Traceback" not in done.stderr and done.stdout == ""


def test_a_capture_without_frc_packets_says_so(tmp_path):
    frame = b"\xff" * 12 + b"\x08\x06" + b"\0" * 28  # an ARP frame
    path = tmp_path / "arp.pcap"
    path.write_bytes(pcap_header(1) + struct.pack("<IIII", 1, 0, len(frame), len(frame)) + frame)
    with pytest.raises(ReplayError, match=r"no FRC packets among its 1 packets .*nothing to replay"):
        load(str(path))


async def test_a_truncated_last_packet_is_said_and_the_rest_replayed(tmp_path):
    path, written = recording(tmp_path)
    raw = path.read_bytes()
    cut = tmp_path / "cut.pcap"
    cut.write_bytes(raw[:-5])  # the last record loses its last five bytes
    capture = load(str(cut))
    assert capture.cut is not None and capture.cut.startswith("cut short at offset")
    # every packet but the last is there (a TCP frame may need the lost segment: at most one more)
    assert len(written) - 2 <= len(capture.packets) <= len(written) - 1
    app, engine, clock = replay_app(cut)
    async with app.run_test(size=SIZE) as pilot:
        await pilot.pause()
        await play(app, pilot, clock, 10.0)
        assert inspector(app).ring.seq == len(capture.packets)
        assert any(n.startswith("the capture is cut short (cut short at offset") and "are replayed" in n
                   for n in notes(app))



async def test_a_replay_exported_again_keeps_the_capture_s_times_and_bytes(tmp_path):
    path, _ = recording(tmp_path)
    original = load(str(path)).packets
    app, engine, clock = replay_app(path)
    async with app.run_test(size=SIZE) as pilot:
        await pilot.pause()
        await play(app, pilot, clock, 10.0)
        out = tmp_path / "again.pcap"
        assert inspector(app).export(out) == len(original)
        assert "REPLAY" in str(app.query_one("#inspector-state").render())  # not LIVE: nothing is live
    again = load(str(out)).packets
    assert [(p.kind, p.data) for p in again] == [(p.kind, p.data) for p in original]
    assert all(abs(a.time - b.time) < 1e-5 for a, b in zip(again, original))


async def test_p_at_the_end_plays_the_capture_again_from_the_start(tmp_path):
    path, written = recording(tmp_path)
    app, engine, clock = replay_app(path)
    async with app.run_test(size=SIZE) as pilot:
        await pilot.pause()
        await play(app, pilot, clock, 10.0)
        assert engine.ended and "the end (p plays it again)" in str(app.query_one("#status-line").render())
        await pilot.press("p")
        await pilot.pause()
        # from the start: the first packet (at 0 s) again, and what was shown before is gone
        assert not engine.paused and engine.position <= 1 and len(inspector(app).ring) == engine.position
        await play(app, pilot, clock, 10.0)
        assert len(inspector(app).ring) == len(written)


def test_a_tcpdump_capture_on_linux_cooked_headers_replays(tmp_path):
    """``tcpdump -i any`` writes Linux cooked (SLL) headers, not Ethernet."""
    from fieldbox.pcap import udp_datagram

    control = bytes.fromhex("0001 01 04 10 00")
    status = bytes.fromhex("0001 01 04 32 0c80 00")
    ds, rio = ("10.2.54.5", 57000), ("10.2.54.2", 1110)
    frames = [udp_datagram(ds, rio, control, 1), udp_datagram(("10.2.54.2", 1150), ("10.2.54.5", 1150), status, 2)]
    raw = pcap_header(113)
    for i, ip in enumerate(frames):
        frame = struct.pack(">HHH8sH", 0, 1, 6, b"\0" * 8, 0x0800) + ip
        raw += struct.pack("<IIII", 100, i * 20_000, len(frame), len(frame)) + frame
    path = tmp_path / "any.pcap"
    path.write_bytes(raw)
    engine = ReplayEngine(load(str(path)), clock=Clock(), paused=True)
    got: list = []
    engine.add_tap(got.append)
    engine.step(), engine.step()
    assert [(r.role, r.link, r.direction, r.kind, r.data, round(r.time, 6)) for r in got] == [
        ("ds 254", "robot", "out", "ds-to-rio", control, 0.0), ("ds 254", "robot", "in", "rio-to-ds", status, 0.02)]
    assert (got[1].remote, got[1].local) == (("10.2.54.2", 1150), ("10.2.54.5", 1150))  # as the DS saw them


def test_a_capture_over_the_size_bound_is_refused_before_it_is_read(tmp_path, monkeypatch):
    from fieldbox import replay

    path, _ = recording(tmp_path)
    monkeypatch.setattr(replay, "MAX_FILE", 1000)
    with pytest.raises(ReplayError, match=r"bytes: a replay reads captures up to 1,000 bytes \(cut it first"):
        load(str(path))


@needs_capture
async def test_i_on_the_timeline_opens_the_packet_picked_after_steps_on_the_timeline():
    app, engine, clock = replay_app(CAPTURE, paused=True)
    async with app.run_test(size=SIZE) as pilot:
        await pilot.pause()
        await pilot.press("full_stop")  # the inspector shows the first packet
        await pilot.pause()
        await pilot.press("f6")  # the timeline, while the capture plays on ten seconds
        await pilot.press("p")
        await play(app, pilot, clock, 10.0)
        await pilot.press("p")
        await pilot.press("full_stop")
        await pilot.pause()
        picked = app.query_one(TimelineView).selected()
        assert picked is not None and picked.packet.time > 9.0
        await pilot.press("i")
        await pilot.pause()
        shown = inspector(app).packets.selected()
        assert shown is not None and shown.seq == picked.packet.seq  # that packet, not an older one
        assert f"at {picked.packet.time:.3f} s" in str(app.query_one("#inspector-hex").border_title)


async def test_the_replay_keys_type_into_a_path_prompt(tmp_path):
    """p . < > b are the replay's on its screen, but letters in a dialog's text box: a path
    to export to has them."""
    from textual.widgets import Input

    path, _ = recording(tmp_path)
    app, engine, clock = replay_app(path, paused=True)
    async with app.run_test(size=SIZE) as pilot:
        await pilot.pause()
        await pilot.press("X")  # export to a path of your choosing
        await pilot.pause()
        box = app.screen.query_one(Input)
        box.value = ""
        await pilot.press("b", "p", ".", "p", "greater_than_sign")
        await pilot.pause()
        assert box.value == "bp.p>"
        assert engine.position == 0 and engine.paused and engine.speed == 1.0


def test_a_capture_of_too_many_frc_packets_is_refused_with_how_to_cut_it(tmp_path, monkeypatch):
    from fieldbox import replay

    path, written = recording(tmp_path)
    monkeypatch.setattr(replay, "MAX_PACKETS", 100)
    with pytest.raises(ReplayError, match=r"over 100 FRC packets: a replay holds them all \(cut the capture first"):
        load(str(path))
