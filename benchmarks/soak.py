"""Hostile input against a running full field: does fieldbox keep its beat, count every bad
packet, stay within its bounds, keep its memory flat, and never let an exception escape?

    python benchmarks/soak.py                   # 60 s, a table
    python benchmarks/soak.py --seconds 10      # shorter
    python benchmarks/soak.py --rate 3000 --json

The field: six DS, six fake roboRIOs and the FMS, ephemeral plan (127.0.0.1, OS-chosen
ports), on the wire's own thread exactly as the app runs it (``roles.runtime.engine.ThreadEngine``),
a match running. The attacker: a separate process (this script with ``--attack``), so its
CPU is not the wire's (it runs at nice 10: on a field, hostile traffic comes from another
machine), sending from 127.0.0.1 only:

* UDP, to every listening socket (each roboRIO's control ports, each DS's robot and FMS
  ports, the FMS's status port), ``--rate`` datagrams a second in all: random bytes,
  truncated real packets, packets with a corrupted byte, empty datagrams and, now and then,
  oversized ones (9-60 KB). Each is checked with the protocol's own decoder before it goes:
  only what the decoder rejects is sent, so every one of them must be counted: as bad, or as
  foreign where a role judges the source before the bytes and the attacker is not its peer
  (a roboRIO's second DS, a DS's FMS control, a station's status at the FMS). The
  roboRIOs also get well-formed control packets *with enable set* from this second sender:
  each must be counted as foreign and ignored.
* TCP, to every server (each roboRIO's 1740, the FMS's 1750): connections that send garbage,
  a frame header over the size bound, a frame never finished, nothing at all, bursts of 100
  connections at once, and (FMS) logins for teams not in the match.

Figures: the 20 ms beat as each roboRIO receives its DS's control packets (a runtime tap
on the receiving side), lost packets (sequence gaps), bad-packet counters against what was
sent (less what the kernel dropped for a full socket buffer, from /proc/net/udp), the peak
of every connection bound, RSS before and after, and every error logged or exception
raised anywhere (logging handler, sys/threading excepthooks, the loop's exception handler).
The exit status is 0 when every check holds.
"""

from __future__ import annotations

import argparse
import asyncio
import gc
import json
import logging
import os
import random
import socket
import subprocess
import sys
import threading
import time
from typing import Any

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), ".."))
if ROOT not in sys.path:
    sys.path.insert(0, ROOT)

from protocol import ds_to_fms, ds_to_rio, fms_to_ds, rio_to_ds  # noqa: E402
from protocol.enums import AllianceStation, Mode  # noqa: E402
from protocol.errors import ProtocolError  # noqa: E402

SIX_TEAMS = [254, 1114, 2056, 118, 148, 1678]
#: What each listening UDP socket expects, and the decoder that judges a datagram bad.
DECODERS = {
    "rio": ds_to_rio.decode_control,     # a roboRIO's control ports
    "ds-robot": rio_to_ds.decode_status,  # a DS's robot port
    "ds-fms": fms_to_ds.decode_control,   # a DS's FMS port
    "fms": ds_to_fms.decode_status,       # the FMS's status port
}


# ==============================================================================================
# the attacker (a separate process)
# ==============================================================================================
def _sample(family: str, rng: random.Random) -> bytes:
    """A well-formed packet of the kind a socket expects (to truncate or corrupt)."""
    if family == "rio":
        joy = ds_to_rio.Joystick(tuple(rng.randint(-128, 127) for _ in range(4)), rng.getrandbits(12), 12, (-1,))
        return ds_to_rio.ControlPacket(rng.getrandbits(16), enabled=True, mode=Mode.TELEOP,
                                       tags=(ds_to_rio.Countdown(12.5), joy)).encode()
    if family == "ds-robot":
        return rio_to_ds.StatusPacket(rng.getrandbits(16), robot_code=True, is_roborio=True, battery=12.5).encode()
    if family == "ds-fms":
        return fms_to_ds.FmsControlPacket(rng.getrandbits(16), enabled=True, station=AllianceStation.BLUE2,
                                          match_number=7, remaining_seconds=100).encode()
    return ds_to_fms.DsStatusPacket(rng.getrandbits(16), robot_comms=True, team=254, battery=12.0,
                                    tags=(ds_to_fms.CommsMetrics(1, 2, 3),)).encode()


