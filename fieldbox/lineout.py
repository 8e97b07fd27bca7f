"""Lines to stdout and stderr that never hold up the field (``fieldbox --headless``, ``fieldbox run``).

Both print from the event loop that runs the wire: the 20 ms beat, the commands, the e-stop.
A print to a pipe nobody reads blocks once the pipe is full (64 KB on Linux), and would stop
the beat with it; a print to a pipe whose reader went away (``| head -3``) raises
BrokenPipeError, which would end the task that obeys the commands. So :meth:`LineOut.line`
only appends to a queue (a lock held for an append), and a thread of its own writes:

* the reader went away (a broken pipe, a closed stream): every later line is dropped, said
  once on ``problems`` (stderr); the run goes on and commands are still obeyed;
* the reader falls behind by more than :data:`BACKLOG` characters: new lines are dropped and
  counted until it catches up; said once at the first drop, and the count at the end;
* at the end, :meth:`LineOut.close` writes what is queued within its ``timeout``; what it
  cannot is counted as dropped (a run must end when asked, whoever reads its output).

A stream with a file descriptor (the real stdout) is written with ``os.write`` on it, never
through ``sys.stdout``'s buffer: a thread blocked in a write then holds no lock, and the
interpreter's own flush of that buffer at exit has nothing to write.
"""

from __future__ import annotations

import os
import threading
from collections import deque
from typing import TextIO

#: Characters a reader may fall behind by before new lines are dropped (counted).
BACKLOG = 1 << 20


class LineOut:
    """Lines to ``stream`` from any thread, never blocking and never raising. ``name`` is the
    stream's name in what is said; ``problems`` is where a reader gone or falling behind is
    said (another LineOut, for stderr; None: nowhere, as for stderr itself)."""

    def __init__(self, stream: TextIO | None, name: str = "stdout", problems: "LineOut | None" = None,
                 backlog: int = BACKLOG) -> None:
        self.stream = stream
        self.name = name
        self.problems = problems
        self.backlog = backlog
        #: lines not written: the reader went away, or fell behind by more than ``backlog``
        self.dropped = 0
        self.gone = False  # the reader went away: nothing is written any more
        self._queue: deque[str] = deque()
        self._queued = 0  # characters in _queue
        self._writing = False  # the thread holds lines it took from the queue
        self._said_behind = False
        self._closing = False
        self._cond = threading.Condition()
        try:
            self._fd: int | None = stream.fileno() if stream is not None else None
        except (AttributeError, OSError, ValueError):  # io.UnsupportedOperation is an OSError
            self._fd = None
        self._encoding = getattr(stream, "encoding", None) or "utf-8"
        self._thread = threading.Thread(target=self._run, name=f"fieldbox-{name}", daemon=True)
        self._thread.start()

    def line(self, text: str) -> None:
        """Queue ``text`` and a newline; dropped (counted) if the reader is gone or too far behind."""
        data = text + "\n"
        first_drop = False
        with self._cond:
            if self.gone or self._closing:
                self.dropped += 1
                return
            if self._queued + len(data) > self.backlog and (self._queue or self._writing):
                self.dropped += 1
                first_drop, self._said_behind = not self._said_behind, True
            else:
                self._queue.append(data)
                self._queued += len(data)
                self._cond.notify()
        if first_drop:
            self._say(f"fieldbox: {self.name} is not being read ({self.backlog // 1024} KiB waiting): "
                      "lines for it are dropped until it is; the run goes on")

    def close(self, timeout: float) -> None:
        """Write what is queued, for at most ``timeout`` seconds; then say how many lines were
        dropped because the reader fell behind, if any."""
        with self._cond:
            self._closing = True
            self._cond.notify()
        self._thread.join(timeout)
        with self._cond:
            left = len(self._queue)
            self._queue.clear()
            self._queued = 0
            self.dropped += left
            behind = self._said_behind or (left and not self.gone)
        if behind and self.dropped:
            self._say(f"fieldbox: {self.dropped} line{'s' if self.dropped != 1 else ''} for {self.name} "
                      "dropped: its reader fell behind")

    # -- the writing thread ------------------------------------------------------------------
    def _run(self) -> None:
        stream = self.stream
        if stream is None:  # the process started with the fd closed
            self._lost()
            return
        try:
            stream.flush()  # anything printed before, in its order
        except (AttributeError, OSError, ValueError):
            self._lost()
            return
        while True:
            with self._cond:
                while not self._queue and not self._closing:
                    self._cond.wait()
                if not self._queue:
                    return  # closing, everything written
                batch = "".join(self._queue)
                self._queue.clear()
                self._queued = 0
                self._writing = True
            try:
                self._write(stream, batch)
            except (OSError, ValueError):  # BrokenPipeError, a closed or unwritable stream
                self._lost()
                return
            finally:
                with self._cond:
                    self._writing = False

    def _write(self, stream: TextIO, text: str) -> None:
        if self._fd is None:
            stream.write(text)
            stream.flush()
            return
        data = memoryview(text.encode(self._encoding, "backslashreplace"))
        while data:
            data = data[os.write(self._fd, data):]

    def _lost(self) -> None:
        with self._cond:
            self.gone = True
            self.dropped += len(self._queue)
            self._queue.clear()
            self._queued = 0
        self._say(f"fieldbox: {self.name} is closed (its reader went away): nothing more is written "
                  "to it; the run goes on")

    def _say(self, text: str) -> None:
        if self.problems is not None:
            self.problems.line(text)
