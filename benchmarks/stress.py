"""Safety under stress: a full field whose six robot programs each need 30 ms of CPU a call,
measured from outside, where the packets arrive.

    python benchmarks/stress.py                 # 60 s, a table
    python benchmarks/stress.py --seconds 20    # shorter
    python benchmarks/stress.py --json          # one JSON object
    python benchmarks/stress.py --work sleep    # programs that sleep 30 ms instead of working

The field is the real command line, ``fieldbox field --headless --roles ds,rio --robot-program
benchmarks/busy_robot.py`` on the ephemeral plan, in a process of its own (each robot program
in a process under it). Every robot is enabled: six programs asking for 4.5 cores of a
2-core machine. This script watches the loopback interface with a packet socket (root:
CAP_NET_RAW) and the kernel's receive times, so nothing of the field's own clock is trusted:

* the DS beat: the interval between consecutive control packets as each robot's socket
  receives them; target p99 |interval - 20 ms| <= 1 ms;
* e-stop to status: ``@TEAM estop`` written to the field's stdin, then the first status
  packet from that team's robot with its e-stop bit, as the DS's socket receives it (the DS
  sends on its next 20 ms slot: half a beat on average); target median <= 40 ms. Each robot
  is then restarted and enabled again, a team at a time;
* how many control packets each robot answered (one reply each, at once, whatever its
  program does) and the robot programs' overruns, from the field's status.
"""

from __future__ import annotations

import argparse
import json
import os
import socket
import sys
import tempfile
import time
from typing import Any

import _common as C  # noqa: E402  (puts the project root on sys.path)

class Field(C.HeadlessField):
    """``fieldbox field --headless --json`` with six busy robot programs."""

    def __init__(self, program: str) -> None:
        teams = ",".join(str(t) for t in C.SIX_TEAMS)
        super().__init__(["field", "--teams", teams, "--roles", "ds,rio", "--headless", "--json", "--net", "ephemeral",
                          "--no-log-files", "--robot-program", program])
        self.rio_port = {t: int(self.raw_bound[f"rio {t}"]["ds"].rsplit(":", 1)[1]) for t in C.SIX_TEAMS}


def rio_says(team: int, **want):
    return lambda o: (o.get("type") == "status" and o.get("role") == "rio" and o.get("team") == team
                      and all(o.get(k) == v for k, v in want.items()))


def ds_says(team: int, **want):
    return lambda o: (o.get("type") == "status" and o.get("role") == "ds" and o.get("team") == team
                      and all(o.get(k) == v for k, v in want.items()))


def enable(field: Field, team: int) -> None:
    field.wait(ds_says(team, robot_comms=True, robot_code=True))
    mark = field.mark()
    field.send(f"@{team} enable")
    field.wait(ds_says(team, enabled=True), mark)


def run(seconds: float, work: str) -> dict[str, Any]:
    program = os.path.join(C.ROOT, "benchmarks", "busy_robot.py")
    if work == "sleep":
        program = os.path.join(tempfile.mkdtemp(prefix="fieldbox-stress-"), "sleepy_robot.py")
        with open(program, "w") as f:
            f.write("import time\ndef robot_periodic(state, robot):\n    if state.enabled:\n"
                    "        time.sleep(0.030)\n")
    capture = C.Capture()
    field = Field(program)
    try:
        for team in C.SIX_TEAMS:
            enable(field, team)
        time.sleep(2.0)  # every program busy
        t0 = time.monotonic()
        estops: list[float] = []
        k = 0
        while time.monotonic() - t0 < seconds:
            team = C.SIX_TEAMS[k % 6]
            k += 1
            port = field.rio_port[team]
            sent = field.send(f"@{team} estop")
            seen = None
            end = time.monotonic() + 5.0
            while seen is None and time.monotonic() < end:
                time.sleep(0.01)
                for stamp, src, _, payload, _ in list(capture.packets[-400:]):
                    if src == port and stamp >= sent and len(payload) >= 4 and payload[3] & 0x80:
                        seen = stamp
                        break
            if seen is not None:
                estops.append((seen - sent) * 1000.0)
            mark = field.mark()
            field.send(f"@{team} restart")
            field.wait(rio_says(team, code_state="running", estopped=False), mark)
            enable(field, team)
            time.sleep(max(0.0, 1.0 - (time.monotonic() - sent)))
        t1 = time.monotonic()
        mark = field.mark()
        field.send("status")
        statuses = {}
        for team in C.SIX_TEAMS:
            statuses[team] = field.wait(rio_says(team), mark)
    finally:
        field.close()
        capture.close()
    intervals, answered = [], {}
    for team in C.SIX_TEAMS:
        port = field.rio_port[team]
        received = sum(1 for t, _, dst, _, _ in capture.packets if dst == port and t0 <= t <= t1)
        replies = sum(1 for t, src, _, _, _ in capture.packets if src == port and t0 <= t <= t1)
        intervals += C.intervals_at(capture.packets, port, t0, t1)
        answered[team] = (received, replies)
    return {"machine": C.machine(), "seconds": round(t1 - t0, 1), "work": work,
            "beat_deviation_ms": C.rounded(C.summary(intervals)),
            "estop_to_status_ms": C.rounded(C.summary(estops)),
            "control_packets_and_replies": answered,
            "load": os.getloadavg()}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seconds", type=float, default=60.0)
    parser.add_argument("--work", choices=("busy", "sleep"), default="busy")
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args()
    if not hasattr(socket, "AF_PACKET"):
        print("needs Linux packet sockets", file=sys.stderr)
        return 2
    try:
        r = run(args.seconds, args.work)
    except PermissionError:
        print("needs CAP_NET_RAW (root) to watch the loopback interface", file=sys.stderr)
        return 2
    if args.json:
        print(json.dumps(r))
        return 0
    print(C.machine_line(r["machine"]))
    print(f"{r['seconds']} s, six robot programs of 30 ms a call ({r['work']}), every robot enabled; "
          f"load {r['load'][0]:.2f}")
    b, e = r["beat_deviation_ms"], r["estop_to_status_ms"]
    print(f"DS beat at the receiver |interval - 20 ms|: median {b['median']} p99 {b['p99']} max {b['max']} "
          f"(n {b['n']})")
    print(f"e-stop command -> robot status with e-stop: median {e['median']} p99 {e['p99']} max {e['max']} "
          f"(n {e['n']})")
    print("control packets received / replies sent per robot: "
          + ", ".join(f"{t} {a}/{b}" for t, (a, b) in r["control_packets_and_replies"].items()))
    checks = [C.check("beat p99 |dev|", b["p99"], b["p99"] <= 1.0, "<= 1 ms"),
              C.check("e-stop median", e["median"], e["median"] <= 40.0, "<= 40 ms")]
    C.print_checks(checks)
    return 0


if __name__ == "__main__":
    sys.exit(main())
