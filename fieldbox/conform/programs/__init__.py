"""Robot programs that report what their robot code sees, for ``fieldbox conform robot``.

* ``fieldbox_robot.py``: for fieldbox's fake roboRIO (``--robot-program``); its ``print``
  reaches the Driver Station's console over TCP 1740, where conform reads it.
* ``wpilib_robot.py``: a RobotPy robot for WPILib's simulator; it prints to its stdout
  (the simulator sends nothing on TCP 1740), which conform reads when it starts the robot
  itself (``--launch``).

Each prints a line ``conform {json}`` when what it sees changes, and once a second.
"""

from pathlib import Path

HERE = Path(__file__).parent
FIELDBOX_PROGRAM = HERE / "fieldbox_robot.py"
WPILIB_PROGRAM = HERE / "wpilib_robot.py"
