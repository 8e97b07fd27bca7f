"""The app in a real pseudo-terminal: it draws its panels and quits cleanly on ctrl+q."""

from __future__ import annotations

import os
import pty
import re
import select
import subprocess
import sys
import time

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
ANSI = re.compile(rb"\x1b\[[0-9;?<>=]*[ -/]*[@-~]|\x1b[()][0-9A-B]|\x1b[=>]|\x1b\][^\x07]*\x07")


def read_for(fd: int, seconds: float, until: bytes | None = None) -> bytes:
    out = b""
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        ready, _, _ = select.select([fd], [], [], 0.1)
        if ready:
            try:
                chunk = os.read(fd, 65536)
            except OSError:
                break
            if not chunk:
                break
            out += chunk
            if until is not None and until in ANSI.sub(b"", out):
                break
    return out


def test_app_draws_in_a_pty_and_quits_on_ctrl_q(tmp_path):
    master, slave = pty.openpty()
    env = dict(os.environ, TERM="xterm-256color", COLUMNS="120", LINES="40")
    proc = subprocess.Popen([sys.executable, "-m", "fieldbox", "--net", "ephemeral", "--team", "254",
                             "--log-file", str(tmp_path / "fieldbox.log"), "--log-dir", str(tmp_path / "logs")],
                            cwd=ROOT, stdin=slave, stdout=slave, stderr=slave, env=env, start_new_session=True)
    os.close(slave)
    try:
        import fcntl
        import struct
        import termios
        fcntl.ioctl(master, termios.TIOCSWINSZ, struct.pack("HHHH", 40, 120, 0, 0))
        screen = ANSI.sub(b"", read_for(master, 20, until=b"Inspector"))
        for title in (b"Driver Station", b"Joysticks", b"Console", b"FMS", b"Inspector"):
            assert title in screen, screen[-2000:]
        os.write(master, b"\x11")  # ctrl+q
        deadline = time.monotonic() + 10
        while proc.poll() is None and time.monotonic() < deadline:
            read_for(master, 0.2)
        assert proc.poll() == 0
    finally:
        if proc.poll() is None:
            proc.kill()
        os.close(master)
    log = (tmp_path / "fieldbox.log").read_text()
    assert "fieldbox" in log and "started" in log
    # Nothing lost: the robot's console reached its log file as it arrived.
    (run,) = (tmp_path / "logs").iterdir()
    assert "Robot program started" in (run / "ds-254-console.log").read_text()
