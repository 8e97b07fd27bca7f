"""The roles of a field: Driver Station, fake roboRIO and FMS, in three groups (docs/design.md).

* ``roles.cores``: the sans-IO state machines (the DS, the fake roboRIO, the FMS, the match)
  and the pure parts they are made of; time and every byte come in as arguments; each core
  makes frozen views of itself (``roles.cores.views``), which is all the app reads.
* ``roles.runtime``: what runs the cores for real: the asyncio shell, the field, the engines,
  the wire process and the pipe that carries its views, the classroom host, log files.
* ``roles.sim``: the in-memory network on a fake clock, and faults on purpose.
"""
