"""Resident memory of a full field with the app, over a long run.

    python benchmarks/memory.py                 # 600 s, RSS every 30 s, a table
    python benchmarks/memory.py --seconds 120 --every 10
    python benchmarks/memory.py --json
    python benchmarks/memory.py --trace         # also: what grew in the app's process, by line
    python benchmarks/memory.py --program benchmarks/chatty_robot.py   # a line every beat

A full field (six DS, six fake roboRIOs, the FMS) with the app on Textual's headless driver
(160 x 50), every panel refreshed at 10 Hz, tabs cycling, the inspector recording (as
``benchmarks/field.py --app``), the wire in a process of its own as the app runs it by
default (``--wire thread``: on a thread of the app's process). RSS is read from
/proc/PID/status (VmRSS): the app's process plus the wire's (none with ``--wire thread``;
pages the two share, such as Python's own code, count twice). The slope is a
least-squares fit in MB per minute, over the whole run and over its second half (after the
bounded buffers have filled). Nothing is recorded per packet in this run (the wire
figures come from benchmarks/field.py), so the benchmark itself does not grow.

``--trace`` runs Python's ``tracemalloc`` in the app's process (one frame per allocation) and
prints the source lines whose live memory grew most from the middle of the run to its end:
where a creep comes from. Its own bookkeeping inflates RSS, so the RSS figures of a traced
run are not the benchmark's.

Targets: RSS <= 150 MB throughout; flat: the second half grows less than 0.2 MB a minute
(12 MB an hour).
"""

from __future__ import annotations

import argparse
import asyncio
import json
import sys
import time
import tracemalloc
from typing import Any

import _common as C  # noqa: E402
import field as F  # noqa: E402  (benchmarks/field.py)

from roles.runtime.field import FieldConfig  # noqa: E402

RSS_TARGET_MB = 150.0
SLOPE_TARGET = 0.2  # MB per minute, second half


def _deep_size(obj: Any, depth: int = 0) -> int:
    """Bytes of one buffered item, roughly: the object, its items and attributes, two deep."""
    size = sys.getsizeof(obj)
    if depth >= 3:
        return size
    if isinstance(obj, (tuple, list)):
        return size + sum(_deep_size(x, depth + 1) for x in obj)
    attrs = getattr(obj, "__dict__", None)
    if attrs is not None:
        return size + sum(_deep_size(x, depth + 1) for x in attrs.values())
    slots = getattr(type(obj), "__slots__", ())
    return size + sum(_deep_size(getattr(obj, name, None), depth + 1) for name in slots
                      if isinstance(name, str))


#: Deques that are queues, not buffers: drained as they fill (the inspector's tap queue, at
#: 10 Hz). They hold what arrived since the last drain, and more while the census below runs
#: (its seconds of walking the heap hold the app's loop, not the views' reader thread).
QUEUES = {"CaptureRing._incoming"}


