"""A classroom on one machine: 30 browser tabs on one field, measured from outside.

    python benchmarks/classroom.py                  # 30 s: 6 drivers, 24 observers (root: a packet socket)
    python benchmarks/classroom.py --seconds 60 --observers 12
    python benchmarks/classroom.py --json

``fieldbox serve --classroom --teams 254,1114,2056,118,148,1678 --net loopback`` and as many
browser tabs as asked, each a websocket to textual-serve exactly as a browser's page opens it
(160 x 50), reading everything its app draws and switching its app's tab every 2 s (F1 ..
F7, round and round, the tabs out of step), as a class clicking around. The teacher's tab
starts a match, so six robots are enabled while it runs. Figures:

* the field's beat: each robot's socket's receive times of its DS's packets (a packet socket
  on ``lo``, the kernel's clock; nothing of fieldbox's own). Target: p99 |interval - 20 ms|
  <= 1 ms;
* each observer tab's memory: the proportional set size (PSS: shared pages split among the
  processes sharing them, the fork server's that the tabs share included) of its app's
  process, from /proc. Target: <= 60 MB each;
* the CPU of the field's process and of all the tabs' processes, over wall time;
* how long the tabs take to start: from the moment they all open (a class arriving at once)
  to each one's app showing its seat (median and the last).
"""

from __future__ import annotations

import argparse
import asyncio
import json
import os
import re
import signal
import socket
import subprocess
import sys
import tempfile
import time
from typing import Any

import _common as C  # noqa: E402  (puts the project root on sys.path)
from outside import F_KEYS, ROBOT_PORTS, TEAMS, _tree, beat, robot_ips, tree_cpu_seconds

WIDTH, HEIGHT = 160, 50


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def pss_mb(pid: int) -> float:
    """The process's proportional set size, MB (0 if it is gone)."""
    try:
        with open(f"/proc/{pid}/smaps_rollup") as f:
            for line in f:
                if line.startswith("Pss:"):
                    return int(line.split()[1]) / 1024.0
    except OSError:
        pass
    return 0.0


def silences(capture: C.Capture, t0: float, t1: float, over_ms: float = 100.0) -> list[list[float]]:
    """[seconds into the run, gap ms] of each robot's silences longer than ``over_ms``."""
    out = []
    for ip in robot_ips():
        times = [t for t, _, dst, _, dip in capture.packets if dst in ROBOT_PORTS and t0 <= t <= t1 and dip == ip]
        out += [[round(a - t0, 2), round((b - a) * 1000.0, 1)] for a, b in zip(times, times[1:])
                if (b - a) * 1000.0 > over_ms]
    return sorted(out)


def processes(root: int, words: str) -> list[int]:
    """The processes under ``root`` whose command line holds ``words`` (not the shells that
    start them), or whose name starts with ``words`` (a tab forked by fieldbox/tabfork.py is
    named for its seat: fb-tab-observer, fb-tab-driver, fb-tab-teacher)."""
    found = []
    for pid in _tree(root):
        try:
            with open(f"/proc/{pid}/cmdline", "rb") as f:
                line = f.read().replace(b"\0", b" ").decode(errors="replace")
            with open(f"/proc/{pid}/comm") as f:
                name = f.read().strip()
        except OSError:
            continue
        if (words in line and not line.startswith("/bin/sh")) or name.startswith(words):
            found.append(pid)
    return found


async def tab(url: str, index: int, stop: asyncio.Event, shown: dict[int, bool], drawn: list[int],
              shown_at: dict[int, float]) -> None:
    import aiohttp

    async with aiohttp.ClientSession() as session:
        async with session.ws_connect(f"{url}?width={WIDTH}&height={HEIGHT}", max_msg_size=0) as ws:
            seen = b""

            async def switch() -> None:
                await asyncio.sleep(2.0 + index * 0.07)
                k = index
                while not stop.is_set():
                    await ws.send_json(["stdin", F_KEYS[k % len(F_KEYS)].decode()])
                    k += 1
                    await asyncio.sleep(2.0)

            switcher = asyncio.ensure_future(switch())
            try:
                while not stop.is_set():
                    try:
                        msg = await asyncio.wait_for(ws.receive(), 0.5)
                    except asyncio.TimeoutError:
                        continue
                    if msg.type not in (aiohttp.WSMsgType.BINARY, aiohttp.WSMsgType.TEXT):
                        break
                    data = msg.data if isinstance(msg.data, bytes) else msg.data.encode()
                    drawn[0] += len(data)
                    if not shown.get(index):
                        seen += data
                        shown[index] = b"classroom: you" in seen
                        if shown[index]:
                            shown_at[index] = time.monotonic()
                        seen = seen[-64:]
            finally:
                switcher.cancel()


