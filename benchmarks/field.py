"""A full field (six DS, six fake roboRIOs, the FMS) in one process, measured where the
packets arrive.

    python benchmarks/field.py                  # headless, 60 s, a table
    python benchmarks/field.py --seconds 10     # shorter
    python benchmarks/field.py --app            # with the app drawing (Textual headless, 160 x 50)
    python benchmarks/field.py --app --wire thread    # the app's wire on a thread of its process
    python benchmarks/field.py --app --tab inspector  # one tab shown throughout (what it costs)
    python benchmarks/field.py --json           # one JSON object
    python benchmarks/field.py --beside-app     # headless, while the app runs in another process

``--beside-app`` is the design experiment behind the wire's own process: the field keeps its
beat in a process of its own while another process draws the app (``--app --wire thread``,
with a field of its own, tabs switching): two interpreters, two GILs. Under ``--app --wire
thread`` the wire and the drawing share one GIL; under ``--app`` (the app's default) the
wire has a process of its own and the app reads views of it (roles/runtime/wireproc.py).

Figures: the interval between consecutive DS -> roboRIO control packets as each fake
roboRIO receives them (a tap on the receiving role, runtime clock), packets lost (sequence
gaps at the receiver), the round trip as each DS sees it (its TripTimer samples: control
sent -> status with the same sequence received), and process CPU time over wall time.

Targets (Performance issue), 2-core machine, CPython 3.11:
  headless: interval median 20.0 ms, p99 20 +- 1 ms, max 20 +- 5 ms, none lost,
            trip median <= 0.3 ms, p99 <= 2 ms, CPU <= 25 % of one core;
  --app:    interval p99 20 +- 2 ms, CPU <= 60 % (all panels refreshed, tabs cycling).
"""

from __future__ import annotations

import argparse
import asyncio
import gc
import json
import os
import sys
import tempfile
import time
from typing import Any

import _common as C  # noqa: E402  (puts the project root on sys.path)

from roles.runtime.field import FieldConfig  # noqa: E402


# -- the headless field ------------------------------------------------------------------------
def run_headless(config: FieldConfig, seconds: float, warmup: float = 3.0) -> dict[str, Any]:
    """``fieldbox field --headless`` as the command line runs it (its own code, on this
    process's main loop), measured."""
    return asyncio.run(C.measure_cli_headless(config, seconds, warmup))


# -- the field under the app -----------------------------------------------------------------
def enable_all_panels() -> list[str]:
    """Every panel refreshes at 10 Hz whether its tab shows or not."""
    from fieldbox.app import panel_classes

    ids = []
    for cls in panel_classes():
        cls.ALWAYS_REFRESH = True
        ids.append(cls.ID)
    return ids


def start_inspector_recording(app, folder: str) -> str:
    """The inspector records a pcap (into ``folder``), as its ``r`` key does; says what it did."""
    try:
        panel = app.query_one("#panel-inspector")
    except Exception:
        return "no inspector panel"
    fn = getattr(panel, "start_recording", None)
    if not callable(fn):
        return "the inspector has no start_recording(): not recording"
    path = os.path.join(folder, "bench.pcap")
    try:
        fn(path)
    except Exception as exc:  # noqa: BLE001
        return f"inspector.start_recording() failed: {exc}"
    return "the inspector recording a pcap"


def _fresh_trips(engine) -> None:
    """In a wire process: every DS keeps all its round-trip samples from now on (the views
    show them), as C.big_trip_buffers and C.clear_trips do on a field in this process."""
    from roles.cores.commands import KeepRoundTrips

    for st in engine.field.stations:
        if st.ds is not None:
            engine.execute(KeepRoundTrips(10_000_000, team=st.team))


def _proc_cpu_s(pid: int) -> float:
    """CPU seconds (user + system) of another process, from /proc/PID/stat."""
    with open(f"/proc/{pid}/stat") as f:
        fields = f.read().rpartition(")")[2].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


