"""Deliberately wrong Driver Stations for the conformance tests: fieldbox's own DS, run
headless, with one wire bug of another implementation put in.

    python tests/conform/wrong_ds.py BUG -- FIELDBOX ARGS...

BUG is one of:

* ``libds-joystick-size``: joystick tags with LibDS's 2015/2016 size byte, payload + 2 (one
  more than the layout; PROTOCOL-NOTES Corrections "A malformed tag");
* ``step-two``: the sequence number steps by two, as open-ds's does;
* ``period-25ms``: a control packet every 25 ms instead of 20 (LibDS sends every ~25.5 ms);
* ``stall-6s``: one control packet, then nothing for 6 s, then every 20 ms (as open-ds starts);
* ``one-packet``: one control packet, then nothing ever again;
* ``swing-14-26``: control packets 14 and 26 ms apart by turns (a 20 ms median, a jitter of 6 ms);
* ``gap-2s``: a second of control packets, nothing for 2 s, then every 20 ms again;
* ``toggle-stays-enabled``: ``enable`` toggles (open-ds's enable button), and robot comms are
  never counted lost, so the DS keeps sending enabled to a silent robot.
* ``udp-only-fms``: never opens TCP 1750, but sends its UDP status to the FMS every 500 ms
  all the same (as LibDS does).
* ``libds-date``: LibDS's 2020 date: while the robot asks (request-date) every packet carries
  the date instead of joysticks, its date tag with no size byte (``0f`` and ten bytes: the
  epoch, as LibDS's clock that is never read, with the day of the year, 0, as the day) and the
  time zone written id first (``10 03 UTC``), so a robot never reads it and keeps asking.
* ``empty-match-info``: on connecting to TCP 1740, an empty match info frame ``00 01 07``
  (no name length, type, number or replay) after the descriptors.
"""

from __future__ import annotations

import sys

BUGS = ("libds-joystick-size", "step-two", "period-25ms", "stall-6s", "one-packet", "swing-14-26", "gap-2s",
        "toggle-stays-enabled", "udp-only-fms", "libds-date", "empty-match-info")
#: LibDS's date and time zone (frc_2020.c get_timezone_data, its clock at 0: the epoch): the
#: date tag's id with no size byte, µs, s, min, hour, day of the year, month, year - 1900; then
#: the time zone's id before its length.
LIBDS_DATE = bytes.fromhex("0f 00000000 00 00 00 00 00 46 10 03") + b"UTC"


def libds_sizes(data: bytes) -> bytes:
    """A control packet with every non-empty joystick tag's size byte one too big."""
    out = bytearray(data[:6])
    pos = 6
    while pos < len(data):
        size = data[pos]
        chunk = data[pos:pos + 1 + size]
        if size > 1 and data[pos + 1] == 0x0C:
            chunk = bytes((size + 1,)) + chunk[1:]
        out += chunk
        pos += 1 + size
    return bytes(out)


def install(bug: str) -> None:
    import dataclasses

    import roles.cores.ds as ds

    if bug == "libds-joystick-size":
        encode = ds.ModernRobotCodec.encode_control
        ds.ModernRobotCodec.encode_control = staticmethod(lambda state: libds_sizes(encode(state)))
    elif bug == "step-two":
        from roles.cores.ds_robot import RobotLink

        send = RobotLink.control_datagram

        def step_two(self, now, **state):
            datagram = send(self, now, **state)
            self._seq = (self._seq + 1) & 0xFFFF
            return datagram
        RobotLink.control_datagram = step_two
    elif bug == "period-25ms":
        ds.PERIOD = 0.025
    elif bug in ("stall-6s", "one-packet", "gap-2s"):
        from roles.cores.ds_robot import RobotLink

        due = RobotLink.slot_due
        first: list[float] = []

        def stall(self, now):
            if not due(self, now):
                return False
            if not first:
                first.append(now)
            if bug == "gap-2s":
                return not first[0] + 1.0 <= now < first[0] + 3.0
            return now == first[0] or (bug == "stall-6s" and now >= first[0] + 6.0)
        RobotLink.slot_due = stall
    elif bug == "swing-14-26":
        import roles.cores.ds_robot as ds_robot
        from roles.cores.core import Grid

        class Swing(Grid):
            """Send slots 14 and 26 ms apart by turns."""

            @property
            def next(self):
                if self.origin is None:
                    return None
                return self.origin + (self.k // 2) * 0.040 + (0.014 if self.k % 2 else 0.0)

            def take(self, now):
                due = self.next
                if due is None or now < due:
                    return None
                skipped = -1
                while self.next <= now:
                    self.k += 1
                    skipped += 1
                return skipped
        ds_robot.Grid = Swing
    elif bug == "toggle-stays-enabled":
        from roles.cores.ds_robot import RobotLink

        RobotLink.comms_timed_out = lambda self, now: False
        enable = ds.DriverStation.enable

        def toggle(self, now):
            if self.arbiter.enabled_local:
                self.disable(now)
            else:
                enable(self, now)
        ds.DriverStation.enable = toggle
    elif bug == "udp-only-fms":
        from roles.cores.ds_fms import FMS_OUT, Datagram, FmsClient

        def udp_only(self, now):
            if self.fms_udp is None:
                return []
            if self._reports.next_deadline() == float("inf"):
                self._reports.start(now, 0)
            status, _ = self._reports.due(now, self._report, True)
            return [Datagram(FMS_OUT, status, self.fms_udp, "ds-to-fms")] if status is not None else []
        FmsClient.poll = udp_only
        FmsClient.next_deadline = lambda self: self._reports.next_deadline() if self.fms_udp else None
    elif bug == "libds-date":
        from roles.cores.ds_robot import DateTag

        DateTag.asked = lambda self: setattr(self, "_due", True)  # asked again: sent again, as LibDS
        encode = ds.ModernRobotCodec.encode_control

        def libds_date(state):
            if state.date is None:
                return encode(state)
            head = encode(dataclasses.replace(state, joysticks=(), countdown=None, date=None, timezone=None))
            return head + LIBDS_DATE  # the date instead of the joysticks
        ds.ModernRobotCodec.encode_control = staticmethod(libds_date)
    elif bug == "empty-match-info":
        from roles.cores.ds_robot_tcp import RobotTcpClient

        sends = RobotTcpClient.sends

        def empty_match_info(self, descriptors):
            actions = sends(self, descriptors)
            for k, a in enumerate(actions):
                if a.data[2:3] == b"\x07":
                    actions[k] = dataclasses.replace(a, data=bytes.fromhex("000107"))
            return actions
        RobotTcpClient.sends = empty_match_info
    else:
        raise SystemExit(f"unknown bug {bug!r}: one of {', '.join(BUGS)}")


def run_with_bug(argv: list[str], install, usage: str | None) -> int:
    """``BUG -- FIELDBOX ARGS...``: fieldbox, headless, with ``install(BUG)`` done first."""
    if len(argv) < 2 or argv[1] != "--":
        raise SystemExit(usage)
    install(argv[0])
    from fieldbox.cli import main as fieldbox

    return fieldbox(argv[2:])


if __name__ == "__main__":
    sys.exit(run_with_bug(sys.argv[1:], install, __doc__))
