"""The fake roboRIO's control link: which DS it follows, which control packet it obeys, the
watchdog and the e-stop latch. The rules are stated in roles/cores/rio.py's docstring; this is
where they are kept, apart from everything else the robot does, so they can be read in one go.

The Rio asks :meth:`ControlLink.foreign` about each datagram's source before it decodes a
byte (a second DS's packets, or a flood from anywhere, cost a comparison, not a decode), then
hands each decoded control packet to :meth:`ControlLink.receive`, which answers with a verdict
(:data:`STALE` or :class:`Obeyed`); for an obeyed packet the Rio acts on the requests it
carries, then :meth:`ControlLink.obey` takes its header. Whether the robot is enabled is
decided in one place, :meth:`ControlLink.apply`.
"""

from __future__ import annotations

from contextlib import contextmanager
from dataclasses import dataclass
from typing import TYPE_CHECKING, Iterator

from protocol.ds_to_rio import ControlPacket, MalformedTag
from protocol.enums import AllianceStation, Mode

from .core import Address, Events, LinkStats, Throttle
from .rio_program import BEAT
from .views import MODE_LABEL

if TYPE_CHECKING:
    from .rio import RioFaults

#: A sequence number further ahead of the last one obeyed than this (a second of packets),
#: plus two a beat since that one arrived, is not a DS that lost a few: it is counted and not
#: obeyed (a forged packet must not make the real DS's next packets look old).
MAX_SEQUENCE_JUMP = 50


FOREIGN = "foreign"  # from a second DS while the first is heard: dropped undecoded, not answered
STALE = "stale"  # not the newest, taken up late or a sequence far ahead: answered, not obeyed


@dataclass(frozen=True, slots=True)
class Obeyed:
    """The packet is obeyed; the requests it starts (a bit's rising edge) come first."""

    reboot: bool
    restart: bool


