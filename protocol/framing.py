"""TCP stream framing: ``[u16 size][u8 id][payload]``, size counting the id byte.

Every TCP stream in these protocols (DS <-> roboRIO on 1740, DS <-> FMS on 1750) uses this
framing. :class:`FrameDecoder` takes bytes in any chunking and returns whole frames, each
with its two size bytes, so a frame can be handed to the message decoders, annotated and
captured exactly as it crossed the wire. One decoder per connection: parser state is never
shared between clients (a trap other implementations fell into).

A size of 0 is a frame with no id: an empty keep-alive. It is returned as ``b"\\x00\\x00"``.
"""

from __future__ import annotations

from .errors import ProtocolError
from .wire import U16

#: The largest frame any peer here sends is a few kilobytes (an error message with a call
#: stack); the wire format allows 65 537. A decoder refuses frames above its bound.
DEFAULT_MAX_FRAME = 0xFFFF + 2


class FrameDecoder:
    """Reassembles frames from a byte stream, bounded in memory by ``max_frame``.

    Each frame's size field is checked against the bound as soon as its two bytes are in,
    before any of its body is buffered: a peer that announces a frame over the bound is
    refused at its header, and a peer that drips bytes or floods whole frames costs each
    byte one copy, never a rescan of what is held.
    """

    __slots__ = ("name", "max_frame", "_buffer", "_consumed", "_error")

    def __init__(self, name: str = "TcpStream", max_frame: int = DEFAULT_MAX_FRAME) -> None:
        if not 2 <= max_frame <= DEFAULT_MAX_FRAME:
            raise ValueError(f"max_frame must be 2..{DEFAULT_MAX_FRAME}")
        self.name = name
        self.max_frame = max_frame
        self._buffer = bytearray()  # the start of one frame not yet complete (never more)
        self._consumed = 0  # stream offset of _buffer[0]: the bytes of every frame handed out
        self._error: ProtocolError | None = None

    @property
    def buffered(self) -> int:
        """Bytes held of a frame not yet complete."""
        return len(self._buffer)

    @property
    def stream_offset(self) -> int:
        return self._consumed + len(self._buffer)

    def feed(self, data: bytes) -> list[bytes]:
        """Add bytes; return every frame now complete. After a ProtocolError the stream is
        unusable (the caller closes the connection) and every further call raises it again."""
        frames, error = self.feed_until_error(data)
        if error is not None:
            raise error
        return frames

    def _check(self, size: int, offset: int) -> ProtocolError | None:
        """The error for a frame whose size field (at stream ``offset``) says ``size``, if any."""
        total = size + 2
        if total <= self.max_frame:
            return None
        self._error = ProtocolError(self.name, "size", offset,
                                    f"frame of {total} bytes is over the {self.max_frame}-byte bound")
        return self._error

    def feed_until_error(self, data: bytes) -> tuple[list[bytes], ProtocolError | None]:
        """Add bytes; return the frames complete before a bad size field, and its error (None
        if there is none). A chunk that holds whole frames and then a bad header gives the
        frames first, so the caller handles them before it closes the connection (they
        arrived first). After an error every further call returns it again, with no frame."""
        if self._error is not None:
            return [], self._error
        frames: list[bytes] = []
        n = len(data)
        pos = 0
        buf = self._buffer
        if buf:  # finish the frame held first: its header, if not whole yet, then its body
            if len(buf) < 2:
                pos = min(2 - len(buf), n)
                buf += data[:pos]
                if len(buf) < 2:
                    return frames, None
                error = self._check((buf[0] << 8) | buf[1], self._consumed)
                if error is not None:
                    return frames, error
            total = ((buf[0] << 8) | buf[1]) + 2
            take = min(total - len(buf), n - pos)
            buf += data[pos:pos + take]
            pos += take
            if len(buf) < total:
                return frames, None
            frames.append(bytes(buf))
            self._consumed += total
            buf.clear()
        base = self._consumed - pos  # the stream offset of data[0]
        while n - pos >= 2:
            size = (data[pos] << 8) | data[pos + 1]
            error = self._check(size, base + pos)
            if error is not None:
                self._consumed = base + pos
                return frames, error  # the whole frames before it come first
            total = size + 2
            if n - pos < total:
                break
            frames.append(bytes(data[pos:pos + total]))
            pos += total
        self._consumed = base + pos
        if pos < n:
            buf += data[pos:]  # the start of the next frame, its header (if whole) checked
        return frames, None


def split_frames(data: bytes, name: str = "TcpStream", max_frame: int = DEFAULT_MAX_FRAME) -> list[bytes]:
    """All frames of a complete byte string; trailing bytes of a cut frame are an error."""
    decoder = FrameDecoder(name, max_frame)
    frames = decoder.feed(data)
    if decoder.buffered:
        raise ProtocolError(name, "size", decoder.stream_offset - decoder.buffered,
                            f"{decoder.buffered} byte(s) of an unfinished frame")
    return frames


def frame_payload(name: str, frame: bytes) -> tuple[int | None, int]:
    """Check a whole frame's size field; return ``(tag id or None for a keep-alive, payload
    start offset)``."""
    if len(frame) < 2:
        raise ProtocolError(name, "size", 0, f"needs 2 bytes, {len(frame)} given")
    (size,) = U16.unpack_from(frame, 0)
    if len(frame) != size + 2:
        raise ProtocolError(name, "size", 0, f"size field says {size} byte(s) follow, {len(frame) - 2} do")
    if size == 0:
        return None, 2
    return frame[2], 3