async def _with_app(config: FieldConfig, seconds: float, warmup: float, tab_period: float,
                    folder: str, during=None, size=(160, 50), record: bool = True,
                    wire: str = "process", tab: str | None = None) -> dict[str, Any]:
    from fieldbox.app import FieldboxApp
    from roles.runtime.engine import ThreadEngine
    from roles.runtime.wireproc import ProcessEngine

    window = C.Window(record)
    engines: list[Any] = []

    def factory(cfg: FieldConfig):
        engine = ProcessEngine(cfg) if wire == "process" else ThreadEngine(cfg)
        engine.start()
        engine.add_tap(window.recorder.tap)
        engines.append(engine)
        return engine

    tabs = enable_all_panels()
    if tab is not None:  # one tab shown the whole run (the others still refresh, hidden)
        if tab not in tabs:
            raise SystemExit(f"--tab: no tab {tab!r} (the tabs: {', '.join(tabs)})")
        tabs = [tab]
    if hasattr(config, "log_dir"):
        config.log_dir = folder  # log files on, as by default, but not in the user's folder
    app = FieldboxApp(factory, config, hold_collector=True)  # as the app's main does
    async with app.run_test(headless=True, size=size) as pilot:
        await pilot.pause()
        window.attach([engines[-1].field])
        window.seconds = seconds
        inspector = start_inspector_recording(app, folder)

        async def cycle(until: float) -> None:
            i = 0
            while time.perf_counter() < until:
                app.action_show_tab(tabs[i % len(tabs)])
                i += 1
                await asyncio.sleep(min(tab_period, max(0.0, until - time.perf_counter())))

        await cycle(time.perf_counter() + warmup)
        child = getattr(engines[-1], "proc", None)
        if child is not None and record:  # the DS's round-trip samples, kept and cleared in the child
            _fresh_trips(engines[-1])
        window.begin()
        collector = C.CollectorWatch()
        collector.start()
        child_cpu0, child_wall0 = (_proc_cpu_s(child.pid), time.perf_counter()) if child else (0.0, 0.0)
        if during is not None:
            task = asyncio.create_task(cycle(time.perf_counter() + seconds))
            await during(seconds)
            await task
        else:
            await cycle(time.perf_counter() + seconds)
        result = window.end()
        collected = collector.stop()
        if child is not None:  # the wire's own process: its CPU, and the app's shown apart
            wall = time.perf_counter() - child_wall0
            child_cpu = 100.0 * (_proc_cpu_s(child.pid) - child_cpu0) / wall
            result["wire_process"] = {"pid": child.pid, "cpu_percent": round(child_cpu, 2),
                                      "app_cpu_percent": result["cpu"]["cpu_percent"],
                                      "note": "trip times and DS counters read from the views the app holds "
                                              "(at most 100 ms old)"}
            result["cpu"]["cpu_percent"] = round(result["cpu"]["cpu_percent"] + child_cpu, 2)
        result["app"] = {"size": list(size), "tabs": tabs, "tab_period_s": tab_period, "inspector": inspector,
                         "wire": wire, "collector": collected}
        pcap = os.path.join(folder, "bench.pcap")
        if os.path.exists(pcap):
            result["app"]["pcap_bytes"] = os.path.getsize(pcap)
        await app.action_quit()
    return result


def run_app(config: FieldConfig, seconds: float, warmup: float = 3.0, tab_period: float = 1.0,
            **kw) -> dict[str, Any]:
    with tempfile.TemporaryDirectory(prefix="fieldbox-bench-") as folder:
        return asyncio.run(_with_app(config, seconds, warmup, tab_period, folder=folder, **kw))


