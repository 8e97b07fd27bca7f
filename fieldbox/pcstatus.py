"""The PC's own battery and CPU, as the NI Driver Station shows them beside the robot's.

A laptop at the driver station runs out of battery, or is too busy to send control packets
on time: both are worth a glance. Read from Linux's ``/proc/stat`` (the whole machine's CPU
time, between two reads at least :data:`CPU_PERIOD` apart) and ``/sys/class/power_supply``
(a ``Battery`` supply's ``capacity`` and ``status``). Elsewhere, or without a battery, the
value is None and nothing is shown. No textual here: the app reads it at its own pace.
"""

from __future__ import annotations

import os
import time
from dataclasses import dataclass
from typing import Callable

#: Seconds between CPU readings: shorter gives a jumpy figure from a handful of ticks.
CPU_PERIOD = 1.0
#: Seconds between battery readings (it changes by a percent in minutes).
BATTERY_PERIOD = 10.0


@dataclass(frozen=True)
class PcReading:
    """CPU busy in percent over the last period, battery charge in percent and whether it
    charges (None: not known here)."""

    cpu: float | None = None
    battery: float | None = None
    charging: bool | None = None

    def text(self) -> str:
        """``PC cpu 12% battery 80%`` (``+`` when charging), or "" when nothing is known."""
        parts = []
        if self.cpu is not None:
            parts.append(f"cpu {self.cpu:.0f}%")
        if self.battery is not None:
            parts.append(f"battery {self.battery:.0f}%{'+' if self.charging else ''}")
        return ("PC " + " ".join(parts)) if parts else ""


class PcStatus:
    """``read()`` the latest :class:`PcReading`; cheap to call ten times a second (the files
    are read only once per period)."""

    def __init__(self, proc_stat: str = "/proc/stat", power_supply: str = "/sys/class/power_supply",
                 clock: Callable[[], float] = time.monotonic) -> None:
        self.proc_stat = proc_stat
        self.power_supply = power_supply
        self.clock = clock
        self._cpu_at = float("-inf")
        self._ticks: tuple[int, int] | None = None  # (busy, total) at the last reading
        self._cpu: float | None = None
        self._battery_at = float("-inf")
        self._battery: tuple[float | None, bool | None] = (None, None)

    def read(self) -> PcReading:
        now = self.clock()
        if now - self._cpu_at >= CPU_PERIOD:
            self._cpu_at = now
            self._cpu = self._read_cpu()
        if now - self._battery_at >= BATTERY_PERIOD:
            self._battery_at = now
            self._battery = self._read_battery()
        return PcReading(self._cpu, *self._battery)

    def _read_cpu(self) -> float | None:
        try:
            with open(self.proc_stat) as f:
                fields = f.readline().split()
        except OSError:
            return None
        if not fields or fields[0] != "cpu":
            return None
        try:
            values = [int(v) for v in fields[1:]]
        except ValueError:
            return None
        idle = values[3] + (values[4] if len(values) > 4 else 0)  # idle + iowait
        total = sum(values[:8])  # guest time is already counted in user time
        ticks = (total - idle, total)
        old, self._ticks = self._ticks, ticks
        if old is None or ticks[1] <= old[1]:
            return self._cpu
        return max(0.0, min(100.0, 100.0 * (ticks[0] - old[0]) / (ticks[1] - old[1])))

    def _read_battery(self) -> tuple[float | None, bool | None]:
        try:
            supplies = sorted(os.listdir(self.power_supply))
        except OSError:
            return (None, None)
        for name in supplies:
            folder = os.path.join(self.power_supply, name)
            if _read(folder, "type") != "Battery":
                continue
            capacity = _read(folder, "capacity")
            if capacity is None or not capacity.isdigit():
                continue
            status = _read(folder, "status") or ""
            return (float(min(100, int(capacity))), status in ("Charging", "Full"))
        return (None, None)


def _read(folder: str, name: str) -> str | None:
    try:
        with open(os.path.join(folder, name)) as f:
            return f.read(64).strip()
    except OSError:
        return None
