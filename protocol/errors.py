"""The one exception family of the protocol library."""

from __future__ import annotations


class ProtocolError(ValueError):
    """Bytes that are not a valid message, or a message that cannot be encoded.

    ``message`` names the message (``ControlPacket``), ``field`` the dotted field path
    (``tags[2].joystick.axes[0]``) and ``offset`` the byte offset in the packet where the
    problem starts (``None`` when encoding: the message is not bytes yet).
    """

    def __init__(self, message: str, field: str, offset: int | None, reason: str) -> None:
        self.message = message
        self.field = field
        self.offset = offset
        self.reason = reason
        where = f" at byte {offset}" if offset is not None else ""
        super().__init__(f"{message}.{field}{where}: {reason}")

    def __reduce__(self) -> tuple[type[ProtocolError], tuple[str, str, int | None, str]]:  # keep pickling (multiprocessing, hypothesis) working
        return (type(self), (self.message, self.field, self.offset, self.reason))
