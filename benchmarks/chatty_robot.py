"""A robot program that prints a line every beat, as many a team's first teleopPeriodic does
(``System.out.println`` in a loop): the worst a console sees. For
``python benchmarks/memory.py --program benchmarks/chatty_robot.py``.

Each fake roboRIO runs its own copy: six stations print 300 lines a second in all, which fill
the console panel's 20 000 lines in about a minute."""

beats = 0


def robot_periodic(state, robot):
    global beats
    beats += 1
    robot.print(f"periodic {beats}: drive left={state.time * 0.013 % 1:.3f} right={state.time * 0.017 % 1:.3f}")
