"""``fieldbox replay FILE``: a capture played into the app's Inspector and Timeline.

A pcap or pcapng file (Wireshark's, tcpdump's, fieldbox's own recordings) is read whole before
the app opens, by the same reader as ``fieldbox decode --pcap`` (fieldbox/capread.py), so a bad
file is one line on stderr and exit code 1, never a screen that opens on nothing. A capture cut
short in its last packet is said (stderr, then a notification) and the packets before it play.

:class:`ReplayEngine` stands where a live field's engine stands: it has no sockets and binds
nothing. It hands each packet, when its recorded time comes, to the taps the inspector added
(one ``TapRecord`` a packet, as roles/runtime/shell.py gives its taps),
so the Inspector and the Timeline read a replay as they read a live field. Each packet is
tapped as its Driver Station saw it (``ds 6443``, link ``robot``, ``out`` for control), the
link names of fieldbox's own DS (roles/cores/ds.py): the timeline's lanes work unchanged. Who
is who comes from the ports (capread's kinds), the team from 10.TE.AM.x addresses.

Its clock is the capture's, in seconds from the first packet (Wireshark's relative time), and
moves at the replay's speed while it plays; :meth:`ReplayEngine.play` is called by the app's
10 Hz refresh. ``p`` pauses, ``.`` steps one packet, ``<`` ``>`` change the speed, ``b`` plays
from the beginning again.

:class:`ReplayApp` is the app with only those two tabs; Space and Enter are still the robot's
keys and say there is no robot.
"""

from __future__ import annotations

import os
import sys
import time
from concurrent.futures import Future
from dataclasses import dataclass, field
from typing import Any, Callable

from textual.binding import Binding
from textual.widgets import TabbedContent

from roles.cores.core import CommandError
from roles.runtime.engine import Engine
from roles.runtime.field import FieldConfig
from roles.runtime.shell import Tap, TapRecord

from . import capread
from .app import FieldboxApp, StatusLine
from .history import DsHistory
from .panels.base import Panel

#: The speeds ``<`` and ``>`` step through.
SPEEDS = (0.1, 0.25, 0.5, 1.0, 2.0, 5.0, 10.0, 50.0)
#: A capture file larger than this is refused before it is read: a replay holds its FRC
#: packets in memory (a field's capture of a whole event is cut first, e.g. with editcap).
MAX_FILE = 1 << 30
#: FRC packets held at most (each is held twice, as read and as tapped: some 400 bytes; the
#: inspector keeps the last 50,000 it was handed).
MAX_PACKETS = 500_000
#: Link types the reader takes (fieldbox/capread.py), by name for the refusal's line.
LINKTYPES = {
    capread.LINKTYPE_NULL: "BSD loopback", capread.LINKTYPE_ETHERNET: "Ethernet",
    capread.LINKTYPE_RAW: "raw IP", capread.LINKTYPE_LOOP: "OpenBSD loopback",
    capread.LINKTYPE_LINUX_SLL: "Linux cooked", capread.LINKTYPE_IPV4: "raw IPv4",
    capread.LINKTYPE_IPV6: "raw IPv6", capread.LINKTYPE_LINUX_SLL2: "Linux cooked v2",
}
#: Some link types a capture may have that no FRC packet is read from, for the refusal.
OTHER_LINKTYPES = {105: "IEEE 802.11 wireless", 127: "802.11 radiotap", 9: "PPP", 6: "Token Ring",
                   147: "a user link type", 220: "USB"}

#: What the DS role calls each kind's link and direction (roles/cores/ds.py KINDS,
#: roles/cores/legacy_ds.py), so the replay's links read as a live DS's.
DS_LINKS = {
    "ds-to-rio": ("robot", "out"), "rio-to-ds": ("robot", "in"),
    "ds-to-rio-tcp": ("robot-tcp", "out"), "rio-to-ds-tcp": ("robot-tcp", "in"),
    "fms-to-ds": ("fms", "in"), "ds-to-fms": ("fms-out", "out"),
    "fms-to-ds-tcp": ("fms-tcp", "in"), "ds-to-fms-tcp": ("fms-tcp", "out"),
    "legacy-ds-to-robot": ("robot", "out"), "legacy-robot-to-ds": ("robot", "in"),
    "legacy-dashboard": ("dashboard", "out"), "legacy-netconsole": ("netconsole", "in"),
}

