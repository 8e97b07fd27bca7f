"""Shared helpers for the benchmarks: the receiving-side recorder, statistics, CPU and RSS,
the machine description, and output as a table or JSON.

Every wire figure is measured where a packet *arrives*: a tap on the receiving fake
roboRIO sees each inbound ``ds-to-rio`` datagram with the runtime clock's receive time, so
the intervals include everything the sending side and the event loop add (timer lateness,
GIL hand-over, drawing on another thread).
"""

from __future__ import annotations

import asyncio
import gc
import json
import os
import platform
import resource
import select
import socket
import struct
import sys
import threading
import time
from collections import deque
from dataclasses import dataclass, field
from typing import Any, Iterable

#: The project measured: this folder's parent, or ``FIELDBOX_BENCH_ROOT`` (benchmarks/ab.py runs
#: one copy of the benchmarks against several worktrees, each the root of its own run).
ROOT = os.path.abspath(os.environ.get("FIELDBOX_BENCH_ROOT") or os.path.join(os.path.dirname(__file__), ".."))
if ROOT not in sys.path:
    sys.path.insert(0, ROOT)

SIX_TEAMS = [254, 1114, 2056, 118, 148, 1678]
PERIOD_MS = 20.0


# -- the machine ------------------------------------------------------------------------------
def machine() -> dict[str, Any]:
    cpu = platform.processor() or platform.machine()
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                if line.startswith("model name"):
                    cpu = line.split(":", 1)[1].strip()
                    break
    except OSError:
        pass
    mem_mb = None
    try:
        with open("/proc/meminfo") as f:
            for line in f:
                if line.startswith("MemTotal:"):
                    mem_mb = int(line.split()[1]) // 1024
                    break
    except OSError:
        pass
    return {"python": platform.python_version(), "implementation": platform.python_implementation(),
            "cpu": cpu, "cpus": os.cpu_count(), "memory_mb": mem_mb, "platform": platform.platform()}


def machine_line(m: dict[str, Any]) -> str:
    return (f"{m['implementation']} {m['python']} on {m['cpus']} x {m['cpu']}, "
            f"{m['memory_mb']} MB, {m['platform']}")


# -- statistics -------------------------------------------------------------------------------
def percentile(sorted_values: list[float], q: float) -> float:
    """Nearest-rank percentile (q in 0..100) of an already sorted list."""
    if not sorted_values:
        return float("nan")
    k = max(0, min(len(sorted_values) - 1, int(round(q / 100.0 * len(sorted_values) + 0.5)) - 1))
    return sorted_values[k]


def summary(values: Iterable[float]) -> dict[str, float]:
    v = sorted(values)
    if not v:
        return {"n": 0, "min": float("nan"), "median": float("nan"), "p99": float("nan"),
                "p999": float("nan"), "max": float("nan"), "mean": float("nan")}
    return {"n": len(v), "min": v[0], "median": percentile(v, 50), "p99": percentile(v, 99),
            "p999": percentile(v, 99.9), "max": v[-1], "mean": sum(v) / len(v)}


def rounded(d: dict[str, Any], digits: int = 3) -> dict[str, Any]:
    return {k: (round(x, digits) if isinstance(x, float) else x) for k, x in d.items()}


# -- the receiving-side recorder --------------------------------------------------------------
@dataclass
class _Stream:
    times: list[float] = field(default_factory=list)
    seqs: list[int] = field(default_factory=list)


