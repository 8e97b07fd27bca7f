"""``fieldbox conform ROLE ADDRESS``: check any Driver Station, robot or FMS against the
protocol, the way Autobahn|Testsuite checks WebSocket servers.

fieldbox plays the other side of the link and runs numbered cases (``cases_robot.py``,
``cases_ds.py``, ``cases_fms.py``), each naming the rule it checks and where the rule is
written; a verdict is pass, fail (with the packets that broke it, explained byte by byte) or
not applicable (and why). ``report.py`` writes the run as text, JSON and HTML; ``cli.py``
is the subcommand. Every byte goes through :mod:`protocol`; no role core stands between the
peer and the judgement.
"""