NO_FIELD = "a replay: no field runs"


class ReplayError(ValueError):
    """The file cannot be replayed: one line says why."""


@dataclass
class Capture:
    """A capture's FRC packets, read whole."""

    path: str
    packets: list[capread.FrcPacket]
    first_time: float
    records: int
    other: int
    #: Why the file was not read to its end (a cut-short last packet), or None.
    cut: str | None = None
    notes: list[str] = field(default_factory=list)

    @property
    def duration(self) -> float:
        return self.packets[-1].time - self.first_time if self.packets else 0.0


def load(path: str) -> Capture:
    """Every FRC packet of the capture at ``path``; :class:`ReplayError` with one line if there
    is nothing to replay (not a capture, no FRC packet, a link type not read, too big)."""
    try:
        size = os.path.getsize(path)
        f = open(path, "rb")
    except OSError as exc:
        raise ReplayError(f"{path}: {exc.strerror or exc}") from None
    if size > MAX_FILE:
        f.close()
        raise ReplayError(f"{path}: {size:,} bytes: a replay reads captures up to {MAX_FILE:,} bytes "
                          "(cut it first, e.g. editcap -A/-B or -r)")
    reader = capread.Reader()
    packets: list[capread.FrcPacket] = []
    unread: dict[int, int] = {}  # link types no packet is read from -> records
    cut: str | None = None
    with f:
        try:
            for record in capread.records(f):
                reader.counts.records += 1
                if reader.counts.first_time is None:
                    reader.counts.first_time = record.time
                if record.linktype not in LINKTYPES:
                    unread[record.linktype] = unread.get(record.linktype, 0) + 1
                found = list(reader.feed(record))
                packets.extend(found)
                if len(packets) > MAX_PACKETS:
                    raise ReplayError(f"{path}: over {MAX_PACKETS:,} FRC packets: a replay holds them all "
                                      "(cut the capture first, e.g. editcap -c 1000000 FILE PART.pcapng)")
        except capread.CaptureError as exc:
            cut = str(exc)
        except OSError as exc:
            cut = f"read error: {exc.strerror or exc}"
    counts = reader.counts
    if not packets:
        if cut is not None:
            raise ReplayError(f"{path}: {cut}")
        if unread:
            lt = max(unread, key=lambda k: unread[k])
            name = OTHER_LINKTYPES.get(lt, "not one fieldbox reads")
            raise ReplayError(f"{path}: link type {lt} ({name}): a replay reads Ethernet, Linux cooked, raw IP "
                              "and loopback captures")
        if counts.records == 0:
            raise ReplayError(f"{path}: no packets in the capture")
        raise ReplayError(f"{path}: no FRC packets among its {counts.records:,} packets (FRC ports: UDP 1110, "
                          "1150, 1120, 1160, TCP 1740, 1750): nothing to replay")
    return Capture(path, packets, counts.first_time or packets[0].time, counts.records, counts.other, cut,
                   list(counts.notes))


# -- the engine ---------------------------------------------------------------------------------
@dataclass
class Replayed:
    """A role seen in the capture (where a live field has its core): its name and address."""

    name: str
    host: str


@dataclass
class ReplayStation:
    """A station as the panels read one (roles/runtime/field.py StationRoles): a DS seen in the
    capture and the robot it spoke to."""

    team: int
    ds: Replayed | None = None
    rio: Replayed | None = None
    ds_name: str = ""
    rio_name: str = ""


@dataclass
class ReplayField:
    """The field as the panels read it: the stations seen, no FMS core (an FMS's packets are
    on the DS's links)."""

    stations: list[ReplayStation]
    config: FieldConfig
    fms: Any = None
    fms_name: str = "fms"
    bound: dict = field(default_factory=dict)




@dataclass(frozen=True)
class _Tapped:
    """One packet as it is handed to the taps."""

    time: float  # from the capture's first packet
    role: str
    link: str
    direction: str
    kind: str
    data: bytes
    remote: tuple[str, int]
    local: tuple[str, int]


