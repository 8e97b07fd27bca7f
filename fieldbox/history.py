"""What each Driver Station saw over the last minutes, for the Charts tab.

The DS core keeps a minute of battery samples and its last 256 round trips, with no times on
the latter; the NI Driver Station charts several minutes. :class:`DsHistory` samples every DS
of the field every :data:`SAMPLE_PERIOD` seconds of the field's clock (so a test on a fake
clock draws the same chart each run), keeping :data:`KEPT_SECONDS`:

* ``battery``: the lowest voltage in the period (a brief dip is what matters on a battery);
* ``trip``: the worst round trip (control packet -> its status echo) of the period, in ms;
* ``lost``: control packets lost in the period, per second;
* ``cpu``: the roboRIO's CPU in percent, from the status packet's CPU tag (all threads, the
  mean over its CPUs);
* ``mode``: what the robot was told: ``estop``, ``disabled``, or the mode when enabled.

Reading the cores costs a few attribute reads per DS and period: the app calls
:meth:`sample` from its 10 Hz refresh whatever tab is shown, so a chart opened later has its
minutes. No textual here.
"""

from __future__ import annotations

import bisect
from collections import deque
from dataclasses import dataclass, field
from typing import Any

SAMPLE_PERIOD = 0.5
KEPT_SECONDS = 600.0
_KEPT = int(KEPT_SECONDS / SAMPLE_PERIOD)

Series = deque  # of (time, value): value None where nothing was known


@dataclass
class StationHistory:
    """One DS's series, each a deque of ``(time, value)`` in time order."""

    battery: Series = field(default_factory=lambda: deque(maxlen=_KEPT))
    trip: Series = field(default_factory=lambda: deque(maxlen=_KEPT))
    lost: Series = field(default_factory=lambda: deque(maxlen=_KEPT))
    cpu: Series = field(default_factory=lambda: deque(maxlen=_KEPT))
    mode: Series = field(default_factory=lambda: deque(maxlen=_KEPT))
    #: (time, lost packets, packets sent) at the last sample
    last: tuple[float, int, int] | None = None

    def series(self, name: str) -> Series:
        return getattr(self, name)


def cpu_percent(cpu: Any) -> float | None:
    """The roboRIO's CPU tag as one figure: the four priority classes summed, the mean over
    its CPUs, 0..100 (None without a tag)."""
    loads = getattr(cpu, "cpus", None)
    if not loads:
        return None
    total = sum(c.time_critical + c.above_normal + c.normal + c.low for c in loads) / len(loads)
    return max(0.0, min(100.0, total))


def mode_of(ds: Any) -> str:
    if ds.arbiter.estopped:
        return "estop"
    if not ds.link.robot_comms:
        return "no comms"
    if not ds.enabled:
        return "disabled"
    return ds.mode.label.lower()


class DsHistory:
    """Every DS's history, by team. ``sample(engine, now)`` from the app's refresh."""

    def __init__(self) -> None:
        self.stations: dict[int, StationHistory] = {}
        self._engine: Any = None
        self._next = float("-inf")

    def get(self, team: int | None) -> StationHistory | None:
        return self.stations.get(team) if team is not None else None

    def sample(self, engine: Any, now: float) -> None:
        if engine is not self._engine:  # another field: other teams, another clock
            self._engine = engine
            self.stations.clear()
            self._next = float("-inf")
        if now < self._next:
            return
        # on the period's grid, so samples of a fake clock fall at the same times every run
        self._next = (now // SAMPLE_PERIOD + 1) * SAMPLE_PERIOD
        for st in engine.field.stations:
            ds = st.ds
            if ds is None:
                continue
            h = self.stations.get(st.team)
            if h is None:
                h = self.stations[st.team] = StationHistory()
            self._sample_ds(h, ds, now)

    @staticmethod
    def _sample_ds(h: StationHistory, ds: Any, now: float) -> None:
        since = h.last[0] if h.last is not None else now - SAMPLE_PERIOD
        points = list(ds.telemetry.battery_history)  # one C-level copy: the wire may append meanwhile
        start = bisect.bisect_right(points, (since, float("inf")))
        volts = [v for _, v in points[start:]]
        h.battery.append((now, min(volts) if volts else (ds.link.battery if ds.link.robot_comms else None)))
        sent, lost = ds.link.echoes.sent_packets, ds.link.echoes.lost_packets
        new_trips = 0 if h.last is None else max(0, sent - h.last[2])
        trips = list(ds.link.echoes.trip.samples)[-new_trips:] if new_trips and ds.link.robot_comms else []
        h.trip.append((now, max(trips) if trips else None))
        if h.last is not None and now > h.last[0]:
            h.lost.append((now, max(0, lost - h.last[1]) / (now - h.last[0])))
        else:
            h.lost.append((now, 0.0))
        h.cpu.append((now, cpu_percent(ds.telemetry.cpu) if ds.link.robot_comms else None))
        h.mode.append((now, mode_of(ds)))
        h.last = (now, lost, sent)