class ArrivalRecorder:
    """A runtime tap: every ``ds-to-rio`` datagram arriving at a fake roboRIO, per roboRIO
    (so per DS), with its receive time and sequence number. Cheap: two list appends."""

    KIND = "ds-to-rio"

    def __init__(self) -> None:
        self.streams: dict[str, _Stream] = {}
        self.sent: dict[str, _Stream] = {}  # the same packets as each DS sent them (diagnosis)
        self.recording = False

    def tap(self, r) -> None:  # a roles.runtime.shell.TapRecord
        if r.kind != "ds-to-rio" or not self.recording:
            return
        streams = self.streams if r.direction == "in" else self.sent
        s = streams.get(r.role)
        if s is None:
            s = streams[r.role] = _Stream()
        s.times.append(r.time)
        s.seqs.append((r.data[0] << 8) | r.data[1])

    def send_lateness(self) -> dict[str, float]:
        """How late each DS sent against its own 20 ms grid (ms; relative to its typical,
        median, phase): separates the sender's timer from the way across. A send is placed
        on the grid modulo 20 ms, so lateness reads from -5 to +15 ms (later than that shows
        as a skipped slot in the DS's own count)."""
        period = PERIOD_MS / 1000.0
        late: list[float] = []
        for s in self.sent.values():
            if not s.times:
                continue
            t0 = s.times[0]
            phases = [(t - t0) % period for t in s.times]
            ref = sorted(phases)[len(phases) // 2]
            late += [(((p - ref + period / 4) % period) - period / 4) * 1000.0 for p in phases]
        return rounded(summary(late))

    def start(self) -> None:
        self.recording = True

    def stop(self) -> None:
        self.recording = False

    def analyse(self, seconds: float | None = None) -> dict[str, Any]:
        """Intervals (ms), lost and duplicate/reordered sequence numbers, per stream and
        over all streams."""
        per: dict[str, Any] = {}
        all_intervals: list[float] = []
        lost_total = reordered_total = received = 0
        for role, s in sorted(self.streams.items()):
            t = s.times
            iv = [(t[i] - t[i - 1]) * 1000.0 for i in range(1, len(t))]
            lost = reordered = 0
            for i in range(1, len(s.seqs)):
                gap = (s.seqs[i] - s.seqs[i - 1]) & 0xFFFF
                if gap == 0 or gap > 0x8000:
                    reordered += 1
                else:
                    lost += gap - 1
            all_intervals += iv
            lost_total += lost
            reordered_total += reordered
            received += len(t)
            per[role] = rounded({**summary(iv), "received": len(t), "lost": lost, "reordered": reordered})
        out = {"streams": len(self.streams), "received": received, "lost": lost_total,
               "reordered": reordered_total, "interval_ms": rounded(summary(all_intervals)),
               "send_late_ms": self.send_lateness(), "per_stream": per}
        if seconds:
            expected = seconds * 1000.0 / PERIOD_MS * len(self.streams)
            out["rate_hz_per_stream"] = round(received / seconds / max(1, len(self.streams)), 2)
            out["expected"] = int(expected)
        return out


def big_trip_buffers(field_obj) -> None:
    """Keep every round-trip sample of the run (the DS keeps the last 256 for its panel)."""
    for st in field_obj.stations:
        if st.ds is not None:
            samples = st.ds.link.echoes.trip.samples
            if isinstance(samples, deque):  # code from before streams were numbered (--code)
                st.ds.link.echoes.trip.samples = deque(samples, maxlen=10_000_000)
            else:
                kept = type(samples)(10_000_000)
                kept.extend(samples)
                st.ds.link.echoes.trip.samples = kept


def clear_trips(field_obj) -> None:
    for st in field_obj.stations:
        if st.ds is not None:
            st.ds.link.echoes.trip.samples.clear()


def trip_figures(field_obj) -> dict[str, Any]:
    samples: list[float] = []
    for st in field_obj.stations:
        if st.ds is not None:
            samples += list(st.ds.link.echoes.trip.samples)
    return rounded(summary(samples), 4)


def ds_counters(field_obj) -> dict[str, int]:
    out = {"sent": 0, "lost": 0, "missed_slots": 0, "stale_echoes": 0}
    for st in field_obj.stations:
        ds = st.ds
        if ds is not None:
            echoes = ds.link.echoes
            out["sent"] += echoes.sent_packets
            out["lost"] += echoes.lost_packets
            out["missed_slots"] += ds.link.missed_slots
            out["stale_echoes"] += echoes.stale_echoes
    return out


# -- CPU and memory -----------------------------------------------------------------------------
class CpuMeter:
    """Process CPU time (all threads) over wall time, as a percentage of one core."""

    def __init__(self) -> None:
        self.wall0 = time.perf_counter()
        self.cpu0 = time.process_time()
        r = resource.getrusage(resource.RUSAGE_SELF)
        self.user0, self.sys0 = r.ru_utime, r.ru_stime
        self.nivcsw0 = r.ru_nivcsw
        self.load0 = os.getloadavg()[0]

    def read(self) -> dict[str, float]:
        wall = time.perf_counter() - self.wall0
        cpu = time.process_time() - self.cpu0
        r = resource.getrusage(resource.RUSAGE_SELF)
        return {"wall_s": round(wall, 3), "cpu_s": round(cpu, 3),
                "cpu_percent": round(100.0 * cpu / wall, 2) if wall > 0 else float("nan"),
                "user_percent": round(100.0 * (r.ru_utime - self.user0) / wall, 2) if wall > 0 else 0.0,
                "sys_percent": round(100.0 * (r.ru_stime - self.sys0) / wall, 2) if wall > 0 else 0.0,
                # how busy the machine was: other processes take the CPU from the wire
                "involuntary_switches": r.ru_nivcsw - self.nivcsw0,
                "load_average": [round(self.load0, 2), round(os.getloadavg()[0], 2)]}


class CollectorWatch:
    """The cyclic garbage collector's work in this process while watched (``gc.callbacks``):
    per generation, how many collections, their time (a full one stops every thread of the
    process: the app's drawing, and the wire when it runs on a thread of it) and the objects
    they found unreachable (cyclic garbage: what reference counting could not free).

    Each full collection's time is kept (a few a minute: their median); the young ones, 40 a
    second under the app, are only summed, so that watching does not itself grow the heap
    that ``benchmarks/memory.py`` measures (a float a collection was 0.08 MB a minute)."""

    def __init__(self) -> None:
        self._full: list[float] = []
        self._count = [0, 0, 0]
        self._total = [0.0, 0.0, 0.0]
        self._max = [0.0, 0.0, 0.0]
        self._found = [0, 0, 0]
        self._t0 = 0.0

    def _callback(self, phase: str, info: dict[str, int]) -> None:
        if phase == "start":
            self._t0 = time.perf_counter()
        else:
            generation = info["generation"]
            took = time.perf_counter() - self._t0
            self._count[generation] += 1
            self._total[generation] += took
            if took > self._max[generation]:
                self._max[generation] = took
            if generation == 2:
                self._full.append(took)
            self._found[generation] += info["collected"]

    def start(self) -> None:
        gc.callbacks.append(self._callback)

    def stop(self) -> dict[str, Any]:
        if self._callback in gc.callbacks:
            gc.callbacks.remove(self._callback)
        out: dict[str, Any] = {}
        full = sorted(t * 1e3 for t in self._full)
        for generation in (0, 1, 2):
            out[f"gen{generation}"] = {
                "collections": self._count[generation],
                "total_ms": round(self._total[generation] * 1e3, 1),
                # young collections: not kept one by one, so no median
                "median_ms": (round(percentile(full, 50), 2) if full else 0.0) if generation == 2 else None,
                "max_ms": round(self._max[generation] * 1e3, 1),
                "garbage_objects": self._found[generation]}
        return out


def collector_line(watch: dict[str, Any], seconds: float) -> str:
    full, young = watch["gen2"], (watch["gen0"], watch["gen1"])
    garbage = sum(g["garbage_objects"] for g in watch.values())
    return (f"{full['collections']} full collections (median {full['median_ms']:.0f} ms, max "
            f"{full['max_ms']:.0f} ms, {full['total_ms'] / 1e3:.2f} s in all), "
            f"{sum(g['collections'] for g in young)} young ({sum(g['total_ms'] for g in young) / 1e3:.2f} s); "
            f"cyclic garbage {garbage / seconds:,.0f} objects a second")


def rss_mb(pid: int | str = "self") -> float:
    """Resident set size from /proc/PID/status (VmRSS), in MB (nan if it cannot be read)."""
    try:
        with open(f"/proc/{pid}/status") as f:
            for line in f:
                if line.startswith("VmRSS:"):
                    return int(line.split()[1]) / 1024.0
    except OSError:
        pass
    return float("nan")


def child_pids(command_has: str = "") -> list[int]:
    """This process's children (Linux: /proc/self/task/*/children) whose command line holds
    ``command_has`` (``"roles.runtime.wireproc"``: the app's wire process)."""
    pids: list[int] = []
    try:
        for task in os.listdir("/proc/self/task"):
            with open(f"/proc/self/task/{task}/children") as f:
                pids += [int(p) for p in f.read().split()]
    except OSError:
        pass
    out = []
    for pid in pids:
        try:
            with open(f"/proc/{pid}/cmdline", "rb") as f:
                if command_has.encode() in f.read():
                    out.append(pid)
        except OSError:
            pass
    return out


# -- how quiet the machine is ------------------------------------------------------------------
_PROBE = """
import json, sys, time
n = int(sys.argv[1]); late = []; t0 = time.monotonic()
for k in range(1, n + 1):
    target = t0 + k * 0.020
    d = target - time.monotonic()
    if d > 0:
        time.sleep(d)
    late.append((time.monotonic() - target) * 1000.0)
print(json.dumps(late))
"""


def wake_probe(seconds: float = 3.0) -> dict[str, float]:
    """The machine's own timer jitter: a separate, otherwise idle Python process sleeping to
    a 20 ms grid, and how late it wakes (ms). Other processes' load shows here first: when a
    bare sleeper wakes 3 ms late, no design of ours can send on time."""
    probe = WakeProbe(seconds)
    return probe.result()


class WakeProbe:
    """:func:`wake_probe` running beside a measurement (started now, read with result())."""

    def __init__(self, seconds: float) -> None:
        import subprocess

        self.seconds = seconds
        n = max(10, int(seconds / 0.020))
        self.proc = subprocess.Popen([sys.executable, "-c", _PROBE, str(n)], stdout=subprocess.PIPE,
                                     stderr=subprocess.DEVNULL, text=True)

    def result(self) -> dict[str, float]:
        import json

        out, _ = self.proc.communicate(timeout=self.seconds + 60)
        return rounded(summary(json.loads(out)))


# -- a measurement window -------------------------------------------------------------------
class Window:
    """What one measured stretch of a running field needs: the receiving-side recorder, the
    DS round-trip samples, the DS counters and the CPU meter."""

    def __init__(self, record: bool = True) -> None:
        self.recorder = ArrivalRecorder()
        self.record = record  # False: no per-packet lists (a long memory run must not grow them)
        self.fields: list[Any] = []
        self.seconds = 0.0  # set it to run the machine's wake probe beside the measurement

    def attach(self, fields: list[Any]) -> None:
        self.fields = fields
        if self.record:
            for f in fields:
                big_trip_buffers(f)

    def begin(self) -> None:
        for f in self.fields:
            clear_trips(f)
        self.before = self._counters()
        if self.record:
            self.recorder.start()
        self.cpu = CpuMeter()
        self.probe = WakeProbe(self.seconds) if self.seconds else None

    def end(self) -> dict[str, Any]:
        self.recorder.stop()
        cpu = self.cpu.read()
        after = self._counters()
        trips: list[float] = []
        for f in self.fields:
            for st in f.stations:
                if st.ds is not None:
                    trips += list(st.ds.link.echoes.trip.samples)
        return {"pairs": sum(len(f.stations) for f in self.fields), "wire": self.recorder.analyse(cpu["wall_s"]),
                "trip_ms": rounded(summary(trips), 4), "cpu": cpu,
                "ds": {k: after[k] - self.before[k] for k in after}, "rss_mb": round(rss_mb(), 1),
                "wake_probe_ms": self.probe.result() if self.probe else None}

    def _counters(self) -> dict[str, int]:
        total: dict[str, int] = {}
        for f in self.fields:
            for k, v in ds_counters(f).items():
                total[k] = total.get(k, 0) + v
        return total


class _QuitLater:
    """stdin for ``fieldbox --headless``: nothing until :meth:`quit`, then ``quit``."""

    def __init__(self) -> None:
        self.event = threading.Event()

    def __iter__(self):
        self.event.wait(24 * 3600)
        yield "quit\n"

    def quit(self) -> None:
        self.event.set()


async def measure_cli_headless(config, seconds: float, warmup: float) -> dict[str, Any]:
    """Run the real ``fieldbox --headless`` code (fieldbox.headless.run: status lines, log
    files, commands reader) on this loop, with a tap on its runtime, and measure it."""
    import tempfile

    import fieldbox.headless as H

    window = Window()
    seen: dict[str, Any] = {}

    class TappedEngine(H.LoopEngine):
        def __init__(self, *args, **kwargs) -> None:
            super().__init__(*args, **kwargs)
            self.add_tap(window.recorder.tap)
            seen["field"] = self.field

    stdin = _QuitLater()
    old = H.LoopEngine
    H.LoopEngine = TappedEngine
    with tempfile.TemporaryDirectory(prefix="fieldbox-bench-") as logs, open(os.devnull, "w") as null:
        if hasattr(config, "log_dir"):
            config.log_dir = logs  # log files on, as by default, but not in the user's folder
        task = asyncio.create_task(H.run(config, stdin=stdin, out=null, err=null))
        try:
            for _ in range(200):  # bounded: 10 s to bind
                if "field" in seen and seen["field"].bound or task.done():
                    break
                await asyncio.sleep(0.05)
            if task.done():
                raise RuntimeError(f"fieldbox --headless ended early: {task.result()}")
            H.LoopEngine = old
            window.attach([seen["field"]])
            window.seconds = seconds
            await asyncio.sleep(warmup)
            window.begin()
            await asyncio.sleep(seconds)
            result = window.end()
        finally:
            H.LoopEngine = old
            stdin.quit()
            await asyncio.wait_for(task, 10)
    return result


# -- packets seen from outside -------------------------------------------------------------------
SO_TIMESTAMPNS = 35
ETH_P_ALL = 0x0003
SO_RCVBUFFORCE = 33
SOL_PACKET, PACKET_STATISTICS = 263, 6  # struct tpacket_stats: packets, drops (reset when read)
PACKET_HOST = 0  # sll_pkttype of a packet this host received (lo shows each packet twice)


class Capture:
    """UDP on ``lo`` as received, with the kernel's receive times (monotonic clock): what a
    receiving socket saw, measured by nothing of fieldbox's own (root: CAP_NET_RAW).
    ``max_payload``: longer datagrams are only counted (``big``), not kept (a flood of 64 KB
    ones would fill the memory)."""

    def __init__(self, max_payload: int | None = None) -> None:
        self.max_payload = max_payload
        self.big = 0
        self.sock = socket.socket(socket.AF_PACKET, socket.SOCK_RAW, socket.htons(ETH_P_ALL))
        self.sock.bind(("lo", 0))
        self.sock.setsockopt(socket.SOL_SOCKET, SO_TIMESTAMPNS, 1)
        # room for seconds of a busy loopback (browser tabs' websockets included) while this
        # process waits for a CPU: rmem_max caps SO_RCVBUF, root may force past it
        try:
            self.sock.setsockopt(socket.SOL_SOCKET, SO_RCVBUFFORCE, 64 << 20)
        except OSError:
            self.sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 64 << 20)
        self.packets: list[tuple[float, int, int, bytes, str]] = []  # (time, src port, dst port, payload, dst ip)
        self.dropped = 0
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()

    def _run(self) -> None:
        space = socket.CMSG_SPACE(16)
        while not self._stop.is_set():
            ready, _, _ = select.select([self.sock], [], [], 0.1)
            if not ready:
                continue
            data, anc, _, addr = self.sock.recvmsg(65535, space)
            if addr[2] != PACKET_HOST or len(data) < 14 + 20 + 8:
                continue
            offset = 14  # the loopback "Ethernet" header
            if data[offset] >> 4 != 4 or data[offset + 9] != 17:
                continue  # IPv4 UDP only
            ihl = (data[offset] & 0x0F) * 4
            src, dst = struct.unpack_from(">HH", data, offset + ihl)
            stamp = None
            for level, kind, value in anc:
                if level == socket.SOL_SOCKET and kind == SO_TIMESTAMPNS:
                    sec, nsec = struct.unpack_from("@ll", value)
                    stamp = sec + nsec * 1e-9
            if stamp is None:
                continue
            mono = time.monotonic() - (time.time() - stamp)
            if self.max_payload is not None and len(data) - offset - ihl - 8 > self.max_payload:
                self.big += 1
                continue
            dst_ip = socket.inet_ntoa(data[offset + 16:offset + 20])
            self.packets.append((mono, src, dst, bytes(data[offset + ihl + 8:]), dst_ip))

    def drops(self) -> int:
        """Packets the kernel dropped for want of room in this socket since the last call (a
        dropped packet would read as a silence of the field)."""
        try:
            _, dropped = struct.unpack("II", self.sock.getsockopt(SOL_PACKET, PACKET_STATISTICS, 8))
        except OSError:
            return 0
        self.dropped += dropped
        return self.dropped

    def close(self) -> None:
        self._stop.set()
        self._thread.join(2)
        self.drops()
        self.sock.close()