def _bad_datagram(family: str, rng: random.Random) -> tuple[str, bytes] | None:
    """(kind, bytes) that the family's decoder rejects, or None if the draw decoded."""
    r = rng.random()
    if r < 0.01:
        kind, data = "oversized", rng.randbytes(rng.randint(9000, 60000))
    elif r < 0.05:
        kind, data = "empty", b""
    elif r < 0.40:
        kind, data = "random", rng.randbytes(rng.randint(1, 1400))
    elif r < 0.75:
        sample = _sample(family, rng)
        kind, data = "truncated", sample[:rng.randrange(len(sample))]
    else:
        sample = bytearray(_sample(family, rng))
        i = rng.randrange(len(sample))
        sample[i] ^= rng.randint(1, 255)
        kind, data = "malformed", bytes(sample)
    try:
        DECODERS[family](data)
    except ProtocolError:
        return kind, data
    return None


class _TcpAttack:
    """Connections against one TCP server, of every hostile kind, bounded in number."""

    HOLD = 40  # connections kept open at once per server (idle or with an unfinished frame)

    def __init__(self, name: str, addr: tuple[str, int], fms: bool, rng: random.Random) -> None:
        self.name, self.addr, self.fms, self.rng = name, addr, fms, rng
        self.counts: dict[str, int] = {}
        self.held: list[asyncio.StreamWriter] = []
        self.bad_closed_in: list[float] = []  # how long fieldbox took to close a bad-frame connection

    def count(self, key: str, n: int = 1) -> None:
        self.counts[key] = self.counts.get(key, 0) + n

    async def _open(self):
        try:
            return await asyncio.wait_for(asyncio.open_connection(*self.addr), 2.0)
        except (OSError, asyncio.TimeoutError):
            self.count("connect_failed")
            return None

    async def _closed_by_peer(self, reader, timeout: float) -> float | None:
        """Seconds until fieldbox closed the connection (None: still open after ``timeout``)."""
        t0 = time.monotonic()
        while True:
            left = timeout - (time.monotonic() - t0)
            if left <= 0:
                return None
            try:
                data = await asyncio.wait_for(reader.read(65536), left)
            except asyncio.TimeoutError:
                return None
            except (OSError, ValueError):  # reset: closed too
                return time.monotonic() - t0
            if not data:
                return time.monotonic() - t0

    async def one(self) -> None:
        rng = self.rng
        kinds = ["garbage", "oversized", "unfinished", "idle", "burst"] + (["login"] if self.fms else [])
        kind = rng.choice(kinds)
        if kind == "burst":
            opened = await asyncio.gather(*(self._open() for _ in range(100)))
            writers = [c[1] for c in opened if c is not None]
            self.count("burst_connections", len(writers))
            await asyncio.sleep(0.2)
            for w in writers:
                w.transport.abort()
            return
        conn = await self._open()
        if conn is None:
            return
        reader, writer = conn
        self.count(kind)
        if kind in ("garbage", "oversized"):
            if kind == "oversized":  # a size field far over any bound, then some bytes of it
                writer.write(bytes([0xFF, rng.randint(0xF0, 0xFF)]) + rng.randbytes(100))
            else:
                writer.write(bytes([0xFF, 0xFF]) + rng.randbytes(rng.randint(1, 3000)))
            closed = await self._closed_by_peer(reader, 2.0)
            if closed is None:
                self.count(f"{kind}_not_closed")
                writer.transport.abort()
            else:
                self.bad_closed_in.append(closed)
            return
        if kind == "login":  # a well-formed login for a team not in the match, then leave
            writer.write(ds_to_fms.TeamNumber(rng.randint(2000, 9999)).encode())
            await asyncio.sleep(0.05)
            writer.transport.abort()
            return
        if kind == "unfinished":  # a frame that announces 200 bytes and sends 50
            writer.write(bytes([0x00, 0xC8]) + rng.randbytes(50))
        self.held.append(writer)
        while len(self.held) > self.HOLD:
            self.held.pop(0).transport.abort()

    async def run(self, until: float, per_second: float) -> None:
        while time.monotonic() < until:
            try:
                await self.one()
            except (OSError, ConnectionError):
                self.count("errors")
            await asyncio.sleep(min(self.rng.expovariate(per_second), max(0.0, until - time.monotonic())))
        for w in self.held:
            w.transport.abort()
        self.held.clear()


