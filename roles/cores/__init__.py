"""The role cores: sans-IO state machines on the shell's clock (the aioquic shape, docs/style.md).

A core is told what arrived and what time it is, and returns the actions to perform; it opens
no socket and reads no clock. Here: what every core shares (``core``), the Driver Station
(``ds`` and its parts: the robot link ``ds_robot``, the robot TCP client ``ds_robot_tcp``,
the joystick slots ``ds_joysticks``, the enable arbiter ``ds_enable``, the FMS client
``ds_fms``, ``practice``), the fake roboRIO (``rio`` and its parts: the control link
``rio_control``, the DS's inputs ``rio_inputs``, the program runner ``rio_program``, the TCP
clients ``rio_tcp``, ``rio_telemetry``; its ``battery`` and the robot program's API,
``robot_program``), the FMS (``fms`` and its parts: a station's parts and
its readiness ``fms_station``, TCP 1750's logins and challenge ``fms_login``; ``match``,
``ownership``),
the 2010 protocol's codecs (``legacy_ds``, ``legacy_rio``), and the pure pieces every role
and the headless mode use (``addresses``, ``commands``). No edge leaves the group: the fake
roboRIO asks for its program to be run (``rio_program``'s requests) and the runtime runs it
(``roles.runtime.program_host``); tests/test_purity.py holds the line.
"""
