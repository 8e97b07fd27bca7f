"""What the DS told the fake roboRIO beyond enable and mode, as the robot program reads it:
the joysticks (values in each control packet, names in the TCP descriptors), the date and
time zone, the match countdown, match info, game data, and the 2010 DS's digital and analog
inputs. Only packets the control link obeys reach it (roles/cores/rio_control.py).
"""

from __future__ import annotations

import math
from typing import Any

from protocol import ds_to_rio
from protocol.ds_to_rio import EMPTY_JOYSTICK, Countdown, Date, Joystick, MalformedTag, Timezone

from .core import Events
from .robot_program import MAX_TEXT, SLOTS, JoystickState


class DsInputs:
    """The DS's inputs to the robot program; a reboot starts a fresh one."""

    def __init__(self, events: Events) -> None:
        self.events = events
        self.joystick_tags: tuple[Joystick, ...] = ()  # as the last packet obeyed sent them
        self.descriptors: list[ds_to_rio.JoystickDescriptor | None] = [None] * SLOTS
        self._joysticks: tuple[JoystickState, ...] | None = ()  # None: to build again
        self.countdown: float | None = None
        self.got_date = False
        self.got_timezone = False
        self.ds_date = None
        self.ds_timezone = ""
        self.match_info: ds_to_rio.MatchInfo | None = None
        self.game_data = ""
        self.ds_io: tuple[int, tuple[int, ...]] = (0, (0, 0, 0, 0))  # 2010: the DS's digital, analog in

    @property
    def request_date(self) -> bool:
        return not (self.got_date and self.got_timezone)

    @property
    def joysticks(self) -> tuple[JoystickState, ...]:
        """The joysticks as the program reads them; rebuilt only when a packet or a
        descriptor changed them."""
        if self._joysticks is None:
            names = [d.name if d else "" for d in self.descriptors]
            self._joysticks = tuple(
                JoystickState(tuple(ds_to_rio.int8_to_axis(a) for a in j.axes), j.buttons, j.button_count,
                              tuple(j.povs), names[i])
                for i, j in enumerate(self.joystick_tags))
        return self._joysticks

    def take_tags(self, tags: tuple[Any, ...]) -> None:
        """The tags of an obeyed control packet (a malformed one is counted by the control
        link; a malformed joystick keeps its slot, neutral)."""
        joysticks: list[Joystick] = []
        for tag in tags:
            kind = type(tag)
            if kind is Joystick:
                if len(joysticks) < SLOTS:  # a 7th joystick tag overwrites nothing
                    joysticks.append(tag)
            elif kind is Date:
                self.got_date = True
                self.ds_date = tag.to_datetime()
            elif kind is Timezone:
                self.got_timezone = True
                self.ds_timezone = tag.name
            elif kind is Countdown:
                self.countdown = tag.seconds if math.isfinite(tag.seconds) else None
            elif kind is MalformedTag and tag.tag_id == ds_to_rio.TAG_JOYSTICK and len(joysticks) < SLOTS:
                joysticks.append(EMPTY_JOYSTICK)
        if tuple(joysticks) != self.joystick_tags:
            self.joystick_tags = tuple(joysticks)
            self._joysticks = None

    def take_ds_io(self, inputs: tuple[int, tuple[int, ...]]) -> None:
        """2010: the DS's digital and analog inputs in an obeyed packet."""
        self.ds_io = inputs

    def take_message(self, message: Any, now: float) -> str | None:
        """A TCP message from the DS; what is wrong with it, if anything (the frame is then
        counted bad)."""
        kind = type(message)
        if kind is ds_to_rio.JoystickDescriptor:
            if not 0 <= message.index < SLOTS:
                return f"joystick descriptor for slot {message.index}, only 0-{SLOTS - 1}"
            self.descriptors[message.index] = message
            self._joysticks = None
        elif kind is ds_to_rio.MatchInfo:
            if message != self.match_info:
                self.events.add(now, f"match info: {message.competition or '(no event)'} "
                                     f"{getattr(message.match_type, 'name', message.match_type)} "
                                     f"#{message.match_number}")
            self.match_info = message
        elif kind is ds_to_rio.GameData:
            text = message.text[:MAX_TEXT]
            if text != self.game_data:
                self.events.add(now, f"game data: {text!r}")
            self.game_data = text
        # keep-alives and frames no document names are fine: nothing to do
        return None
