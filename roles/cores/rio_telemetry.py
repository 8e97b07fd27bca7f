"""What the fake roboRIO measures beyond its state: the battery under the load the robot draws
(a brownout disables the outputs and counts a 12 V fault), the sixteen PDP currents, and the
disk, CPU, RAM and CAN tags a real roboRIO adds to its status packets.

The numbers are a model, deterministic on a fake clock, so tests stay exact.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

from protocol import rio_to_ds
from protocol.rio_to_ds import CanMetrics, CpuInfo, CpuLoad, DiskInfo, PdpLog, RamInfo

from .battery import Battery
from .core import Events
from .robot_program import JoystickState

if TYPE_CHECKING:
    from .rio import RioFaults

BASE_AMPS = 2.5  # the roboRIO, the radio and friends, always drawn


class Telemetry:
    """The battery and the measurements a status packet carries."""

    def __init__(self, battery: Battery, *, extra_tags: bool, events: Events, faults: RioFaults) -> None:
        self.battery = battery
        self.extra_tags = extra_tags  # False: the status packets carry none (as the simulator's)
        self.events = events
        self.faults = faults
        self.power_on()

    def power_on(self) -> None:
        """What a reboot forgets: the cached readings, the brownouts already counted."""
        self._brownouts = self.battery.brownouts
        self._amps_key: tuple[Any, ...] | None = None
        self._amps: list[float] = [0.0] * 16
        self._extra_key: tuple[Any, ...] | None = None
        self._extra: list[rio_to_ds.StatusTag] = []

    def pdp_amps(self, live: bool, joysticks: tuple[JoystickState, ...]) -> list[float]:
        """Sixteen PDP channel currents: 8 "drive motors" follow the joystick axes (40 A at
        full stick), the other channels draw a little while the outputs are ``live``;
        nothing when they are off (disabled, brownout, no code)."""
        key = (live, joysticks)
        if key == self._amps_key:
            return self._amps
        amps = [0.0] * 16
        if live:
            axes = [abs(a) for joy in joysticks for a in joy.axes]
            amps = [0.25] * 16
            if axes:
                for c in range(8):
                    amps[c] += 40.0 * axes[c % len(axes)]
        self._amps_key, self._amps = key, amps
        return amps

    def update_battery(self, now: float, live: bool, joysticks: tuple[JoystickState, ...]) -> None:
        self.battery.update(now, sum(self.pdp_amps(live, joysticks)) + BASE_AMPS)
        if self.battery.brownouts != self._brownouts:
            self.faults.rail_12v += self.battery.brownouts - self._brownouts
            self._brownouts = self.battery.brownouts
            self.events.add(now, f"BROWNOUT at {self.battery.volts:.2f} V: outputs disabled")

    def status_tags(self, live: bool, joysticks: tuple[JoystickState, ...], busy: bool, enabled: bool,
                    beats: int) -> list[rio_to_ds.StatusTag]:
        """Disk, CPU, RAM, PDP and CAN tags, as a real roboRIO sends (the simulator does not);
        ``busy``: robot code runs."""
        if not self.extra_tags:
            return []
        amps = self.pdp_amps(live, joysticks)
        # the numbers move a little every half second
        key = (self._amps_key, busy, enabled, beats // 25)
        if key == self._extra_key:
            return self._extra
        load = 1.0 if busy else 0.0
        wobble = 2.0 * math.sin(key[3] * 1.7)
        cpu = CpuLoad(time_critical=4.0 * load, above_normal=3.0, normal=18.0 * load + 6.0 * enabled + wobble + 5.0,
                      low=1.0)
        cpu2 = CpuLoad(time_critical=1.0, above_normal=2.0, normal=9.0 * load + 3.0, low=0.5)
        self._extra_key = key
        self._extra = [
            DiskInfo(free_bytes=412_000_000, block=0),
            CpuInfo((cpu, cpu2)),
            RamInfo(block=256_000_000, free_bytes=int(118_000_000 - 4_000_000 * load)),
            PdpLog(currents=tuple(min(rio_to_ds.MAX_PDP_RAW, round(a / rio_to_ds.PDP_AMPS_PER_UNIT))
                                  for a in amps)),
            CanMetrics(utilization=(12.0 + 0.02 * sum(amps)) if load else 3.0),
        ]
        return self._extra
