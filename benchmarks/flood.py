"""Big datagrams from anyone (issue 27): a flood of maximum-size datagrams at every UDP port
of a full field, six robots enabled, measured from outside, where the packets arrive.

    unshare -n sh -c 'ip link set lo up; python benchmarks/flood.py'   # 10 s of flood, a table
    python benchmarks/flood.py --seconds 5 --rate 250                   # root: a packet socket
    python benchmarks/flood.py --json
    python benchmarks/flood.py --code ../main    # the field from another checkout, to compare

What was seen before the fix: 65 KB datagrams of zeros, ten a second to one robot's UDP 1115
on a full field: 93 of ~1,500 control packets answered in 5 s, gaps up to 1,034 ms, and
``@254 estop`` 1,429 ms to reach the robot's status (each datagram took the fake roboRIO
210 ms to decode).

The field is the real command line, ``fieldbox field --teams 254,1114,2056,118,148,1678
--headless --json --no-log-files`` (six DS, six fake roboRIOs, the FMS, the loopback plan:
team 254's robot at 127.2.54.2, its DS at 127.2.54.5, the FMS at 127.0.100.5), in a process of
its own; ``match start`` enables every robot. The flood comes from a process of its own too
(this script with ``--flood``): 65,507-byte datagrams (zeros; to the FMS, a team's number at
bytes 4-5) to every UDP socket of the field (each robot's 1110 and 1115, each DS's 1150, 1121
and 1120, the FMS's 1160), each from an outsider (127.9.9.9) and from the host of the peer
that socket follows (the DS's at its robot and at the FMS, the robot's at its DS, the FMS's at
each DS), ``--rate`` datagrams a second in all. A packet socket on ``lo`` with the kernel's
receive times measures (nothing of fieldbox's own clocks):

* the DS beat: the interval between consecutive control packets as each robot's socket
  receives them, before the flood (undisturbed) and during it; target p99
  |interval - 20 ms| <= 1 ms during the flood;
* e-stop to status: ``@TEAM estop`` written to the field's stdin during the flood, then the
  first status packet from that team's robot with its e-stop bit, as the DS's socket receives
  it (the DS sends on its next 20 ms slot: half a beat on average); target <= 40 ms. Once per
  team: an e-stop under an FMS latches the station until the match ends;
* control packets received and answered per robot during the flood;
* the drops: datagrams sent, dropped by the kernel for a full socket buffer (/proc/net/udp),
  and counted by the field where its status lines show them (each DS's bad packets; the FMS's
  refused status per station and its bad packets). The roboRIOs count theirs as foreign
  (the Faults panel; tests/roles/test_flood.py checks every datagram is counted).

Run it in a network namespace of its own (``unshare -n``): the loopback interface is then
the field's alone, as in docs/figures.md.
"""

from __future__ import annotations

import argparse
import json
import os
import signal
import socket
import subprocess
import sys
import time
from typing import Any

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))  # _common, when a test imports this file
import _common as C  # noqa: E402  (puts the project root on sys.path)

BIGGEST_DATAGRAM = 65507  # the largest UDP payload over IPv4
OUTSIDER = "127.9.9.9"
ROBOT_PORTS = (1110, 1115)  # the DS sends to 1115 while an FMS is attached
DS_PORT = 1150


# -- the flood (a process of its own) --------------------------------------------------------------
def targets(bound: dict[str, dict[str, tuple[str, int]]], teams: list[int]) -> list[list]:
    """``[source host, destination host, port, payload hex prefix]`` for every UDP socket of a
    field (``bound``: role name -> channel -> (host, port)), from the outsider and from the
    host of the peer that socket follows. To the FMS, the team's number at bytes 4-5."""
    fms_host, fms_port = bound["fms"]["udp"]
    out = []
    for team in teams:
        ds, rio = bound[f"ds {team}"], bound[f"rio {team}"]
        ds_host, rio_host = ds["robot"][0], rio["ds"][0]
        out += [[OUTSIDER, fms_host, fms_port, f"00000000{team:04x}"], [ds_host, fms_host, fms_port, f"00000000{team:04x}"]]
        for channel in ("ds", "ds-fms"):
            out += [[OUTSIDER, *rio[channel], ""], [ds_host, *rio[channel], ""]]
        out += [[OUTSIDER, *ds["robot"], ""], [rio_host, *ds["robot"], ""]]
        for channel in ("fms", "fms-lite"):
            out += [[OUTSIDER, *ds[channel], ""], [fms_host, *ds[channel], ""]]
    return out