async def _attack(plan: dict[str, Any]) -> dict[str, Any]:
    rng = random.Random(plan["seed"])
    until = time.monotonic() + plan["seconds"]
    socks = []
    for _ in range(4):
        s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        s.setsockopt(socket.SOL_SOCKET, socket.SO_SNDBUF, 1 << 20)
        s.bind(("127.0.0.1", 0))
        s.setblocking(False)
        socks.append(s)
    udp = {name: {"family": t["family"], "addr": tuple(t["addr"]), "bad": 0, "valid_foreign": 0,
                  "send_failed": 0, "kinds": {}} for name, t in plan["udp"].items()}
    skipped = 0
    tcp = [_TcpAttack(name, tuple(t["addr"]), t["family"] == "fms", random.Random(rng.random()))
           for name, t in plan["tcp"].items()]
    tasks = [asyncio.create_task(a.run(until, plan["tcp_rate"])) for a in tcp]
    names = list(udp)
    tick, rate = 0.005, plan["rate"]
    per_tick = rate * tick
    owed, t_next, i = 0.0, time.monotonic(), 0
    while time.monotonic() < until:
        owed += per_tick
        while owed >= 1.0:
            owed -= 1.0
            name = names[i % len(names)]
            i += 1
            target = udp[name]
            family = target["family"]
            if family == "rio" and rng.random() < 0.1:  # well-formed, enabled, from a second sender
                kind, data = "valid_foreign", _sample("rio", rng)
            else:
                drawn = _bad_datagram(family, rng)
                if drawn is None:
                    skipped += 1
                    continue
                kind, data = drawn
            try:
                rng.choice(socks).sendto(data, target["addr"])
            except (BlockingIOError, OSError):
                target["send_failed"] += 1
                continue
            if kind == "valid_foreign":
                target["valid_foreign"] += 1
            else:
                target["bad"] += 1
            target["kinds"][kind] = target["kinds"].get(kind, 0) + 1
        t_next += tick
        await asyncio.sleep(max(0.0, t_next - time.monotonic()))
    await asyncio.gather(*tasks, return_exceptions=True)
    for s in socks:
        s.close()
    return {"udp": udp, "skipped_valid_draws": skipped,
            "tcp": {a.name: {"counts": a.counts, "bad_frame_closed_max_s": max(a.bad_closed_in, default=None)}
                    for a in tcp}}


def attacker_main(plan_json: str) -> int:
    plan = json.loads(plan_json)
    try:  # hostile traffic comes from elsewhere on a field: do not take the CPU from the wire
        os.nice(plan.get("nice", 10))
    except OSError:
        pass
    print(json.dumps(asyncio.run(_attack(plan))), flush=True)
    return 0


# ==============================================================================================
# the field under attack (this process)
# ==============================================================================================
class ErrorRecorder(logging.Handler):
    """Every ERROR logged, every exception that reaches a hook: must stay empty."""

    def __init__(self) -> None:
        super().__init__(logging.ERROR)
        self.items: list[str] = []
        self._old: dict[str, Any] = {}

    def emit(self, record: logging.LogRecord) -> None:
        self.items.append(f"log {record.name}: {record.getMessage()}"
                          + (f" ({record.exc_info[1]!r})" if record.exc_info else ""))

    def install(self) -> None:
        logging.getLogger().addHandler(self)
        self._old = {"sys": sys.excepthook, "threading": threading.excepthook}
        sys.excepthook = lambda t, v, tb: self.items.append(f"sys.excepthook: {v!r}")
        threading.excepthook = lambda a: self.items.append(f"thread {a.thread and a.thread.name}: {a.exc_value!r}")

    def loop_handler(self, loop, context) -> None:
        self.items.append(f"asyncio: {context.get('message')} {context.get('exception')!r}")

    def uninstall(self) -> None:
        logging.getLogger().removeHandler(self)
        sys.excepthook = self._old.get("sys", sys.__excepthook__)
        threading.excepthook = self._old.get("threading", threading.__excepthook__)


