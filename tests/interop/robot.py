"""A headless RobotPy TimedRobot: the real peer our Driver Station drives in the interop
test. Every line meant for the test starts with ``FB`` and an event name."""

import signal

# Started from a process without job control, SIGINT may arrive ignored: re-arm it so the
# test's SIGINT stops the robot cleanly.
signal.signal(signal.SIGINT, signal.default_int_handler)

import wpilib  # noqa: E402
from wpilib.interfaces import GenericHID  # noqa: E402

DS = wpilib.DriverStation


def fb(_event: str, /, **kw) -> None:
    print(f"FB {_event} " + " ".join(f"{k}={v!r}" for k, v in kw.items()), flush=True)


class PeerRobot(wpilib.TimedRobot):
    def robotInit(self):
        self.hid = GenericHID(0)
        self.last = {}
        fb("robotInit")

    def _report(self, name, value):
        if self.last.get(name) != value:
            self.last[name] = value
            fb(name, **value)

    def robotPeriodic(self):
        self._report("STATE", dict(enabled=DS.isEnabled(), auto=DS.isAutonomous(), teleop=DS.isTeleop(),
                                   test=DS.isTest(), estop=DS.isEStopped(), fms=DS.isFMSAttached(),
                                   location=DS.getLocation(), alliance=str(DS.getAlliance())))
        self._report("MATCH", dict(event=DS.getEventName(), type=str(DS.getMatchType()),
                                   number=DS.getMatchNumber(), replay=DS.getReplayNumber(),
                                   gsm=DS.getGameSpecificMessage()))
        time_left = DS.getMatchTime()
        self._report("TIME", dict(seconds=int(time_left) if time_left >= 0 else -1))
        self._report("DESC", dict(name=DS.getJoystickName(0), axes=DS.getStickAxisCount(0),
                                  buttons=DS.getStickButtonCount(0), povs=DS.getStickPOVCount(0)))
        h = self.hid
        self._report("STICK", dict(axes=[round(h.getRawAxis(i), 4) for i in range(h.getAxisCount())],
                                   buttons=[i + 1 for i in range(h.getButtonCount()) if h.getRawButton(i + 1)],
                                   povs=[h.getPOV(i) for i in range(h.getPOVCount())]))

    def _outputs(self, outputs, left, right):
        self.hid.setOutputs(outputs)
        self.hid.setRumble(GenericHID.RumbleType.kLeftRumble, left)
        self.hid.setRumble(GenericHID.RumbleType.kRightRumble, right)

    def disabledInit(self):
        fb("disabledInit")
        self._outputs(0, 0.0, 0.0)

    def autonomousInit(self):
        fb("autonomousInit")
        self._outputs(0x00000001, 1.0, 0.0)

    def teleopInit(self):
        fb("teleopInit")
        self._outputs(0x12345678, 0.25, 0.75)

    def disabledPeriodic(self):
        pass

    def autonomousPeriodic(self):
        pass

    def teleopPeriodic(self):
        pass

    def testPeriodic(self):
        pass

    def _simulationPeriodic(self):
        pass
