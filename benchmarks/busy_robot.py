"""A robot program that needs 30 ms of CPU a call (heavy but ordinary: vision on the roboRIO,
a big path follower): each call overruns the 20 ms loop. For ``python benchmarks/stress.py``
and ``fieldbox --robot-program benchmarks/busy_robot.py``.

It works while enabled and idles while disabled, as a real program's teleopPeriodic does."""

import time

WORK = 0.030  # seconds of CPU a call


def robot_periodic(state, robot):
    if not state.enabled:
        return
    t0 = time.process_time()
    x = 0
    while time.process_time() - t0 < WORK:
        x += 1
    robot.set_rumble(0, left=0.5 if x % 2 else 0.25)
