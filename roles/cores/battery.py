"""A robot battery for the fake roboRIO: voltage that sags under load and recovers at rest,
with the roboRIO's brownout protection on top. Pure: time comes in as ``now``.

The model is the one a power budget uses (frc-docs, "roboRIO Brownout and Understanding
Current Draw"): terminal voltage = resting voltage - internal resistance x current, reached
through a short lag (sag is fast, recovery slower), the resting voltage falling slowly as
charge is used. Brownout follows the roboRIO's stage-2 rule: below the trigger the outputs
are disabled and the DS's 12 V fault counter goes up by one; the roboRIO stays there until
the voltage rises above 7.5 V. The trigger is 6.8 V here (the issue's number, and close to
the roboRIO 2's default of 6.75 V; the original roboRIO disabled outputs at 6.3 V).
"""

from __future__ import annotations

import math
import random

DEFAULT_VOLTS = 12.6
BROWNOUT_VOLTS = 6.8
RECOVER_VOLTS = 7.5
MAX_VOLTS = 20.0  # anything a 12 V lead-acid battery and a bench supply can show


class Battery:
    """Battery voltage driven by ``update(now, amps)``.

    ``volts`` is the terminal voltage the roboRIO reads; ``brownout`` is the roboRIO's
    brownout state (with hysteresis); ``brownouts`` counts entries into it. ``force(v)``
    pins the reading (fault injection, teaching); ``force(None)`` lets the model run again.
    """

    def __init__(self, volts: float = DEFAULT_VOLTS, *, resistance: float = 0.015,
                 sag_time: float = 0.05, recover_time: float = 0.5,
                 capacity_ah: float | None = 18.0, empty_drop: float = 1.2,
                 noise: float = 0.0, seed: int | None = None,
                 brownout_volts: float = BROWNOUT_VOLTS, recover_volts: float = RECOVER_VOLTS) -> None:
        _check_volts(volts)
        if not recover_volts >= brownout_volts:
            raise ValueError("recover_volts must be at least brownout_volts")
        self.resistance = resistance  # ohms: battery plus wiring (about 0.011 + a little)
        self.sag_time = sag_time  # s: time constant while the voltage falls
        self.recover_time = recover_time  # s: time constant while it rises
        self.capacity_ah = capacity_ah  # None: the resting voltage never falls
        self.empty_drop = empty_drop  # V lost from the resting voltage over the whole capacity
        self.noise = noise  # V: standard deviation of the reading's noise
        self.brownout_volts = brownout_volts
        self.recover_volts = recover_volts
        self._rng = random.Random(seed)
        self.rest_volts = float(volts)  # open-circuit voltage
        self._model_volts = float(volts)  # before noise and forcing
        self.volts = float(volts)  # what the roboRIO reads
        self.amps = 0.0  # the load of the last update
        self.used_ah = 0.0
        self.forced: float | None = None
        self.brownout = False
        self.brownouts = 0
        self._last: float | None = None

    # -- commands -------------------------------------------------------------------
    def set_voltage(self, volts: float) -> None:
        """A fresh (or another) battery: resting voltage ``volts``, nothing used yet."""
        _check_volts(volts)
        self.rest_volts = float(volts)
        self._model_volts = float(volts)
        self.used_ah = 0.0
        if self.forced is None:
            self.volts = float(volts)

    def force(self, volts: float | None) -> None:
        """Pin the reading at ``volts`` whatever the load (``None``: back to the model)."""
        if volts is not None:
            _check_volts(volts)
            self.volts = float(volts)
        self.forced = None if volts is None else float(volts)

    # -- time -----------------------------------------------------------------------
    def update(self, now: float, amps: float) -> float:
        """Advance to ``now`` with ``amps`` drawn since the last update; return the volts.

        Brownout is judged on the new reading. Going back in time (or standing still)
        only re-judges the reading.
        """
        amps = max(0.0, float(amps)) if amps == amps else 0.0
        dt = 0.0 if self._last is None else max(0.0, now - self._last)
        self._last = now if self._last is None else max(self._last, now)
        if dt > 0.0:
            if self.capacity_ah:
                self.used_ah = min(self.capacity_ah, self.used_ah + self.amps * dt / 3600.0)
                drop = self.empty_drop * self.used_ah / self.capacity_ah
            else:
                drop = 0.0
            target = max(0.0, self.rest_volts - drop - self.resistance * amps)
            tau = self.sag_time if target < self._model_volts else self.recover_time
            self._model_volts += (target - self._model_volts) * (1.0 - math.exp(-dt / tau))
        self.amps = amps
        if self.forced is not None:
            self.volts = self.forced
        else:
            jitter = self._rng.gauss(0.0, self.noise) if self.noise > 0 and dt > 0 else 0.0
            self.volts = min(MAX_VOLTS, max(0.0, self._model_volts + jitter))
        self._judge()
        return self.volts

    def _judge(self) -> None:
        if not self.brownout and self.volts < self.brownout_volts:
            self.brownout = True
            self.brownouts += 1
        elif self.brownout and self.volts > self.recover_volts:
            self.brownout = False

    def snapshot(self) -> dict[str, float | bool | None]:
        return {"volts": round(self.volts, 3), "rest_volts": round(self.rest_volts, 3),
                "amps": round(self.amps, 2), "used_ah": round(self.used_ah, 4),
                "forced": self.forced, "brownout": self.brownout, "brownouts": self.brownouts}


def _check_volts(volts: float) -> None:
    if isinstance(volts, bool) or not isinstance(volts, (int, float)) or not 0.0 <= volts <= MAX_VOLTS:
        raise ValueError(f"battery voltage must be a number of volts in 0..{MAX_VOLTS:g}, not {volts!r}")
