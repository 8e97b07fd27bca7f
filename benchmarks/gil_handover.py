"""How late a thread keeping a 20 ms beat wakes while another thread of the same process
runs Python: the GIL hand-over on this machine, without fieldbox.

    python benchmarks/gil_handover.py            # 10 s per row, a table
    python benchmarks/gil_handover.py --seconds 20 --json

One thread sleeps to a 20 ms grid and does 0.1 ms of work per beat (the wire's shape); the
main thread runs pure Python in bursts of B ms every 100 ms (the app's refresh shape) and
sleeps in between. Each row is a fresh process, with CPython's switch interval as fieldbox's
thread mode sets it (0.1 ms) unless the row says otherwise, and either free to run on any CPU
or pinned (both threads on CPU 0).

This is the experiment behind the performance notes (docs/figures.md): on a 2-vCPU virtual
machine the hand-over between two threads sometimes takes 3-5 ms (in some runs, not others), whatever
the switch interval, so a wire that shares the interpreter with the app cannot promise a
2 ms p99; in a process of its own it keeps the headless figures (``field.py --beside-app``).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time

ROWS = [  # (burst ms, switch interval s, pinned)
    (0, 0.0001, False),
    (10, 0.0001, False),
    (30, 0.0001, False),
    (30, 0.0001, True),
    (30, 0.005, False),
]


def child(seconds: float, burst_ms: float, interval: float) -> dict[str, float]:
    import threading

    sys.setswitchinterval(interval)
    burst = burst_ms / 1000.0
    lates: list[float] = []
    stop = threading.Event()

    def beat() -> None:
        deadline = time.monotonic() + 0.02
        while not stop.is_set():
            wait = deadline - time.monotonic()
            if wait > 0:
                time.sleep(wait)
            lates.append((time.monotonic() - deadline) * 1000.0)
            x = 0
            for i in range(2000):  # about 0.1 ms of work
                x += i
            deadline += 0.02

    t = threading.Thread(target=beat)
    t.start()
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        t0 = time.monotonic()
        while time.monotonic() - t0 < burst:
            sum(range(100))
        time.sleep(max(0.0, 0.1 - burst))
    stop.set()
    t.join()
    v = sorted(lates)
    n = len(v)
    return {"beats": n, "median_ms": v[n // 2], "p99_ms": v[min(n - 1, int(n * 0.99))], "max_ms": v[-1],
            "over_2ms_percent": 100.0 * sum(1 for x in v if x > 2.0) / n}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=10.0, help="per row (default 10)")
    ap.add_argument("--json", action="store_true")
    ap.add_argument("--child", nargs=2, type=float, help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.child:
        print(json.dumps(child(args.seconds, args.child[0], args.child[1])))
        return 0
    rows = []
    if not args.json:
        print(f"{'burst ms':>8} {'switch ms':>9} {'CPUs':>6} {'late median':>11} {'p99':>7} {'max':>7} "
              f"{'> 2 ms':>7}")
    for burst, interval, pinned in ROWS:
        cmd = [sys.executable, os.path.abspath(__file__), "--seconds", str(args.seconds),
               "--child", str(burst), str(interval)]
        if pinned:
            cmd = ["taskset", "-c", "0", *cmd]
        try:
            out = subprocess.run(cmd, capture_output=True, text=True, timeout=args.seconds + 30, check=True)
        except (OSError, subprocess.SubprocessError) as exc:  # no taskset: say so, go on
            rows.append({"burst_ms": burst, "switch_ms": interval * 1000, "pinned": pinned, "error": str(exc)})
            if not args.json:
                print(f"{burst:>8} {interval * 1000:>9.1f} {'cpu 0' if pinned else 'any':>6}  could not run: {exc}")
            continue
        r = json.loads(out.stdout.strip().splitlines()[-1])
        rows.append({"burst_ms": burst, "switch_ms": interval * 1000, "pinned": pinned, **r})
        if not args.json:
            print(f"{burst:>8} {interval * 1000:>9.1f} {'cpu 0' if pinned else 'any':>6} {r['median_ms']:>11.3f} "
                  f"{r['p99_ms']:>7.3f} {r['max_ms']:>7.3f} {r['over_2ms_percent']:>6.2f}%", flush=True)
    if args.json:
        print(json.dumps({"rows": rows}))
    else:
        print("\nlate: how long after its 20 ms deadline the beat thread ran (ms); > 2 ms: share of beats")
    return 0


if __name__ == "__main__":
    sys.exit(main())
