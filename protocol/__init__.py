"""fieldbox's wire formats: every FRC Driver Station, roboRIO and FMS message, byte-exact.

Pure: no sockets, clocks, asyncio or UI. Each module is one wire direction; ``kinds`` names
them all for decoding and annotating by name.
"""

from .errors import ProtocolError
from .framing import FrameDecoder
from . import kinds
from .kinds import annotate, decode, get
from .wire import Span, UnknownTag

__all__ = ["FrameDecoder", "ProtocolError", "Span", "UnknownTag", "annotate", "decode", "get", "kinds"]
