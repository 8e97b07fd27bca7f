"""A real NI Driver Station talking to a real roboRIO, replayed through fieldbox.

The capture: ``../shared/captures/ni-ds-roborio-2021.pcapng`` beside the repository (team
6443, roboRIO image 2020_v10, 116 s on 2021-06-01; see the captures README). It is reference
data and is not copied into the project: read where it lies, skipped when it is not there.

Every packet and TCP frame decodes, re-encodes byte-identical, is explained byte by byte, and
keeps no documented tag raw; and fieldbox's Driver Station, put in the real DS's state,
writes the real DS's bytes.
"""

from __future__ import annotations

import datetime as dt
from functools import lru_cache
from pathlib import Path

import pytest

from protocol import ds_to_rio, rio_to_ds
from protocol.enums import AllianceStation, JoystickType
from protocol.frames import MalformedTag
from protocol.framing import FrameDecoder
from protocol.kinds import coverage_gaps
from protocol.wire import Reader, UnknownTag
from roles.cores.core import Connect, Datagram, StreamSend
from roles.cores.ds import DriverStation

from . import pcapng

CAPTURE = Path(__file__).resolve().parents[1].parent / "shared" / "captures" / "ni-ds-roborio-2021.pcapng"
pytestmark = pytest.mark.skipif(
    not CAPTURE.is_file(),
    reason=f"the real capture is not at {CAPTURE} (it lives in shared/captures beside the repository)")

DS_HOST, RIO_HOST = "10.64.43.231", "10.64.43.2"
XBOX = "Controller (Xbox One For Windows)"


@lru_cache(maxsize=1)
def capture() -> dict:
    """The capture's DS -> roboRIO and roboRIO -> DS datagrams (frame number, bytes) and the
    TCP 1740 frames of each direction, in order."""
    control, status = [], []
    for u in pcapng.udp(CAPTURE):
        if u.src[0] == DS_HOST and u.dst == (RIO_HOST, 1110):
            control.append((u.number, u.payload))
        elif u.src[0] == RIO_HOST and u.dst == (DS_HOST, 1150):
            status.append((u.number, u.payload))
    to_rio, to_ds = [], []
    for stream in pcapng.streams(CAPTURE, 1740):
        frames = list(FrameDecoder("capture", 0x10001).feed(stream.data))
        (to_rio if stream.dst[1] == 1740 else to_ds).extend(frames)
    return {"control": control, "status": status, "to_rio": to_rio, "to_ds": to_ds}


def packet(frame: int) -> bytes:
    c = capture()
    return next(data for number, data in c["control"] + c["status"] if number == frame)


def test_the_capture_holds_what_its_readme_says():
    c = capture()
    assert (len(c["control"]), len(c["status"])) == (5067, 4352)
    assert len(c["to_rio"]) + len(c["to_ds"]) == 1670


def test_every_control_packet_decodes_and_re_encodes_identically():
    for number, data in capture()["control"]:
        p = ds_to_rio.decode_control(data)
        assert p.encode() == data, number
        assert not [t for t in p.tags if type(t) in (UnknownTag, MalformedTag)], number
        assert p == ds_to_rio.walk_control(Reader(data, ds_to_rio.CONTROL)), number
        assert not coverage_gaps(ds_to_rio.annotate_control(data), len(data)), number


def test_every_status_packet_decodes_with_no_documented_tag_kept_raw():
    # The real roboRIO's CPU tag (u8 count) used to be kept raw: 87 packets.
    kinds = set()
    for number, data in capture()["status"]:
        p = rio_to_ds.decode_status(data)
        assert p.encode() == data, number
        assert not [t for t in p.tags if type(t) is UnknownTag], number
        assert p == rio_to_ds.walk_status(Reader(data, rio_to_ds.STATUS)), number
        assert not coverage_gaps(rio_to_ds.annotate_status(data), len(data)), number
        kinds.update(type(t) for t in p.tags)
    assert kinds == {rio_to_ds.DiskInfo, rio_to_ds.CpuInfo, rio_to_ds.RamInfo, rio_to_ds.CanMetrics}