class BeatRecorder:
    """A runtime tap: the control packets each roboRIO receives *from its own DS*."""

    def __init__(self, sources: dict[str, tuple[str, int]]) -> None:
        self.sources = sources  # rio role name -> its DS's robot socket
        self.times: dict[str, list[float]] = {name: [] for name in sources}
        self.seqs: dict[str, list[int]] = {name: [] for name in sources}
        self.on = False

    def tap(self, r) -> None:  # a roles.runtime.shell.TapRecord
        if not self.on or r.direction != "in" or r.kind != "ds-to-rio":
            return
        source, remote, data = self.sources.get(r.role), r.remote, r.data
        if source is None or remote is None or (remote[0], remote[1]) != source or len(data) < 2:
            return
        self.times[r.role].append(r.time)
        self.seqs[r.role].append((data[0] << 8) | data[1])

    def figures(self) -> dict[str, Any]:
        intervals: list[float] = []
        lost = reordered = received = 0
        worst_p99 = 0.0
        for role, times in self.times.items():
            iv = [(b - a) * 1000.0 for a, b in zip(times, times[1:])]
            intervals += iv
            if iv:
                worst_p99 = max(worst_p99, _pct(sorted(iv), 99))
            received += len(times)
            seqs = self.seqs[role]
            for a, b in zip(seqs, seqs[1:]):
                gap = (b - a) & 0xFFFF
                if gap == 0 or gap > 0x8000:
                    reordered += 1
                else:
                    lost += gap - 1
        iv = sorted(intervals)
        return {"received": received, "lost": lost, "reordered": reordered,
                "interval_ms": {"n": len(iv), "min": _r(iv[0] if iv else None), "median": _r(_pct(iv, 50)),
                                "p99": _r(_pct(iv, 99)), "p999": _r(_pct(iv, 99.9)),
                                "max": _r(iv[-1] if iv else None)},
                "worst_stream_p99_ms": _r(worst_p99)}


def _pct(v: list[float], q: float) -> float | None:
    if not v:
        return None
    return v[max(0, min(len(v) - 1, int(round(q / 100.0 * len(v) + 0.5)) - 1))]


def _r(x, digits: int = 3):
    return None if x is None else round(x, digits)


def rss_mb() -> float:
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) / 1024.0
    return float("nan")


def udp_drops(ports: set[int]) -> dict[int, int]:
    """Datagrams the kernel dropped (full receive buffer) per local UDP port, /proc/net/udp."""
    out: dict[int, int] = {}
    for path in ("/proc/net/udp", "/proc/net/udp6"):
        try:
            with open(path) as f:
                next(f)
                for line in f:
                    cols = line.split()
                    port = int(cols[1].rsplit(":", 1)[1], 16)
                    if port in ports:
                        out[port] = out.get(port, 0) + int(cols[-1])
        except (OSError, StopIteration, ValueError, IndexError):
            pass
    return out


def _targets(field) -> tuple[dict, dict, dict]:
    """UDP targets, TCP targets, and for each UDP target how to read its counters."""
    udp, tcp, readers = {}, {}, {}
    for st in field.stations:
        rb = field.bound[st.rio_name]
        for ch in ("ds", "ds-fms"):
            name = f"{st.rio_name} {ch}"
            udp[name] = {"family": "rio", "addr": list(rb[ch])}
        tcp[f"{st.rio_name} tcp"] = {"family": "rio", "addr": list(rb["tcp"])}
        db = field.bound[st.ds_name]
        udp[f"{st.ds_name} robot"] = {"family": "ds-robot", "addr": list(db["robot"])}
        udp[f"{st.ds_name} fms"] = {"family": "ds-fms", "addr": list(db["fms"])}
    fb = field.bound[field.fms_name]
    udp["fms udp"] = {"family": "fms", "addr": list(fb["udp"])}
    tcp["fms tcp"] = {"family": "fms", "addr": list(fb["tcp"])}
    return udp, tcp, readers