class ReplayEngine(Engine):
    """A capture played on a clock of its own; no sockets. ``clock``: the wall clock (tests
    give a fake one)."""

    def __init__(self, capture: Capture, *, speed: float = 1.0, paused: bool = False,
                 clock: Callable[[], float] = time.monotonic) -> None:
        self.capture = capture
        self.config = FieldConfig(roles=frozenset())
        self.stations: dict[str, ReplayStation] = {}
        self.tapped = [self._tapped(p) for p in capture.packets]
        self.field = ReplayField(list(self.stations.values()), self.config)  # type: ignore[assignment]
        #: The capture's first packet, Unix seconds: what the replay's clock counts from (a
        #: recording or an export of the replay keeps the capture's times, fieldbox/pcap.py).
        self.capture_start = float(capture.first_time)
        #: What the inspector's state line calls following the newest packet.
        self.follow_word = "REPLAY"
        self.speed = speed
        self.paused = paused
        self.position = 0  # packets handed to the taps
        self.time = 0.0  # the replay's clock: seconds from the capture's first packet
        self._clock = clock
        self._wall = clock()
        self._taps: list[Tap] = []

    def _tapped(self, p: capread.FrcPacket) -> _Tapped:
        """``p`` as its DS saw it; the DS (and its station) is found by address."""
        sender, receiver = capread.ROLES.get(p.kind, ("ds", "robot"))
        link, direction = DS_LINKS.get(p.kind, ("robot", "out"))
        ds_end, other_end = (p.src, p.dst) if direction == "out" else (p.dst, p.src)
        other_role = receiver if direction == "out" else sender
        team = capread.team_of(ds_end[0])
        if team is None and other_role != "fms":
            team = capread.team_of(other_end[0])
        name = f"ds {team}" if team is not None else f"ds {ds_end[0]}"
        st = self.stations.get(name)
        if st is None:
            st = self.stations[name] = ReplayStation(team or 0, ds=Replayed(name, ds_end[0]), ds_name=name)
        if other_role == "robot" and st.rio is None:
            rio = f"rio {team}" if team is not None else f"rio {other_end[0]}"
            st.rio, st.rio_name = Replayed(rio, other_end[0]), rio
        return _Tapped(p.time - self.capture.first_time, name, link, direction, p.kind, p.data,
                       other_end, ds_end)

    # -- the Engine's face -------------------------------------------------------------------
    def now(self) -> float:
        return self.time

    def views(self, now: float) -> Any:
        return self.field

    def submit(self, fn: Callable[[], Any], host: str | None = None) -> Future:
        future: Future = Future()
        future.set_exception(CommandError(NO_FIELD))
        return future

    def submit_command(self, command: Any) -> Future:
        return self.submit(lambda: None)

    def add_tap(self, tap: Tap) -> None:
        if tap not in self._taps:
            self._taps.append(tap)

    def remove_tap(self, tap: Tap) -> None:
        if tap in self._taps:
            self._taps.remove(tap)

    def stop(self) -> None:
        self._taps.clear()  # nothing runs: the app is closing

    # -- playing -----------------------------------------------------------------------------
    @property
    def total(self) -> int:
        return len(self.tapped)

    @property
    def ended(self) -> bool:
        return self.position >= len(self.tapped)

    def play(self) -> int:
        """Move the clock on by the wall time since the last call times the speed (not while
        paused) and hand over every packet due; how many."""
        wall = self._clock()
        elapsed, self._wall = max(0.0, wall - self._wall), wall
        if self.paused or self.ended or not self._taps:  # nothing plays before the inspector listens
            return 0
        self.time += elapsed * self.speed
        n = self._hand_until(self.time)
        if self.ended:
            self.time = self.tapped[-1].time
        return n

    def step(self) -> _Tapped | None:
        """Pause, and hand over the next packet (the clock moves to its time)."""
        self.paused = True
        if self.ended:
            return None
        p = self.tapped[self.position]
        self.time = max(self.time, p.time)
        self._emit(p)
        self.position += 1
        return p

    def toggle_pause(self) -> bool:
        """Pause or play; True: now paused."""
        self._wall = self._clock()  # the time paused does not count
        self.paused = not self.paused
        return self.paused

    def faster(self, steps: int) -> float:
        """The next speed up (``steps`` > 0) or down; the speed now."""
        at = min(range(len(SPEEDS)), key=lambda i: abs(SPEEDS[i] - self.speed))
        self.speed = SPEEDS[max(0, min(len(SPEEDS) - 1, at + steps))]
        return self.speed

    def rewind(self) -> None:
        """Back to the first packet (the app clears what the inspector held)."""
        self.position = 0
        self.time = 0.0
        self._wall = self._clock()

    def _hand_until(self, t: float) -> int:
        start = self.position
        tapped = self.tapped
        while self.position < len(tapped) and tapped[self.position].time <= t:
            self._emit(tapped[self.position])
            self.position += 1
        return self.position - start

    def _emit(self, p: _Tapped) -> None:
        for tap in list(self._taps):
            tap(TapRecord(p.role, p.link, p.direction, p.kind, p.data, p.remote, p.local, p.time))

    def position_text(self) -> str:
        """``packet 1,234 of 11,089 · 12.345 s of 116.2 s · 2x · playing``."""
        state = "the end (p plays it again)" if self.ended else "PAUSED" if self.paused else "playing"
        speed = f"{self.speed:g}x"
        return (f"packet {self.position:,} of {self.total:,} · {self.time:.3f} s of "
                f"{self.capture.duration:.1f} s · {speed} · {state}")


