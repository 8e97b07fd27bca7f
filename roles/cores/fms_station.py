"""One FMS alliance station (roles/cores/fms.py), in its parts, and what its row says.

A station is who should be there (its team), and four parts, each reset on its own terms:

* :class:`StationLogin`: the DS's TCP login holding the station (its connection, its
  ownership state, its challenge). A new one each time a login leaves or the team changes.
* :class:`DsReport` (roles/cores/views.py): what the DS's latest UDP status said. Frozen, and
  a new one replaces it on each status packet (or when the DS is lost), so nothing is ever
  half updated, and the station's view holds the very same one.
* :class:`FieldCommands`: what the field commands (bypass, e-stop, a-stop, the enable it
  computes). These outlive a DS: an e-stop holds through a login or a team change.
* :class:`DsTcpReports`: what the DS sent on TCP (log data, versions, error events).

The refusals counted for the station (logins and status from elsewhere) stay with it for
the whole run: they are the field's record, not the DS's.

:func:`readiness` says, in one state and its words, what a station's row shows: the FMS
panel maps the state to a colour, and the start box lists :meth:`FieldManagementSystem.start_refusals`.
"""

from __future__ import annotations

import enum
from collections import deque
from dataclasses import dataclass, field
from typing import Hashable

from protocol.ds_to_fms import DsHello, ErrorEvent, LogRecord, UsageReport
from protocol.enums import AllianceStation
from protocol.fms_to_ds import DeviceVersion

from .core import Address, LinkStats
from .ownership import CHALLENGE_TIMEOUT, Challenge, Owner
from .views import DsReport

LOG_RECORDS = 1000    # log-data records kept per station (a match at 4 per second)
ERROR_EVENTS = 200    # error/event entries kept per station
#: A DS status this long after its period began has seen the field's enable (the FMS sends it at once).
HEARD_AFTER = 0.05


@dataclass(eq=False)
class StationLogin:
    """The DS's TCP login that holds the station (all None: no DS logged in for its team)."""

    conn: Hashable | None = None
    peer: Address | None = None
    status: str | None = None                 # "good" / "bad": what station info told the DS
    wrong_station: AllianceStation | None = None  # where its address says it is, when bad
    owner: Owner = Owner.EMPTY                # roles/cores/ownership.py: empty / live / lost
    login_at: float | None = None             # when the login holding the station came
    challenge: Challenge = Challenge.NONE     # none / sent / right / wrong / late
    challenge_value: int | None = None
    challenge_at: float | None = None         # when the question went out
    challenge_answer: str | None = None       # the answer received
    status_port: int | None = None            # ds_port=None: the one port its status is taken from
    #: The 2027 FIRST Driver Station's hello, when the login was one (None: the NI DS's team
    #: number): its control goes to the port the hello named, its game data in the control packet.
    hello: DsHello | None = None

    @property
    def ds_kind(self) -> str | None:
        """Which DS holds the station, in the FMS tab's words: "NI DS" or "2027 DS" (None: none)."""
        if self.conn is None:
            return None
        return "2027 DS" if self.hello is not None else "NI DS"

    @property
    def trusted(self) -> bool:
        """Whether the field may enable this login: the NI DS once it answered the challenge
        right; the 2027 DS on its hello, as it is asked no question (no source says it answers
        one, and Cheesy Arena asks neither DS)."""
        return self.hello is not None or self.challenge.trusted


@dataclass(eq=False)
class FieldCommands:
    """What the field commands the station: kept through logins and team changes (an e-stop
    latches until the match is reset or the next one is set up)."""

    estop: bool = False
    estop_by: str | None = None               # who e-stopped it: "FMS" (the field's x) or "DS" (mid-match)
    astop: bool = False
    bypass: bool = False
    enabled: bool = False                     # computed by the FMS's _sync, the one place that decides it
    control_sequence: int = 0


@dataclass(eq=False)
class DsTcpReports:
    """What the station's DS reported on TCP 1750, bounded."""

    log_data: LogRecord | None = None
    log_records: deque[LogRecord] = field(default_factory=lambda: deque(maxlen=LOG_RECORDS))
    versions: dict[str, DeviceVersion] = field(default_factory=dict)
    error_events: deque[ErrorEvent] = field(default_factory=lambda: deque(maxlen=ERROR_EVENTS))
    usage_report: UsageReport | None = None


@dataclass(eq=False)
class Station:
    """One alliance station: who should be there, and its parts (see the module docstring)."""

    station: AllianceStation
    team: int | None = None
    link: LinkStats = field(default_factory=lambda: LinkStats("fms"))
    login: StationLogin = field(default_factory=StationLogin)
    report: DsReport = field(default_factory=DsReport)
    commands: FieldCommands = field(default_factory=FieldCommands)
    tcp: DsTcpReports = field(default_factory=DsTcpReports)
    # Refusals: status from elsewhere is counted in link.foreign_packets.
    refused_logins: int = 0                   # logins for this team refused: its DS was live
    # ...of which status that came while no DS was logged in: a real DS sends status before its
    # login is answered (Cheesy Arena drops it unsaid), so at every start: logged, not flagged
    unclaimed_status: int = 0
    last_refused: str | None = None           # the address refused last

    def __post_init__(self) -> None:
        self.link = LinkStats(f"fms-{self.label}")

    @property
    def label(self) -> str:
        return self.station.label

    @property
    def name(self) -> str:
        """``R2 (254)``: how events and refusals name a station."""
        return f"{self.label} ({self.team if self.team is not None else 'empty'})"

    @property
    def tcp_connected(self) -> bool:
        return self.login.conn is not None

    @property
    def ds_link(self) -> bool:
        """The DS is linked: logged in on TCP and its UDP status is arriving."""
        return self.login.conn is not None and self.report.udp_link

    def forget_ds(self) -> None:
        """Forget everything the last team's DS did and said (the station got a new team):
        its login, its report and its TCP reports. What the field commands stays, and so do
        the link's counters and the refusals."""
        self.login = StationLogin()
        self.report = DsReport()
        self.tcp = DsTcpReports()

    @property
    def estop_status(self) -> str | None:
        """What e-stops this station, in words for its row (None: nothing): the field's own
        e-stop ("FMS e-stop"), its DS's e-stop in the match, which the field latched ("DS
        e-stop"), or its DS reporting an e-stop the field does not hold: a robot e-stopped in
        an earlier match (or before this one) stays e-stopped until its code restarts, as a
        real roboRIO does, whatever the field says ("robot still e-stopped")."""
        if self.commands.estop:
            return "DS e-stop" if self.commands.estop_by == "DS" else "FMS e-stop"
        if self.report.ds_estop and self.report.udp_link:
            return "robot still e-stopped"
        return None


