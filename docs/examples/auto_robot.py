"""A small RobotPy robot for the ``fieldbox run`` example (docs/examples/auto.fbx): it says
what it does on its stdout, as a team's first autonomous routine does."""

import wpilib


class Robot(wpilib.TimedRobot):
    def robotInit(self):
        print("robot ready", flush=True)

    def autonomousInit(self):
        self.loops = 0
        print("auto started", flush=True)

    def autonomousPeriodic(self):
        self.loops += 1
        if self.loops == 50:  # one second of 20 ms loops
            print("auto: drove forward for 1 s", flush=True)

    def disabledInit(self):
        print("disabled", flush=True)