class ControlLink:
    """The DS followed on UDP and what it asked, as the robot applies it."""

    def __init__(self, *, watchdog: float, ds_timeout: float, single_ds: bool, events: Events,
                 faults: RioFaults, link: LinkStats, reply_port: int | None = None) -> None:
        self.watchdog = watchdog
        #: Where the DS is answered: its host's UDP ``reply_port`` (1150, as a real roboRIO), or
        #: None: the packet's source port (the ephemeral plan). It also says who the DS is.
        self.reply_port = reply_port
        self.ds_timeout = ds_timeout
        self.single_ds = single_ds
        self.events = events
        self.faults = faults
        self.link = link  # ds->rio
        self.power_on()

    def power_on(self) -> None:
        """Everything a reboot forgets."""
        self.estopped = False
        self.enabled = False  # applied
        self.mode = Mode.TELEOP  # the DS's mode, echoed
        self.watchdog_tripped = False
        self.ds_address: Address | None = None
        self.ds_enabled = False  # what the DS asks
        self.ds_estop = False
        self.fms_attached = False
        self.station = AllianceStation.RED1
        self.last_sequence: int | None = None
        self._last_packet_at: float | None = None  # when the last packet obeyed arrived
        self._ds_alive = False
        self._request_bits = (False, False)  # (reboot, restart) in the last packet obeyed
        self._enable_held = False  # a restarted DS's sequence: no enabling before a disabled packet
        self._arriving = False  # a control packet is being taken up: no enable before it is
        self._log = Throttle()

    def power_off(self) -> None:
        """The roboRIO reboots: nothing is heard or enabled until it is back."""
        self.enabled = False
        self.link.connected = False

    @property
    def ds_connected(self) -> bool:
        return self._ds_alive

    @property
    def ds_host(self) -> str | None:
        """The host of the DS followed, while it is heard."""
        return self.ds_address[0] if self._ds_alive and self.ds_address else None

    def is_followed(self, source: Address) -> bool:
        """Whether ``source`` is the DS followed. A DS is known by where the robot answers it: a
        real roboRIO answers its DS's host on UDP 1150 whatever port the packets come from, so
        the host alone says who the DS is (LibDS re-creates its socket, and sends from a new
        port, each time its 1 s watchdog expires: still the same DS, its sequence going on).
        Only where replies go back to the source port (``reply_port`` None, the ephemeral plan,
        every role on 127.0.0.1) is the port part of it."""
        followed = self.ds_address
        if followed is None or source[0] != followed[0]:
            return False
        return self.reply_port is not None or source[1] == followed[1]

    # -- a control packet --------------------------------------------------------------
    def foreign(self, source: Address, now: float) -> bool:
        """Whether a datagram from ``source`` is dropped before it is decoded: from anywhere
        but the DS followed (:meth:`is_followed`: another host), while that DS is heard
        (counted, and logged once a second). A DS that falls silent for ``ds_timeout`` is lost,
        and then the first DS heard is followed (a DS restarted elsewhere, or a new one)."""
        if not (self.single_ds and self.ds_address is not None and not self.is_followed(source) and self._ds_alive):
            return False
        self.faults.foreign_packets += 1
        self.link.foreign_packets += 1
        held = self._log.due("foreign", now)
        if held is not None:
            self.events.add(now, f"ignoring a second DS at {source[0]}:{source[1]} "
                                 f"(following {self.ds_address[0]}:{self.ds_address[1]}){Throttle.suffix(held)}")
        return True

    def receive(self, packet: ControlPacket, size: int, source: Address, now: float, arrived: float,
                superseded: bool) -> str | Obeyed:
        """The verdict on a decoded control packet of ``size`` bytes from ``source``, which
        :meth:`foreign` let through. An e-stop in it latches at once, whatever the verdict,
        if it comes from the DS followed (or from any DS while none is heard)."""
        refused = self._refusal(packet.sequence, source, now, arrived, superseded)
        if refused is not None and refused != "resync":
            # Not the newest packet (a delayed, reordered, duplicated or superseded one), taken
            # up late (the robot's process stalled), or a sequence far ahead. It changes
            # nothing, not even the watchdog, but an e-stop in it latches; the Rio answers it
            # with the state applied now, so the DS's trip time stays true.
            if packet.estop and (self.is_followed(source) or not self._ds_alive):
                self._latch_estop(now)
            if refused == "jump":
                self.faults.sequence_jumps += 1
                if self._log.due("jump", now) is not None:
                    self.events.add(now, f"ignoring a control packet whose sequence jumped from "
                                         f"{self.last_sequence} to {packet.sequence} "
                                         f"(more than {MAX_SEQUENCE_JUMP} ahead)")
            else:
                self.faults.stale_packets += 1
            self.link.stale_packets += 1
            return STALE
        self.link.received(size, now)
        self.link.connected = True
        if not self.is_followed(source):
            self.events.add(now, f"following the DS at {source[0]}:{source[1]}")
        else:
            was = self.ds_address
            if was is not None and source != was:  # the same DS from a new port: its socket re-created
                held = self._log.due("port", now)
                if held is not None:
                    self.events.add(now, f"the DS at {source[0]} now sends from port {source[1]} "
                                         f"(was {was[1]}){Throttle.suffix(held)}")
            if not self._ds_alive:
                self.events.add(now, "DS packets arriving again")
        self.ds_address = source
        self._ds_alive = True
        self._last_packet_at = arrived
        self.watchdog_tripped = False
        self.last_sequence = packet.sequence
        if refused == "resync" and not self._enable_held:
            # the DS restarted (or its packets were lost and a far older or newer one came):
            # followed again, but a packet from before the gap must not enable the robot
            self._enable_held = True
            self.events.add(now, f"DS sequence restarted at {packet.sequence}: disabled until it sends "
                                 "a disabled packet")
        if not packet.enabled:
            self._enable_held = False
        # requests act on the bit's rising edge: a DS may repeat the bit for a few packets
        was_reboot, was_restart = self._request_bits
        self._request_bits = (packet.reboot_roborio, packet.restart_code)
        return Obeyed(packet.reboot_roborio and not was_reboot, packet.restart_code and not was_restart)

    def obey(self, packet: ControlPacket, now: float) -> None:
        """Take the header of an obeyed packet (its requests already acted on). A malformed
        tag is counted and dropped; the header stands, as WPILib's robot side does."""
        self.ds_estop = packet.estop
        if packet.estop:
            self._latch_estop(now)
        self.ds_enabled = packet.enabled
        self.mode = packet.mode
        self.fms_attached = packet.fms_attached
        self.station = packet.station
        for tag in packet.tags:
            if type(tag) is MalformedTag:
                self.faults.malformed_tags += 1
                self.link.last_error = f"malformed tag dropped, header applied: {tag.reason}"

    def _refusal(self, sequence: int, source: Address, now: float, arrived: float,
                 superseded: bool) -> str | None:
        """Why a control packet is not obeyed: ``"stale"`` (superseded, taken up more than
        ``watchdog`` after it arrived, or not newer than the last one obeyed from the same
        sender while that one is younger than ``watchdog``), ``"jump"`` (more than
        MAX_SEQUENCE_JUMP ahead of it), or None: obey it; ``"resync"``: obey it, but its
        sequence does not follow the last one, which is older than ``watchdog`` (a restarted
        DS): the robot stays disabled until the DS sends a disabled packet. The DS followed is
        one sender whatever its source port (:meth:`is_followed`), so a DS that re-creates its
        socket and starts its sequence again is held like any other restarted DS. Newer means
        ``(seq - last) mod 65536`` in 1..32767 (serial-number arithmetic)."""
        if superseded or now - arrived > self.watchdog:
            return "stale"
        if self.last_sequence is None or self._last_packet_at is None or not self.is_followed(source):
            return None
        step = (sequence - self.last_sequence) & 0xFFFF
        gap = arrived - self._last_packet_at
        # as far ahead as a DS can get in that time (50 Hz; open-ds steps by 2), and a second more
        follows = 0 < step <= min(0x7FFF, MAX_SEQUENCE_JUMP + int(2 * max(gap, 0.0) / BEAT))
        if gap >= self.watchdog:
            return None if follows else "resync"  # the watchdog has tripped: taken again
        if not 0 < step < 0x8000:
            return "stale"
        return None if follows else "jump"

    # -- the latch, the watchdog and the enable ------------------------------------------
    def _latch_estop(self, now: float) -> None:
        if not self.estopped:
            self.estopped = True
            self.events.add(now, "E-STOP: latched until the code restarts or the roboRIO reboots")
            self._set_enabled(False, now)

    def clear_estop(self, now: float) -> None:
        """The code restarts: the only way (with a reboot) an e-stop is ever cleared."""
        if self.estopped:
            self.events.add(now, "e-stop cleared by the code restart")
        self.estopped = False

    def watch(self, now: float) -> None:
        """The watchdog (disables) and the DS timeout (the DS is lost), by arrival time."""
        if self._last_packet_at is None:
            return
        if not self.watchdog_tripped and now >= self._last_packet_at + self.watchdog:
            self.watchdog_tripped = True
            if self.enabled:
                self.faults.comms += 1
                self.events.add(now, f"watchdog: no DS packet for {self.watchdog * 1000:.0f} ms, robot disabled")
        if self._ds_alive and now >= self._last_packet_at + self.ds_timeout:
            self._ds_alive = False
            self.link.connected = False
            self.events.add(now, f"DS lost: no packet for {self.ds_timeout:g} s")

    def deadlines(self) -> list[float]:
        """When the watchdog or the DS timeout next needs a look."""
        if self._last_packet_at is None:
            return []
        times = []
        if not self.watchdog_tripped:
            times.append(self._last_packet_at + self.watchdog)
        if self._ds_alive:
            times.append(self._last_packet_at + self.ds_timeout)
        return times

    @contextmanager
    def arriving(self) -> Iterator[None]:
        """While a control packet is being taken up, what falls due first (a code start, a
        beat) must not enable the robot on the word of the packet before it."""
        self._arriving = True
        try:
            yield
        finally:
            self._arriving = False

    def apply(self, now: float, code_alive: bool) -> None:
        """The one rule for enabling: the DS asks, no e-stop, code there, the watchdog quiet, no
        restarted DS's sequence held, and never before the packet under way is taken up."""
        self._set_enabled(self.ds_enabled and not self.estopped and code_alive and not self.watchdog_tripped
                          and not self._enable_held and (self.enabled or not self._arriving)
                          and self._last_packet_at is not None, now)

    def _set_enabled(self, enabled: bool, now: float) -> None:
        if enabled != self.enabled:
            self.enabled = enabled
            self.events.add(now, f"robot enabled in {MODE_LABEL[self.mode]}" if enabled else "robot disabled")

