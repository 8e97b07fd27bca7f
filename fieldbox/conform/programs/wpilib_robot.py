"""A RobotPy robot for WPILib's simulator that reports what its robot code sees, for
``fieldbox conform robot``: one line ``conform {json}`` on stdout when it changes, and once a
second. WPILib's simulator sends nothing on TCP 1740, so conform starts it and reads stdout:

    fieldbox conform robot 127.0.0.1 --launch "python -m robotpy --main wpilib_robot.py run"

with ``HALSIM_EXTENSIONS`` naming the halsim_ds_socket library (see the README).
"""

import json
import signal
import time

# Started from a process without job control, SIGINT may arrive ignored: re-arm it so conform
# can stop the robot cleanly.
signal.signal(signal.SIGINT, signal.default_int_handler)

import wpilib  # noqa: E402

DS = wpilib.DriverStation
SLOTS = 6


def _stick(slot):
    axes = [round(DS.getStickAxis(slot, a), 4) for a in range(DS.getStickAxisCount(slot))]
    count = DS.getStickButtonCount(slot)
    buttons = [b for b in range(1, count + 1) if DS.getStickButton(slot, b)]
    povs = [int(DS.getStickPOV(slot, p)) for p in range(DS.getStickPOVCount(slot))]
    return {"axes": axes, "buttons": buttons, "button_count": count, "povs": povs,
            "name": DS.getJoystickName(slot), "type": int(DS.getJoystickType(slot)),
            "xbox": bool(DS.getJoystickIsXbox(slot))}


class ConformRobot(wpilib.TimedRobot):
    def robotInit(self):
        self.last = None
        self.said_at = 0.0

    def robotPeriodic(self):
        mode = "auto" if DS.isAutonomous() else "test" if DS.isTest() else "teleop"
        event = DS.getEventName()
        match = {"event": event, "type": int(DS.getMatchType().value), "number": DS.getMatchNumber(),
                 "replay": DS.getReplayNumber()}
        seen = {"enabled": DS.isEnabled(), "mode": mode, "estop": DS.isEStopped(), "ds": DS.isDSAttached(),
                "fms": DS.isFMSAttached(), "sticks": [_stick(s) for s in range(SLOTS)], "match": match,
                "game_data": DS.getGameSpecificMessage()}
        now = time.monotonic()
        if seen != self.last or now - self.said_at >= 1.0:
            self.last, self.said_at = seen, now
            print("conform " + json.dumps(seen, separators=(",", ":")), flush=True)

    def disabledPeriodic(self):
        pass

    def autonomousPeriodic(self):
        pass

    def teleopPeriodic(self):
        pass

    def testPeriodic(self):
        pass