def _counters(field) -> dict[str, int]:
    """The bad/foreign counters the attack must move, summed per family."""
    out = {"rio_bad": 0, "rio_foreign": 0, "ds_robot_bad": 0, "ds_fms_bad": 0, "ds_fms_foreign": 0, "fms_bad": 0,
           "fms_foreign": 0, "rio_tcp_bad": 0, "rio_refused": 0, "fms_tcp_bad": 0, "fms_refused": 0}
    for st in field.stations:
        out["rio_bad"] += st.rio.stats["ds->rio"].bad_packets
        out["rio_foreign"] += st.rio.faults.foreign_packets
        out["rio_tcp_bad"] += st.rio.stats["rio-tcp"].bad_packets
        out["rio_refused"] += st.rio.faults.refused_clients
        out["ds_robot_bad"] += st.ds.stats["rio->ds"].bad_packets
        out["ds_fms_bad"] += st.ds.stats["fms-udp"].bad_packets
        out["ds_fms_foreign"] += st.ds.fms.foreign_packets
    out["fms_bad"] = field.fms.udp_stats.bad_packets
    out["fms_foreign"] = field.fms.udp_stats.foreign_packets  # a station's status not from its DS
    out["fms_tcp_bad"] = field.fms.logins.tcp_stats.bad_packets
    out["fms_refused"] = field.fms.logins.refused_connections
    return out


class BoundsWatch:
    """Peaks of every connection bound, sampled while the attack runs."""

    def __init__(self, engine) -> None:
        from roles.runtime.shell import MAX_CONNECTIONS

        self.engine = engine
        self.limit_shell = MAX_CONNECTIONS
        self.peak: dict[str, int] = {"shell_streams_per_server": 0, "rio_tcp_clients": 0, "fms_connections": 0,
                                     "fms_match_log": 0}
        self.ds_links_dropped = 0
        self._was: dict[str, bool] = {}

    def sample(self) -> None:
        field = self.engine.field
        for host in list(self.engine.runtime.hosts.values()):
            per: dict[str, int] = {}
            for conn in list(host.streams):
                if isinstance(conn, tuple):
                    per[conn[0]] = per.get(conn[0], 0) + 1
            if per:
                self.peak["shell_streams_per_server"] = max(self.peak["shell_streams_per_server"], max(per.values()))
        for st in field.stations:
            self.peak["rio_tcp_clients"] = max(self.peak["rio_tcp_clients"], st.rio.tcp.count)
            for key, up in ((f"{st.ds_name} robot-tcp", st.ds.tcp.state == "open"),
                            (f"{st.ds_name} comms", st.ds.link.robot_comms),
                            (f"{st.ds_name} fms", st.ds.fms.attached)):
                if self._was.get(key) and not up:
                    self.ds_links_dropped += 1
                self._was[key] = up
        self.peak["fms_connections"] = max(self.peak["fms_connections"], len(field.fms.logins.connections))
        self.peak["fms_match_log"] = max(self.peak["fms_match_log"], len(field.fms.match_log))


