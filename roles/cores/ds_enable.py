"""The Driver Station's enable arbiter: who decides enable, mode and station, and the e-stop latch.

Three can enable the robot: the operator (``enable()``), a practice run (its phases) and an
attached FMS (its control packets). An FMS overrides the other two and a practice run the
operator. Nothing enables while e-stopped or without robot comms. Whenever another takes over
or goes away (an FMS attaches or detaches, robot comms are lost, a practice run ends, a
restart or reboot is asked), the operator's enable is forgotten: the robot needs a fresh one.
The e-stop latches; only a restart-code or reboot request clears it.

The arbiter holds no link: it is told what the robot link and the FMS client show
(:class:`~roles.cores.ds_robot.RobotLink`, :class:`~roles.cores.ds_fms.FmsClient`, read,
never written) and says what the control packets carry. roles/cores/ds.py routes to it.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from protocol.enums import AllianceStation, Mode

from .core import CommandError, Events
from .views import EnableView, PracticeTimingView
from .practice import PracticePhase, PracticeRun, PracticeTiming

if TYPE_CHECKING:  # pragma: no cover
    from .ds_fms import FmsClient
    from .ds_robot import RobotLink


class EnableArbiter:
    """Enable, mode, station and e-stop of one DS. ``modes`` and ``protocol`` are the robot
    codec's (the 2010 protocol has no test mode)."""

    def __init__(self, station: AllianceStation, practice_timing: PracticeTiming, events: Events, *,
                 modes: tuple[Mode, ...], protocol: str) -> None:
        self.events = events
        self.modes = modes
        self.protocol = protocol
        # what the operator chose (the FMS or a practice run may override while they run)
        self.chosen_station = AllianceStation(station)
        self.chosen_mode = Mode.TELEOP
        self.enabled_local = False
        self.estopped = False
        # Who latched the e-stop ("operator" or "FMS"), and in which FMS match (level, number,
        # play; None without an FMS attached): what the screens say holds it (estop_reason).
        self.estop_by: str | None = None
        self.estop_match: tuple[int, int, int] | None = None
        self.practice_timing = practice_timing
        self.practice: PracticeRun | None = None
        self.practice_phase: PracticePhase | None = None
        # what the last control packet said: the "robot enabled/disabled" event, and the NI
        # log's DS flags (a record shows what went to the robot, not the command's moment)
        self.sent_enabled = False
        self.sent_mode: Mode | None = None

    def view(self) -> EnableView:
        t = self.practice_timing
        phase = self.practice_phase
        return EnableView(self.estopped, self.practice is not None, None if phase is None else phase.value,
                          PracticeTimingView(float(t.countdown), float(t.auto), float(t.pause), float(t.teleop)),
                          self.sent_enabled, self.sent_mode)

    # -- what the control packets say ---------------------------------------------------------
    def enabled(self, robot_comms: bool, fms: FmsClient) -> bool:
        """The operator's, the FMS's or the practice run's enable, never while e-stopped or
        without robot comms."""
        if self.estopped or not robot_comms:
            return False
        if fms.attached:
            return fms.robot_enabled
        if self.practice is not None:
            return self.practice_phase is not None and self.practice_phase.enabled
        return self.enabled_local

    def mode(self, fms: FmsClient) -> Mode:
        if fms.attached and fms.control is not None:
            return fms.control.mode
        if self.practice is not None and self.practice_phase is not None:
            return self.practice_phase.mode
        return self.chosen_mode

    def station(self, fms: FmsClient) -> AllianceStation:
        if fms.attached and fms.control is not None:
            return fms.control.station
        return self.chosen_station

    def countdown(self, now: float, fms: FmsClient) -> float | None:
        """Seconds left in the current period, while a match or a practice run is timing."""
        if fms.attached:
            left: float = fms.control.remaining_seconds if fms.control else 0
            return float(left) if left > 0 else None
        if self.practice is not None:
            phase, left = self.practice.phase_at(now)
            return left if phase is not PracticePhase.ENDED else None
        return None

    def sent(self, now: float, enabled: bool, mode: Mode) -> None:
        """A control packet goes out saying ``enabled`` in ``mode``: a change is an event."""
        if enabled != self.sent_enabled or (enabled and mode != self.sent_mode):
            self.events.add(now, f"robot enabled ({mode.label})" if enabled else "robot disabled")
        self.sent_enabled, self.sent_mode = enabled, mode

    def next_deadline(self, now: float) -> float | None:
        """The next practice phase boundary (``now`` once the run is over), None without a run."""
        if self.practice is None:
            return None
        boundary = self.practice.next_boundary(now)
        return now if boundary is None else boundary

    def estop_state(self, fms: FmsClient, robot_estopped: bool) -> tuple[str, str]:
        """``(kind, words)``: what holds the robot e-stopped, for the screens ("", "" when
        nothing does). Kinds: ``fms`` (the FMS e-stops this station now: for the rest of the
        match), ``fms-held`` (the operator's e-stop, which the FMS now holds the same way: a
        screen does not call it the FMS's), ``stale`` (latched in an earlier match, or by the FMS that no longer e-stops:
        the robot stays e-stopped until its code restarts, as a real roboRIO does),
        ``latched`` (the operator's, in this match or without an FMS), ``robot`` (no latch
        here, but the robot reports one: a DS started after its robot was e-stopped)."""
        c = fms.control if fms.attached else None
        if not self.estopped:
            if robot_estopped:
                return "robot", "robot still e-stopped: restart its code"
            return "", ""
        if c is not None and c.estop:
            if self.estop_by == "FMS":
                return "fms", "FMS e-stop: the FMS holds this station e-stopped for the rest of the match"
            return "fms-held", "E-stop (operator): the FMS holds this station e-stopped for the rest of the match"
        match = (int(c.tournament_level), c.match_number, c.play_number) if c is not None else None
        if self.estop_by == "FMS" or (match is not None and match != self.estop_match):
            return "stale", "robot still e-stopped: restart its code"
        return "latched", "E-stop latched: restart the robot code or reboot the roboRIO to clear it"

    # -- commands -------------------------------------------------------------------------------
    def blocker(self, robot: RobotLink, fms: FmsClient) -> tuple[str, str] | None:
        """What keeps the robot from being enabled now, ``(kind, words)``, or None: nothing does.
        The words are those :meth:`enable` refuses with; the kind is what a screen maps to its
        own words (``fms``, ``estop``, ``comms``, ``robot-estop``, ``code``, ``practice``)."""
        if fms.attached:
            return "fms", "an FMS is attached: it decides enable"
        if self.estopped:
            return "estop", "e-stopped: restart the robot code or reboot the roboRIO to clear it"
        if not robot.robot_comms:
            return "comms", "no robot comms"
        if robot.robot_estopped:
            return "robot-estop", "the robot still reports an e-stop: restart its code"
        if not robot.robot_code:
            return "code", "no robot code"
        if self.practice is not None:
            return "practice", "a practice run is going: it enables the robot itself"
        return None

    def _refuse_if_blocked(self, robot: RobotLink, fms: FmsClient, while_practice: str) -> None:
        blocked = self.blocker(robot, fms)
        if blocked is not None:
            raise CommandError(while_practice if blocked[0] == "practice" else blocked[1])

    def enable(self, now: float, robot: RobotLink, fms: FmsClient) -> None:
        self._refuse_if_blocked(robot, fms, "a practice run is going: it enables the robot itself")
        self.enabled_local = True

    def disable(self, now: float) -> None:
        self.enabled_local = False
        if self.practice is not None:
            self.end_practice(now, "practice run stopped: disabled by the operator")

    def latch_estop(self, now: float, why: str, fms: FmsClient, by: str = "operator") -> None:
        if not self.estopped:
            self.estopped = True
            self.estop_by = by
            c = fms.control
            self.estop_match = ((int(c.tournament_level), c.match_number, c.play_number)
                                if fms.attached and c is not None else None)
            latch = "latched until the robot code restarts or the roboRIO reboots"
            if by == "FMS":
                # The FMS keeps a station e-stopped for the rest of its match: a restart within
                # it is e-stopped again by the FMS's next packet, whatever the phase.
                text = f"FMS E-STOP ({why}): held by the FMS for the rest of the match, and {latch}"
            elif fms.attached:
                text = (f"E-STOP ({why}): {latch}; then held disabled until the FMS changes phase or "
                        "detaches, or for the rest of the match if the FMS e-stops this station too")
            else:
                text = f"E-STOP ({why}): {latch}"
            self.events.add(now, text)
        self.enabled_local = False
        if self.practice is not None:
            self.end_practice(now, "practice run ended: e-stop")

    def set_mode(self, mode: Mode | str, now: float, fms: FmsClient, enabled: bool) -> None:
        if isinstance(mode, str):
            try:
                mode = Mode.parse(mode)
            except ValueError as exc:
                raise CommandError(str(exc)) from None
        if not isinstance(mode, Mode) or mode is Mode.RESERVED:
            raise CommandError(f"mode must be teleop, auto or test, not {mode!r}")
        if mode not in self.modes:
            raise CommandError(f"the {self.protocol} protocol has no {mode.label} mode")
        if fms.attached:
            raise CommandError("an FMS is attached: it decides the mode")
        if self.practice is not None:
            raise CommandError("a practice run is going: it sets the mode itself")
        if enabled:
            raise CommandError("disable the robot before changing mode")
        if mode is not self.chosen_mode:
            self.chosen_mode = mode
            self.events.add(now, f"mode: {mode.label}")

    def set_station(self, station: AllianceStation | str, now: float, fms: FmsClient) -> None:
        if isinstance(station, str):
            try:
                station = AllianceStation.parse(station)
            except ValueError as exc:
                raise CommandError(str(exc)) from None
        if not isinstance(station, AllianceStation):
            raise CommandError(f"station must be R1..B3, not {station!r}")
        if fms.attached:
            raise CommandError("an FMS is attached: it decides the station")
        self.chosen_station = station

    def request(self, now: float, what: str) -> None:
        """A restart-code or reboot request goes out: it disables, and it alone clears the e-stop
        (the packets carrying it no longer carry the e-stop bit)."""
        self.enabled_local = False
        if self.practice is not None:
            self.end_practice(now, f"practice run stopped: {what}")
        if self.estopped:
            self.estopped = False
            self.estop_by = self.estop_match = None
            self.events.add(now, f"e-stop cleared: {what} requested")

    def start_practice(self, now: float, robot: RobotLink, fms: FmsClient, timing: PracticeTiming | None) -> None:
        self._refuse_if_blocked(robot, fms, "a practice run is already going")
        self.enabled_local = False
        self.practice = PracticeRun(timing or self.practice_timing, now)
        self.practice_phase = None
        self.events.add(now, "practice run started")
        self.update_practice(now)

    def stop_practice(self, now: float) -> None:
        if self.practice is None:
            raise CommandError("no practice run is going")
        self.end_practice(now, "practice run stopped by the operator")

    # -- what happened on the wire -----------------------------------------------------------------
    def update_practice(self, now: float) -> None:
        if self.practice is None:
            return
        phase, left = self.practice.phase_at(now)
        if phase is self.practice_phase:
            return
        self.practice_phase = phase
        if phase is PracticePhase.ENDED:
            self.end_practice(now, "practice run over")
        else:
            self.events.add(now, f"practice: {phase.value} ({left:.0f} s)")

    def end_practice(self, now: float, why: str) -> None:
        self.practice = None
        self.practice_phase = None
        self.enabled_local = False
        self.chosen_mode = Mode.TELEOP
        self.events.add(now, why)

    def fms_attached(self, now: float) -> None:
        self.enabled_local = False
        if self.practice is not None:
            self.end_practice(now, "practice run ended: an FMS took over")
        self.events.add(now, "FMS attached: it decides enable, mode and station now")

    def fms_detached(self, now: float, reason: str) -> None:
        self.enabled_local = False
        self.events.add(now, f"FMS lost ({reason}): disabled, back to local control; enable by hand")

    def comms_lost(self, now: float, fms: FmsClient) -> None:
        """Robot comms just went (the link already says so): disabled, and a DS that lost its
        robot asks for a fresh enable."""
        had_enable = self.enabled_local or self.enabled(True, fms)
        self.enabled_local = False
        self.events.add(now, "robot comms lost (no status for 1 s): disabled"
                        + ("; enable again by hand once comms return" if had_enable and not fms.attached
                           else ""))
        if self.practice is not None:
            self.end_practice(now, "practice run ended: robot comms lost")