def test_every_tcp_frame_decodes_and_re_encodes_identically():
    c = capture()
    for decode, annotate, frames in ((ds_to_rio.decode_tcp, ds_to_rio.annotate_tcp, c["to_rio"]),
                                     (rio_to_ds.decode_tcp, rio_to_ds.annotate_tcp, c["to_ds"])):
        for frame in frames:
            message = decode(frame)
            assert message.encode() == frame
            assert type(message).__name__ != "UnknownFrame", frame.hex()
            assert not coverage_gaps(annotate(frame), len(frame))
    names = {type(rio_to_ds.decode_tcp(f)).__name__ for f in c["to_ds"]}
    assert {"StdoutMessage", "ErrorMessage", "VersionInfo"} <= names


# -- fieldbox's DS in the real DS's state writes the real DS's bytes ----------------------------
def real_ds(clock: dt.datetime | None = None, timezone: str = "UTC") -> DriverStation:
    """Team 6443 at blue 2 (the capture's station byte 04), disabled teleop."""
    return DriverStation(6443, (RIO_HOST, 1110), (RIO_HOST, 1740), station=AllianceStation.BLUE2,
                         clock=(lambda: clock) if clock else None, timezone_name=timezone)


def control_bytes(actions) -> bytes:
    (datagram,) = [a for a in actions if isinstance(a, Datagram)]
    return datagram.data


def test_date_and_timezone_after_the_robots_request():
    # Frame 2595: the roboRIO asks for the date (request byte 0x01); frame 2596: the DS's next
    # packet carries date 2021-06-01 20:06:04.227271 UTC (month 0-based) and time zone PST8PDT.
    asking, answer = packet(2595), packet(2596)
    assert rio_to_ds.decode_status(asking).request_date
    ds = real_ds(dt.datetime(2021, 6, 1, 20, 6, 4, 227271, tzinfo=dt.timezone.utc), "PST8PDT")
    ds.poll(1.0)
    ds.datagram("robot", asking, (RIO_HOST, 1110), 1.001)
    ours = control_bytes(ds.poll(1.02))
    # the sequence number counts this DS's own packets; every other byte is the real DS's
    assert ours[2:] == answer[2:]
    assert answer[6:] == bytes.fromhex("0b 0f 000377c7 04 06 14 01 05 79 08 10") + b"PST8PDT"


def test_a_resting_xbox_controller_in_slot_0():
    # Frame 7366: one joystick tag, the Xbox controller at rest (6 axes at 0, 16 buttons up,
    # POV centred), and no tag for the empty slots after it.
    ds = real_ds()
    ds.set_joystick(0, 6, 16, 1, 0.0, name=XBOX, is_xbox=True, joystick_type=JoystickType.XINPUT_GAMEPAD,
                    axis_types=(0, 1, 2, 3, 4, 5))
    ours = control_bytes(ds.poll(1.0))
    assert ours[2:] == packet(7366)[2:]
    assert packet(7366)[6:] == bytes.fromhex("0e 0c 06 000000000000 10 0000 01 ffff")


def test_no_joystick_no_joystick_tag():
    # Frame 1: the header alone (disabled teleop, request 0x10, blue 2).
    assert control_bytes(real_ds().poll(1.0))[2:] == packet(1)[2:] == bytes.fromhex("01 00 10 04")


def test_robot_tcp_on_connect_descriptors_match_info_and_game_data():
    # The second TCP connection (from frame 2695): six descriptors, empty match info and game
    # data; then, once the controller was seen, six descriptors again: slot 0 the Xbox
    # controller, slot 1 a device the real DS still lists by name only, slots 2-5 empty.
    frames = [f for f in capture()["to_rio"] if f != b"\x00\x00"]
    first, match_info, game_data, second = frames[:6], frames[6], frames[7], frames[8:14]
    assert match_info == bytes.fromhex("0006 07 00 00 0000 00") and game_data == bytes.fromhex("0001 0e")
    assert [ds_to_rio.decode_tcp(f).index for f in first + second] == [0, 1, 2, 3, 4, 5] * 2
    ds = real_ds()
    ds.set_joystick(0, 6, 16, 1, 0.0, name=XBOX, is_xbox=True, joystick_type=JoystickType.XINPUT_GAMEPAD,
                    axis_types=(0, 1, 2, 3, 4, 5))
    ds.set_joystick(1, 0, 0, 0, 0.0, name=XBOX, joystick_type=JoystickType.UNKNOWN, axis_types=())
    assert Connect("robot-tcp", (RIO_HOST, 1740)) in ds.poll(1.0)
    sent = [a.data for a in ds.stream_opened("robot-tcp", (RIO_HOST, 1740), 1.01) if isinstance(a, StreamSend)]
    assert sent == second + [match_info, game_data]