def intervals_at(packets, dst_port: int | tuple[int, ...], t0: float, t1: float,
                 dst_ip: str | None = None) -> list[float]:
    """|interval - 20 ms| between consecutive packets to ``dst_port`` (one, or any of several: a
    DS under an FMS sends to 1115, else 1110) and ``dst_ip``, received in [t0, t1]."""
    ports = dst_port if isinstance(dst_port, tuple) else (dst_port,)
    times = [t for t, _, dst, _, ip in packets if dst in ports and t0 <= t <= t1 and (dst_ip is None or ip == dst_ip)]
    return [abs((b - a) * 1000.0 - PERIOD_MS) for a, b in zip(times, times[1:])]


# -- output -----------------------------------------------------------------------------------
def verdict(ok: bool) -> str:
    return "met" if ok else "MISSED"


def check(name: str, value: float, ok: bool, target: str) -> dict[str, Any]:
    return {"name": name, "value": value, "target": target, "met": bool(ok)}


def print_checks(checks: list[dict[str, Any]]) -> None:
    width = max(len(c["name"]) for c in checks) if checks else 10
    print(f"{'target':{width}}  {'measured':>10}  {'wanted':18} result")
    for c in checks:
        v = c["value"]
        vs = f"{v:.3f}" if isinstance(v, float) else str(v)
        print(f"{c['name']:{width}}  {vs:>10}  {c['target']:18} {verdict(c['met'])}")