# -- the field beside the app in another process ------------------------------------------------
def run_beside_app(config: FieldConfig, args: argparse.Namespace, argv: list[str] | None) -> dict[str, Any]:
    """The headless field measured while ``field.py --app`` (a whole field and the app)
    runs in a second process for the whole measurement; its own figures come back too."""
    import subprocess

    app_seconds = args.warmup + args.seconds + 6.0
    other = subprocess.Popen([sys.executable, os.path.abspath(__file__), "--app", "--wire", "thread", "--json",
                              "--seconds", f"{app_seconds:g}", "--tab-period", f"{args.tab_period:g}"],
                             stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
    try:
        time.sleep(4.0)  # the app's start-up (about 0.5 s) and its own warm-up
        result = run_headless(config, args.seconds, args.warmup)
        out, _ = other.communicate(timeout=app_seconds + 60)
    finally:
        if other.poll() is None:
            other.kill()
            other.wait()
    try:
        app = json.loads(out.strip().splitlines()[-1])
        result["beside"] = {"interval_ms": app["wire"]["interval_ms"], "cpu": app["cpu"]}
    except (ValueError, IndexError, KeyError):
        result["beside"] = None
    return result


# -- targets and output ------------------------------------------------------------------------
def checks(result: dict[str, Any], app: bool) -> list[dict[str, Any]]:
    iv = result["wire"]["interval_ms"]
    trip = result["trip_ms"]
    cpu = result["cpu"]["cpu_percent"]
    lost = result["wire"]["lost"]
    if app:
        return [C.check("interval p99 ms", iv["p99"], abs(iv["p99"] - 20) <= 2, "20 +- 2"),
                C.check("lost packets", lost, lost == 0, "0"),
                C.check("CPU % of one core", cpu, cpu <= 60, "<= 60")]
    return [C.check("interval median ms", iv["median"], round(iv["median"], 1) == 20.0, "20.0"),
            C.check("interval p99 ms", iv["p99"], abs(iv["p99"] - 20) <= 1, "20 +- 1"),
            C.check("interval max ms", iv["max"], abs(iv["max"] - 20) <= 5, "20 +- 5"),
            C.check("lost packets", lost, lost == 0, "0"),
            C.check("trip median ms", trip["median"], trip["median"] <= 0.3, "<= 0.3"),
            C.check("trip p99 ms", trip["p99"], trip["p99"] <= 2, "<= 2"),
            C.check("CPU % of one core", cpu, cpu <= 25, "<= 25")]


def print_table(result: dict[str, Any], app: bool, command: str) -> None:
    m = result["machine"]
    wire, trip, cpu = result["wire"], result["trip_ms"], result["cpu"]
    iv = wire["interval_ms"]
    mode = "with the app (Textual headless, 160 x 50)" if app else "headless"
    if "beside" in result:
        mode = "headless, beside the app in another process"
    print(f"full field {mode}: "
          f"{result['pairs']} DS/roboRIO pairs + FMS, {cpu['wall_s']:.1f} s measured")
    print(f"machine: {C.machine_line(m)}")
    print(f"command: {command}")
    print()
    print(f"{'DS -> roboRIO interval (ms)':30} {'median':>8} {'p99':>8} {'p99.9':>8} {'min':>8} {'max':>8}")
    print(f"{'all streams':30} {iv['median']:8.3f} {iv['p99']:8.3f} {iv['p999']:8.3f} {iv['min']:8.3f} "
          f"{iv['max']:8.3f}")
    for role, s in wire["per_stream"].items():
        print(f"{'  ' + role:30} {s['median']:8.3f} {s['p99']:8.3f} {s['p999']:8.3f} {s['min']:8.3f} "
              f"{s['max']:8.3f}")
    late = wire["send_late_ms"]
    print(f"sent late against each DS's grid (ms): median {late['median']:.3f}, p99 {late['p99']:.3f}, "
          f"max {late['max']:.3f}")
    print(f"received {wire['received']} (about {wire.get('expected', '?')} expected), lost {wire['lost']}, "
          f"reordered {wire['reordered']}; DS missed slots {result['ds']['missed_slots']}, "
          f"DS-counted lost {result['ds']['lost']}")
    print(f"round trip as the DS sees it (ms): median {trip['median']:.3f}, p99 {trip['p99']:.3f}, "
          f"max {trip['max']:.3f} ({trip['n']} samples)")
    print(f"CPU: {cpu['cpu_percent']:.1f} % of one core (user {cpu['user_percent']:.1f} %, "
          f"system {cpu['sys_percent']:.1f} %); RSS {result['rss_mb']} MB")
    wp = result["wake_probe_ms"]
    if wp:
        print(f"the machine's own timer jitter meanwhile (a separate idle process sleeping to a 20 ms grid): "
              f"wakes late median {wp['median']:.3f}, p99 {wp['p99']:.3f}, max {wp['max']:.3f} ms")
    print(f"machine load: 1-min load average {cpu['load_average'][0]} at start, {cpu['load_average'][1]} at end; "
          f"{cpu['involuntary_switches']} involuntary context switches")
    if app:
        tabs = result["app"]["tabs"]
        shown = (f"the {tabs[0]} tab shown throughout" if len(tabs) == 1
                 else f"tabs cycled every {result['app']['tab_period_s']} s")
        print(f"app: {shown}, all panels refreshed; "
              f"{result['app']['inspector']}; the wire on a {result['app'].get('wire', 'process')}")
        print(f"the app's process, its garbage collector: "
              f"{C.collector_line(result['app']['collector'], cpu['wall_s'])}")
    if "wire_process" in result:
        wp = result["wire_process"]
        print(f"wire process: CPU {wp['cpu_percent']:.1f} % of one core; the app's process "
              f"{wp['app_cpu_percent']:.1f} % (CPU above: both); {wp['note']}")
    if "beside" in result:
        b = result["beside"]
        if b is None:
            print("beside: the app process gave no figures")
        else:
            print(f"beside, in another process: the app with a field of its own (tabs switching), "
                  f"CPU {b['cpu']['cpu_percent']:.1f} % of one core; its own field's interval p99 "
                  f"{b['interval_ms']['p99']:.3f} ms, max {b['interval_ms']['max']:.3f} ms (one GIL for both)")
    print()
    C.print_checks(result["checks"])


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=60.0, help="measured time (default 60)")
    ap.add_argument("--warmup", type=float, default=3.0, help="unmeasured start (default 3)")
    ap.add_argument("--app", action="store_true", help="run the app too (Textual headless driver, 160 x 50)")
    ap.add_argument("--tab-period", type=float, default=1.0, help="with --app: seconds per tab (default 1)")
    ap.add_argument("--tab", help="with --app: show this tab (ds, inspector, ...) the whole run "
                                  "instead of cycling; an unknown one lists them")
    ap.add_argument("--teams", default=",".join(map(str, C.SIX_TEAMS)), help="six teams")
    ap.add_argument("--net", default="ephemeral", choices=("ephemeral", "loopback"), help="address plan")
    ap.add_argument("--beside-app", action="store_true",
                    help="headless, while `field.py --app` runs in another process")
    ap.add_argument("--wire", default="process", choices=("thread", "process"),
                    help="with --app: the wire in a child process (default, as the app runs it) or on "
                         "a thread of the app's process (the app's --wire thread)")
    ap.add_argument("--json", action="store_true", help="one JSON object")
    args = ap.parse_args(argv)
    config = FieldConfig(teams=[int(t) for t in args.teams.split(",")], plan=args.net)
    gc.collect()
    if args.app:
        result = run_app(config, args.seconds, args.warmup, args.tab_period, wire=args.wire, tab=args.tab)
    elif args.beside_app:
        result = run_beside_app(config, args, argv)
    else:
        result = run_headless(config, args.seconds, args.warmup)
    result["machine"] = C.machine()
    result["mode"] = "app" if args.app else ("beside-app" if args.beside_app else "headless")
    result["checks"] = checks(result, args.app)
    command = "python benchmarks/field.py " + " ".join(argv if argv is not None else sys.argv[1:])
    result["command"] = command.strip()
    if args.json:
        print(json.dumps(result))
    else:
        print_table(result, args.app, result["command"])
    return 0 if all(c["met"] for c in result["checks"]) else 1


if __name__ == "__main__":
    sys.exit(main())