def station_of_team(stations: list[Station], team: int | None) -> Station | None:
    """The station whose team is ``team`` (None: none, or ``team`` is None)."""
    if team is None:
        return None
    for st in stations:
        if st.team == team:
            return st
    return None


class Readiness(str, enum.Enum):
    """What a station's row says it is, the first that holds, in this order."""

    EMPTY = "empty"                   # no team
    BYPASSED = "bypassed"
    WRONG_STATION = "wrong-station"   # its DS logged in from another station's address
    NO_DS = "no-ds"                   # no DS logged in for its team
    WRONG_ANSWER = "wrong-answer"     # its DS answered the challenge wrong
    NO_ANSWER = "no-answer"           # its DS did not answer the challenge in time
    ASKED = "asked"                   # its DS was asked the challenge and has not answered yet
    NO_STATUS = "no-status"           # its DS logged in, but no UDP status arrives
    ESTOPPED = "estopped"             # the field's e-stop, its DS's in the match, or the robot's latch
    NO_ROBOT = "no-robot"             # its DS has no robot link
    READY = "ready"                   # no match runs, and nothing above holds
    HELD = "held"                     # a match runs and the field does not enable it (an a-stop, the pause)
    RUNNING = "running"               # the field enables it and its DS reports its robot enabled
    ENABLING = "enabling"             # the field enables it; no report from its DS since the period began
    HELD_BY_DS = "held-by-ds"         # the field enables it; its DS holds its robot disabled


def readiness(st: Station, running: bool, period_start: float | None) -> tuple[Readiness, str]:
    """A station's state and its words for its row (``running``, ``period_start``: the
    match's). A running row says what its robot is as its DS last reported (DS status comes
    every 500 ms): "enabling" until a report made since the period began, then "running" or
    "held by its DS"."""
    login, report = st.login, st.report
    estop = st.estop_status
    if st.team is None:
        return Readiness.EMPTY, "empty"
    if st.commands.bypass:
        return Readiness.BYPASSED, "bypassed"
    if login.status == "bad":
        where = login.wrong_station.label if login.wrong_station else "?"
        return Readiness.WRONG_STATION, f"WRONG STATION ({where})"
    if login.conn is None:
        return Readiness.NO_DS, "no DS"
    if login.challenge is Challenge.WRONG:
        return Readiness.WRONG_ANSWER, "WRONG CHALLENGE ANSWER"
    if login.challenge is Challenge.LATE:
        return Readiness.NO_ANSWER, "NO CHALLENGE ANSWER"
    if not login.trusted:
        return Readiness.ASKED, "challenge asked"
    if not report.udp_link:
        return Readiness.NO_STATUS, "DS logged in, no status"
    if estop is not None:
        return Readiness.ESTOPPED, estop
    if not report.robot_link:
        return Readiness.NO_ROBOT, "no robot"
    if not running:
        return Readiness.READY, "ready"
    if not st.commands.enabled:
        return Readiness.HELD, "held"
    if report.ds_enabled:
        return Readiness.RUNNING, "running"
    if period_start is not None and (report.last_udp or 0.0) < period_start + HEARD_AFTER:
        return Readiness.ENABLING, "enabling"
    return Readiness.HELD_BY_DS, "held by its DS"  # Enter on the DS holds its robot for the period


#: What a station in each state says when a start is refused ("{where}": the station its DS
#: logged in from); a station in any other state (or bypassed) lets a match start. Cheesy
#: Arena refuses a start until every station's DS is connected or bypassed, as this does.
START_REFUSALS: dict[Readiness, str] = {
    Readiness.WRONG_STATION: "DS at the wrong station ({where}) and not bypassed",
    Readiness.NO_DS: "not connected and not bypassed",
    Readiness.WRONG_ANSWER: "its DS answered the challenge wrong; not bypassed",
    Readiness.NO_ANSWER: f"its DS did not answer the challenge within {CHALLENGE_TIMEOUT:g} s; not bypassed",
    Readiness.ASKED: "waiting for its DS's challenge answer",
    Readiness.NO_STATUS: "not connected and not bypassed",
}


def start_refusal(st: Station) -> str | None:
    """Why ``st`` keeps a match from starting, in the start box's words (None: it does not).
    The same ladder as its row's :func:`readiness`, so the two never disagree."""
    state, _ = readiness(st, False, None)
    words = START_REFUSALS.get(state)
    if words is None:
        return None
    where = st.login.wrong_station.label if st.login.wrong_station is not None else "?"
    return words.format(where=where)


__all__ = ["START_REFUSALS", "DsReport", "DsTcpReports", "FieldCommands", "Readiness", "Station", "StationLogin", "readiness", "start_refusal", "station_of_team"]