class HeadlessField:
    """A ``fieldbox ... --headless --json`` process (``args`` after ``-m fieldbox``, run in
    ``code``'s checkout): its JSON lines gathered by a thread, commands on its stdin. ``raw_bound``
    is its first "bound" line's roles."""

    def __init__(self, args: list[str], code: str = ROOT) -> None:
        import subprocess

        self.proc = subprocess.Popen([sys.executable, "-m", "fieldbox", *args], cwd=code, stdin=subprocess.PIPE,
                                     stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True, bufsize=1)
        self.lines: list[dict] = []
        self.lock = threading.Lock()
        threading.Thread(target=self._read, daemon=True).start()
        self.raw_bound: dict[str, dict[str, str]] = self.wait(lambda o: o.get("type") == "bound")["roles"]

    def _read(self) -> None:
        for line in self.proc.stdout:
            with self.lock:
                self.lines.append(json.loads(line))

    def wait(self, predicate, start: int = 0, timeout: float = 30.0) -> dict:
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            with self.lock:
                for obj in self.lines[start:]:
                    if predicate(obj):
                        return obj
            time.sleep(0.005)
        raise RuntimeError("the field did not say it")

    def latest(self, predicate) -> dict | None:
        with self.lock:
            return next((o for o in reversed(self.lines) if predicate(o)), None)

    def send(self, text: str) -> float:
        self.proc.stdin.write(text + "\n")
        self.proc.stdin.flush()
        return time.monotonic()

    def mark(self) -> int:
        with self.lock:
            return len(self.lines)

    def close(self) -> None:
        try:
            self.send("quit")
            self.proc.wait(10)
        except Exception:  # noqa: BLE001
            self.proc.kill()