def run_soak(seconds: float = 60.0, rate: float = 1000.0, tcp_rate: float = 5.0, seed: int = 1,
             warmup: float = 2.0, baseline: float | None = None, attacker_nice: int = 10) -> dict[str, Any]:
    """Start the field, measure its beat undisturbed for ``baseline`` seconds (default: a
    sixth of ``seconds``, 2..10 s: this machine's own noise), attack it for ``seconds``,
    and return every figure."""
    from roles.cores.fms import MAX_CONNECTIONS as FMS_MAX
    from roles.runtime import process_tuning
    from roles.runtime.engine import ThreadEngine
    from roles.runtime.field import FieldConfig
    from roles.runtime.shell import MAX_CONNECTIONS, MAX_WRITE_BUFFER

    errors = ErrorRecorder()
    errors.install()
    config = FieldConfig(roles=frozenset({"ds", "rio", "fms"}), team=SIX_TEAMS[0], plan="ephemeral",
                         log_files=False)
    config.teams = list(SIX_TEAMS)
    engine = ThreadEngine(config)
    engine.start()
    process_tuning.hold_collector()  # as the app does while its wire runs
    result: dict[str, Any] = {"seconds": seconds, "rate": rate, "tcp_rate_per_server": tcp_rate, "seed": seed,
                              "attacker_nice": attacker_nice}
    try:
        runtime, field = engine.runtime, engine.field
        runtime.call(lambda: runtime.loop.set_exception_handler(errors.loop_handler)).result(5)
        deadline = time.monotonic() + 15
        while time.monotonic() < deadline and not all(
                s.ds.link.robot_comms and s.ds.link.robot_code and s.ds.fms.attached and s.ds.tcp.state == "open"
                for s in field.stations):
            time.sleep(0.05)
        engine.execute(_parse("match start"))
        time.sleep(warmup)
        sources = {st.rio_name: tuple(field.bound[st.ds_name]["robot"]) for st in field.stations}
        quiet = BeatRecorder(sources)
        engine.add_tap(quiet.tap)
        quiet.on = True
        time.sleep(baseline if baseline is not None else min(10.0, max(2.0, seconds / 6)))
        quiet.on = False
        engine.remove_tap(quiet.tap)
        beat = BeatRecorder(sources)
        engine.add_tap(beat.tap)
        watchdog_before = sum(st.rio.faults.comms for st in field.stations)
        udp, tcp, _ = _targets(field)
        ports = {t["addr"][1] for t in udp.values()}
        gc.collect()
        before = {"counters": engine.call(lambda: _counters(field)), "drops": udp_drops(ports), "rss": rss_mb(),
                  "match_log": field.fms.match_log_total}
        bounds = BoundsWatch(engine)
        plan = {"seconds": seconds, "rate": rate, "tcp_rate": tcp_rate, "seed": seed, "udp": udp, "tcp": tcp,
                "nice": attacker_nice}
        beat.on = True
        t0 = time.monotonic()
        proc = subprocess.Popen([sys.executable, os.path.abspath(__file__), "--attack", json.dumps(plan)],
                                stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        rss_mid = None
        while proc.poll() is None and time.monotonic() - t0 < seconds + 30:
            bounds.sample()
            if rss_mid is None and time.monotonic() - t0 >= seconds / 2:
                rss_mid = rss_mb()
            time.sleep(0.1)
        try:
            out, err = proc.communicate(timeout=30)
        except subprocess.TimeoutExpired:
            proc.kill()
            out, err = proc.communicate()
        attack_wall = time.monotonic() - t0
        time.sleep(0.5)  # what is in flight lands
        beat.on = False
        bounds.sample()
        gc.collect()
        after = {"counters": engine.call(lambda: _counters(field)), "drops": udp_drops(ports), "rss": rss_mb(),
                 "match_log": field.fms.match_log_total}
        if proc.returncode != 0 or not out.strip():
            raise RuntimeError(f"the attacker failed ({proc.returncode}): {err.strip()[-2000:]}")
        attack = json.loads(out.strip().splitlines()[-1])
        delta = {k: after["counters"][k] - before["counters"][k] for k in after["counters"]}
        drops = {p: after["drops"].get(p, 0) - before["drops"].get(p, 0) for p in ports}

        def family_sent(family: str, key: str) -> int:
            return sum(t[key] for t in attack["udp"].values() if t["family"] == family)

        def family_drops(family: str) -> int:
            return sum(drops.get(t["addr"][1], 0) for t in udp.values() if t["family"] == family)

        counted = {}
        for family, got in (("rio", delta["rio_bad"] + delta["rio_foreign"]), ("ds-robot", delta["ds_robot_bad"]),
                            ("ds-fms", delta["ds_fms_bad"] + delta["ds_fms_foreign"]),
                            ("fms", delta["fms_bad"] + delta["fms_foreign"])):
            sent = family_sent(family, "bad") + family_sent(family, "valid_foreign")
            dropped = family_drops(family)
            counted[family] = {"sent": sent, "kernel_drops": dropped, "counted": got, "ok": got == sent - dropped}
        counted["rio"]["foreign_sent"] = family_sent("rio", "valid_foreign")
        counted["rio"]["foreign_counted"] = delta["rio_foreign"]
        kinds: dict[str, int] = {}
        for t in attack["udp"].values():
            for k, n in t["kinds"].items():
                kinds[k] = kinds.get(k, 0) + n
        tcp_counts: dict[str, int] = {}
        bad_close = []
        for t in attack["tcp"].values():
            for k, n in t["counts"].items():
                tcp_counts[k] = tcp_counts.get(k, 0) + n
            if t["bad_frame_closed_max_s"] is not None:
                bad_close.append(t["bad_frame_closed_max_s"])
        result.update({
            "attack": {"wall_s": round(attack_wall, 2),
                       "udp_sent": sum(t["bad"] + t["valid_foreign"] for t in attack["udp"].values()),
                       "udp_kinds": kinds, "udp_send_failed": sum(t["send_failed"] for t in attack["udp"].values()),
                       "tcp": tcp_counts, "bad_frame_closed_max_s": _r(max(bad_close, default=None))},
            "beat": beat.figures(),
            "beat_undisturbed": quiet.figures(),
            "watchdog_disables": sum(st.rio.faults.comms for st in field.stations) - watchdog_before,
            "counted": counted,
            "tcp_counters": {k: delta[k] for k in ("rio_tcp_bad", "rio_refused", "fms_tcp_bad", "fms_refused")},
            "bounds": {**bounds.peak, "limits": {"shell_streams_per_server": MAX_CONNECTIONS,
                                                 "rio_tcp_clients": field.stations[0].rio.tcp.max_clients,
                                                 "fms_connections": FMS_MAX,
                                                 "shell_write_buffer": MAX_WRITE_BUFFER}},
            "ds_links_dropped": bounds.ds_links_dropped,
            "memory": {"rss_before_mb": round(before["rss"], 1), "rss_after_mb": round(after["rss"], 1),
                       "rss_mid_mb": None if rss_mid is None else round(rss_mid, 1),
                       "growth_mb": round(after["rss"] - before["rss"], 1),
                       "fms_match_log_growth": after["match_log"] - before["match_log"]},
            "errors": errors.items[:20], "error_count": len(errors.items),
            "attacker_stderr": err.strip()[-500:],
        })
    finally:
        engine.stop()
        process_tuning.release_collector()
        errors.uninstall()
    return result


def _parse(line: str):
    from fieldbox.language import parse

    return parse(line)


def verdicts(r: dict[str, Any], *, p99_ms: float = 25.0, p99_margin_ms: float = 5.0, max_ms: float = 100.0,
             median_tol_ms: float = 0.5, rss_mb: float = 10.0, timing: bool = True) -> list[str]:
    """Every check that failed (empty: all good).

    The beat: median 20 ms; p99 within ``p99_ms``, or within ``p99_margin_ms`` of what the
    same field showed undisturbed just before (a busy machine's own noise is not the
    attack's doing); no gap of ``max_ms`` (the roboRIO's 100 ms watchdog) or more, no
    watchdog disable, no control packet lost. ``timing=False`` leaves out what a busy
    machine decides rather than the attack (the beat's figures, watchdog disables, how soon
    a bad connection closed): the test's checks; the figures are this script's to print."""
    fail = []
    b = r["beat"]
    iv = b["interval_ms"]
    quiet = r.get("beat_undisturbed", {}).get("interval_ms", {})
    if iv["n"] < 10:
        fail.append(f"too few control packets measured ({iv['n']})")
    elif timing:
        if abs(iv["median"] - 20.0) > median_tol_ms:
            fail.append(f"beat median {iv['median']} ms, not 20 +- {median_tol_ms}")
        allowed = max(p99_ms, (quiet.get("p99") or 0.0) + p99_margin_ms)
        if iv["p99"] > allowed:
            fail.append(f"beat p99 {iv['p99']} ms > {allowed:g} (undisturbed p99 {quiet.get('p99')})")
        if iv["max"] >= max_ms:
            fail.append(f"beat max {iv['max']} ms >= {max_ms}")
    if timing and r.get("watchdog_disables"):
        fail.append(f"{r['watchdog_disables']} robot watchdog disables")
    if b["lost"]:
        fail.append(f"{b['lost']} control packets lost")
    for family, c in r["counted"].items():
        if not c["ok"]:
            fail.append(f"{family}: counted {c['counted']}, sent {c['sent']} less {c['kernel_drops']} kernel drops")
    if r["counted"]["rio"]["foreign_sent"] and not r["counted"]["rio"]["foreign_counted"]:
        fail.append("no foreign control packet counted")
    lim = r["bounds"]["limits"]
    for key in ("shell_streams_per_server", "rio_tcp_clients", "fms_connections"):
        if r["bounds"][key] > lim[key]:
            fail.append(f"{key} peaked at {r['bounds'][key]} > {lim[key]}")
    tcp = r["attack"]["tcp"]
    for kind in ("garbage", "oversized"):
        if timing and tcp.get(f"{kind}_not_closed"):
            fail.append(f"{tcp[f'{kind}_not_closed']} {kind} connections not closed within 2 s")
    if r["ds_links_dropped"]:
        fail.append(f"{r['ds_links_dropped']} DS links (robot comms, robot TCP, FMS) dropped during the attack")
    if r["memory"]["growth_mb"] > rss_mb:
        fail.append(f"RSS grew {r['memory']['growth_mb']} MB > {rss_mb}")
    if r["error_count"]:
        fail.append(f"{r['error_count']} errors/exceptions: {r['errors'][:3]}")
    return fail


def table(r: dict[str, Any], failures: list[str]) -> str:
    a, b, m = r["attack"], r["beat"], r["memory"]
    iv = b["interval_ms"]
    q = r["beat_undisturbed"]["interval_ms"]
    lines = [
        f"soak: {r['seconds']:g} s of hostile input against a full field (6 DS, 6 roboRIOs, FMS; ephemeral plan)",
        f"  attack      {a['udp_sent']} bad/foreign datagrams ({r['rate']:g}/s asked; "
        + ", ".join(f"{k} {v}" for k, v in sorted(a["udp_kinds"].items())) + ")",
        "              TCP: " + ", ".join(f"{k} {v}" for k, v in sorted(a["tcp"].items()))
        + f"; bad-frame connections closed within {a['bad_frame_closed_max_s']} s",
        f"  beat        {iv['n']} intervals: median {iv['median']} ms, p99 {iv['p99']}, p99.9 {iv['p999']}, "
        f"max {iv['max']} (worst stream p99 {b['worst_stream_p99_ms']}); lost {b['lost']}, reordered {b['reordered']}, "
        f"watchdog disables {r['watchdog_disables']}",
        f"  undisturbed {q['n']} intervals just before: median {q['median']} ms, p99 {q['p99']}, "
        f"p99.9 {q['p999']}, max {q['max']}",
    ]
    for family, c in r["counted"].items():
        lines.append(f"  counted     {family:9s} sent {c['sent']}, kernel drops {c['kernel_drops']}, "
                     f"counted {c['counted']} {'ok' if c['ok'] else 'MISMATCH'}"
                     + (f" (foreign {c['foreign_counted']}/{c['foreign_sent']})" if "foreign_sent" in c else ""))
    lines.append("  TCP counted " + ", ".join(f"{k} {v}" for k, v in r["tcp_counters"].items()))
    bd = r["bounds"]
    lines.append("  bounds      " + ", ".join(f"{k} {bd[k]}/{bd['limits'][k]}" for k in
                                              ("shell_streams_per_server", "rio_tcp_clients", "fms_connections"))
                 + f"; FMS match log +{m['fms_match_log_growth']} entries; DS links dropped {r['ds_links_dropped']}")
    lines.append(f"  memory      RSS {m['rss_before_mb']} -> {m['rss_mid_mb']} (half-way) -> {m['rss_after_mb']} MB "
                 f"({m['growth_mb']:+} MB; the cores' bounded buffers, e.g. each DS's minute of battery "
                 "history, fill in the first minute)")
    lines.append(f"  errors      {r['error_count']}" + (f": {r['errors'][:3]}" if r["errors"] else ""))
    lines.append("  verdict     " + ("OK" if not failures else "FAILED: " + "; ".join(failures)))
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--seconds", type=float, default=60.0, help="how long the attack lasts (default 60)")
    p.add_argument("--rate", type=float, default=1000.0, help="hostile datagrams per second in all (default 1000)")
    p.add_argument("--tcp-rate", type=float, default=5.0, help="hostile TCP connections per second per server")
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--attacker-nice", type=int, default=10, metavar="N",
                   help="the attacker process's niceness (default 10: on a field hostile traffic comes "
                        "from another machine; 0 lets it take the CPU from the wire)")
    p.add_argument("--json", action="store_true", help="one JSON object")
    p.add_argument("--attack", help=argparse.SUPPRESS)
    args = p.parse_args(argv)
    if args.attack:
        return attacker_main(args.attack)
    if not (0 < args.seconds <= 3600) or args.rate <= 0 or args.tcp_rate <= 0:
        p.error("--seconds 0..3600, --rate and --tcp-rate above 0")
    sys.setswitchinterval(0.0005)
    r = run_soak(args.seconds, args.rate, args.tcp_rate, args.seed, attacker_nice=args.attacker_nice)
    failures = verdicts(r)
    r["failures"] = failures
    print(json.dumps(r, indent=1) if args.json else table(r, failures))
    return 0 if not failures else 1


if __name__ == "__main__":
    sys.exit(main())
