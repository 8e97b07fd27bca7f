"""Joystick input for the Driver Station: real joysticks through pygame (SDL), a keyboard
joystick for terminals, and the six slots they are assigned to.

No textual here, so a headless DS could use it too; pygame is imported only when real
devices are started (:meth:`JoystickHub.start_devices`): it costs about 0.2 s, and SDL must
see its environment first (``SDL_VIDEODRIVER=dummy``, background joystick events, and no
signal handlers, or SDL would swallow Ctrl-C and SIGTERM).

One module per concept; import from the package, as the app does:

* :class:`KeyboardJoystick` (``keyboard.py``): a 6-axis, 12-button, 1-POV gamepad driven by
  key presses. Terminals send no key-up events, so axes either *spring* (a press pushes the
  axis fully, it returns to 0 once the key stops repeating) or *step* (each press moves it
  0.25, a key centres), and buttons either *pulse* (down for 0.2 s per press) or *toggle*.
* :class:`PygameDevices` (``devices.py``): SDL joysticks, with hot-plug (device added /
  removed events).
* :class:`JoystickHub` (``hub.py``): which source sits in which slot, locking a device to its
  slot (a locked device that is unplugged keeps its slot, reported neutral, until it
  returns), and the difference between what the DS has and what it should have, as one
  :class:`~roles.cores.commands.UpdateJoysticks` command per poll (one command carries every
  change).
* ``descriptor.py``: what both sources report, a :class:`Descriptor` (what the DS declares
  for a slot) and a :class:`Reading` (its live values).

Times are ``time.monotonic()`` seconds passed in by the caller (the key timing is the
user's, not the wire's).
"""

from __future__ import annotations

from .descriptor import (MAX_AXES, MAX_BUTTONS, MAX_POVS, SLOTS, TYPE_HID_GAMEPAD, TYPE_HID_JOYSTICK, TYPE_UNKNOWN,
                         TYPE_XINPUT_GAMEPAD, Descriptor, Reading, axis_int8)
from .devices import HAT_TO_POV, SDL_ENVIRONMENT, Device, DeviceError, PygameDevices, describe_device, import_pygame
from .hub import DeviceKey, JoystickHub, SlotEntry
from .keyboard import (AXIS_KEYS, AXIS_MODE_KEY, BUTTON_KEYS, BUTTON_MODE_KEY, CENTRE_KEY, KEYBOARD_KEYS,
                       KEYBOARD_NAME, POV_KEYS, KeyboardJoystick)

__all__ = [
    "AXIS_KEYS", "AXIS_MODE_KEY", "BUTTON_KEYS", "BUTTON_MODE_KEY", "CENTRE_KEY", "Descriptor", "Device",
    "DeviceError", "DeviceKey", "HAT_TO_POV", "JoystickHub", "KEYBOARD_KEYS", "KEYBOARD_NAME",
    "KeyboardJoystick", "MAX_AXES", "MAX_BUTTONS", "MAX_POVS", "POV_KEYS", "PygameDevices", "Reading",
    "SDL_ENVIRONMENT", "SLOTS", "SlotEntry", "TYPE_HID_GAMEPAD", "TYPE_HID_JOYSTICK", "TYPE_UNKNOWN",
    "TYPE_XINPUT_GAMEPAD", "axis_int8", "describe_device", "import_pygame",
]