def filling_buffers(top: int = 5) -> dict[str, Any]:
    """Every bounded buffer (a deque with a maxlen) alive now that is not full yet: how many,
    and how much more memory they take once full (their items' mean size times the room
    left). A creep that these explain stops when they are full. ``held_mb``: what the ones
    not full hold now; they started empty with the run, so over its length that is how fast
    they grow. ``biggest``: the ``top`` owners (class and attribute, summed over their instances) with
    the most room left."""
    import collections
    import gc

    filling, room_bytes, full, held_bytes = 0, 0, 0, 0
    frozen = gc.get_freeze_count()
    if frozen:  # the wire's GC policy froze what existed at its start (roles/runtime/process_tuning.py):
        gc.unfreeze()  # get_objects() does not see frozen objects; the run is over anyway
    objects = gc.get_objects()
    if frozen:
        gc.freeze()
    names: dict[int, str] = {}  # a deque held in an attribute: whose, and which
    for obj in objects:
        try:
            attrs = getattr(obj, "__dict__", None)
        except Exception:  # a dead weak proxy, ...
            continue
        if type(attrs) is dict:
            for name, value in attrs.items():
                if type(value) is collections.deque and value.maxlen:
                    names[id(value)] = f"{type(obj).__qualname__}.{name}"
    owners: dict[str, list] = {}  # name -> [instances, items, their maxlens summed, room bytes]
    for obj in objects:
        if type(obj) is not collections.deque or obj.maxlen is None or obj.maxlen < 16:
            continue
        name = names.get(id(obj), "(no attribute)")
        if name in QUEUES:
            continue
        if not obj:
            continue
        if len(obj) >= obj.maxlen:
            full += 1
            continue
        filling += 1
        sample = [obj[i] for i in range(0, len(obj), max(1, len(obj) // 20))]
        mean = sum(_deep_size(x) for x in sample) / len(sample)
        held_bytes += int(mean * len(obj))
        room = int(mean * (obj.maxlen - len(obj)))
        room_bytes += room
        owner = owners.setdefault(name, [0, 0, 0, 0])
        owner[0] += 1
        owner[1] += len(obj)
        owner[2] += obj.maxlen
        owner[3] += room
    biggest = [{"name": name, "instances": n, "items": items, "capacity": capacity,
                "room_mb": round(room / 1e6, 1)}
               for name, (n, items, capacity, room) in sorted(owners.items(), key=lambda kv: -kv[1][3])[:top]]
    return {"full": full, "filling": filling, "room_mb": round(room_bytes / 1e6, 1),
            "held_mb": round(held_bytes / 1e6, 2), "biggest": biggest}


def traced_growth(first, last, top: int = 15) -> dict[str, Any]:
    """What grew between two tracemalloc snapshots of this process: the whole, and the source
    lines that grew most (``tracemalloc``'s own frames left out)."""
    leave_out = [tracemalloc.Filter(False, tracemalloc.__file__)]
    first, last = first.filter_traces(leave_out), last.filter_traces(leave_out)
    stats = last.compare_to(first, "lineno")
    return {"total_kb": round(sum(st.size_diff for st in stats) / 1e3, 1),
            "lines": [{"kb": round(st.size_diff / 1e3, 1), "blocks": st.count_diff,
                       "where": f"{st.traceback[0].filename}:{st.traceback[0].lineno}"}
                      for st in stats[:top]]}


def slope_mb_per_min(samples: list[tuple[float, float]]) -> float:
    if len(samples) < 2:
        return float("nan")
    n = len(samples)
    mt = sum(t for t, _ in samples) / n
    mr = sum(r for _, r in samples) / n
    var = sum((t - mt) ** 2 for t, _ in samples)
    if var == 0:
        return float("nan")
    return sum((t - mt) * (r - mr) for t, r in samples) / var * 60.0


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=600.0, help="run time (default 600)")
    ap.add_argument("--every", type=float, default=30.0, help="seconds between RSS samples (default 30)")
    ap.add_argument("--teams", default=",".join(map(str, C.SIX_TEAMS)))
    ap.add_argument("--wire", default="process", choices=("thread", "process"),
                    help="the wire in a child process (the app's default) or on a thread of the app's process")
    ap.add_argument("--trace", action="store_true",
                    help="tracemalloc in the app's process: the lines that grew from the middle to the end")
    ap.add_argument("--program", help="the fake roboRIOs run this robot program file (a console's worst "
                    "case: benchmarks/chatty_robot.py prints a line every beat)")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args(argv)
    if args.trace:
        tracemalloc.start(1)
    snapshots: list[Any] = []

    samples: list[tuple[float, float]] = []
    t0 = time.perf_counter()
    if not args.json:
        print(f"full field with the app, {args.seconds:g} s (machine: {C.machine_line(C.machine())})")
        print(f"{'t s':>6} {'RSS MB':>8} {'app':>8} {'wire':>8}")
    parts: list[tuple[float, float]] = []

    def sample() -> None:
        app = C.rss_mb()
        wire = sum(C.rss_mb(pid) for pid in C.child_pids("roles.runtime.wireproc"))  # the wire's process (none: 0)
        t, rss = time.perf_counter() - t0, app + wire
        samples.append((t, rss))
        parts.append((app, wire))
        if not args.json:
            print(f"{t:>6.0f} {rss:>8.1f} {app:>8.1f} {wire:>8.1f}", flush=True)

    async def during(seconds: float) -> None:
        end = time.perf_counter() + seconds
        middle = end - seconds / 2
        sample()
        while True:
            left = end - time.perf_counter()
            if left <= 0:
                break
            wait = min(args.every, left)
            if args.trace and not snapshots:
                to_middle = middle - time.perf_counter()
                if to_middle <= 0:
                    snapshots.append(tracemalloc.take_snapshot())
                else:
                    wait = min(wait, to_middle)
            await asyncio.sleep(wait)
            sample()
        if args.trace:
            snapshots.append(tracemalloc.take_snapshot())

    config = FieldConfig(teams=[int(t) for t in args.teams.split(",")], plan="ephemeral", program=args.program)
    t0 = time.perf_counter()
    buffers: dict[str, Any] = {}

    async def during_then_buffers(seconds: float) -> None:
        await during(seconds)
        buffers.update(filling_buffers())

    result = F.run_app(config, args.seconds, warmup=0.0, during=during_then_buffers, record=False,
                       wire=args.wire)
    half = [s for s in samples if s[0] >= samples[-1][0] / 2]
    peak = max(r for _, r in samples)
    out: dict[str, Any] = {
        "machine": C.machine(), "seconds": args.seconds, "wire": args.wire,
        "last_app_mb": round(parts[-1][0], 1), "last_wire_mb": round(parts[-1][1], 1), "samples": [[round(t, 1), round(r, 1)] for t, r in samples],
        "peak_mb": round(peak, 1), "first_mb": round(samples[0][1], 1), "last_mb": round(samples[-1][1], 1),
        "slope_mb_per_min": round(slope_mb_per_min(samples), 3),
        "second_half_slope_mb_per_min": round(slope_mb_per_min(half), 3),
        "ds": result["ds"], "buffers": buffers,
        "traced": traced_growth(*snapshots) if len(snapshots) == 2 else None,
        "cpu": result["cpu"], "app": result.get("app"),
        "command": ("python benchmarks/memory.py " + " ".join(argv if argv is not None else sys.argv[1:])).strip(),
    }
    out["checks"] = [C.check("peak RSS MB", out["peak_mb"], peak <= RSS_TARGET_MB, f"<= {RSS_TARGET_MB:g}"),
                     C.check("2nd-half slope MB/min", out["second_half_slope_mb_per_min"],
                             out["second_half_slope_mb_per_min"] <= SLOPE_TARGET, f"<= {SLOPE_TARGET}")]
    if args.json:
        print(json.dumps(out))
    else:
        print(f"RSS: first {out['first_mb']} MB, last {out['last_mb']} MB, peak {out['peak_mb']} MB; "
              f"slope {out['slope_mb_per_min']} MB/min overall, {out['second_half_slope_mb_per_min']} MB/min "
              f"in the second half")
        print(f"bounded buffers at the end: {buffers['full']} full, {buffers['filling']} still filling, "
              f"with room for about {buffers['room_mb']} MB more (a creep they explain stops there)")
        minutes = max(args.seconds, 1.0) / 60.0
        print(f"  the ones filling hold {buffers['held_mb']} MB, all taken in this run: about "
              f"{buffers['held_mb'] / minutes:.3f} MB a minute (RSS slope above: "
              f"{out['second_half_slope_mb_per_min']}); the most room left:")
        for b in buffers["biggest"]:
            times = f" x{b['instances']}" if b["instances"] > 1 else ""
            room_items = b["capacity"] - b["items"]
            full_in = (f"full in {room_items / (b['items'] / minutes):,.0f} min at this run's pace"
                       if b["items"] else "empty")
            print(f"  {b['room_mb']:6.1f} MB more in {b['name']}{times} ({b['items']:,} items held of "
                  f"{b['capacity']:,}; {full_in})")
        print(f"meanwhile: the DSs sent {out['ds']['sent']} packets and skipped {out['ds']['missed_slots']} "
              f"slots; CPU {out['cpu']['cpu_percent']:.1f} % (no per-packet recording in this run)")
        if out["app"] and "collector" in out["app"]:
            print(f"the app's process, its garbage collector: "
                  f"{C.collector_line(out['app']['collector'], out['cpu']['wall_s'])}")
        traced = out["traced"]
        if traced is not None:
            print(f"traced in the app's process, the second half: {traced['total_kb']:+.1f} kB live; "
                  f"the lines that grew most (tracemalloc's own bookkeeping makes the RSS above larger):")
            for line in traced["lines"]:
                print(f"  {line['kb']:+9.1f} kB {line['blocks']:+8d} blocks  {line['where']}")
        print()
        C.print_checks(out["checks"])
    return 0 if all(c["met"] for c in out["checks"]) else 1


if __name__ == "__main__":
    sys.exit(main())
