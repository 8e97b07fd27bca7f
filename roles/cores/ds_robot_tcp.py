"""The Driver Station's robot TCP client (conn ``"robot-tcp"``, to the robot's port 1740).

Closed, it asks for a connection (:class:`~roles.cores.core.Connect`) every ``TCP_RETRY``
seconds. Open, it sends the joystick descriptors, match info and game data whenever they
change (all three on every new connection, match info and game data empty when there are
none, as a real NI DS does), and keeps what the robot sends: console lines, versions, fault
counters. A frame that breaks the framing closes the connection.
"""

from __future__ import annotations

import math
from typing import Any

from protocol import rio_to_ds
from protocol.ds_to_rio import GameData, JoystickDescriptor, MatchInfo
from protocol.framing import FrameDecoder

from .core import Action, Address, Close, Connect, Events, LinkStats, Stream, StreamSend, decode_frames
from .views import RobotTcpView

ROBOT_TCP = "robot-tcp"
TCP_RETRY = 1.0
CONSOLE_LINES = 2000
MAX_TEXT = 4096  # characters kept of one console line
MAX_VERSIONS = 64
MAX_NAME = 64
#: Robot TCP frames above this are a framing error (the connection is dropped). The wire
#: allows 64 KiB; a real robot's largest frame is an error with its call stack, a few KiB.
MAX_ROBOT_FRAME = 0x8000


def _clip(text: str, n: int) -> str:
    return text if len(text) <= n else text[:n] + "…"


class RobotTcpClient:
    """The robot TCP connection of one DS. ``uses_tcp`` False (the 2010 protocol): it never connects."""

    def __init__(self, address: Address, events: Events, *, uses_tcp: bool = True) -> None:
        self.address: Address = address
        self.events = events
        self.stats = LinkStats(ROBOT_TCP)
        self.state = "closed"  # closed | connecting | open
        self._retry_at = -math.inf if uses_tcp else math.inf
        self._decoder: FrameDecoder | None = None
        self.match_info: MatchInfo | None = None
        self.game_data: str | None = None
        self._match_info_dirty = False
        self._game_data_dirty = False
        self.console: Stream[tuple[float, str, str]] = Stream(CONSOLE_LINES)  # (time, level, text)
        self.versions: dict[str, str] = {}
        self.faults = {"comms": 0, "12v": 0, "6v": 0, "5v": 0, "3.3v": 0}
        self.usage_reports = 0
        self.unknown_frames = 0

    @property
    def console_total(self) -> int:
        """Console lines ever added: a reader's cheap "anything new?"."""
        return self.console.total

    def view(self) -> RobotTcpView:
        return RobotTcpView(self.address, self.state, self.console.view(), tuple(self.versions.items()),
                            tuple(self.faults.items()), self.usage_reports, self.unknown_frames, self.match_info,
                            self.game_data)

    @property
    def dirty(self) -> bool:
        """Match info or game data changed since they last went out."""
        return self._match_info_dirty or self._game_data_dirty

    def next_deadline(self) -> float | None:
        return self._retry_at if self.state == "closed" else None

    # -- the connection ----------------------------------------------------------------------------
    def poll(self, now: float) -> list[Action]:
        """The connection to ask for, when closed and the retry is due."""
        if self.state == "closed" and now >= self._retry_at:
            self.state = "connecting"
            return [Connect(ROBOT_TCP, self.address)]
        return []

    def opened(self, peer: Address, now: float) -> None:
        self.state = "open"
        self._decoder = FrameDecoder(ROBOT_TCP, MAX_ROBOT_FRAME)
        self.stats.connected = True
        self.events.add(now, f"robot TCP connected ({peer[0]}:{peer[1]})")
        self._match_info_dirty = self._game_data_dirty = True

    def closed(self, reason: str, now: float) -> None:
        if self.state == "closed":
            return
        if self.state == "open":
            self.events.add(now, f"robot TCP closed: {reason}")
        self.state = "closed"
        self._retry_at = now + TCP_RETRY
        self._decoder = None
        self.stats.connected = False

    def set_address(self, address: Address, now: float) -> list[Action]:
        """Another robot: an open or opening connection is closed, and the new one asked for at once."""
        if address == self.address:
            return []
        self.address = address
        if self.state == "closed":
            return []
        self.closed("robot address changed", now)
        self._retry_at = now
        return [Close(ROBOT_TCP, "robot address changed")]

    def sends(self, descriptors: list[JoystickDescriptor]) -> list[Action]:
        """The frames due on the open connection: ``descriptors`` (the joystick slots', when they
        changed), then match info and game data when they changed."""
        frames = [d.encode() for d in descriptors]
        # Match info and game data go out on connect even when there are none, empty, as a
        # real NI DS sends them (00 06 07 00 00 0000 00 and 00 01 0e, the 2021 capture).
        if self._match_info_dirty:
            frames.append((self.match_info or MatchInfo()).encode())
        if self._game_data_dirty:
            frames.append(GameData(self.game_data or "").encode())
        self._match_info_dirty = self._game_data_dirty = False
        for f in frames:
            self.stats.sent(len(f))
        return [StreamSend(ROBOT_TCP, f, "ds-to-rio-tcp") for f in frames]

    def data(self, data: bytes, now: float) -> list[Action]:
        if self.state != "open" or self._decoder is None:
            return []
        messages, error = decode_frames(self._decoder, data, rio_to_ds.decode_tcp, self.stats, now)
        for msg in messages:
            self._on_frame(msg, now)
        if error is not None:
            self.events.add(now, f"robot TCP sent a bad frame, closing it: {error}")
            self.closed("bad frame", now)
            return [Close(ROBOT_TCP, f"bad frame: {error}")]
        return []

    # -- what goes out -------------------------------------------------------------------------------
    def set_match_info(self, info: MatchInfo | None) -> None:
        if info != self.match_info:
            self.match_info = info
            self._match_info_dirty = True

    def set_game_data(self, text: str) -> None:
        if text != self.game_data:
            self.game_data = text
            self._game_data_dirty = True

    # -- what comes in ---------------------------------------------------------------------------------
    def _on_frame(self, msg: Any, now: float) -> None:
        kind = type(msg)
        if kind is rio_to_ds.StdoutMessage:
            self.add_console_line(now, "stdout", msg.text)
        elif kind is rio_to_ds.ErrorMessage:
            where = f" ({msg.location})" if msg.location else ""
            code = f"[{msg.error_code}] " if msg.error_code else ""
            self.add_console_line(now, "error" if msg.is_error else "warning", f"{code}{msg.details}{where}")
        elif kind is rio_to_ds.VersionInfo:
            if not msg.is_end_of_list and (msg.name in self.versions or len(self.versions) < MAX_VERSIONS):
                self.versions[_clip(msg.name, MAX_NAME)] = _clip(msg.version, MAX_NAME)
        elif kind is rio_to_ds.DisableFaults:
            self.faults["comms"], self.faults["12v"] = msg.comms, msg.rail_12v
        elif kind is rio_to_ds.RailFaults:
            self.faults["6v"], self.faults["5v"], self.faults["3.3v"] = msg.rail_6v, msg.rail_5v, msg.rail_3v3
        elif kind is rio_to_ds.RadioEvents:
            self.add_console_line(now, "radio", msg.text)
        elif kind is rio_to_ds.UsageReport:
            self.usage_reports += 1
        elif kind is not rio_to_ds.KeepAlive:
            self.unknown_frames += 1

    def add_console_line(self, now: float, level: str, text: str) -> None:
        self.console.append((now, level, _clip(text.rstrip("\r\n"), MAX_TEXT)))