async def start_match(url: str) -> None:
    """The teacher's tab: F5 (the FMS) and S (start the match), as a person would."""
    import aiohttp

    async with aiohttp.ClientSession() as session:
        async with session.ws_connect(f"{url}?width={WIDTH}&height={HEIGHT}", max_msg_size=0) as ws:
            seen = b""
            while b"classroom: you are the teacher" not in seen:
                msg = await asyncio.wait_for(ws.receive(), 60)
                seen = (seen + (msg.data if isinstance(msg.data, bytes) else msg.data.encode()))[-65536:]
            await asyncio.sleep(1.0)
            for key in (F_KEYS[4].decode(), "s"):
                await ws.send_json(["stdin", key])
                await asyncio.sleep(1.0)
            while True:  # read on, as a browser does, until the benchmark ends
                await ws.receive()


def measure(seconds: float, drivers: int, observers: int, warmup: float = 8.0) -> dict[str, Any]:
    capture = C.Capture()
    logs = tempfile.mkdtemp(prefix="fieldbox-classroom-")
    port = free_port()
    seats = drivers + observers + 1  # the teacher's too; all from this machine's one address
    server = subprocess.Popen([sys.executable, "-m", "fieldbox", "serve", "--classroom", "--teams", TEAMS,
                               "--net", "loopback", "--port", str(port), "--log-dir", logs,
                               "--max-tabs", str(max(seats, 40)), "--tabs-per-client", str(seats)],
                              cwd=C.ROOT, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True,
                              start_new_session=True)
    urls: dict[str, str] = {}
    try:
        while "teacher" not in urls:
            line = server.stdout.readline()
            if not line:
                raise SystemExit("fieldbox serve --classroom did not start")
            for name in ("students", "watch only", "teacher ("):
                if name in line:
                    urls[name.split()[0]] = re.search(r"http\S+", line).group(0)
        token = {name: url.split("token=")[1] for name, url in urls.items()}  # each seat's own
        ws = f"ws://127.0.0.1:{port}/ws"
        field_pid = processes(server.pid, "roles.runtime.classroom import classroom_main")[0]

        async def run() -> dict[str, Any]:
            stop = asyncio.Event()
            shown: dict[int, bool] = {}
            shown_at: dict[int, float] = {}
            drawn = [0]
            opened = time.monotonic()
            tabs = [asyncio.ensure_future(tab(f"{ws}/{token['students' if i < drivers else 'watch']}", i, stop,
                                              shown, drawn, shown_at)) for i in range(drivers + observers)]
            teacher = asyncio.ensure_future(start_match(f"{ws}/{token['teacher']}"))
            deadline = time.monotonic() + 120
            while sum(shown.values()) < len(tabs) and time.monotonic() < deadline:
                await asyncio.sleep(0.5)
            ready = sum(shown.values())
            starts = sorted(t - opened for t in shown_at.values())
            await asyncio.sleep(warmup)
            tab_pids = processes(server.pid, "--join-as ") or processes(server.pid, "fb-tab-")
            observer_pids = processes(server.pid, "--join-as observer") or processes(server.pid, "fb-tab-observer")
            fork_pids = [p for p in processes(server.pid, "fieldbox.tabfork import") if p not in tab_pids]
            cpu0 = {p: tree_cpu_seconds(p) for p in [field_pid, *tab_pids]}
            t0 = time.monotonic()
            drawn0 = drawn[0]
            await asyncio.sleep(seconds)
            t1 = time.monotonic()
            cpu1 = {p: tree_cpu_seconds(p) for p in cpu0}
            pss = sorted(pss_mb(p) for p in observer_pids)
            result = {
                "tabs": len(tabs), "tabs_showing_their_seat": ready, "tab_processes": len(tab_pids),
                "tab_start_s": C.rounded({"median": C.percentile(starts, 50), "last": starts[-1] if starts
                                         else float("nan")}, 2),
                "beat": beat(capture, t0, t1),
                "silences_over_100ms": silences(capture, t0, t1),
                "capture_drops": capture.drops(),
                "observer_pss_mb": C.rounded({"max": max(pss, default=0.0), "median": C.percentile(pss, 50) if pss
                                             else 0.0, "count": len(pss)}, 1),
                "observer_pss_each_mb": [round(v, 1) for v in pss],
                "field_process_pss_mb": round(pss_mb(field_pid), 1),
                "fork_server_pss_mb": round(sum(pss_mb(p) for p in fork_pids), 1),
                "field_cpu_pct": round(100.0 * (cpu1[field_pid] - cpu0[field_pid]) / (t1 - t0), 1),
                "tabs_cpu_pct": round(100.0 * sum(cpu1[p] - cpu0[p] for p in tab_pids) / (t1 - t0), 1),
                "drawn_mb_per_s": round((drawn[0] - drawn0) / (t1 - t0) / 1e6, 2),
                "seconds": round(t1 - t0, 1),
            }
            stop.set()
            teacher.cancel()
            await asyncio.gather(*tabs, teacher, return_exceptions=True)
            return result

        return asyncio.run(run())
    finally:
        capture.close()
        server.send_signal(signal.SIGINT)
        try:
            server.wait(30)
        except subprocess.TimeoutExpired:
            os.killpg(server.pid, signal.SIGKILL)
            server.wait()


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seconds", type=float, default=30.0)
    ap.add_argument("--drivers", type=int, default=6)
    ap.add_argument("--observers", type=int, default=24)
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    probe = C.WakeProbe(args.seconds + 40)
    result = measure(args.seconds, args.drivers, args.observers)
    result["machine_jitter"] = probe.result()
    result["machine"] = C.machine()
    result["checks"] = [
        C.check("field beat p99 |dev| ms", result["beat"].get("p99", float("nan")),
                result["beat"].get("p99", 99) <= 1.0, "<= 1 ms"),
        C.check("observer tab PSS MB (max)", result["observer_pss_mb"]["max"],
                0 < result["observer_pss_mb"]["max"] <= 60.0, "<= 60 MB"),
        C.check("tabs showing their seat", result["tabs_showing_their_seat"],
                result["tabs_showing_their_seat"] == result["tabs"], f"all {result['tabs']}"),
    ]
    if args.json:
        print(json.dumps(result, indent=2))
        return 0
    print(C.machine_line(result["machine"]))
    print(f"{result['tabs']} tabs ({args.drivers} drivers, {args.observers} observers) on one field, "
          f"{result['seconds']} s measured; the machine's own jitter p99 "
          f"{result['machine_jitter'].get('p99', float('nan')):.3f} ms")
    print(f"field process: {result['field_cpu_pct']} % CPU, PSS {result['field_process_pss_mb']} MB; the tabs' "
          f"fork server: PSS {result['fork_server_pss_mb']} MB; "
          f"all tabs: {result['tabs_cpu_pct']} % CPU, drawing {result['drawn_mb_per_s']} MB/s")
    print(f"tabs opened at once showed their seat after: median {result['tab_start_s']['median']} s, "
          f"the last {result['tab_start_s']['last']} s")
    print(f"beat: {result['beat']}")
    if result["silences_over_100ms"] or result["capture_drops"]:
        print(f"silences over 100 ms [s into the run, ms]: {result['silences_over_100ms']}; packets the capture "
              f"lost (a lost packet reads as a silence): {result['capture_drops']}")
    print(f"observer PSS MB: {result['observer_pss_mb']}; each: {result['observer_pss_each_mb']}")
    C.print_checks(result["checks"])
    return 0


if __name__ == "__main__":
    sys.exit(main())