# -- the app ------------------------------------------------------------------------------------
class ReplayStatus(StatusLine):
    """The replay's position instead of a DS's state."""

    def refresh_view(self, engine: Any, now: float, stale: bool = False, pending: str = "",
                     pc: str = "") -> None:
        replay = getattr(engine, "engine", engine)
        if not isinstance(replay, ReplayEngine):
            return
        name = os.path.basename(replay.capture.path)
        text = f"REPLAY {name}   {replay.position_text()}"
        if text != self._shown:
            self._shown = text
            self.update(text, layout=False)


class _NoHistory(DsHistory):
    """A replay has no DS core to sample (the Charts tab is not shown)."""

    def sample(self, engine: Any, now: float) -> None:
        return None


def replay_panels() -> list[type[Panel]]:
    from .panels.inspector import InspectorPanel
    from .panels.timeline import TimelinePanel

    return [InspectorPanel, TimelinePanel]


class ReplayApp(FieldboxApp):
    """The app over a :class:`ReplayEngine`: the Inspector and the Timeline, the replay's
    position on the status line, its keys in the footer."""

    BINDINGS = [
        # the replay's keys come before a panel's own p (the view's pause) and before nothing
        # else: Space and Enter are taken earlier still (FieldboxApp.on_event)
        Binding("p", "replay_pause", "Pause/play", priority=True),
        Binding("full_stop", "replay_step", "Step", key_display=".", priority=True),
        Binding("less_than_sign", "replay_speed(-1)", "Slower", key_display="<", priority=True),
        Binding("greater_than_sign", "replay_speed(1)", "Faster", key_display=">", priority=True),
        Binding("b", "replay_rewind", "From the start", priority=True),
        Binding("e", "enable", "Enable", show=False),
        Binding("f8", "pick_roles", "Roles", show=False),
    ]

    def __init__(self, engine: ReplayEngine, *, theme_name: str | None = None, animate: bool = True,
                 pc_status: Any = None) -> None:
        super().__init__(lambda config: engine, engine.config, panel="inspector", theme_name=theme_name,
                         animate=animate, pc_status=pc_status)
        self.replay = engine
        self.history = _NoHistory()

    STATUS_LINE = ReplayStatus

    def tab_classes(self) -> list[type[Panel]]:
        return replay_panels()

    @staticmethod
    def _describe(config: FieldConfig) -> str:
        return "replay"

    def start_engine(self, config: FieldConfig) -> bool:
        """The replay's engine, made before the app: no field starts."""
        started = super().start_engine(config)
        self.sub_title = f"replay of {os.path.basename(self.replay.capture.path)}"
        return started

    def _first_hint(self) -> None:
        if self.replay.capture.cut is not None:
            self.notify(f"the capture is cut short ({self.replay.capture.cut}): the "
                        f"{self.replay.total:,} packets before it are replayed", severity="warning", timeout=15)
        capture = self.replay.capture
        other = f"; {capture.other:,} other packets are not shown" if capture.other else ""
        self.notify(f"A replay of {self.replay.total:,} FRC packets{other}. p plays and pauses, . steps one "
                    "packet, < > slower and faster, b from the start; F6 switches Inspector and Timeline.",
                    title="fieldbox replay", timeout=10)

    def refresh_views(self, tick: int | None = None) -> None:
        self.replay.play()  # what the wall clock says is due, at the replay's speed
        super().refresh_views(tick)

    # -- the replay's keys -------------------------------------------------------------------
    def action_replay_pause(self) -> None:
        if self.replay.ended:  # p at the end plays it again, from the start
            self.action_replay_rewind()
            self.replay.paused = True
        self.replay.toggle_pause()
        self.refresh_views()

    def action_replay_step(self) -> None:
        if self.replay.step() is None:
            self.notify("the end of the capture (b plays it from the start)", timeout=3)
            return
        self.refresh_views()
        self._show_newest()

    def action_replay_speed(self, steps: int) -> None:
        speed = self.replay.faster(steps)
        self.notify(f"replay at {speed:g}x", timeout=2)
        self.refresh_views()

    def action_replay_rewind(self) -> None:
        self.replay.rewind()
        inspector = self._inspector()
        if inspector is not None:
            inspector.action_clear()
        self.refresh_views()

    def _inspector(self) -> Any:
        try:
            return self.screen_stack[0].query_one("#panel-inspector")
        except Exception:  # noqa: BLE001 - not mounted yet
            return None

    def _show_newest(self) -> None:
        """The packet just stepped to, shown: its link in the inspector, its bytes explained;
        the timeline drawn again (it draws once a second of the capture's clock)."""
        inspector = self._inspector()
        if inspector is None:
            return
        ring = inspector.ring
        newest = max((r[-1] for r in ring.links.values() if r), key=lambda p: p.seq, default=None)
        shown = self.query_one(TabbedContent).active
        if newest is not None and shown == "inspector":
            inspector.show_packet(newest)
        if shown == "timeline":
            timeline = self.screen_stack[0].query_one("#panel-timeline")
            reading = self.read_now()
            if reading is not None:
                timeline.redraw(reading, reading.now())  # type: ignore[attr-defined]

    # -- what a replay has not ----------------------------------------------------------------
    def action_estop(self) -> None:
        self.notify("a replay: no robot to e-stop", severity="warning", timeout=3)

    async def action_disable(self) -> None:
        self.notify("a replay: no robot to disable", severity="warning", timeout=3)

    def action_enable(self) -> None:
        self.notify("a replay: no robot to enable", severity="warning", timeout=3)

    def action_pick_roles(self) -> None:
        self.notify(f"{NO_FIELD}: quit (ctrl+q) and start fieldbox to run one", severity="warning")

    def action_restart_field(self) -> None:
        self.notify(NO_FIELD, severity="warning")

    def action_tab_key(self, key: str) -> None:
        if key != "f6":
            self.notify(f"{NO_FIELD}: F6 switches the Inspector and the Timeline", severity="warning", timeout=3)
            return
        active = self.query_one(TabbedContent).active
        self.action_show_tab("timeline" if active == "inspector" else "inspector")


def run_replay(path: str, *, speed: float = 1.0, paused: bool = False, theme: str | None = None,
               err: Any = None) -> int:
    """``fieldbox replay FILE``: 1 with one line on stderr if it cannot be replayed."""
    err = err or sys.stderr
    try:
        capture = load(path)
    except ReplayError as exc:
        print(f"fieldbox replay: {exc}", file=err)
        return 1
    if capture.cut is not None:
        print(f"fieldbox replay: {path}: {capture.cut}: the {len(capture.packets):,} FRC packets before it "
              "are replayed", file=err)
    app = ReplayApp(ReplayEngine(capture, speed=speed, paused=paused), theme_name=theme)
    app.run()
    return 0
