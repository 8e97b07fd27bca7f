"""What runs the cores for real: sockets, threads, processes and files.

The asyncio shell (``shell``) binds the sockets a core's spec names; a ``field`` composes any
mix of roles on it (or on ``roles.sim``'s network); the engines (``engine``) put a field
behind the small interface the app uses, on a thread, or in a process of its own
(``wireproc``), whose cores' views (``roles.cores.views``) reach the app through ``viewwire``;
``classroom`` serves one field to many apps. Around the wire: how each process sets the
collector, the GIL's hand-over and its scheduling priority (``process_tuning``), the robot
program's host process (``program_host``), and the log files (``logfiles``, the NI DS format
in ``dslog``).
"""