def flooder(plan: list[list], rate: float, seconds: float) -> list[str]:
    """The command line of a flooder process (stopped by SIGTERM or after ``seconds``; it
    prints how many datagrams went to each target, as JSON)."""
    return [sys.executable, os.path.abspath(__file__), "--flood", json.dumps(plan), str(rate), str(seconds)]


def flood(plan: list[list], rate: float, seconds: float) -> None:
    stop: list[int] = []
    signal.signal(signal.SIGTERM, lambda *_: stop.append(1))
    socks: dict[str, socket.socket] = {}
    for src, *_ in plan:
        if src not in socks:
            socks[src] = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
            socks[src].bind((src, 0))
    payloads = [bytes.fromhex(prefix) + bytes(BIGGEST_DATAGRAM - len(prefix) // 2) for *_, prefix in plan]
    sent = [0] * len(plan)
    t0 = time.monotonic()
    k = 0
    while time.monotonic() - t0 < seconds and not stop:
        i = k % len(plan)
        src, host, port, _ = plan[i]
        try:
            socks[src].sendto(payloads[i], (host, port))
            sent[i] += 1
        except OSError:
            pass
        k += 1
        time.sleep(max(0.0, t0 + k / rate - time.monotonic()))
    print(json.dumps(sent), flush=True)


def kernel_drops() -> dict[tuple[str, int], int]:
    """Datagrams the kernel dropped for a full receive buffer, per bound (ip, port)."""
    out: dict[tuple[str, int], int] = {}
    with open("/proc/net/udp") as f:
        next(f)
        for line in f:
            cols = line.split()
            ip_hex, port_hex = cols[1].split(":")
            key = (socket.inet_ntoa(int(ip_hex, 16).to_bytes(4, "little")), int(port_hex, 16))
            out[key] = out.get(key, 0) + int(cols[-1])
    return out


# -- the field -------------------------------------------------------------------------------------
class Field(C.HeadlessField):
    """``fieldbox field --headless --json``, six teams, the loopback plan, the FMS."""

    def __init__(self, code: str = C.ROOT) -> None:
        teams = ",".join(str(t) for t in C.SIX_TEAMS)
        super().__init__(["field", "--teams", teams, "--headless", "--json", "--no-log-files"], code)
        self.bound = {role: {ch: (a.rsplit(":", 1)[0], int(a.rsplit(":", 1)[1])) for ch, a in chans.items()}
                      for role, chans in self.raw_bound.items()}


def says(role: str, team: int | None = None, **want):
    return lambda o: (o.get("type") == "status" and o.get("role") == role and (team is None or o.get("team") == team)
                      and all(o.get(k) == v for k, v in want.items()))


def run(seconds: float, rate: float, baseline: float, code: str = C.ROOT) -> dict[str, Any]:
    capture = C.Capture(max_payload=2048)
    field = Field(code)
    hosts = {t: (field.bound[f"rio {t}"]["ds"][0], field.bound[f"ds {t}"]["robot"][0]) for t in C.SIX_TEAMS}
    try:
        for team in C.SIX_TEAMS:
            field.wait(says("ds", team, robot_code=True, fms_status="good"))
        # every station linked and its challenge answered right, or the start is refused
        field.wait(lambda o: says("fms")(o) and all(s["ds_link"] and s["challenge"] == "right"
                                                     for s in o["stations"]))
        mark = field.mark()
        field.send("match start")
        for team in C.SIX_TEAMS:
            field.wait(says("rio", team, enabled=True), mark)
        time.sleep(0.5)
        b0 = time.monotonic()
        time.sleep(baseline)
        b1 = time.monotonic()
        plan = targets(field.bound, C.SIX_TEAMS)
        sockets = {(host, port) for _, host, port, _ in plan}
        drops0 = kernel_drops()
        proc = subprocess.Popen(flooder(plan, rate, seconds + 30), stdout=subprocess.PIPE, text=True)
        time.sleep(0.5)
        t0 = time.monotonic()
        estops: dict[int, float | None] = {}
        for k, team in enumerate(C.SIX_TEAMS):
            time.sleep(max(0.0, t0 + (k + 0.5) * seconds / 6 - time.monotonic()))
            rio_host, ds_host = hosts[team]
            sent = field.send(f"@{team} estop")
            seen = None
            end = time.monotonic() + 5.0
            while seen is None and time.monotonic() < end:
                time.sleep(0.01)
                for stamp, src, dst, payload, dst_ip in list(capture.packets[-2000:]):
                    if (src in ROBOT_PORTS and dst == DS_PORT and dst_ip == ds_host and stamp >= sent
                            and len(payload) >= 4 and payload[3] & 0x80):
                        seen = stamp
                        break
            estops[team] = None if seen is None else (seen - sent) * 1000.0
        time.sleep(max(0.0, t0 + seconds - time.monotonic()))
        t1 = time.monotonic()
        proc.send_signal(signal.SIGTERM)
        out, _ = proc.communicate(timeout=30)
        flood_sent = json.loads(out)
        time.sleep(0.5)
        drops1 = kernel_drops()
        mark = field.mark()
        field.send("status")
        ds_status = {t: field.wait(says("ds", t), mark) for t in C.SIX_TEAMS}
        fms_status = field.wait(says("fms"), mark)
    finally:
        field.close()
        capture.close()
    before, during, answered = [], [], {}
    for team in C.SIX_TEAMS:
        rio_host, ds_host = hosts[team]
        before += C.intervals_at(capture.packets, ROBOT_PORTS, b0, b1, dst_ip=rio_host)
        during += C.intervals_at(capture.packets, ROBOT_PORTS, t0, t1, dst_ip=rio_host)
        received = sum(1 for t, _, dst, _, ip in capture.packets if dst in ROBOT_PORTS and ip == rio_host
                       and t0 <= t <= t1)
        replies = sum(1 for t, src, dst, _, ip in capture.packets if src in ROBOT_PORTS and dst == DS_PORT
                      and ip == ds_host and t0 <= t <= t1)
        answered[team] = (received, replies)

    def family(port_or_channel: str) -> tuple[int, int]:
        pick = [i for i, (_, host, port, _) in enumerate(plan) if _family(host, port, field.bound) == port_or_channel]
        keys = {(plan[i][1], plan[i][2]) for i in pick}
        return (sum(flood_sent[i] for i in pick),
                sum(drops1.get(k, 0) - drops0.get(k, 0) for k in keys))

    fams = {name: family(name) for name in ("robot 1110/1115", "DS 1150", "DS 1121/1120", "FMS 1160")}
    stations = fms_status["stations"]
    valid = [v for v in estops.values() if v is not None]
    return {"machine": C.machine(), "seconds": round(t1 - t0, 1), "rate": rate, "baseline_s": round(b1 - b0, 1),
            "beat_before_ms": C.rounded(C.summary(before)), "beat_during_ms": C.rounded(C.summary(during)),
            "estop_to_status_ms": {**C.rounded(C.summary(valid)), "missed": sum(v is None for v in estops.values()),
                                   "per_team": {t: None if v is None else round(v, 1) for t, v in estops.items()}},
            "control_packets_and_replies": answered, "sockets": len(sockets),
            "flood": {"sent": sum(flood_sent), "datagram_bytes": BIGGEST_DATAGRAM,
                      "per_family": {k: {"sent": s, "kernel_drops": d} for k, (s, d) in fams.items()}},
            "counted": {"ds_bad_packets": sum(ds_status[t]["bad_packets"] for t in C.SIX_TEAMS),
                        "fms_refused_status": sum(s["refused_status"] for s in stations),
                        "fms_bad_udp": fms_status["bad_packets"]["udp"]},
            "big_datagrams_seen_on_lo": capture.big, "capture_drops": capture.drops(),
            "load": os.getloadavg()}


def _family(host: str, port: int, bound) -> str:
    for role, chans in bound.items():
        for channel, addr in chans.items():
            if addr == (host, port):
                if role == "fms":
                    return "FMS 1160"
                if role.startswith("rio"):
                    return "robot 1110/1115"
                return "DS 1150" if channel == "robot" else "DS 1121/1120"
    return "?"


def main() -> int:
    if len(sys.argv) > 1 and sys.argv[1] == "--flood":
        flood(json.loads(sys.argv[2]), float(sys.argv[3]), float(sys.argv[4]))
        return 0
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seconds", type=float, default=10.0, help="how long the flood lasts (default 10)")
    parser.add_argument("--rate", type=float, default=250.0,
                        help="65,507-byte datagrams a second, in all (default 250: 16 MB/s)")
    parser.add_argument("--baseline", type=float, default=4.0, help="seconds measured before the flood")
    parser.add_argument("--code", default=C.ROOT,
                        help="run the field from another checkout of fieldbox (to compare; default this one)")
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args()
    if not hasattr(socket, "AF_PACKET"):
        print("needs Linux packet sockets", file=sys.stderr)
        return 2
    try:
        r = run(args.seconds, args.rate, args.baseline, os.path.abspath(args.code))
    except PermissionError:
        print("needs CAP_NET_RAW (root) to watch the loopback interface", file=sys.stderr)
        return 2
    if args.json:
        print(json.dumps(r))
        return 0
    print(C.machine_line(r["machine"]))
    if os.path.abspath(args.code) != C.ROOT:
        print(f"the field's code: {os.path.abspath(args.code)}")
    f = r["flood"]
    print(f"{r['seconds']} s of flood: {f['sent']} datagrams of {f['datagram_bytes']:,} bytes ({r['rate']:g}/s asked) "
          f"to {r['sockets']} sockets, six robots enabled; load {r['load'][0]:.2f}")
    b0, b, e = r["beat_before_ms"], r["beat_during_ms"], r["estop_to_status_ms"]
    print(f"DS beat at the receiver |interval - 20 ms|, before ({r['baseline_s']} s): median {b0['median']} "
          f"p99 {b0['p99']} max {b0['max']} (n {b0['n']})")
    print(f"DS beat at the receiver |interval - 20 ms|, during the flood: median {b['median']} p99 {b['p99']} "
          f"max {b['max']} (n {b['n']})")
    print(f"e-stop command -> robot status with e-stop, during the flood: median {e['median']} max {e['max']} "
          f"(n {e['n']}, missed {e['missed']})")
    print("control packets received / replies sent per robot during the flood: "
          + ", ".join(f"{t} {a}/{b_}" for t, (a, b_) in r["control_packets_and_replies"].items()))
    for name, v in f["per_family"].items():
        print(f"  flood to {name:16} sent {v['sent']:>6}, dropped by the kernel (full buffer) {v['kernel_drops']}")
    c = r["counted"]
    print(f"counted by the field (its status lines): DS bad packets {c['ds_bad_packets']}, FMS refused status "
          f"{c['fms_refused_status']}, FMS bad UDP {c['fms_bad_udp']} (the roboRIOs count theirs as foreign: "
          "the Faults panel)")
    checks = [C.check("beat p99 |dev| during the flood", b["p99"], b["p99"] <= 1.0, "<= 1 ms"),
              C.check("e-stop to status, max", e["max"], e["max"] <= 40.0 and not e["missed"], "<= 40 ms")]
    C.print_checks(checks)
    return 0


if __name__ == "__main__":
    sys.exit(main())
