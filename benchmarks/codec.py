"""Encode and decode time per operation for the packets on the 50 Hz path.

    python benchmarks/codec.py            # a table
    python benchmarks/codec.py --json     # one JSON object

Target (protocol issue): the six-joystick DS control packet encodes and decodes in 10 us or
less each way on a 2-core machine.

Then the worst cases (issue 27: a flood of 65 KB datagrams froze a field, 210 ms a decode):
for each UDP packet kind, a 65,507-byte datagram (zeros, 0xff, runs of short tags), refused
by its size bound; and the slowest packet within the bound found among runs of every short
tag (size 0-7, every id), which the tag-count bound keeps short. Target: every one decodes
or is refused in well under a millisecond.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import timeit

sys.path.insert(0, os.environ.get("FIELDBOX_BENCH_ROOT") or os.path.join(os.path.dirname(__file__), ".."))  # as _common

from protocol import ds_to_fms, ds_to_rio, fms_to_ds, kinds, legacy, rio_to_ds  # noqa: E402
from protocol.enums import AllianceStation, Mode, TournamentLevel  # noqa: E402
from protocol.errors import ProtocolError  # noqa: E402

BIGGEST_DATAGRAM = 65507
#: UDP kind -> (its size bound, the bytes its header takes)
UDP_KINDS = {
    "ds-to-rio": (ds_to_rio.MAX_CONTROL_SIZE, 6),
    "rio-to-ds": (rio_to_ds.MAX_STATUS_SIZE, 8),
    "fms-to-ds": (fms_to_ds.MAX_CONTROL_SIZE, 22),
    "ds-to-fms": (ds_to_fms.MAX_STATUS_SIZE, 8),
    "legacy-ds-to-robot": (legacy.CONTROL_SIZE, 0),
    "legacy-robot-to-ds": (legacy.STATUS_LCD_SIZE, 0),
}


def packets():
    joysticks = tuple(ds_to_rio.Joystick((12, -40, 127, -128, 0, 64), 0b1010_0101_0011, 12, (90,))
                      for _ in range(6))
    control = ds_to_rio.ControlPacket(
        sequence=4242, enabled=True, mode=Mode.TELEOP, station=AllianceStation.BLUE2,
        tags=(ds_to_rio.Countdown(97.5),) + joysticks)
    status = rio_to_ds.StatusPacket(
        sequence=4242, enabled=True, robot_code=True, is_roborio=True, user_teleop=True, battery=12.25,
        tags=tuple(rio_to_ds.JoystickOutput(0b101, 30000, 0) for _ in range(6)) + (
            rio_to_ds.DiskInfo(512_000_000),
            rio_to_ds.CpuInfo((rio_to_ds.CpuLoad(1.0, 2.0, 30.0, 4.0),) * 2),
            rio_to_ds.RamInfo(0, 200_000_000),
            rio_to_ds.PdpLog(tuple(range(0, 160, 10))),
            rio_to_ds.CanMetrics(42.5, 0, 0, 0, 0),
        ))
    fms = fms_to_ds.FmsControlPacket(
        sequence=7, enabled=True, mode=Mode.AUTONOMOUS, station=AllianceStation.RED3,
        tournament_level=TournamentLevel.QUALIFICATION, match_number=42, play_number=1,
        remaining_seconds=15)
    legacy_control = legacy.LegacyControlPacket(
        packet_index=77, enabled=True, team=294, station=AllianceStation.RED1,
        joysticks=(legacy.LegacyJoystick((1, 2, 3, -4, -5, 127), 0b1010),) * 4, analog=(100, 200, 300, 1023))
    return [
        ("DS control, 6 joysticks", control, ds_to_rio.decode_control),
        ("roboRIO status, every tag", status, rio_to_ds.decode_status),
        ("FMS control", fms, fms_to_ds.decode_control),
        ("2010 DS control (1024 B, CRC)", legacy_control, legacy.decode_legacy_control),
    ]


def measure(fn, budget: float = 0.4) -> float:
    """Best-of-five microseconds per call, each run about budget/5 seconds."""
    n = 1
    while timeit.timeit(fn, number=n) < budget / 25:
        n *= 2
    return min(timeit.repeat(fn, number=n, repeat=5)) / n * 1e6


def _quietly(fn, data):
    try:
        fn(data)
    except ProtocolError:
        pass


def _fill(header: int, unit: bytes, n: int) -> bytes:
    return (bytes(header) + unit * (n // len(unit) + 1))[:n]


def worst_cases() -> list[dict]:
    """Per UDP kind: the slowest 65,507-byte flood, and the slowest packet at its size bound
    made of one short tag repeated (decode and annotate, microseconds)."""
    floods = [bytes(BIGGEST_DATAGRAM), b"\xff" * BIGGEST_DATAGRAM]
    floods += [_fill(0, bytes.fromhex(u), BIGGEST_DATAGRAM) for u in ("01 07", "01 0c", "01 01", "00")]
    rows = []
    for name, (bound, header) in UDP_KINDS.items():
        k = kinds.get(name)
        flood = max(measure(lambda d=d: _quietly(k.decode, d), 0.05) for d in floods)
        flood_annotate = max(measure(lambda d=d: k.annotate_lenient(d), 0.05) for d in floods)
        # search: one pass each, then the slowest measured properly
        found = []
        for size in range(8):
            for tag in range(256):
                unit = bytes((size, tag)) + bytes(max(0, size - 1))
                data = _fill(header, unit, bound)
                t = timeit.timeit(lambda d=data: _quietly(k.decode, d), number=1)
                found.append((t, data, unit))
        _, data, unit = max(found, key=lambda f: f[0])
        rows.append({"kind": name, "bound": bound, "flood_decode_us": round(flood, 1),
                     "flood_annotate_us": round(flood_annotate, 1), "worst_unit": unit.hex(" "),
                     "worst_decode_us": round(measure(lambda d=data: _quietly(k.decode, d), 0.1), 1),
                     "worst_annotate_us": round(measure(lambda d=data: k.annotate_lenient(d), 0.1), 1)})
    return rows


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    rows = []
    for name, message, decode in packets():
        data = message.encode()
        assert decode(data) == message, name
        rows.append({"packet": name, "bytes": len(data), "encode_us": round(measure(message.encode), 2),
                     "decode_us": round(measure(lambda d=data, f=decode: f(d)), 2)})
    machine = {"python": platform.python_version(), "machine": platform.machine(),
               "cpus": os.cpu_count(), "platform": platform.platform()}
    worst = worst_cases()
    if args.json:
        print(json.dumps({"machine": machine, "codecs": rows, "worst": worst}))
        return 0
    print(f"codec timings, Python {machine['python']} on {machine['cpus']} CPUs ({machine['platform']})")
    print(f"{'packet':32} {'bytes':>6} {'encode us':>10} {'decode us':>10}")
    for r in rows:
        print(f"{r['packet']:32} {r['bytes']:>6} {r['encode_us']:>10.2f} {r['decode_us']:>10.2f}")
    target = rows[0]
    ok = target["encode_us"] <= 10 and target["decode_us"] <= 10
    print(f"target: six-joystick control packet <= 10 us each way: {'met' if ok else 'MISSED'}")
    print()
    print("worst cases: a 65,507-byte datagram (refused by its size), and the slowest packet at the bound")
    print(f"{'kind':20} {'bound':>6} {'65 KB decode':>13} {'annotate':>9}  {'worst at the bound':24} "
          f"{'decode':>7} {'annotate':>9}  (us)")
    for w in worst:
        print(f"{w['kind']:20} {w['bound']:>6} {w['flood_decode_us']:>13.1f} {w['flood_annotate_us']:>9.1f}  "
              f"{'runs of ' + w['worst_unit']:24} {w['worst_decode_us']:>7.1f} {w['worst_annotate_us']:>9.1f}")
    slowest = max(max(w["flood_decode_us"], w["worst_decode_us"]) for w in worst)
    print(f"target: every one decoded or refused in well under 1 ms: {'met' if slowest < 1000 else 'MISSED'} "
          f"(slowest {slowest:.1f} us)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
